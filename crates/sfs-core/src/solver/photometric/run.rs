//! One level's run of linearisations ([`run_level`]): linearise, solve
//! the normal equations by conjugate gradients (`linear`), search the
//! distance along the rays, refit the intensities; shared by the solve
//! (`mod.rs`) and the start (`start`), below both. Uses `level`, `linear`
//! and the solver's problem (reports, cancellation).

use std::time::Instant;

use super::level::{Level, Scales, Shared};
use super::linear::{Operator, Stencil, conjugate_gradients};
use super::set::LinearSolves;
use crate::cancel::Cancel;
use crate::grid::Grid;
use crate::light::PointLight;
use crate::model::Energy;
use crate::solver::problem::{IterationReport, SolveError, SolveObserver, check_cancelled};

/// Most conjugate-gradient iterations per linearisation: coarse levels,
/// fine levels. Safety caps: with the multigrid preconditioner the face's
/// seven photographs meet their tolerances in 400 iterations over 35
/// solves (`PhotometricSolution::linear` counts any solve that does not).
const CG_ITERATIONS: usize = 300;
const CG_ITERATIONS_FINE: usize = 60;
/// Their relative tolerance on the fine levels (which refine) and on the
/// coarse ones (which find the shape and the distance; the distance is a
/// slow mode of the system, resolved only by a tight solve).
const CG_TOLERANCE_FINE: f64 = 1e-3;
const CG_TOLERANCE_COARSE: f64 = 1e-6;
/// A level stops once a linearisation lowers the energy by less than this
/// share (fine levels, coarse levels).
const STOP_FINE: f64 = 1e-3;
const STOP_COARSE: f64 = 1e-4;
/// Levels larger than this (longest side, pixels) refine what the coarser
/// ones found, in at most [`FINE_ITERATIONS`] linearisations.
pub(super) const FINE_SIDE: usize = 300;

/// How a level runs: its most linearisations, and whether the distance
/// along the rays is searched after each step (the coarsest level, where
/// the start may be far off; elsewhere the linearisation moves it).
#[derive(Clone, Copy)]
pub(super) struct LevelRun {
    /// Linearisations at most.
    pub max_iterations: usize,
    /// Whether the distance along the rays is searched after each step.
    pub search_distance: bool,
    /// Reported after each linearisation as this level of that many, the
    /// solve having started then (`None`: a trial, not reported).
    pub report: Option<(usize, usize, Instant)>,
}

/// What a level's run of linearisations ended with.
pub(super) struct LevelOutcome {
    /// The energy of the final surface.
    pub energy: Energy,
    /// The energy after each step.
    pub energies: Vec<f64>,
    /// Steps run.
    pub steps: usize,
    /// The steps' linear solves.
    pub linear: LinearSolves,
}

