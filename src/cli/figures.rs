//! Figures of the benchmark report: image grids (grey values, colour-mapped
//! depth and differences) and labelled log-log line plots, written as PNG.
//! Plots carry decade tick labels, axis names and a legend in a small
//! built-in 5x7 pixel font; report.md carries the captions.

use std::path::Path;

use anyhow::{Context, Result};

use sfs_core::colour::colour_map;
use sfs_core::grid::Grid;

/// An RGB picture being composed.
pub struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

/// How a panel's values become colours.
#[derive(Clone, Copy, Debug)]
pub enum Shade {
    /// Grey from `range[0]` (black) to `range[1]` (white).
    Grey([f64; 2]),
    /// The colour map over the range.
    Colour([f64; 2]),
}

impl Canvas {
    /// A white canvas.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            rgb: vec![255; width * height * 3],
        }
    }

    /// Sets one pixel (ignored outside the canvas).
    pub fn put(&mut self, x: isize, y: isize, colour: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            let i = (y as usize * self.width + x as usize) * 3;
            self.rgb[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Draws `values` with its top-left corner at `(x, y)`, shrunk by the
    /// integer factor `step` (block average of finite values); NaN is drawn
    /// light grey.
    pub fn panel(&mut self, values: &Grid<f64>, shade: Shade, x: usize, y: usize, step: usize) {
        let step = step.max(1);
        let (w, h) = values.size();
        for r in 0..h / step {
            for c in 0..w / step {
                let (mut sum, mut n) = (0.0, 0usize);
                for rr in r * step..(r + 1) * step {
                    for cc in c * step..(c + 1) * step {
                        let v = *values.at(cc, rr);
                        if v.is_finite() {
                            sum += v;
                            n += 1;
                        }
                    }
                }
                let colour = if n == 0 {
                    [225, 225, 225]
                } else {
                    let v = sum / n as f64;
                    match shade {
                        Shade::Grey([lo, hi]) => {
                            let t = ((v - lo) / (hi - lo).max(1e-300)).clamp(0.0, 1.0);
                            let g = (t * 255.0).round() as u8;
                            [g, g, g]
                        }
                        Shade::Colour([lo, hi]) => {
                            colour_map(((v - lo) / (hi - lo).max(1e-300)) as f32)
                        }
                    }
                };
                self.put((x + c) as isize, (y + r) as isize, colour);
            }
        }
    }

    /// Draws a line from `a` to `b` (pixel coordinates), `thickness` pixels wide.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), colour: [u8; 3], thickness: isize) {
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            for dy in 0..thickness {
                for dx in 0..thickness {
                    self.put(x.round() as isize + dx, y.round() as isize + dy, colour);
                }
            }
        }
    }

    /// Draws `text` with its top-left corner at `(x, y)` in the built-in
    /// 5x7 font, each font pixel `scale` pixels wide; characters without a
    /// glyph are left blank.
    pub fn text(&mut self, x: isize, y: isize, text: &str, colour: [u8; 3], scale: isize) {
        for (i, ch) in text.chars().enumerate() {
            let Some(rows) = glyph(ch) else { continue };
            let left = x + i as isize * 6 * scale;
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..5 {
                    if bits & (0b10000 >> c) != 0 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                self.put(
                                    left + c * scale + dx,
                                    y + r as isize * scale + dy,
                                    colour,
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// Writes the canvas as an 8-bit RGB PNG.
    pub fn save(self, path: &Path) -> Result<()> {
        let image = image::RgbImage::from_raw(self.width as u32, self.height as u32, self.rgb)
            .context("figure buffer has the wrong size")?;
        image
            .save(path)
            .with_context(|| format!("cannot write figure {}", path.display()))
    }
}

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: isize) -> isize {
    text.chars().count() as isize * 6 * scale
}

/// The 5x7 glyph of a character (rows top to bottom, bit 4 = leftmost), for
/// the characters the plots need.
#[rustfmt::skip]
fn glyph(ch: char) -> Option<[u8; 7]> {
    Some(match ch {
        '0' => [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110],
        '1' => [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        '2' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111],
        '3' => [0b11110, 0b00001, 0b00001, 0b01110, 0b00001, 0b00001, 0b11110],
        '4' => [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010],
        '5' => [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110],
        '6' => [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110],
        '7' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000],
        '8' => [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110],
        '9' => [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100],
        '-' => [0, 0, 0, 0b11111, 0, 0, 0],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100],
        '(' => [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010],
        ')' => [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000],
        'a' => [0, 0, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111],
        'b' => [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110],
        'c' => [0, 0, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110],
        'd' => [0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111],
        'e' => [0, 0, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110],
        'i' => [0b00100, 0, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110],
        'l' => [0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        'n' => [0, 0, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001],
        'o' => [0, 0, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110],
        'p' => [0, 0, 0b11110, 0b10001, 0b11110, 0b10000, 0b10000],
        'r' => [0, 0, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000],
        's' => [0, 0, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110],
        't' => [0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110],
        'x' => [0, 0, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001],
        'f' => [0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000],
        'g' => [0, 0b01111, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110],
        'h' => [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001],
        'j' => [0b00010, 0, 0b00110, 0b00010, 0b00010, 0b10010, 0b01100],
        'k' => [0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010],
        'm' => [0, 0, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001],
        'q' => [0, 0, 0b01101, 0b10011, 0b01111, 0b00001, 0b00001],
        'u' => [0, 0, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101],
        'v' => [0, 0, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100],
        'w' => [0, 0, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010],
        'y' => [0, 0, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110],
        'z' => [0, 0, 0b11111, 0b00010, 0b00100, 0b01000, 0b11111],
        'E' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111],
        'R' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001],
        'S' => [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110],
        ' ' => [0; 7],
        _ => return None,
    })
}

