//! The coarse-to-fine loop both variational schemes share (IPOL style: the
//! single-level solver apart from the driver): the depth resampled from level
//! to level, a [`LevelScheme`] run on each, every level's result sent to the
//! observer, the per-level reports kept, and a scheme that runs out of budget
//! carried straight to full resolution.

use std::time::Instant;

use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::model::{self, Energy, Reflectance};

use super::prepare::{Prepared, level_energy, level_result};
use super::problem::{
    LevelReport, PhaseTimes, Problem, Solution, SolveError, SolveObserver, check_cancelled,
    on_object,
};
use super::pyramid::{self, PyramidLevel};
use crate::params::SolverParams;

/// One level as the loop hands it to a scheme.
pub(crate) struct LevelStep<'a> {
    /// The level.
    pub level: &'a PyramidLevel<'a>,
    /// Its index as observers see it (after a shown start).
    pub index: usize,
    /// The number of levels observers see.
    pub levels: usize,
    /// Whether it is the full-resolution level.
    pub finest: bool,
    /// When the solve started.
    pub start: Instant,
    /// The energy of the depth the level starts from, where the loop knows
    /// it (the first level: computed for the walk's report), so that a
    /// scheme need not evaluate it again.
    pub start_energy: Option<Energy>,
}

/// What a scheme reports at the end of a level.
pub(crate) struct LevelEnd {
    /// Energies after each step (the scheme's own convention).
    pub energies: Vec<f64>,
    /// The energy of the level's final depth.
    pub energy: Energy,
    /// A time or iteration budget ran out: stop refining.
    pub out_of_budget: bool,
}

/// A variational scheme's work on one level.
pub(crate) trait LevelScheme {
    /// Improves `depth` on `step.level`, reporting iterations to `observer`
    /// and polling its cancellation.
    fn solve_level(
        &mut self,
        step: &LevelStep<'_>,
        depth: &mut Grid<f64>,
        observer: &mut dyn SolveObserver,
    ) -> Result<LevelEnd, SolveError>;
}

/// What the loop produced.
pub(crate) struct Walk {
    /// Depth at full resolution (on the finest level's domain).
    pub depth: Grid<f64>,
    /// Its reprojection.
    pub reprojection: Grid<f64>,
    /// Per-level reports, coarsest first.
    pub reports: Vec<LevelReport>,
    /// Energy of the initial depth on the first level.
    pub initial_energy: Energy,
    /// Energy of the result at full resolution.
    pub final_energy: Energy,
    /// Whether a budget stopped the scheme.
    pub budget_exhausted: bool,
    /// With the shadow bound asked for and a shadow taken out: the pixels
    /// it moved onto their grazing rays; `None` when it did not run.
    pub shadow_bound_moved: Option<usize>,
}

impl Walk {
    /// The solve's result: the depth and reprojection on the object, the
    /// walk's energies and reports, `prepared`'s start, alpha, lambda,
    /// scales and shadow, the scheme's `iterations` and `phases`.
    pub(crate) fn into_solution(
        self,
        problem: &Problem,
        params: &SolverParams,
        prepared: &mut Prepared<'_>,
        start: Instant,
        iterations: usize,
        phases: PhaseTimes,
    ) -> Result<Solution, SolveError> {
        let shadow = prepared.shadow.take();
        let (depth, reprojection) = on_object(problem, self.depth, self.reprojection);
        Solution {
            depth,
            reprojection,
            initial_energy: self.initial_energy,
            final_energy: self.final_energy,
            levels: self.reports,
            phases,
            initial_depth: prepared.initial_depth,
            seconds: start.elapsed().as_secs_f64(),
            iterations,
            budget_exhausted: self.budget_exhausted,
            shadow,
            alpha: prepared.alpha_used,
            alpha_px: prepared.alpha,
            lambda_px: prepared.lambda,
            scales: prepared.scales,
            material: params.material(),
            material_fit: None,
            albedo_fit: None,
            start_denoised: prepared.start_denoised,
            noise: Some(prepared.noise),
            unused_parameters: Vec::new(),
        }
        .checked()
    }
}