/// Runs the linearisations of one level from `zeta` (and `m`, the albedo
/// factor), with the intensities refitted when asked.
#[allow(clippy::too_many_arguments)]
pub(super) fn run_level(
    level: &Level,
    lights: &[PointLight],
    intensities: &mut Vec<f64>,
    estimate_intensities: bool,
    cast: &[Vec<bool>],
    scales: Scales,
    zeta: &mut Vec<f64>,
    m: &mut Vec<f64>,
    how: LevelRun,
    observer: &mut dyn SolveObserver,
) -> Result<LevelOutcome, SolveError> {
    let pixels = level.domain.iter().filter(|&&d| d).count().max(1);
    let fine = level.width.max(level.height) > FINE_SIDE;
    // The distance search looks at about 20 000 pixels.
    let stride = (pixels / 20_000).max(1);
    let mut energies = Vec::new();
    let mut run = 0;
    let mut before: Option<Energy> = None;
    let mut linear = LinearSolves::default();
    loop {
        check_cancelled(observer)?;
        let shared = Shared::new(lights, intensities, cast, scales);
        // The energy of the surface as it stands comes with its
        // linearisation.
        let (forms, m_now, data) = level.linearise(&shared, zeta, m);
        *m = m_now;
        let smoothness = level.smoothness_weights(&shared, zeta);
        let now = Energy {
            data,
            smoothness: smoothness.energy,
            total: data + scales.alpha * smoothness.energy,
        };
        if let Some(previous) = before {
            energies.push(now.total);
            let relative = (previous.total - now.total) / now.total.abs().max(1e-300);
            if relative < if fine { STOP_FINE } else { STOP_COARSE } {
                before = Some(now);
                break;
            }
        }
        before = Some(now);
        if run >= how.max_iterations {
            break;
        }
        let stencil = Stencil::assemble(&forms, &level.domain, level.width);
        let mean_diagonal = forms
            .iter()
            .zip(&level.domain)
            .filter(|(_, d)| **d)
            .map(|(f, _)| f.t[0] + f.t[3])
            .sum::<f64>()
            / pixels as f64;
        let tau = 1e-6 * mean_diagonal.max(1e-300);
        let rhs: Vec<f64> = stencil
            .rhs
            .iter()
            .zip(zeta.iter())
            .map(|(b, z)| b + tau * z)
            .collect();
        let operator = Operator {
            stencil: &stencil,
            smoothness: &smoothness.weights,
            tau,
            domain: &level.domain,
            width: level.width,
        };
        let mut next = zeta.clone();
        let cancelled = || observer.is_cancelled();
        let (tolerance, cap) = if fine {
            (CG_TOLERANCE_FINE, CG_ITERATIONS_FINE)
        } else {
            (CG_TOLERANCE_COARSE, CG_ITERATIONS)
        };
        let ran = conjugate_gradients(
            &operator,
            &rhs,
            &mut next,
            tolerance,
            cap,
            Cancel::new(&cancelled),
        )?;
        linear.add(ran, cap);
        if how.search_distance {
            // The distance along the rays: a golden-section search on the
            // constant of zeta.
            let shift = golden_section(
                |c| level.shifted_data(&shared, &next, c, stride),
                -0.3,
                0.3,
                24,
            );
            for (z, d) in next.iter_mut().zip(&level.domain) {
                if *d {
                    *z += shift;
                }
            }
        }
        if let Some((index, levels, started)) = how.report {
            let max_step = next
                .iter()
                .zip(zeta.iter())
                .zip(&level.domain)
                .filter(|(_, d)| **d)
                .map(|((a, b), _)| (a - b).abs())
                .fold(0.0, f64::max);
            observer.on_iteration(&IterationReport {
                level: index,
                levels,
                width: level.width,
                height: level.height,
                iteration: run,
                energy: now,
                max_step,
                elapsed: started.elapsed(),
            });
        }
        *zeta = next;
        if estimate_intensities {
            *intensities = level.refit_intensities(&shared, zeta, m);
        }
        run += 1;
    }
    let last = before.unwrap_or(Energy {
        data: 0.0,
        smoothness: 0.0,
        total: 0.0,
    });
    Ok(LevelOutcome {
        energy: last,
        energies,
        steps: run,
        linear,
    })
}

/// The minimiser of `f` on `[lo, hi]` by golden-section search
/// (`evaluations` evaluations); the end points are candidates too.
fn golden_section(f: impl Fn(f64) -> f64, lo: f64, hi: f64, evaluations: usize) -> f64 {
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (lo, hi);
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..evaluations {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = f(d);
        }
    }
    let middle = 0.5 * (a + b);
    let f0 = f(0.0);
    if f(middle) <= f0 { middle } else { 0.0 }
}

/// `exp(zeta)` on the domain, NaN elsewhere.
pub(super) fn depth_grid(level: &Level, zeta: &[f64]) -> Grid<f64> {
    Grid::from_fn(level.width, level.height, |c, r| {
        let p = r * level.width + c;
        if level.domain[p] {
            zeta[p].exp()
        } else {
            f64::NAN
        }
    })
}
