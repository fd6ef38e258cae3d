//! Baseline: the explicit variational scheme of Ju et al. (the scheme the
//! paper's method replaces), on exactly the same discrete energy.
//!
//! Same model, same upwind data term, same second-order Charbonnier
//! smoothness, same pyramid and initial depth as [`super::driver`] (both use
//! [`super::prepare::prepare`]). On every level the depth evolves by gradient
//! descent on the level's energy `E = sum c D^2 + alpha sum Psi(S^2)`,
//! alternating (Lie splitting, as in Ju et al.'s alternating scheme) a data
//! half-step `z <- z - tau grad E_data` and a smoothness half-step
//! `z <- z - tau grad E_smooth` with one time step `tau` for both, so that a
//! fixed point is a stationary point of the whole energy up to `O(tau)`.
//!
//! ## The time step
//!
//! A gradient step with `tau <= 1/L` on a function whose gradient is
//! `L`-Lipschitz never increases it. Each half-step uses
//! `tau = 1 / max(L_data, L_smooth)` with bounds taken from the energy:
//!
//! - data: the Gauss-Newton part of its Hessian is `2 J^T C J`, and
//!   `||J^T C J|| <= ||C^(1/2) J||_inf ||C^(1/2) J||_1` (largest row sum times
//!   largest column sum of `|J|`), recomputed at every energy check;
//! - smoothness: with `Psi' <= 1` and `Psi'' < 0` the Hessian of
//!   `alpha sum Psi(S^2)` is bounded by `alpha (2 ||K_xx||^2 + 4 ||K_xy||^2 +
//!   2 ||K_yy||^2) <= alpha (32/hx^4 + 4/(hx hy)^2 + 32/hy^4)`.
//!
//! The upwind switching and the neglected second-order data term can still
//! make a step overshoot: the energy is checked every
//! [`ExplicitParams::check_interval`] steps, and a check that finds it higher
//! than at the previous check restores that depth and halves `tau` for the
//! rest of the level.
//!
//! ## Stopping
//!
//! A level ends when the energy's relative decrease between two checks falls
//! below [`ExplicitParams::tolerance`] ([`ExplicitParams::finest_tolerance`]
//! on the finest level), or after
//! [`ExplicitParams::level_iterations`] steps on a coarse level. The whole
//! solve stops when its time or iteration budget is spent: the current depth
//! is then carried to full resolution and returned with
//! [`Solution::budget_exhausted`] set.
//!
//! It streams progress like the main solver: an [`IterationReport`] at every
//! check, a [`LevelResult`] at the end of every level and, with
//! [`ExplicitParams::snapshot_seconds`], repeatedly on the finest level (the
//! same level index again), so that error over time can be recorded.

use std::time::Instant;

use rayon::prelude::*;

use crate::cancel::{Cancel, Uncancelled};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::{self, Reflectance, Spacing, charbonnier_derivative, slot};
use crate::params::SolverParams;

use super::coarse_to_fine::{LevelEnd, LevelScheme, LevelStep, coarse_to_fine};
use super::prepare::{Prepared, level_energy, level_result, prepare};
use super::problem::{
    IterationReport, PhaseTimes, Problem, Solution, SolveError, SolveObserver, check_cancelled,
};
use super::pyramid::PyramidLevel;

/// Budget and control of the explicit scheme (the model's parameters come
/// from [`SolverParams`]: alpha, lambda, eta, domain, initial depth).
#[derive(Clone, Debug, PartialEq)]
pub struct ExplicitParams {
    /// Wall-time budget of the whole solve in seconds (`None`: unlimited).
    pub max_seconds: Option<f64>,
    /// Budget of gradient steps over all levels (`None`: unlimited).
    pub max_iterations: Option<usize>,
    /// Most steps on each coarse level; default 5000.
    pub level_iterations: usize,
    /// A coarse level ends when the energy falls by less than this fraction
    /// between two checks; default 1e-6.
    pub tolerance: f64,
    /// The same for the finest level (0: run until the budget is spent);
    /// default 1e-6.
    pub finest_tolerance: f64,
    /// Steps between energy checks and progress reports; default 100.
    pub check_interval: usize,
    /// Seconds between snapshots of the finest level (`None`: only its end).
    pub snapshot_seconds: Option<f64>,
}

