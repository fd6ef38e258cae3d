//! The bridge between egui and the wgpu surface renderer: a paint callback
//! that renders in `prepare` and blits in `paint`, orbit/pan/zoom input, and a
//! background thread that turns each level into a mesh and the 2-D panels'
//! images, so that a large level never stalls a frame.

use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TryRecvError};
use eframe::egui;
use egui_wgpu::wgpu;

use crate::depth_mesh::{DepthMesh, MeshOptions};
use crate::grid::Grid;
use crate::render::{Bounds, ColourMode, OrbitCamera, SurfaceMesh, SurfaceRenderer, ViewSettings};
use crate::solver::{LevelResult, pyramid};

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
    /// Reprojection, grey.
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
    use super::images;
    let MeshJob {
        generation,
        level,
        inputs,
    } = job;
    let size = level.depth.size();
    let depth = match &inputs.object {
        Some(object) if object.size() == inputs.image.size() => {
            masked(&level.depth, &object_at_level(object, size))
        }
        _ => level.depth,
    };
    let mut difference = images::abs_difference(&level.reprojection, &inputs.image);
    if let Some(object) = &inputs.object
        && object.size() == difference.size()
    {
        difference = masked(&difference, object);
    }
    let difference_range = [0.0, images::finite_range(&difference).map_or(1.0, |r| r[1])];
    let depth_range = images::finite_range(&depth).unwrap_or([0.0, 1.0]);
    let depth_error = inputs.ground_truth.as_ref().map(|gt| {
        let error = images::abs_difference(&depth, gt);
        let range = [0.0, images::finite_range(&error).map_or(1.0, |r| r[1])];
        (images::colour_mapped(&error, range), range)
    });
    let panels = LevelPanels {
        reprojection: images::grey_image(&level.reprojection),
        difference: (
            images::colour_mapped(&difference, difference_range),
            difference_range,
        ),
        depth: (images::colour_mapped(&depth, depth_range), depth_range),
        depth_error,
    };
    let level_difference = images::abs_difference(&inputs.image, &level.reprojection);
    let photo = exposure_normalised(at_level(&inputs.image, size), &depth);
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
            let _ = handle.join();
        }
    }
}

/// GPU state kept in egui-wgpu's callback resources.
struct SurfaceResources {
    renderer: SurfaceRenderer,
    uploaded_generation: Option<u64>,
    /// What the offscreen target holds: it is re-rendered only when the
    /// mesh, the view or the size changed, and blitted every frame.
    rendered: Option<(Option<u64>, ViewSettings, [u32; 2])>,
}

/// Installs the renderer in the callback resources; returns false (and the
/// 3-D view shows a message) when the GPU refused.
pub fn install(render_state: &egui_wgpu::RenderState) -> Result<(), String> {
    let renderer = SurfaceRenderer::new(&render_state.device, render_state.target_format)
        .map_err(|e| format!("3-D view unavailable: {e}"))?;
    render_state
        .renderer
        .write()
        .callback_resources
        .insert(SurfaceResources {
            renderer,
            uploaded_generation: None,
            rendered: None,
        });
    Ok(())
}

/// What one frame's callback carries.
struct SurfaceCallback {
    mesh: Option<(u64, Arc<SurfaceMesh>)>,
    settings: ViewSettings,
    size_px: [u32; 2],
}

impl egui_wgpu::CallbackTrait for SurfaceCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(res) = resources.get_mut::<SurfaceResources>() else {
            log_once("3-D view: renderer resources missing");
            return Vec::new();
        };
        if let Some((generation, mesh)) = &self.mesh
            && res.uploaded_generation != Some(*generation)
        {
            match res.renderer.upload(device, queue, mesh) {
                Ok(()) => res.uploaded_generation = Some(*generation),
                Err(e) => log_once(&format!("3-D view: upload failed: {e}")),
            }
        }
        let key = (res.uploaded_generation, self.settings, self.size_px);
        if res.rendered.as_ref() == Some(&key) {
            return Vec::new();
        }
        match res
            .renderer
            .render(device, queue, encoder, self.size_px, &self.settings)
        {
            Ok(()) => res.rendered = Some(key),
            Err(e) => log_once(&format!("3-D view: render failed: {e}")),
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        render_pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(res) = resources.get::<SurfaceResources>() else {
            return;
        };
        res.renderer.paint(render_pass);
    }
}

fn log_once(message: &str) {
    use std::sync::atomic::{AtomicBool, Ordering};
    static LOGGED: AtomicBool = AtomicBool::new(false);
    if !LOGGED.swap(true, Ordering::Relaxed) {
        eprintln!("{message}");
    }
}

/// The 3-D view's state on the UI side.
pub struct SurfaceView {
    /// Orbit camera.
    pub camera: OrbitCamera,
    mesh: Option<(u64, Arc<SurfaceMesh>)>,
    /// The bounds the camera framed (or is to frame at the next frame).
    framed_bounds: Option<Bounds>,
    /// Framing waits for the view's size (its aspect).
    needs_framing: bool,
    /// Width / height of the view at the last frame.
    aspect: f32,
    /// Whether the GPU renderer was installed.
    pub available: Result<(), String>,
}

impl SurfaceView {
    /// A view with no mesh yet.
    pub fn new(available: Result<(), String>) -> Self {
        Self {
            camera: OrbitCamera::default(),
            mesh: None,
            framed_bounds: None,
            needs_framing: false,
            aspect: 1.0,
            available,
        }
    }

