//! The viewer's panels: menu, status line, controls (camera, parameters,
//! mask tools, known distances, progress, export), the 2-D image panels and
//! the 3-D view; the energy plot is `energy_plot`'s.

use std::path::{Path, PathBuf};

use eframe::egui;

use super::document::{CameraSource, Document, KnownDistance};
use super::images;
use super::level_prep::BuiltMesh;
use super::session::{Export, Session};
use super::set_view::SetView;
use super::settings::{InitialChoice, Settings, SurfaceColour, Tool};
use super::view3d::SurfaceView;
use crate::mask_edit::{Brush, ImagePoint, Layer, Mode, OverlayStyle};
use sfs_core::grid::Grid;
use sfs_core::material::Material;
use sfs_core::params::{AlbedoChoice, PARAMS, ParamKind, ParamValue, SolverParams};
use sfs_core::photo::{PhotoInput, Vignetting};
use sfs_core::solver::{Solution, material_fit};

/// Which 2-D panel is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Panel2d {
    /// The input with the mask overlay (paint here).
    Input,
    /// The reprojected image of the latest level.
    Reprojection,
    /// `|input - reprojection|`.
    Difference,
    /// Depth with a colour map.
    Depth,
    /// `|depth - ground truth|` (with ground truth).
    DepthError,
    /// A set's albedo, grey.
    Albedo,
    /// A set's normals, normal-map colours.
    Normals,
    /// One photograph's residual under its own light (a set).
    PhotoResidual,
    /// The depth of one photograph solved alone against the set's.
    SingleDifference,
}

/// What the panels ask the app to do after the frame (what needs more
/// than the document being edited: files, the worker, the window).
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Open an image (or a set folder).
    Open(PathBuf),
    /// Open several photographs (or a folder) as one photometric-stereo set.
    OpenSet(Vec<PathBuf>),
    /// Solve photograph `index` of the set alone and compare.
    SolveSingle(usize),
    /// The same with the set's albedo divided out of the photograph first.
    SolveSingleWithSetAlbedo(usize),
    /// Apply a camera file.
    LoadCamera(PathBuf),
    /// Load a mask PNG into a layer.
    LoadMask(Layer, PathBuf),
    /// Save a mask layer as PNG.
    SaveMask(Layer, PathBuf),
    /// Export the finished result.
    Export(PathBuf, Export),
    /// Save a screenshot of the window.
    Screenshot(PathBuf),
    /// Cancel the running solve.
    CancelSolve,
    /// Solve now.
    SolveNow,
    /// Parameters or the camera changed: solve after the debounce.
    RequestSolve,
    /// Show a message on the status line.
    Notice(String),
    /// Clear the status line's message.
    DismissNotice,
    /// Lower the confidence where the model cannot hold (one undo step).
    SuggestConfidence,
}

