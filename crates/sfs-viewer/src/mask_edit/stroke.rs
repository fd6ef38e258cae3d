//! Brushes and strokes: a stroke keeps each pixel's largest coverage so far
//! and sets the pixel from its value at the start of the stroke (see the
//! [module docs](super)); a whole stroke is one undo step.

use super::brush::{Brush, Snapshot, Stroke};
use super::masks::Masks;
use super::rect::{Rect, rect_spanning, whole};
use super::types::{Cell, ImagePoint, Layer, MaskError};
use super::undo::{Change, diff};

/// Distance from `p` to the segment `a`-`b`, symmetric in `a` and `b` to
/// the last bit (so a segment's direction does not matter).
fn distance_to_segment(p: ImagePoint, a: ImagePoint, b: ImagePoint) -> f32 {
    let (a, b) = if (a[0], a[1]) <= (b[0], b[1]) {
        (a, b)
    } else {
        (b, a)
    };
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (px, py) = (p[0] - a[0], p[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        ((px * dx + py * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - t * dx).powi(2) + (py - t * dy).powi(2)).sqrt()
}

/// Covers segment `from`-`to` with `brush`: raises the stroke's per-pixel
/// coverage and sets the values from the stroke's start values. Returns the
/// bounding box of the values that changed. Allocates nothing.
fn stamp<T: Cell>(
    values: &mut [T],
    start: &[T],
    coverage: &mut [f32],
    size: (usize, usize),
    brush: &Brush,
    [from, to]: [ImagePoint; 2],
) -> Option<Rect> {
    let r = brush.radius_px;
    let x = (from[0].min(to[0]) - r, from[0].max(to[0]) + r);
    let y = (from[1].min(to[1]) - r, from[1].max(to[1]) + r);
    let rect = rect_spanning(x, y, size)?;
    let mut changed = None;
    for row in rect.y0..rect.y1 {
        for col in rect.x0..rect.x1 {
            let centre = [col as f32 + 0.5, row as f32 + 0.5];
            let a = brush.coverage(distance_to_segment(centre, from, to));
            let i = row * size.0 + col;
            if a > coverage[i] {
                coverage[i] = a;
                let v = T::blend(start[i], a, brush.mode);
                if v != values[i] {
                    values[i] = v;
                    changed = Some(Rect::include(changed, col, row));
                }
            }
        }
    }
    changed
}

impl Masks {
    /// Starts a stroke on `layer` and covers the point `at`. A stroke in
    /// progress is ended first. Errors (changing nothing) on an invalid brush.
    pub fn begin_stroke(
        &mut self,
        layer: Layer,
        brush: Brush,
        at: ImagePoint,
    ) -> Result<(), MaskError> {
        brush.validate()?;
        self.end_stroke();
        let start = match layer {
            Layer::Confidence => Snapshot::Confidence(self.confidence.as_slice().to_vec()),
            Layer::Object => Snapshot::Object(self.object.as_slice().to_vec()),
        };
        let coverage = vec![0.0; self.confidence.len()];
        self.stroke = Some(Stroke {
            brush,
            coverage,
            start,
            dirty: None,
        });
        self.stroke_segment(at, at);
        Ok(())
    }

    /// Covers the segment `from`-`to` with the stroke's brush. Returns false
    /// (doing nothing) when no stroke is in progress or a coordinate is not
    /// finite.
    pub fn stroke_segment(&mut self, from: ImagePoint, to: ImagePoint) -> bool {
        let size = self.size();
        let Some(Stroke {
            brush,
            coverage,
            start,
            dirty,
        }) = self.stroke.as_mut()
        else {
            return false;
        };
        if !from.iter().chain(&to).all(|v| v.is_finite()) {
            return false;
        }
        let segment = [from, to];
        let (confidence, object) = (self.confidence.as_mut_slice(), self.object.as_mut_slice());
        let changed = match start {
            Snapshot::Confidence(s) => stamp(confidence, s, coverage, size, brush, segment),
            Snapshot::Object(s) => stamp(object, s, coverage, size, brush, segment),
        };
        if let Some(rect) = changed {
            *dirty = Some(rect.union(*dirty));
            self.bump();
        }
        true
    }

    /// Whether a stroke is in progress.
    pub fn is_stroking(&self) -> bool {
        self.stroke.is_some()
    }

    /// Ends the stroke in progress and returns its change, if any.
    fn take_stroke(&mut self) -> Option<Change> {
        let stroke = self.stroke.take()?;
        let rect = stroke.dirty?;
        Some(match stroke.start {
            Snapshot::Confidence(s) => {
                let before = rect.gather(&s, whole(&self.confidence));
                Change::Confidence(diff(&self.confidence, &before, rect)?)
            }
            Snapshot::Object(s) => {
                let before = rect.gather(&s, whole(&self.object));
                Change::Object(diff(&self.object, &before, rect)?)
            }
        })
    }

    /// Ends the stroke in progress and records it as one undo step; returns
    /// whether a step was recorded (false when no stroke was in progress or
    /// it changed nothing). The revision does not change here.
    pub fn end_stroke(&mut self) -> bool {
        let change = self.take_stroke();
        change.map(|c| self.history.push(c)).is_some()
    }

    /// Abandons the stroke in progress, restoring the values it changed;
    /// returns whether anything was restored.
    pub fn cancel_stroke(&mut self) -> bool {
        let change = self.take_stroke();
        change.map(|c| self.apply(&c, false)).is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::Mode;
    use crate::mask_edit::test_support::*;

    /// Distance from the centre of pixel `(c, r)` to the polyline `points`.
    fn distance(c: usize, r: usize, points: &[ImagePoint]) -> f32 {
        let p = [c as f32 + 0.5, r as f32 + 0.5];
        let segments = points
            .windows(2)
            .map(|s| distance_to_segment(p, s[0], s[1]));
        segments.fold(distance_to_segment(p, points[0], points[0]), f32::min)
    }

    #[test]
    fn brush_edges_gaps_and_erase() {
        let mut m = Masks::new(40, 40);
        stroke(
            &mut m,
            Layer::Confidence,
            brush(5.0, 1.0, Mode::Paint),
            &[[20.0, 20.0]],
        );
        let soft = brush(8.0, 0.25, Mode::Paint);
        let mut s = Masks::new(40, 40);
        stroke(&mut s, Layer::Confidence, soft, &[[20.0, 20.0]]);
        stroke(&mut s, Layer::Object, soft, &[[20.0, 20.0]]);
        let mut ramp = 0;
        for (r, c) in (0..40).flat_map(|r| (0..40).map(move |c| (r, c))) {
            let d = distance(c, r, &[[20.0, 20.0]]);
            assert_eq!(*m.confidence().at(c, r), if d <= 5.0 { 0.0 } else { 1.0 });
            let v = *s.confidence().at(c, r);
            assert_eq!(v, 1.0 - soft.coverage(d));
            assert!(
                (v == 0.0) == (d <= 2.0) && (v == 1.0) == (d >= 8.0),
                "{d} {v}"
            );
            ramp += usize::from(v > 0.0 && v < 1.0);
            assert_eq!(*s.object().at(c, r), soft.coverage(d) < 0.5, "({c}, {r})");
        }
        assert!(ramp > 100, "{ramp}");
        // Erasing with a larger hard brush restores both layers exactly.
        let erase = brush(8.5, 1.0, Mode::Erase);
        stroke(&mut s, Layer::Confidence, erase, &[[20.0, 20.0]]);
        stroke(&mut s, Layer::Object, erase, &[[20.0, 20.0]]);
        assert_eq!(state(&s), state(&Masks::new(40, 40)));

        // Two far-apart points in one segment: every pixel near it, no gaps.
        let mut m = Masks::new(100, 60);
        let points = [[2.0, 3.0], [97.0, 55.0], [3.0, 57.0]];
        stroke(
            &mut m,
            Layer::Confidence,
            brush(1.0, 1.0, Mode::Paint),
            &points,
        );
        for (r, c) in (0..60).flat_map(|r| (0..100).map(move |c| (r, c))) {
            assert_eq!(
                excluded(&m, Layer::Confidence, c, r),
                distance(c, r, &points) <= 1.0
            );
        }
        for c in 2..97 {
            assert!(
                (0..60).any(|r| excluded(&m, Layer::Confidence, c, r)),
                "gap at {c}"
            );
        }
    }

    #[test]
    fn strokes_are_order_independent_and_do_not_compound() {
        let soft = brush(6.0, 0.2, Mode::Paint);
        let points = [[10.0, 10.0], [20.0, 14.0], [13.0, 22.0], [11.0, 11.0]];
        let (mut forward, mut backward) = (Masks::new(32, 32), Masks::new(32, 32));
        stroke(&mut forward, Layer::Confidence, soft, &points);
        let reversed: Vec<_> = points.iter().rev().copied().collect();
        stroke(&mut backward, Layer::Confidence, soft, &reversed);
        assert_eq!(forward.confidence(), backward.confidence());

        let (mut once, mut many) = (Masks::new(32, 32), Masks::new(32, 32));
        stroke(&mut once, Layer::Confidence, soft, &[[16.0, 16.0]]);
        stroke(&mut many, Layer::Confidence, soft, &[[16.0, 16.0]; 5]);
        assert_eq!(once.confidence(), many.confidence());
        // A second stroke does combine with the first (min rule).
        stroke(&mut many, Layer::Confidence, soft, &[[17.0, 16.0]]);
        let pairs = many
            .confidence()
            .as_slice()
            .iter()
            .zip(once.confidence().as_slice());
        assert!(pairs.clone().all(|(a, b)| a <= b) && pairs.clone().any(|(a, b)| a < b));
    }

    #[test]
    fn invalid_brush_and_cancelled_stroke() {
        let mut m = Masks::new(8, 8);
        let e = m.begin_stroke(Layer::Confidence, brush(0.2, 1.0, Mode::Paint), [1.0, 1.0]);
        assert!(e.unwrap_err().to_string().contains("radius_px"));
        let e = m.begin_stroke(Layer::Object, brush(2.0, f32::NAN, Mode::Paint), [1.0, 1.0]);
        assert!(e.unwrap_err().to_string().contains("hardness"));
        assert!(!m.is_stroking() && !m.stroke_segment([1.0, 1.0], [2.0, 2.0]));
        m.begin_stroke(Layer::Object, brush(2.0, 1.0, Mode::Paint), [4.0, 4.0])
            .unwrap();
        assert!(excluded(&m, Layer::Object, 4, 4));
        assert!(!m.stroke_segment([f32::NAN, 1.0], [2.0, 2.0]));
        assert!(m.cancel_stroke());
        assert_eq!(state(&m), state(&Masks::new(8, 8)));
        assert!(!m.can_undo());
    }
}
