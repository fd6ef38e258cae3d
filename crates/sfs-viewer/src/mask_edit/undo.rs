//! The undo/redo log: each step the bounding box of the pixels an edit
//! changed with their values before and after, the whole bounded in bytes
//! (see the [module docs](super)). It knows nothing of the masks.

use std::collections::VecDeque;

use sfs_core::grid::Grid;

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
    pub(super) fn bytes(&self) -> usize {
        size_of::<Self>() + (self.before.len() + self.after.len()) * size_of::<T>()
    }

    pub(super) fn apply(&self, grid: &mut Grid<T>, forward: bool) {
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
    pub(super) fn bytes(&self) -> usize {
        match self {
            Change::Confidence(d) => d.bytes(),
            Change::Object(d) => d.bytes(),
        }
    }
}

/// Undo and redo stacks with their total size.
#[derive(Clone, Debug)]
pub(super) struct History {
    pub(super) undo: VecDeque<Change>,
    pub(super) redo: Vec<Change>,
    pub(super) bytes: usize,
    pub(super) limit_bytes: usize,
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
    pub(super) fn trim(&mut self) {
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