impl Default for ExplicitParams {
    fn default() -> Self {
        Self {
            max_seconds: None,
            max_iterations: None,
            level_iterations: 5000,
            tolerance: 1e-6,
            finest_tolerance: 1e-6,
            check_interval: 100,
            snapshot_seconds: None,
        }
    }
}

impl ExplicitParams {
    fn validate(&self) -> Result<(), SolveError> {
        let bad = |m: &str| Err(SolveError::Input(m.into()));
        if let Some(s) = self.max_seconds
            && !(s.is_finite() && s > 0.0)
        {
            return bad("explicit time budget must be finite and > 0 seconds");
        }
        if self.max_iterations == Some(0) {
            return bad("explicit iteration budget must be > 0");
        }
        if self.level_iterations == 0 || self.check_interval == 0 {
            return bad("explicit level iterations and check interval must be > 0");
        }
        if !(self.tolerance.is_finite()
            && self.tolerance >= 0.0
            && self.finest_tolerance.is_finite()
            && self.finest_tolerance >= 0.0)
        {
            return bad("explicit tolerance must be finite and >= 0");
        }
        if let Some(s) = self.snapshot_seconds
            && !(s.is_finite() && s > 0.0)
        {
            return bad("explicit snapshot interval must be finite and > 0 seconds");
        }
        Ok(())
    }
}

/// Per-pixel quantities of one gradient evaluation, kept between calls.
struct Workspace {
    /// `2 c_p D_p`.
    weighted_residual: Vec<f64>,
    /// `J_p` for the 5 stencil slots, `[slot][pixel]` (0 where `c_p = 0`).
    jacobian: [Vec<f64>; 5],
    /// `Psi'_p z_xx`, `Psi'_p z_xy`, `Psi'_p z_yy` (0 where not defined).
    smooth: [Vec<f64>; 3],
    /// The gradient of the current half-step.
    gradient: Vec<f64>,
}

impl Workspace {
    fn new(n: usize) -> Self {
        Self {
            weighted_residual: vec![0.0; n],
            jacobian: std::array::from_fn(|_| vec![0.0; n]),
            smooth: std::array::from_fn(|_| vec![0.0; n]),
            gradient: vec![0.0; n],
        }
    }
}

/// Fills `2 c D` and `J` for every pixel (branches at `depth`).
fn linearise_data<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    ws: &mut Workspace,
) {
    let geometry = &level.geometry;
    let w = geometry.width;
    let [j0, j1, j2, j3, j4] = &mut ws.jacobian;
    ws.weighted_residual
        .par_chunks_mut(w)
        .zip(j0.par_chunks_mut(w))
        .zip(j1.par_chunks_mut(w))
        .zip(j2.par_chunks_mut(w))
        .zip(j3.par_chunks_mut(w))
        .zip(j4.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (((((wr, a0), a1), a2), a3), a4))| {
            for c in 0..w {
                let conf = level.confidence.at(c, r);
                let mut jac = [0.0; 5];
                let mut d = 0.0;
                if *level.domain.at(c, r) && conf > 0.0 {
                    let nb = model::neighbourhood(depth, &level.domain, c, r);
                    let (branches, _, _) = nb.upwind(geometry.spacing);
                    if let Some((res, j)) = model::residual_and_jacobian(
                        model,
                        &geometry.ray(c, r),
                        *level.image.at(c, r),
                        &nb.values(),
                        branches,
                        geometry.spacing,
                        model::Derivatives::Exact,
                    ) && res.is_finite()
                        && j.iter().all(|v| v.is_finite())
                    {
                        d = 2.0 * conf * res;
                        jac = j;
                    }
                }
                wr[c] = d;
                a0[c] = jac[slot::CENTRE];
                a1[c] = jac[slot::LEFT];
                a2[c] = jac[slot::RIGHT];
                a3[c] = jac[slot::UP];
                a4[c] = jac[slot::DOWN];
            }
        });
}

