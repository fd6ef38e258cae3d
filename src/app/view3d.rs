//! The bridge between egui and the wgpu surface renderer: a paint callback
//! that renders in `prepare` and blits in `paint`, orbit/pan/zoom input, and a
//! background thread that turns each level into a mesh and the 2-D panels'
//! images, so that a large level never stalls a frame.

use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TryRecvError};
use eframe::egui;
use egui_wgpu::wgpu;

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::render::{Bounds, ColourMode, OrbitCamera, SurfaceMesh, SurfaceRenderer, ViewSettings};

/// Meshes shown in the 3-D view have at most this many vertices; larger
/// depth maps are point-sampled with a stride (display only).
pub const MAX_VIEW_VERTICES: usize = 512 * 512;

/// A level to prepare for display: its mesh and its 2-D panel images.
pub struct MeshJob {
    /// Increases with every job; the newest wins.
    pub generation: u64,
    /// Depth (NaN = no surface).
    pub depth: Grid<f64>,
    /// Reprojection at the level's size.
    pub reprojection: Grid<f64>,
    /// Camera at the depth map's resolution.
    pub camera: Intrinsics,
    /// The full-size input image.
    pub image: Arc<Grid<f64>>,
    /// Ground-truth depth at full size.
    pub ground_truth: Option<Arc<Grid<f64>>>,
}

/// Images of the 2-D panels for one level, with the colour-map ranges.
pub struct LevelPanels {
    /// Reprojection, grey.
    pub reprojection: egui::ColorImage,
    /// |input - reprojection| at full size.
    pub difference: (egui::ColorImage, [f64; 2]),
    /// Depth.
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

/// The CPU work of a level: panel images, then the mesh (coloured by the
/// reprojection error at the level's size).
fn prepare_level(job: MeshJob) -> BuiltMesh {
    use super::images;
    let difference = images::abs_difference(&job.reprojection, &job.image);
    let difference_range = [0.0, images::finite_range(&difference).map_or(1.0, |r| r[1])];
    let depth_range = images::finite_range(&job.depth).unwrap_or([0.0, 1.0]);
    let depth_error = job.ground_truth.as_ref().map(|gt| {
        let error = images::abs_difference(&job.depth, gt);
        let range = [0.0, images::finite_range(&error).map_or(1.0, |r| r[1])];
        (images::colour_mapped(&error, range), range)
    });
    let panels = LevelPanels {
        reprojection: images::grey_image(&job.reprojection),
        difference: (
            images::colour_mapped(&difference, difference_range),
            difference_range,
        ),
        depth: (images::colour_mapped(&job.depth, depth_range), depth_range),
        depth_error,
    };
    let level_difference = images::abs_difference(&job.image, &job.reprojection);
    let (depth, camera, values) = decimate(job.depth, job.camera, Some(level_difference));
    let mesh = SurfaceMesh::from_depth(&depth, &camera, values.as_ref());
    BuiltMesh {
        generation: job.generation,
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

/// Point-samples a large depth map (and its values) with a stride so that
/// the mesh stays below [`MAX_VIEW_VERTICES`]; scales the camera to match.
fn decimate(
    depth: Grid<f64>,
    camera: Intrinsics,
    values: Option<Grid<f64>>,
) -> (Grid<f64>, Intrinsics, Option<Grid<f64>>) {
    let (w, h) = depth.size();
    if w * h <= MAX_VIEW_VERTICES {
        return (depth, camera, values);
    }
    let stride = ((w * h) as f64 / MAX_VIEW_VERTICES as f64).sqrt().ceil() as usize;
    let (sw, sh) = (w.div_ceil(stride), h.div_ceil(stride));
    let sample = |g: &Grid<f64>| Grid::from_fn(sw, sh, |c, r| *g.at(c * stride, r * stride));
    let s = stride as f64;
    // Column c of the sampled grid is column c * stride of the original:
    // x = (c s - cx) / f = (c - cx / s) / (f / s).
    let camera = Intrinsics {
        focal_px: camera.focal_px / s,
        principal_x_px: camera.principal_x_px / s,
        principal_y_px: camera.principal_y_px / s,
    };
    (sample(&depth), camera, values.as_ref().map(sample))
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
    framed_bounds: Option<Bounds>,
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
    }

    /// Shows a new mesh; frames it the first time (later meshes keep the
    /// user's view).
    pub fn set_mesh(&mut self, built: BuiltMesh) -> Option<LevelPanels> {
        if self.framed_bounds.is_none() && !built.mesh.is_empty() {
            let bounds = built.mesh.bounds();
            self.camera = OrbitCamera::framing(&bounds);
            self.framed_bounds = Some(bounds);
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
            self.camera = OrbitCamera::framing(&mesh.bounds());
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
    fn decimation_keeps_geometry_consistent() {
        let (w, h) = (1920, 1080);
        let camera = Intrinsics::centred(1920.0, w, h);
        let depth = Grid::from_fn(w, h, |c, r| 2.0 + (c + r) as f64 * 1e-4);
        let (small, cam, _) = decimate(depth.clone(), camera, None);
        assert!(small.len() <= MAX_VIEW_VERTICES);
        let stride = w / small.width();
        // The same pixel back-projects to the same ray in both cameras.
        let (x0, y0) = camera.image_xy((10 * stride) as f64, (7 * stride) as f64);
        let (x1, y1) = cam.image_xy(10.0, 7.0);
        let p0 = camera.back_project(x0, y0, 2.0);
        let p1 = cam.back_project(x1, y1, 2.0);
        assert!(
            p0.iter().zip(p1).all(|(a, b)| (a - b).abs() < 1e-12),
            "{p0:?} {p1:?}"
        );
        assert_eq!(*small.at(10, 7), *depth.at(10 * stride, 7 * stride));
    }
}
