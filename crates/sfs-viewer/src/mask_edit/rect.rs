//! Pixel rectangles: the bounding boxes of edits and undo steps, and the
//! pixels whose centres lie in a span. Uses `Grid` only.

use sfs_core::grid::Grid;

/// A pixel rectangle `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Rect {
    pub(super) x0: usize,
    pub(super) y0: usize,
    pub(super) x1: usize,
    pub(super) y1: usize,
}

impl Rect {
    pub(super) fn new(x0: usize, y0: usize, x1: usize, y1: usize) -> Self {
        Self { x0, y0, x1, y1 }
    }

    pub(super) fn width(&self) -> usize {
        self.x1 - self.x0
    }

    pub(super) fn area(&self) -> usize {
        self.width() * (self.y1 - self.y0)
    }

    /// The smallest rectangle holding `rect` (if any) and pixel `(c, r)`.
    pub(super) fn include(rect: Option<Rect>, c: usize, r: usize) -> Rect {
        match rect {
            None => Rect::new(c, r, c + 1, r + 1),
            Some(q) => Rect::new(q.x0.min(c), q.y0.min(r), q.x1.max(c + 1), q.y1.max(r + 1)),
        }
    }

    /// The smallest rectangle holding this one and `other` (if any).
    pub(super) fn union(self, other: Option<Rect>) -> Rect {
        let q = Rect::include(other, self.x0, self.y0);
        Rect::include(Some(q), self.x1 - 1, self.y1 - 1)
    }

    /// The values of this rectangle taken from `data`, the row-major values
    /// of rectangle `within` (which holds this one).
    pub(super) fn gather<T: Copy>(&self, data: &[T], within: Rect) -> Vec<T> {
        let mut out = Vec::with_capacity(self.area());
        for r in self.y0..self.y1 {
            let start = (r - within.y0) * within.width() + self.x0 - within.x0;
            out.extend_from_slice(&data[start..start + self.width()]);
        }
        out
    }
}

/// The whole of `grid` as a rectangle.
pub(super) fn whole<T>(grid: &Grid<T>) -> Rect {
    Rect::new(0, 0, grid.width(), grid.height())
}

/// Indices `[start, end)` of the pixels among `0..n` whose centres lie in
/// `[lo, hi]`; `None` when there are none (or a bound is NaN).
pub(super) fn span(lo: f32, hi: f32, n: usize) -> Option<(usize, usize)> {
    let start = (f64::from(lo) - 0.5).ceil().max(0.0);
    let end = ((f64::from(hi) - 0.5).floor() + 1.0).min(n as f64);
    (start < end).then_some((start as usize, end as usize))
}

/// The pixels of a `size` grid whose centres lie in `[x0, x1] x [y0, y1]`.
pub(super) fn rect_spanning(x: (f32, f32), y: (f32, f32), size: (usize, usize)) -> Option<Rect> {
    let (x0, x1) = span(x.0, x.1, size.0)?;
    let (y0, y1) = span(y.0, y.1, size.1)?;
    Some(Rect::new(x0, y0, x1, y1))
}
