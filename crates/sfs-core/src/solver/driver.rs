//! The linearised coarse-to-fine Gauss-Newton scheme (paper Section 3):
//! from the shared preparation, `kappa` (up to `kappa_max`) outer
//! Gauss-Newton iterations per level, each with up to `l_max` inner
//! fixed-point iterations on Psi' and a linear solve each (SOR sweeps, or
//! multigrid V-cycles), the update cropped (and backtracked), the depth
//! resampled to the next level; reports to a [`SolveObserver`]. Refining a
//! full-resolution start, the inner iterations stop early where they would
//! only polish the step (see `solve_level`).

use std::time::Instant;

use crate::cancel::Cancel;
use crate::grid::Grid;
use crate::model::{Energy, Reflectance};
use crate::params::{InitialDepth, LinearSolver, SolverParams, StepControl};

use super::coarse_to_fine::{LevelEnd, LevelScheme, LevelStep, coarse_to_fine};
use super::multigrid::Multigrid;
use super::prepare::{Crop, Prepared, level_energy, prepare};
use super::problem::{
    IterationReport, MEMO_MAX_PIXELS, ObserverEvent, PhaseTimes, Problem, RememberedSolve,
    Solution, SolveError, SolveMemo, SolveObserver, check_cancelled, free_on_pool, rows_per_task,
};
use super::sor;
use super::system::LinearSystem;
use super::unused::{Effects, Path, unused_parameters};

/// Solves with the problem's own model and the material of `params`
/// (`auto` as Lambert, what it resolves to; [`super::solve`] runs its fit
/// first): the paper's model with
/// the light at the optical centre, or lights anywhere (METHOD.md section 9).
/// A working copy solved before in the same pipeline is not solved again
/// (see [`SolveMemo`](super::problem::SolveMemo)).
pub fn solve(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    crate::memory::return_large_frees_to_the_system();
    rayon::scope(|_| solve_own_model(problem, params, observer)).map(|(solution, _)| solution)
}

/// Solves with any reflectance model.
///
/// The solve runs on a worker of rayon's global pool (the calling thread
/// waits): parallel loops inside then split work among workers directly,
/// instead of handing every loop from an outside thread to the pool and back,
/// which cost two thread switches per SOR half-sweep.
pub fn solve_with_model<M: Reflectance>(
    problem: &Problem,
    params: &SolverParams,
    model: &M,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    crate::memory::return_large_frees_to_the_system();
    rayon::scope(|_| {
        solve_with_effects(problem, params, model, false, observer).map(|(solution, _)| solution)
    })
}

/// [`solve`] on the calling worker, with what its decisions did; kept in
/// and taken from the observer's memo where it offers one.
fn solve_own_model(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<(Solution, Effects), SolveError> {
    let solve = |observer: &mut dyn SolveObserver| {
        solve_with_effects(
            problem,
            params,
            &problem.model(params.material()),
            true,
            observer,
        )
    };
    let (width, height) = problem.image.size();
    match observer.memo() {
        Some(memo) if width * height <= MEMO_MAX_PIXELS => {
            remembered(&memo, problem, params, observer, solve)
        }
        _ => solve(observer),
    }
}

/// `solve`'s answer from `memo` (its messages sent to `observer` again),
/// or `solve` run and kept there.
fn remembered(
    memo: &SolveMemo,
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
    solve: impl FnOnce(&mut dyn SolveObserver) -> Result<(Solution, Effects), SolveError>,
) -> Result<(Solution, Effects), SolveError> {
    let key = (problem.clone(), params.clone());
    if let Some(kept) = memo.0.get(&key) {
        let start = Instant::now();
        for event in &kept.events {
            match event {
                ObserverEvent::Iteration(report) => observer.on_iteration(report),
                ObserverEvent::Level(level) => observer.on_level(level),
            }
        }
        check_cancelled(observer)?;
        let mut solution = kept.solution;
        solution.seconds = start.elapsed().as_secs_f64();
        solution.phases = PhaseTimes::default();
        return Ok((solution, kept.effects));
    }
    let mut recorder = Recorder {
        observer,
        events: Vec::new(),
    };
    let (solution, effects) = solve(&mut recorder)?;
    memo.0.insert(
        key,
        RememberedSolve {
            solution: solution.clone(),
            effects,
            events: recorder.events,
        },
    );
    Ok((solution, effects))
}

/// Passes everything on and keeps the messages (for [`remembered`]).
struct Recorder<'a> {
    observer: &'a mut dyn SolveObserver,
    events: Vec<ObserverEvent>,
}

