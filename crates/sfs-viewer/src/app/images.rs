//! Grids to display images: the input photograph as it looks (an automatic
//! viewing exposure, then the sRGB transfer function), colour maps with
//! their value range, and the scale bar drawn beside a colour-mapped panel.
//! Display only: nothing here changes the values the solver gets.

use eframe::egui;

use crate::render::colour_map;
use sfs_core::grid::Grid;

/// The automatic viewing exposure maps this quantile of the pixel values to
/// white.
pub const WHITE_QUANTILE: f64 = 0.99;

/// At most about this many pixels are sampled (evenly) to find the white
/// point, so that an 18 MP photograph costs no more than a small one.
const WHITE_SAMPLES: usize = 1 << 20;

/// The sRGB transfer function (IEC 61966-2-1): linear light in [0, 1] to
/// the encoded value in [0, 1] that a display shows as that light.
pub fn srgb_encode(linear: f64) -> f64 {
    let v = linear.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// How the input image (and the reprojection, which is in the same units)
/// is shown: the linear value times `exposure`, clipped to [0, 1] and
/// encoded with the sRGB transfer function, so that a photograph looks as
/// it did. Display only: the solver and the hover readout keep the linear
/// values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayMapping {
    /// Factor applied to the linear values before encoding.
    pub exposure: f64,
}

impl Default for DisplayMapping {
    /// No exposure change.
    fn default() -> Self {
        Self { exposure: 1.0 }
    }
}

impl DisplayMapping {
    /// The automatic viewing exposure: the [`WHITE_QUANTILE`] of the finite
    /// values of `image` maps to white. Only the object's pixels count when
    /// `object` marks some (the background of a photograph is often much
    /// darker or brighter than the object); no exposure change when that
    /// quantile is not positive (a black image).
    pub fn automatic(image: &Grid<f64>, object: Option<&Grid<bool>>) -> Self {
        let object = object
            .filter(|o| o.size() == image.size() && o.as_slice().iter().any(|&v| v))
            .map(Grid::as_slice);
        let stride = image.len().div_ceil(WHITE_SAMPLES).max(1);
        let mut values: Vec<f64> = image
            .as_slice()
            .iter()
            .enumerate()
            .step_by(stride)
            .filter(|&(k, v)| v.is_finite() && object.is_none_or(|o| o[k]))
            .map(|(_, &v)| v)
            .collect();
        if values.is_empty() {
            return Self::default();
        }
        let k = ((values.len() - 1) as f64 * WHITE_QUANTILE).round() as usize;
        let (_, &mut white, _) = values.select_nth_unstable_by(k, f64::total_cmp);
        let exposure = 1.0 / white;
        if white > 0.0 && exposure.is_finite() {
            Self { exposure }
        } else {
            Self::default()
        }
    }

    /// The displayed (sRGB-encoded) value in [0, 1] of a linear value.
    pub fn display_value(&self, linear: f64) -> f64 {
        srgb_encode(linear * self.exposure)
    }

    /// What the panel says about it: `shown ×3.2, sRGB`.
    pub fn describe(&self) -> String {
        let e = self.exposure;
        let decimals = (1.0 - e.log10().floor()).clamp(0.0, 6.0) as usize;
        format!("shown ×{e:.decimals$}, sRGB")
    }

    /// `values` as a grey image; NaN is dark red.
    pub fn image(&self, values: &Grid<f64>) -> egui::ColorImage {
        let (w, h) = values.size();
        let pixels = values
            .as_slice()
            .iter()
            .map(|&v| {
                if v.is_finite() {
                    egui::Color32::from_gray((self.display_value(v) * 255.0).round() as u8)
                } else {
                    egui::Color32::from_rgb(60, 0, 0)
                }
            })
            .collect();
        egui::ColorImage::new([w, h], pixels)
    }
}

/// Finite range of `values` (`None` when nothing is finite).
pub fn finite_range(values: &Grid<f64>) -> Option<[f64; 2]> {
    let mut range: Option<[f64; 2]> = None;
    for &v in values.as_slice() {
        if v.is_finite() {
            range = Some(match range {
                None => [v, v],
                Some([lo, hi]) => [lo.min(v), hi.max(v)],
            });
        }
    }
    range
}

/// Colour map of `values` over `range`; NaN (no surface) is dark grey.
pub fn colour_mapped(values: &Grid<f64>, range: [f64; 2]) -> egui::ColorImage {
    let (w, h) = values.size();
    let span = (range[1] - range[0]).max(1e-300);
    let pixels = values
        .as_slice()
        .iter()
        .map(|&v| {
            if v.is_finite() {
                let t = ((v - range[0]) / span).clamp(0.0, 1.0) as f32;
                let [r, g, b] = colour_map(t);
                egui::Color32::from_rgb(r, g, b)
            } else {
                egui::Color32::from_gray(40)
            }
        })
        .collect();
    egui::ColorImage::new([w, h], pixels)
}

