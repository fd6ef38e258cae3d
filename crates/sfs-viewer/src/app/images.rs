//! Grids to display images: grey with display gamma, colour maps with their
//! value range, and the scale bar drawn beside a colour-mapped panel.

use eframe::egui;

use crate::render::colour_map;
use sfs_core::grid::Grid;

/// Linear values in [0, 1] shown with a display gamma of 2.2 (linear images
/// look dark otherwise); NaN is dark red.
pub fn grey_image(values: &Grid<f64>) -> egui::ColorImage {
    let (w, h) = values.size();
    let pixels = values
        .as_slice()
        .iter()
        .map(|&v| {
            if v.is_finite() {
                let g = (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
                egui::Color32::from_gray(g)
            } else {
                egui::Color32::from_rgb(60, 0, 0)
            }
        })
        .collect();
    egui::ColorImage::new([w, h], pixels)
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
