//! Undo and redo: every edit is one step holding the bounding box of the
//! pixels it changed with their values before and after; the history is
//! bounded in bytes (see the [module docs](super)).

use super::masks::Masks;
use super::undo::Change;

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
        self.step(false)
    }

    /// Redoes the last undone edit; false when there is none.
    pub fn redo(&mut self) -> bool {
        self.step(true)
    }

    /// Redoes (`forward`) or undoes one edit, moving it to the other list.
    fn step(&mut self, forward: bool) -> bool {
        self.end_stroke();
        let change = if forward {
            self.history.redo.pop()
        } else {
            self.history.undo.pop_back()
        };
        let Some(change) = change else {
            return false;
        };
        self.apply(&change, forward);
        if forward {
            self.history.undo.push_back(change);
        } else {
            self.history.redo.push(change);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::test_support::*;
    use crate::mask_edit::{Layer, Mode};
    use sfs_core::grid::Grid;
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
