//! A photometric-stereo set's part of the panels: the "Photometric stereo"
//! controls (the set's smoothness, each photograph's fit, one photograph
//! solved alone with the single-image method and compared with the set),
//! the selector of the layer the mask tools paint (every photograph or one
//! photograph's own confidence), and the set's 2-D images (albedo in grey,
//! normals in normal-map colours, a photograph's residual, the depth
//! difference of the comparison), built once per result. Uses `session`,
//! `settings`, `images` and the core's `colour`; draws, owns no solve.

use eframe::egui;

use super::context::{Action, Panel2d, UiContext};
use crate::app::images;
use crate::app::session::Session;
use crate::app::settings::SetParamSettings;
use sfs_core::grid::Grid;
use sfs_core::solver::photometric::PhotometricSolution;

/// A texture built for `key` (the result it shows), with its value range.
struct Built<K> {
    key: K,
    texture: egui::TextureHandle,
    range: [f64; 2],
}

impl<K> Built<K> {
    /// The texture and its range, to show.
    fn shown(&self) -> (egui::TextureHandle, [f64; 2]) {
        (self.texture.clone(), self.range)
    }
}

/// The set's selections and textures.
#[derive(Default)]
pub struct SetView {
    /// The photograph whose residual the residual panel shows.
    pub residual_photo: usize,
    /// The photograph to solve alone.
    pub single_photo: usize,
    /// Solve it with the set's albedo divided out.
    pub single_with_albedo: bool,
    /// The layer the mask tools paint: `None` the set-wide masks, else
    /// that photograph's own confidence.
    pub paint_photo: Option<usize>,
    albedo: Option<Built<usize>>,
    normals: Option<Built<usize>>,
    residual: Option<Built<(usize, usize)>>,
    single: Option<Built<usize>>,
}

/// The 99th percentile of the finite, positive values (white of a grey
/// image), 1 when there are none.
fn white_point(values: &Grid<f64>) -> f64 {
    let mut finite = values.finite_positive_values();
    if finite.is_empty() {
        return 1.0;
    }
    let k = (finite.len() - 1) * 99 / 100;
    *finite.select_nth_unstable_by(k, f64::total_cmp).1
}

/// Normal-map colours of `normals` (black where there is no surface).
fn normal_image(normals: &Grid<[f64; 3]>) -> egui::ColorImage {
    let (w, h) = normals.size();
    let pixels = normals
        .as_slice()
        .iter()
        .map(|&n| {
            let [r, g, b] = sfs_core::colour::normal_rgb(n);
            let byte = |v: f64| (v * 255.0).round() as u8;
            egui::Color32::from_rgb(byte(r), byte(g), byte(b))
        })
        .collect();
    egui::ColorImage::new([w, h], pixels)
}

/// A range symmetric about 0 that holds 99 % of the finite values (a few
/// outliers, e.g. a specular speck, would leave the rest one colour).
fn symmetric_range(values: &Grid<f64>) -> [f64; 2] {
    let magnitudes = values.map(|v| v.abs());
    let largest = white_point(&magnitudes);
    [-largest, largest]
}

