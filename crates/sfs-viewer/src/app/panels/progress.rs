//! The solve's section at the top of the controls: progress, the fit in one
//! line with its warnings, the material and known-distance fits, cancel,
//! solve again and the energy plot.

use eframe::egui;

use super::{Action, Panels, UiContext};
use sfs_core::solver::{Solution, material_fit};

impl Panels {
    pub(super) fn progress_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let s = &cx.session.solve;
        let running = s.running;
        // `auto`: the material is fitted before the solve reports anything.
        let fitting = s.running
            && s.energies.is_empty()
            && cx.settings.params.to_params().fixed_material().is_none();
        ui.horizontal(|ui| {
            if fitting {
                ui.spinner();
                ui.label(format!(
                    "fitting the reflectance ({} solves on a {} px copy)",
                    material_fit::candidates().len(),
                    material_fit::FIT_SIDE
                ))
                .on_hover_text(
                    "reflectance auto: every candidate material is solved on a coarse copy \
                     of the image and their energies compared; the solve follows",
                );
            } else if s.running {
                ui.spinner();
                let p = &s.progress;
                ui.label(format!(
                    "level {} of {} ({}x{}), iteration {}",
                    p.level + 1,
                    p.levels.max(1),
                    p.size.0,
                    p.size.1,
                    p.iteration + 1
                ));
                let searching = cx
                    .session
                    .document
                    .as_ref()
                    .is_some_and(|d| !d.known_depths.is_empty());
                if searching && s.search_solve > 0 {
                    ui.label(format!("(scale search, solve {})", s.search_solve))
                        .on_hover_text(
                            "The depth scale is searched until the surface meets the known \
                             distances: each solve runs through the levels again",
                        );
                }
            } else if let Some(done) = s.finished() {
                // The whole wait: the final solve is only its last part
                // where the depth unit was searched.
                match s.waited_seconds {
                    Some(waited) => {
                        ui.label(format!("done in {waited:.2} s"))
                            .on_hover_text(format!(
                                "from the request to the result; the final solve took {:.2} s \
                             (before it: the depth unit's searches and the albedo decision)",
                                done.seconds
                            ))
                    }
                    None => ui.label(format!("done in {:.2} s", done.seconds)),
                };
            } else if let Some(done) = &s.set {
                ui.label(format!("set done in {:.2} s", done.seconds));
            } else if s.failure.is_some() {
                ui.colored_label(ui.visuals().error_fg_color, "solve failed");
            } else {
                ui.label("idle");
            }
        });
        if s.running {
            ui.label(format!(
                "energy per pixel {:.4e}, {:.2} s",
                s.progress.energy_per_pixel,
                s.progress.elapsed.as_secs_f64()
            ));
        }
        if let Some((rse, rie)) = s.errors {
            ui.label(format!("against ground truth: RSE {rse:.5}, RIE {rie:.5}"));
        }
        let units = cx
            .session
            .document
            .as_ref()
            .map_or("depth units", |d| d.depth_units())
            .to_owned();
        fit_line(ui, s, &units);
        if let Some(share) = s.shadow_share() {
            ui.label(format!(
                "shadow: {:.1} % of the object taken out of the data term",
                100.0 * share
            ))
            .on_hover_text(
                "no light reaches these pixels (near-black against the image's reference \
                 brightness and its noise): they say the surface is turned away or hidden, \
                 not how bright it is; the fill continues the lit surface there. \
                 Mask > shadows shows them in violet.",
            );
        }
        if let Some(s_used) = s.intensity_scale_used() {
            ui.weak(format!("intensity scale used: {s_used:.4e}"));
        }
        if let Some(solution) = s.finished() {
            material_ui(ui, solution);
        }
        if let Some(fit) = s.known_depth_fit() {
            ui.label(fit_summary(fit)).on_hover_text(
                "The intensity scale s that puts the surface at the known distances (relative \
                 least squares); residuals: (solved - given) / given at each point",
            );
        }
        if let Some(failure) = &s.failure {
            ui.colored_label(ui.visuals().error_fg_color, failure.clone());
        }
        ui.horizontal(|ui| {
            if ui
                .add_enabled(running, egui::Button::new("Cancel"))
                .clicked()
            {
                cx.actions.push(Action::CancelSolve);
            }
            if ui.button("Solve again").clicked() {
                cx.actions.push(Action::SolveNow);
            }
        });
        crate::app::energy_plot::energy_plot(ui, &cx.session.solve.energies);
    }
}

/// Candidates of a material fit listed under its summary.
const TRIALS_SHOWN: usize = 5;

