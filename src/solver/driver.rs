//! The coarse-to-fine driver: validates a [`Problem`], builds the pyramid,
//! runs `kappa` outer Gauss-Newton iterations per level (each with `l_max`
//! inner fixed-point iterations on Psi' and SOR sweeps) and resamples depth to
//! the next level, reporting to a [`SolveObserver`].

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::model::{self, Energy, Lambertian, LevelGeometry, Reflectance};
use crate::params::{DomainMode, InitialDepth, ParamError, SolverParams, StepControl};

use super::pyramid::{self, PyramidLevel};
use super::sor;
use super::system::LinearSystem;

/// Smallest accepted image side.
pub const MIN_IMAGE_SIDE: usize = 3;

/// What the solver is asked to explain.
#[derive(Clone, Debug)]
pub struct Problem {
    /// Linear image values (>= 0, finite).
    pub image: Grid<f64>,
    /// Camera at full resolution.
    pub camera: Intrinsics,
    /// Intensity scale `s`.
    pub intensity_scale: f64,
    /// Pixels that see the object (`None`: every pixel).
    pub object_mask: Option<Grid<bool>>,
    /// Confidence in [0, 1] (`None`: 1 everywhere).
    pub confidence: Option<Grid<f64>>,
}

/// Why a solve did not produce a depth map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// A parameter is out of range.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The input cannot be solved; the message names the problem.
    #[error("invalid input: {0}")]
    Input(String),
    /// The observer asked to stop.
    #[error("cancelled")]
    Cancelled,
}

/// Reported after every outer iteration.
#[derive(Clone, Debug, Serialize)]
pub struct IterationReport {
    /// Level index, 0 = coarsest.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// Level width.
    pub width: usize,
    /// Level height.
    pub height: usize,
    /// Outer iteration within the level, from 0.
    pub iteration: usize,
    /// Energy after the update.
    pub energy: Energy,
    /// Largest `|dz|` applied (after cropping).
    pub max_step: f64,
    /// Time since the solve started.
    #[serde(serialize_with = "seconds")]
    pub elapsed: Duration,
}

/// Reported after every level: its depth and reprojection at its own size.
#[derive(Clone, Debug)]
pub struct LevelResult {
    /// Level index, 0 = coarsest.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// Depth at this level's size; NaN outside the domain.
    pub depth: Grid<f64>,
    /// Reprojected image at this level's size.
    pub reprojection: Grid<f64>,
    /// Energy at the end of the level.
    pub energy: Energy,
    /// Time since the solve started.
    pub elapsed: Duration,
}

/// Per-level summary kept in a [`Solution`].
#[derive(Clone, Debug, Serialize)]
pub struct LevelReport {
    /// Level width.
    pub width: usize,
    /// Level height.
    pub height: usize,
    /// Energies after each outer iteration.
    pub energies: Vec<f64>,
    /// Seconds spent on this level.
    pub seconds: f64,
}

/// Seconds spent in each phase of a solve.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct PhaseTimes {
    /// Linearising the data term and building its part of the system.
    pub linearise_seconds: f64,
    /// Evaluating Psi' and assembling the full system (every inner iteration).
    pub assemble_seconds: f64,
    /// SOR sweeps.
    pub sor_seconds: f64,
    /// Cropping, applying and (with backtracking) re-evaluating the update.
    pub update_seconds: f64,
}

/// The result of a solve.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Full-resolution depth; NaN outside the object.
    pub depth: Grid<f64>,
    /// Reprojected image; 0 outside the object.
    pub reprojection: Grid<f64>,
    /// Energy of the initial depth at the coarsest level and of the result.
    pub initial_energy: Energy,
    /// Final energy at full resolution.
    pub final_energy: Energy,
    /// Levels, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Where the time went.
    pub phases: PhaseTimes,
    /// Constant initial depth used (or the warm start's mean).
    pub initial_depth: f64,
    /// Wall time.
    pub seconds: f64,
    /// Outer iterations (linearised), gradient steps (explicit) or 1 (fast
    /// marching).
    pub iterations: usize,
    /// True when a time or iteration budget stopped the scheme early.
    pub budget_exhausted: bool,
}