impl SetView {
    /// Forgets the textures and selections (a new document).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// The texture of one of the set's panels and its scale (`None` for the
    /// other panels, or before there is a result to show).
    pub fn texture(
        &mut self,
        ctx: &egui::Context,
        panel: Panel2d,
        session: &Session,
    ) -> Option<(egui::TextureHandle, [f64; 2])> {
        let key = session.solve.completed_jobs;
        let options = egui::TextureOptions::NEAREST;
        let solution: Option<&PhotometricSolution> = session.solve.set.as_deref();
        match panel {
            Panel2d::Albedo => {
                // A set's albedo, or the albedo one photograph was solved
                // with (`auto`: the estimate when used, else 1); built once
                // per result.
                if self.albedo.as_ref().is_none_or(|b| b.key != key) {
                    let albedo = session.surface_albedo()?;
                    let white = white_point(&albedo);
                    let mapping = images::DisplayMapping {
                        exposure: 1.0 / white,
                    };
                    let image = mapping.image(&albedo);
                    self.albedo = Some(Built {
                        key,
                        texture: images::load_texture(ctx, "albedo", image, options),
                        range: [0.0, white],
                    });
                }
                self.albedo.as_ref().map(Built::shown)
            }
            Panel2d::Normals => {
                let solution = solution?;
                if self.normals.as_ref().is_none_or(|b| b.key != key) {
                    let image = normal_image(&solution.normals);
                    self.normals = Some(Built {
                        key,
                        texture: images::load_texture(ctx, "normals", image, options),
                        range: [-1.0, 1.0],
                    });
                }
                self.normals.as_ref().map(Built::shown)
            }
            Panel2d::PhotoResidual => {
                let solution = solution?;
                let photo = self
                    .residual_photo
                    .min(solution.photos.len().checked_sub(1)?);
                let residual_key = (key, photo);
                if self.residual.as_ref().is_none_or(|b| b.key != residual_key) {
                    // I - R, as the single image's residual panel.
                    let residual = solution.photos[photo].residual.clone();
                    let range = symmetric_range(&residual);
                    let image = images::colour_mapped(&residual, range);
                    self.residual = Some(Built {
                        key: residual_key,
                        texture: images::load_texture(ctx, "photo-residual", image, options),
                        range,
                    });
                }
                self.residual.as_ref().map(Built::shown)
            }
            Panel2d::SingleDifference => {
                let difference = session.compare.difference.as_ref()?;
                let key = session.compare.completed;
                if self.single.as_ref().is_none_or(|b| b.key != key) {
                    let range = symmetric_range(difference);
                    let image = images::colour_mapped(difference, range);
                    self.single = Some(Built {
                        key,
                        texture: images::load_texture(ctx, "single-difference", image, options),
                        range,
                    });
                }
                self.single.as_ref().map(Built::shown)
            }
            _ => None,
        }
    }

    /// A line under the panel selector saying what the set's panel shows.
    pub fn caption(&self, panel: Panel2d, session: &Session) -> Option<String> {
        let solution = session.solve.set.as_deref();
        let names = session
            .document
            .as_ref()
            .and_then(|d| d.set.as_ref())
            .map(|s| s.names())
            .unwrap_or_default();
        if panel == Panel2d::Albedo
            && solution.is_none()
            && let Some(fit) = session.solve.finished().and_then(|s| s.albedo_fit.as_ref())
        {
            return Some(format!(
                "albedo (relative, white 1){}: {}",
                if fit.used {
                    ""
                } else {
                    " not used, shown as 1"
                },
                fit.summary
            ));
        }
        match panel {
            Panel2d::Albedo => solution.map(|s| {
                format!(
                    "albedo{}: black 0, white {:.4}",
                    if s.albedo_relative {
                        " (relative: s·ρ, the intensity scale unknown)"
                    } else {
                        ""
                    },
                    white_point(&s.albedo)
                )
            }),
            Panel2d::Normals => {
                Some("normals: red = right, green = up, blue = towards the camera".into())
            }
            Panel2d::PhotoResidual => names
                .get(self.residual_photo)
                .map(|n| format!("residual I − R of {n} under its own light")),
            Panel2d::SingleDifference => session.compare.comparison.as_ref().map(|c| {
                format!(
                    "k·z_single − z_set of {} (k = {:.4})",
                    names.get(session.compare.photo).map_or("?", String::as_str),
                    c.scale_to_set
                )
            }),
            _ => None,
        }
    }

