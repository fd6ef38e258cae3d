//! The viewer's panels: menu, status line, controls (camera, parameters,
//! mask tools, known distances, progress, export), the 2-D image panels and
//! the 3-D view; the energy plot is `energy_plot`'s.
//!
//! Each panel, and each section of the controls, is a child module adding
//! its own `impl Panels` block; this module holds what they share: the
//! actions, the frame's context, the panels' state and the file dialogs.

mod camera;
mod context;
mod controls;
mod image_panel;
mod known_distance;
mod mask;
mod menu;
mod params;
mod progress;
mod set_view;
mod status;
mod surface;
mod view_settings;

use std::path::PathBuf;

use eframe::egui;

use super::images;
use super::level_prep::BuiltMesh;
use super::session::Session;
use super::view3d::SurfaceView;
use crate::mask_edit::ImagePoint;
pub use context::{Action, Panel2d, UiContext};
use set_view::SetView;
use sfs_core::grid::Grid;

/// A drag in the image panel in progress.
enum Gesture {
    Stroke,
    Rectangle(ImagePoint),
    Lasso(Vec<ImagePoint>),
}

/// Textures of the 2-D panels.
#[derive(Default)]
struct Textures {
    /// The input as shown, with the display mapping it was built with.
    input: Option<(images::DisplayMapping, egui::TextureHandle)>,
    overlay: Option<(u64, egui::TextureHandle)>,
    /// What the last solve took out as shadow, keyed by its job's count.
    shadows: Option<(usize, egui::TextureHandle)>,
    /// Where the last solve grazes the view beside a brighter pixel, keyed
    /// by its job's count.
    contours: Option<(usize, egui::TextureHandle)>,
    reprojection: Option<egui::TextureHandle>,
    difference: Option<(egui::TextureHandle, [f64; 2])>,
    depth: Option<(egui::TextureHandle, [f64; 2])>,
    depth_error: Option<(egui::TextureHandle, [f64; 2])>,
}

/// The "Known distance" tool: picking a pixel in the input panel, the
/// photograph's pixel picked and the distance being typed for it, and why
/// the last pixel or distance was refused.
#[derive(Default)]
struct KnownDistanceTool {
    /// The next click in the input panel picks a pixel (no mask tool).
    picking: bool,
    /// The pixel picked (of the photograph), waiting for its distance.
    pending: Option<(usize, usize)>,
    /// The distance as typed.
    text: String,
    /// Why the last pixel or distance was refused.
    refused: Option<String>,
    /// The object's distance as typed (`None`: not being edited, show the
    /// document's).
    distance_text: Option<String>,
}

/// The panels' own state: which 2-D panel, its zoom and pan, the mask
/// gesture in progress, the known-distance tool, the textures, the hover
/// text and the 3-D view.
pub struct Panels {
    panel: Panel2d,
    zoom: f32,
    pan: egui::Vec2,
    gesture: Option<Gesture>,
    known: KnownDistanceTool,
    textures: Textures,
    hover: Option<String>,
    surface: SurfaceView,
    set: SetView,
}

/// A file dialog (kept behind one function: headless tests never open one).
fn pick_open(filters: &[(&str, &[&str])]) -> Option<PathBuf> {
    let mut dialog = rfd::FileDialog::new();
    for (name, extensions) in filters {
        dialog = dialog.add_filter(*name, extensions);
    }
    dialog.pick_file()
}

/// A folder dialog (behind one function, as [`pick_open`]).
fn pick_folder() -> Option<PathBuf> {
    rfd::FileDialog::new().pick_folder()
}

/// A save dialog with a suggested file name.
fn pick_save(name: &str, extension: &str) -> Option<PathBuf> {
    rfd::FileDialog::new()
        .set_file_name(name)
        .add_filter(extension, &[extension])
        .save_file()
}

const IMAGE_EXTENSIONS: &[&str] = &["png", "tif", "tiff", "jpg", "jpeg"];

/// The input image's texture, shown through `mapping`.
fn input_texture(
    ctx: &egui::Context,
    image: &Grid<f64>,
    mapping: images::DisplayMapping,
) -> egui::TextureHandle {
    images::load_texture(
        ctx,
        "input",
        mapping.image(image),
        egui::TextureOptions::NEAREST,
    )
}