/// The material a solve used (when not Lambert or fitted), and with
/// `reflectance auto` what the fit found and its best candidates.
fn material_ui(ui: &mut egui::Ui, solution: &Solution) {
    if solution.material.is_lambert() && solution.material_fit.is_none() {
        return;
    }
    ui.label(format!("reflectance: {}", solution.material.describe()))
        .on_hover_text("The reflectance model the surface was solved with (METHOD.md section 10)");
    let Some(fit) = &solution.material_fit else {
        return;
    };
    let text = format!("material fit ({:.1} s): {}", fit.seconds, fit.summary);
    let hover = format!(
        "reflectance auto: each of the {} candidates solved on a {} px copy of the image and \
         ranked by energy (data term plus smoothness), each with its residual; the solve used \
         the reflectance above. To solve as another model, choose it under Parameters",
        fit.trials.len(),
        fit.working_side
    );
    if !fit.determined && !fit.best.is_lambert() {
        ui.colored_label(ui.visuals().warn_fg_color, format!("warning: {text}"))
            .on_hover_text(hover.as_str());
    } else {
        ui.label(text).on_hover_text(hover.as_str());
    }
    egui::CollapsingHeader::new(format!(
        "best {} of {} candidates",
        TRIALS_SHOWN.min(fit.trials.len()),
        fit.trials.len()
    ))
    .id_salt("material candidates")
    .default_open(false)
    .show(ui, |ui| {
        let best = fit.trials.iter().take(TRIALS_SHOWN);
        // Lambert's row for comparison when it is not among the best.
        let lambert = fit
            .trials
            .iter()
            .skip(TRIALS_SHOWN)
            .find(|t| t.material.is_lambert());
        egui::Grid::new("material trials")
            .striped(true)
            .show(ui, |ui| {
                ui.strong("material");
                ui.strong("energy")
                    .on_hover_text("the solve's final energy relative to the best candidate's");
                ui.strong("residual")
                    .on_hover_text("sqrt(sum c (I - R)^2 / sum c I^2) of the candidate's solve");
                ui.end_row();
                for trial in best.chain(lambert) {
                    ui.label(trial.material.short())
                        .on_hover_text(trial.material.describe());
                    ui.label(format!("×{:.3}", trial.relative_energy));
                    ui.label(format!("{:.4}", trial.relative_residual));
                    ui.end_row();
                }
            });
    });
}

/// The side panel's line on a known-distance fit: the scale, each
/// point's relative residual and how precisely the points fix the scale
/// (unless loosely: that is a warning of its own).
/// The fit in one line, coloured (green: explained, no warning; orange:
/// warnings; red: much of the image unexplained or the depth unit a
/// guess), with the one thing to do next; the figures on hover and the
/// warnings in a list that opens.
fn fit_line(ui: &mut egui::Ui, s: &crate::app::session::SolveState, units: &str) {
    let warnings = s.warnings();
    let Some(fit) = s.fit() else {
        if let Some(unit) = s.depth_unit() {
            ui.label(unit.words(units));
        }
        return;
    };
    let guess = s
        .depth_unit()
        .is_some_and(|u| u.source == sfs_core::solver::depth_unit::UnitSource::Guess);
    let (colour, verdict) = if fit.poor_share > 0.3 || guess {
        (ui.visuals().error_fg_color, "poor")
    } else if warnings.is_empty() {
        (egui::Color32::from_rgb(60, 170, 80), "good")
    } else {
        (ui.visuals().warn_fg_color, "fair")
    };
    let next = if s.depth_unit().is_some_and(|u| u.wants_distance()) {
        "next: give the object's distance (Known distance)"
    } else if fit.near_black_share > 0.05 || fit.poor_share > 0.15 {
        "next: paint the shadows and highlights low confidence (Mask)"
    } else {
        ""
    };
    let mut line = format!(
        "fit {verdict}: RIE {:.3}, {:.0} % badly explained",
        fit.rie_trusted,
        100.0 * fit.poor_share
    );
    if !next.is_empty() {
        line.push_str(" — ");
        line.push_str(next);
    }
    ui.colored_label(colour, line).on_hover_text(format!(
        "RIE: relative image error of the reprojection over trusted object pixels; badly \
         explained: residual above 15 %; {:.0} % near-black, {:.1} % saturated. See the \
         residual panel.",
        100.0 * fit.near_black_share,
        100.0 * fit.saturated_share
    ));
    if let Some(unit) = s.depth_unit() {
        ui.weak(unit.words(units));
    }
    if !warnings.is_empty() {
        egui::CollapsingHeader::new(format!(
            "{} warning{}",
            warnings.len(),
            if warnings.len() == 1 { "" } else { "s" }
        ))
        .id_salt("solve warnings")
        .show(ui, |ui| {
            for warning in warnings {
                ui.colored_label(ui.visuals().warn_fg_color, warning);
            }
        });
    }
}

fn fit_summary(fit: &sfs_core::solver::calibrate::KnownDepthFit) -> String {
    let n = fit.points.len();
    let residuals: Vec<String> = fit
        .points
        .iter()
        .map(|p| format!("{:+.2} %", 100.0 * p.relative_residual))
        .collect();
    let mut summary = format!(
        "s = {:.4e} from {n} known distance{}; residuals {}",
        fit.intensity_scale,
        if n == 1 { "" } else { "s" },
        residuals.join(", ")
    );
    // A loose scale's words are its warning instead.
    if let Some(precision) = fit.scale_precision.filter(|p| !p.is_loose()) {
        summary.push_str("; ");
        summary.push_str(&precision.words(n));
    }
    summary
}