    /// The "Photometric stereo" section: the set's smoothness, the
    /// photographs' fit, and one photograph solved alone to compare.
    pub fn controls_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let Some(names) = cx
            .session
            .document
            .as_ref()
            .and_then(|d| d.set.as_ref())
            .map(|s| s.names())
        else {
            return;
        };
        self.smoothness_ui(ui, cx);
        if let Some(solution) = cx.session.solve.set.as_deref() {
            fit_table_ui(ui, solution);
        }
        ui.separator();
        self.single_ui(ui, cx, &names);
    }

    /// Auto or a value, stored in the settings; a change re-solves.
    fn smoothness_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let stored = &mut cx.settings.set_params;
        let used = cx.session.solve.set.as_ref().map(|s| s.alpha);
        let (low, high) = SetParamSettings::ALPHA_RANGE;
        let mut is_auto = stored.alpha.is_none();
        let mut value = stored
            .alpha
            .or(used)
            .filter(|a| a.is_finite())
            .unwrap_or(1e-6)
            .clamp(low, high);
        let mut changed = false;
        ui.horizontal(|ui| {
            if ui
                .checkbox(&mut is_auto, "auto")
                .on_hover_text(
                    "Let the solver choose the set's smoothness from the photographs' noise; \
                     the slider shows its choice",
                )
                .changed()
            {
                changed = true;
            }
            if ui
                .add(
                    egui::Slider::new(&mut value, low..=high)
                        .logarithmic(true)
                        .custom_formatter(|v, _| format!("{v:.3e}"))
                        .text("set smoothness"),
                )
                .on_hover_text(
                    "Smoothness weight of the set's solve (relative: second derivatives of \
                     the log-depth times f²); small, as several photographs fix the normals",
                )
                .changed()
            {
                is_auto = false;
                changed = true;
            }
        });
        if changed {
            stored.alpha = (!is_auto).then_some(value);
            cx.actions.push(Action::RequestSolve);
        }
    }

    /// Photograph selector, the button, and the comparison's numbers.
    fn single_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>, names: &[String]) {
        self.single_photo = self.single_photo.min(names.len().saturating_sub(1));
        ui.horizontal(|ui| {
            egui::ComboBox::from_id_salt("single photograph")
                .selected_text(names.get(self.single_photo).map_or("", String::as_str))
                .show_ui(ui, |ui| {
                    for (k, name) in names.iter().enumerate() {
                        ui.selectable_value(&mut self.single_photo, k, name);
                    }
                });
            let ready = cx.session.solve.set.is_some() && !cx.session.solve.running;
            if ui
                .add_enabled(
                    ready && !cx.session.compare.running,
                    egui::Button::new("Solve one photograph alone (single-image method)"),
                )
                .on_hover_text(
                    "Solves the chosen photograph with the single-image method (its light \
                     from the set's camera file, the painted masks, the parameters above) \
                     and compares its shape with the set's",
                )
                .clicked()
            {
                cx.actions.push(if self.single_with_albedo {
                    Action::SolveSingleWithSetAlbedo(self.single_photo)
                } else {
                    Action::SolveSingle(self.single_photo)
                });
            }
        });
        ui.checkbox(
            &mut self.single_with_albedo,
            "use the albedo from photometric stereo",
        )
        .on_hover_text(
            "Divide the set's albedo out of the photograph before solving it alone: what the \
             single-image method gives with the right albedo, to compare with its own \
             estimate (parameters: 'estimate the albedo')",
        );
        let compare = &cx.session.compare;
        if compare.running {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!(
                    "solving {} alone",
                    names.get(compare.photo).map_or("?", String::as_str)
                ));
            });
        }
        if let Some(failure) = &compare.failure {
            ui.colored_label(ui.visuals().error_fg_color, failure.clone());
        }
        if let Some(c) = &compare.comparison {
            let name = names.get(compare.photo).map_or("?", String::as_str);
            ui.label(format!(
                "{name} alone{} against the set: RSE {:.4}, scaled {:.4} (k = {:.4}), normals \
                 {:.1}° mean, {:.1}° median apart; depth range {:.4} (set) vs {:.4} (alone), \
                 {} pixels",
                if compare.with_set_albedo {
                    " (the set's albedo divided out)"
                } else {
                    ""
                },
                c.rse_to_set,
                c.rse_to_set_scaled,
                c.scale_to_set,
                c.mean_normal_angle_deg,
                c.median_normal_angle_deg,
                c.set_depth_range,
                c.single_depth_range,
                c.pixels
            ))
            .on_hover_text(
                "RSE: relative depth error of the single photograph's depth against the \
                 set's over the pixels both solved; scaled: after the one factor k that best \
                 matches them; depth range: 2nd to 98th percentile. The panel 'alone − set' \
                 shows k·z_single − z_set",
            );
        }
    }

    /// "paint confidence for: all photographs | NAME": which layer the mask
    /// tools paint (a photograph's own layer holds confidence only).
    pub fn paint_selector_ui(&mut self, ui: &mut egui::Ui, names: &[String]) {
        if self.paint_photo.is_some_and(|k| k >= names.len()) {
            self.paint_photo = None;
        }
        let selected = self
            .paint_photo
            .and_then(|k| names.get(k))
            .map_or("all photographs", String::as_str)
            .to_owned();
        ui.horizontal(|ui| {
            let label = ui.label("paint confidence for").id;
            egui::ComboBox::from_id_salt("paint photograph")
                .selected_text(selected)
                .show_ui(ui, |ui| {
                    ui.selectable_value(&mut self.paint_photo, None, "all photographs");
                    for (k, name) in names.iter().enumerate() {
                        ui.selectable_value(&mut self.paint_photo, Some(k), name);
                    }
                })
                .response
                .labelled_by(label)
                .on_hover_text(
                    "All photographs: the object mask and the confidence apply to every \
                     photograph. A photograph: its own confidence (e.g. a highlight or shadow \
                     of that light alone), combined with the set's",
                );
        });
    }

    /// The residual panel's photograph selector.
    pub fn residual_selector_ui(&mut self, ui: &mut egui::Ui, names: &[String]) {
        self.residual_photo = self.residual_photo.min(names.len().saturating_sub(1));
        egui::ComboBox::from_id_salt("residual photograph")
            .selected_text(names.get(self.residual_photo).map_or("", String::as_str))
            .show_ui(ui, |ui| {
                for (k, name) in names.iter().enumerate() {
                    ui.selectable_value(&mut self.residual_photo, k, name);
                }
            });
    }
}