fn seconds<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(d.as_secs_f64())
}

/// Receives progress from the solver; every method has a no-op default.
///
/// Observers are `Send`: the solve runs on a worker of rayon's pool.
pub trait SolveObserver: Send {
    /// After every outer iteration.
    fn on_iteration(&mut self, _report: &IterationReport) {}
    /// After every level.
    fn on_level(&mut self, _result: &LevelResult) {}
    /// Polled between SOR sweeps; returning true stops the solve with
    /// [`SolveError::Cancelled`].
    fn is_cancelled(&self) -> bool {
        false
    }
}

/// An observer that ignores everything.
impl SolveObserver for () {}

impl Problem {
    /// Checks sizes and values; returns the effective domain and confidence.
    pub(crate) fn validate(
        &self,
        params: &SolverParams,
    ) -> Result<(Grid<bool>, Grid<f64>), SolveError> {
        let (w, h) = self.image.size();
        let bad = |m: String| Err(SolveError::Input(m));
        if w < MIN_IMAGE_SIDE || h < MIN_IMAGE_SIDE {
            return bad(format!(
                "image is {w}x{h}; at least {MIN_IMAGE_SIDE}x{MIN_IMAGE_SIDE} pixels are needed"
            ));
        }
        let f = self.camera.focal_px;
        if !(f.is_finite() && f > 0.0) {
            return bad(format!("focal length must be finite and > 0 (got {f})"));
        }
        if !(self.camera.principal_x_px.is_finite() && self.camera.principal_y_px.is_finite()) {
            return bad("principal point must be finite".into());
        }
        let s = self.intensity_scale;
        if !(s.is_finite() && s > 0.0) {
            return bad(format!("intensity scale must be finite and > 0 (got {s})"));
        }
        if let Some(bad_value) = self
            .image
            .as_slice()
            .iter()
            .find(|v| !v.is_finite() || **v < 0.0)
        {
            return bad(format!(
                "image contains an invalid value {bad_value} (values must be finite and >= 0)"
            ));
        }
        let object = match &self.object_mask {
            Some(m) if m.size() != (w, h) => {
                return bad(format!(
                    "object mask is {}x{} but the image is {w}x{h}",
                    m.width(),
                    m.height()
                ));
            }
            Some(m) => m.clone(),
            None => Grid::filled(w, h, true),
        };
        let confidence = match &self.confidence {
            Some(c) if c.size() != (w, h) => {
                return bad(format!(
                    "confidence is {}x{} but the image is {w}x{h}",
                    c.width(),
                    c.height()
                ));
            }
            Some(c) => {
                if c.as_slice().iter().any(|v| !(0.0..=1.0).contains(v)) {
                    return bad("confidence values must lie in [0, 1]".into());
                }
                c.clone()
            }
            None => Grid::filled(w, h, 1.0),
        };
        let confidence = Grid::from_fn(w, h, |c, r| {
            if *object.at(c, r) {
                *confidence.at(c, r)
            } else {
                0.0
            }
        });
        let trusted: Vec<f64> = (0..w * h)
            .filter(|&q| confidence.as_slice()[q] > 0.0)
            .map(|q| self.image.as_slice()[q])
            .collect();
        if !object.as_slice().iter().any(|&o| o) {
            return bad("the object mask is empty".into());
        }
        if trusted.is_empty() {
            return bad("no pixel is both on the object and trusted (confidence > 0)".into());
        }
        let brightest = trusted.iter().cloned().fold(0.0, f64::max);
        if brightest <= 0.0 {
            return bad(
                "the image is black on every trusted object pixel: there is no shading to explain"
                    .into(),
            );
        }
        let saturated = trusted.iter().filter(|&&v| v >= 1.0).count();
        if saturated * 2 > trusted.len() {
            return bad(format!(
                "the image is saturated: {saturated} of {} trusted object pixels are at the maximum value; \
                 lower the exposure or mask the saturated region (confidence 0)",
                trusted.len()
            ));
        }
        if let InitialDepth::Map(map) = &params.initial_depth
            && map.size() != (w, h)
        {
            return bad(format!(
                "initial depth map is {}x{} but the image is {w}x{h}",
                map.width(),
                map.height()
            ));
        }
        let domain = match params.domain {
            DomainMode::Object => object,
            DomainMode::Paper => Grid::filled(w, h, true),
        };
        Ok((domain, confidence))
    }
}