impl SolveObserver for Recorder<'_> {
    fn on_iteration(&mut self, report: &IterationReport) {
        self.events.push(ObserverEvent::Iteration(report.clone()));
        self.observer.on_iteration(report);
    }
    fn on_level(&mut self, result: &super::problem::LevelResult) {
        self.events.push(ObserverEvent::Level(result.clone()));
        self.observer.on_level(result);
    }
    fn is_cancelled(&self) -> bool {
        self.observer.is_cancelled()
    }
    fn memo(&self) -> Option<std::sync::Arc<SolveMemo>> {
        self.observer.memo()
    }
}

/// The scheme with `model`, and what its decisions did (for a walked
/// start's refinement, which reports the options of the whole solve).
/// `own_model`: `model` is the problem's own (its intensity scale, lights
/// and `params`' material), so a walked start's copy is solved with its
/// own too, through the memo.
fn solve_with_effects<M: Reflectance>(
    problem: &Problem,
    params: &SolverParams,
    model: &M,
    own_model: bool,
    observer: &mut dyn SolveObserver,
) -> Result<(Solution, Effects), SolveError> {
    let start = Instant::now();
    // The default start where fast marching cannot serve a large image: the
    // same scheme on a working copy (see `prepare::WALK_SIDE`).
    let mut walker = |copy: &Problem, observer: &mut dyn SolveObserver| {
        if own_model {
            solve_own_model(copy, params, observer)
        } else {
            solve_with_effects(copy, params, model, false, observer)
        }
    };
    let mut prepared = prepare(problem, params, Some(start), Some(&mut walker), observer)?;
    let initial = prepared.take_depth();
    let walked = prepared.walked.take();
    let alternatives = std::mem::take(&mut prepared.alternatives);
    let initial = pick_start(initial, alternatives, model, params, &prepared, observer)?;
    let mut scheme = GaussNewton {
        model,
        params,
        schedule: Schedule::new(params, prepared.refines_holes),
        prepared: &prepared,
        // Relative to the depth's own scale: any unit of depth works.
        z_floor: 1e-6 * prepared.initial_depth.abs().max(f64::MIN_POSITIVE),
        phases: PhaseTimes::default(),
        effects: Effects::default(),
    };
    // A start computed by another method (fast marching) is shown to the
    // observer as the first level, so a viewer has a surface at once.
    // (The walked start's own levels were shown as the walk ran.)
    let show_start = matches!(params.initial_depth, InitialDepth::FastMarching) && walked.is_none();
    let walk = coarse_to_fine(
        model,
        &prepared,
        initial,
        show_start,
        prepared.shown,
        start,
        observer,
        &mut scheme,
    )?;
    let mut phases = scheme.phases;
    if let Some(walked) = &walked {
        scheme.effects.merge(walked.effects);
    }
    let unused_parameters = unused_parameters(
        params,
        Path {
            refines_warm_start: prepared.refines_warm_start,
            refines_holes: prepared.refines_holes,
            walked_start: walked.is_some(),
            linear_solver: scheme.schedule.linear_solver,
            kappa: scheme.schedule.kappa,
            kappa_max: scheme.schedule.kappa_max,
            has_object_mask: problem.object_mask.is_some(),
            shadow_bound_moved: walk.shadow_bound_moved,
            start_denoised: prepared.start_denoised,
            auto_start_denoised: prepared.noise.reads_noisy(),
        },
        scheme.effects,
    );
    let effects = scheme.effects;
    let mut iterations = walk.reports.iter().map(|l| l.energies.len()).sum();
    if let Some(walked) = &walked {
        phases.add(&walked.phases);
        iterations += walked.iterations;
    }
    let mut solution =
        walk.into_solution(problem, params, &mut prepared, start, iterations, phases)?;
    if let Some(walked) = walked {
        // The copy's levels first: the report lists every level solved.
        solution.levels.splice(0..0, walked.reports);
    }
    solution.unused_parameters = unused_parameters;
    Ok((solution, effects))
}