    /// Generation of the mesh on screen.
    pub fn generation(&self) -> Option<u64> {
        self.mesh.as_ref().map(|(g, _)| *g)
    }

    /// Forgets the mesh (a new image).
    pub fn clear(&mut self) {
        self.mesh = None;
        self.framed_bounds = None;
        self.needs_framing = false;
    }

    /// Shows a new mesh; frames it (at the next frame, when the view's
    /// aspect is known) the first time: later meshes keep the user's view.
    pub fn set_mesh(&mut self, built: BuiltMesh) -> Option<LevelPanels> {
        if self.framed_bounds.is_none() && !built.mesh.is_empty() {
            self.framed_bounds = Some(built.mesh.bounds());
            self.needs_framing = true;
        }
        self.mesh = Some((built.generation, built.mesh));
        built.panels
    }

    /// Depth range of the mesh on screen.
    pub fn depth_range(&self) -> Option<[f32; 2]> {
        self.mesh.as_ref().and_then(|(_, m)| m.depth_range())
    }

    /// Draws the view into `ui`'s remaining space and handles the mouse:
    /// drag to orbit, right/middle drag to pan, scroll to zoom, double-click
    /// to reset.
    pub fn ui(&mut self, ui: &mut egui::Ui, prefs: &super::settings::ViewPrefs, error_range: f32) {
        if let Err(message) = &self.available {
            ui.label(message.clone());
            return;
        }
        let size = ui.available_size().max(egui::vec2(64.0, 64.0));
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        self.aspect = rect.width() / rect.height().max(1.0);
        if self.needs_framing
            && let Some(bounds) = &self.framed_bounds
        {
            self.camera = OrbitCamera::framing(bounds, self.aspect);
            self.needs_framing = false;
        }
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            self.camera.orbit(-d.x * 0.01, d.y * 0.01);
        }
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            let d = response.drag_delta();
            self.camera.pan(d.x, d.y, rect.height());
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.zoom((scroll * 0.002).exp());
            }
        }
        if response.double_clicked() {
            self.reset();
        }
        let ppp = ui.ctx().pixels_per_point();
        let size_px = [
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        ];
        let (colour_mode, value_range) = match prefs.colour {
            _ if prefs.photo_texture => (ColourMode::Photo, [0.0, 1.0]),
            super::settings::SurfaceColour::Shaded => (ColourMode::Shaded, [0.0, 1.0]),
            super::settings::SurfaceColour::Depth => {
                (ColourMode::Depth, self.depth_range().unwrap_or([0.0, 1.0]))
            }
            super::settings::SurfaceColour::Error => {
                (ColourMode::Error, [0.0, error_range.max(1e-6)])
            }
        };
        let settings = ViewSettings {
            camera: self.camera,
            light_yaw_rad: prefs.light_yaw_deg.to_radians(),
            light_pitch_rad: prefs.light_pitch_deg.to_radians(),
            colour_mode,
            value_range,
            wireframe: prefs.wireframe,
            ..ViewSettings::default()
        };
        ui.painter().add(egui_wgpu::Callback::new_paint_callback(
            rect,
            SurfaceCallback {
                mesh: self.mesh.clone(),
                settings,
                size_px,
            },
        ));
        if self.mesh.is_none() {
            ui.painter().text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "the surface appears with the first level",
                egui::FontId::proportional(14.0),
                ui.visuals().weak_text_color(),
            );
        }
    }

    /// Frames the current mesh again.
    pub fn reset(&mut self) {
        if let Some((_, mesh)) = &self.mesh {
            self.camera = OrbitCamera::framing(&mesh.bounds(), self.aspect);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 3-D view alone, showing the analytic Sombrero's exact depth.
    struct ViewOnly {
        view: SurfaceView,
        prefs: super::super::settings::ViewPrefs,
    }

    impl eframe::App for ViewOnly {
        fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
            egui::CentralPanel::default().show(ui, |ui| self.view.ui(ui, &self.prefs, 1.0));
        }
    }

    #[test]
    fn snapshot_of_the_surface_view() {
        let scene = crate::scene::sombrero::sombrero(96, 96);
        let mut harness = egui_kittest::Harness::builder()
            .with_size(egui::vec2(320.0, 240.0))
            .wgpu()
            .build_eframe(move |cc| {
                let available = match cc.wgpu_render_state.as_ref() {
                    Some(rs) => install(rs),
                    None => Err("no wgpu".into()),
                };
                let mut view = SurfaceView::new(available);
                let mesh = SurfaceMesh::from_depth(&scene.depth_gt, &scene.camera, None);
                view.set_mesh(BuiltMesh {
                    generation: 1,
                    mesh: Arc::new(mesh),
                    panels: None,
                });
                ViewOnly {
                    view,
                    prefs: Default::default(),
                }
            });
        assert!(harness.state().view.available.is_ok(), "no 3-D renderer");
        harness.run_steps(3);
        harness.snapshot("surface_view_sombrero");
    }

    #[test]
    fn a_level_shows_only_the_object_and_large_levels_are_sampled() {
        use crate::camera::Intrinsics;
        use crate::model::{Energy, LevelGeometry};
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
            depth: Grid::filled(20, 15, 3.0),
            reprojection: Grid::filled(20, 15, 0.5),
            geometry,
            domain_pixels: 300,
            energy: Energy::default(),
            elapsed: std::time::Duration::ZERO,
        };
        let inputs = LevelInputs {
            image: Arc::new(Grid::from_fn(w, h, |c, _| c as f64 / w as f64)),
            ground_truth: None,
            object: Some(Arc::new(object.clone())),
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
