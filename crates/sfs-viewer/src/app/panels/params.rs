//! The "Parameters" section: the albedo estimate and its fit, the parameter
//! table's sliders and selectors, the start selector and the defaults.

use eframe::egui;

use super::{Action, Panels, UiContext};
use crate::app::settings::InitialChoice;
use sfs_core::params::{AlbedoChoice, PARAMS, ParamKind, ParamValue, SolverParams};

impl Panels {
    pub(super) fn params_ui(&mut self, ui: &mut egui::Ui, cx: &mut UiContext<'_>) {
        let defaults = SolverParams::default();
        let mut p = cx.settings.params.to_params();
        let chosen_alpha = cx.session.solve.finished().map(|s| s.alpha);
        let mut changed = false;
        let mut estimate_albedo = p.albedo == AlbedoChoice::Auto;
        if ui
            .checkbox(&mut estimate_albedo, "estimate the albedo")
            .on_hover_text(
                "Albedo auto: dark marks (brows, text, paint) estimated as albedo with the \
                 shape and used where they explain the photograph better than albedo 1; \
                 'albedo edge' is its prior's weight. Off: all brightness is shading.",
            )
            .changed()
        {
            p.albedo = if estimate_albedo {
                AlbedoChoice::Auto
            } else {
                AlbedoChoice::One
            };
            changed = true;
        }
        if let Some(fit) = cx
            .session
            .solve
            .finished()
            .and_then(|s| s.albedo_fit.as_ref())
        {
            let text = egui::RichText::new(&fit.summary).small();
            let text = if fit.is_close_call() {
                text.color(ui.visuals().warn_fg_color)
            } else {
                text
            };
            ui.label(text)
                .on_hover_text("How the albedo estimate compared with albedo 1 on this solve");
        }
        for spec in PARAMS {
            // A model's own parameters only while it is chosen.
            let Some((low, high)) = spec.slider.filter(|_| p.applies(spec.name)) else {
                continue;
            };
            let tooltip = format!("{} Default: {}.", spec.help, (spec.get)(&defaults));
            let value = (spec.get)(&p);
            match (spec.kind, value) {
                (ParamKind::Choice(words), ParamValue::Choice(chosen)) => {
                    // One line, labelled on the right as the sliders are.
                    let mut picked = chosen;
                    egui::ComboBox::from_label(spec.label)
                        .selected_text(chosen)
                        .show_ui(ui, |ui| {
                            for &word in words {
                                ui.selectable_value(&mut picked, word, word);
                            }
                        })
                        .response
                        .on_hover_text(tooltip.as_str());
                    if picked != chosen {
                        (spec.set)(&mut p, ParamValue::Choice(picked));
                        changed = true;
                    }
                }
                (ParamKind::Real { log, auto, .. }, value) => {
                    let mut number = match value {
                        ParamValue::Real(v) => v,
                        // Auto shows the value the last solve chose.
                        _ => chosen_alpha.filter(|a| a.is_finite()).unwrap_or(low),
                    };
                    ui.horizontal(|ui| {
                        if auto {
                            let mut is_auto = value == ParamValue::Auto;
                            if ui
                                .checkbox(&mut is_auto, "auto")
                                .on_hover_text("Let the solver choose from the image's noise level; the slider shows its choice")
                                .changed()
                            {
                                let new = if is_auto {
                                    ParamValue::Auto
                                } else {
                                    ParamValue::Real(number)
                                };
                                (spec.set)(&mut p, new);
                                changed = true;
                            }
                        }
                        if ui
                            .add(
                                egui::Slider::new(&mut number, low..=high)
                                    .logarithmic(log)
                                    .custom_formatter(|v, _| slider_number(v))
                                    .text(spec.label),
                            )
                            .on_hover_text(tooltip.as_str())
                            .changed()
                        {
                            (spec.set)(&mut p, ParamValue::Real(number));
                            changed = true;
                        }
                    });
                }
                (ParamKind::Count { .. }, ParamValue::Count(mut count)) => {
                    let range = (low as usize)..=(high as usize);
                    if ui
                        .add(egui::Slider::new(&mut count, range).text(spec.label))
                        .on_hover_text(tooltip.as_str())
                        .changed()
                    {
                        (spec.set)(&mut p, ParamValue::Count(count));
                        changed = true;
                    }
                }
                _ => {}
            }
        }
        let lights_off_centre = cx
            .session
            .document
            .as_ref()
            .is_some_and(|d| !sfs_core::light::is_centred(&d.camera.solve_lights()));
        let [fast_marching, from_image] = start_labels(lights_off_centre);
        let initial = &mut cx.settings.params.initial_depth;
        let before = *initial;
        ui.horizontal_wrapped(|ui| {
            ui.label("start")
                .on_hover_text("Initial depth: fast marching refined at full resolution (default), the paper's constant depth from the brightest pixel, or a constant, each followed by the solver. With lights off the optical centre fast marching runs in the lights' own frame (within 20 degrees of the camera and a third of the way to the object), else from the best-fitting plane; the paper's start is that plane");
            ui.selectable_value(initial, InitialChoice::FastMarching, fast_marching.0)
                .on_hover_text(fast_marching.1.as_str());
            ui.selectable_value(initial, InitialChoice::FromImage, from_image.0)
                .on_hover_text(from_image.1.as_str());
            if ui
                .selectable_label(matches!(initial, InitialChoice::Constant(_)), "constant")
                .clicked()
                && !matches!(initial, InitialChoice::Constant(_))
            {
                *initial = InitialChoice::Constant(1.0);
            }
            if let InitialChoice::Constant(z) = initial {
                let label = ui.label("depth").id;
                ui.add(egui::DragValue::new(z).range(1e-3..=1e6).speed(0.01))
                    .labelled_by(label);
            }
        });
        if *initial != before {
            p.initial_depth = cx.settings.params.to_params().initial_depth;
            changed = true;
        }
        if ui
            .button("defaults")
            .on_hover_text("Restore every parameter to its default (alpha auto)")
            .clicked()
        {
            p = SolverParams {
                albedo: AlbedoChoice::Auto,
                ..SolverParams::default()
            };
            changed = true;
        }
        if changed {
            cx.settings.params = crate::app::ParamSettings::from_params(&p);
            cx.actions.push(Action::RequestSolve);
        }
    }
}

