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

mod compare;
mod finish;
mod held_out;
mod left_out;
mod level;
mod levels;
mod linear;
mod run;
mod set;
mod start;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::problem::{LevelReport, LevelResult, SolveError, SolveObserver, check_cancelled};
use crate::grid::Grid;
use crate::light::PointLight;
use crate::model::{Energy, LevelGeometry};
use finish::{FinishInfo, check_finite, finish};
use held_out::{HELD_OUT_SIDE, Snapshot, held_out_fits};
use left_out::{CastShadows, auto_robust_scale, cast_for, cast_shadows};
use level::{Level, MAX_PHOTOS, Observation, Scales, Shared};
use levels::{coarsen, finest_level, noise_sigma, reference_brightness, upsample};
use run::{FINE_SIDE, LevelRun, depth_grid, run_level};
use start::choose_start;

pub use compare::{
    SingleComparison, compare_single, depth_normals, depth_range, positive_quantile,
};
pub use level::{LEFT_OUT_OFF, LEFT_OUT_ROBUST, LEFT_OUT_SHADOW, LEFT_OUT_UNTRUSTED, USED};
pub use set::{
    LinearSolves, PhotoResult, PhotometricParams, PhotometricProblem, PhotometricSolution, SetPhoto,
};

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
    if let Some(size_error) = mask_size_error(problem, size) {
        return bad(size_error);
    }
    if let Some(message) = light_geometry_error(photos) {
        return bad(message);
    }
    if let Some((a, b, sine)) = most_similar_pair(problem) {
        return bad(format!(
            "{} and {} are the same photograph (they differ by {:.2} % of their brightness \
             beyond a common scale, under {:.0} %) although lit from {:?} and {:?}: a copy \
             under another name, or one light left on; each photograph of a set needs its \
             own light",
            photos[a].name,
            photos[b].name,
            100.0 * sine,
            100.0 * SAME_PHOTOGRAPH_DIFFERENCE,
            photos[a].light.position,
            photos[b].light.position
        ));
    }
    problem
        .camera
        .check_for(size.0, size.1)
        .map_err(SolveError::Input)?;
    Ok(())
}

/// Two lights of a set closer than this angle, seen from where the object
/// is expected, are one light: their photographs say the same.
pub const MIN_LIGHT_ANGLE_DEG: f64 = 0.25;
/// Three or more lights whose unit directions towards the object have a
/// smallest singular value below this share of their largest lie in one
/// plane with it (collinear lights): one component of the normal is not
/// seen. A ring of LEDs 10 degrees off the axis has about 0.12.
pub const MIN_LIGHT_SPREAD: f64 = 0.01;

/// Refuses a set whose lights cannot tell the normals apart, naming them:
/// two lights (nearly) in one direction, or three or more (nearly) in one
/// plane with the object. The object is expected on the optical axis at
/// twice the farthest light's distance from the camera (lights sit around
/// the camera or between it and the object); directions are judged from
/// there. These sets gave "the solve diverged".
fn light_geometry_error(photos: &[SetPhoto]) -> Option<String> {
    let positions: Vec<DVec3> = photos
        .iter()
        .map(|p| DVec3::from_array(p.light.position))
        .collect();
    let reach = positions.iter().map(|p| p.length()).fold(0.0, f64::max);
    if !(reach.is_finite() && reach > 0.0) {
        return None;
    }
    let object = DVec3::new(0.0, 0.0, 2.0 * reach);
    let directions: Vec<DVec3> = positions
        .iter()
        .map(|p| (*p - object).normalize_or_zero())
        .collect();
    for (k, a) in directions.iter().enumerate() {
        for (j, b) in directions[..k].iter().enumerate() {
            let angle = a.angle_between(*b).to_degrees();
            if angle < MIN_LIGHT_ANGLE_DEG {
                return Some(format!(
                    "the lights of {} (at {:?}) and {} (at {:?}) are {angle:.3} degrees apart \
                     seen from the object (under {MIN_LIGHT_ANGLE_DEG}): their photographs \
                     cannot tell the normals apart; each photograph of a set needs a light \
                     from a different direction",
                    photos[j].name,
                    photos[j].light.position,
                    photos[k].name,
                    photos[k].light.position
                ));
            }
        }
    }
    if directions.len() >= 3 {
        let m = directions.iter().fold(glam::DMat3::ZERO, |m, d| {
            m + glam::DMat3::from_cols(*d * d.x, *d * d.y, *d * d.z)
        });
        let (smallest, largest) = symmetric_eigen_range(&m);
        let spread = (smallest.max(0.0) / largest.max(1e-300)).sqrt();
        if spread < MIN_LIGHT_SPREAD {
            let names: Vec<String> = photos
                .iter()
                .map(|p| format!("{} (at {:?})", p.name, p.light.position))
                .collect();
            return Some(format!(
                "the lights of {} lie in one plane with the object (spread {spread:.4}, under \
                 {MIN_LIGHT_SPREAD}): one component of the normals is not seen; a set needs \
                 lights around the object's direction, not on one line",
                names.join(", ")
            ));
        }
    }
    None
}