/// What the panels read and edit in one frame, and where they put what the
/// app must do.
pub struct UiContext<'a> {
    /// The document and its solve (masks and camera are edited in place).
    pub session: &'a mut Session,
    /// Persisted settings (edited in place).
    pub settings: &'a mut Settings,
    /// The status line's message.
    pub notice: Option<&'a str>,
    /// Actions for the app, run after the frame.
    pub actions: &'a mut Vec<Action>,
}

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

    pub(super) fn menu_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open image…").clicked()
                    && let Some(path) = pick_open(&[("images", IMAGE_EXTENSIONS)])
                {
                    cx.actions.push(Action::Open(path));
                }
                if ui
                    .button("Open photometric set (folder)…")
                    .on_hover_text(
                        "A folder whose scene.json or calibration.json names each photograph \
                         by its light (`image`): the photographs open as one set, with the \
                         folder's mask.png and ambient.png",
                    )
                    .clicked()
                    && let Some(folder) = pick_folder()
                {
                    cx.actions.push(Action::OpenSet(vec![folder]));
                }
                if ui.button("Open built-in sample").clicked()
                    && let Some(path) = super::sample_image_path()
                {
                    cx.actions.push(Action::Open(path));
                }
                if ui.button("Load camera file…").clicked()
                    && let Some(path) = pick_open(&[("camera JSON", &["json"])])
                {
                    cx.actions.push(Action::LoadCamera(path));
                }
                ui.menu_button("Recent files", |ui| {
                    let recent = cx.settings.recent_files.clone();
                    if recent.is_empty() {
                        ui.label("none yet");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).clicked() {
                            cx.actions.push(Action::Open(path));
                        }
                    }
                });
                ui.separator();
                self.export_menu_ui(ui, cx);
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                }
            });
            ui.menu_button("Edit", |ui| {
                let (can_undo, can_redo) = cx
                    .session
                    .document
                    .as_ref()
                    .map_or((false, false), |d| (d.masks.can_undo(), d.masks.can_redo()));
                if ui
                    .add_enabled(can_undo, egui::Button::new("Undo mask edit (Ctrl+Z)"))
                    .clicked()
                    && let Some(doc) = &mut cx.session.document
                {
                    doc.masks.undo();
                }
                if ui
                    .add_enabled(can_redo, egui::Button::new("Redo (Ctrl+Shift+Z)"))
                    .clicked()
                    && let Some(doc) = &mut cx.session.document
                {
                    doc.masks.redo();
                }
            });
        });
    }

    fn export_menu_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let has_result = cx.session.solve.finished.is_some();
        let name = cx
            .session
            .document
            .as_ref()
            .and_then(|d| d.path.file_stem())
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "result".into());
        ui.add_enabled_ui(has_result, |ui| {
            if ui.button("Export depth (.npy)…").clicked()
                && let Some(path) = pick_save(&format!("{name}-depth.npy"), "npy")
            {
                cx.actions.push(Action::Export(path, Export::DepthNpy));
            }
            if ui.button("Export depth (16-bit PNG)…").clicked()
                && let Some(path) = pick_save(&format!("{name}-depth16.png"), "png")
            {
                cx.actions.push(Action::Export(path, Export::DepthPng));
            }
            if ui.button("Export mesh (.ply)…").clicked()
                && let Some(path) = pick_save(&format!("{name}.ply"), "ply")
            {
                cx.actions.push(Action::Export(path, Export::MeshPly));
            }
            if ui.button("Export mesh (.obj)…").clicked()
                && let Some(path) = pick_save(&format!("{name}.obj"), "obj")
            {
                cx.actions.push(Action::Export(path, Export::MeshObj));
            }
            if ui.button("Export reprojection (16-bit PNG)…").clicked()
                && let Some(path) = pick_save(&format!("{name}-reprojection.png"), "png")
            {
                cx.actions.push(Action::Export(path, Export::Reprojection));
            }
        });
        if ui.button("Save window screenshot…").clicked()
            && let Some(path) = pick_save(&format!("{name}-screenshot.png"), "png")
        {
            cx.actions.push(Action::Screenshot(path));
        }
        let has_doc = cx.session.document.is_some();
        ui.add_enabled_ui(has_doc, |ui| {
            for (label, layer, file) in [
                ("Save confidence mask…", Layer::Confidence, "confidence.png"),
                ("Save object mask…", Layer::Object, "mask.png"),
            ] {
                if ui.button(label).clicked()
                    && let Some(path) = pick_save(file, "png")
                {
                    cx.actions.push(Action::SaveMask(layer, path));
                }
            }
            for (label, layer) in [
                ("Load confidence mask…", Layer::Confidence),
                ("Load object mask…", Layer::Object),
            ] {
                if ui.button(label).clicked()
                    && let Some(path) = pick_open(&[("mask PNG", &["png"])])
                {
                    cx.actions.push(Action::LoadMask(layer, path));
                }
            }
        });
    }

    pub(super) fn status_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        ui.horizontal(|ui| {
            if let Some(doc) = &cx.session.document {
                let (w, h) = doc.size();
                ui.label(format!("{} ({w}x{h})", doc.path.display()));
                ui.separator();
            }
            if let Some(hover) = &self.hover {
                ui.monospace(hover);
                ui.separator();
            }
            if let Some(notice) = cx.notice.map(str::to_string) {
                ui.colored_label(ui.visuals().warn_fg_color, notice);
                if ui.small_button("x").on_hover_text("dismiss").clicked() {
                    cx.actions.push(Action::DismissNotice);
                }
            }
        });
    }

    pub(super) fn controls_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        self.progress_ui(ui, cx);
        ui.separator();
        let is_set = cx
            .session
            .document
            .as_ref()
            .is_some_and(|d| d.set.is_some());
        if is_set {
            egui::CollapsingHeader::new("Photometric stereo")
                .default_open(true)
                .show(ui, |ui| self.set.controls_ui(ui, cx));
        }
        egui::CollapsingHeader::new(if is_set {
            "Parameters (single-image method)"
        } else {
            "Parameters"
        })
        .default_open(!is_set)
        .show(ui, |ui| self.params_ui(ui, cx));
        egui::CollapsingHeader::new("Mask")
            .default_open(true)
            .show(ui, |ui| self.mask_ui(ui, cx));
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| self.camera_ui(ui, cx));
        egui::CollapsingHeader::new("Known distance")
            .default_open(true)
            .show(ui, |ui| self.known_distance_ui(ui, cx));
        egui::CollapsingHeader::new("3-D view")
            .default_open(true)
            .show(ui, |ui| self.view_settings_ui(ui, cx));
    }

    fn progress_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let s = &cx.session.solve;
        let running = s.running;
        // `auto`: the material is fitted before the solve reports anything.
        let fitting = s.running
            && s.energies.is_empty()
            && cx.settings.params.to_params().fixed_material().is_none();
        ui.horizontal(|ui| {
            if fitting {
                ui.spinner();
                ui.label(format!(
                    "fitting the reflectance ({} solves on a {} px copy)",
                    material_fit::candidates().len(),
                    material_fit::FIT_SIDE
                ))
                .on_hover_text(
                    "reflectance auto: every candidate material is solved on a coarse copy \
                     of the image and their energies compared; the solve follows",
                );
            } else if s.running {
                ui.spinner();
                let p = &s.progress;
                ui.label(format!(
                    "level {} of {} ({}x{}), iteration {}",
                    p.level + 1,
                    p.levels.max(1),
                    p.size.0,
                    p.size.1,
                    p.iteration + 1
                ));
                let searching = cx
                    .session
                    .document
                    .as_ref()
                    .is_some_and(|d| !d.known_depths.is_empty());
                if searching && s.search_solve > 0 {
                    ui.label(format!("(scale search, solve {})", s.search_solve))
                        .on_hover_text(
                            "The depth scale is searched until the surface meets the known \
                             distances: each solve runs through the levels again",
                        );
                }
            } else if let Some(done) = &s.finished {
                ui.label(format!("done in {:.2} s", done.seconds));
            } else if let Some(done) = &s.set {
                ui.label(format!("set done in {:.2} s", done.seconds));
            } else if s.failure.is_some() {
                ui.colored_label(ui.visuals().error_fg_color, "solve failed");
            } else {
                ui.label("idle");
            }
        });
        if s.running {
            ui.label(format!(
                "energy per pixel {:.4e}, {:.2} s",
                s.progress.energy_per_pixel,
                s.progress.elapsed.as_secs_f64()
            ));
        }
        if let Some((rse, rie)) = s.errors {
            ui.label(format!("against ground truth: RSE {rse:.5}, RIE {rie:.5}"));
        }
        let units = cx
            .session
            .document
            .as_ref()
            .map_or("depth units", |d| d.depth_units())
            .to_owned();
        fit_line(ui, s, &units);
        if let Some(share) = s.shadow_share {
            ui.label(format!(
                "shadow: {:.1} % of the object taken out of the data term",
                100.0 * share
            ))
            .on_hover_text(
                "no light reaches these pixels (near-black against the image's reference \
                 brightness and its noise): they say the surface is turned away or hidden, \
                 not how bright it is; the fill continues the lit surface there. \
                 Mask > shadows shows them in violet.",
            );
        }
        if let Some(s_used) = s.intensity_scale_used {
            ui.weak(format!("intensity scale used: {s_used:.4e}"));
        }
        if let Some(solution) = &s.finished {
            material_ui(ui, solution);
        }
        if let Some(fit) = &s.known_depth_fit {
            ui.label(fit_summary(fit)).on_hover_text(
                "The intensity scale s that puts the surface at the known distances (relative \
                 least squares); residuals: (solved - given) / given at each point",
            );
        }
        if let Some(failure) = &s.failure {
            ui.colored_label(ui.visuals().error_fg_color, failure.clone());
        }
        ui.horizontal(|ui| {
            if ui
                .add_enabled(running, egui::Button::new("Cancel"))
                .clicked()
            {
                cx.actions.push(Action::CancelSolve);
            }
            if ui.button("Solve again").clicked() {
                cx.actions.push(Action::SolveNow);
            }
        });
        super::energy_plot::energy_plot(ui, &cx.session.solve.energies);
    }

    fn params_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let defaults = SolverParams::default();
        let mut p = cx.settings.params.to_params();
        let chosen_alpha = cx.session.solve.finished.as_ref().map(|s| s.alpha);
        let mut changed = false;
        let mut estimate_albedo = p.albedo == AlbedoChoice::Auto;
        if ui
            .checkbox(&mut estimate_albedo, "estimate the albedo")
            .on_hover_text(
                "Albedo auto: dark marks (brows, text, paint) estimated as albedo with the \
                 shape and used where they explain the photograph better than albedo 1; \
                 'albedo edge' is its prior's weight. Off: all brightness is shading.",
            )
            .changed()
        {
            p.albedo = if estimate_albedo {
                AlbedoChoice::Auto
            } else {
                AlbedoChoice::One
            };
            changed = true;
        }
        if let Some(fit) = cx
            .session
            .solve
            .finished
            .as_ref()
            .and_then(|s| s.albedo_fit.as_ref())
        {
            let text = egui::RichText::new(&fit.summary).small();
            let text = if fit.is_close_call() {
                text.color(ui.visuals().warn_fg_color)
            } else {
                text
            };
            ui.label(text)
                .on_hover_text("How the albedo estimate compared with albedo 1 on this solve");
        }
        for spec in PARAMS {
            // A model's own parameters only while it is chosen.
            let Some((low, high)) = spec.slider.filter(|_| p.applies(spec.name)) else {
                continue;
            };
            let tooltip = format!("{} Default: {}.", spec.help, (spec.get)(&defaults));
            let value = (spec.get)(&p);
            match (spec.kind, value) {
                (ParamKind::Choice(words), ParamValue::Choice(chosen)) => {
                    // One line, labelled on the right as the sliders are.
                    let mut picked = chosen;
                    egui::ComboBox::from_label(spec.label)
                        .selected_text(chosen)
                        .show_ui(ui, |ui| {
                            for &word in words {
                                ui.selectable_value(&mut picked, word, word);
                            }
                        })
                        .response
                        .on_hover_text(tooltip.as_str());
                    if picked != chosen {
                        (spec.set)(&mut p, ParamValue::Choice(picked));
                        changed = true;
                    }
                }
                (ParamKind::Real { log, auto, .. }, value) => {
                    let mut number = match value {
                        ParamValue::Real(v) => v,
                        // Auto shows the value the last solve chose.
                        _ => chosen_alpha.filter(|a| a.is_finite()).unwrap_or(low),
                    };
                    ui.horizontal(|ui| {
                        if auto {
                            let mut is_auto = value == ParamValue::Auto;
                            if ui
                                .checkbox(&mut is_auto, "auto")
                                .on_hover_text("Let the solver choose from the image's noise level; the slider shows its choice")
                                .changed()
                            {
                                let new = if is_auto {
                                    ParamValue::Auto
                                } else {
                                    ParamValue::Real(number)
                                };
                                (spec.set)(&mut p, new);
                                changed = true;
                            }
                        }
                        if ui
                            .add(
                                egui::Slider::new(&mut number, low..=high)
                                    .logarithmic(log)
                                    .custom_formatter(|v, _| slider_number(v))
                                    .text(spec.label),
                            )
                            .on_hover_text(tooltip.as_str())
                            .changed()
                        {
                            (spec.set)(&mut p, ParamValue::Real(number));
                            changed = true;
                        }
                    });
                }
                (ParamKind::Count { .. }, ParamValue::Count(mut count)) => {
                    let range = (low as usize)..=(high as usize);
                    if ui
                        .add(egui::Slider::new(&mut count, range).text(spec.label))
                        .on_hover_text(tooltip.as_str())
                        .changed()
                    {
                        (spec.set)(&mut p, ParamValue::Count(count));
                        changed = true;
                    }
                }
                _ => {}
            }
        }
        let lights_off_centre = cx
            .session
            .document
            .as_ref()
            .is_some_and(|d| !sfs_core::light::is_centred(&d.camera.solve_lights()));
        let [fast_marching, from_image] = start_labels(lights_off_centre);
        let initial = &mut cx.settings.params.initial_depth;
        let before = *initial;
        ui.horizontal_wrapped(|ui| {
            ui.label("start")
                .on_hover_text("Initial depth: fast marching refined at full resolution (default), the paper's constant depth from the brightest pixel, or a constant, each followed by the solver. With lights off the optical centre fast marching runs in the lights' own frame (within 20 degrees of the camera and a third of the way to the object), else from the best-fitting plane; the paper's start is that plane");
            ui.selectable_value(initial, InitialChoice::FastMarching, fast_marching.0)
                .on_hover_text(fast_marching.1);
            ui.selectable_value(initial, InitialChoice::FromImage, from_image.0)
                .on_hover_text(from_image.1);
            if ui
                .selectable_label(matches!(initial, InitialChoice::Constant(_)), "constant")
                .clicked()
                && !matches!(initial, InitialChoice::Constant(_))
            {
                *initial = InitialChoice::Constant(1.0);
            }
            if let InitialChoice::Constant(z) = initial {
                let label = ui.label("depth").id;
                ui.add(egui::DragValue::new(z).range(1e-3..=1e6).speed(0.01))
                    .labelled_by(label);
            }
        });
        if *initial != before {
            p.initial_depth = cx.settings.params.to_params().initial_depth;
            changed = true;
        }
        if ui
            .button("defaults")
            .on_hover_text("Restore every parameter to its default (alpha auto)")
            .clicked()
        {
            p = SolverParams {
                albedo: AlbedoChoice::Auto,
                ..SolverParams::default()
            };
            changed = true;
        }
        if changed {
            cx.settings.params = super::ParamSettings::from_params(&p);
            cx.actions.push(Action::RequestSolve);
        }
    }

    fn mask_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let names = cx
            .session
            .document
            .as_ref()
            .and_then(|d| d.set.as_ref())
            .map(|s| s.names());
        if let Some(names) = &names {
            let before = self.set.paint_photo;
            self.set.paint_selector_ui(ui, names);
            if self.set.paint_photo != before {
                self.textures.overlay = None;
            }
        }
        let own_layer = self.set.paint_photo.is_some() && names.is_some();
        let b = &mut cx.settings.brush;
        if own_layer {
            // A photograph's own layer holds confidence only.
            b.layer = Layer::Confidence;
        }
        ui.add_enabled_ui(!own_layer, |ui| {
            ui.horizontal(|ui| {
                ui.label("paint into");
                ui.selectable_value(&mut b.layer, Layer::Confidence, "confidence")
                    .on_hover_text("c = 0 where painted: the data term is not trusted there");
                ui.selectable_value(&mut b.layer, Layer::Object, "object")
                    .on_hover_text("painted pixels are background: no surface there");
            })
        });
        ui.horizontal(|ui| {
            ui.selectable_value(&mut b.mode, Mode::Paint, "paint");
            ui.selectable_value(&mut b.mode, Mode::Erase, "erase");
        });
        ui.horizontal(|ui| {
            for (tool, name) in [
                (Tool::Brush, "brush"),
                (Tool::Rectangle, "rectangle"),
                (Tool::Lasso, "lasso"),
                (Tool::FloodFill, "flood fill"),
            ] {
                ui.selectable_value(&mut b.tool, tool, name);
            }
        });
        ui.add(
            egui::Slider::new(&mut b.radius_px, 0.5..=200.0)
                .logarithmic(true)
                .text("brush size (px)"),
        );
        ui.add(egui::Slider::new(&mut b.hardness, 0.0..=1.0).text("hardness"));
        ui.add(egui::Slider::new(&mut b.flood_tolerance, 0.0..=0.5).text("flood tolerance"));
        ui.add(egui::Slider::new(&mut b.overlay_opacity, 0.0..=1.0).text("overlay opacity"));
        ui.checkbox(&mut b.show_shadows, "shadows")
            .on_hover_text("show in violet what the last solve took out of the data term as shadow (no light reaches it)");
        ui.checkbox(&mut b.show_contours, "contours").on_hover_text(
            "show in orange where the last solve grazes the view beside a much brighter pixel: \
             an occluding contour (what lies behind it was joined to it) or a dark mark read as \
             a slope",
        );
        let layer = b.layer;
        let threshold = &mut b.threshold;
        let paint_photo = self.set.paint_photo;
        let Some(doc) = &mut cx.session.document else {
            return;
        };
        ui.horizontal(|ui| {
            let (masks, _) = doc.paint_target(paint_photo);
            if ui.button("clear").clicked() {
                masks.clear(layer);
            }
            if ui.button("invert").clicked() {
                masks.invert(layer);
            }
            if ui
                .add_enabled(masks.can_undo(), egui::Button::new("undo"))
                .clicked()
            {
                masks.undo();
            }
            if ui
                .add_enabled(masks.can_redo(), egui::Button::new("redo"))
                .clicked()
            {
                masks.redo();
            }
        });
        if ui
            .button("suggest confidence")
            .on_hover_text(
                "Lower the confidence where the model cannot hold: saturated highlights, \
                 near-black pixels, cast shadows (darker than half the model's prediction \
                 after a solve, else than their surroundings) and the silhouette band. \
                 One undo step: undo to reject, erase or paint over to edit.",
            )
            .clicked()
        {
            cx.actions.push(Action::SuggestConfidence);
        }
        ui.horizontal(|ui| {
            ui.add(
                egui::Slider::new(threshold, 0.0..=0.5)
                    .logarithmic(true)
                    .text("threshold"),
            );
            if ui
                .button("object = brighter")
                .on_hover_text(
                    "Set the object mask: pixels darker than the threshold are background",
                )
                .clicked()
                && let Err(e) = doc.masks.threshold(&doc.image, *threshold)
            {
                cx.actions.push(Action::Notice(e.to_string()));
            }
        });
    }

    /// The "Known distance" section: "Set distance" picks a pixel of the
    /// object in the input panel, a typed distance confirms it; the points
    /// with, after a solve, their solved depth and residual; remove one or
    /// all. Each change re-solves (the session asks for it).
    fn known_distance_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let Some(doc) = &cx.session.document else {
            ui.label("no image");
            return;
        };
        if doc.set.is_some() {
            ui.weak(
                "not for a set: a photometric-stereo set's depth is metric from its lights' \
                 positions",
            );
            return;
        }
        let units = doc.depth_units().to_owned();
        let points: Vec<(KnownDistance, (f64, f64))> = doc
            .known_depths
            .iter()
            .map(|p| (*p, doc.working_pixel(p.column_px, p.row_px)))
            .collect();
        let tool = &mut self.known;
        let current = doc.object_distance;
        let mut distance_outcome = None;
        ui.horizontal(|ui| {
            let label = ui
                .label("object distance")
                .on_hover_text(
                    "How far the object is from the camera, roughly (its median depth): sets \
                     the depth unit without picking a pixel. Known distances at pixels, when \
                     given, are used instead.",
                )
                .id;
            let text = tool
                .distance_text
                .get_or_insert_with(|| current.map(significant).unwrap_or_default());
            let edit = ui
                .add(
                    egui::TextEdit::singleline(text)
                        .desired_width(70.0)
                        .hint_text("e.g. 650"),
                )
                .labelled_by(label);
            ui.label(&units);
            let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            if ui.button("Set").clicked() || entered {
                let typed = text.trim().to_owned();
                distance_outcome = Some(if typed.is_empty() {
                    Ok(None)
                } else {
                    typed.parse::<f64>().map(Some).map_err(|_| {
                        format!("\"{typed}\" is not a number: type the distance in {units}")
                    })
                });
            }
            if current.is_some() && ui.button("Clear").clicked() {
                distance_outcome = Some(Ok(None));
                tool.distance_text = Some(String::new());
            }
        });
        if current.is_some() && !points.is_empty() {
            ui.weak("not used: the known distances at pixels set the depth unit");
        }
        if let Some(outcome) = distance_outcome {
            match outcome.and_then(|d| cx.session.set_object_distance(d)) {
                Ok(note) => {
                    tool.refused = None;
                    if let Some(note) = note {
                        cx.actions.push(Action::Notice(note));
                    }
                }
                Err(reason) => tool.refused = Some(reason),
            }
        }
        ui.horizontal_wrapped(|ui| {
            if ui
                .selectable_label(tool.picking, "Set distance")
                .on_hover_text(
                    "Then click a pixel of the object in the input panel and type how far it \
                     is from the camera (depth along the optical axis): the depth scale \
                     follows the distances you know",
                )
                .clicked()
            {
                tool.picking = !tool.picking;
                tool.refused = None;
                if tool.picking {
                    self.panel = Panel2d::Input;
                }
            }
            if tool.picking {
                ui.weak("click a pixel of the object in the input panel");
            }
        });
        let mut confirm = false;
        if let Some((x, y)) = tool.pending {
            ui.horizontal(|ui| {
                ui.label(format!("pixel ({x}, {y})"));
                let label = ui.label("distance").id;
                let edit = ui
                    .add(
                        egui::TextEdit::singleline(&mut tool.text)
                            .desired_width(70.0)
                            .hint_text("e.g. 350"),
                    )
                    .labelled_by(label);
                ui.label(&units);
                let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                if ui.button("OK").clicked() || entered {
                    confirm = true;
                }
                if ui.button("Cancel").clicked() {
                    tool.pending = None;
                    tool.refused = None;
                }
            });
        }
        if confirm && let Some((x, y)) = tool.pending {
            let typed = tool.text.trim();
            let outcome = match typed.parse::<f64>() {
                Ok(depth) => cx.session.set_known_depth(x, y, depth),
                Err(_) => Err(format!(
                    "\"{typed}\" is not a number: type the distance in {units}"
                )),
            };
            match outcome {
                Ok(note) => {
                    tool.pending = None;
                    tool.text.clear();
                    tool.refused = None;
                    if let Some(note) = note {
                        cx.actions.push(Action::Notice(note));
                    }
                }
                Err(reason) => tool.refused = Some(reason),
            }
        }
        if let Some(reason) = &tool.refused {
            ui.colored_label(ui.visuals().error_fg_color, reason);
        }
        if points.is_empty() {
            ui.weak("none: the depth scale comes from the camera file or the image");
            return;
        }
        let fit = cx.session.solve.known_depth_fit.as_ref();
        let mut remove = None;
        egui::Grid::new("known distances")
            .num_columns(3)
            .striped(true)
            .show(ui, |ui| {
                for (index, (point, (c, r))) in points.iter().enumerate() {
                    ui.label(format!("({}, {})", point.column_px, point.row_px));
                    let solved = fit.and_then(|f| {
                        f.points
                            .iter()
                            .find(|q| q.column_px == *c && q.row_px == *r && q.given == point.depth)
                    });
                    let text = match solved {
                        Some(q) => format!(
                            "{} {units}, solved {} ({:+.2} %)",
                            significant(point.depth),
                            significant(q.solved),
                            100.0 * q.relative_residual
                        ),
                        None => format!("{} {units}", significant(point.depth)),
                    };
                    ui.label(text);
                    if ui
                        .small_button("remove")
                        .on_hover_text("Forget this distance")
                        .clicked()
                    {
                        remove = Some(index);
                    }
                    ui.end_row();
                }
            });
        let mut note = None;
        if let Some(index) = remove {
            note = cx.session.remove_known_depth(index);
        }
        if ui.button("clear all").clicked() {
            note = cx.session.clear_known_depths();
        }
        if let Some(note) = note {
            cx.actions.push(Action::Notice(note));
        }
    }

    fn camera_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let Some(doc) = &mut cx.session.document else {
            ui.label("no image");
            return;
        };
        let (w, _) = doc.size();
        let c = &mut doc.camera;
        let mut changed = false;
        changed |= ui
            .add(
                egui::Slider::new(&mut c.focal_px, 1.0..=20000.0)
                    .logarithmic(true)
                    .text("focal (px)"),
            )
            .changed();
        ui.label(format!(
            "horizontal field of view {:.1}°",
            c.horizontal_fov_deg(w)
        ));
        ui.horizontal(|ui| {
            let label = ui.label("principal point").id;
            changed |= ui
                .add(egui::DragValue::new(&mut c.cx_px).speed(0.5).prefix("x "))
                .labelled_by(label)
                .changed();
            changed |= ui
                .add(egui::DragValue::new(&mut c.cy_px).speed(0.5).prefix("y "))
                .labelled_by(label)
                .changed();
        });
        let scale_changed = ui
            .add(
                egui::Slider::new(&mut c.intensity_scale, 1e-3..=1e6)
                    .logarithmic(true)
                    .text("intensity scale"),
            )
            .changed();
        if scale_changed {
            c.scale_given = true;
        }
        changed |= scale_changed;
        if c.use_lights && !c.scale_given && c.lights.iter().any(|l| !l.is_centred()) {
            ui.weak("intensity scale: estimated at each solve (lights off the centre)");
        }
        if c.lights.is_empty() {
            ui.weak("light: at the optical centre (the paper's)");
        } else {
            for (k, light) in c.lights.iter().enumerate() {
                ui.weak(format!(
                    "light {}: ({:.1}, {:.1}, {:.1}){}",
                    k + 1,
                    light.position[0],
                    light.position[1],
                    light.position[2],
                    if light.direction.is_some() && light.mu > 0.0 {
                        format!(", mu {}", light.mu)
                    } else {
                        String::new()
                    }
                ));
            }
            changed |= ui
                .checkbox(&mut c.use_lights, "solve with the lights where they are")
                .on_hover_text(
                    "Off: the paper's light at the optical centre, to compare. With lights \
                     off the centre depth is metric: set the intensity scale (solve \
                     --intensity-scale auto estimates it).",
                )
                .changed();
        }
        if changed {
            c.source = CameraSource::Manual;
        }
        ui.weak(c.source.describe());
        let mut srgb = doc.srgb;
        let mut reread = false;
        if ui
            .checkbox(&mut srgb, "sRGB photograph (linearise)")
            .changed()
        {
            match doc.set_srgb(srgb) {
                Ok(()) => {
                    changed = true;
                    reread = true;
                    self.textures.input = None;
                }
                Err(e) => cx.actions.push(Action::Notice(format!("{e:#}"))),
            }
        }
        ui.weak(&doc.srgb_reason);
        if self.corrections_ui(ui, doc, cx.actions) {
            changed = true;
            reread = true;
        }
        let (w, h) = doc.size();
        if (w, h) != doc.full_size {
            ui.weak(format!(
                "working at {w}x{h} of {}x{}",
                doc.full_size.0, doc.full_size.1
            ));
        }
        let path = doc.path.clone();
        ui.horizontal(|ui| {
            ui.add(
                egui::DragValue::new(&mut cx.settings.max_side)
                    .range(0..=20000)
                    .speed(10.0)
                    .prefix("working size "),
            )
            .on_hover_text(
                "Longest side photographs are solved at (area averaging; 0 = full size). \
                 Applies when an image is opened.",
            );
            if ui
                .button("reopen")
                .on_hover_text("Open this image again at the working size (masks start anew)")
                .clicked()
            {
                cx.actions.push(Action::Open(path));
            }
        });
        if changed {
            cx.actions.push(Action::RequestSolve);
        }
        if reread {
            cx.session.refresh_display();
        }
    }

    /// The photograph's corrections (ambient frame, vignetting, albedo):
    /// each change reads the image again through the photo pipeline, the
    /// masks stay. Returns whether the image changed.
    fn corrections_ui(
        &mut self,
        ui: &mut egui::Ui,
        doc: &mut Document,
        actions: &mut Vec<Action>,
    ) -> bool {
        type Change = Box<dyn FnOnce(&mut PhotoInput)>;
        let mut change: Option<Change> = None;
        fn name(path: &Path) -> String {
            path.file_name().map_or_else(
                || path.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        }
        let images = [("image", IMAGE_EXTENSIONS)];
        ui.horizontal(|ui| {
            ui.label("ambient frame");
            match &doc.input.ambient {
                Some(path) => {
                    ui.weak(name(path))
                        .on_hover_text(path.display().to_string());
                    if ui.small_button("clear").clicked() {
                        change = Some(Box::new(|input| input.ambient = None));
                    }
                }
                None => {
                    ui.weak("none");
                }
            }
            if ui
                .small_button("choose…")
                .on_hover_text(
                    "A photograph with every light off (same exposure), subtracted from the image",
                )
                .clicked()
                && let Some(path) = pick_open(&images)
            {
                change = Some(Box::new(move |input| input.ambient = Some(path)));
            }
        });
        if doc.input.ambient.is_some() && doc.report.ambient_clamped_share > 0.0 {
            ui.weak(format!(
                "{:.1} % of pixels darker than the ambient frame (set to 0)",
                100.0 * doc.report.ambient_clamped_share
            ));
        }
        let current = match &doc.input.vignetting {
            Vignetting::None => "none".to_owned(),
            Vignetting::Cos4 => "cos⁴ (pinhole fall-off)".to_owned(),
            Vignetting::FlatField(path) => format!("flat field {}", name(path)),
        };
        egui::ComboBox::from_label("vignetting")
            .selected_text(current)
            .show_ui(ui, |ui| {
                if ui
                    .selectable_label(doc.input.vignetting == Vignetting::None, "none")
                    .clicked()
                {
                    change = Some(Box::new(|input| input.vignetting = Vignetting::None));
                }
                if ui
                    .selectable_label(
                        doc.input.vignetting == Vignetting::Cos4,
                        "cos⁴ (pinhole fall-off)",
                    )
                    .clicked()
                {
                    change = Some(Box::new(|input| input.vignetting = Vignetting::Cos4));
                }
                if ui
                    .selectable_label(
                        matches!(doc.input.vignetting, Vignetting::FlatField(_)),
                        "flat field…",
                    )
                    .on_hover_text("A photograph of a uniform white target, divided out")
                    .clicked()
                    && let Some(path) = pick_open(&images)
                {
                    change = Some(Box::new(move |input| {
                        input.vignetting = Vignetting::FlatField(path);
                    }));
                }
            });
        ui.horizontal(|ui| {
            ui.label("albedo");
            match &doc.input.albedo {
                Some(path) => {
                    ui.weak(name(path))
                        .on_hover_text(path.display().to_string());
                    if ui.small_button("clear").clicked() {
                        change = Some(Box::new(|input| input.albedo = None));
                    }
                }
                None => {
                    ui.weak("none (uniform)");
                }
            }
            if ui
                .small_button("choose…")
                .on_hover_text(
                    "A known albedo map (linear, relative), divided out; pixels below 0.02 \
                     are not trusted",
                )
                .clicked()
                && let Some(path) = pick_open(&images)
            {
                change = Some(Box::new(move |input| input.albedo = Some(path)));
            }
        });
        let Some(change) = change else {
            return false;
        };
        match doc.reread(change) {
            Ok(()) => {
                self.textures.input = None;
                true
            }
            Err(e) => {
                actions.push(Action::Notice(format!("{e:#}")));
                false
            }
        }
    }

    fn view_settings_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let v = &mut cx.settings.view;
        ui.horizontal(|ui| {
            ui.selectable_value(&mut v.colour, SurfaceColour::Shaded, "shaded");
            ui.selectable_value(&mut v.colour, SurfaceColour::Depth, "depth");
            ui.selectable_value(&mut v.colour, SurfaceColour::Error, "error");
        });
        ui.checkbox(&mut v.wireframe, "wireframe");
        // A set, or a single photograph solved with the albedo estimated.
        let has_albedo = cx
            .session
            .document
            .as_ref()
            .is_some_and(|d| d.set.is_some())
            || cx
                .session
                .solve
                .finished
                .as_ref()
                .is_some_and(|s| s.albedo_fit.is_some());
        ui.horizontal(|ui| {
            ui.checkbox(&mut v.photo_texture, "texture").on_hover_text(
                "Show the input image (a set: the photographs' mean) or the albedo on the \
                     surface instead of the shading or colour map",
            );
            ui.add_enabled_ui(v.photo_texture && has_albedo, |ui| {
                ui.selectable_value(&mut v.albedo_texture, false, "photograph");
                ui.selectable_value(&mut v.albedo_texture, true, "albedo")
                    .on_hover_text(
                        "a set's albedo, or the albedo a single photograph was solved with \
                         ('estimate the albedo'), once it is solved",
                    );
            });
        });
        ui.add(egui::Slider::new(&mut v.light_yaw_deg, -80.0..=80.0).text("light yaw (°)"));
        ui.add(egui::Slider::new(&mut v.light_pitch_deg, -80.0..=80.0).text("light pitch (°)"));
        if ui.button("reset view").clicked() {
            self.surface.reset();
        }
    }

    pub(super) fn view3d_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        ui.heading("3-D surface");
        ui.weak("drag: orbit · right-drag: pan · scroll: zoom · double-click: reset");
        let range = self.error_range();
        let prefs = cx.settings.view.clone();
        self.surface.ui(ui, &prefs, range);
    }

    pub(super) fn image_panel_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let set_names = cx
            .session
            .document
            .as_ref()
            .and_then(|d| d.set.as_ref())
            .map(|s| s.names());
        let mut rows = vec![vec![
            (Panel2d::Input, "input + mask"),
            (Panel2d::Reprojection, "reprojection"),
            (Panel2d::Difference, "residual I − R"),
            (Panel2d::Depth, "depth"),
            (Panel2d::DepthError, "depth error"),
        ]];
        if set_names.is_none()
            && cx
                .session
                .solve
                .finished
                .as_ref()
                .is_some_and(|s| s.albedo_fit.is_some())
        {
            // On a row of its own: a sixth tab does not fit the first.
            rows.push(vec![(Panel2d::Albedo, "albedo")]);
        }
        if set_names.is_some() {
            // A set's own panels on a row of their own: nine tabs do not
            // fit one row of the image panel.
            rows[0].retain(|(p, _)| *p != Panel2d::DepthError);
            rows.push(vec![
                (Panel2d::Albedo, "albedo"),
                (Panel2d::Normals, "normals"),
                (Panel2d::PhotoResidual, "photo residual"),
                (Panel2d::SingleDifference, "alone − set"),
            ]);
        }
        for panels in rows {
            ui.horizontal_wrapped(|ui| {
                for (panel, name) in panels {
                    let enabled = panel != Panel2d::DepthError
                        || cx
                            .session
                            .document
                            .as_ref()
                            .is_some_and(|d| d.ground_truth.is_some());
                    ui.add_enabled_ui(enabled, |ui| {
                        ui.selectable_value(&mut self.panel, panel, name);
                    });
                }
            });
        }
        ui.horizontal_wrapped(|ui| {
            if self.panel == Panel2d::PhotoResidual
                && let Some(names) = &set_names
            {
                self.set.residual_selector_ui(ui, names);
            }
            if let Some(caption) = self.set.caption(self.panel, cx.session) {
                ui.weak(caption);
            }
            if matches!(self.panel, Panel2d::Input | Panel2d::Reprojection)
                && cx.session.document.is_some()
            {
                let display = cx.session.display;
                ui.weak(display.describe()).on_hover_text(format!(
                    "For viewing only: the linear values times {:.3}, so that the {:.0}th \
                     percentile of the object's pixels is white, then the sRGB transfer \
                     function (display gamma). The solver gets the linear values, and \
                     hovering shows them (I).",
                    display.exposure,
                    100.0 * images::WHITE_QUANTILE
                ));
            }
        });
        let Some((w, h)) = cx.session.document.as_ref().map(|d| d.size()) else {
            ui.label("Open an image (File > Open or drop a file here).");
            return;
        };
        let (texture, range) = match self.panel {
            Panel2d::Input => (self.input_texture(ui.ctx(), cx.session), None),
            Panel2d::Reprojection => (self.textures.reprojection.clone(), None),
            Panel2d::Difference => split(&self.textures.difference),
            Panel2d::Depth => split(&self.textures.depth),
            Panel2d::DepthError => split(&self.textures.depth_error),
            Panel2d::Albedo
            | Panel2d::Normals
            | Panel2d::PhotoResidual
            | Panel2d::SingleDifference => {
                match self.set.texture(ui.ctx(), self.panel, cx.session) {
                    // Albedo is grey and normals are colours: no colour bar.
                    Some((texture, range)) => {
                        let bar = matches!(
                            self.panel,
                            Panel2d::PhotoResidual | Panel2d::SingleDifference
                        );
                        (Some(texture), bar.then_some(range))
                    }
                    None => (None, None),
                }
            }
        };
        let bar_width = if range.is_some() { 90.0 } else { 0.0 };
        let available = ui.available_size() - egui::vec2(bar_width, 0.0);
        let (rect, response) = ui.allocate_exact_size(
            available.max(egui::vec2(32.0, 32.0)),
            egui::Sense::click_and_drag(),
        );
        // image -> screen: fit, then the user's zoom and pan.
        let fit = (rect.width() / w as f32).min(rect.height() / h as f32);
        let scale = fit * self.zoom;
        let origin = rect.center() - egui::vec2(w as f32, h as f32) * scale / 2.0 + self.pan;
        let to_image = |p: egui::Pos2| -> ImagePoint {
            let q = (p - origin) / scale;
            [q.x, q.y]
        };
        // Zoom about the cursor, pan with the right or middle button.
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0
                && let Some(cursor) = response.hover_pos()
            {
                let factor = (scroll * 0.002).exp();
                let before = to_image(cursor);
                self.zoom = (self.zoom * factor).clamp(0.1, 64.0);
                let new_scale = fit * self.zoom;
                let new_origin = rect.center() - egui::vec2(w as f32, h as f32) * new_scale / 2.0;
                self.pan = cursor - new_origin - egui::vec2(before[0], before[1]) * new_scale;
            }
        }
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            self.pan += response.drag_delta();
        }
        if response.double_clicked_by(egui::PointerButton::Secondary) {
            self.zoom = 1.0;
            self.pan = egui::Vec2::ZERO;
        }
        let image_rect = egui::Rect::from_min_size(origin, egui::vec2(w as f32, h as f32) * scale);
        let painter = ui.painter_at(rect);
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some(texture) = &texture {
            painter.image(texture.id(), image_rect, uv, egui::Color32::WHITE);
        } else {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "waiting for the first level",
                egui::FontId::proportional(14.0),
                ui.visuals().weak_text_color(),
            );
        }
        if self.panel == Panel2d::Input {
            self.update_overlay(ui.ctx(), cx);
            if let Some((_, overlay)) = &self.textures.overlay {
                painter.image(overlay.id(), image_rect, uv, egui::Color32::WHITE);
            }
            let solve = &cx.session.solve;
            let key = solve.completed_jobs;
            let alpha = (cx.settings.brush.overlay_opacity.clamp(0.0, 1.0) * 255.0) as u8;
            if cx.settings.brush.show_shadows {
                let shadow = solve.finished.as_ref().and_then(|s| s.shadow.as_ref());
                let violet = [150, 60, 220, alpha];
                update_mask_texture(
                    ui.ctx(),
                    &mut self.textures.shadows,
                    "shadows",
                    shadow,
                    violet,
                    key,
                );
                if let Some((_, shadows)) = &self.textures.shadows {
                    painter.image(shadows.id(), image_rect, uv, egui::Color32::WHITE);
                }
            }
            if cx.settings.brush.show_contours {
                let contours = solve.occlusion_edges.as_ref();
                let orange = [255, 150, 0, alpha.max(160)];
                update_mask_texture(
                    ui.ctx(),
                    &mut self.textures.contours,
                    "contours",
                    contours,
                    orange,
                    key,
                );
                if let Some((_, contours)) = &self.textures.contours {
                    painter.image(contours.id(), image_rect, uv, egui::Color32::WHITE);
                }
            }
            self.draw_known_distances(&painter, cx, scale, origin);
            self.paint_input(ui, cx, &response, &to_image, scale, origin);
        }
        if let Some(range) = range {
            let bar = egui::Rect::from_min_size(
                egui::pos2(rect.right() + 8.0, rect.top() + 10.0),
                egui::vec2(80.0, (rect.height() - 20.0).max(20.0)),
            );
            images::scale_bar(ui, bar, range);
        }
        self.hover = response.hover_pos().and_then(|p| {
            let [x, y] = to_image(p);
            (x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h)
                .then(|| describe_pixel(cx.session, x as usize, y as usize))
        });
    }

    fn update_overlay(&mut self, ctx: &egui::Context, cx: &UiContext<'_>) {
        let Some(doc) = &cx.session.document else {
            return;
        };
        // A set's photograph's own layer, when the tools paint it.
        let masks = match (self.set.paint_photo, &doc.set) {
            (Some(k), Some(set)) => set.photo_masks.get(k).unwrap_or(&doc.masks),
            _ => &doc.masks,
        };
        let key = (masks.revision() ^ (cx.settings.brush.overlay_opacity.to_bits() as u64) << 32)
            .wrapping_add(self.set.paint_photo.map_or(0, |k| k as u64 + 1) << 56);
        if self
            .textures
            .overlay
            .as_ref()
            .is_some_and(|(k, _)| *k == key)
        {
            return;
        }
        let style = OverlayStyle {
            opacity: cx.settings.brush.overlay_opacity,
            ..OverlayStyle::default()
        };
        let rgba = masks.overlay_rgba(&style);
        let (w, h) = doc.size();
        let image = egui::ColorImage::from_rgba_unmultiplied([w, h], &rgba);
        self.textures.overlay = Some((
            key,
            images::load_texture(ctx, "overlay", image, egui::TextureOptions::NEAREST),
        ));
    }

    /// The known distances (and the pixel waiting for its distance) as
    /// rings on the input panel, at the centre of their photograph pixel.
    fn draw_known_distances(
        &self,
        painter: &egui::Painter,
        cx: &UiContext<'_>,
        scale: f32,
        origin: egui::Pos2,
    ) {
        let Some(doc) = &cx.session.document else {
            return;
        };
        let ((w, h), (fw, fh)) = (doc.size(), doc.full_size);
        let at = |x: f64, y: f64| {
            let q = [
                (x + 0.5) * w as f64 / fw as f64,
                (y + 0.5) * h as f64 / fh as f64,
            ];
            origin + egui::vec2(q[0] as f32, q[1] as f32) * scale
        };
        let set = egui::Stroke::new(2.0, egui::Color32::from_rgb(0, 220, 255));
        for p in &doc.known_depths {
            let centre = at(p.column_px, p.row_px);
            painter.circle_stroke(centre, 6.0, set);
            painter.circle_filled(centre, 1.5, set.color);
        }
        if let Some((x, y)) = self.known.pending {
            let centre = at(x as f64, y as f64);
            painter.circle_stroke(centre, 6.0, egui::Stroke::new(2.0, egui::Color32::YELLOW));
        }
    }

    /// Mask tools on the input panel.
    fn paint_input(
        &mut self,
        ui: &egui::Ui,
        cx: &mut UiContext<'_>,
        response: &egui::Response,
        to_image: &dyn Fn(egui::Pos2) -> ImagePoint,
        scale: f32,
        origin: egui::Pos2,
    ) {
        let b = cx.settings.brush.clone();
        let paint_photo = self.set.paint_photo;
        let Some(doc) = &mut cx.session.document else {
            return;
        };
        let pointer = response.interact_pointer_pos().or(response.hover_pos());
        let primary = egui::PointerButton::Primary;
        if self.known.picking {
            // "Set distance": a click picks the pixel; no mask tool.
            if response.hovered() {
                ui.ctx().set_cursor_icon(egui::CursorIcon::Crosshair);
            }
            if response.clicked_by(primary)
                && let Some(p) = pointer
            {
                let picked = doc
                    .photo_pixel(to_image(p))
                    .ok_or_else(|| "that is outside the image: click a pixel of the object".into())
                    .and_then(|(x, y)| {
                        let probe = KnownDistance {
                            column_px: x as f64,
                            row_px: y as f64,
                            depth: 1.0,
                        };
                        doc.check_known_depth(&probe).map(|_| (x, y))
                    });
                match picked {
                    Ok(pixel) => {
                        self.known.pending = Some(pixel);
                        self.known.picking = false;
                        self.known.refused = None;
                    }
                    Err(reason) => {
                        cx.actions.push(Action::Notice(reason.clone()));
                        self.known.refused = Some(reason);
                    }
                }
            }
            return;
        }
        let (masks, image) = doc.paint_target(paint_photo);
        match b.tool {
            Tool::Brush => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    let brush = Brush {
                        radius_px: b.radius_px,
                        hardness: b.hardness,
                        mode: b.mode,
                    };
                    match masks.begin_stroke(b.layer, brush, to_image(p)) {
                        Ok(()) => self.gesture = Some(Gesture::Stroke),
                        Err(e) => cx.actions.push(Action::Notice(e.to_string())),
                    }
                }
                if response.dragged_by(primary)
                    && matches!(self.gesture, Some(Gesture::Stroke))
                    && let Some(p) = pointer
                {
                    let d = response.drag_delta();
                    masks.stroke_segment(to_image(p - d), to_image(p));
                }
                if response.clicked_by(primary)
                    && let Some(p) = pointer
                {
                    // A click is a single dab.
                    let brush = Brush {
                        radius_px: b.radius_px,
                        hardness: b.hardness,
                        mode: b.mode,
                    };
                    if masks.begin_stroke(b.layer, brush, to_image(p)).is_ok() {
                        masks.end_stroke();
                    }
                }
                if let Some(p) = response.hover_pos() {
                    ui.painter().circle_stroke(
                        p,
                        b.radius_px * scale,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                    );
                }
            }
            Tool::Rectangle => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    self.gesture = Some(Gesture::Rectangle(to_image(p)));
                }
                if let (Some(Gesture::Rectangle(start)), Some(p)) = (&self.gesture, pointer) {
                    let a = origin + egui::vec2(start[0], start[1]) * scale;
                    ui.painter().rect_stroke(
                        egui::Rect::from_two_pos(a, p),
                        0.0,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                        egui::StrokeKind::Middle,
                    );
                }
            }
            Tool::Lasso => {
                if response.drag_started_by(primary)
                    && let Some(p) = pointer
                {
                    self.gesture = Some(Gesture::Lasso(vec![to_image(p)]));
                }
                if let (Some(Gesture::Lasso(points)), Some(p)) = (&mut self.gesture, pointer) {
                    if response.dragged_by(primary) {
                        points.push(to_image(p));
                    }
                    let screen: Vec<egui::Pos2> = points
                        .iter()
                        .map(|q| origin + egui::vec2(q[0], q[1]) * scale)
                        .collect();
                    ui.painter().add(egui::Shape::line(
                        screen,
                        egui::Stroke::new(1.0, egui::Color32::YELLOW),
                    ));
                }
            }
            Tool::FloodFill => {
                if response.clicked_by(primary)
                    && let Some(p) = pointer
                    && let Err(e) =
                        masks.flood_fill(b.layer, b.mode, image, to_image(p), b.flood_tolerance)
                {
                    cx.actions.push(Action::Notice(e.to_string()));
                }
            }
        }
        if response.drag_stopped_by(primary) {
            match self.gesture.take() {
                Some(Gesture::Stroke) => {
                    masks.end_stroke();
                }
                Some(Gesture::Rectangle(start)) => {
                    if let Some(p) = pointer {
                        masks.fill_rect(b.layer, b.mode, start, to_image(p));
                    }
                }
                Some(Gesture::Lasso(points)) => {
                    masks.fill_lasso(b.layer, b.mode, &points);
                }
                None => {}
            }
        }
    }
}