/// `grad E_data` by gathering each pixel's share from the residuals of the
/// pixels whose stencil contains it.
fn data_gradient(w: usize, h: usize, ws: &mut Workspace) {
    let (wr, jac) = (&ws.weighted_residual, &ws.jacobian);
    let share = |p: usize, s: usize| wr[p] * jac[s][p];
    ws.gradient
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(r, g)| {
            for (c, gq) in g.iter_mut().enumerate() {
                let q = r * w + c;
                let mut sum = share(q, slot::CENTRE);
                if c + 1 < w {
                    sum += share(q + 1, slot::LEFT);
                }
                if c > 0 {
                    sum += share(q - 1, slot::RIGHT);
                }
                if r + 1 < h {
                    sum += share(q + w, slot::UP);
                }
                if r > 0 {
                    sum += share(q - w, slot::DOWN);
                }
                *gq = sum;
            }
        });
}

/// `max(row sums) * max(column sums)` of `|sqrt(c) J|`: a bound on
/// `||J^T C J||`.
fn data_lipschitz(w: usize, h: usize, confidence: &Confidence, ws: &Workspace) -> f64 {
    let jac = &ws.jacobian;
    let a = |s: usize, p: usize| confidence.weight(p).sqrt() * jac[s][p].abs();
    let rows = (0..w * h)
        .into_par_iter()
        .map(|p| (0..5).map(|s| a(s, p)).sum::<f64>())
        .reduce(|| 0.0, f64::max);
    let columns = (0..w * h)
        .into_par_iter()
        .map(|q| {
            let (c, r) = (q % w, q / w);
            let mut sum = a(slot::CENTRE, q);
            if c + 1 < w {
                sum += a(slot::LEFT, q + 1);
            }
            if c > 0 {
                sum += a(slot::RIGHT, q - 1);
            }
            if r + 1 < h {
                sum += a(slot::UP, q + w);
            }
            if r > 0 {
                sum += a(slot::DOWN, q - w);
            }
            sum
        })
        .reduce(|| 0.0, f64::max);
    2.0 * rows * columns
}

/// The smoothness Hessian bound `alpha (32/hx^4 + 4/(hx hy)^2 + 32/hy^4)`.
fn smoothness_lipschitz(alpha: f64, h: Spacing) -> f64 {
    let (hx2, hy2) = (h.x * h.x, h.y * h.y);
    alpha * (32.0 / (hx2 * hx2) + 4.0 / (hx2 * hy2) + 32.0 / (hy2 * hy2))
}

