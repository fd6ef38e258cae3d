//! The 3-D view's panel on the right: its heading, the controls' hint and
//! the surface.

use eframe::egui;

use super::{Panels, UiContext};

impl Panels {
    pub(super) fn view3d_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        ui.heading("3-D surface");
        ui.weak("drag: orbit · right-drag: pan · scroll: zoom · double-click: reset");
        let range = self.error_range();
        let prefs = cx.settings.view.clone();
        self.surface.ui(ui, &prefs, range);
    }
}
