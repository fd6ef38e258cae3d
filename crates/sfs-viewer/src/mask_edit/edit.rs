//! Shapes and whole-layer operations, each one undo step: rectangle,
//! lasso, flood fill, clear, invert, threshold and lowering the confidence
//! to a suggestion.

use sfs_core::grid::Grid;

use super::masks::Masks;
use super::rect::{Rect, rect_spanning, span, whole};
use super::types::{Cell, ImagePoint, Layer, MaskError, Mode, parameter};
use super::undo::{Change, region_edit};

/// A hard region operation on one layer.
enum Op<'a> {
    /// Sets the pixels for which the predicate holds to the mode's target.
    Set(Mode, &'a dyn Fn(usize, usize) -> bool),
    Clear,
    Invert,
}

impl Op<'_> {
    fn apply<T: Cell>(&self, c: usize, r: usize, v: T) -> T {
        match self {
            Op::Set(mode, inside) if inside(c, r) => T::target(*mode),
            Op::Set(..) => v,
            Op::Clear => T::DEFAULT,
            Op::Invert => v.inverted(),
        }
    }
}

impl Masks {
    /// Runs `op` over `rect` of `layer` as one undo step (ending a stroke in
    /// progress first); returns whether anything changed.
    fn apply_op(&mut self, layer: Layer, rect: Rect, op: &Op) -> bool {
        self.end_stroke();
        let change = match layer {
            Layer::Confidence => {
                region_edit(&mut self.confidence, rect, |c, r, v| op.apply(c, r, v))
                    .map(Change::Confidence)
            }
            Layer::Object => {
                region_edit(&mut self.object, rect, |c, r, v| op.apply(c, r, v)).map(Change::Object)
            }
        };
        self.record(change)
    }

    /// Sets the pixels whose centres lie in the rectangle with corners `a`
    /// and `b` (edges included) to `mode`'s value (confidence 0/1, object
    /// false/true). Returns whether anything changed (one undo step if so);
    /// non-finite corners change nothing.
    pub fn fill_rect(&mut self, layer: Layer, mode: Mode, a: ImagePoint, b: ImagePoint) -> bool {
        let (x, y) = (
            (a[0].min(b[0]), a[0].max(b[0])),
            (a[1].min(b[1]), a[1].max(b[1])),
        );
        let Some(rect) = rect_spanning(x, y, self.size()) else {
            return false;
        };
        self.apply_op(layer, rect, &Op::Set(mode, &|_, _| true))
    }

