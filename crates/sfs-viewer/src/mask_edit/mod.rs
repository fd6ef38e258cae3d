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

mod edit;
mod history;
mod overlay;
mod persist;
mod rect;
mod stroke;

pub use history::DEFAULT_HISTORY_BYTES;
pub use overlay::OverlayStyle;
pub use persist::autosave_dir;
pub use stroke::Brush;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use sfs_core::grid::Grid;
use sfs_core::io::IoError;

use history::History;
use stroke::Stroke;

/// A position in image pixel coordinates `[x, y]` (see the module docs).
pub type ImagePoint = [f32; 2];

/// Smallest accepted brush radius. A hard brush of this radius centred on a
/// pixel centre covers exactly that pixel; radii below about 0.71 can miss
/// every pixel centre when the cursor is near a pixel corner.
pub const MIN_BRUSH_RADIUS_PX: f32 = 0.5;

/// Why a mask operation failed; messages name the file or parameter.
#[derive(Debug, thiserror::Error)]
pub enum MaskError {
    /// Reading or writing a file failed (the message names the file; a mask
    /// file of the wrong size is [`IoError::SizeMismatch`]).
    #[error(transparent)]
    Io(#[from] IoError),
    /// A parameter is out of range.
    #[error("invalid {name}: {reason}")]
    Parameter {
        /// The parameter, as named in the API (`radius_px`, `tolerance`, ...).
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// An image or layer passed in does not have the size of the masks.
    #[error(
        "the {what} is {}x{} but the masks are {}x{}",
        found.0, found.1, expected.0, expected.1
    )]
    SizeMismatch {
        /// What was passed in (`image`, `object mask`).
        what: &'static str,
        /// Its `(width, height)`.
        found: (usize, usize),
        /// The masks' `(width, height)`.
        expected: (usize, usize),
    },
    /// An autosave folder exists but cannot be restored.
    #[error("autosave {} is unusable: {reason}", path.display())]
    Autosave {
        /// The autosave file concerned.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
}

fn parameter(name: &'static str, reason: String) -> MaskError {
    MaskError::Parameter { name, reason }
}

/// Which mask an edit applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Layer {
    /// The confidence mask, `c` in [0, 1], 1 = trusted.
    Confidence,
    /// The object mask, `true` = object, `false` = background.
    Object,
}

/// What an edit does to the pixels it covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Mode {
    /// Exclude: confidence towards 0, object to background.
    Paint,
    /// Restore: confidence towards 1, object to object.
    Erase,
}

/// A layer's cell type.
trait Cell: Copy + PartialEq {
    /// The value of a cleared layer.
    const DEFAULT: Self;
    /// What a hard shape sets in `mode`.
    fn target(mode: Mode) -> Self;
    /// A stroke's value from the value at its start and its coverage.
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self;
    /// The inverted value.
    fn inverted(self) -> Self;
}

impl Cell for f32 {
    const DEFAULT: Self = 1.0;
    fn target(mode: Mode) -> Self {
        if mode == Mode::Erase { 1.0 } else { 0.0 }
    }
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self {
        match mode {
            Mode::Paint => start.min(1.0 - coverage),
            Mode::Erase => start.max(coverage),
        }
    }
    fn inverted(self) -> Self {
        1.0 - self
    }
}

impl Cell for bool {
    const DEFAULT: Self = true;
    fn target(mode: Mode) -> Self {
        mode == Mode::Erase
    }
    fn blend(start: Self, coverage: f32, mode: Mode) -> Self {
        if coverage >= 0.5 {
            Self::target(mode)
        } else {
            start
        }
    }
    fn inverted(self) -> Self {
        !self
    }
}

/// The two editable masks of one image, with their undo/redo history.
#[derive(Clone, Debug)]
pub struct Masks {
    confidence: Grid<f32>,
    object: Grid<bool>,
    history: History,
    stroke: Option<Stroke>,
    revision: u64,
}

impl Masks {
    /// Default masks (every pixel trusted and object) for a `width` x
    /// `height` image.
    pub fn new(width: usize, height: usize) -> Self {
        let confidence = Grid::filled(width, height, 1.0);
        let object = Grid::filled(width, height, true);
        Self::with_layers(confidence, object)
    }

    fn with_layers(confidence: Grid<f32>, object: Grid<bool>) -> Self {
        Self {
            confidence,
            object,
            history: History::new(DEFAULT_HISTORY_BYTES),
            stroke: None,
            revision: 0,
        }
    }

    /// Masks holding the given layers, with an empty history. Errors when the
    /// sizes differ or a confidence value is outside [0, 1].
    pub fn from_layers(confidence: Grid<f32>, object: Grid<bool>) -> Result<Self, MaskError> {
        let (found, expected) = (object.size(), confidence.size());
        if found != expected {
            return Err(MaskError::SizeMismatch {
                what: "object mask",
                found,
                expected,
            });
        }
        let values = confidence.as_slice();
        if let Some(k) = values.iter().position(|v| !(0.0..=1.0).contains(v)) {
            let (c, r) = (k % expected.0, k / expected.0);
            let reason = format!("value {} at ({c}, {r}) is outside [0, 1]", values[k]);
            return Err(parameter("confidence", reason));
        }
        Ok(Self::with_layers(confidence, object))
    }

    /// `(width, height)` of the masks.
    pub fn size(&self) -> (usize, usize) {
        self.confidence.size()
    }

    /// The confidence layer (1 = trusted).
    pub fn confidence(&self) -> &Grid<f32> {
        &self.confidence
    }

    /// The object layer (`true` = object).
    pub fn object(&self) -> &Grid<bool> {
        &self.object
    }

    /// The confidence for the solver's `Problem`: `None` when every pixel is
    /// trusted.
    pub fn confidence_for_solver(&self) -> Option<Grid<f64>> {
        let all_trusted = self.confidence.as_slice().iter().all(|&v| v == 1.0);
        (!all_trusted).then(|| self.confidence.map(|&v| f64::from(v)))
    }

    /// The object mask for the solver's `Problem`: `None` when every pixel
    /// is object.
    pub fn object_for_solver(&self) -> Option<Grid<bool>> {
        let all_object = self.object.as_slice().iter().all(|&v| v);
        (!all_object).then(|| self.object.clone())
    }

    /// A counter that changes whenever a mask value changes (during strokes
    /// too, and on undo/redo); the app re-solves and re-uploads the overlay
    /// when it differs from the value it last saw.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    fn bump(&mut self) {
        self.revision = self.revision.wrapping_add(1);
    }
}

/// Helpers shared by the tests of the child modules.
#[cfg(test)]
mod test_support {
    use super::*;

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
