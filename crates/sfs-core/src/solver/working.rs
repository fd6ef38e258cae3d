//! What the searches share: a working copy of a problem at a smaller size,
//! and an observer that passes only cancellation through (their trial
//! solves are not levels of the user's solve).

use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::resample::{resize_area, scale_intrinsics, working_size};

use super::problem::{Problem, SolveObserver};

/// The working copy of `problem` at a longest side of `side` pixels.
pub(crate) fn working_copy(problem: &Problem, side: usize) -> Problem {
    let (w, h) = problem.image.size();
    let (sw, sh) = working_size(w, h, Some(side));
    let resize = |grid: &Grid<f64>| resize_area(grid, sw, sh, Cancel::NEVER).uncancelled();
    let mask = problem
        .object_mask
        .as_ref()
        .map(|m| resize(&m.map(|&v| if v { 1.0 } else { 0.0 })).map(|&v| v >= 0.5));
    Problem {
        image: resize(&problem.image),
        camera: scale_intrinsics(problem.camera, (w, h), (sw, sh)),
        intensity_scale: problem.intensity_scale,
        object_mask: mask,
        confidence: problem
            .confidence
            .as_ref()
            .map(|c| resize(c).map(|v| v.clamp(0.0, 1.0))),
        lights: problem.lights.clone(),
    }
}

/// Passes cancellation through, nothing else (the trials are not levels of
/// the user's solve).
pub(crate) struct Forward<'a>(pub(crate) &'a mut dyn SolveObserver);

impl SolveObserver for Forward<'_> {
    fn is_cancelled(&self) -> bool {
        self.0.is_cancelled()
    }
}