/// Candidates of a material fit listed under its summary.
const TRIALS_SHOWN: usize = 5;

/// The material a solve used (when not Lambert or fitted), and with
/// `reflectance auto` what the fit found and its best candidates.
fn material_ui(ui: &mut egui::Ui, solution: &Solution) {
    if solution.material.is_lambert() && solution.material_fit.is_none() {
        return;
    }
    ui.label(format!("reflectance: {}", solution.material.describe()))
        .on_hover_text("The reflectance model the surface was solved with (METHOD.md section 10)");
    let Some(fit) = &solution.material_fit else {
        return;
    };
    let text = format!("material fit ({:.1} s): {}", fit.seconds, fit.summary);
    let hover = format!(
        "reflectance auto: each of the {} candidates solved on a {} px copy of the image and \
         ranked by energy (data term plus smoothness), each with its residual; the solve used \
         the reflectance above. To solve as another model, choose it under Parameters",
        fit.trials.len(),
        fit.working_side
    );
    if !fit.determined && !fit.best.is_lambert() {
        ui.colored_label(ui.visuals().warn_fg_color, format!("warning: {text}"))
            .on_hover_text(hover.as_str());
    } else {
        ui.label(text).on_hover_text(hover.as_str());
    }
    egui::CollapsingHeader::new(format!(
        "best {} of {} candidates",
        TRIALS_SHOWN.min(fit.trials.len()),
        fit.trials.len()
    ))
    .id_salt("material candidates")
    .default_open(false)
    .show(ui, |ui| {
        let best = fit.trials.iter().take(TRIALS_SHOWN);
        // Lambert's row for comparison when it is not among the best.
        let lambert = fit
            .trials
            .iter()
            .skip(TRIALS_SHOWN)
            .find(|t| t.material.is_lambert());
        egui::Grid::new("material trials")
            .striped(true)
            .show(ui, |ui| {
                ui.strong("material");
                ui.strong("energy")
                    .on_hover_text("the solve's final energy relative to the best candidate's");
                ui.strong("residual")
                    .on_hover_text("sqrt(sum c (I - R)^2 / sum c I^2) of the candidate's solve");
                ui.end_row();
                for trial in best.chain(lambert) {
                    ui.label(short_material(&trial.material))
                        .on_hover_text(trial.material.describe());
                    ui.label(format!("×{:.3}", trial.relative_energy));
                    ui.label(format!("{:.4}", trial.relative_residual));
                    ui.end_row();
                }
            });
    });
}

