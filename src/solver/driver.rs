//! The linearised coarse-to-fine Gauss-Newton scheme (paper Section 3):
//! from the shared preparation, `kappa` (up to `kappa_max`) outer
//! Gauss-Newton iterations per level, each with `l_max` inner fixed-point
//! iterations on Psi' and SOR sweeps, the update cropped (and backtracked),
//! the depth resampled to the next level; reports to a [`SolveObserver`].

use std::time::Instant;

use crate::grid::Grid;
use crate::model::{Energy, Lambertian, Reflectance};
use crate::params::{InitialDepth, SolverParams, StepControl};

use super::prepare::{Crop, Prepared, level_energy, level_result, prepare};
use super::problem::{
    IterationReport, LevelReport, PhaseTimes, Problem, Solution, SolveError, SolveObserver,
    on_object,
};
use super::pyramid;
use super::sor;
use super::system::LinearSystem;

/// Solves with the Lambertian model of the paper.
pub fn solve(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let model = Lambertian {
        intensity_scale: problem.intensity_scale,
    };
    solve_with_model(problem, params, &model, observer)
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
    rayon::scope(|_| solve_on_worker(problem, params, model, observer))
}

fn solve_on_worker<M: Reflectance>(
    problem: &Problem,
    params: &SolverParams,
    model: &M,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let start = Instant::now();
    let Prepared {
        levels,
        mut depth,
        initial_depth,
        alpha,
        lambda,
        scales,
        alpha_used,
        crop,
        derivatives,
    } = prepare(problem, params)?;
    // A start computed by another method (fast marching) is shown to the
    // observer as the first level, so a viewer has a surface at once.
    let offset = usize::from(matches!(params.initial_depth, InitialDepth::FastMarching));
    let level_count = levels.len() + offset;
    let coarsest = &levels[0];
    let initial_energy = level_energy(model, coarsest, &depth, alpha, lambda);
    let z_floor = 1e-6 * initial_depth.abs().max(1e-9);
    if offset == 1 {
        observer.on_level(&level_result(
            model,
            coarsest,
            &depth,
            0,
            level_count,
            initial_energy,
            start,
        ));
    }

    let mut reports = Vec::with_capacity(level_count);
    // The finest level's reprojection, kept for the solution.
    let mut last_reprojection = Grid::filled(0, 0, 0.0);
    let mut phases = PhaseTimes::default();
    let mut final_energy = initial_energy;
    for (index, level) in levels.iter().enumerate() {
        let level_start = Instant::now();
        if index > 0 {
            depth = pyramid::upsample_depth(&depth, &levels[index - 1].domain, &level.domain);
        }
        let mut system = LinearSystem::new(level);
        let mut energies = Vec::with_capacity(params.kappa_max);
        // Energy of the current depth on this level, once known.
        let mut current_energy: Option<Energy> = None;
        // The depth before a trial step (backtracking), reused across iterations.
        let mut previous = depth.clone();
        for iteration in 0..params.kappa_max {
            if iteration >= params.kappa
                && let [.., before, after] = energies[..]
                && before - after <= params.level_tolerance * before
            {
                break; // the level has converged
            }
            let t0 = Instant::now();
            if !system.linearise_data(model, level, &depth, derivatives) {
                return Err(SolveError::Input(
                    "the reflectance model has no exact derivatives; use numeric derivatives"
                        .into(),
                ));
            }
            system.clear_dz();
            phases.linearise_seconds += t0.elapsed().as_secs_f64();
            for _ in 0..params.inner_iterations {
                let t1 = Instant::now();
                system.add_smoothness(level, alpha, lambda);
                phases.assemble_seconds += t1.elapsed().as_secs_f64();
                let t2 = Instant::now();
                for _ in 0..params.sor_iterations {
                    if observer.is_cancelled() {
                        return Err(SolveError::Cancelled);
                    }
                    sor::sweep(&mut system, params.omega);
                }
                phases.sor_seconds += t2.elapsed().as_secs_f64();
            }
            let t3 = Instant::now();
            let (max_step, energy) = match params.step_control {
                StepControl::Crop => {
                    let step = apply_update(&mut depth, &system, &level.domain, crop, 1.0, z_floor);
                    (step, level_energy(model, level, &depth, alpha, lambda))
                }
                StepControl::Backtracking => {
                    let before = match current_energy {
                        Some(e) => e,
                        None => level_energy(model, level, &depth, alpha, lambda),
                    };
                    previous.as_mut_slice().copy_from_slice(depth.as_slice());
                    let mut scale = 1.0;
                    loop {
                        let step =
                            apply_update(&mut depth, &system, &level.domain, crop, scale, z_floor);
                        let after = level_energy(model, level, &depth, alpha, lambda);
                        if after.total <= before.total || scale < 1.0 / 16.0 {
                            break (step, after);
                        }
                        depth.as_mut_slice().copy_from_slice(previous.as_slice());
                        scale *= 0.5;
                    }
                }
            };
            energies.push(energy.total);
            current_energy = Some(energy);
            phases.update_seconds += t3.elapsed().as_secs_f64();
            final_energy = energy;
            observer.on_iteration(&IterationReport {
                level: index + offset,
                levels: level_count,
                width: level.geometry.width,
                height: level.geometry.height,
                iteration,
                energy,
                max_step,
                elapsed: start.elapsed(),
            });
        }
        let result = level_result(
            model,
            level,
            &depth,
            index + offset,
            level_count,
            final_energy,
            start,
        );
        observer.on_level(&result);
        last_reprojection = result.reprojection;
        reports.push(LevelReport {
            width: level.geometry.width,
            height: level.geometry.height,
            energies,
            seconds: level_start.elapsed().as_secs_f64(),
        });
    }
    let (depth, reprojection) = on_object(problem, &depth, &last_reprojection);
    let iterations = reports.iter().map(|l| l.energies.len()).sum();
    Ok(Solution {
        depth,
        reprojection,
        initial_energy,
        final_energy,
        levels: reports,
        phases,
        initial_depth,
        seconds: start.elapsed().as_secs_f64(),
        iterations,
        budget_exhausted: false,
        alpha: alpha_used,
        alpha_px: alpha,
        lambda_px: lambda,
        scales,
    })
}

/// Crops `dz`, adds it to the depth (kept above `z_floor`), returns the
/// largest applied step.
fn apply_update(
    depth: &mut Grid<f64>,
    system: &LinearSystem,
    domain: &Grid<bool>,
    crop: Crop,
    scale: f64,
    z_floor: f64,
) -> f64 {
    let (w, h) = depth.size();
    let mut max_step: f64 = 0.0;
    for r in 0..h {
        for c in 0..w {
            if !domain.at(c, r) {
                continue;
            }
            let dz = f64::from(system.dz_padded[system.padded_index(c, r)]);
            let z = depth.at_mut(c, r);
            let limit = crop.limit(*z);
            let dz = if dz.is_finite() {
                scale * dz.clamp(-limit, limit)
            } else {
                0.0
            };
            let new = (*z + dz).max(z_floor);
            max_step = max_step.max((new - *z).abs());
            *z = new;
        }
    }
    max_step
}