/// Finite minimum and maximum of several grids.
pub fn range_of<'a>(grids: impl IntoIterator<Item = &'a Grid<f64>>) -> [f64; 2] {
    let mut range = [f64::INFINITY, f64::NEG_INFINITY];
    for g in grids {
        for &v in g.as_slice() {
            if v.is_finite() {
                range[0] = range[0].min(v);
                range[1] = range[1].max(v);
            }
        }
    }
    if range[0] > range[1] {
        [0.0, 1.0]
    } else {
        range
    }
}

/// Lays out panels (all of one size) in a grid with 4 px gaps; returns the
/// canvas. `rows[i][j]` is a panel and how to shade it; `step` shrinks each.
pub fn panel_grid(rows: &[Vec<(&Grid<f64>, Shade)>], step: usize) -> Canvas {
    let gap = 4;
    let (pw, ph) = rows.iter().flatten().next().map_or((1, 1), |(g, _)| {
        (g.width() / step.max(1), g.height() / step.max(1))
    });
    let columns = rows.iter().map(Vec::len).max().unwrap_or(0);
    let mut canvas = Canvas::new(columns * (pw + gap) + gap, rows.len() * (ph + gap) + gap);
    for (i, row) in rows.iter().enumerate() {
        for (j, (grid, shade)) in row.iter().enumerate() {
            canvas.panel(
                grid,
                *shade,
                gap + j * (pw + gap),
                gap + i * (ph + gap),
                step,
            );
        }
    }
    canvas
}

/// A curve of a plot: its colour, legend label and `(x, y)` points
/// (positive values).
pub struct Series<'a> {
    /// Line colour.
    pub colour: [u8; 3],
    /// Legend text.
    pub label: &'a str,
    /// Points, x increasing.
    pub points: &'a [(f64, f64)],
}

/// The decade range `[10^floor(log10 min), 10^ceil(log10 max)]` of positive values.
pub fn decades(values: impl Iterator<Item = f64>) -> [f64; 2] {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return [0.1, 1.0];
    }
    let lo = 10f64.powf(lo.log10().floor());
    let mut hi = 10f64.powf(hi.log10().ceil());
    if hi <= lo {
        hi = lo * 10.0;
    }
    [lo, hi]
}