/// Runs `scheme` coarse to fine over `prepared`'s levels from its initial
/// depth. With `show_start`, the initial depth (a start computed by another
/// method) is sent to the observer first as a level of its own. `shown`
/// levels were sent before (a preview): the indices count on from them.
/// `depth` is the initial depth on the coarsest level (taken out of
/// `prepared` by [`Prepared::take_depth`]: one copy at full resolution, not
/// two).
#[allow(clippy::too_many_arguments)]
pub(crate) fn coarse_to_fine<M: Reflectance>(
    model: &M,
    prepared: &Prepared,
    mut depth: Grid<f64>,
    show_start: bool,
    shown: usize,
    start: Instant,
    observer: &mut dyn SolveObserver,
    scheme: &mut impl LevelScheme,
) -> Result<Walk, SolveError> {
    let levels = &prepared.levels;
    let (alpha, lambda) = (prepared.alpha, prepared.lambda);
    let offset = usize::from(show_start) + shown;
    let count = levels.len() + offset;
    check_cancelled(observer)?;
    let initial_energy = level_energy(
        model,
        &levels[0],
        &depth,
        alpha,
        lambda,
        Cancel::new(&|| observer.is_cancelled()),
    )?;
    if show_start {
        let result = level_result(
            model,
            &levels[0],
            &depth,
            shown,
            count,
            initial_energy,
            start,
            Cancel::new(&|| observer.is_cancelled()),
        )?;
        // A cancelled reprojection is incomplete: it is not shown.
        check_cancelled(observer)?;
        observer.on_level(&result);
        check_cancelled(observer)?;
    }
    let mut walk = Walk {
        depth: Grid::filled(0, 0, 0.0),
        reprojection: Grid::filled(0, 0, 0.0),
        reports: Vec::with_capacity(levels.len()),
        initial_energy,
        final_energy: initial_energy,
        budget_exhausted: false,
        shadow_bound_moved: None,
    };
    let finest = &levels[levels.len() - 1];
    for (index, level) in levels.iter().enumerate() {
        let level_start = Instant::now();
        if index > 0 {
            depth = pyramid::upsample_depth(&depth, &levels[index - 1].domain, &level.domain);
        }
        let step = LevelStep {
            level,
            index: index + offset,
            levels: count,
            finest: index + 1 == levels.len(),
            start,
            start_energy: (index == 0).then_some(initial_energy),
        };
        let mut end = scheme.solve_level(&step, &mut depth, observer)?;
        // With the shadow bound asked for, what the shadow says is checked
        // against the full-resolution surface: shadow pixels it would light
        // go back onto the ray that grazes their occluder
        // (`shadow_bound`), and the level's energy follows.
        if step.finest
            && prepared.shadow_bound
            && let Some(shadow) = &prepared.shadow
        {
            let moved = super::shadow_bound::enforce(
                level,
                shadow,
                prepared.lights,
                &mut depth,
                Cancel::new(&|| observer.is_cancelled()),
            )?;
            walk.shadow_bound_moved = Some(moved);
            if moved > 0 {
                end.energy = level_energy(
                    model,
                    level,
                    &depth,
                    alpha,
                    lambda,
                    Cancel::new(&|| observer.is_cancelled()),
                )?;
            }
        }
        walk.final_energy = end.energy;
        let result = level_result(
            model,
            level,
            &depth,
            step.index,
            count,
            end.energy,
            start,
            Cancel::new(&|| observer.is_cancelled()),
        )?;
        check_cancelled(observer)?;
        observer.on_level(&result);
        walk.reprojection = std::sync::Arc::unwrap_or_clone(result.reprojection);
        walk.reports.push(LevelReport {
            width: level.geometry.width,
            height: level.geometry.height,
            energies: end.energies,
            seconds: level_start.elapsed().as_secs_f64(),
        });
        if end.out_of_budget {
            walk.budget_exhausted = true;
            if !step.finest {
                // Carry the current depth straight to full resolution.
                depth = pyramid::upsample_depth(&depth, &level.domain, &finest.domain);
                walk.final_energy =
                    level_energy(model, finest, &depth, alpha, lambda, Cancel::NEVER).uncancelled();
                walk.reprojection = model::reproject(
                    model,
                    &finest.geometry,
                    &finest.domain,
                    &depth,
                    Cancel::NEVER,
                )
                .uncancelled();
            }
            break;
        }
    }
    walk.depth = depth;
    Ok(walk)
}
