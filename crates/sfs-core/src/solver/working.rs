//! What the searches share: a working copy of a problem at a smaller size,
//! an observer that passes only cancellation through (their trial solves
//! are not levels of the user's solve), and how well a trial explains its
//! image.

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
    fn memo(&self) -> Option<std::sync::Arc<super::problem::SolveMemo>> {
        self.0.memo()
    }
}

/// Passes cancellation through from an observer shared between solves run
/// side by side, nothing else (no memo: such trials are not repeated).
pub(crate) struct CancelOnly<'a>(pub(crate) &'a dyn SolveObserver);

impl SolveObserver for CancelOnly<'_> {
    fn is_cancelled(&self) -> bool {
        self.0.is_cancelled()
    }
}

/// How well a trial solve explains its image: `sqrt(sum c (I - R)^2 /
/// sum c I^2)` over the solved pixels (finite depth), `c` the confidence.
pub(crate) fn relative_residual(problem: &Problem, solution: &super::problem::Solution) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for q in 0..problem.image.len() {
        if !solution.depth.as_slice()[q].is_finite() {
            continue;
        }
        let c = problem.confidence.as_ref().map_or(1.0, |c| c.as_slice()[q]);
        let (i, r) = (
            problem.image.as_slice()[q],
            solution.reprojection.as_slice()[q],
        );
        num += c * (i - r) * (i - r);
        den += c * i * i;
    }
    (num / den.max(f64::MIN_POSITIVE)).sqrt()
}