/// A log-log plot of `series` over the given decade ranges: light grey
/// gridlines and `1eN` labels at every decade, black axes named `x_name` and
/// `y_name`, 2 px lines and a legend.
pub fn log_log_plot(
    series: &[Series],
    x_range: [f64; 2],
    y_range: [f64; 2],
    x_name: &str,
    y_name: &str,
) -> Canvas {
    let (w, h) = (720usize, 440usize);
    let (left, right, top, bottom) = (64.0, 20.0, 34.0, 44.0);
    let mut canvas = Canvas::new(w, h);
    let (x0, x1) = (x_range[0].log10(), x_range[1].log10());
    let (y0, y1) = (y_range[0].log10(), y_range[1].log10());
    let to_px = |x: f64, y: f64| {
        let u = (x.log10() - x0) / (x1 - x0);
        let v = (y.log10() - y0) / (y1 - y0);
        (
            left + u * (w as f64 - left - right),
            h as f64 - bottom - v * (h as f64 - top - bottom),
        )
    };
    let grey = [215, 215, 215];
    let black = [0, 0, 0];
    let mut d = x0.round() as i32;
    while f64::from(d) <= x1 + 1e-9 {
        let x = 10f64.powi(d);
        canvas.line(to_px(x, y_range[0]), to_px(x, y_range[1]), grey, 1);
        let (px, py) = to_px(x, y_range[0]);
        let label = format!("1e{d}");
        canvas.text(
            px as isize - text_width(&label, 1) / 2,
            py as isize + 6,
            &label,
            black,
            1,
        );
        d += 1;
    }
    let mut d = y0.round() as i32;
    while f64::from(d) <= y1 + 1e-9 {
        let y = 10f64.powi(d);
        canvas.line(to_px(x_range[0], y), to_px(x_range[1], y), grey, 1);
        let (px, py) = to_px(x_range[0], y);
        let label = format!("1e{d}");
        canvas.text(
            px as isize - text_width(&label, 1) - 6,
            py as isize - 3,
            &label,
            black,
            1,
        );
        d += 1;
    }
    let (ax, ay) = to_px(x_range[1], y_range[0]);
    canvas.text(
        ax as isize - text_width(x_name, 2),
        ay as isize + 20,
        x_name,
        black,
        2,
    );
    canvas.text(4, 4, y_name, black, 2);
    let mut legend_y = top as isize + 6;
    for s in series {
        let lx = w as isize - right as isize - text_width(s.label, 2) - 40;
        canvas.line(
            (lx as f64, legend_y as f64 + 6.0),
            (lx as f64 + 28.0, legend_y as f64 + 6.0),
            s.colour,
            3,
        );
        canvas.text(lx + 34, legend_y, s.label, s.colour, 2);
        legend_y += 20;
    }
    canvas.line(
        to_px(x_range[0], y_range[0]),
        to_px(x_range[1], y_range[0]),
        black,
        1,
    );
    canvas.line(
        to_px(x_range[0], y_range[0]),
        to_px(x_range[0], y_range[1]),
        black,
        1,
    );
    for s in series {
        let points: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
            .map(|&(x, y)| {
                to_px(
                    x.clamp(x_range[0], x_range[1]),
                    y.clamp(y_range[0], y_range[1]),
                )
            })
            .collect();
        for pair in points.windows(2) {
            canvas.line(pair[0], pair[1], s.colour, 2);
        }
        for &(x, y) in &points {
            for dy in -2..=2 {
                for dx in -2..=2 {
                    canvas.put(x as isize + dx, y as isize + dy, s.colour);
                }
            }
        }
    }
    canvas
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_lower_case_letter_and_digit_has_a_glyph() {
        // Legends such as "fast marching" and "multigrid" lost letters.
        for ch in ('a'..='z').chain('0'..='9') {
            assert!(glyph(ch).is_some(), "no glyph for {ch:?}");
        }
    }

    #[test]
    fn panels_and_plots_draw_where_asked() {
        let g = Grid::from_fn(8, 4, |c, _| c as f64);
        let canvas = panel_grid(
            &[vec![
                (&g, Shade::Grey([0.0, 7.0])),
                (&g, Shade::Colour([0.0, 7.0])),
            ]],
            1,
        );
        assert_eq!((canvas.width, canvas.height), (2 * 12 + 4, 12));
        // First panel: black at its left, white at its right.
        let at = |x: usize, y: usize| {
            let i = (y * canvas.width + x) * 3;
            [canvas.rgb[i], canvas.rgb[i + 1], canvas.rgb[i + 2]]
        };
        assert_eq!(at(4, 4), [0, 0, 0]);
        assert_eq!(at(11, 4), [255, 255, 255]);
        assert_eq!(decades([0.003, 0.2].into_iter()), [0.001, 1.0]);
        let points = [(0.1, 0.5), (10.0, 0.01)];
        let plot = log_log_plot(
            &[Series {
                colour: [255, 0, 0],
                label: "explicit",
                points: &points,
            }],
            [0.1, 10.0],
            [0.01, 1.0],
            "seconds",
            "RSE",
        );
        assert!(plot.rgb.chunks(3).any(|p| p == [255, 0, 0]));
        // Labels are drawn in black below the axis.
        let black = plot.rgb.chunks(3).filter(|p| *p == [0, 0, 0]).count();
        assert!(black > 700 + 400, "{black} black pixels");
        for ch in "0123456789-.e seconds RSE linearised explicit".chars() {
            assert!(glyph(ch).is_some(), "{ch}");
        }
    }
}
