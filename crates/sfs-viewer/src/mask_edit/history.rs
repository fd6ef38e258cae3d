//! Undo and redo: every edit is one step holding the bounding box of the
//! pixels it changed with their values before and after; the history is
//! bounded in bytes (see the [module docs](super)).

use std::collections::VecDeque;

use sfs_core::grid::Grid;

use super::Masks;
use super::rect::{Rect, whole};

/// Default bound on the undo/redo history: 256 MiB of diffs.
pub const DEFAULT_HISTORY_BYTES: usize = 256 << 20;

/// One layer's part of an undo step: the values of `rect` before and after.
#[derive(Clone, Debug)]
pub(super) struct Diff<T> {
    rect: Rect,
    before: Vec<T>,
    after: Vec<T>,
}

impl<T: Copy> Diff<T> {
    fn bytes(&self) -> usize {
        size_of::<Self>() + (self.before.len() + self.after.len()) * size_of::<T>()
    }

    fn apply(&self, grid: &mut Grid<T>, forward: bool) {
        let (w, rect) = (grid.width(), self.rect);
        let values = if forward { &self.after } else { &self.before };
        for (k, r) in (rect.y0..rect.y1).enumerate() {
            grid.as_mut_slice()[r * w + rect.x0..r * w + rect.x1]
                .copy_from_slice(&values[k * rect.width()..(k + 1) * rect.width()]);
        }
    }
}

/// The diff between `before` (the values of `rect`) and `grid`, over the
/// bounding box of the pixels that differ; `None` when none does.
pub(super) fn diff<T: Copy + PartialEq>(
    grid: &Grid<T>,
    before: &[T],
    rect: Rect,
) -> Option<Diff<T>> {
    let now = grid.as_slice();
    let mut changed = None;
    for r in rect.y0..rect.y1 {
        for c in rect.x0..rect.x1 {
            if now[r * grid.width() + c] != before[(r - rect.y0) * rect.width() + c - rect.x0] {
                changed = Some(Rect::include(changed, c, r));
            }
        }
    }
    let tight = changed?;
    let (before, after) = (tight.gather(before, rect), tight.gather(now, whole(grid)));
    Some(Diff {
        rect: tight,
        before,
        after,
    })
}

/// Sets every pixel of `rect` to `f(column, row, old)` and returns the diff.
pub(super) fn region_edit<T: Copy + PartialEq>(
    grid: &mut Grid<T>,
    rect: Rect,
    mut f: impl FnMut(usize, usize, T) -> T,
) -> Option<Diff<T>> {
    let before = rect.gather(grid.as_slice(), whole(grid));
    for r in rect.y0..rect.y1 {
        for c in rect.x0..rect.x1 {
            let v = grid.at_mut(c, r);
            *v = f(c, r, *v);
        }
    }
    diff(grid, &before, rect)
}

/// One undo step.
#[derive(Clone, Debug)]
pub(super) enum Change {
    Confidence(Diff<f32>),
    Object(Diff<bool>),
}

impl Change {
    fn bytes(&self) -> usize {
        match self {
            Change::Confidence(d) => d.bytes(),
            Change::Object(d) => d.bytes(),
        }
    }
}

/// Undo and redo stacks with their total size.
#[derive(Clone, Debug)]
pub(super) struct History {
    undo: VecDeque<Change>,
    redo: Vec<Change>,
    bytes: usize,
    limit_bytes: usize,
}

impl History {
    /// An empty history bounded to `limit_bytes`.
    pub(super) fn new(limit_bytes: usize) -> Self {
        Self {
            undo: VecDeque::new(),
            redo: Vec::new(),
            bytes: 0,
            limit_bytes,
        }
    }

    pub(super) fn push(&mut self, change: Change) {
        for c in self.redo.drain(..) {
            self.bytes -= c.bytes();
        }
        self.bytes += change.bytes();
        self.undo.push_back(change);
        self.trim();
    }

    /// Drops the oldest undo steps (keeping the newest), then the farthest
    /// redo steps, until the history fits its limit.
    fn trim(&mut self) {
        while self.bytes > self.limit_bytes && self.undo.len() > 1 {
            if let Some(c) = self.undo.pop_front() {
                self.bytes -= c.bytes();
            }
        }
        while self.bytes > self.limit_bytes && !self.redo.is_empty() {
            self.bytes -= self.redo.remove(0).bytes();
        }
    }
}

impl Masks {
    /// Whether [`Masks::undo`] would do something.
    pub fn can_undo(&self) -> bool {
        !self.history.undo.is_empty() || self.stroke.as_ref().is_some_and(|s| s.dirty.is_some())
    }

    /// Whether [`Masks::redo`] would do something.
    pub fn can_redo(&self) -> bool {
        !self.history.redo.is_empty()
    }

    /// Bytes held by the undo and redo steps.
    pub fn history_bytes(&self) -> usize {
        self.history.bytes
    }

    /// The history bound in bytes.
    pub fn history_limit_bytes(&self) -> usize {
        self.history.limit_bytes
    }

    /// Sets the history bound, dropping the oldest steps that no longer fit.
    pub fn set_history_limit_bytes(&mut self, limit_bytes: usize) {
        self.history.limit_bytes = limit_bytes;
        self.history.trim();
    }

    /// Pushes `change` (if any) on the history and bumps the revision;
    /// returns whether there was a change.
    pub(super) fn record(&mut self, change: Option<Change>) -> bool {
        let Some(change) = change else { return false };
        self.history.push(change);
        self.bump();
        true
    }

    pub(super) fn apply(&mut self, change: &Change, forward: bool) {
        match change {
            Change::Confidence(d) => d.apply(&mut self.confidence, forward),
            Change::Object(d) => d.apply(&mut self.object, forward),
        }
        self.bump();
    }