/// Each photograph's fit: name, intensity (estimated or given), relative
/// residual, and the shares used, in shadow and weighted down.
fn fit_table_ui(ui: &mut egui::Ui, solution: &PhotometricSolution) {
    ui.label(format!(
        "set solved in {:.2} s: smoothness {:.3e}, {} linearisations, intensities {}",
        solution.seconds,
        solution.alpha,
        solution.iterations,
        if solution.intensities_estimated {
            "estimated"
        } else {
            "given"
        }
    ));
    for warning in sfs_core::solver::photometric::warnings(solution) {
        ui.colored_label(ui.visuals().warn_fg_color, format!("warning: {warning}"));
    }
    egui::Grid::new("set fit").striped(true).show(ui, |ui| {
        ui.strong("photograph");
        ui.strong("intensity")
            .on_hover_text(if solution.intensities_estimated {
                "estimated (semi-calibrated), geometric mean 1 over the set"
            } else {
                "given by the camera file"
            });
        ui.strong("residual")
            .on_hover_text("||prediction − I|| / ||I|| over its used observations");
        ui.strong("used");
        ui.strong("shadow")
            .on_hover_text("left out as attached or cast shadow");
        ui.strong("robust")
            .on_hover_text("weighted down below half by the robust estimator");
        ui.end_row();
        for photo in &solution.photos {
            let name = std::path::Path::new(&photo.name);
            ui.label(crate::app::document::file_name(name))
                .on_hover_text(photo.name.as_str());
            ui.label(format!("{:.3}", photo.intensity));
            ui.label(format!("{:.4}", photo.relative_residual));
            ui.label(format!("{:.0} %", 100.0 * photo.used_share));
            ui.label(format!("{:.0} %", 100.0 * photo.shadow_share));
            ui.label(format!("{:.1} %", 100.0 * photo.robust_share));
            ui.end_row();
        }
    });
}
