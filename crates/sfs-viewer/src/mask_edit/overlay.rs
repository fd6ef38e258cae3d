//! The masks as an overlay texture over the input image: untrusted pixels
//! tinted, background pixels hatched.

use serde::{Deserialize, Serialize};

use super::masks::Masks;

/// Colours of [`Masks::overlay_rgba`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OverlayStyle {
    /// Colour of untrusted pixels; alpha `opacity * (1 - c)`.
    pub confidence_rgb: [u8; 3],
    /// Colour of background (non-object) pixels.
    pub background_rgb: [u8; 3],
    /// Overall opacity in [0, 1] (values outside are clamped, NaN is 0).
    pub opacity: f32,
    /// Period in pixels of the diagonal hatching of the background: half of
    /// each period at full opacity, the rest at a third of it; 0 = solid.
    pub hatch_period_px: usize,
}

impl Default for OverlayStyle {
    /// Red for untrusted, blue hatching for background, opacity 0.5,
    /// hatch period 8 pixels.
    fn default() -> Self {
        Self {
            confidence_rgb: [230, 40, 40],
            background_rgb: [40, 90, 230],
            opacity: 0.5,
            hatch_period_px: 8,
        }
    }
}

impl Masks {
    /// The overlay texture: row-major RGBA8, 4 bytes per pixel, NOT
    /// premultiplied (egui's `ColorImage::from_rgba_unmultiplied`).
    /// Untrusted pixels get `confidence_rgb` with alpha `opacity (1 - c)`,
    /// composited over the (hatched) `background_rgb` of background pixels;
    /// trusted object pixels are transparent.
    pub fn overlay_rgba(&self, style: &OverlayStyle) -> Vec<u8> {
        let opacity = if style.opacity.is_nan() {
            0.0
        } else {
            style.opacity.clamp(0.0, 1.0)
        };
        let (w, period) = (self.confidence.width().max(1), style.hatch_period_px);
        let cells = self
            .confidence
            .as_slice()
            .iter()
            .zip(self.object.as_slice());
        let mut out = Vec::with_capacity(4 * self.confidence.len());
        for (k, (&c, &object)) in cells.enumerate() {
            let a1 = opacity * (1.0 - c.clamp(0.0, 1.0));
            let a2 = match (object, period) {
                (true, _) => 0.0,
                (false, 0) => opacity,
                (false, p) if ((k % w) + (k / w)) % p < p.div_ceil(2) => opacity,
                (false, _) => opacity / 3.0,
            };
            let alpha = a1 + a2 * (1.0 - a1);
            if alpha <= 0.0 {
                out.extend_from_slice(&[0; 4]);
                continue;
            }
            for (fg, bg) in style.confidence_rgb.iter().zip(&style.background_rgb) {
                let v = (f32::from(*fg) * a1 + f32::from(*bg) * a2 * (1.0 - a1)) / alpha;
                out.push(v.round().clamp(0.0, 255.0) as u8);
            }
            out.push((alpha * 255.0).round() as u8);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::{Layer, Mode};

    #[test]
    fn overlay_colours_untrusted_and_background() {
        let mut m = Masks::new(3, 1);
        m.fill_rect(Layer::Confidence, Mode::Paint, [0.0, 0.0], [1.0, 1.0]);
        m.fill_rect(Layer::Object, Mode::Paint, [1.0, 0.0], [2.0, 1.0]);
        let style = OverlayStyle {
            hatch_period_px: 0,
            ..OverlayStyle::default()
        };
        let rgba = m.overlay_rgba(&style);
        assert_eq!(rgba, [230, 40, 40, 128, 40, 90, 230, 128, 0, 0, 0, 0]);
        let hatched = m.overlay_rgba(&OverlayStyle {
            hatch_period_px: 2,
            ..style
        });
        assert_eq!(hatched[4..8], [40, 90, 230, 43]);
    }
}
