//! The energy plot under the solve's progress: the energy per pixel (total
//! divided by the level's `w·h`, so that levels of different sizes compare)
//! after every outer iteration of the job, levels coarse to fine with a faint
//! line where a level starts, on a log scale (log10 values, axis labels in
//! powers of ten), and a readout of level, iteration and value under the
//! pointer. Uses egui_plot and `session::EnergyPoint`; no state of its own.

use eframe::egui;
use egui_plot::{AxisHints, HoverPosition, Line, Plot, PlotPoints, Text, VLine};

use super::session::EnergyPoint;

/// Height of the plot, in points.
const HEIGHT: f32 = 120.0;

/// The points the plot can show (a log scale: finite and positive), in
/// order; the plot's x is the position in this list, counted from 1.
pub fn plotted(energies: &[EnergyPoint]) -> Vec<EnergyPoint> {
    energies
        .iter()
        .copied()
        .filter(|e| e.per_pixel.is_finite() && e.per_pixel > 0.0)
        .collect()
}

/// The label of a log10 axis mark: `1e-4` on a power of ten, else the value
/// with two significant digits (`3.2e-4`).
pub fn power_of_ten_label(log10: f64) -> String {
    if (log10 - log10.round()).abs() < 1e-9 {
        format!("1e{}", log10.round())
    } else {
        format!("{:.1e}", 10f64.powf(log10))
    }
}

/// The label of an x axis mark: whole iterations only.
pub fn iteration_label(x: f64) -> String {
    if x >= 1.0 && (x - x.round()).abs() < 1e-9 {
        format!("{}", x.round())
    } else {
        String::new()
    }
}

/// The readout for the pointer at plot x `x` over `points`: the nearest
/// point's level, iteration and energy per pixel (`None` off the data).
pub fn readout(points: &[EnergyPoint], x: f64) -> Option<String> {
    let k = x - 1.0;
    let last = points.len().checked_sub(1)?;
    if !k.is_finite() || k < -0.5 || k > last as f64 + 0.5 {
        return None;
    }
    let point = points[(k.round().max(0.0) as usize).min(last)];
    let step = match point.iteration {
        Some(i) => format!("iteration {}", i + 1),
        None => "start (no iterations)".to_string(),
    };
    Some(format!(
        "level {}, {step}\nenergy per pixel {:.4e}",
        point.level + 1,
        point.per_pixel
    ))
}

/// Draws the plot of `energies` (all of the job's points so far) across the
/// available width.
pub fn energy_plot(ui: &mut egui::Ui, energies: &[EnergyPoint]) {
    let points = plotted(energies);
    let line_colour = ui.visuals().hyperlink_color;
    let weak = ui.visuals().weak_text_color();
    let values: Vec<[f64; 2]> = points
        .iter()
        .enumerate()
        .map(|(k, e)| [k as f64 + 1.0, e.per_pixel.log10()])
        .collect();
    let level_starts: Vec<f64> = (1..points.len())
        .filter(|&k| points[k].level != points[k - 1].level)
        .map(|k| k as f64 + 0.5)
        .collect();
    ui.weak("energy per pixel (total / level w·h), per iteration");
    Plot::new("energy per pixel")
        .height(HEIGHT)
        .allow_zoom(false)
        .allow_drag(false)
        .allow_scroll(false)
        .allow_boxed_zoom(false)
        .allow_axis_zoom_drag(false)
        .allow_double_click_reset(false)
        .show_crosshair(false)
        .include_x(1.0)
        .include_x(2.0)
        .custom_x_axes(vec![
            AxisHints::new_x()
                .label("iteration (all levels)")
                .formatter(|mark, _| iteration_label(mark.value))
                .label_spacing(20.0..=30.0),
        ])
        .y_axis_formatter(|mark, _| power_of_ten_label(mark.value))
        .y_axis_min_width(36.0)
        .label_formatter(|position: &HoverPosition<'_>| {
            let x = match position {
                HoverPosition::NearDataPoint { index, .. } => *index as f64 + 1.0,
                HoverPosition::Elsewhere { position } => position.x,
            };
            readout(&points, x)
        })
        .show(ui, |plot| {
            if values.is_empty() {
                let middle = egui_plot::PlotPoint::new(1.5, 0.0);
                plot.text(Text::new("waiting", middle, "no iteration yet").color(weak));
                return;
            }
            for x in level_starts {
                plot.add(
                    VLine::new("level start", x)
                        .color(weak.gamma_multiply(0.5))
                        .allow_hover(false),
                );
            }
            plot.line(
                Line::new("energy per pixel", PlotPoints::new(values))
                    .color(line_colour)
                    .width(1.5),
            );
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(level: usize, iteration: Option<usize>, per_pixel: f64) -> EnergyPoint {
        EnergyPoint {
            level,
            iteration,
            per_pixel,
        }
    }

    #[test]
    fn log_axis_labels_and_readout() {
        assert_eq!(power_of_ten_label(-4.0), "1e-4");
        assert_eq!(power_of_ten_label(0.0), "1e0");
        assert_eq!(power_of_ten_label(2.0_f64.log10() - 3.0), "2.0e-3");
        let energies = [
            point(0, None, 4e-3),
            point(1, Some(0), f64::NAN),
            point(1, Some(1), 2.5e-4),
            point(1, Some(2), 0.0),
            point(1, Some(3), 1.25e-4),
        ];
        let points = plotted(&energies);
        assert_eq!(points.len(), 3);
        let first = readout(&points, 1.2).expect("over the first point");
        assert!(first.contains("level 1, start") && first.contains("4.0000e-3"));
        let last = readout(&points, 3.4).expect("over the last point");
        assert!(
            last.contains("level 2, iteration 4") && last.contains("1.2500e-4"),
            "{last}"
        );
        assert_eq!(readout(&points, 3.6), None);
        assert_eq!(readout(&points, 0.4), None);
        assert_eq!(readout(&[], 1.0), None);
        assert_eq!(iteration_label(3.0), "3");
        assert_eq!(iteration_label(2.5), "");
        assert_eq!(iteration_label(0.0), "");
    }
}
