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
}