/// Of several full-resolution starts (holes leave fast marching's start
/// ambiguous), the one whose first Gauss-Newton step on the full image ends
/// at the lowest energy: the model's own energy decides. A start's energy
/// alone misleads (a start marched on a denoised image fits the data
/// unevenly until a step has evened it out). The steps are not shown to
/// `observer`; cancellation is polled as in the solve.
fn pick_start<M: Reflectance>(
    start: Grid<f64>,
    alternatives: Vec<Grid<f64>>,
    model: &M,
    params: &SolverParams,
    prepared: &Prepared<'_>,
    observer: &mut dyn SolveObserver,
) -> Result<Grid<f64>, SolveError> {
    let Some(finest) = prepared.levels.last() else {
        return Ok(start);
    };
    if alternatives.is_empty() {
        return Ok(start);
    }
    /// Forwards only cancellation.
    struct Quiet<'a>(&'a dyn SolveObserver);
    impl SolveObserver for Quiet<'_> {
        fn is_cancelled(&self) -> bool {
            self.0.is_cancelled()
        }
    }
    let mut trial = GaussNewton {
        model,
        params,
        // One step of the schedule without holes (SOR by default): a cheap
        // probe of each start, the full-size multigrid's setup thrice
        // costs more than it tells.
        schedule: Schedule {
            kappa: 1,
            kappa_max: 1,
            ..Schedule::new(params, false)
        },
        prepared,
        z_floor: 1e-6 * prepared.initial_depth.abs().max(f64::MIN_POSITIVE),
        phases: PhaseTimes::default(),
        effects: Effects::default(),
    };
    let step = LevelStep {
        level: finest,
        index: 0,
        levels: 1,
        finest: true,
        start: Instant::now(),
        start_energy: None,
    };
    let mut best: Option<(f64, Grid<f64>)> = None;
    for candidate in std::iter::once(start).chain(alternatives) {
        let mut stepped = candidate.clone();
        let energy = trial
            .solve_level(&step, &mut stepped, &mut Quiet(&*observer))?
            .energy
            .total;
        // The first start wins ties and non-finite energies.
        if best
            .as_ref()
            .is_none_or(|(lowest, _)| energy < *lowest || !lowest.is_finite())
        {
            best = Some((energy, candidate));
        }
    }
    best.map(|(_, depth)| depth)
        .ok_or_else(|| SolveError::Input("no start to refine".into()))
}

/// One level of the linearised scheme: `kappa` (up to `kappa_max`) outer
/// Gauss-Newton iterations, each with `l_max` inner fixed-point iterations
/// on Psi' and SOR sweeps, the update cropped and (with backtracking) halved
/// until the energy does not rise.
struct GaussNewton<'a, M> {
    model: &'a M,
    params: &'a SolverParams,
    schedule: Schedule,
    prepared: &'a Prepared<'a>,
    z_floor: f64,
    phases: PhaseTimes,
    /// What the parameters' decisions did against the defaults' (for the
    /// unused options).
    effects: Effects,
}

/// What each level of the scheme runs, resolved for the problem: the
/// outer iterations (`kappa_holes` where a start is refined across holes)
/// and the linear solver ([`LinearSolver::Auto`] resolved).
#[derive(Clone, Copy, Debug)]
struct Schedule {
    kappa: usize,
    kappa_max: usize,
    linear_solver: LinearSolver,
}

impl Schedule {
    fn new(params: &SolverParams, refines_holes: bool) -> Self {
        let kappa = match refines_holes {
            true => params.kappa.max(params.kappa_holes),
            false => params.kappa,
        };
        Self {
            kappa,
            kappa_max: params.kappa_max.max(kappa),
            linear_solver: params.linear_solver.resolved(refines_holes),
        }
    }
}

