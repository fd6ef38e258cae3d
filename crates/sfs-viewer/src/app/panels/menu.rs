//! The menu bar: File (open an image, a set or the sample, a camera file,
//! recent files, exports, masks, a screenshot, quit) and Edit (undo, redo).

use eframe::egui;

use super::{Action, IMAGE_EXTENSIONS, Panels, UiContext, pick_folder, pick_open, pick_save};
use crate::app::session::Export;
use crate::mask_edit::Layer;

impl Panels {
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
                    && let Some(path) = crate::app::sample_image_path()
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
        let has_result = cx.session.solve.finished().is_some();
        let name = cx
            .session
            .document
            .as_ref()
            .and_then(|d| d.path.file_stem())
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "result".into());
        ui.add_enabled_ui(has_result, |ui| {
            // (label, the file name after the image's name, extension, what)
            for (label, suffix, extension, what) in [
                (
                    "Export depth (.npy)…",
                    "-depth.npy",
                    "npy",
                    Export::DepthNpy,
                ),
                (
                    "Export depth (16-bit PNG)…",
                    "-depth16.png",
                    "png",
                    Export::DepthPng,
                ),
                ("Export mesh (.ply)…", ".ply", "ply", Export::MeshPly),
                ("Export mesh (.obj)…", ".obj", "obj", Export::MeshObj),
                (
                    "Export reprojection (16-bit PNG)…",
                    "-reprojection.png",
                    "png",
                    Export::Reprojection,
                ),
                (
                    "Export report (.json)…",
                    "-report.json",
                    "json",
                    Export::Report,
                ),
            ] {
                if ui.button(label).clicked()
                    && let Some(path) = pick_save(&format!("{name}{suffix}"), extension)
                {
                    cx.actions.push(Action::Export(path, what));
                }
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
}
