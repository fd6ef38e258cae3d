//! The plain types every part of the mask editor shares: a point, the
//! layers, the modes, the errors and how a pixel of each layer blends.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use sfs_core::io::IoError;

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

pub(super) fn parameter(name: &'static str, reason: String) -> MaskError {
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
pub(super) trait Cell: Copy + PartialEq {
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