impl<M: Reflectance> LevelScheme for GaussNewton<'_, M> {
    fn solve_level(
        &mut self,
        step: &LevelStep<'_>,
        depth: &mut Grid<f64>,
        observer: &mut dyn SolveObserver,
    ) -> Result<LevelEnd, SolveError> {
        let (model, params, level) = (self.model, self.params, step.level);
        let Prepared {
            alpha,
            lambda,
            crop,
            derivatives,
            refines_warm_start,
            ..
        } = *self.prepared;
        // Every pass over the level polls cancellation per block of rows
        // (seconds each at 18 megapixels otherwise).
        let energy_of = |depth: &Grid<f64>, observer: &dyn SolveObserver| {
            level_energy(
                model,
                level,
                depth,
                alpha,
                lambda,
                Cancel::new(&|| observer.is_cancelled()),
            )
        };
        let mut system = LinearSystem::new(level, Cancel::new(&|| observer.is_cancelled()))?;
        let schedule = self.schedule;
        let mut energies = Vec::with_capacity(schedule.kappa_max);
        // Energy of the current depth on this level, once known.
        let mut current: Option<Energy> = step.start_energy;
        // The defaults' schedule: whether the stopping test decided as the
        // defaults' would have (for the unused options).
        let defaults = SolverParams::for_units(params.units);
        let default_schedule = Schedule::new(
            &SolverParams {
                kappa: defaults.kappa,
                kappa_holes: defaults.kappa_holes,
                ..params.clone()
            },
            self.prepared.refines_holes,
        );
        let converged = |energies: &[f64], tolerance: f64| matches!(energies[..], [.., before, after] if before - after <= tolerance * before);
        // Refining a full-resolution start (not across holes, whose fill
        // moves a small share of the pixels far), the level has converged
        // once an outer iteration moved the depth by less than
        // `step_tolerance` of itself on average (`last_step`).
        let step_rule = refines_warm_start && !self.prepared.refines_holes;
        let settled = |last_step: Option<f64>, tolerance: f64| {
            step_rule && tolerance > 0.0 && last_step.is_some_and(|step| step < tolerance)
        };
        let default_stops = |iteration: usize, energies: &[f64], last_step: Option<f64>| {
            iteration >= default_schedule.kappa_max
                || (iteration >= default_schedule.kappa
                    && converged(energies, defaults.level_tolerance))
                || settled(last_step, defaults.step_tolerance)
        };
        // The mean share of the depth the last outer iteration moved.
        let mut last_step: Option<f64> = None;
        for iteration in 0..schedule.kappa_max {
            let stops = (iteration >= schedule.kappa
                && converged(&energies, params.level_tolerance))
                || settled(last_step, params.step_tolerance);
            if stops != default_stops(iteration, &energies, last_step) {
                self.effects.level_stop_differed = true;
            }
            if stops {
                break; // the level has converged
            }
            let t0 = Instant::now();
            let linearised = system.linearise_data(
                model,
                level,
                depth,
                derivatives,
                Cancel::new(&|| observer.is_cancelled()),
            )?;
            if !linearised {
                return Err(SolveError::Input(
                    "the reflectance model has no exact derivatives; use numeric derivatives"
                        .into(),
                ));
            }
            system.clear_dz(Cancel::new(&|| observer.is_cancelled()))?;
            self.phases.linearise_seconds += t0.elapsed().as_secs_f64();
            // The multigrid hierarchy of this outer iteration's first
            // system serves its later inner iterations too: only Psi' moves.
            let mut hierarchy: Option<Multigrid> = None;
            // The residual at dz = 0: the V-cycles reduce it by
            // `linear_tolerance` (inexact Newton), the stopping test below
            // compares the first solve's residual with it.
            let mut start_residual = 0.0;
            // Whether the later inner iterations would only polish the step
            // (decided after the first solve).
            let mut only_polish = false;
            let adaptive = refines_warm_start && params.inner_tolerance > 0.0;
            // The default tolerance's decisions, for the unused options.
            let adaptive_default = refines_warm_start && defaults.inner_tolerance > 0.0;
            // Where the inner iterations ended: stopped by the tolerance at
            // this index, or `None` after all of them (for the unused options).
            let mut stopped_at: Option<usize> = None;
            for inner in 0..params.inner_iterations {
                let t1 = Instant::now();
                let change = system.update_weights(
                    level,
                    depth,
                    lambda,
                    Cancel::new(&|| observer.is_cancelled()),
                )?;
                self.phases.assemble_seconds += t1.elapsed().as_secs_f64();
                // Refining a full-resolution start, once the weights have
                // settled the later inner iterations only polish the step:
                // where the step is small against the crop (the start is
                // nearly the minimum), and where the sweeps reach only
                // locally (large images). Where one solve's sweeps converge
                // the system and the step is large (small images, far from
                // the minimum), they go on: their sweeps lengthen the step
                // and change the answer. The rows of a system not solved
                // again are not assembled.
                let stops = inner > 0 && adaptive && change < params.inner_tolerance && only_polish;
                let default_stops = inner > 0
                    && adaptive_default
                    && change < defaults.inner_tolerance
                    && only_polish;
                if stops != default_stops {
                    self.effects.inner_stop_differed = true;
                }
                if stops {
                    stopped_at = Some(inner);
                    break;
                }
                let t2 = Instant::now();
                system.assemble(
                    level,
                    depth,
                    alpha,
                    Cancel::new(&|| observer.is_cancelled()),
                )?;
                if inner == 0 && (params.linear_tolerance > 0.0 || adaptive || adaptive_default) {
                    // At dz = 0 the residual is the right-hand side.
                    start_residual = system
                        .rhs_norm_squared(Cancel::new(&|| observer.is_cancelled()))?
                        .sqrt();
                }
                self.phases.assemble_seconds += t2.elapsed().as_secs_f64();
                self.phases.inner_iterations += 1;
                self.linear_solve(
                    &mut system,
                    &mut hierarchy,
                    params.linear_tolerance * start_residual,
                    observer,
                )?;
                if inner == 0 && (adaptive || adaptive_default) {
                    // The step's length first (a light pass); the residual
                    // (a pass over the whole system) only where that does
                    // not decide.
                    only_polish =
                        step_share_of_crop(depth, &system, &level.domain, crop, observer)?
                            < SMALL_STEP
                            || residual_norm(&system, observer)? > LOCAL_REACH * start_residual;
                }
            }
            // The default count would have ended the same way where the
            // tolerance stopped below it; a loop that ran its whole count
            // ends elsewhere with another count, unless the count is below
            // the default's and the default's tolerance would have stopped
            // right there. That stop test needs the weights once more; they
            // are rebuilt before any later use, so the answer is untouched.
            self.effects.inner_count_differed |= match stopped_at {
                Some(at) => at > defaults.inner_iterations,
                None if params.inner_iterations < defaults.inner_iterations
                    && params.inner_iterations > 0
                    && adaptive_default
                    && only_polish =>
                {
                    let change = system.update_weights(
                        level,
                        depth,
                        lambda,
                        Cancel::new(&|| observer.is_cancelled()),
                    )?;
                    change >= defaults.inner_tolerance
                }
                None => params.inner_iterations != defaults.inner_iterations,
            };
            let t3 = Instant::now();
            let z_floor = self.z_floor;
            let (moved, energy) = match params.step_control {
                StepControl::Crop => {
                    let before = match current {
                        Some(energy) => energy,
                        None => energy_of(depth, observer)?,
                    };
                    let moved =
                        apply_update(depth, &system, &level.domain, crop, 1.0, z_floor, observer);
                    check_cancelled(observer)?;
                    let after = energy_of(depth, observer)?;
                    // Backtracking would have halved this step.
                    self.effects.energy_rose |= after.total > before.total;
                    (moved, after)
                }
                StepControl::Backtracking => {
                    let before = match current {
                        Some(energy) => energy,
                        None => energy_of(depth, observer)?,
                    };
                    // The depth before the trial steps, kept in the
                    // system's data part (dead until the next linearisation).
                    system.stash_depth(depth);
                    let mut scale = 1.0;
                    loop {
                        let moved = apply_update(
                            depth,
                            &system,
                            &level.domain,
                            crop,
                            scale,
                            z_floor,
                            observer,
                        );
                        check_cancelled(observer)?;
                        let after = energy_of(depth, observer)?;
                        if after.total <= before.total || scale < 1.0 / 16.0 {
                            break (moved, after);
                        }
                        system.restore_depth(depth);
                        scale *= 0.5;
                    }
                }
            };
            energies.push(energy.total);
            current = Some(energy);
            last_step = Some(moved.mean_share);
            let max_step = moved.max;
            self.phases.update_seconds += t3.elapsed().as_secs_f64();
            observer.on_iteration(&IterationReport {
                level: step.index,
                levels: step.levels,
                width: level.geometry.width,
                height: level.geometry.height,
                iteration,
                energy,
                max_step,
                elapsed: step.start.elapsed(),
            });
        }
        if energies.len() == schedule.kappa_max
            && !default_stops(schedule.kappa_max, &energies, last_step)
        {
            // The defaults would have gone on past kappa-max.
            self.effects.level_stop_differed = true;
        }
        // Whether the cap bound: the level ran past the default cap, or
        // ended at its own lower cap where the stopping test would not
        // have stopped it.
        let ran = energies.len();
        let default_cap = Schedule::new(
            &SolverParams {
                kappa_max: defaults.kappa_max,
                ..params.clone()
            },
            self.prepared.refines_holes,
        )
        .kappa_max;
        self.effects.kappa_max_bound |= ran > default_cap
            || (ran == schedule.kappa_max
                && ran < default_cap
                && !(ran >= schedule.kappa && converged(&energies, params.level_tolerance))
                && !settled(last_step, params.step_tolerance));
        let energy = match current {
            Some(energy) => energy,
            None => energy_of(depth, observer)?,
        };
        // Freeing the system's pages takes tens of milliseconds at 18 MP: on
        // the pool, polling meanwhile, and done before the level's results
        // are allocated (a peak that does not depend on thread timing).
        free_on_pool(system, observer)?;
        Ok(LevelEnd {
            energies,
            energy,
            out_of_budget: false,
        })
    }
}