impl Panels {
    /// Panels with the 3-D view (`Err`: why it is unavailable).
    pub fn new(surface_available: Result<(), String>) -> Self {
        Self {
            panel: Panel2d::Input,
            zoom: 1.0,
            pan: egui::Vec2::ZERO,
            gesture: None,
            known: KnownDistanceTool::default(),
            textures: Textures::default(),
            hover: None,
            surface: SurfaceView::new(surface_available),
            set: SetView::default(),
        }
    }

    /// Which layers the mask tools paint: the set-wide masks (`None`) or a
    /// set's photograph's own confidence.
    pub fn paint_photo(&self) -> Option<usize> {
        self.set.paint_photo
    }

    /// Chooses the layers the mask tools paint (see [`Self::paint_photo`]).
    pub fn set_paint_photo(&mut self, photo: Option<usize>) {
        self.set.paint_photo = photo;
        self.textures.overlay = None;
    }

    /// Selects a 2-D panel.
    pub fn show_panel(&mut self, panel: Panel2d) {
        self.panel = panel;
    }

    /// A mask gesture (stroke, rectangle, lasso) is in progress.
    pub fn gesture_in_progress(&self) -> bool {
        self.gesture.is_some()
    }

    /// Generation of the level shown in the 3-D view.
    pub fn level_generation(&self) -> Option<u64> {
        self.surface.generation()
    }

    /// A new document: forget the old one's textures and surface, show its
    /// input (with the session's display mapping).
    pub fn document_opened(&mut self, ctx: &egui::Context, session: &Session) {
        self.textures = Textures::default();
        self.known = KnownDistanceTool::default();
        self.set.clear();
        if session.document.as_ref().is_some_and(|d| d.set.is_none())
            && matches!(
                self.panel,
                Panel2d::Albedo
                    | Panel2d::Normals
                    | Panel2d::PhotoResidual
                    | Panel2d::SingleDifference
            )
        {
            self.panel = Panel2d::Input;
        }
        self.surface.clear();
        self.zoom = 1.0;
        self.pan = egui::Vec2::ZERO;
        self.input_texture(ctx, session);
    }

    /// The input's texture, rebuilt when the session's display mapping
    /// changed (or after the image was re-read).
    fn input_texture(
        &mut self,
        ctx: &egui::Context,
        session: &Session,
    ) -> Option<egui::TextureHandle> {
        let doc = session.document.as_ref()?;
        let mapping = session.display;
        match &self.textures.input {
            Some((built, texture)) if *built == mapping => Some(texture.clone()),
            _ => {
                let texture = input_texture(ctx, &doc.image, mapping);
                self.textures.input = Some((mapping, texture.clone()));
                Some(texture)
            }
        }
    }

    /// Shows a prepared level: its mesh and its panel images.
    pub fn show_level(&mut self, ctx: &egui::Context, built: BuiltMesh) {
        let Some(panels) = self.surface.set_mesh(built) else {
            return;
        };
        let options = egui::TextureOptions::NEAREST;
        self.textures.reprojection = Some(images::load_texture(
            ctx,
            "reprojection",
            panels.reprojection,
            options,
        ));
        let (difference, range) = panels.difference;
        self.textures.difference = Some((
            images::load_texture(ctx, "difference", difference, options),
            range,
        ));
        let (depth, range) = panels.depth;
        self.textures.depth = Some((images::load_texture(ctx, "depth", depth, options), range));
        self.textures.depth_error = panels.depth_error.map(|(image, range)| {
            (
                images::load_texture(ctx, "depth-error", image, options),
                range,
            )
        });
    }

    fn error_range(&self) -> f32 {
        self.textures
            .difference
            .as_ref()
            .map_or(1.0, |(_, r)| r[1] as f32)
    }

    /// The whole window: menu, status line, controls, the 3-D view and the
    /// 2-D image panel.
    pub fn ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui, cx));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui, cx));
        egui::Panel::left("controls")
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls_ui(ui, cx));
            });
        egui::Panel::right("view3d")
            .default_size(480.0)
            .resizable(true)
            .show(ui, |ui| self.view3d_ui(ui, cx));
        egui::CentralPanel::default().show(ui, |ui| self.image_panel_ui(ui, cx));
    }
}
