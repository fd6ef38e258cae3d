//! Near-light photometric stereo (METHOD.md section 11): several
//! photographs of one object, each lit by one point light of its own, give
//! one depth and one albedo per pixel.
//!
//! The energy sums the near-light data terms of all photographs, Cauchy-
//! robust, leaving out observations in attached or cast shadow of the
//! current surface and saturated ones, plus the paper's second-order
//! Charbonnier smoothness (small). It is minimised in the paper's way:
//! coarse to fine, and at each level by linearisation. The unknown is the
//! log-depth `zeta = ln z`; with `n = (f zeta_x, f zeta_y, -(1 + x zeta_x +
//! y zeta_y))` photograph `j` reads `I_j = m (n . L_j)` where `L_j = phi_j
//! a_j (S_j - P) / |S_j - P|^3` and `m = rho / |n|`. Each linearisation
//! freezes the lights at the current surface and eliminates `m` per pixel
//! in closed form (weighted least squares over its photographs); what is
//! left is quadratic in the gradient of `zeta`, and its normal equations
//! (a 9-point stencil plus the smoothness) are solved by preconditioned
//! conjugate gradients. The gradient does not fix the distance along the
//! rays; the lights' fall-off does: a one-dimensional search on the
//! constant of `zeta` follows each step, and the coarsest level starts
//! from the best of a range of distances. Without measured intensities
//! (semi-calibrated) each photograph's intensity is refitted after each
//! step. Queau et al., JMIV 2018, is the reference model (their near_ps
//! alternates normal estimation and integration; this scheme keeps the
//! paper's linearised coarse-to-fine energy minimisation).

mod level;
mod linear;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::problem::{
    IterationReport, LevelReport, LevelResult, SolveError, SolveObserver, check_cancelled,
};
use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::light::PointLight;
use crate::model::{Energy, LevelGeometry};
use crate::resample::{resize_area, scale_intrinsics};
use level::{Level, MAX_PHOTOS, Observation, Scales, Shared};
use linear::{Operator, Stencil, conjugate_gradients, gradient};

pub use level::{LEFT_OUT_OFF, LEFT_OUT_ROBUST, LEFT_OUT_SHADOW, LEFT_OUT_UNTRUSTED, USED};

/// One photograph of a set, lit by its own light.
#[derive(Clone, Debug)]
pub struct SetPhoto {
    /// Its name (the file), for messages and reports.
    pub name: String,
    /// Linear values (ambient frame, vignetting subtracted or divided out).
    pub image: Grid<f64>,
    /// Its light, camera frame, units of depth; the intensity is relative.
    pub light: PointLight,
    /// Where it was saturated (left out).
    pub saturated: Option<Grid<bool>>,
    /// Its own confidence in [0, 1] (a per-photograph mask), combined with
    /// the set's.
    pub confidence: Option<Grid<f64>>,
}

/// A photometric-stereo problem.
#[derive(Clone, Debug)]
pub struct PhotometricProblem {
    /// The photographs, all of one size.
    pub photos: Vec<SetPhoto>,
    /// Intrinsics at the photographs' size.
    pub camera: Intrinsics,
    /// Pixels that see the object (`None`: every pixel).
    pub object_mask: Option<Grid<bool>>,
    /// Confidence for every photograph, in [0, 1].
    pub confidence: Option<Grid<f64>>,
    /// Whether the lights' intensities were measured; if not, each
    /// photograph's intensity is estimated (semi-calibrated).
    pub intensities_known: bool,
    /// The intensity scale `s`, when known: the albedo is then absolute;
    /// otherwise it is `s rho` (relative).
    pub intensity_scale: Option<f64>,
}

/// The scheme's settings; the defaults are what a user gets.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotometricParams {
    /// Smoothness weight (relative: the second derivatives of the log-depth
    /// times `f^2`); `None`: automatic from the photographs' noise.
    pub alpha: Option<f64>,
    /// Charbonnier `lambda` of the smoothness, in the same units.
    pub lambda: f64,
    /// The Cauchy scale of the residuals relative to the brightness;
    /// `None`: automatic (from the residuals' median).
    pub robust_scale: Option<f64>,
    /// Leave out observations in the current surface's cast shadows.
    pub cast_shadows: bool,
    /// Most linearisations per level.
    pub iterations: usize,
    /// Distance of the object along the optical axis to start from;
    /// `None`: searched.
    pub initial_depth: Option<f64>,
    /// Smallest side of the coarsest level, pixels.
    pub min_side: usize,
}

impl Default for PhotometricParams {
    fn default() -> Self {
        Self {
            alpha: None,
            lambda: 10.0,
            robust_scale: None,
            cast_shadows: true,
            iterations: 30,
            initial_depth: None,
            min_side: 16,
        }
    }
}

/// One photograph's fit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PhotoResult {
    /// The photograph.
    pub name: String,
    /// Its intensity (given, or estimated and normalised to a geometric
    /// mean of 1 over the set).
    pub intensity: f64,
    /// Relative residual `||prediction - I|| / ||I||` over its used
    /// observations.
    pub relative_residual: f64,
    /// Share of the object's observations used.
    pub used_share: f64,
    /// Share left out as attached or cast shadow.
    pub shadow_share: f64,
    /// Share left out as untrusted (confidence 0, its own mask, saturated).
    pub untrusted_share: f64,
    /// Share the robust estimator gave less than half their weight.
    pub robust_share: f64,
    /// `I - prediction` per pixel (as a single solve's residual); NaN off
    /// the object.
    #[serde(skip)]
    pub residual: Grid<f64>,
    /// Why each observation was left out ([`USED`], [`LEFT_OUT_SHADOW`], ...).
    #[serde(skip)]
    pub left_out: Grid<u8>,
}

