//! Figures of the benchmark reports, drawn with `plotters` on an RGB bitmap
//! and written as PNG: panel grids (images side by side, each under its
//! title, in grey or the colour map) and log-log line plots with gridlines,
//! tick labels, axis names, a title and a legend. Text is set in DejaVu Sans
//! (`crates/sfs-bench/assets/fonts`), compiled in and registered with
//! `plotters` once, so no system font is needed; report.md and speed.md
//! carry the captions.

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::coord::combinators::WithKeyPoints;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use sfs_core::colour::colour_map;
use sfs_core::grid::Grid;

/// The family name the figures' font is registered under.
const FONT: &str = "sans-serif";
/// DejaVu Sans 2.37 (licence: `assets/fonts/LICENSE-DejaVu.txt`).
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
/// Panels' titles, tick labels and legends, pixels.
const SMALL_TEXT: f64 = 14.0;
/// Axis names, pixels.
const AXIS_TEXT: f64 = 16.0;
/// Plot titles, pixels.
const TITLE_TEXT: f64 = 18.0;
/// Light grey of a panel's pixels with no finite value.
const MISSING: [u8; 3] = [225, 225, 225];

/// Registers the compiled-in font with `plotters` (once per process).
fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let registered = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok()
    });
    anyhow::ensure!(
        registered,
        "the figures' font (DejaVu Sans) is not a valid font"
    );
    Ok(())
}