/// A material in a few characters, for the candidates' table (the narrow
/// side panel): `oren-nayar σ 0.40`, `blinn-phong k_s 0.60 n 5`.
fn short_material(material: &Material) -> String {
    match *material {
        Material::Lambert => "lambert".into(),
        Material::OrenNayar { roughness_rad } => format!("oren-nayar σ {roughness_rad:.2}"),
        Material::BlinnPhong {
            specular,
            shininess,
        } => format!("blinn-phong k_s {specular:.2} n {shininess:.0}"),
    }
}

/// The side panel's line on a known-distance fit: the scale, each
/// point's relative residual and how precisely the points fix the scale
/// (unless loosely: that is a warning of its own).
/// Every warning of the last solve: the model fit's, the depth unit's and
/// the known distances'.
fn solve_warnings(s: &super::session::SolveState, units: &str) -> Vec<String> {
    let mut warnings = Vec::new();
    if let Some(w) = s.depth_unit.as_ref().and_then(|u| u.warning(units)) {
        warnings.push(w);
    }
    if let Some(fit) = &s.known_depth_fit {
        if !fit.converged {
            warnings.push(
                "the scale search for the known distances did not settle; the residuals say how \
                 far off it stopped"
                    .into(),
            );
        }
        if let Some(w) = fit
            .scale_precision
            .and_then(|p| p.warning(fit.points.len()))
        {
            warnings.push(w);
        }
    }
    if let Some(fit) = &s.fit {
        warnings.extend(fit.warnings.iter().cloned());
    }
    warnings
}