/// `grad (alpha sum Psi(S^2))`: per pixel `Psi' z_xx`, `Psi' z_xy`, `Psi' z_yy`
/// (only the components whose stencil lies in the domain,
/// [`model::second_derivatives`]), then the transposed stencils gathered.
fn smoothness_gradient(
    level: &PyramidLevel,
    depth: &Grid<f64>,
    alpha: f64,
    lambda: f64,
    ws: &mut Workspace,
) {
    let (w, h) = depth.size();
    let sp = level.geometry.spacing;
    let domain = &level.domain;
    let [sxx, sxy, syy] = &mut ws.smooth;
    sxx.par_chunks_mut(w)
        .zip(sxy.par_chunks_mut(w))
        .zip(syy.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, ((axx, axy), ayy))| {
            for c in 0..w {
                let (xx, xy, yy) = if *domain.at(c, r) {
                    model::second_derivatives(depth, domain, c, r, sp)
                } else {
                    (None, None, None)
                };
                let s2 = xx.map_or(0.0, |v| v * v)
                    + 2.0 * xy.map_or(0.0, |v| v * v)
                    + yy.map_or(0.0, |v| v * v);
                let psi = charbonnier_derivative(s2, lambda);
                axx[c] = xx.map_or(0.0, |v| psi * v);
                axy[c] = xy.map_or(0.0, |v| psi * v);
                ayy[c] = yy.map_or(0.0, |v| psi * v);
            }
        });
    let (axx, axy, ayy) = (&ws.smooth[0], &ws.smooth[1], &ws.smooth[2]);
    let at = |a: &Vec<f64>, c: isize, r: isize| {
        if c < 0 || r < 0 || c >= w as isize || r >= h as isize {
            0.0
        } else {
            a[r as usize * w + c as usize]
        }
    };
    let (hx2, hy2, hxy4) = (sp.x * sp.x, sp.y * sp.y, 4.0 * sp.x * sp.y);
    ws.gradient
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(r, g)| {
            let r = r as isize;
            for (c, gq) in g.iter_mut().enumerate() {
                let c = c as isize;
                let xx = (at(axx, c - 1, r) - 2.0 * at(axx, c, r) + at(axx, c + 1, r)) / hx2;
                let yy = (at(ayy, c, r - 1) - 2.0 * at(ayy, c, r) + at(ayy, c, r + 1)) / hy2;
                let xy = (at(axy, c - 1, r - 1) - at(axy, c - 1, r + 1) - at(axy, c + 1, r - 1)
                    + at(axy, c + 1, r + 1))
                    / hxy4;
                *gq = alpha * (2.0 * xx + 4.0 * xy + 2.0 * yy);
            }
        });
}

/// The gradient of a level's energy at `depth` (data plus smoothness), for
/// tests and diagnostics.
pub fn energy_gradient<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    alpha: f64,
    lambda: f64,
) -> Grid<f64> {
    let (w, h) = depth.size();
    let mut ws = Workspace::new(w * h);
    linearise_data(model, level, depth, &mut ws);
    data_gradient(w, h, &mut ws);
    let data = ws.gradient.clone();
    smoothness_gradient(level, depth, alpha, lambda, &mut ws);
    let total: Vec<f64> = data.iter().zip(&ws.gradient).map(|(a, b)| a + b).collect();
    Grid::from_vec(w, h, total).unwrap_or_else(|| Grid::filled(w, h, 0.0))
}

/// `z <- max(z - tau g, z_floor)` on the domain.
fn descend(depth: &mut Grid<f64>, domain: &Grid<bool>, gradient: &[f64], tau: f64, z_floor: f64) {
    depth
        .as_mut_slice()
        .par_iter_mut()
        .zip(domain.as_slice().par_iter())
        .zip(gradient.par_iter())
        .for_each(|((z, &inside), &g)| {
            if inside && g.is_finite() {
                *z = (*z - tau * g).max(z_floor);
            }
        });
}

/// Solves with the explicit scheme and the problem's model (lights
/// anywhere).
pub fn solve_explicit(
    problem: &Problem,
    params: &SolverParams,
    explicit: &ExplicitParams,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let model = problem.model(params.material());
    rayon::scope(|_| run(problem, params, explicit, &model, observer))
}

fn run<M: Reflectance>(
    problem: &Problem,
    params: &SolverParams,
    explicit: &ExplicitParams,
    model: &M,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let start = Instant::now();
    explicit.validate()?;
    let mut prepared = prepare(problem, params, None, None, observer)?;
    let initial = prepared.take_depth();
    let mut scheme = Descent {
        model,
        explicit,
        prepared: &prepared,
        // Relative to the depth's own scale: any unit of depth works.
        z_floor: 1e-6 * prepared.initial_depth.abs().max(f64::MIN_POSITIVE),
        total_steps: 0,
    };
    let walk = coarse_to_fine(
        model,
        &prepared,
        initial,
        false,
        0,
        start,
        observer,
        &mut scheme,
    )?;
    let iterations = scheme.total_steps;
    walk.into_solution(
        problem,
        params,
        &mut prepared,
        start,
        iterations,
        PhaseTimes::default(),
    )
}

