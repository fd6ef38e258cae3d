//! What every panel is handed: the session and settings to read and
//! change, the actions it asks of the app, and the names of the panels.

use std::path::PathBuf;

use super::super::session::{Export, Session};
use super::super::settings::Settings;
use crate::mask_edit::Layer;

/// Which 2-D panel is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Panel2d {
    /// The input with the mask overlay (paint here).
    Input,
    /// The reprojected image of the latest level.
    Reprojection,
    /// `|input - reprojection|`.
    Difference,
    /// Depth with a colour map.
    Depth,
    /// `|depth - ground truth|` (with ground truth).
    DepthError,
    /// A set's albedo, grey.
    Albedo,
    /// A set's normals, normal-map colours.
    Normals,
    /// One photograph's residual under its own light (a set).
    PhotoResidual,
    /// The depth of one photograph solved alone against the set's.
    SingleDifference,
}

/// What the panels ask the app to do after the frame (what needs more
/// than the document being edited: files, the worker, the window).
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Open an image (or a set folder).
    Open(PathBuf),
    /// Open several photographs (or a folder) as one photometric-stereo set.
    OpenSet(Vec<PathBuf>),
    /// Solve photograph `index` of the set alone and compare.
    SolveSingle(usize),
    /// The same with the set's albedo divided out of the photograph first.
    SolveSingleWithSetAlbedo(usize),
    /// Apply a camera file.
    LoadCamera(PathBuf),
    /// Load a mask PNG into a layer.
    LoadMask(Layer, PathBuf),
    /// Save a mask layer as PNG.
    SaveMask(Layer, PathBuf),
    /// Export the finished result.
    Export(PathBuf, Export),
    /// Save a screenshot of the window.
    Screenshot(PathBuf),
    /// Cancel the running solve.
    CancelSolve,
    /// Solve now.
    SolveNow,
    /// Parameters or the camera changed: solve after the debounce.
    RequestSolve,
    /// Show a message on the status line.
    Notice(String),
    /// Clear the status line's message.
    DismissNotice,
    /// Lower the confidence where the model cannot hold (one undo step).
    SuggestConfidence,
}

/// What the panels read and edit in one frame, and where they put what the
/// app must do.
pub struct UiContext<'a> {
    /// The document and its solve (masks and camera are edited in place).
    pub session: &'a mut Session,
    /// Persisted settings (edited in place).
    pub settings: &'a mut Settings,
    /// The status line's message.
    pub notice: Option<&'a str>,
    /// Actions for the app, run after the frame.
    pub actions: &'a mut Vec<Action>,
}

impl UiContext<'_> {
    /// The names of the open set's photographs (`None`: no set is open).
    pub(super) fn set_names(&self) -> Option<Vec<String>> {
        self.session
            .document
            .as_ref()
            .and_then(|d| d.set.as_ref())
            .map(|s| s.names())
    }
}