    /// Sets the pixels whose centres lie inside the closed `polygon`
    /// (even-odd rule) to `mode`'s value. Fewer than 3 points or a
    /// non-finite coordinate change nothing. Returns whether anything changed.
    pub fn fill_lasso(&mut self, layer: Layer, mode: Mode, polygon: &[ImagePoint]) -> bool {
        if polygon.len() < 3 || !polygon.iter().flatten().all(|v| v.is_finite()) {
            return false;
        }
        let bounds = |k: usize| {
            let lo = polygon.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min);
            (lo, polygon.iter().map(|p| p[k]).fold(lo, f32::max))
        };
        let Some(rect) = rect_spanning(bounds(0), bounds(1), self.size()) else {
            return false;
        };
        let index = |c: usize, r: usize| (r - rect.y0) * rect.width() + c - rect.x0;
        let mut inside = vec![false; rect.area()];
        let mut crossings = Vec::new();
        for r in rect.y0..rect.y1 {
            let y = r as f32 + 0.5;
            crossings.clear();
            for (k, p) in polygon.iter().enumerate() {
                let q = polygon[(k + 1) % polygon.len()];
                if (p[1] <= y) != (q[1] <= y) {
                    crossings.push(p[0] + (y - p[1]) * (q[0] - p[0]) / (q[1] - p[1]));
                }
            }
            crossings.sort_by(f32::total_cmp);
            for pair in crossings.chunks_exact(2) {
                if let Some((c0, c1)) = span(pair[0], pair[1], rect.x1) {
                    (c0.max(rect.x0)..c1).for_each(|c| inside[index(c, r)] = true);
                }
            }
        }
        self.apply_op(layer, rect, &Op::Set(mode, &|c, r| inside[index(c, r)]))
    }

    fn check_image(&self, image: &Grid<f64>) -> Result<(), MaskError> {
        let (found, expected) = (image.size(), self.size());
        if found == expected {
            return Ok(());
        }
        Err(MaskError::SizeMismatch {
            what: "image",
            found,
            expected,
        })
    }

    /// Sets to `mode`'s value the pixels 4-connected to the pixel under
    /// `seed` through pixels whose `image` value is within `tolerance`
    /// (inclusive) of the seed pixel's. A seed outside the image changes
    /// nothing. Errors on an image of another size or a negative or
    /// non-finite tolerance. Returns whether anything changed.
    pub fn flood_fill(
        &mut self,
        layer: Layer,
        mode: Mode,
        image: &Grid<f64>,
        seed: ImagePoint,
        tolerance: f64,
    ) -> Result<bool, MaskError> {
        self.check_image(image)?;
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            let reason = format!("{tolerance} (must be finite and >= 0)");
            return Err(parameter("tolerance", reason));
        }
        let (w, h) = self.size();
        let (x, y) = (seed[0].floor(), seed[1].floor());
        if !(x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h) {
            return Ok(false);
        }
        let (values, seed) = (image.as_slice(), (x as usize, y as usize));
        let seed_value = values[seed.1 * w + seed.0];
        let mut inside = vec![false; w * h];
        inside[seed.1 * w + seed.0] = true;
        let (mut stack, mut rect) = (vec![seed], None);
        while let Some((c, r)) = stack.pop() {
            rect = Some(Rect::include(rect, c, r));
            let (left, up) = (c.wrapping_sub(1), r.wrapping_sub(1));
            for (nc, nr) in [(left, r), (c + 1, r), (c, up), (c, r + 1)] {
                let i = nr.wrapping_mul(w).wrapping_add(nc);
                if nc < w && nr < h && !inside[i] && (values[i] - seed_value).abs() <= tolerance {
                    inside[i] = true;
                    stack.push((nc, nr));
                }
            }
        }
        let rect = Rect::include(rect, seed.0, seed.1);
        Ok(self.apply_op(layer, rect, &Op::Set(mode, &|c, r| inside[r * w + c])))
    }

    /// Resets `layer` to its default (confidence 1, object true). Returns
    /// whether anything changed.
    pub fn clear(&mut self, layer: Layer) -> bool {
        self.apply_op(layer, whole(&self.object), &Op::Clear)
    }

    /// Inverts `layer` (`c -> 1 - c`, object <-> background). Returns whether
    /// anything changed.
    pub fn invert(&mut self, layer: Layer) -> bool {
        self.apply_op(layer, whole(&self.object), &Op::Invert)
    }

    /// Sets the object layer to `image > threshold`: dark background pixels
    /// (and NaN) become background. Errors on an image of another size or a
    /// non-finite threshold. Returns whether anything changed.
    pub fn threshold(&mut self, image: &Grid<f64>, threshold: f64) -> Result<bool, MaskError> {
        self.check_image(image)?;
        if !threshold.is_finite() {
            return Err(parameter(
                "threshold",
                format!("{threshold} (must be finite)"),
            ));
        }
        self.end_stroke();
        let change = region_edit(&mut self.object, whole(image), |c, r, _| {
            *image.at(c, r) > threshold
        });
        Ok(self.record(change.map(Change::Object)))
    }

    /// Sets the confidence layer to `min(current, proposal)` (values clamped
    /// to [0, 1], NaN ignored) as one undo step, so a suggestion can be
    /// undone, erased or painted over; errors on another size. Returns
    /// whether anything changed.
    pub fn lower_confidence(&mut self, proposal: &Grid<f64>) -> Result<bool, MaskError> {
        self.check_image(proposal)?;
        self.end_stroke();
        let change = region_edit(&mut self.confidence, whole(proposal), |c, r, current| {
            let p = *proposal.at(c, r);
            if p.is_finite() {
                current.min(p.clamp(0.0, 1.0) as f32)
            } else {
                current
            }
        })
        .map(Change::Confidence);
        Ok(self.record(change))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::test_support::*;

    #[test]
    fn shapes_on_each_layer() {
        for layer in [Layer::Confidence, Layer::Object] {
            let mut m = Masks::new(12, 12);
            assert!(m.fill_rect(layer, Mode::Paint, [5.9, 6.4], [2.2, 3.0]));
            for (r, c) in (0..12).flat_map(|r| (0..12).map(move |c| (r, c))) {
                let inside = (2..=5).contains(&c) && (3..=5).contains(&r);
                assert_eq!(excluded(&m, layer, c, r), inside);
            }
            assert!(m.fill_rect(layer, Mode::Erase, [0.0, 0.0], [12.0, 12.0]));
            assert!(!m.fill_rect(layer, Mode::Erase, [0.0, 0.0], [12.0, 12.0]));
            assert!(!m.fill_rect(layer, Mode::Paint, [20.0, 0.0], [30.0, 12.0]));

            let triangle = [[0.0, 0.0], [10.2, 0.0], [0.0, 10.2]];
            assert!(m.fill_lasso(layer, Mode::Paint, &triangle));
            for (r, c) in (0..12).flat_map(|r| (0..12).map(move |c| (r, c))) {
                assert_eq!(excluded(&m, layer, c, r), c + r <= 9, "({c}, {r})");
            }
            assert!(m.fill_lasso(layer, Mode::Erase, &triangle));
            assert_eq!(state(&m), state(&Masks::new(12, 12)));
            assert!(!m.fill_lasso(layer, Mode::Paint, &triangle[..2]));
        }
    }

    /// Dark background 0.05, a bright textured square at columns and rows

    #[test]
    fn flood_fill_stops_at_image_edges() {
        let image = scene();
        for layer in [Layer::Confidence, Layer::Object] {
            let mut m = Masks::new(30, 20);
            assert!(
                m.flood_fill(layer, Mode::Paint, &image, [7.3, 9.9], 0.05)
                    .unwrap()
            );
            for (r, c) in (0..20).flat_map(|r| (0..30).map(move |c| (r, c))) {
                let big = (5..15).contains(&c) && (5..15).contains(&r);
                assert_eq!(excluded(&m, layer, c, r), big, "({c}, {r})");
            }
            assert!(
                !m.flood_fill(layer, Mode::Paint, &image, [-1.0, 3.0], 0.05)
                    .unwrap()
            );
            assert!(
                !m.flood_fill(layer, Mode::Paint, &image, [30.0, 3.0], 0.05)
                    .unwrap()
            );
        }
        let mut m = Masks::new(30, 20);
        assert!(
            m.flood_fill(Layer::Object, Mode::Paint, &image, [0.5, 0.5], 0.0)
                .unwrap()
        );
        assert_eq!(
            m.object().as_slice().iter().filter(|&&o| !o).count(),
            600 - 100 - 16
        );
        let small = Grid::filled(3, 3, 0.0);
        let e = m.flood_fill(Layer::Object, Mode::Paint, &small, [0.0, 0.0], 0.1);
        assert!(e.unwrap_err().to_string().contains("3x3"));
        let e = m.flood_fill(Layer::Object, Mode::Paint, &image, [0.0, 0.0], -1.0);
        assert!(e.unwrap_err().to_string().contains("tolerance"));
    }

    #[test]
    fn threshold_clear_and_invert() {
        let image = scene();
        let mut m = Masks::new(30, 20);
        assert!(m.threshold(&image, 0.1).unwrap());
        assert_eq!(*m.object(), image.map(|&v| v > 0.1));
        assert_eq!(m.object_for_solver().as_ref(), Some(m.object()));
        assert!(
            m.threshold(&image, f64::NAN)
                .unwrap_err()
                .to_string()
                .contains("threshold")
        );
        assert!(m.invert(Layer::Object));
        assert_eq!(*m.object(), image.map(|&v| v <= 0.1));
        m.fill_rect(Layer::Confidence, Mode::Paint, [0.0, 0.0], [3.0, 3.0]);
        assert!(m.invert(Layer::Confidence));
        assert_eq!(
            m.confidence()
                .as_slice()
                .iter()
                .filter(|&&v| v == 1.0)
                .count(),
            9
        );
        assert!(m.clear(Layer::Confidence) && m.clear(Layer::Object) && !m.clear(Layer::Object));
        assert_eq!(state(&m), state(&Masks::new(30, 20)));
        assert!(m.confidence_for_solver().is_none() && m.object_for_solver().is_none());
    }
}