/// The constant initial depth of [`InitialDepth::FromImage`] on a level: the
/// brightest trusted domain pixel `b` is assumed to face the light,
/// `z0 = Q_b sqrt(s / I_b)`.
pub fn initial_depth_from_image(level: &PyramidLevel, intensity_scale: f64) -> f64 {
    let (w, h) = level.image.size();
    let mut best = (0.0, 1.0);
    for r in 0..h {
        for c in 0..w {
            let v = *level.image.at(c, r);
            if *level.domain.at(c, r) && *level.confidence.at(c, r) > 0.0 && v > best.0 {
                best = (v, level.geometry.ray(c, r).q());
            }
        }
    }
    if best.0 > 0.0 {
        best.1 * (intensity_scale / best.0).sqrt()
    } else {
        1.0
    }
}

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

/// A validated problem ready for a coarse-to-fine scheme: its pyramid
/// (coarsest first), the initial depth on the coarsest level and the
/// smoothness weights in pixel units. Shared by every variational scheme so
/// that they minimise the same discrete energy on the same levels.
pub(crate) struct Prepared {
    /// Levels, coarsest first; the last one is the full image.
    pub levels: Vec<PyramidLevel>,
    /// Initial depth on the coarsest level.
    pub depth: Grid<f64>,
    /// The constant initial depth (or the warm start's mean).
    pub initial_depth: f64,
    /// `alpha` in pixel units.
    pub alpha: f64,
    /// `lambda` in pixel units.
    pub lambda: f64,
}

/// Validates `problem` and `params` and builds the pyramid and initial depth.
pub(crate) fn prepare(problem: &Problem, params: &SolverParams) -> Result<Prepared, SolveError> {
    params.validate()?;
    let (domain, confidence) = problem.validate(params)?;
    let (w, h) = problem.image.size();
    let (alpha, lambda) = params.pixel_smoothness(problem.camera.focal_px);
    let finest = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, problem.camera),
        image: problem.image.clone(),
        confidence,
        domain,
    };
    let warm = match &params.initial_depth {
        InitialDepth::Map(map) => Some(map),
        _ => None,
    };
    let sizes = if warm.is_some() {
        vec![(w, h)]
    } else {
        pyramid::level_sizes(w, h, params.eta, params.min_level_side)
    };
    let mut levels = vec![finest];
    for &(lw, lh) in &sizes[1..] {
        let geometry = LevelGeometry::new(lw, lh, w, h, problem.camera);
        let Some(finer) = levels.last() else { break };
        let source = if params.anti_alias_sigma == 0.0 {
            &levels[0]
        } else {
            finer
        };
        let next = pyramid::downsample(source, geometry, params.anti_alias_sigma);
        if !next.domain.as_slice().iter().any(|&d| d) {
            break; // the object vanished at this size: stop coarsening
        }
        levels.push(next);
    }
    levels.reverse(); // coarsest first

    let coarsest = &levels[0];
    let (depth, initial_depth) = match &params.initial_depth {
        InitialDepth::FromImage => {
            let z0 = initial_depth_from_image(coarsest, problem.intensity_scale);
            (
                Grid::filled(coarsest.geometry.width, coarsest.geometry.height, z0),
                z0,
            )
        }
        InitialDepth::Constant(z0) => (
            Grid::filled(coarsest.geometry.width, coarsest.geometry.height, *z0),
            *z0,
        ),
        InitialDepth::Map(map) => fill_warm_start(map),
    };
    Ok(Prepared {
        levels,
        depth,
        initial_depth,
        alpha,
        lambda,
    })
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
    } = prepare(problem, params)?;
    let level_count = levels.len();
    let coarsest = &levels[0];
    let initial_energy = level_energy(model, coarsest, &depth, alpha, lambda);
    let z_floor = 1e-6 * initial_depth.abs().max(1e-9);

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
        let mut energies = Vec::with_capacity(params.kappa);
        // Energy of the current depth on this level, once known.
        let mut current_energy: Option<Energy> = None;
        // The depth before a trial step (backtracking), reused across iterations.
        let mut previous = depth.clone();
        for iteration in 0..params.kappa {
            let t0 = Instant::now();
            if !system.linearise_data(model, level, &depth, params.derivatives) {
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
                    let step = apply_update(
                        &mut depth,
                        &system,
                        &level.domain,
                        params.dz_limit,
                        1.0,
                        z_floor,
                    );
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
                        let step = apply_update(
                            &mut depth,
                            &system,
                            &level.domain,
                            params.dz_limit,
                            scale,
                            z_floor,
                        );
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
                level: index,
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
            index,
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
    })
}

