//! The bridge between egui and the wgpu surface renderer: a paint callback
//! that renders in `prepare` and blits in `paint`, and the 3-D view's
//! orbit/pan/zoom input and framing; its meshes come from `level_prep`.

use std::sync::Arc;

use eframe::egui;
use egui_wgpu::wgpu;

use super::level_prep::{BuiltMesh, LevelPanels};
use crate::render::{Bounds, ColourMode, OrbitCamera, SurfaceMesh, SurfaceRenderer, ViewSettings};

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
    /// aspect is known) the first time, and again when it has left what was
    /// framed (a set's surface can move along the rays between levels, as
    /// its distance is found): otherwise later meshes keep the user's view.
    pub fn set_mesh(&mut self, built: BuiltMesh) -> Option<LevelPanels> {
        if !built.mesh.is_empty() {
            let new = built.mesh.bounds();
            let moved = self.framed_bounds.as_ref().is_none_or(|old| {
                (new.centre_world - old.centre_world).length() > 0.5 * old.radius
                    || new.radius > 2.0 * old.radius
                    || new.radius < 0.5 * old.radius
            });
            if moved {
                self.framed_bounds = Some(new);
                self.needs_framing = true;
            }
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
        let scene = sfs_core::scene::sombrero::sombrero(96, 96);
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
}
