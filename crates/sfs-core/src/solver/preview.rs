//! The quick first look of a large solve: fast marching on the image
//! area-averaged to [`PREVIEW_SIDE`] pixels, sent to the observer as level 0
//! before the full-resolution start is computed, so a viewer shows a
//! surface at once instead of after the start's seconds at photograph size.

use std::time::Instant;

use super::fast_marching::{FastMarchingParams, solve_fast_marching};
use super::problem::{IterationReport, LevelResult, Problem, SolveError, SolveObserver};
use crate::cancel::Cancel;
use crate::grid::Grid;
use crate::resample::{resize_area, scale_intrinsics, working_size};

/// Longest side of the preview, in pixels.
pub const PREVIEW_SIDE: usize = 256;
/// Images with more pixels than this get a preview (512x512): below it the
/// start itself takes a few tens of milliseconds.
pub const PREVIEW_ABOVE_PIXELS: usize = 512 * 512;

/// Forwards cancellation and relabels the preview's level.
struct Relabel<'a> {
    observer: &'a mut dyn SolveObserver,
    levels: usize,
    start: Instant,
    sent: bool,
}

impl SolveObserver for Relabel<'_> {
    fn on_iteration(&mut self, _report: &IterationReport) {}
    fn on_level(&mut self, result: &LevelResult) {
        let mut relabelled = result.clone();
        relabelled.level = 0;
        relabelled.levels = self.levels;
        relabelled.elapsed = self.start.elapsed();
        self.observer.on_level(&relabelled);
        self.sent = true;
    }
    fn is_cancelled(&self) -> bool {
        self.observer.is_cancelled()
    }
    fn memo(&self) -> Option<std::sync::Arc<super::problem::SolveMemo>> {
        self.observer.memo()
    }
}

/// Sends the preview of `problem` to `observer` as level 0 of `levels`,
/// with its time measured from `start`; whether it was sent. A problem too
/// small, or one whose preview cannot be solved (the object vanishes at the
/// preview's size), sends nothing; cancellation is passed on.
pub(crate) fn send_preview(
    problem: &Problem,
    material: crate::material::Material,
    levels: usize,
    start: Instant,
    observer: &mut dyn SolveObserver,
) -> Result<bool, SolveError> {
    let (w, h) = problem.image.size();
    if w * h <= PREVIEW_ABOVE_PIXELS {
        return Ok(false);
    }
    let (pw, ph) = working_size(w, h, Some(PREVIEW_SIDE));
    let cancelled = || observer.is_cancelled();
    let cancel = Cancel::new(&cancelled);
    let resize = |grid: &Grid<f64>| resize_area(grid, pw, ph, cancel);
    let image = resize(&problem.image)?;
    let object_mask = match &problem.object_mask {
        Some(mask) => Some(resize(&mask.map(|&o| f64::from(u8::from(o))))?.map(|&v| v >= 0.5)),
        None => None,
    };
    let confidence = match &problem.confidence {
        Some(confidence) => Some(resize(confidence)?),
        None => None,
    };
    let small = Problem {
        image,
        camera: scale_intrinsics(problem.camera, (w, h), (pw, ph)),
        intensity_scale: problem.intensity_scale,
        object_mask,
        confidence,
        lights: problem.lights.clone(),
    };
    let mut relabel = Relabel {
        observer,
        levels,
        start,
        sent: false,
    };
    match solve_fast_marching(
        &small,
        &FastMarchingParams::for_material(material),
        &mut relabel,
    ) {
        Err(SolveError::Cancelled) => Err(SolveError::Cancelled),
        // Only a preview: the full solve reports its own errors.
        _ => Ok(relabel.sent),
    }
}
