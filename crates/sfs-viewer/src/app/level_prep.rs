//! The level preparation: a named thread that turns each level the solver
//! reports into what the viewer shows — its depth on the object only, the
//! 2-D panels' images and the 3-D mesh (by `depth_mesh`, placed by the
//! level's own geometry) — so that a large level never stalls a frame. The
//! newest level wins; uses `depth_mesh`, `render::SurfaceMesh`, `solver`,
//! `images`, no GPU.

use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TryRecvError};
use eframe::egui;

use super::images;
use crate::render::SurfaceMesh;
use sfs_core::depth_mesh::{DepthMesh, MeshOptions};
use sfs_core::grid::Grid;
use sfs_core::solver::{LevelResult, pyramid};

/// Meshes shown in the 3-D view have at most this many vertices; larger
/// depth maps are sampled with a stride (display only).
pub const MAX_VIEW_VERTICES: usize = 512 * 512;

/// The full-size inputs of a solve job that every level is shown against,
/// shared with the level-preparation thread.
#[derive(Clone)]
pub struct LevelInputs {
    /// The input image (linear).
    pub image: Arc<Grid<f64>>,
    /// Ground-truth depth.
    pub ground_truth: Option<Arc<Grid<f64>>>,
    /// The object mask (`None`: every pixel is object). The solver's levels
    /// carry depth off the object too (the paper's domain): the view shows
    /// only the object.
    pub object: Option<Arc<Grid<bool>>>,
    /// How the input panel shows the image: the reprojection (in the
    /// image's units) is shown the same way, so the two compare.
    pub display: images::DisplayMapping,
    /// The grey the surface carries as its texture instead of the image
    /// (the albedo of a set or of a single solve, NaN where there is none),
    /// at the image's size.
    pub texture: Option<Arc<Grid<f64>>>,
}

/// A level to prepare for display: its mesh and its 2-D panel images.
pub struct MeshJob {
    /// Increases with every job; the newest wins.
    pub generation: u64,
    /// The level as the solver reported it (depth, reprojection, geometry).
    pub level: LevelResult,
    /// The job's full-size inputs.
    pub inputs: LevelInputs,
}

/// Images of the 2-D panels for one level, with the colour-map ranges.
pub struct LevelPanels {
    /// Reprojection, grey, shown as the input is.
    pub reprojection: egui::ColorImage,
    /// |input - reprojection| at full size, on the object.
    pub difference: (egui::ColorImage, [f64; 2]),
    /// Depth on the object.
    pub depth: (egui::ColorImage, [f64; 2]),
    /// |depth - ground truth| at full size.
    pub depth_error: Option<(egui::ColorImage, [f64; 2])>,
}

/// A prepared level.
pub struct BuiltMesh {
    /// Generation of the job.
    pub generation: u64,
    /// The mesh.
    pub mesh: Arc<SurfaceMesh>,
    /// The panel images (absent for meshes made elsewhere, e.g. tests).
    pub panels: Option<LevelPanels>,
}

/// `full` sampled at the centres of a `(width, height)` level's pixels, in
/// full-resolution pixels as the solver's rays (bilinear).
fn at_level(full: &Grid<f64>, (width, height): (usize, usize)) -> Grid<f64> {
    let (full_width, full_height) = full.size();
    Grid::from_fn(width, height, |c, r| {
        pyramid::bilinear(
            full,
            pyramid::map_coordinate(c, width, full_width),
            pyramid::map_coordinate(r, height, full_height),
        )
    })
}

/// The object mask at a `(width, height)` level: a level pixel is object
/// when at least half of the bilinear weight at its centre is.
fn object_at_level(object: &Grid<bool>, (width, height): (usize, usize)) -> Grid<bool> {
    let (full_width, full_height) = object.size();
    Grid::from_fn(width, height, |c, r| {
        let taps = pyramid::bilinear_taps(
            (full_width, full_height),
            pyramid::map_coordinate(c, width, full_width),
            pyramid::map_coordinate(r, height, full_height),
        );
        let weight: f64 = taps
            .iter()
            .filter(|&&(q, _)| object.as_slice()[q])
            .map(|&(_, w)| w)
            .sum();
        weight >= 0.5
    })
}

