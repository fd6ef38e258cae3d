//! The "Mask" section: the layer and mode painted, the tools and their
//! settings, the overlays shown, clear/invert/undo/redo, the suggested
//! confidence and the threshold.

use eframe::egui;

use super::{Action, Panels, UiContext};
use crate::app::settings::Tool;
use crate::mask_edit::{Layer, Mode};

impl Panels {
    pub(super) fn mask_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let names = cx.set_names();
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
}
