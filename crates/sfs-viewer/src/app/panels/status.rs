//! The status line: the open file and its size, the hovered pixel's values
//! and the notice with its dismiss button.

use eframe::egui;

use super::{Action, Panels, UiContext};

impl Panels {
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
}