/// One level of the explicit scheme: alternating data and smoothness
/// gradient half-steps with the Lipschitz time step, the energy checked every
/// `check_interval` steps (a rise restores the last check and halves the
/// step), until the level's tolerance, its iteration count or the budget.
struct Descent<'a, M> {
    model: &'a M,
    explicit: &'a ExplicitParams,
    prepared: &'a Prepared<'a>,
    z_floor: f64,
    /// Gradient steps over all levels so far.
    total_steps: usize,
}

impl<M: Reflectance> LevelScheme for Descent<'_, M> {
    fn solve_level(
        &mut self,
        step: &LevelStep<'_>,
        depth: &mut Grid<f64>,
        observer: &mut dyn SolveObserver,
    ) -> Result<LevelEnd, SolveError> {
        let (model, explicit, level) = (self.model, self.explicit, step.level);
        let (alpha, lambda) = (self.prepared.alpha, self.prepared.lambda);
        let out_of_budget = |steps: usize| {
            explicit.max_iterations.is_some_and(|m| steps >= m)
                || explicit
                    .max_seconds
                    .is_some_and(|s| step.start.elapsed().as_secs_f64() >= s)
        };
        let (w, h) = depth.size();
        let mut ws = Workspace::new(w * h);
        let mut energy =
            level_energy(model, level, depth, alpha, lambda, Cancel::NEVER).uncancelled();
        let mut checkpoint = depth.clone();
        let mut energies = vec![energy.total];
        let smooth_bound = smoothness_lipschitz(alpha, level.geometry.spacing);
        let mut shrink = 1.0;
        let mut tau = 0.0;
        let mut steps = 0usize;
        let mut last_snapshot = Instant::now();
        let mut exhausted = false;
        loop {
            if observer.is_cancelled() {
                return Err(SolveError::Cancelled);
            }
            if out_of_budget(self.total_steps) {
                exhausted = true;
                break;
            }
            if !step.finest && steps >= explicit.level_iterations {
                break;
            }
            // Data half-step (its linearisation also refreshes the bound).
            linearise_data(model, level, depth, &mut ws);
            if steps.is_multiple_of(explicit.check_interval) {
                let bound = data_lipschitz(w, h, &level.confidence, &ws).max(smooth_bound);
                tau = if bound > 0.0 && bound.is_finite() {
                    shrink / bound
                } else {
                    0.0
                };
            }
            data_gradient(w, h, &mut ws);
            descend(depth, &level.domain, &ws.gradient, tau, self.z_floor);
            // Smoothness half-step at the updated depth.
            smoothness_gradient(level, depth, alpha, lambda, &mut ws);
            descend(depth, &level.domain, &ws.gradient, tau, self.z_floor);
            steps += 1;
            self.total_steps += 1;
            if !steps.is_multiple_of(explicit.check_interval) {
                continue;
            }
            let trial =
                level_energy(model, level, depth, alpha, lambda, Cancel::NEVER).uncancelled();
            let improved = trial.total <= energy.total; // false for NaN too
            if !improved {
                // Overshoot (or a non-finite energy): back to the last check.
                depth.as_mut_slice().copy_from_slice(checkpoint.as_slice());
                shrink *= 0.5;
                if shrink < 1e-6 {
                    break;
                }
                continue;
            }
            let decrease = (energy.total - trial.total) / energy.total.abs().max(f64::MIN_POSITIVE);
            energy = trial;
            checkpoint.as_mut_slice().copy_from_slice(depth.as_slice());
            energies.push(energy.total);
            observer.on_iteration(&IterationReport {
                level: step.index,
                levels: step.levels,
                width: w,
                height: h,
                iteration: steps,
                energy,
                max_step: tau,
                elapsed: step.start.elapsed(),
            });
            if step.finest
                && let Some(every) = explicit.snapshot_seconds
                && last_snapshot.elapsed().as_secs_f64() >= every
            {
                let result = level_result(
                    model,
                    level,
                    depth,
                    step.index,
                    step.levels,
                    energy,
                    step.start,
                    Cancel::new(&|| observer.is_cancelled()),
                )?;
                check_cancelled(observer)?;
                observer.on_level(&result);
                last_snapshot = Instant::now();
            }
            let tolerance = if step.finest {
                explicit.finest_tolerance
            } else {
                explicit.tolerance
            };
            if decrease < tolerance {
                break;
            }
        }
        Ok(LevelEnd {
            energies,
            energy,
            out_of_budget: exhausted,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Lambertian;
    use crate::model::LevelGeometry;
    use crate::scene::sombrero::sombrero;

    struct Energies(Vec<(usize, f64)>);

    impl SolveObserver for Energies {
        fn on_iteration(&mut self, report: &IterationReport) {
            self.0.push((report.level, report.energy.total));
        }
    }

    #[test]
    fn gradient_matches_finite_differences_of_the_energy() {
        let scene = sombrero(24, 24);
        let level = PyramidLevel {
            geometry: LevelGeometry::new(24, 24, 24, 24, scene.camera),
            image: std::borrow::Cow::Borrowed(&scene.image),
            confidence: Confidence::from_grid(
                Grid::from_fn(24, 24, |c, _| if c < 5 { 0.0 } else { 1.0 }),
                Cancel::NEVER,
            )
            .uncancelled(),
            domain: Grid::filled(24, 24, true),
        };
        // A depth with distinct neighbours (no upwind ties to flip).
        let depth = Grid::from_fn(24, 24, |c, r| {
            1.8 + 0.013 * c as f64 + 0.007 * r as f64 + 0.02 * ((c * 7 + r * 3) as f64).sin()
        });
        let model = Lambertian {
            intensity_scale: scene.intensity_scale,
        };
        let (alpha, lambda) = (50.0, 1e-3);
        let gradient = energy_gradient(&model, &level, &depth, alpha, lambda);
        let energy = |z: &Grid<f64>| {
            level_energy(&model, &level, z, alpha, lambda, Cancel::NEVER)
                .uncancelled()
                .total
        };
        for (c, r) in [(0, 0), (3, 7), (12, 12), (23, 5), (6, 23)] {
            let step = 1e-6;
            let mut plus = depth.clone();
            *plus.at_mut(c, r) += step;
            let mut minus = depth.clone();
            *minus.at_mut(c, r) -= step;
            let numeric = (energy(&plus) - energy(&minus)) / (2.0 * step);
            let exact = *gradient.at(c, r);
            assert!(
                (numeric - exact).abs() <= 1e-5 * numeric.abs().max(1.0),
                "pixel ({c}, {r}): numeric {numeric} exact {exact}"
            );
        }
    }

    #[test]
    fn energy_decreases_and_the_budget_stops_it() {
        let scene = sombrero(48, 48);
        let problem = Problem {
            image: scene.image.clone(),
            camera: scene.camera,
            intensity_scale: scene.intensity_scale,
            object_mask: None,
            confidence: None,
            lights: Vec::new(),
        };
        let params = SolverParams::paper(50.0);
        let explicit = ExplicitParams {
            max_iterations: Some(3000),
            level_iterations: 300,
            check_interval: 20,
            ..ExplicitParams::default()
        };
        let mut seen = Energies(Vec::new());
        let solution =
            solve_explicit(&problem, &params, &explicit, &mut seen).expect("explicit solve");
        assert!(seen.0.len() > 20, "progress is streamed");
        for pair in seen.0.windows(2) {
            if pair[0].0 == pair[1].0 {
                assert!(
                    pair[1].1 <= pair[0].1,
                    "energy rose within a level: {pair:?}"
                );
            }
        }
        assert!(solution.budget_exhausted && solution.iterations == 3000);
        assert!(
            solution
                .depth
                .as_slice()
                .iter()
                .all(|z| z.is_finite() && *z > 0.0)
        );
        let constant = Grid::filled(48, 48, solution.initial_depth);
        let before = crate::metrics::rse(&constant, &scene.depth_gt).expect("sizes");
        let after = crate::metrics::rse(&solution.depth, &scene.depth_gt).expect("sizes");
        assert!(after < 0.8 * before, "RSE {before} -> {after}");
    }
}
