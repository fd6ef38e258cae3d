//! The "Known distance" section (the object's distance typed, distances
//! picked on the input and typed, their fit) and its rings on the input panel.

use eframe::egui;

use super::{Action, Panel2d, Panels, UiContext};
use crate::app::document::KnownDistance;

impl Panels {
    /// The "Known distance" section: "Set distance" picks a pixel of the
    /// object in the input panel, a typed distance confirms it; the points
    /// with, after a solve, their solved depth and residual; remove one or
    /// all. Each change re-solves (the session asks for it).
    pub(super) fn known_distance_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
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
            if distance_field(ui, text, label, "e.g. 650", &units, "Set") {
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
                if distance_field(ui, &mut tool.text, label, "e.g. 350", &units, "OK") {
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
        let fit = cx.session.solve.known_depth_fit();
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

    /// The known distances (and the pixel waiting for its distance) as
    /// rings on the input panel, at the centre of their photograph pixel.
    pub(super) fn draw_known_distances(
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

/// A distance's text field (labelled by `label`, with `hint` while empty),
/// its units and the button `confirm`; true when the button was clicked or
/// Enter pressed in the field.
fn distance_field(
    ui: &mut egui::Ui,
    text: &mut String,
    label: egui::Id,
    hint: &str,
    units: &str,
    confirm: &str,
) -> bool {
    let edit = ui
        .add(
            egui::TextEdit::singleline(text)
                .desired_width(70.0)
                .hint_text(hint),
        )
        .labelled_by(label);
    ui.label(units);
    let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
    ui.button(confirm).clicked() || entered
}