/// The start selector's `(label, hover text)` for fast marching and for the
/// paper's start from the image. With the solve's lights off the centre
/// fast marching runs in the lights' own frame when they are within 20
/// degrees of the camera (seen from the object), else the solver starts
/// from the best-fitting plane (`sfs_core::solver::prepare`); the paper's
/// start from the image is then that plane; the labels say so.
fn start_labels(lights_off_centre: bool) -> [(&'static str, String); 2] {
    if lights_off_centre {
        [
            (
                "fast marching (in the lights' frame)",
                format!(
                    "Fast marching solves the light at the optical centre: with these lights it \
                     is marched in their own frame (a camera at the lights, where they are \
                     centred) and refined by the solver at full resolution. Lights more than 20 \
                     degrees off the camera, seen from the object, or more than a third of the \
                     way to it, start from the constant depth (fronto-parallel plane) whose \
                     rendering best fits the image, refined through the whole pyramid: on an \
                     image more than {} pixels on a side, the pyramid of a {}-pixel working copy, \
                     whose surface is then refined at full resolution.",
                    sfs_core::solver::WALK_ABOVE_SIDE,
                    sfs_core::solver::WALK_SIDE
                ),
            ),
            (
                "from image (lights off the centre: best-fitting plane)",
                "The paper's constant from the brightest pixel assumes the light at the optical \
                 centre. With these lights the solver starts from the constant depth \
                 (fronto-parallel plane) whose rendering best fits the image, refined through \
                 the whole pyramid."
                    .into(),
            ),
        ]
    } else {
        [
            (
                "fast marching",
                "Fast marching on the (denoised) image, refined by the solver at full \
                 resolution (the default)."
                    .into(),
            ),
            (
                "from image",
                "The paper's start: a constant depth from the brightest pixel, refined through \
                 the whole pyramid."
                    .into(),
            ),
        ]
    }
}

/// A slider's number: scientific notation where plain decimals would show
/// only zeros or too many digits (alpha is around 1e-7 in relative units).
fn slider_number(value: f64) -> String {
    let magnitude = value.abs();
    if magnitude != 0.0 && !(1e-3..1e5).contains(&magnitude) {
        format!("{value:.3e}")
    } else {
        format!("{}", (value * 1e4).round() / 1e4)
    }
}
