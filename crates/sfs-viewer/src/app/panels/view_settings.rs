//! The "3-D view" section of the controls: the surface's colouring,
//! wireframe, texture, light direction and view reset.

use eframe::egui;

use super::{Panels, UiContext};
use crate::app::settings::SurfaceColour;

impl Panels {
    pub(super) fn view_settings_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
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
                .finished()
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
}
