//! The one preconditioned conjugate-gradient routine of the crate
//! ([`solve`]), used by the albedo integration (`crate::albedo`, a
//! multigrid V-cycle as preconditioner), the thin-plate hole fill
//! (`solver::holes`, Jacobi-preconditioned) and the photometric linear
//! systems (`solver::photometric::linear`, a multigrid V-cycle of their
//! rows, in the flexible form of [`Beta::PolakRibiere`]).
//!
//! Each caller keeps its own rules, which are parameters here
//! ([`Settings`]): how dot products are summed ([`Summation`]), which
//! residual norm stops the iteration, against what and when ([`Stop`]), how
//! often cancellation is polled and where ([`CancelPoll`]), and what a
//! non-positive `r . z` does ([`RzGuard`]), how the next direction is
//! formed ([`Beta`]). The floating-point operations
//! and their order are the same as each caller's own loop had, so results
//! are the same to the bit. Uses `cancel` only.

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};

/// Element-wise vector updates run on one thread below this many entries
/// (element-wise results do not depend on the split).
const PARALLEL_MIN_LEN: usize = 8192;

/// How dot products are summed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Summation {
    /// One pass in order, on one thread.
    Serial,
    /// Partial sums over fixed chunks of this many entries (in parallel),
    /// added in order: the same bits on every run and any number of
    /// threads.
    Chunked(usize),
}

impl Summation {
    /// `a . b` summed this way.
    pub(crate) fn dot(self, a: &[f64], b: &[f64]) -> f64 {
        match self {
            Summation::Serial => a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>(),
            Summation::Chunked(chunk) => {
                let partial: Vec<f64> = a
                    .par_chunks(chunk)
                    .zip(b.par_chunks(chunk))
                    .map(|(x, y)| x.iter().zip(y).map(|(x, y)| x * y).sum::<f64>())
                    .collect();
                partial.iter().sum::<f64>()
            }
        }
    }
}

/// The residual norm a stopping test measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Norm {
    /// `sqrt(r . r)`, summed as the dot products are.
    Euclidean,
    /// `max |r_i|`.
    Max,
}

impl Norm {
    fn of(self, r: &[f64], summation: Summation) -> f64 {
        match self {
            Norm::Euclidean => summation.dot(r, r).sqrt(),
            Norm::Max => r.iter().fold(0.0f64, |m, r| m.max(r.abs())),
        }
    }
}

/// When the iteration stops for a small residual.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Stop {
    /// Before each step (the first included): stop with the steps taken so
    /// far once the residual's `norm` is at most `tolerance`.
    BeforeStep {
        /// The norm measured.
        norm: Norm,
        /// The absolute bound.
        tolerance: f64,
    },
    /// After each step's update of `x` and the residual: stop, counting
    /// that step, once the residual's `norm` is at most `tolerance` times
    /// the initial residual's. An initial residual that is not finite and
    /// positive stops before any step.
    AfterStepRelative {
        /// The norm measured.
        norm: Norm,
        /// The bound relative to the initial residual.
        tolerance: f64,
    },
}

/// How often cancellation is polled, and where in the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct CancelPoll {
    /// Polled at steps `0, every, 2 every, ...` (at least 1).
    pub every: usize,
    /// Polled before the [`Stop::BeforeStep`] test (else after it).
    pub before_test: bool,
}

/// What a non-positive `r . z` (the preconditioned residual's product)
/// does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RzGuard {
    /// Nothing: the step goes on.
    None,
    /// After each step's preconditioning: an `r . z` that is not positive
    /// or not finite stops, counting that step.
    AfterPreconditioning,
    /// Before each step, after the cancellation poll and with the
    /// [`Stop::BeforeStep`] test: an `r . z` at most 0 stops (a NaN goes
    /// on).
    BeforeStep,
}

/// How the next direction is formed from the new preconditioned residual.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Beta {
    /// `beta = r' . z' / r . z` (Fletcher-Reeves): the classical
    /// conjugate gradients, for a fixed symmetric preconditioner.
    FletcherReeves,
    /// `beta = (r' - r) . z' / r . z` (Polak-Ribiere): flexible conjugate
    /// gradients, robust to a preconditioner that is not exactly symmetric
    /// (a multigrid cycle with Gauss-Seidel smoothing).
    PolakRibiere,
}