/// `b - a` where both are finite, NaN elsewhere (`a` point-sampled to the
/// size of `b`): the residual `I - R` with `a` the reprojection and `b` the
/// image.
pub fn signed_difference(a: &Grid<f64>, b: &Grid<f64>) -> Grid<f64> {
    let (w, h) = b.size();
    let (aw, ah) = a.size();
    Grid::from_fn(w, h, |c, r| {
        let ac = (c * aw / w).min(aw.saturating_sub(1));
        let ar = (r * ah / h).min(ah.saturating_sub(1));
        let (x, y) = (*a.at(ac, ar), *b.at(c, r));
        if x.is_finite() && y.is_finite() {
            y - x
        } else {
            f64::NAN
        }
    })
}

/// `|a - b|` where both are finite, NaN elsewhere; `a` is resampled to the
/// size of `b` by point sampling when the sizes differ (a coarse level
/// against the full image).
pub fn abs_difference(a: &Grid<f64>, b: &Grid<f64>) -> Grid<f64> {
    signed_difference(a, b).map(|v| v.abs())
}

/// Draws a vertical colour scale bar with its end values into `rect`.
pub fn scale_bar(ui: &egui::Ui, rect: egui::Rect, range: [f64; 2]) {
    let painter = ui.painter_at(rect.expand(2.0));
    let bar = egui::Rect::from_min_size(rect.min, egui::vec2(12.0, rect.height()));
    let steps = 64;
    for i in 0..steps {
        let t0 = i as f32 / steps as f32;
        let t1 = (i + 1) as f32 / steps as f32;
        let [r, g, b] = colour_map(1.0 - t0);
        let y0 = egui::lerp(bar.top()..=bar.bottom(), t0);
        let y1 = egui::lerp(bar.top()..=bar.bottom(), t1);
        painter.rect_filled(
            egui::Rect::from_x_y_ranges(bar.x_range(), y0..=y1),
            0.0,
            egui::Color32::from_rgb(r, g, b),
        );
    }
    let text = ui.visuals().text_color();
    let font = egui::FontId::monospace(10.0);
    painter.text(
        egui::pos2(bar.right() + 3.0, bar.top()),
        egui::Align2::LEFT_TOP,
        format!("{:.4}", range[1]),
        font.clone(),
        text,
    );
    painter.text(
        egui::pos2(bar.right() + 3.0, bar.bottom()),
        egui::Align2::LEFT_BOTTOM,
        format!("{:.4}", range[0]),
        font,
        text,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_differences_ignore_nan() {
        let a = Grid::from_fn(4, 4, |c, _| if c == 0 { f64::NAN } else { c as f64 });
        assert_eq!(finite_range(&a), Some([1.0, 3.0]));
        let b = Grid::filled(8, 8, 1.0);
        let d = abs_difference(&a, &b);
        assert_eq!(d.size(), (8, 8));
        assert!(d.at(0, 0).is_nan());
        assert_eq!(*d.at(7, 7), 2.0);
        let image = colour_mapped(&a, [1.0, 3.0]);
        assert_eq!(image.size, [4, 4]);
        assert_eq!(image.pixels[0], egui::Color32::from_gray(40));
    }

    #[test]
    fn the_display_mapping_is_srgb_after_an_automatic_exposure() {
        // sRGB: linear 0.18 (mid-grey) is 46 %, 0.5 is 73.5 %, 0 and 1 stay.
        assert!((srgb_encode(0.18) - 0.4613).abs() < 1e-4);
        assert!((srgb_encode(0.5) - 0.7354).abs() < 1e-4);
        assert!((srgb_encode(0.214_041) - 0.5).abs() < 1e-5);
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-12 && srgb_encode(7.0) == srgb_encode(1.0));
        assert!(
            (srgb_encode(0.002) - 0.02584).abs() < 1e-9,
            "the linear toe"
        );

        // A dark photograph: values 0.001 .. 0.1 (99th percentile 0.099);
        // a NaN and a bright background pixel off the object count nowhere.
        let mut image = Grid::from_fn(10, 10, |c, r| (r * 10 + c + 1) as f64 / 1000.0);
        *image.at_mut(0, 0) = f64::NAN;
        *image.at_mut(1, 0) = 50.0;
        let mut object = Grid::filled(10, 10, true);
        *object.at_mut(1, 0) = false;
        let bits = |g: &Grid<f64>| g.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let before = bits(&image);
        let mapping = DisplayMapping::automatic(&image, Some(&object));
        assert_eq!(bits(&image), before, "the document's image is not changed");
        assert!((mapping.exposure - 1.0 / 0.099).abs() < 1e-9, "{mapping:?}");
        assert!((mapping.display_value(0.099) - 1.0).abs() < 1e-12);
        let clipped = mapping.display_value(0.1);
        assert_eq!(clipped, srgb_encode(1.0), "brighter clips to white");
        assert_eq!(mapping.describe(), "shown ×10, sRGB");
        let grid = mapping.image(&image);
        assert_eq!(bits(&image), before, "nor by showing it");
        assert_eq!(grid.pixels[0], egui::Color32::from_rgb(60, 0, 0));
        assert_eq!(grid.pixels[1], egui::Color32::WHITE);
        // Monotone over the range, and 0.18 of white shows as mid-grey.
        let shown: Vec<f64> = (0..=200)
            .map(|k| mapping.display_value(k as f64 * 0.0006))
            .collect();
        assert!(shown.windows(2).all(|p| p[0] <= p[1]) && shown[0] == 0.0);
        let grey = mapping.image(&Grid::filled(1, 1, 0.18 * 0.099));
        assert_eq!(grey.pixels[0], egui::Color32::from_gray(118));
        // Without a mask the bright pixel is the 99th percentile here.
        let whole = DisplayMapping::automatic(&image, None);
        assert!((whole.exposure - 1.0 / 0.1).abs() < 1e-9, "{whole:?}");
        // A black image keeps the exposure; small and large factors read.
        let black = Grid::filled(4, 4, 0.0);
        assert_eq!(DisplayMapping::automatic(&black, None).exposure, 1.0);
        assert_eq!(
            DisplayMapping { exposure: 3.24 }.describe(),
            "shown ×3.2, sRGB"
        );
        assert_eq!(
            DisplayMapping { exposure: 0.853 }.describe(),
            "shown ×0.85, sRGB"
        );
        assert_eq!(
            DisplayMapping { exposure: 1.0 }.describe(),
            "shown ×1.0, sRGB"
        );
    }
}