/// The result of a photometric-stereo solve.
#[derive(Clone, Debug)]
pub struct PhotometricSolution {
    /// Depth along the optical axis, units of the lights; NaN off the object.
    pub depth: Grid<f64>,
    /// Unit normals of the solved surface (camera frame, towards the
    /// camera); NaN off the object.
    pub normals: Grid<[f64; 3]>,
    /// Albedo per pixel: absolute with a known intensity scale, else
    /// `s rho`; NaN off the object or where no photograph says anything.
    pub albedo: Grid<f64>,
    /// Whether the albedo is relative (`s rho`, the scale unknown).
    pub albedo_relative: bool,
    /// Each photograph's fit.
    pub photos: Vec<PhotoResult>,
    /// Whether the intensities were estimated (semi-calibrated).
    pub intensities_estimated: bool,
    /// The smoothness weight used.
    pub alpha: f64,
    /// The Cauchy scale used at the end, relative to the brightness.
    pub robust_scale: f64,
    /// The reference brightness (median of the trusted object values).
    pub brightness: f64,
    /// The distance the solve started from, and every distance tried at
    /// the coarsest level with its energy per pixel.
    pub initial_depth: f64,
    /// The distances tried `(distance, energy per pixel)`.
    pub distances_tried: Vec<(f64, f64)>,
    /// Final energy (data over the brightness squared; smoothness; total).
    pub energy: Energy,
    /// Levels, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Linearisations over all levels.
    pub iterations: usize,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Checks the set: at least two photographs of one size, each with a valid
/// light, no two lights at the same place, masks of the photographs' size.
/// The message names the photograph at fault.
pub fn validate(problem: &PhotometricProblem) -> Result<(), SolveError> {
    let bad = |m: String| Err(SolveError::Input(m));
    let photos = &problem.photos;
    if photos.len() < 2 {
        return bad(format!(
            "photometric stereo needs at least 2 photographs, each with its own light; got {}",
            photos.len()
        ));
    }
    if photos.len() > MAX_PHOTOS {
        return bad(format!(
            "at most {MAX_PHOTOS} photographs in a set; got {}",
            photos.len()
        ));
    }
    let size = photos[0].image.size();
    if size.0 < 3 || size.1 < 3 {
        return bad(format!(
            "{} is {}x{}: too small",
            photos[0].name, size.0, size.1
        ));
    }
    for (k, photo) in photos.iter().enumerate() {
        if photo.image.size() != size {
            return bad(format!(
                "{} is {}x{} but {} is {}x{}: the photographs of a set must have one size",
                photo.name,
                photo.image.width(),
                photo.image.height(),
                photos[0].name,
                size.0,
                size.1
            ));
        }
        photo
            .light
            .validated(k + 1)
            .map_err(|e| SolveError::Input(format!("{}: {e}", photo.name)))?;
        let sizes_ok = photo.saturated.as_ref().is_none_or(|g| g.size() == size)
            && photo.confidence.as_ref().is_none_or(|g| g.size() == size);
        if !sizes_ok {
            return bad(format!(
                "{}: its mask is not {}x{}",
                photo.name, size.0, size.1
            ));
        }
        if photo.image.as_slice().iter().any(|v| !v.is_finite()) {
            return bad(format!("{}: holds values that are not finite", photo.name));
        }
        for other in &photos[..k] {
            let d = DVec3::from_array(photo.light.position)
                .distance(DVec3::from_array(other.light.position));
            let scale = DVec3::from_array(photo.light.position).length().max(1e-300);
            if d <= 1e-9 * scale {
                return bad(format!(
                    "{} and {} have the same light (at {:?}): a set needs each photograph lit \
                     from a different place",
                    other.name, photo.name, photo.light.position
                ));
            }
        }
    }
    if problem
        .object_mask
        .as_ref()
        .is_some_and(|m| m.size() != size)
        || problem
            .confidence
            .as_ref()
            .is_some_and(|m| m.size() != size)
    {
        return bad(format!(
            "the mask is not the photographs' size {}x{}",
            size.0, size.1
        ));
    }
    if !(problem.camera.focal_px.is_finite() && problem.camera.focal_px > 0.0) {
        return bad(format!(
            "focal length {} must be positive",
            problem.camera.focal_px
        ));
    }
    Ok(())
}

/// Most conjugate-gradient iterations per linearisation: coarse levels,
/// fine levels (inexact steps: each fine level refines what the coarser
/// ones found, and its next linearisation goes on; on a 768 px render 60
/// instead of 300 costs 0.0003 of RSE and halves the time).
const CG_ITERATIONS: usize = 300;
const CG_ITERATIONS_FINE: usize = 60;
/// Their relative tolerance on the fine levels (which refine) and on the
/// coarse ones (which find the shape and the distance; the distance is a
/// slow mode of the system, resolved only by a tight solve).
const CG_TOLERANCE_FINE: f64 = 1e-3;
const CG_TOLERANCE_COARSE: f64 = 1e-6;
/// Cast shadows are traced on a copy of the surface at most this many
/// pixels on its longest side (shadows are large; tracing is quadratic).
const SHADOW_SIDE: usize = 128;
/// The Cauchy scale never falls below this share of the brightness (a
/// render's residuals are round-off).
const MIN_ROBUST_SCALE: f64 = 5e-3;
/// Automatic smoothness: `ALPHA_FLOOR + ALPHA_NOISE * (sigma / I_ref)^2`.
const ALPHA_FLOOR: f64 = 1e-7;
const ALPHA_NOISE: f64 = 1e-4;
/// A level stops once a linearisation lowers the energy by less than this
/// share (fine levels, coarse levels).
const STOP_FINE: f64 = 1e-3;
const STOP_COARSE: f64 = 1e-4;
/// Levels larger than this (longest side, pixels) refine what the coarser
/// ones found, in at most [`FINE_ITERATIONS`] linearisations.
const FINE_SIDE: usize = 300;
const FINE_ITERATIONS: usize = 4;
/// Semi-calibrated: rounds of (shape, intensities) per coarse level.
const INTENSITY_ROUNDS: usize = 4;
/// Distances kept from the coarsest level for the next.
const FINALISTS: usize = 3;
/// Linearisations per distance tried.
const CANDIDATE_ITERATIONS: usize = 5;
/// Distances tried at the coarsest level.
const DISTANCE_CANDIDATES: usize = 12;

/// The pyramid of a `width` x `height` set, finest first (the coarsest may
/// only choose the start: its result is streamed when it is the first
/// level solved).
pub fn level_sizes(width: usize, height: usize, params: &PhotometricParams) -> Vec<(usize, usize)> {
    super::pyramid::level_sizes(width, height, 0.5, params.min_side.max(3))
}

/// Solves the set: depth, normals, albedo and each photograph's fit,
/// every level's depth to `observer` (its reprojection: the mean of the
/// photographs' predictions).
///
/// # Errors
/// An invalid set (see [`validate`]), no trusted observation, cancellation,
/// or a result that is not a surface.
pub fn solve_photometric(
    problem: &PhotometricProblem,
    params: &PhotometricParams,
    observer: &mut dyn SolveObserver,
) -> Result<PhotometricSolution, SolveError> {
    let start = Instant::now();
    validate(problem)?;
    let (width, height) = problem.photos[0].image.size();
    let finest = finest_level(problem);
    let brightness = reference_brightness(&finest).ok_or_else(|| {
        SolveError::Input("no trusted, lit object pixel in any photograph".into())
    })?;
    let sigma = noise_sigma(problem, &finest);
    let alpha = match params.alpha {
        Some(a) => a,
        None => ALPHA_FLOOR + ALPHA_NOISE * (sigma / brightness).powi(2),
    };
    // Dark: within three noise deviations of black, and at least 2 % of
    // the brightness (a render has no noise).
    let dark_level = (3.0 * sigma).max(0.02 * brightness);
    let scales_at = |robust_scale: f64| Scales {
        robust_scale,
        dark_level,
        brightness,
        alpha,
        lambda: params.lambda,
    };
    let lights: Vec<PointLight> = problem.photos.iter().map(|p| p.light).collect();
    let mut intensities: Vec<f64> = lights.iter().map(|l| l.intensity).collect();
    let estimate_intensities = !problem.intensities_known;
    if estimate_intensities {
        intensities = vec![1.0; lights.len()];
    }
    let sizes = level_sizes(width, height, params);
    let mut levels_data = vec![finest];
    for &(w, h) in &sizes[1..] {
        let coarser = coarsen(levels_data.last().unwrap_or_else(|| unreachable!()), w, h);
        levels_data.push(coarser);
    }
    levels_data.reverse();
    let level_count = levels_data.len();
    let mut robust_scale = params.robust_scale.map(|s| s * brightness);
    let mut reports = Vec::new();
    let mut iterations = 0usize;
    let mut distances_tried = Vec::new();
    let mut initial_depth = f64::NAN;
    let mut first_level = 0;
    let mut zeta: Vec<f64> = Vec::new();
    let mut m: Vec<f64> = Vec::new();
    let mut cast = CastShadows::default();
    let mut energy = Energy {
        data: 0.0,
        smoothness: 0.0,
        total: 0.0,
    };
    for (index, level) in levels_data.iter().enumerate() {
        check_cancelled(observer)?;
        let level_start = Instant::now();
        let mut scale = robust_scale.unwrap_or(1e3 * brightness);
        if index == 0 {
            // The start is chosen with equal (or the given) intensities: on
            // a plane the intensities would absorb the shape.
            let start = choose_start(
                &levels_data,
                &lights,
                &intensities,
                false,
                scales_at(scale),
                params,
                observer,
            )?;
            zeta = start.zeta;
            m = start.m;
            intensities = start.intensities;
            initial_depth = start.distance;
            distances_tried = start.tried;
            first_level = start.level;
            if first_level > index {
                continue;
            }
        } else if index > first_level {
            let previous = &levels_data[index - 1];
            zeta = upsample(&zeta, previous, level);
            m = upsample(&m, previous, level);
        }
        // Robust scale and shadows from the surface as it stands.
        if params.robust_scale.is_none() {
            scale = auto_robust_scale(
                dark_level,
                level,
                &lights,
                &intensities,
                &cast_for(&cast, level),
                &zeta,
                &m,
                brightness,
            );
            robust_scale = Some(scale);
        }
        if params.cast_shadows {
            cast = cast_shadows(level, &lights, &zeta, std::mem::take(&mut cast));
        }
        let level_cast = cast_for(&cast, level);
        let fine = level.width.max(level.height) > FINE_SIDE;
        let how = LevelRun {
            max_iterations: if fine {
                FINE_ITERATIONS.min(params.iterations)
            } else {
                params.iterations
            },
            search_distance: index == 0,
            report: Some((index, level_count, start)),
        };
        // Semi-calibrated: on the coarse levels the intensities are refitted
        // to the shape each time it has settled, and the shape solved again
        // (refitting them inside the linearisations runs away along the
        // coupling of a light's intensity and the surface's tilt).
        if estimate_intensities && !fine {
            for _ in 0..INTENSITY_ROUNDS {
                run_level(
                    level,
                    &lights,
                    &mut intensities,
                    false,
                    &level_cast,
                    scales_at(scale),
                    &mut zeta,
                    &mut m,
                    LevelRun {
                        report: None,
                        ..how
                    },
                    observer,
                )?;
                let shared = Shared::new(&lights, &intensities, &level_cast, scales_at(scale));
                intensities = level.refit_intensities(&shared, &zeta, &m);
            }
        }
        let (e, energies, its) = run_level(
            level,
            &lights,
            &mut intensities,
            false,
            &level_cast,
            scales_at(scale),
            &mut zeta,
            &mut m,
            how,
            observer,
        )?;
        iterations += its;
        energy = e;
        reports.push(LevelReport {
            width: level.width,
            height: level.height,
            energies,
            seconds: level_start.elapsed().as_secs_f64(),
        });
        let shared = Shared::new(&lights, &intensities, &level_cast, scales_at(scale));
        let depth = depth_grid(level, &zeta);
        let reprojection = mean_prediction(level, &shared, &zeta, &m);
        observer.on_level(&LevelResult {
            level: index,
            levels: level_count,
            depth: std::sync::Arc::new(depth),
            reprojection: std::sync::Arc::new(reprojection),
            geometry: LevelGeometry::new(level.width, level.height, width, height, problem.camera),
            domain_pixels: level.domain.iter().filter(|&&d| d).count(),
            energy: e,
            elapsed: start.elapsed(),
        });
    }
    let Some(level) = levels_data.last() else {
        return Err(SolveError::Input("no level".into()));
    };
    let final_cast = cast_for(&cast, level);
    let scale = robust_scale.unwrap_or(1e3 * brightness);
    let shared = Shared::new(&lights, &intensities, &final_cast, scales_at(scale));
    let solution = finish(
        problem,
        level,
        &shared,
        &zeta,
        &m,
        FinishInfo {
            estimate_intensities,
            alpha,
            initial_depth,
            distances_tried,
            energy,
            levels: reports,
            iterations,
            start,
        },
    );
    check_finite(&solution)?;
    Ok(solution)
}

/// Where the solve starts: the surface, albedo factor and intensities at
/// `level`, the distance chosen and every distance tried with its energy.
struct Start {
    level: usize,
    zeta: Vec<f64>,
    m: Vec<f64>,
    intensities: Vec<f64>,
    distance: f64,
    tried: Vec<(f64, f64)>,
}

/// Chooses the distance to start from: every candidate (or the one given)
/// is solved briefly at the coarsest level from a plane at that distance;
/// the [`FINALISTS`] best are solved again at the next level, where the
/// surface is less aliased, and the best of them is kept.
#[allow(clippy::too_many_arguments)]
fn choose_start(
    levels: &[Level],
    lights: &[PointLight],
    intensities: &[f64],
    estimate_intensities: bool,
    scales: Scales,
    params: &PhotometricParams,
    observer: &mut dyn SolveObserver,
) -> Result<Start, SolveError> {
    let candidates = match params.initial_depth {
        Some(d) => vec![d],
        None => distance_candidates(lights),
    };
    let how = LevelRun {
        max_iterations: CANDIDATE_ITERATIONS.min(params.iterations),
        search_distance: true,
        report: None,
    };
    let per_pixel = |e: Energy, level: &Level| {
        e.total / level.domain.iter().filter(|&&d| d).count().max(1) as f64
    };
    let no_cast: Vec<Vec<bool>> = Vec::new();
    let coarsest = &levels[0];
    let n = coarsest.width * coarsest.height;
    let mut runs = Vec::new();
    let mut tried = Vec::new();
    for &d in &candidates {
        let mut zeta = vec![d.ln(); n];
        let mut m = vec![0.0; n];
        let mut phi = intensities.to_vec();
        let (e, _, _) = run_level(
            coarsest,
            lights,
            &mut phi,
            estimate_intensities,
            &no_cast,
            scales,
            &mut zeta,
            &mut m,
            how,
            observer,
        )?;
        let value = per_pixel(e, coarsest);
        tried.push((d, value));
        runs.push((value, d, zeta, m, phi));
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    runs.truncate(FINALISTS);
    let mut level = 0;
    if let (Some(next), true) = (levels.get(1), runs.len() > 1) {
        level = 1;
        for run in &mut runs {
            run.2 = upsample(&run.2, coarsest, next);
            run.3 = upsample(&run.3, coarsest, next);
            let (e, _, _) = run_level(
                next,
                lights,
                &mut run.4,
                estimate_intensities,
                &no_cast,
                scales,
                &mut run.2,
                &mut run.3,
                how,
                observer,
            )?;
            run.0 = per_pixel(e, next);
        }
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let Some((_, distance, zeta, m, intensities)) = runs.into_iter().next() else {
        return Err(SolveError::Input("no distance to start from".into()));
    };
    Ok(Start {
        level,
        zeta,
        m,
        intensities,
        distance,
        tried,
    })
}

/// How a level runs: its most linearisations, and whether the distance
/// along the rays is searched after each step (the coarsest level, where
/// the start may be far off; elsewhere the linearisation moves it).
#[derive(Clone, Copy)]
struct LevelRun {
    max_iterations: usize,
    search_distance: bool,
    /// Reported after each linearisation as this level of that many, the
    /// solve having started then (`None`: a trial, not reported).
    report: Option<(usize, usize, Instant)>,
}

/// Runs the linearisations of one level from `zeta` (and `m`, the albedo
/// factor), with the intensities refitted when asked. Returns the final
/// energy, the energy after each step and the steps run.
#[allow(clippy::too_many_arguments)]
fn run_level(
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
) -> Result<(Energy, Vec<f64>, usize), SolveError> {
    let pixels = level.domain.iter().filter(|&&d| d).count().max(1);
    let fine = level.width.max(level.height) > FINE_SIDE;
    // The distance search looks at about 20 000 pixels.
    let stride = (pixels / 20_000).max(1);
    let mut energies = Vec::new();
    let mut run = 0;
    let mut before: Option<Energy> = None;
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
        conjugate_gradients(
            &operator,
            &rhs,
            &mut next,
            if fine {
                CG_TOLERANCE_FINE
            } else {
                CG_TOLERANCE_COARSE
            },
            if fine {
                CG_ITERATIONS_FINE
            } else {
                CG_ITERATIONS
            },
            Cancel::new(&cancelled),
        )?;
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
    Ok((last, energies, run))
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

/// Distances along the optical axis to start from, log-spaced: from just
/// beyond the farthest light to where the lights are 5 degrees off the
/// axis seen from the object (beyond it the photographs barely differ in
/// direction, and a set says little about the shape).
fn distance_candidates(lights: &[PointLight]) -> Vec<f64> {
    let lateral = lights
        .iter()
        .map(|l| l.position[0].hypot(l.position[1]))
        .fold(0.0, f64::max);
    let spread = lights
        .iter()
        .map(|l| DVec3::from_array(l.position).length())
        .fold(0.0, f64::max)
        .max(1e-12);
    let reach = if lateral > 0.0 { lateral } else { spread };
    let farthest = lights
        .iter()
        .map(|l| l.position[2])
        .fold(f64::MIN, f64::max);
    let lo = (farthest + 0.05 * reach).max(0.05 * reach);
    let hi = farthest.max(0.0) + reach / 5f64.to_radians().tan();
    let hi = hi.max(2.0 * lo);
    (0..DISTANCE_CANDIDATES)
        .map(|k| lo * (hi / lo).powf(k as f64 / (DISTANCE_CANDIDATES - 1) as f64))
        .collect()
}

/// The finest level: the photographs with their weights.
fn finest_level(problem: &PhotometricProblem) -> Level {
    let (w, h) = problem.photos[0].image.size();
    let domain: Vec<bool> = match &problem.object_mask {
        Some(mask) => mask.as_slice().to_vec(),
        None => vec![true; w * h],
    };
    let images = problem
        .photos
        .iter()
        .map(|p| p.image.as_slice().iter().map(|v| v.max(0.0)).collect())
        .collect();
    let weights = problem
        .photos
        .iter()
        .map(|p| {
            (0..w * h)
                .map(|q| {
                    let set = problem.confidence.as_ref().map_or(1.0, |c| c.as_slice()[q]);
                    let own = p.confidence.as_ref().map_or(1.0, |c| c.as_slice()[q]);
                    let saturated = p.saturated.as_ref().is_some_and(|s| s.as_slice()[q]);
                    if domain[q] && !saturated {
                        (set * own).clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    Level {
        width: w,
        height: h,
        camera: problem.camera,
        domain,
        images,
        weights,
    }
}

/// A coarser level by area averaging over the domain (a coarse pixel is in
/// the domain when at least half of its area is); an observation is as
/// trusted as the average of its area (saturated anywhere: left out).
fn coarsen(finer: &Level, w: usize, h: usize) -> Level {
    let (fw, fh) = (finer.width, finer.height);
    let grid = |v: Vec<f64>| Grid::from_vec(fw, fh, v).unwrap_or_else(|| Grid::filled(fw, fh, 0.0));
    let area = |v: Vec<f64>| {
        resize_area(&grid(v), w, h, Cancel::NEVER)
            .uncancelled()
            .into_vec()
    };
    let coverage = area(
        finer
            .domain
            .iter()
            .map(|&d| f64::from(u8::from(d)))
            .collect(),
    );
    let domain: Vec<bool> = coverage.iter().map(|&c| c >= 0.5).collect();
    let images = finer
        .images
        .iter()
        .map(|image| {
            let sums = area(
                image
                    .iter()
                    .zip(&finer.domain)
                    .map(|(v, &d)| if d { *v } else { 0.0 })
                    .collect(),
            );
            sums.iter()
                .zip(&coverage)
                .map(|(s, c)| if *c > 0.0 { s / c } else { 0.0 })
                .collect()
        })
        .collect();
    let weights = finer
        .weights
        .iter()
        .map(|weights| {
            let untrusted_in_domain: Vec<f64> = weights
                .iter()
                .zip(&finer.domain)
                .map(|(wt, &d)| if d && *wt <= 0.0 { 1.0 } else { 0.0 })
                .collect();
            let mean = area(weights.clone());
            let lost = area(untrusted_in_domain);
            mean.iter()
                .zip(&coverage)
                .zip(&lost)
                .zip(&domain)
                .map(|(((m, c), l), &d)| {
                    if d && *c > 0.0 && *l < 0.5 * c {
                        (m / c).clamp(0.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    Level {
        width: w,
        height: h,
        camera: scale_intrinsics(finer.camera, (fw, fh), (w, h)),
        domain,
        images,
        weights,
    }
}

/// The median of the trusted, positive object values of all photographs.
fn reference_brightness(level: &Level) -> Option<f64> {
    let mut values: Vec<f64> = level
        .images
        .iter()
        .zip(&level.weights)
        .flat_map(|(image, weights)| {
            image
                .iter()
                .zip(weights)
                .filter(|(v, w)| **w > 0.0 && **v > 0.0)
                .map(|(v, _)| *v)
        })
        .step_by(7)
        .collect();
    if values.is_empty() {
        return None;
    }
    let k = values.len() / 2;
    let (_, median, _) = values.select_nth_unstable_by(k, f64::total_cmp);
    (*median > 0.0 && median.is_finite()).then_some(*median)
}

/// The photographs' noise: the median of each one's robust estimate over
/// its trusted object pixels.
fn noise_sigma(problem: &PhotometricProblem, level: &Level) -> f64 {
    let (w, h) = (level.width, level.height);
    let mut sigmas: Vec<f64> = problem
        .photos
        .iter()
        .zip(&level.weights)
        .map(|(photo, weights)| {
            let trusted = Grid::from_vec(w, h, weights.iter().map(|v| *v > 0.0).collect())
                .unwrap_or_else(|| Grid::filled(w, h, false));
            crate::denoise::robust_noise_sigma(&photo.image, &trusted, Cancel::NEVER).uncancelled()
        })
        .collect();
    sigmas.sort_by(f64::total_cmp);
    sigmas.get(sigmas.len() / 2).copied().unwrap_or(0.0)
}

/// The Cauchy scale from the residuals of the current surface: 2.385 (95 %
/// efficiency under Gaussian noise) times the MAD's estimate of their
/// spread, at least [`MIN_ROBUST_SCALE`] of the brightness.
#[allow(clippy::too_many_arguments)]
fn auto_robust_scale(
    dark_level: f64,
    level: &Level,
    lights: &[PointLight],
    intensities: &[f64],
    cast: &[Vec<bool>],
    zeta: &[f64],
    m: &[f64],
    brightness: f64,
) -> f64 {
    let shared = Shared::new(
        lights,
        intensities,
        cast,
        Scales {
            robust_scale: 1e3 * brightness,
            dark_level,
            brightness,
            alpha: 0.0,
            lambda: 1.0,
        },
    );
    let pixels = level.domain.iter().filter(|&&d| d).count().max(1);
    let stride = (pixels / 20_000).max(1);
    let mut residuals: Vec<f64> = (0..zeta.len())
        .into_par_iter()
        .step_by(stride)
        .flat_map_iter(|p| {
            let mut out = Vec::new();
            if level.domain[p] {
                let mut obs = [Observation::default(); MAX_PHOTOS];
                let n = level.observe(&shared, zeta, p, 0.0, &mut obs).n;
                let fit = Level::fit_pixel(&shared, &mut obs[..n], m[p]);
                for o in &obs[..n] {
                    if o.weight > 0.0 {
                        out.push((fit.m * o.u - o.value).abs());
                    }
                }
            }
            out
        })
        .collect();
    let floor = MIN_ROBUST_SCALE * brightness;
    if residuals.is_empty() {
        return floor;
    }
    let k = residuals.len() / 2;
    let (_, median, _) = residuals.select_nth_unstable_by(k, f64::total_cmp);
    (2.385 * 1.4826 * *median).max(floor)
}

/// Cast shadows per photograph, traced at one size.
#[derive(Clone, Default)]
struct CastShadows {
    size: (usize, usize),
    masks: Vec<Vec<bool>>,
}

/// Each photograph's cast shadow for `level`: traced on the surface at this
/// level when it is at most [`SHADOW_SIDE`] pixels (or nothing was traced
/// yet), else the last traced one kept. Lights at the optical centre cast
/// none.
fn cast_shadows(
    level: &Level,
    lights: &[PointLight],
    zeta: &[f64],
    previous: CastShadows,
) -> CastShadows {
    if level.width.max(level.height) > SHADOW_SIDE && !previous.masks.is_empty() {
        return previous;
    }
    let depth = depth_grid(level, zeta);
    let masks = lights
        .iter()
        .map(|light| {
            if light.is_centred() {
                return vec![false; zeta.len()];
            }
            crate::occlusion::cast_shadow(&depth, level.camera, light.position).into_vec()
        })
        .collect();
    CastShadows {
        size: (level.width, level.height),
        masks,
    }
}

/// Shadow masks (traced at any size) resampled to `level` by the nearest
/// pixel.
fn cast_for(cast: &CastShadows, level: &Level) -> Vec<Vec<bool>> {
    let (w, h) = (level.width, level.height);
    let (mw, mh) = cast.size;
    cast.masks
        .iter()
        .map(|mask| {
            if (mw, mh) == (w, h) {
                return mask.clone();
            }
            (0..w * h)
                .map(|p| {
                    let (c, r) = (p % w, p / w);
                    let mc = (((c as f64 + 0.5) * mw as f64 / w as f64) as usize).min(mw - 1);
                    let mr = (((r as f64 + 0.5) * mh as f64 / h as f64) as usize).min(mh - 1);
                    mask[mr * mw + mc]
                })
                .collect()
        })
        .collect()
}

/// A per-pixel value of a coarser level brought to a finer one (bilinear
/// over the coarse domain).
fn upsample(values: &[f64], coarse: &Level, fine: &Level) -> Vec<f64> {
    let grid = Grid::from_vec(coarse.width, coarse.height, values.to_vec())
        .unwrap_or_else(|| Grid::filled(coarse.width, coarse.height, 0.0));
    let coarse_domain = Grid::from_vec(coarse.width, coarse.height, coarse.domain.clone())
        .unwrap_or_else(|| Grid::filled(coarse.width, coarse.height, true));
    let fine_domain = Grid::from_vec(fine.width, fine.height, fine.domain.clone())
        .unwrap_or_else(|| Grid::filled(fine.width, fine.height, true));
    super::pyramid::upsample_depth(&grid, &coarse_domain, &fine_domain).into_vec()
}

/// `exp(zeta)` on the domain, NaN elsewhere.
fn depth_grid(level: &Level, zeta: &[f64]) -> Grid<f64> {
    Grid::from_fn(level.width, level.height, |c, r| {
        let p = r * level.width + c;
        if level.domain[p] {
            zeta[p].exp()
        } else {
            f64::NAN
        }
    })
}

/// The mean over the photographs of the predicted values (the level
/// stream's reprojection).
fn mean_prediction(level: &Level, shared: &Shared<'_>, zeta: &[f64], m: &[f64]) -> Grid<f64> {
    let values: Vec<f64> = (0..zeta.len())
        .into_par_iter()
        .with_min_len(512)
        .map(|p| {
            if !level.domain[p] {
                return 0.0;
            }
            let mut obs = [Observation::default(); MAX_PHOTOS];
            let n = level.observe(shared, zeta, p, 0.0, &mut obs).n;
            obs[..n].iter().map(|o| (m[p] * o.u).max(0.0)).sum::<f64>() / n.max(1) as f64
        })
        .collect();
    Grid::from_vec(level.width, level.height, values)
        .unwrap_or_else(|| Grid::filled(level.width, level.height, 0.0))
}

/// What the solve gathered for its result.
struct FinishInfo {
    estimate_intensities: bool,
    alpha: f64,
    initial_depth: f64,
    distances_tried: Vec<(f64, f64)>,
    energy: Energy,
    levels: Vec<LevelReport>,
    iterations: usize,
    start: Instant,
}

/// Depth, normals, albedo and each photograph's fit at the finest level.
fn finish(
    problem: &PhotometricProblem,
    level: &Level,
    shared: &Shared<'_>,
    zeta: &[f64],
    m: &[f64],
    info: FinishInfo,
) -> PhotometricSolution {
    let (w, h) = (level.width, level.height);
    let f = level.camera.focal_px;
    let depth = depth_grid(level, zeta);
    let mut normals = Grid::filled(w, h, [f64::NAN; 3]);
    let mut albedo = Grid::filled(w, h, f64::NAN);
    let s = problem.intensity_scale.unwrap_or(1.0);
    for (p, &m_p) in m.iter().enumerate() {
        if !level.domain[p] {
            continue;
        }
        let mut obs = [Observation::default(); MAX_PHOTOS];
        let g = level.observe(shared, zeta, p, 0.0, &mut obs).g;
        let (x, y) = level.camera.image_xy((p % w) as f64, (p / w) as f64);
        let n = DVec3::new(f * g[0], f * g[1], -(1.0 + x * g[0] + y * g[1]));
        let length = n.length();
        if length > 0.0 && length.is_finite() {
            normals.as_mut_slice()[p] = (n / length).to_array();
            if m_p > 0.0 {
                albedo.as_mut_slice()[p] = m_p * length / s;
            }
        }
    }
    let per_pixel = level.residuals(shared, zeta, m);
    let photos = problem
        .photos
        .iter()
        .enumerate()
        .map(|(j, photo)| {
            let mut residual = Grid::filled(w, h, f64::NAN);
            let mut left_out = Grid::filled(w, h, LEFT_OUT_OFF);
            let (mut counts, mut sum_r2, mut sum_i2) = ([0usize; 5], 0.0, 0.0);
            for (p, observed) in per_pixel.iter().enumerate() {
                let (r, _, why) = observed[j];
                left_out.as_mut_slice()[p] = why;
                if level.domain[p] {
                    residual.as_mut_slice()[p] = -r;
                    counts[why as usize] += 1;
                    if why == USED {
                        sum_r2 += r * r;
                        sum_i2 += level.images[j][p] * level.images[j][p];
                    }
                }
            }
            let object = level.domain.iter().filter(|&&d| d).count().max(1) as f64;
            PhotoResult {
                name: photo.name.clone(),
                intensity: shared.intensities[j],
                relative_residual: if sum_i2 > 0.0 {
                    (sum_r2 / sum_i2).sqrt()
                } else {
                    f64::NAN
                },
                used_share: counts[USED as usize] as f64 / object,
                shadow_share: counts[LEFT_OUT_SHADOW as usize] as f64 / object,
                untrusted_share: counts[LEFT_OUT_UNTRUSTED as usize] as f64 / object,
                robust_share: counts[LEFT_OUT_ROBUST as usize] as f64 / object,
                residual,
                left_out,
            }
        })
        .collect();
    PhotometricSolution {
        depth,
        normals,
        albedo,
        albedo_relative: problem.intensity_scale.is_none(),
        photos,
        intensities_estimated: info.estimate_intensities,
        alpha: info.alpha,
        robust_scale: shared.robust_scale / shared.brightness,
        brightness: shared.brightness,
        initial_depth: info.initial_depth,
        distances_tried: info.distances_tried,
        energy: info.energy,
        levels: info.levels,
        iterations: info.iterations,
        seconds: info.start.elapsed().as_secs_f64(),
    }
}

/// Refuses a result that is not a surface: a depth that is not positive
/// and finite, or none at all.
fn check_finite(solution: &PhotometricSolution) -> Result<(), SolveError> {
    let values: Vec<f64> = solution
        .depth
        .as_slice()
        .iter()
        .copied()
        .filter(|z| !z.is_nan())
        .collect();
    if values.is_empty() {
        return Err(SolveError::Diverged("no pixel has a depth".into()));
    }
    let bad = values
        .iter()
        .filter(|z| !(z.is_finite() && **z > 0.0 && **z <= super::problem::MAX_SOLVED_DEPTH))
        .count();
    if bad > 0 {
        return Err(SolveError::Diverged(format!(
            "{bad} of {} depths are not positive and finite",
            values.len()
        )));
    }
    Ok(())
}

/// What the user should know of a set's fit, in plain words (the command
/// line prints them, the viewer shows them): too few photographs to fix
/// the distance, a photograph barely used, estimated intensities far apart.
pub fn warnings(solution: &PhotometricSolution) -> Vec<String> {
    let mut warnings = Vec::new();
    if solution.photos.len() < 4 {
        warnings.push(format!(
            "{} photographs: each pixel has no more photographs than unknowns (albedo and two \
             slopes), so a shadow leaves it to its neighbours and the distance (the depth unit) \
             is barely determined; on renders three LEDs gave the right shape on smooth objects \
             but up to 25 % off in distance on others; four or more photographs determine it",
            solution.photos.len()
        ));
    }
    for photo in &solution.photos {
        if photo.used_share < 0.3 {
            warnings.push(format!(
                "{} is used on only {:.0} % of the object ({:.0} % shadow, {:.0} % untrusted or \
                 saturated, {:.0} % not explained by the model): check its light and exposure",
                photo.name,
                100.0 * photo.used_share,
                100.0 * photo.shadow_share,
                100.0 * photo.untrusted_share,
                100.0 * photo.robust_share
            ));
        }
    }
    if solution.intensities_estimated {
        let spread = solution
            .photos
            .iter()
            .map(|p| p.intensity)
            .fold((f64::MAX, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if spread.0 > 0.0 && spread.1 / spread.0 > 10.0 {
            warnings.push(format!(
                "the estimated intensities of the lights differ by {:.0}x: a photograph may be \
                 mislabelled or its light misplaced",
                spread.1 / spread.0
            ));
        }
    }
    warnings
}

/// How far a single-photograph shape is from the set's: the single-image
/// method measured on a real photograph against what the set says.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SingleComparison {
    /// RSE of the single-image depth against the set's over the pixels
    /// both solved.
    pub rse_to_set: f64,
    /// The same after the single depth is scaled by the one factor that
    /// best matches the set's (a single photograph's depth unit may be
    /// unknown).
    pub rse_to_set_scaled: f64,
    /// That factor.
    pub scale_to_set: f64,
    /// The mean angle between the two surfaces' normals, degrees.
    pub mean_normal_angle_deg: f64,
    /// The median of the same.
    pub median_normal_angle_deg: f64,
    /// The set's depth range (2nd to 98th percentile), units of depth.
    pub set_depth_range: f64,
    /// The single photograph's depth range, the same way.
    pub single_depth_range: f64,
    /// The pixels compared.
    pub pixels: usize,
}

/// Compares a single-photograph depth with the set's (both at the set's
/// working size, NaN off the object; `camera`: its intrinsics).
pub fn compare_single(
    set_depth: &Grid<f64>,
    single_depth: &Grid<f64>,
    camera: Intrinsics,
) -> Option<SingleComparison> {
    if set_depth.size() != single_depth.size() {
        return None;
    }
    let both = set_depth.zip_map(single_depth, |a, b| {
        a.is_finite() && b.is_finite() && *a > 0.0 && *b > 0.0
    });
    let pairs: Vec<(f64, f64)> = set_depth
        .as_slice()
        .iter()
        .zip(single_depth.as_slice())
        .zip(both.as_slice())
        .filter(|(_, b)| **b)
        .map(|((a, b), _)| (*a, *b))
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let norm = pairs.iter().map(|(a, _)| a * a).sum::<f64>().sqrt();
    let rse = |k: f64| {
        pairs
            .iter()
            .map(|(a, b)| (k * b - a).powi(2))
            .sum::<f64>()
            .sqrt()
            / norm
    };
    let k = pairs.iter().map(|(a, b)| a * b).sum::<f64>()
        / pairs.iter().map(|(_, b)| b * b).sum::<f64>().max(1e-300);
    let normals_set = depth_normals(set_depth, camera);
    let normals_single = depth_normals(single_depth, camera);
    let mut angles: Vec<f64> = normals_set
        .as_slice()
        .iter()
        .zip(normals_single.as_slice())
        .zip(both.as_slice())
        .filter(|(_, b)| **b)
        .filter_map(|((a, b), _)| {
            let (u, v) = (DVec3::from_array(*a), DVec3::from_array(*b));
            (u.is_finite() && v.is_finite()).then(|| u.angle_between(v).to_degrees())
        })
        .collect();
    let mean_angle = angles.iter().sum::<f64>() / angles.len().max(1) as f64;
    let median_angle = if angles.is_empty() {
        f64::NAN
    } else {
        let k = angles.len() / 2;
        *angles.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let range = |depth: &Grid<f64>| {
        let masked = depth.zip_map(&both, |z, &b| if b { *z } else { f64::NAN });
        depth_range(&masked).map_or(f64::NAN, |[near, far]| far - near)
    };
    Some(SingleComparison {
        rse_to_set: rse(1.0),
        rse_to_set_scaled: rse(k),
        scale_to_set: k,
        mean_normal_angle_deg: mean_angle,
        median_normal_angle_deg: median_angle,
        set_depth_range: range(set_depth),
        single_depth_range: range(single_depth),
        pixels: pairs.len(),
    })
}

/// The `q` quantile (0..1, nearest rank) of the finite positive values of
/// `grid` (a depth, an albedo); `None` when there is none.
pub fn positive_quantile(grid: &Grid<f64>, q: f64) -> Option<f64> {
    let mut values: Vec<f64> = grid
        .as_slice()
        .iter()
        .copied()
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// The 2nd to 98th percentile of a depth (`[near, far]`), the range the
/// reports quote; `None` without a depth.
pub fn depth_range(depth: &Grid<f64>) -> Option<[f64; 2]> {
    Some([
        positive_quantile(depth, 0.02)?,
        positive_quantile(depth, 0.98)?,
    ])
}

/// Unit normals of a depth map (camera frame, towards the camera) from
/// central differences of the log-depth where both neighbours are on the
/// surface (one-sided otherwise); NaN off it.
pub fn depth_normals(depth: &Grid<f64>, camera: Intrinsics) -> Grid<[f64; 3]> {
    let (w, h) = depth.size();
    let domain: Vec<bool> = depth
        .as_slice()
        .iter()
        .map(|z| z.is_finite() && *z > 0.0)
        .collect();
    let zeta: Vec<f64> = depth
        .as_slice()
        .iter()
        .map(|z| {
            if z.is_finite() && *z > 0.0 {
                z.ln()
            } else {
                0.0
            }
        })
        .collect();
    let f = camera.focal_px;
    Grid::from_fn(w, h, |c, r| {
        let p = r * w + c;
        if !domain[p] {
            return [f64::NAN; 3];
        }
        let g = gradient(&zeta, &domain, w, p);
        let (x, y) = camera.image_xy(c as f64, r as f64);
        let n = DVec3::new(f * g[0], f * g[1], -(1.0 + x * g[0] + y * g[1]));
        (n / n.length()).to_array()
    })
}