/// The fit in one line, coloured (green: explained, no warning; orange:
/// warnings; red: much of the image unexplained or the depth unit a
/// guess), with the one thing to do next; the figures on hover and the
/// warnings in a list that opens.
fn fit_line(ui: &mut egui::Ui, s: &super::session::SolveState, units: &str) {
    let warnings = solve_warnings(s, units);
    let Some(fit) = &s.fit else {
        if let Some(unit) = &s.depth_unit {
            ui.label(unit.words(units));
        }
        return;
    };
    let guess = s
        .depth_unit
        .as_ref()
        .is_some_and(|u| u.source == sfs_core::solver::depth_unit::UnitSource::Guess);
    let (colour, verdict) = if fit.poor_share > 0.3 || guess {
        (ui.visuals().error_fg_color, "poor")
    } else if warnings.is_empty() {
        (egui::Color32::from_rgb(60, 170, 80), "good")
    } else {
        (ui.visuals().warn_fg_color, "fair")
    };
    let next = if s.depth_unit.as_ref().is_some_and(|u| u.wants_distance()) {
        "next: give the object's distance (Known distance)"
    } else if fit.near_black_share > 0.05 || fit.poor_share > 0.15 {
        "next: paint the shadows and highlights low confidence (Mask)"
    } else {
        ""
    };
    let mut line = format!(
        "fit {verdict}: RIE {:.3}, {:.0} % badly explained",
        fit.rie_trusted,
        100.0 * fit.poor_share
    );
    if !next.is_empty() {
        line.push_str(" — ");
        line.push_str(next);
    }
    ui.colored_label(colour, line).on_hover_text(format!(
        "RIE: relative image error of the reprojection over trusted object pixels; badly \
         explained: residual above 15 %; {:.0} % near-black, {:.1} % saturated. See the \
         residual panel.",
        100.0 * fit.near_black_share,
        100.0 * fit.saturated_share
    ));
    if let Some(unit) = &s.depth_unit {
        ui.weak(unit.words(units));
    }
    if !warnings.is_empty() {
        egui::CollapsingHeader::new(format!(
            "{} warning{}",
            warnings.len(),
            if warnings.len() == 1 { "" } else { "s" }
        ))
        .id_salt("solve warnings")
        .show(ui, |ui| {
            for warning in &warnings {
                ui.colored_label(ui.visuals().warn_fg_color, warning);
            }
        });
    }
}