/// The figures' text style at `size` pixels, black.
fn text_style(size: f64) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// The figures' drawing area over a bitmap.
type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// An RGB picture: 8 bits per channel, rows top to bottom.
#[derive(Clone, Debug)]
pub struct Figure {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Figure {
    /// A white picture of `width` x `height` pixels, drawn on by `draw`.
    fn drawn(width: u32, height: u32, draw: impl FnOnce(&Area<'_>) -> Result<()>) -> Result<Self> {
        register_font()?;
        let mut rgb = vec![255; width as usize * height as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
            draw(&root)?;
            root.present().context("cannot finish a figure")?;
        }
        Ok(Self { width, height, rgb })
    }

    /// Writes the picture as an 8-bit RGB PNG.
    pub fn save(&self, path: &Path) -> Result<()> {
        image::save_buffer_with_format(
            path,
            &self.rgb,
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .with_context(|| format!("cannot write figure {}", path.display()))
    }
}

/// How a panel's values become colours.
#[derive(Clone, Copy, Debug)]
pub enum Shade {
    /// Grey from `range[0]` (black) to `range[1]` (white).
    Grey([f64; 2]),
    /// The colour map over the range.
    Colour([f64; 2]),
}

impl Shade {
    /// The colour of `value`.
    fn colour(self, value: f64) -> [u8; 3] {
        match self {
            Shade::Grey([lo, hi]) => {
                let t = ((value - lo) / (hi - lo).max(1e-300)).clamp(0.0, 1.0);
                let g = (t * 255.0).round() as u8;
                [g, g, g]
            }
            Shade::Colour([lo, hi]) => colour_map(((value - lo) / (hi - lo).max(1e-300)) as f32),
        }
    }
}

/// One image of a panel grid.
#[derive(Clone, Copy, Debug)]
pub struct Panel<'a> {
    /// The values; NaN is drawn light grey.
    pub values: &'a Grid<f64>,
    /// How they become colours.
    pub shade: Shade,
    /// The title above the image.
    pub title: &'a str,
}

impl<'a> Panel<'a> {
    /// `values` shaded by `shade` under `title`.
    pub fn new(values: &'a Grid<f64>, shade: Shade, title: &'a str) -> Self {
        Self {
            values,
            shade,
            title,
        }
    }
}

/// The colour of the `step` x `step` block at block `(c, r)` of `panel`: its
/// finite values' mean, shaded; light grey where none is finite.
fn block_colour(panel: &Panel<'_>, c: usize, r: usize, step: usize) -> [u8; 3] {
    let (mut sum, mut n) = (0.0, 0usize);
    for rr in r * step..(r + 1) * step {
        for cc in c * step..(c + 1) * step {
            let v = *panel.values.at(cc, rr);
            if v.is_finite() {
                sum += v;
                n += 1;
            }
        }
    }
    if n == 0 {
        MISSING
    } else {
        panel.shade.colour(sum / n as f64)
    }
}

/// Gap between panels and around them, pixels.
const GAP: u32 = 6;
/// Height of a panel's title line, pixels.
const TITLE_HEIGHT: u32 = 20;

/// Lays out panels (of the first one's size) in rows, each shrunk by the integer
/// factor `step` (block average of the finite values) under its title; a
/// column is as wide as its panel or its widest title.
pub fn panel_grid(rows: &[Vec<Panel<'_>>], step: usize) -> Result<Figure> {
    register_font()?;
    let step = step.max(1);
    let (pw, ph) = rows.iter().flatten().next().map_or((1, 1), |p| {
        (p.values.width() / step, p.values.height() / step)
    });
    let title_width = rows
        .iter()
        .flatten()
        .map(|p| {
            text_style(SMALL_TEXT)
                .font
                .box_size(p.title)
                .map_or(0, |(w, _)| w)
        })
        .max()
        .unwrap_or(0);
    let cell = (pw as u32).max(title_width + 4);
    let columns = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let width = columns * (cell + GAP) + GAP;
    let height = rows.len() as u32 * (TITLE_HEIGHT + ph as u32 + GAP) + GAP;
    Figure::drawn(width, height, |root| {
        root.fill(&WHITE)?;
        let title_style = text_style(SMALL_TEXT).pos(Pos::new(HPos::Center, VPos::Top));
        for (i, row) in rows.iter().enumerate() {
            let top = GAP + i as u32 * (TITLE_HEIGHT + ph as u32 + GAP);
            for (j, panel) in row.iter().enumerate() {
                let left = GAP + j as u32 * (cell + GAP);
                root.draw_text(
                    panel.title,
                    &title_style,
                    ((left + cell / 2) as i32, top as i32 + 3),
                )?;
                let x0 = left + (cell - pw as u32) / 2;
                let y0 = top + TITLE_HEIGHT;
                // A panel smaller than the first is drawn at its own size.
                let w = (panel.values.width() / step).min(pw);
                let h = (panel.values.height() / step).min(ph);
                for r in 0..h {
                    for c in 0..w {
                        let [red, green, blue] = block_colour(panel, c, r, step);
                        root.draw_pixel(
                            ((x0 + c as u32) as i32, (y0 + r as u32) as i32),
                            &RGBColor(red, green, blue),
                        )?;
                    }
                }
            }
        }
        Ok(())
    })
}

/// Finite minimum and maximum of several grids (`[0, 1]` when none is
/// finite).
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

/// A tick label of a logarithmic axis: plain decimals from 0.001 to 9999
/// (`0.01`, `2`, `500`), `2e-5` style beyond.
pub fn tick_label(value: f64) -> String {
    if !(value.is_finite() && value > 0.0) {
        return String::new();
    }
    if (1e-3..1e4).contains(&value) {
        // At most three significant digits, without trailing zeros.
        let decimals = (2 - value.log10().floor() as i32).max(0) as usize;
        let text = format!("{value:.decimals$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    } else {
        let exponent = value.log10().floor() as i32;
        let mantissa = value / 10f64.powi(exponent);
        let mantissa = (mantissa * 100.0).round() / 100.0;
        if (mantissa - 1.0).abs() < 1e-9 {
            format!("1e{exponent}")
        } else {
            format!("{mantissa}e{exponent}")
        }
    }
}

/// Ticks of a logarithmic axis over `[lo, hi]`: the decades in it (bold
/// gridlines with labels; every second or third one when there are more
/// than eight) and 2 to 9 times each decade (light gridlines).
fn log_ticks([lo, hi]: [f64; 2]) -> (Vec<f64>, Vec<f64>) {
    let near = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let first = lo.log10().floor() as i32 - 1;
    let last = hi.log10().ceil() as i32;
    let mut bold = Vec::new();
    let mut light = Vec::new();
    for k in first..=last {
        let decade = 10f64.powi(k);
        if near(decade) {
            bold.push(decade.clamp(lo, hi));
        }
        light.extend((2..=9).map(|m| f64::from(m) * decade).filter(|&v| near(v)));
    }
    let every = bold.len().div_ceil(8).max(1);
    let bold = bold.into_iter().step_by(every).collect();
    (bold, light)
}

/// A logarithmic axis over `range` with the ticks of [`log_ticks`].
fn log_axis(range: [f64; 2]) -> WithKeyPoints<LogCoord<f64>> {
    let (bold, light) = log_ticks(range);
    (range[0]..range[1])
        .log_scale()
        .with_key_points(bold)
        .with_light_points(light)
}

impl Series<'_> {
    /// The points a log-log plot over `x_range` x `y_range` draws: the
    /// positive, finite ones, clamped to the ranges.
    fn plotted(&self, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> Vec<(f64, f64)> {
        self.points
            .iter()
            .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
            .map(|&(x, y)| (x.clamp(x0, x1), y.clamp(y0, y1)))
            .collect()
    }
}

/// A log-log line plot.
pub struct LogLogPlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Name of the x axis.
    pub x_name: &'a str,
    /// Name of the y axis.
    pub y_name: &'a str,
    /// The x axis' extent (positive; see [`decades`]).
    pub x_range: [f64; 2],
    /// The y axis' extent (positive).
    pub y_range: [f64; 2],
    /// The curves, drawn in order, with a legend in the upper right.
    pub series: &'a [Series<'a>],
}

/// Plot size, pixels.
const PLOT_SIZE: (u32, u32) = (800, 480);

impl LogLogPlot<'_> {
    /// Draws the plot: light grey gridlines, tick labels on both axes, the
    /// axis names, 2 px lines with a dot at every point (points outside the
    /// ranges are clamped to them, non-positive ones left out) and a legend.
    pub fn draw(&self) -> Result<Figure> {
        let [x0, x1] = self.x_range;
        let [y0, y1] = self.y_range;
        anyhow::ensure!(
            x0 > 0.0 && x0 < x1 && x1.is_finite() && y0 > 0.0 && y0 < y1 && y1.is_finite(),
            "a log-log plot needs positive, increasing ranges (x {x0}..{x1}, y {y0}..{y1})"
        );
        let (x_axis, y_axis) = (log_axis(self.x_range), log_axis(self.y_range));
        Figure::drawn(PLOT_SIZE.0, PLOT_SIZE.1, |root| {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(root)
                .margin(14)
                .caption(self.title, text_style(TITLE_TEXT))
                .x_label_area_size(48)
                .y_label_area_size(70)
                .build_cartesian_2d(x_axis, y_axis)?;
            chart
                .configure_mesh()
                .x_desc(self.x_name)
                .y_desc(self.y_name)
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v))
                .label_style(text_style(SMALL_TEXT))
                .axis_desc_style(text_style(AXIS_TEXT))
                .bold_line_style(RGBColor(200, 200, 200))
                .light_line_style(RGBColor(236, 236, 236))
                .axis_style(BLACK)
                .draw()?;
            for series in self.series {
                let [r, g, b] = series.colour;
                let colour = RGBColor(r, g, b);
                let points = series.plotted(self.x_range, self.y_range);
                chart
                    .draw_series(LineSeries::new(
                        points.iter().copied(),
                        colour.stroke_width(2),
                    ))?
                    .label(series.label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(3))
                    });
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            }
            if !self.series.is_empty() {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .label_font(text_style(SMALL_TEXT))
                    .background_style(WHITE.mix(0.9))
                    .border_style(BLACK)
                    .margin(12)
                    .draw()?;
            }
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl Figure {
        /// `(width, height)` in pixels.
        fn size(&self) -> (u32, u32) {
            (self.width, self.height)
        }

        /// The colour at `(x, y)`; `None` outside the picture.
        fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
            if x >= self.width || y >= self.height {
                return None;
            }
            let i = (y as usize * self.width as usize + x as usize) * 3;
            Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
        }