/// A level's depth (NaN off its domain) and reprojection, as observers get them.
pub(crate) fn level_result<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    index: usize,
    levels: usize,
    energy: Energy,
    start: Instant,
) -> LevelResult {
    LevelResult {
        level: index,
        levels,
        depth: masked(depth, &level.domain),
        reprojection: model::reproject(model, &level.geometry, &level.domain, depth),
        energy,
        elapsed: start.elapsed(),
    }
}

/// The full-resolution depth (NaN) and reprojection (0) outside the
/// problem's object mask, as a [`Solution`] holds them.
pub(crate) fn on_object(
    problem: &Problem,
    depth: &Grid<f64>,
    reprojection: &Grid<f64>,
) -> (Grid<f64>, Grid<f64>) {
    let (w, h) = problem.image.size();
    let object = problem
        .object_mask
        .clone()
        .unwrap_or_else(|| Grid::filled(w, h, true));
    let reprojection = Grid::from_fn(w, h, |c, r| {
        if *object.at(c, r) {
            *reprojection.at(c, r)
        } else {
            0.0
        }
    });
    (masked(depth, &object), reprojection)
}

/// Replaces non-finite or non-positive values of a warm start by the mean.
fn fill_warm_start(map: &Grid<f64>) -> (Grid<f64>, f64) {
    let valid: Vec<f64> = map
        .as_slice()
        .iter()
        .cloned()
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    let mean = valid.iter().sum::<f64>() / valid.len().max(1) as f64;
    (
        map.map(|&z| if z.is_finite() && z > 0.0 { z } else { mean }),
        mean,
    )
}

/// Crops `dz`, adds it to the depth (kept above `z_floor`), returns the
/// largest applied step.
fn apply_update(
    depth: &mut Grid<f64>,
    system: &LinearSystem,
    domain: &Grid<bool>,
    dz_limit: f64,
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
            let dz = if dz.is_finite() {
                scale * dz.clamp(-dz_limit, dz_limit)
            } else {
                0.0
            };
            let z = depth.at_mut(c, r);
            let new = (*z + dz).max(z_floor);
            max_step = max_step.max((new - *z).abs());
            *z = new;
        }
    }
    max_step
}

/// Energy of a level.
pub(crate) fn level_energy<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    alpha: f64,
    lambda: f64,
) -> Energy {
    model::energy(
        model,
        &level.geometry,
        &level.image,
        &level.confidence,
        &level.domain,
        depth,
        alpha,
        lambda,
    )
}

/// The depth with NaN outside `domain`.
pub(crate) fn masked(depth: &Grid<f64>, domain: &Grid<bool>) -> Grid<f64> {
    Grid::from_fn(depth.width(), depth.height(), |c, r| {
        if *domain.at(c, r) {
            *depth.at(c, r)
        } else {
            f64::NAN
        }
    })
}