/// `photo` divided by its 99th percentile over the pixels with finite
/// `depth` (the surface), so that a dark photograph shows on the surface as
/// bright as a well-exposed one; unchanged when that is not positive.
fn exposure_normalised(mut photo: Grid<f64>, depth: &Grid<f64>) -> Grid<f64> {
    let mut on_surface: Vec<f64> = photo
        .as_slice()
        .iter()
        .zip(depth.as_slice())
        .filter(|(p, z)| p.is_finite() && z.is_finite())
        .map(|(&p, _)| p)
        .collect();
    if on_surface.is_empty() {
        return photo;
    }
    let k = (on_surface.len() - 1) * 99 / 100;
    let (_, &mut white, _) = on_surface.select_nth_unstable_by(k, f64::total_cmp);
    if white > 0.0 {
        photo.as_mut_slice().iter_mut().for_each(|p| *p /= white);
    }
    photo
}

/// NaN where `keep` is false.
fn masked(values: &Grid<f64>, keep: &Grid<bool>) -> Grid<f64> {
    Grid::from_fn(values.width(), values.height(), |c, r| {
        if *keep.at(c, r) {
            *values.at(c, r)
        } else {
            f64::NAN
        }
    })
}

/// The stride that keeps a `(width, height)` grid's samples within
/// [`MAX_VIEW_VERTICES`].
fn view_stride((width, height): (usize, usize)) -> usize {
    let pixels = width * height;
    if pixels <= MAX_VIEW_VERTICES {
        1
    } else {
        ((pixels as f64 / MAX_VIEW_VERTICES as f64).sqrt().ceil() as usize).max(1)
    }
}

/// The CPU work of a level: its depth on the object only, the panel images,
/// then the mesh (by the exporters' triangulation, placed by the level's own
/// geometry), coloured by the reprojection error and carrying the
/// photograph at the level's size.
fn prepare_level(job: MeshJob) -> BuiltMesh {
    let MeshJob {
        generation,
        level,
        inputs,
    } = job;
    let size = level.depth.size();
    let depth = match &inputs.object {
        Some(object) if object.size() == inputs.image.size() => {
            Arc::new(masked(&level.depth, &object_at_level(object, size)))
        }
        _ => Arc::clone(&level.depth),
    };
    // The residual I - R (signed: positive where the image is brighter than
    // the model explains), on a range symmetric about 0.
    let mut difference = images::signed_difference(&level.reprojection, &inputs.image);
    if let Some(object) = &inputs.object
        && object.size() == difference.size()
    {
        difference = masked(&difference, object);
    }
    let largest = images::finite_range(&difference).map_or(1.0, |r| r[0].abs().max(r[1].abs()));
    let largest = if largest > 0.0 { largest } else { 1.0 };
    let difference_range = [-largest, largest];
    let depth_range = images::finite_range(&depth).unwrap_or([0.0, 1.0]);
    let depth_error = inputs.ground_truth.as_ref().map(|gt| {
        let error = images::abs_difference(&depth, gt);
        let range = [0.0, images::finite_range(&error).map_or(1.0, |r| r[1])];
        (images::colour_mapped(&error, range), range)
    });
    let panels = LevelPanels {
        reprojection: inputs.display.image(&level.reprojection),
        difference: (
            images::colour_mapped(&difference, difference_range),
            difference_range,
        ),
        depth: (images::colour_mapped(&depth, depth_range), depth_range),
        depth_error,
    };
    let level_difference = images::abs_difference(&inputs.image, &level.reprojection);
    let texture = inputs
        .texture
        .as_deref()
        .filter(|t| t.size() == inputs.image.size())
        .unwrap_or(&inputs.image);
    let photo = exposure_normalised(at_level(texture, size), &depth);
    let options = MeshOptions {
        stride: view_stride(size),
        ..MeshOptions::default()
    };
    let mesh = match DepthMesh::with_options(&depth, &level.geometry, options) {
        Ok(mesh) => SurfaceMesh::from_depth_mesh(&mesh, Some(&level_difference), Some(&photo)),
        Err(e) => {
            log_once(&format!("3-D view: no mesh for level {}: {e}", level.level));
            SurfaceMesh::default()
        }
    };
    BuiltMesh {
        generation,
        mesh: Arc::new(mesh),
        panels: Some(panels),
    }
}