        /// Every pixel's colour, row by row.
        fn pixels(&self) -> impl Iterator<Item = [u8; 3]> + '_ {
            self.rgb.chunks_exact(3).map(|p| [p[0], p[1], p[2]])
        }
    }

    /// How many pixels of `figure` are darker than mid-grey.
    fn dark(figure: &Figure) -> usize {
        figure
            .pixels()
            .filter(|p| p.iter().all(|&v| v < 128))
            .count()
    }

    #[test]
    fn every_letter_digit_and_sign_has_its_own_glyph() {
        // Legends such as "fast marching" and "multigrid" once lost letters:
        // a character the font lacks would draw as the same empty box.
        let drawn: Vec<(char, Vec<[u8; 3]>)> = ('a'..='z')
            .chain('A'..='Z')
            .chain('0'..='9')
            .chain("-.|()".chars())
            .map(|ch| {
                let figure = Figure::drawn(24, 24, |root| {
                    root.fill(&WHITE)?;
                    root.draw_text(&ch.to_string(), &text_style(SMALL_TEXT), (4, 4))?;
                    Ok(())
                })
                .expect("drawn");
                assert!(dark(&figure) > 0, "{ch:?} draws nothing");
                (ch, figure.pixels().collect())
            })
            .collect();
        for (i, (a, pa)) in drawn.iter().enumerate() {
            for (b, pb) in &drawn[i + 1..] {
                assert_ne!(pa, pb, "{a:?} and {b:?} draw the same");
            }
        }
    }

    #[test]
    fn panels_draw_under_their_titles_in_grey_and_colour() {
        // Constant over each 2x2 block, so that shrinking by 2 keeps the
        // ends of the ramp.
        let g = Grid::from_fn(40, 20, |c, _| (c / 2 * 2) as f64);
        let holes = Grid::from_fn(40, 20, |c, _| if c < 20 { f64::NAN } else { 1.0 });
        let figure = panel_grid(
            &[vec![
                Panel::new(&g, Shade::Grey([0.0, 38.0]), "grey"),
                Panel::new(&g, Shade::Colour([0.0, 38.0]), "a much longer title"),
                Panel::new(&holes, Shade::Grey([0.0, 1.0]), "holes"),
            ]],
            2,
        )
        .expect("drawn");
        let (w, h) = figure.size();
        // Three columns as wide as the longest title, each a 20x10 panel
        // under a title line.
        assert_eq!(h, GAP + TITLE_HEIGHT + 10 + GAP);
        assert!(w > 3 * (20 + GAP) + GAP, "{w}");
        let colours: Vec<[u8; 3]> = figure.pixels().collect();
        // Both ends of the grey ramp and of the colour map, and the light
        // grey of the missing values.
        for expected in [
            [0, 0, 0],
            [255, 255, 255],
            colour_map(0.0),
            colour_map(1.0),
            MISSING,
        ] {
            assert!(colours.contains(&expected), "no {expected:?}");
        }
        // Titles are drawn in the band above the panels, panels below it.
        let title_ink = (0..w)
            .flat_map(|x| (GAP..GAP + TITLE_HEIGHT).map(move |y| (x, y)))
            .filter(|&(x, y)| figure.pixel(x, y).is_some_and(|p| p != [255, 255, 255]))
            .count();
        assert!(title_ink > 50, "{title_ink} title pixels");
        // A panel smaller than the first is drawn at its own size.
        let small = Grid::from_fn(4, 4, |_, _| 0.5);
        let mixed = [vec![
            Panel::new(&g, Shade::Grey([0.0, 1.0]), ""),
            Panel::new(&small, Shade::Grey([0.0, 1.0]), ""),
        ]];
        assert!(panel_grid(&mixed, 1).is_ok());
        let first_panel_row = GAP + TITLE_HEIGHT;
        let left_of_panels = (0..w)
            .find(|&x| figure.pixel(x, first_panel_row) == Some([0, 0, 0]))
            .expect("a black first column");
        assert!(left_of_panels >= GAP, "{left_of_panels}");
    }

    #[test]
    fn a_plot_is_written_as_a_png_with_its_lines_labels_and_legend() {
        let points = [(0.1, 0.5), (1.0, 0.05), (10.0, 0.01)];
        let other = [(0.2, 0.2), (5.0, 0.1)];
        let series = [
            Series {
                colour: [255, 0, 0],
                label: "explicit",
                points: &points,
            },
            Series {
                colour: [0, 0, 255],
                label: "linearised",
                points: &other,
            },
        ];
        let plot = LogLogPlot {
            title: "RSE over time",
            x_name: "seconds",
            y_name: "RSE",
            x_range: [0.1, 10.0],
            y_range: [0.01, 1.0],
            series: &series,
        }
        .draw()
        .expect("drawn");
        assert_eq!(plot.size(), PLOT_SIZE);
        let red = plot.pixels().filter(|p| *p == [255, 0, 0]).count();
        let blue = plot.pixels().filter(|p| *p == [0, 0, 255]).count();
        // The curve (hundreds of pixels) and its legend sample.
        assert!(red > 500 && blue > 300, "{red} red, {blue} blue");
        // Axes, tick labels, names, title and legend text are black.
        assert!(dark(&plot) > 2000, "{} dark pixels", dark(&plot));
        // Tick labels below the x axis: ink in the bottom band.
        let bottom_ink = (0..PLOT_SIZE.0)
            .flat_map(|x| (PLOT_SIZE.1 - 60..PLOT_SIZE.1).map(move |y| (x, y)))
            .filter(|&(x, y)| plot.pixel(x, y).is_some_and(|p| p[0] < 128))
            .count();
        assert!(bottom_ink > 200, "{bottom_ink}");

        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("plot.png");
        plot.save(&path).expect("saved");
        let read = image::open(&path).expect("a PNG").to_rgb8();
        assert_eq!(read.dimensions(), PLOT_SIZE);
        assert!(read.pixels().any(|p| p.0 == [255, 0, 0]));
        assert!(read.pixels().any(|p| p.0 != [255, 255, 255]));
        assert!(
            plot.save(&dir.path().join("no/such/folder/plot.png"))
                .is_err()
        );
    }

    #[test]
    fn plots_refuse_ranges_a_log_axis_cannot_show() {
        let plot = |x_range, y_range| LogLogPlot {
            title: "",
            x_name: "x",
            y_name: "y",
            x_range,
            y_range,
            series: &[],
        };
        assert!(plot([0.0, 1.0], [0.1, 1.0]).draw().is_err());
        assert!(plot([1.0, 1.0], [0.1, 1.0]).draw().is_err());
        assert!(plot([0.1, f64::INFINITY], [0.1, 1.0]).draw().is_err());
        assert!(plot([0.1, 1.0], [f64::NAN, 1.0]).draw().is_err());
        assert!(plot([0.1, 1.0], [0.1, 1.0]).draw().is_ok());
    }

    #[test]
    fn decades_and_tick_labels() {
        assert_eq!(decades([0.003, 0.2].into_iter()), [0.001, 1.0]);
        assert_eq!(decades([5.0].into_iter()), [1.0, 10.0]);
        assert_eq!(decades(std::iter::empty()), [0.1, 1.0]);
        assert_eq!(tick_label(0.001), "0.001");
        assert_eq!(tick_label(0.02), "0.02");
        assert_eq!(tick_label(1.0), "1");
        assert_eq!(tick_label(500.0), "500");
        assert_eq!(tick_label(1e-5), "1e-5");
        assert_eq!(tick_label(2e-5), "2e-5");
        assert_eq!(tick_label(1e6), "1e6");
        assert_eq!(tick_label(0.0), "");
        let (bold, light) = log_ticks([0.1, 10.0]);
        assert_eq!(bold, [0.1, 1.0, 10.0]);
        assert_eq!(light.len(), 16);
        assert!(light.iter().all(|v| (0.1..=10.0).contains(v)));
        // Twenty decades: every third labelled.
        let (bold, _) = log_ticks([1e-10, 1e10]);
        assert_eq!(bold.len(), 7);
    }
}