impl<M> GaussNewton<'_, M> {
    /// One inner iteration's linear solve from the current unknowns:
    /// `sor_iterations` SOR sweeps, or V-cycles (`cycles` at most) until the
    /// residual is at most `target` (0: all of them).
    fn linear_solve(
        &mut self,
        system: &mut LinearSystem,
        hierarchy: &mut Option<Multigrid>,
        target: f64,
        observer: &dyn SolveObserver,
    ) -> Result<(), SolveError> {
        let params = self.params;
        let t0 = Instant::now();
        match self.schedule.linear_solver {
            LinearSolver::Sor | LinearSolver::Auto => {
                for _ in 0..params.sor_iterations {
                    sor::sweep(
                        system,
                        params.omega,
                        Cancel::new(&|| observer.is_cancelled()),
                    )?;
                    self.phases.linear_iterations += 1;
                }
            }
            LinearSolver::Multigrid => {
                check_cancelled(observer)?;
                let multigrid = match hierarchy {
                    Some(multigrid) => multigrid,
                    None => {
                        let t1 = Instant::now();
                        let built = Multigrid::build(system, params.smoothing_sweeps);
                        self.phases.hierarchy_seconds += t1.elapsed().as_secs_f64();
                        hierarchy.insert(built)
                    }
                };
                for _ in 0..params.cycles {
                    check_cancelled(observer)?;
                    multigrid.cycle(system, &Multigrid::SMOOTHER);
                    self.phases.linear_iterations += 1;
                    if target > 0.0 && multigrid.residual_norm(system) <= target {
                        break;
                    }
                }
            }
        }
        self.phases.linear_seconds += t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// The first solve of an outer iteration that leaves more than this share
/// of the residual has sweeps that reach only locally (see `solve_level`).
const LOCAL_REACH: f64 = 0.1;

/// A first step whose mean length is below this share of the crop's mean
/// limit is small: the start is nearly the level's minimum (see
/// `solve_level`).
const SMALL_STEP: f64 = 0.25;

/// The mean length of the system's step `dz` over `domain` as a share of the
/// mean limit `crop` puts on it at `depth` (`Err` once cancelled).
fn step_share_of_crop(
    depth: &Grid<f64>,
    system: &LinearSystem,
    domain: &Grid<bool>,
    crop: Crop,
    observer: &dyn SolveObserver,
) -> Result<f64, SolveError> {
    use rayon::prelude::*;
    let w = depth.size().0;
    let (step, limit) = depth
        .as_slice()
        .par_chunks(w)
        .enumerate()
        .with_min_len(rows_per_task(w))
        .map(|(r, row)| {
            let mut sums = (0.0, 0.0);
            if observer.is_cancelled() {
                return sums;
            }
            for (c, &z) in row.iter().enumerate() {
                if *domain.at(c, r) {
                    let dz = f64::from(system.dz_padded[system.padded_index(c, r)]);
                    sums.0 += if dz.is_finite() { dz.abs() } else { 0.0 };
                    sums.1 += crop.limit(z);
                }
            }
            sums
        })
        // Summed in row order: the same decision on every run.
        .collect::<Vec<(f64, f64)>>()
        .into_iter()
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    check_cancelled(observer)?;
    Ok(if limit > 0.0 { step / limit } else { 0.0 })
}

/// The norm of the system's residual at its current unknowns (`Err` once
/// cancelled).
fn residual_norm(system: &LinearSystem, observer: &dyn SolveObserver) -> Result<f64, SolveError> {
    Ok(system
        .residual_norm_squared(Cancel::new(&|| observer.is_cancelled()))?
        .sqrt())
}

/// What one update moved: its largest step, and the mean of its steps'
/// lengths as a share of the mean depth over the domain (after the update).
#[derive(Clone, Copy, Debug)]
struct Moved {
    max: f64,
    mean_share: f64,
}

/// Crops `dz`, adds it to the depth (kept above `z_floor`), returns what it
/// moved. Rows in parallel (the sums added in row order: the same on every
/// run), each polling `observer`'s cancellation (the depth is then half
/// updated: the caller stops).
fn apply_update(
    depth: &mut Grid<f64>,
    system: &LinearSystem,
    domain: &Grid<bool>,
    crop: Crop,
    scale: f64,
    z_floor: f64,
    observer: &dyn SolveObserver,
) -> Moved {
    use rayon::prelude::*;
    let w = depth.size().0;
    let rows: Vec<[f64; 3]> = depth
        .as_mut_slice()
        .par_chunks_mut(w)
        .enumerate()
        .with_min_len(rows_per_task(w))
        .map(|(r, row)| {
            // Largest step, sum of steps, sum of depths.
            let mut sums = [0.0f64; 3];
            if observer.is_cancelled() {
                return sums;
            }
            for (c, z) in row.iter_mut().enumerate() {
                if !domain.at(c, r) {
                    continue;
                }
                let dz = f64::from(system.dz_padded[system.padded_index(c, r)]);
                let limit = crop.limit(*z);
                let dz = if dz.is_finite() {
                    scale * dz.clamp(-limit, limit)
                } else {
                    0.0
                };
                let new = (*z + dz).max(z_floor);
                let step = (new - *z).abs();
                sums[0] = sums[0].max(step);
                sums[1] += step;
                sums[2] += new.abs();
                *z = new;
            }
            sums
        })
        .collect();
    let [max, steps, depths] = rows.into_iter().fold([0.0f64; 3], |a, b| {
        [a[0].max(b[0]), a[1] + b[1], a[2] + b[2]]
    });
    Moved {
        max,
        mean_share: if depths > 0.0 { steps / depths } else { 0.0 },
    }
}