/// The rules of one caller's iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Settings {
    /// Steps at most.
    pub max_iterations: usize,
    /// How dot products are summed.
    pub summation: Summation,
    /// When a small residual stops.
    pub stop: Stop,
    /// How cancellation is polled.
    pub cancel_poll: CancelPoll,
    /// What a non-positive `r . z` does.
    pub rz_guard: RzGuard,
    /// How the next direction is formed.
    pub beta: Beta,
}

/// Solves `A x = b` by preconditioned conjugate gradients from `x`, given
/// the initial residual `r = b - A x`: `apply(v, out)` sets `out = A v`
/// (overwriting every entry), `precondition(r, z)` sets `z = M^-1 r`
/// (every entry; `M` symmetric positive). A direction of non-positive or
/// non-finite curvature stops (without that step). Returns the steps
/// taken.
///
/// # Errors
/// [`Cancelled`] when `cancel` is, at a poll of `settings.cancel_poll`.
pub(crate) fn solve(
    x: &mut [f64],
    mut r: Vec<f64>,
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    settings: &Settings,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    let n = x.len();
    let dot = |a: &[f64], b: &[f64]| settings.summation.dot(a, b);
    let mut z = vec![0.0; n];
    precondition(&r, &mut z);
    let mut d = z.clone();
    let mut rz = dot(&r, &z);
    let (before, after) = match settings.stop {
        Stop::BeforeStep { norm, tolerance } => (Some((norm, tolerance)), None),
        Stop::AfterStepRelative { norm, tolerance } => {
            let r0 = norm.of(&r, settings.summation);
            if !r0.is_finite() || r0 <= 0.0 {
                return Ok(0);
            }
            (None, Some((norm, tolerance * r0)))
        }
    };
    let poll = settings.cancel_poll;
    let every = poll.every.max(1);
    let mut ad = vec![0.0; n];
    let mut previous_r = match settings.beta {
        Beta::FletcherReeves => Vec::new(),
        Beta::PolakRibiere => vec![0.0; n],
    };
    for iteration in 0..settings.max_iterations {
        let due = iteration % every == 0;
        if due && poll.before_test {
            cancel.check()?;
        }
        if let Some((norm, bound)) = before
            && norm.of(&r, settings.summation) <= bound
        {
            return Ok(iteration);
        }
        if settings.rz_guard == RzGuard::BeforeStep && rz <= 0.0 {
            return Ok(iteration);
        }
        if due && !poll.before_test {
            cancel.check()?;
        }
        apply(&d, &mut ad);
        let curvature = dot(&d, &ad);
        if curvature <= 0.0 || !curvature.is_finite() {
            return Ok(iteration);
        }
        let step = rz / curvature;
        if settings.beta == Beta::PolakRibiere {
            previous_r.copy_from_slice(&r);
        }
        x.par_iter_mut()
            .with_min_len(PARALLEL_MIN_LEN)
            .zip(r.par_iter_mut())
            .zip(d.par_iter().zip(ad.par_iter()))
            .for_each(|((x, r), (d, ad))| {
                *x += step * d;
                *r -= step * ad;
            });
        if let Some((norm, bound)) = after
            && norm.of(&r, settings.summation) <= bound
        {
            return Ok(iteration + 1);
        }
        precondition(&r, &mut z);
        let rz_next = dot(&r, &z);
        if settings.rz_guard == RzGuard::AfterPreconditioning
            && (rz_next <= 0.0 || !rz_next.is_finite())
        {
            return Ok(iteration + 1);
        }
        let beta = match settings.beta {
            Beta::FletcherReeves => rz_next / rz,
            Beta::PolakRibiere => (rz_next - dot(&previous_r, &z)) / rz,
        };
        rz = rz_next;
        d.par_iter_mut()
            .with_min_len(PARALLEL_MIN_LEN)
            .zip(z.par_iter())
            .for_each(|(d, z)| *d = z + beta * *d);
    }
    Ok(settings.max_iterations)
}