    /// Undoes the last edit (ending a stroke in progress first); false when
    /// there is nothing to undo.
    pub fn undo(&mut self) -> bool {
        self.end_stroke();
        let Some(change) = self.history.undo.pop_back() else {
            return false;
        };
        self.apply(&change, false);
        self.history.redo.push(change);
        true
    }

    /// Redoes the last undone edit; false when there is none.
    pub fn redo(&mut self) -> bool {
        self.end_stroke();
        let Some(change) = self.history.redo.pop() else {
            return false;
        };
        self.apply(&change, true);
        self.history.undo.push_back(change);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::test_support::*;
    use crate::mask_edit::{Layer, Mode};
    use sfs_core::io;
    use tempfile::tempdir;

    #[test]
    fn undo_and_redo_every_kind_of_edit() {
        let dir = tempdir().unwrap();
        let png = dir.path().join("loaded.png");
        io::write_png8(&png, &Grid::from_fn(30, 20, |c, _| c as f64 / 29.0)).unwrap();
        let (image, soft, hard) = (
            scene(),
            brush(4.0, 0.3, Mode::Paint),
            brush(3.0, 1.0, Mode::Paint),
        );
        let (c, o) = (Layer::Confidence, Layer::Object);
        type Edit<'a> = Box<dyn Fn(&mut Masks) -> bool + 'a>;
        let edits: Vec<Edit> = vec![
            Box::new(|m| {
                stroke(m, c, soft, &[[3.0, 3.0], [25.0, 12.0]]);
                true
            }),
            Box::new(|m| {
                stroke(m, o, hard, &[[20.0, 3.0], [6.0, 15.0]]);
                true
            }),
            Box::new(|m| m.fill_rect(c, Mode::Erase, [4.0, 4.0], [9.0, 7.0])),
            Box::new(|m| m.fill_lasso(o, Mode::Erase, &[[0.0, 0.0], [30.0, 0.0], [0.0, 20.0]])),
            Box::new(|m| {
                m.flood_fill(c, Mode::Paint, &image, [8.0, 8.0], 0.1)
                    .unwrap()
            }),
            Box::new(|m| m.invert(c)),
            Box::new(|m| m.threshold(&image, 0.1).unwrap()),
            Box::new(|m| m.clear(o)),
            Box::new(|m| m.load_png(c, &png, m.size()).unwrap()),
        ];
        let mut m = Masks::new(30, 20);
        let mut states = vec![state(&m)];
        for edit in &edits {
            assert!(edit(&mut m));
            assert_ne!(state(&m), *states.last().unwrap());
            states.push(state(&m));
        }
        for expected in states.iter().rev().skip(1) {
            let before = m.revision();
            assert!(m.undo());
            assert_ne!(m.revision(), before);
            assert_eq!(state(&m), *expected);
        }
        assert!(!m.undo() && m.can_redo());
        for expected in &states[1..] {
            assert!(m.redo());
            assert_eq!(state(&m), *expected);
        }
        assert!(!m.redo());
        // A new edit clears the redo stack.
        assert!(m.undo() && m.undo() && m.can_redo());
        assert!(m.fill_rect(o, Mode::Erase, [0.0, 0.0], [2.0, 2.0]));
        assert!(!m.can_redo() && !m.redo());
        assert!(m.undo());
        assert_eq!(state(&m), states[states.len() - 3]);
        // Undo in the middle of a stroke undoes that stroke.
        m.begin_stroke(c, hard, [1.0, 1.0]).unwrap();
        assert!(m.can_undo() && m.undo());
        assert_eq!(state(&m), states[states.len() - 3]);
    }

    #[test]
    fn history_is_bounded() {
        let mut m = Masks::new(64, 8);
        let square = |m: &mut Masks, k: usize| {
            let x = 4.0 * k as f32;
            assert!(m.fill_rect(Layer::Confidence, Mode::Paint, [x, 0.0], [x + 4.0, 4.0]));
            state(m)
        };
        square(&mut m, 0);
        let step = m.history_bytes();
        assert!((2 * 16 * 4..2 * 16 * 4 + 200).contains(&step), "{step}");
        m.set_history_limit_bytes(3 * step);
        let states: Vec<_> = (1..10).map(|k| square(&mut m, k)).collect();
        assert_eq!(m.history_bytes(), 3 * step);
        assert!(m.undo() && m.undo() && m.undo() && !m.undo());
        assert_eq!(state(&m), states[5]);
        // The newest step is kept even when alone it exceeds the limit.
        m.set_history_limit_bytes(1);
        assert_eq!(m.history_bytes(), 0);
        assert!(m.clear(Layer::Confidence) && m.history_bytes() > 1);
        assert!(m.undo() && !m.undo());
        assert_eq!(state(&m), states[5]);
    }

    #[test]
    fn revision_changes_with_every_change_only() {
        let mut m = Masks::new(10, 10);
        let r0 = m.revision();
        assert!(!m.fill_rect(Layer::Confidence, Mode::Erase, [0.0, 0.0], [10.0, 10.0]));
        assert_eq!(m.revision(), r0);
        m.begin_stroke(Layer::Confidence, brush(1.0, 1.0, Mode::Paint), [2.0, 2.0])
            .unwrap();
        let r1 = m.revision();
        assert_ne!(r1, r0);
        m.stroke_segment([2.0, 2.0], [8.0, 2.0]);
        let r2 = m.revision();
        assert_ne!(r2, r1);
        m.stroke_segment([8.0, 2.0], [2.0, 2.0]);
        assert!(m.end_stroke());
        assert_eq!(m.revision(), r2);
        assert!(m.undo());
        assert_ne!(m.revision(), r2);
    }
}