/// The smallest and largest eigenvalue of a symmetric 3x3 matrix (the
/// trigonometric closed form).
fn symmetric_eigen_range(m: &glam::DMat3) -> (f64, f64) {
    let a = m.to_cols_array_2d();
    let p1 = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
    if p1 <= 0.0 {
        let d = [a[0][0], a[1][1], a[2][2]];
        let lo = d.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = d.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        return (lo, hi);
    }
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let p2 = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    let b = (*m - glam::DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    (smallest, largest)
}

/// The message when a mask is not the photographs' size.
fn mask_size_error(problem: &PhotometricProblem, size: (usize, usize)) -> Option<String> {
    if problem
        .object_mask
        .as_ref()
        .is_some_and(|m| m.size() != size)
        || problem
            .confidence
            .as_ref()
            .is_some_and(|m| m.size() != size)
    {
        return Some(format!(
            "the mask is not the photographs' size {}x{}",
            size.0, size.1
        ));
    }
    None
}

/// Two photographs of a set whose difference, after the best common scale
/// (`|b - k a| / |b|`, the sine of the angle between them as vectors over
/// the object pixels trusted in both), is below this share are one
/// photograph: a copy under another name, at another exposure, or the same
/// light twice. Lit from different places they are not: on the rendered
/// Sombrero (patch albedo) the standard LED rings' photographs differ by
/// 17 % or more, and lights only 1 degree apart (seen from the object) by
/// 2.8 %; an 8-bit copy's quantisation adds about 0.1 %. A copy solved the
/// set 12.8 degrees off (four copies: 48 degrees off, with residuals of
/// 0.000 that read as a perfect fit).
pub const SAME_PHOTOGRAPH_DIFFERENCE: f64 = 0.01;

/// Most pixels compared per pair of photographs (a regular sample of the
/// trusted object pixels).
const SAME_PHOTOGRAPH_SAMPLES: usize = 1 << 16;

/// The first pair `(earlier, later)` of photographs that differ by less
/// than [`SAME_PHOTOGRAPH_DIFFERENCE`] (see there) over the object pixels
/// both trust, with that difference; pairs with fewer than 16 such pixels
/// are not judged.
fn most_similar_pair(problem: &PhotometricProblem) -> Option<(usize, usize, f64)> {
    let photos = &problem.photos;
    let count = photos[0].image.as_slice().len();
    let set_trusted = |q: usize| {
        problem.object_mask.as_ref().is_none_or(|m| m.as_slice()[q])
            && problem
                .confidence
                .as_ref()
                .is_none_or(|c| c.as_slice()[q] > 0.0)
    };
    let stride = (count / SAME_PHOTOGRAPH_SAMPLES).max(1);
    let sample: Vec<usize> = (0..count)
        .step_by(stride)
        .filter(|&q| set_trusted(q))
        .collect();
    for (k, b) in photos.iter().enumerate() {
        for (j, a) in photos[..k].iter().enumerate() {
            let (mut aa, mut bb, mut ab, mut n) = (0.0, 0.0, 0.0, 0usize);
            for &q in &sample {
                if a.trusts(q) && b.trusts(q) {
                    let (x, y) = (
                        a.image.as_slice()[q].max(0.0),
                        b.image.as_slice()[q].max(0.0),
                    );
                    aa += x * x;
                    bb += y * y;
                    ab += x * y;
                    n += 1;
                }
            }
            if n < 16 || aa <= 0.0 || bb <= 0.0 {
                continue;
            }
            let sine = (1.0 - (ab * ab) / (aa * bb)).max(0.0).sqrt();
            if sine < SAME_PHOTOGRAPH_DIFFERENCE {
                return Some((j, k, sine));
            }
        }
    }
    None
}

/// Why a set has no trusted, lit object pixel in any photograph, named as
/// the single-image path names it: an empty object mask, no trusted
/// object pixel, every one saturated, or every photograph black there (an
/// ambient frame as bright as the photographs leaves nothing).
fn why_unlit(problem: &PhotometricProblem) -> String {
    let count = problem.photos[0].image.as_slice().len();
    let object = |q: usize| problem.object_mask.as_ref().is_none_or(|m| m.as_slice()[q]);
    let trusted = |q: usize| {
        object(q)
            && problem
                .confidence
                .as_ref()
                .is_none_or(|c| c.as_slice()[q] > 0.0)
    };
    if !(0..count).any(object) {
        return "the object mask is empty: no photograph has an object pixel to solve".into();
    }
    if !(0..count).any(trusted) {
        return "no pixel is both on the object and trusted (confidence > 0)".into();
    }
    if !problem
        .photos
        .iter()
        .any(|p| (0..count).any(|q| trusted(q) && p.trusts(q)))
    {
        return "every photograph is saturated or untrusted on every trusted object pixel: \
                lower the exposure or mask the saturated region (confidence 0)"
            .into();
    }
    "every photograph is black on every trusted object pixel: there is no shading to explain \
     (an --ambient frame as bright as the photographs takes all of their light away)"
        .into()
}

/// A photograph of a set with fewer than this many trusted object pixels
/// above [`unlit_level`] is refused as unlit: a black photograph (or one
/// whose light misses the object) was used, the fit came out 0.41 in RSE
/// instead of 0.007 and its residual NaN. A rim of a few pixels lit from
/// behind still counts as lit.
pub const MIN_LIT_PIXELS: usize = 4;

/// The value a pixel must exceed to be lit: five noise deviations (Gaussian
/// noise passes it once in 3 million pixels) and a thousandth of the set's
/// brightness (a render has no noise; a photograph a thousand times darker
/// than the others says nothing above their quantisation).
fn unlit_level(sigma: f64, brightness: f64) -> f64 {
    (5.0 * sigma).max(1e-3 * brightness)
}

/// The first photograph with fewer than [`MIN_LIT_PIXELS`] trusted object
/// pixels above [`unlit_level`], with its number of trusted object pixels;
/// a photograph with none trusted is left to the other checks.
fn unlit_photograph(level: &Level, sigma: f64, brightness: f64) -> Option<(usize, usize)> {
    let lit = unlit_level(sigma, brightness);
    level
        .images
        .iter()
        .zip(&level.weights)
        .enumerate()
        .find_map(|(j, (image, weights))| {
            let trusted = weights.iter().filter(|w| **w > 0.0).count();
            let above = image
                .iter()
                .zip(weights)
                .filter(|(v, w)| **w > 0.0 && **v > lit)
                .take(MIN_LIT_PIXELS)
                .count();
            (trusted > 0 && above < MIN_LIT_PIXELS).then_some((j, trusted))
        })
}

/// Automatic smoothness: `ALPHA_FLOOR + ALPHA_NOISE * (sigma / I_ref)^2`.
const ALPHA_FLOOR: f64 = 1e-7;
const ALPHA_NOISE: f64 = 1e-4;
/// Linearisations at most on a level above [`FINE_SIDE`].
const FINE_ITERATIONS: usize = 4;
/// Semi-calibrated: rounds of (shape, intensities) per coarse level.
const INTENSITY_ROUNDS: usize = 4;

/// The pyramid of a `width` x `height` set, finest first (the coarsest may
/// only choose the start: its result is streamed when it is the first
/// level solved).
pub fn level_sizes(width: usize, height: usize, params: &PhotometricParams) -> Vec<(usize, usize)> {
    super::pyramid::level_sizes(width, height, 0.5, params.min_side.max(3))
}

/// An object with fewer trusted pixels than this (20 x 20) at the working
/// size is small enough that resampling may have hidden a photograph's
/// light: the refusal of an unlit photograph says so.
const FEW_OBJECT_PIXELS: usize = 400;

/// Solves the set: depth, normals, albedo and each photograph's fit,
/// every level's depth to `observer` (its reprojection: the mean of the
/// photographs' predictions).
///
/// # Errors
/// A parameter out of its rule ([`PhotometricParams::validate`]), an
/// invalid set (see [`validate`]), no trusted observation, cancellation,
/// or a result that is not a surface.
pub fn solve_photometric(
    problem: &PhotometricProblem,
    params: &PhotometricParams,
    observer: &mut dyn SolveObserver,
) -> Result<PhotometricSolution, SolveError> {
    let start = Instant::now();
    params.validate()?;
    validate(problem)?;
    let (width, height) = problem.photos[0].image.size();
    let finest = finest_level(problem);
    let brightness =
        reference_brightness(&finest).ok_or_else(|| SolveError::Input(why_unlit(problem)))?;
    let sigma = noise_sigma(problem, &finest);
    let alpha = match params.alpha {
        Some(a) => a,
        None => ALPHA_FLOOR + ALPHA_NOISE * (sigma / brightness).powi(2),
    };
    // Dark: within three noise deviations of black, and at least 2 % of
    // the brightness (a render has no noise).
    let dark_level = (3.0 * sigma).max(0.02 * brightness);
    if let Some((j, trusted)) = unlit_photograph(&finest, sigma, brightness) {
        // On a few pixels (a small working size) a lit rim can vanish in
        // the resampling: say so rather than only blame the photograph.
        let few = if trusted < FEW_OBJECT_PIXELS {
            format!(
                "; at the working size {width}x{height} the object has only {trusted} trusted \
                 pixels, so a larger working size (--max-side) may show its light"
            )
        } else {
            String::new()
        };
        return Err(SolveError::Input(format!(
            "{}: no lit object pixel above the noise (fewer than {} of its {trusted} trusted \
             object pixels above {:.3e}): a black photograph, or its light does not reach the \
             object; leave it out of the set{few}",
            problem.photos[j].name,
            MIN_LIT_PIXELS,
            unlit_level(sigma, brightness)
        )));
    }
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
    let mut linear = LinearSolves::default();
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
    // The set's state on the finest level the held-out check runs on.
    let mut snapshot: Option<(usize, Snapshot)> = None;
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
        // Only the last solve of the level reports.
        let refits = if estimate_intensities && !fine {
            INTENSITY_ROUNDS
        } else {
            0
        };
        let mut refit = 0;
        let outcome = loop {
            let last = refit == refits;
            let result = run_level(
                level,
                &lights,
                &mut intensities,
                false,
                &level_cast,
                scales_at(scale),
                &mut zeta,
                &mut m,
                LevelRun {
                    report: how.report.filter(|_| last),
                    ..how
                },
                observer,
            )?;
            linear = linear.plus(result.linear);
            if last {
                break result;
            }
            let shared = Shared::new(&lights, &intensities, &level_cast, scales_at(scale));
            intensities = level.refit_intensities(&shared, &zeta, &m);
            refit += 1;
        };
        let (e, energies) = (outcome.energy, outcome.energies);
        iterations += outcome.steps;
        energy = e;
        if level.width.max(level.height) <= HELD_OUT_SIDE || snapshot.is_none() {
            snapshot = Some((
                index,
                Snapshot {
                    zeta: zeta.clone(),
                    m: m.clone(),
                    intensities: intensities.clone(),
                    cast: level_cast.clone(),
                    scales: scales_at(scale),
                },
            ));
        }
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
    let held_out_start = Instant::now();
    let held_out = match &snapshot {
        Some((index, state)) => held_out_fits(&levels_data[*index], &lights, state, observer)?,
        None => Vec::new(),
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
            linear,
            start,
            held_out,
            held_out_seconds: held_out_start.elapsed().as_secs_f64(),
        },
    );
    check_finite(&solution)?;
    Ok(solution)
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

/// What the user should know of a set's fit, in plain words (the command
/// line prints them, the viewer shows them): too few photographs to fix
/// the distance, a light that cannot light the object as solved, the
/// photograph that does not fit the set ([`misfit_warning`]), a photograph
/// barely used, estimated intensities far apart.
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
    warnings.extend(solution.light_warnings.iter().cloned());
    // The held-out check names the photograph the others contradict; the
    // whole-set misfit of another photograph is then the surface's
    // compromise with it (a doubled photograph in the probe's set left
    // another one the worst fit), and is left out.
    let held_out = held_out_judgement(solution);
    let misfit = misfit_warning(solution).filter(|misfit| {
        held_out
            .as_ref()
            .is_none_or(|(k, _)| misfit.starts_with(&format!("{} ", solution.photos[*k].name)))
    });
    warnings.extend(misfit);
    warnings.extend(held_out.map(|(_, warning)| warning));
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

/// The photograph of a set with the largest
/// [`misfit_ratio`](PhotoResult::misfit_ratio) does not fit the set when that
/// ratio is above this and its
/// [`systematic_misfit`](PhotoResult::systematic_misfit) above
/// [`MISFIT_FLOOR`]. Measured (docs/photometric-fit.md, 120 random
/// renders of the Sombrero and the shared meshes, 4 to 8 LEDs, noise 0 to
/// 2 %): no clean set of 57 warned (clean photographs with a ratio above 2
/// had misfits of at most 0.064, those with a misfit above 0.07 ratios of
/// at most 1.33); 57 of 63 faults (half exposure, a light moved by 0.3
/// units, a light behind the camera) were named, the misses all moved
/// lights the surface absorbed.
pub const MISFIT_RATIO: f64 = 2.0;
/// See [`MISFIT_RATIO`]: a smooth misfit of this share of a photograph's
/// brightness.
pub const MISFIT_FLOOR: f64 = 0.07;

/// The warning for the photograph of a set that its one surface and albedo
/// explain worst under its light as given, when it does not fit (see
/// [`MISFIT_RATIO`]), naming it and its light; `None` when every
/// photograph fits. One photograph at most: a wrong light bends the
/// surface, and the others' misfits rise with it, less; and none when a
/// light is already named as unable to light the object
/// ([`PhotometricSolution::light_warnings`]): that light bends the surface
/// (in the corpus, two of 16 lights behind the camera left another
/// photograph the worst fit).
pub fn misfit_warning(solution: &PhotometricSolution) -> Option<String> {
    if !solution.light_warnings.is_empty() {
        return None;
    }
    let worst = solution
        .photos
        .iter()
        .filter(|p| p.misfit_ratio.is_finite())
        .max_by(|a, b| a.misfit_ratio.total_cmp(&b.misfit_ratio))?;
    if !(worst.misfit_ratio > MISFIT_RATIO && worst.systematic_misfit > MISFIT_FLOOR) {
        return None;
    }
    let s = worst.light.position;
    Some(format!(
        "{} does not fit the set under its light (at ({:.3}, {:.3}, {:.3}), intensity {:.3}): \
         the set's surface and albedo miss its brightness by a smooth {:.1} % ({:.1}x the \
         other photographs' median); the light's position or intensity in the camera file, \
         or the photograph's exposure, is likely wrong",
        worst.name,
        s[0],
        s[1],
        s[2],
        worst.intensity,
        100.0 * worst.systematic_misfit,
        worst.misfit_ratio
    ))
}

/// A photograph whose [`held_out_scale`](PhotoResult::held_out_scale) is
/// above this or below its inverse is brighter or darker than the other
/// photographs predict under its light's intensity as given.
pub const HELD_OUT_SCALE: f64 = 1.3;
/// A photograph whose [`held_out_offset`](PhotoResult::held_out_offset)
/// is beyond this share of its brightness either way carries an offset
/// the other photographs lack.
pub const HELD_OUT_OFFSET: f64 = 0.05;
/// The photograph held out is suspected only when the others fit each
/// other without it ([`held_out_rest`](PhotoResult::held_out_rest)) at
/// most this share of the median of the same without each other
/// photograph: a fault raises every fit it is part of.
pub const HELD_OUT_REST_RATIO: f64 = 0.85;

/// The warning for the photograph of a set that the others contradict:
/// without it they fit each other best (its
/// [`held_out_rest`](PhotoResult::held_out_rest) the smallest, by
/// [`HELD_OUT_REST_RATIO`]), and what they predict of it misses by a scale
/// beyond [`HELD_OUT_SCALE`] (its intensity in the camera file or its
/// exposure) or an offset beyond [`HELD_OUT_OFFSET`] (an ambient frame or
/// black level only it has), whichever explains it better. One photograph
/// at most; no scale when the intensities were estimated (each
/// photograph's own then absorbs it); none when a light is already named
/// as unable to light the object.
pub fn held_out_warning(solution: &PhotometricSolution) -> Option<String> {
    held_out_judgement(solution).map(|(_, warning)| warning)
}

/// [`held_out_warning`] with the photograph's place in the set.
fn held_out_judgement(solution: &PhotometricSolution) -> Option<(usize, String)> {
    if !solution.light_warnings.is_empty() {
        return None;
    }
    let rests: Vec<f64> = solution.photos.iter().map(|p| p.held_out_rest).collect();
    let (k, photo) = solution
        .photos
        .iter()
        .enumerate()
        .filter(|(_, p)| p.held_out_rest.is_finite())
        .min_by(|a, b| a.1.held_out_rest.total_cmp(&b.1.held_out_rest))?;
    let ratio = finish::ratio_to_the_others(&rests, k);
    if ratio.is_nan() || ratio > HELD_OUT_REST_RATIO {
        return None;
    }
    if photo.held_out_offset_better {
        if photo.held_out_offset.is_nan() || photo.held_out_offset.abs() <= HELD_OUT_OFFSET {
            return None;
        }
        return Some((
            k,
            format!(
                "{} has an offset of {:+.2} of its brightness that the other photographs lack \
                 (they predict it under its light without it): an ambient light or a black \
                 level only it has; subtract its ambient frame or black level",
                photo.name, photo.held_out_offset
            ),
        ));
    }
    let scale = photo.held_out_scale;
    if solution.intensities_estimated || !(scale > 0.0 && scale.ln().abs() > HELD_OUT_SCALE.ln()) {
        return None;
    }
    let how = if scale > 1.0 {
        format!("{scale:.2}x brighter than")
    } else {
        format!("{scale:.2}x as bright as")
    };
    Some((
        k,
        format!(
            "{} is {how} the other photographs predict under its light's intensity as \
             given: its intensity in the camera file or its exposure may be wrong",
            photo.name
        ),
    ))
}