/// A named thread that builds meshes, newest job first.
pub struct MeshBuilder {
    jobs: Option<Sender<MeshJob>>,
    meshes: Receiver<BuiltMesh>,
    handle: Option<JoinHandle<()>>,
}

impl MeshBuilder {
    /// Starts the thread; `waker` is called after every mesh.
    pub fn spawn(waker: impl Fn() + Send + 'static) -> std::io::Result<Self> {
        let (job_tx, job_rx) = crossbeam_channel::unbounded::<MeshJob>();
        let (mesh_tx, mesh_rx) = crossbeam_channel::bounded::<BuiltMesh>(4);
        let handle = std::thread::Builder::new()
            .name("sfs-mesh".into())
            .spawn(move || {
                while let Ok(mut job) = job_rx.recv() {
                    // Only the newest pending job matters.
                    while let Ok(newer) = job_rx.try_recv() {
                        job = newer;
                    }
                    let built = prepare_level(job);
                    if mesh_tx.send(built).is_err() {
                        return;
                    }
                    waker();
                }
            })?;
        Ok(Self {
            jobs: Some(job_tx),
            meshes: mesh_rx,
            handle: Some(handle),
        })
    }

    /// Queues a job; never blocks and never drops one (the thread skips to
    /// the newest, so at most the levels that arrive during one preparation
    /// wait here).
    pub fn submit(&self, job: MeshJob) {
        if let Some(jobs) = &self.jobs {
            // Fails only when the thread has ended (it then has nothing to show).
            let _ = jobs.send(job);
        }
    }

    /// The newest finished mesh, if any arrived.
    pub fn poll(&self) -> Option<BuiltMesh> {
        let mut newest = None;
        loop {
            match self.meshes.try_recv() {
                Ok(m) => newest = Some(m),
                Err(TryRecvError::Empty | TryRecvError::Disconnected) => return newest,
            }
        }
    }
}

impl Drop for MeshBuilder {
    fn drop(&mut self) {
        // Closing the job channel ends the thread's loop.
        self.jobs = None;
        if let Some(handle) = self.handle.take() {
            crate::worker::join_within(handle, crate::worker::SHUTDOWN_WAIT);
        }
    }
}

/// The level preparation as the app drives it: the thread (if it could be
/// started) and the generation of the newest level submitted.
pub struct LevelPrep {
    builder: Option<MeshBuilder>,
    generation: u64,
}

impl LevelPrep {
    /// Starts the thread; `waker` is called after every prepared level.
    /// Without a thread, levels are not shown (the 2-D and 3-D views stay
    /// empty) and the error is returned beside.
    pub fn spawn(waker: impl Fn() + Send + 'static) -> (Self, Option<std::io::Error>) {
        let (builder, error) = match MeshBuilder::spawn(waker) {
            Ok(b) => (Some(b), None),
            Err(e) => (None, Some(e)),
        };
        (
            Self {
                builder,
                generation: 0,
            },
            error,
        )
    }

    /// Whether levels can be prepared.
    pub fn is_running(&self) -> bool {
        self.builder.is_some()
    }

