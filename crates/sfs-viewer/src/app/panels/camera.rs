//! The "Camera" section: focal length, principal point, intensity scale,
//! lights, sRGB, the photograph's corrections and the working size.

use std::path::{Path, PathBuf};

use eframe::egui;

use super::{Action, IMAGE_EXTENSIONS, Panels, UiContext, pick_open};
use crate::app::document::{CameraSource, Document};
use sfs_core::photo::{PhotoInput, Vignetting};

impl Panels {
    pub(super) fn camera_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
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
                let (position, aim) = (light.position_text(), light.aim_text());
                ui.weak(format!("light {}: {position}{aim}", k + 1));
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
        let images = [("image", IMAGE_EXTENSIONS)];
        if let Some(ambient) = file_row(
            ui,
            "ambient frame",
            doc.input.ambient.as_deref(),
            "none",
            "A photograph with every light off (same exposure), subtracted from the image",
        ) {
            change = Some(Box::new(move |input| input.ambient = ambient));
        }
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
        if let Some(albedo) = file_row(
            ui,
            "albedo",
            doc.input.albedo.as_deref(),
            "none (uniform)",
            "A known albedo map (linear, relative), divided out; pixels below 0.02 are not \
             trusted",
        ) {
            change = Some(Box::new(move |input| input.albedo = albedo));
        }
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
}

/// A file's name (its whole path if it has none), for a label.
fn name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// One optional file of the photograph's corrections in a row: `label`, the
/// file's name (or `none`), "clear" and "choose…" (explained by `hover`).
/// Returns the new choice: `Some(None)` when cleared, `Some(Some(path))`
/// when an image was chosen, `None` when nothing changed.
fn file_row(
    ui: &mut egui::Ui,
    label: &str,
    current: Option<&Path>,
    none: &str,
    hover: &str,
) -> Option<Option<PathBuf>> {
    ui.horizontal(|ui| {
        let mut choice = None;
        ui.label(label);
        match current {
            Some(path) => {
                ui.weak(name(path))
                    .on_hover_text(path.display().to_string());
                if ui.small_button("clear").clicked() {
                    choice = Some(None);
                }
            }
            None => {
                ui.weak(none);
            }
        }
        if ui.small_button("choose…").on_hover_text(hover).clicked()
            && let Some(path) = pick_open(&[("image", IMAGE_EXTENSIONS)])
        {
            choice = Some(Some(path));
        }
        choice
    })
    .inner
}
