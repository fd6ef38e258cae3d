//! The two editable layers of one image with their history and the stroke
//! in progress; the editing operations are `impl Masks` blocks in the
//! sibling modules.

use sfs_core::grid::Grid;

use super::brush::Stroke;
use super::types::{MaskError, parameter};
use super::undo::{DEFAULT_HISTORY_BYTES, History};

/// The two editable masks of one image, with their undo/redo history.
#[derive(Clone, Debug)]
pub struct Masks {
    pub(super) confidence: Grid<f32>,
    pub(super) object: Grid<bool>,
    pub(super) history: History,
    pub(super) stroke: Option<Stroke>,
    pub(super) revision: u64,
}

impl Masks {
    /// Default masks (every pixel trusted and object) for a `width` x
    /// `height` image.
    pub fn new(width: usize, height: usize) -> Self {
        let confidence = Grid::filled(width, height, 1.0);
        let object = Grid::filled(width, height, true);
        Self::with_layers(confidence, object)
    }

    pub(super) fn with_layers(confidence: Grid<f32>, object: Grid<bool>) -> Self {
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

    pub(super) fn bump(&mut self) {
        self.revision = self.revision.wrapping_add(1);
    }
}