    /// Generation of the newest level submitted (0 before the first).
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Queues `level` against `inputs`; returns its generation, `None`
    /// without a thread.
    pub fn submit(&mut self, level: LevelResult, inputs: LevelInputs) -> Option<u64> {
        let builder = self.builder.as_ref()?;
        self.generation += 1;
        builder.submit(MeshJob {
            generation: self.generation,
            level,
            inputs,
        });
        Some(self.generation)
    }

    /// The newest prepared level, if one arrived.
    pub fn poll(&self) -> Option<BuiltMesh> {
        self.builder.as_ref().and_then(MeshBuilder::poll)
    }
}

/// Logs the first of these messages (a thread has nowhere else to say it).
fn log_once(message: &str) {
    use std::sync::atomic::{AtomicBool, Ordering};
    static LOGGED: AtomicBool = AtomicBool::new(false);
    if !LOGGED.swap(true, Ordering::Relaxed) {
        eprintln!("{message}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_shows_only_the_object_and_large_levels_are_sampled() {
        use sfs_core::camera::Intrinsics;
        use sfs_core::model::{Energy, LevelGeometry};
        // A 40x30 image, the object a centred disc; the level at half size
        // has depth everywhere (the paper's domain).
        let (w, h) = (40, 30);
        let object = Grid::from_fn(w, h, |c, r| {
            (c as f64 - 19.5).powi(2) + (r as f64 - 14.5).powi(2) < 100.0
        });
        let camera = Intrinsics::centred(60.0, w, h);
        let geometry = LevelGeometry::new(20, 15, w, h, camera);
        let level = LevelResult {
            level: 0,
            levels: 1,
            depth: Arc::new(Grid::filled(20, 15, 3.0)),
            reprojection: Arc::new(Grid::filled(20, 15, 0.5)),
            geometry,
            domain_pixels: 300,
            energy: Energy::default(),
            elapsed: std::time::Duration::ZERO,
        };
        let inputs = LevelInputs {
            image: Arc::new(Grid::from_fn(w, h, |c, _| c as f64 / w as f64)),
            ground_truth: None,
            object: Some(Arc::new(object.clone())),
            display: images::DisplayMapping { exposure: 2.0 },
            texture: None,
        };
        let built = prepare_level(MeshJob {
            generation: 7,
            level,
            inputs,
        });
        let object_at_half = object_at_level(&object, (20, 15));
        let inside = object_at_half.as_slice().iter().filter(|&&o| o).count();
        assert!(inside > 50 && inside < 300 / 2, "{inside}");
        assert_eq!(built.generation, 7);
        // The reprojection (0.5 everywhere) is shown as the input: x2, sRGB.
        let panels = built.panels.as_ref().expect("panel images");
        let white = egui::Color32::WHITE;
        assert!(panels.reprojection.pixels.iter().all(|&p| p == white));
        assert_eq!(built.mesh.vertices().len(), inside);
        // Vertices lie on the object's rays: framing sees the disc, not the
        // image rectangle (half-width at depth 3: 20 px * 3 / 60 = 1).
        let b = built.mesh.bounds();
        assert!(b.max_world.x < 0.55 && b.min_world.x > -0.55, "{b:?}");
        // The photo is the image at the level's size, its 99th percentile
        // on the surface scaled to 1 (the image is c / 40 at column c).
        let photos: Vec<f32> = built.mesh.vertices().iter().map(|v| v.photo).collect();
        let brightest = photos.iter().cloned().fold(0.0, f32::max);
        assert!(brightest > 0.99 && brightest < 1.2, "{brightest}");
        assert!(photos.iter().all(|&p| p > 0.25), "{photos:?}");
        assert_eq!(view_stride((512, 512)), 1);
        let stride = view_stride((1920, 1080));
        assert!(1920usize.div_ceil(stride) * 1080usize.div_ceil(stride) <= MAX_VIEW_VERTICES);
        assert!(stride > 1);
    }
}
