//! The mask editing model behind the image panel: the solver's two masks as
//! editable layers, brush strokes, shapes, whole-layer operations, undo/redo
//! with compact diffs, PNG load/save, crash-safe autosave and the overlay
//! texture. No UI and no egui: the app maps pointer events to these calls.
//!
//! # Coordinates
//!
//! Every position is an [`ImagePoint`] in image pixel coordinates `[x, y]`:
//! pixel `(column c, row r)` covers `[c, c + 1) x [r, r + 1)`, its centre is
//! `(c + 0.5, r + 0.5)`, and brushes and shapes test pixel centres. The app
//! maps screen positions to image coordinates with its zoom/pan transform, so
//! the masks do not depend on the zoom.
//!
//! # Layers and modes
//!
//! [`Layer::Confidence`] holds `c` in [0, 1] (1 = trusted, the default; 0 =
//! do not trust); [`Layer::Object`] holds `true` for object (surface, the
//! default) and `false` for background (no surface). [`Mode::Paint`] excludes
//! (towards `c = 0` / background), [`Mode::Erase`] restores (towards `c = 1` /
//! object).
//!
//! # Strokes
//!
//! A stroke keeps, for every pixel, the largest brush coverage it has received
//! so far (coverage falls with the distance from the pixel centre to each
//! segment, see [`Brush::coverage`]) and sets each pixel from its value at the
//! start of the stroke `c0` and that coverage `a`:
//! paint `c = min(c0, 1 - a)`, erase `c = max(c0, a)`; on the object layer a
//! pixel flips when `a >= 0.5`. A segment is covered exactly (the distance to
//! the whole segment, the limit of infinitely dense stamps), so fast mouse
//! moves leave no gaps, overlapping parts of one stroke do not compound and
//! the result does not depend on the order or direction of the segments.
//!
//! # History
//!
//! Every edit (a whole stroke, a shape, a whole-layer operation, a load) is
//! one undo step holding the bounding box of the pixels it changed with their
//! values before and after. The history keeps at most
//! [`Masks::history_limit_bytes`] of such diffs (default
//! [`DEFAULT_HISTORY_BYTES`]) and drops the oldest steps beyond it; the newest
//! step is always kept, even when it alone is larger.
//!
//! # Layout
//!
//! This file holds the layers ([`Masks`], its construction and accessors)
//! and the types every part shares; each child module adds its own
//! `impl Masks` block: `stroke` (brushes and strokes), `edit` (shapes and
//! whole-layer operations), `history` (undo/redo diffs), `persist` (PNG
//! load/save, autosave/restore, [`autosave_dir`]; the one place a mask file
//! is read and size-checked) and `overlay` ([`OverlayStyle`] and the
//! overlay's RGBA); `rect` holds the pixel rectangles they share. The public
//! paths stay `mask_edit::Masks`, `mask_edit::Brush` and so on.

mod brush;
mod edit;
mod history;
mod masks;
mod overlay;
mod persist;
mod rect;
mod stroke;
mod types;
mod undo;

pub use brush::Brush;
pub use masks::Masks;
pub use overlay::OverlayStyle;
pub use persist::autosave_dir;
pub use types::{ImagePoint, Layer, MIN_BRUSH_RADIUS_PX, MaskError, Mode};
pub use undo::DEFAULT_HISTORY_BYTES;

/// Helpers shared by the tests of the child modules.
#[cfg(test)]
mod test_support {
    use super::*;
    use sfs_core::grid::Grid;

    pub(super) fn brush(radius_px: f32, hardness: f32, mode: Mode) -> Brush {
        Brush {
            radius_px,
            hardness,
            mode,
        }
    }

    /// Paints one stroke through `points` and ends it.
    pub(super) fn stroke(m: &mut Masks, layer: Layer, b: Brush, points: &[ImagePoint]) {
        m.begin_stroke(layer, b, points[0]).unwrap();
        for p in points.windows(2) {
            assert!(m.stroke_segment(p[0], p[1]));
        }
        m.end_stroke();
    }

    pub(super) fn state(m: &Masks) -> (Grid<f32>, Grid<bool>) {
        (m.confidence().clone(), m.object().clone())
    }

    /// Whether pixel `(c, r)` of `layer` is fully excluded.
    pub(super) fn excluded(m: &Masks, layer: Layer, c: usize, r: usize) -> bool {
        match layer {
            Layer::Confidence => *m.confidence().at(c, r) == 0.0,
            Layer::Object => !*m.object().at(c, r),
        }
    }

    /// Dark background 0.05, a bright textured square at columns and rows
    /// 5..15 and a detached bright square at columns 20..24, rows 2..6.
    pub(super) fn scene() -> Grid<f64> {
        Grid::from_fn(30, 20, |c, r| {
            let big = (5..15).contains(&c) && (5..15).contains(&r);
            let small = (20..24).contains(&c) && (2..6).contains(&r);
            if big || small {
                0.7 + 0.01 * ((c + r) % 3) as f64
            } else {
                0.05
            }
        })
    }
}