fn fit_summary(fit: &sfs_core::solver::calibrate::KnownDepthFit) -> String {
    let n = fit.points.len();
    let residuals: Vec<String> = fit
        .points
        .iter()
        .map(|p| format!("{:+.2} %", 100.0 * p.relative_residual))
        .collect();
    let mut summary = format!(
        "s = {:.4e} from {n} known distance{}; residuals {}",
        fit.intensity_scale,
        if n == 1 { "" } else { "s" },
        residuals.join(", ")
    );
    // A loose scale's words are its warning instead.
    if let Some(precision) = fit.scale_precision.filter(|p| !p.is_loose()) {
        summary.push_str("; ");
        summary.push_str(&precision.words(n));
    }
    summary
}

/// A distance with four significant digits (no exponent for the sizes
/// distances have; `NaN` as such).
fn significant(value: f64) -> String {
    if !value.is_finite() || value == 0.0 {
        return format!("{value}");
    }
    let decimals = (3 - value.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{value:.decimals$}")
}

/// Hover text: image, reprojection and depth at an image pixel.
fn describe_pixel(session: &Session, c: usize, r: usize) -> String {
    let mut text = format!("({c}, {r})");
    let Some(doc) = &session.document else {
        return text;
    };
    let (w, h) = doc.size();
    text.push_str(&format!(" I {:.4}", doc.image.at(c, r)));
    if let Some(level) = &session.solve.latest {
        let (lw, lh) = level.depth.size();
        let (lc, lr) = ((c * lw / w).min(lw - 1), (r * lh / h).min(lh - 1));
        // Off the object the solver's depth is no surface (the views hide it).
        let z = if *doc.masks.object().at(c, r) {
            *level.depth.at(lc, lr)
        } else {
            f64::NAN
        };
        text.push_str(&format!(
            "  R {:.4}  z {:.4}",
            level.reprojection.at(lc, lr),
            z
        ));
    }
    if let Some(gt) = &doc.ground_truth {
        text.push_str(&format!("  z_gt {:.4}", gt.at(c, r)));
    }
    text.push_str(&format!("  c {:.2}", doc.masks.confidence().at(c, r)));
    text
}

fn split(
    entry: &Option<(egui::TextureHandle, [f64; 2])>,
) -> (Option<egui::TextureHandle>, Option<[f64; 2]>) {
    match entry {
        Some((t, r)) => (Some(t.clone()), Some(*r)),
        None => (None, None),
    }
}

/// The start selector's `(label, hover text)` for fast marching and for the
/// paper's start from the image. With the solve's lights off the centre
/// fast marching runs in the lights' own frame when they are within 20
/// degrees of the camera (seen from the object), else the solver starts
/// from the best-fitting plane (`sfs_core::solver::prepare`); the paper's
/// start from the image is then that plane; the labels say so.
fn start_labels(lights_off_centre: bool) -> [(&'static str, &'static str); 2] {
    if lights_off_centre {
        [
            (
                "fast marching (in the lights' frame)",
                "Fast marching solves the light at the optical centre: with these lights it is \
                 marched in their own frame (a camera at the lights, where they are centred) \
                 and refined by the solver at full resolution. Lights more than 20 degrees off \
                 the camera, seen from the object, or more than a third of the way to it, start \
                 from the constant depth \
                 (fronto-parallel plane) whose rendering best fits the image, refined through \
                 the whole pyramid.",
            ),
            (
                "from image (lights off the centre: best-fitting plane)",
                "The paper's constant from the brightest pixel assumes the light at the optical \
                 centre. With these lights the solver starts from the constant depth \
                 (fronto-parallel plane) whose rendering best fits the image, refined through \
                 the whole pyramid.",
            ),
        ]
    } else {
        [
            (
                "fast marching",
                "Fast marching on the (denoised) image, refined by the solver at full \
                 resolution (the default).",
            ),
            (
                "from image",
                "The paper's start: a constant depth from the brightest pixel, refined through \
                 the whole pyramid.",
            ),
        ]
    }
}

/// A slider's number: scientific notation where plain decimals would show
/// only zeros or too many digits (alpha is around 1e-7 in relative units).
fn slider_number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude != 0.0 && !(1e-3..1e5).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        format!("{}", (value * 1e4).round() / 1e4)
    }
}

/// Keeps `texture` the RGBA of `mask` (`colour` where set, clear elsewhere)
/// for the result `key`: rebuilt once per result, dropped without a mask.
fn update_mask_texture(
    ctx: &egui::Context,
    texture: &mut Option<(usize, egui::TextureHandle)>,
    name: &str,
    mask: Option<&sfs_core::grid::Grid<bool>>,
    colour: [u8; 4],
    key: usize,
) {
    let Some(mask) = mask else {
        *texture = None;
        return;
    };
    if texture.as_ref().is_some_and(|(k, _)| *k == key) {
        return;
    }
    let (w, h) = mask.size();
    let rgba: Vec<u8> = mask
        .as_slice()
        .iter()
        .flat_map(|&on| if on { colour } else { [0, 0, 0, 0] })
        .collect();
    let image = egui::ColorImage::from_rgba_unmultiplied([w, h], &rgba);
    *texture = Some((
        key,
        images::load_texture(ctx, name, image, egui::TextureOptions::NEAREST),
    ));
}
