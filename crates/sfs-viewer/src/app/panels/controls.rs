//! The controls side panel: its sections in order (progress, a set's
//! photometric stereo, parameters, mask, camera, known distance, 3-D view).

use eframe::egui;

use super::{Panels, UiContext};

impl Panels {
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
        type Section = fn(&mut Panels, &mut egui::Ui, &mut UiContext<'_>);
        let sections: [(&str, Section); 4] = [
            ("Mask", Self::mask_ui),
            ("Camera", Self::camera_ui),
            ("Known distance", Self::known_distance_ui),
            ("3-D view", Self::view_settings_ui),
        ];
        for (title, section) in sections {
            egui::CollapsingHeader::new(title)
                .default_open(true)
                .show(ui, |ui| section(self, ui, cx));
        }
    }
}