/// `image` as a texture, shrunk (nearest pixel) so that neither side exceeds
/// the GPU's largest texture side (`ctx`'s `max_texture_side`, 8192 on many
/// devices): only what is shown shrinks, the document keeps its pixels, and
/// the panels map the pointer through the document's size.
pub fn load_texture(
    ctx: &egui::Context,
    name: &str,
    image: egui::ColorImage,
    options: egui::TextureOptions,
) -> egui::TextureHandle {
    let max_side = ctx.input(|i| i.max_texture_side).max(1);
    ctx.load_texture(name, fit_texture_side(image, max_side), options)
}

/// `image` with both sides at most `max_side` (nearest pixel), the aspect
/// ratio kept as far as whole pixels allow.
pub fn fit_texture_side(image: egui::ColorImage, max_side: usize) -> egui::ColorImage {
    let [w, h] = image.size;
    if w <= max_side && h <= max_side {
        return image;
    }
    let shrink = (w.max(h) as f64 / max_side as f64).max(1.0);
    let nw = ((w as f64 / shrink).floor() as usize).clamp(1, max_side);
    let nh = ((h as f64 / shrink).floor() as usize).clamp(1, max_side);
    let pixels = (0..nh)
        .flat_map(|r| {
            let sr = (r * h / nh).min(h - 1);
            let image = &image;
            (0..nw).map(move |c| image.pixels[sr * w + (c * w / nw).min(w - 1)])
        })
        .collect();
    egui::ColorImage::new([nw, nh], pixels)
}

#[cfg(test)]
mod texture_tests {
    use super::*;

    #[test]
    fn textures_fit_the_device_limit() {
        let wide = egui::ColorImage::new([9000, 4], vec![egui::Color32::WHITE; 36_000]);
        let fitted = fit_texture_side(wide, 8192);
        assert_eq!(fitted.size, [8192, 3]);
        assert_eq!(fitted.pixels.len(), 8192 * 3);
        let small = egui::ColorImage::new([5, 7], vec![egui::Color32::RED; 35]);
        assert_eq!(fit_texture_side(small, 8192).size, [5, 7]);
        let tall = egui::ColorImage::new([2, 100], vec![egui::Color32::RED; 200]);
        assert_eq!(fit_texture_side(tall, 10).size, [1, 10]);
    }
}
