//! The end of a set's solve: depth, normals, albedo and each photograph's
//! fit at the finest level, and the check that the result is a surface.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::held_out::HeldOutFit;
use super::level::{LEFT_OUT_OFF, LEFT_OUT_ROBUST, LEFT_OUT_SHADOW, LEFT_OUT_UNTRUSTED, USED};
use super::level::{Level, MAX_PHOTOS, Observation, Shared};
use super::run::depth_grid;
use super::set::{PhotoResult, PhotometricProblem, PhotometricSolution};
use crate::grid::Grid;
use crate::light::lights_that_miss;
use crate::model::Energy;
use crate::solver::problem::{LevelReport, SolveError, depth_divergence};

/// What the solve gathered for its result.
pub(super) struct FinishInfo {
    pub(super) estimate_intensities: bool,
    pub(super) alpha: f64,
    pub(super) initial_depth: f64,
    pub(super) distances_tried: Vec<(f64, f64)>,
    pub(super) energy: Energy,
    pub(super) levels: Vec<LevelReport>,
    pub(super) iterations: usize,
    pub(super) linear: super::set::LinearSolves,
    pub(super) start: Instant,
    /// Each photograph predicted from the others (empty: not measured).
    pub(super) held_out: Vec<HeldOutFit>,
    /// The seconds that took.
    pub(super) held_out_seconds: f64,
}

/// Depth, normals, albedo and each photograph's fit at the finest level.
pub(super) fn finish(
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
    let s = problem.intensity_scale.unwrap_or(1.0);
    // Each pixel's normal and albedo (pixels in parallel).
    let (normal_values, albedo_values): (Vec<[f64; 3]>, Vec<f64>) = m
        .par_iter()
        .enumerate()
        .map(|(p, &m_p)| {
            if !level.domain[p] {
                return ([f64::NAN; 3], f64::NAN);
            }
            let mut obs = [Observation::default(); MAX_PHOTOS];
            let g = level.observe(shared, zeta, p, 0.0, &mut obs).g;
            let (x, y) = level.camera.image_xy((p % w) as f64, (p / w) as f64);
            let n = DVec3::new(f * g[0], f * g[1], -(1.0 + x * g[0] + y * g[1]));
            let length = n.length();
            if length > 0.0 && length.is_finite() {
                let albedo = if m_p > 0.0 {
                    m_p * length / s
                } else {
                    f64::NAN
                };
                ((n / length).to_array(), albedo)
            } else {
                ([f64::NAN; 3], f64::NAN)
            }
        })
        .unzip();
    let normals =
        Grid::from_vec(w, h, normal_values).unwrap_or_else(|| Grid::filled(w, h, [f64::NAN; 3]));
    let albedo =
        Grid::from_vec(w, h, albedo_values).unwrap_or_else(|| Grid::filled(w, h, f64::NAN));
    let per_pixel = level.residuals(shared, zeta, m);
    // Each photograph's fit (in parallel, read in order).
    let mut photos = problem
        .photos
        .par_iter()
        .enumerate()
        .map(|(j, photo)| {
            let mut residual = Grid::filled(w, h, f64::NAN);
            let mut left_out = Grid::filled(w, h, LEFT_OUT_OFF);
            let (mut counts, mut sum_r2, mut sum_i2) = ([0usize; 5], 0.0, 0.0);
            let (mut lit_r2, mut lit_i2) = (0.0, 0.0);
            for (p, observed) in per_pixel.iter().enumerate() {
                let (r, _, why) = observed[j];
                left_out.as_mut_slice()[p] = why;
                if level.domain[p] {
                    residual.as_mut_slice()[p] = -r;
                    counts[why as usize] += 1;
                    let i2 = level.images[j][p] * level.images[j][p];
                    if why == USED {
                        sum_r2 += r * r;
                        sum_i2 += i2;
                    }
                    if why == USED || why == LEFT_OUT_ROBUST {
                        lit_r2 += r * r;
                        lit_i2 += i2;
                    }
                }
            }
            let object = level.domain.iter().filter(|&&d| d).count().max(1) as f64;
            let lit_trusted = per_pixel.iter().enumerate().filter_map(|(p, observed)| {
                let (r, _, why) = observed[j];
                (level.domain[p] && (why == USED || why == LEFT_OUT_ROBUST)).then(|| {
                    let i = level.images[j][p];
                    let (u, v) = (
                        2.0 * (p % w) as f64 / w as f64 - 1.0,
                        2.0 * (p / w) as f64 / h as f64 - 1.0,
                    );
                    // r is prediction - I.
                    (i, i + r, u, v)
                })
            });
            let systematic_misfit = smooth_misfit(lit_trusted);
            let held_out = info.held_out.get(j).copied().unwrap_or(HeldOutFit::NONE);
            PhotoResult {
                name: photo.name.clone(),
                light: photo.light,
                intensity: shared.intensities[j],
                relative_residual: ratio_root(sum_r2, sum_i2),
                fit_residual: ratio_root(lit_r2, lit_i2),
                systematic_misfit,
                misfit_ratio: f64::NAN,
                held_out_scale: held_out.scale,
                held_out_offset: held_out.offset,
                held_out_rest: held_out.rest_residual,
                held_out_offset_better: held_out.offset_better,
                used_share: counts[USED as usize] as f64 / object,
                shadow_share: counts[LEFT_OUT_SHADOW as usize] as f64 / object,
                untrusted_share: counts[LEFT_OUT_UNTRUSTED as usize] as f64 / object,
                robust_share: counts[LEFT_OUT_ROBUST as usize] as f64 / object,
                residual,
                left_out,
            }
        })
        .collect::<Vec<PhotoResult>>();
    let misfits: Vec<f64> = photos.iter().map(|p| p.systematic_misfit).collect();
    for (j, photo) in photos.iter_mut().enumerate() {
        photo.misfit_ratio = ratio_to_the_others(&misfits, j);
    }
    let lights: Vec<_> = problem.photos.iter().map(|p| p.light).collect();
    let light_warnings = lights_that_miss(&lights, &depth, &level.camera)
        .into_iter()
        .map(|warning| {
            // The message names the light by its number from 1, the
            // photograph's place in the set.
            let named = problem
                .photos
                .iter()
                .enumerate()
                .find(|(k, _)| warning.starts_with(&format!("light {} ", k + 1)));
            match named {
                Some((_, photo)) => format!("{}: {warning}", photo.name),
                None => warning,
            }
        })
        .collect();
    PhotometricSolution {
        depth,
        normals,
        albedo,
        albedo_relative: problem.intensity_scale.is_none(),
        photos,
        light_warnings,
        intensities_estimated: info.estimate_intensities,
        alpha: info.alpha,
        robust_scale: shared.robust_scale / shared.brightness,
        brightness: shared.brightness,
        initial_depth: info.initial_depth,
        distances_tried: info.distances_tried,
        energy: info.energy,
        levels: info.levels,
        iterations: info.iterations,
        linear: info.linear,
        seconds: info.start.elapsed().as_secs_f64(),
        held_out_seconds: info.held_out_seconds,
    }
}

/// `sqrt(a / b)`, NaN unless `b > 0`.
fn ratio_root(a: f64, b: f64) -> f64 {
    if b > 0.0 { (a / b).sqrt() } else { f64::NAN }
}

/// The smooth part of a photograph's misfit, from its lit trusted
/// observations `(I, prediction, u, v)` (`u`, `v` the pixel's place across
/// the image, -1 to 1): the factor `a + b u + c v` that best scales the
/// prediction onto the photograph (least squares), and
/// `||prediction (a - 1 + b u + c v)|| / ||I||`. A light's intensity or
/// position other than the camera file says changes its photograph's
/// irradiance over the object by such a smooth factor (a scale, a slope
/// across it); noise and the model's local errors (creases, shadow edges)
/// scale nothing and fall out. NaN without an observation.
fn smooth_misfit(observations: impl Iterator<Item = (f64, f64, f64, f64)>) -> f64 {
    let mut normal = glam::DMat3::ZERO;
    let mut rhs = DVec3::ZERO;
    let (mut pp, mut ii) = (0.0, 0.0);
    for (i, p, u, v) in observations {
        let basis = DVec3::new(p, p * u, p * v);
        normal += glam::DMat3::from_cols(basis * basis.x, basis * basis.y, basis * basis.z);
        rhs += basis * i;
        pp += p * p;
        ii += i * i;
    }
    if !(pp > 0.0 && ii > 0.0) {
        return f64::NAN;
    }
    let determinant = normal.determinant();
    let factor = if determinant.abs() > 1e-12 * (pp * pp * pp) {
        normal.inverse() * rhs - DVec3::X
    } else {
        // Too few or too clustered observations for a slope: the scale.
        DVec3::new(rhs.x / pp - 1.0, 0.0, 0.0)
    };
    // ||P (factor . (1, u, v))||^2 as a quadratic form of the sums.
    let misfit2 = factor.dot(normal * factor).max(0.0);
    (misfit2 / ii).sqrt()
}

/// Photograph `j`'s value over the median of the others' (the mean of the
/// middle two for an even count); NaN when it or that median is not a
/// positive number.
pub(super) fn ratio_to_the_others(values: &[f64], j: usize) -> f64 {
    let mut others: Vec<f64> = values
        .iter()
        .enumerate()
        .filter(|&(k, r)| k != j && r.is_finite())
        .map(|(_, &r)| r)
        .collect();
    if others.is_empty() || !values[j].is_finite() {
        return f64::NAN;
    }
    others.sort_by(f64::total_cmp);
    let middle = others.len() / 2;
    let median = if others.len() % 2 == 1 {
        others[middle]
    } else {
        0.5 * (others[middle - 1] + others[middle])
    };
    if median > 0.0 {
        values[j] / median
    } else {
        f64::NAN
    }
}

/// Refuses a result that is not a surface (see
/// [`depth_divergence`]): a depth outside the range a file holds, or none
/// at all.
pub(super) fn check_finite(solution: &PhotometricSolution) -> Result<(), SolveError> {
    let values: Vec<f64> = solution
        .depth
        .as_slice()
        .iter()
        .copied()
        .filter(|z| !z.is_nan())
        .collect();
    match depth_divergence(&values) {
        Some(why) => Err(SolveError::Diverged(why)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A photograph at half the predicted brightness leaves a smooth misfit
    /// of its whole brightness, one brighter to the right a slope; a
    /// residual that alternates from pixel to pixel (noise) none to speak
    /// of.
    #[test]
    fn the_smooth_misfit_sees_a_scale_and_a_slope_but_not_noise() {
        let at = |k: usize| (k % 16) as f64 / 8.0 - 1.0;
        let grid = |k: usize| (at(k), at(k / 16));
        let halved = smooth_misfit((0..256).map(|k| {
            let (u, v) = grid(k);
            (0.5, 1.0, u, v)
        }));
        assert!((halved - 1.0).abs() < 1e-9, "{halved}");
        let sloped = smooth_misfit((0..256).map(|k| {
            let (u, v) = grid(k);
            (1.0 + 0.2 * u, 1.0, u, v)
        }));
        assert!(sloped > 0.05 && sloped < 0.2, "{sloped}");
        let noisy = smooth_misfit((0..256).map(|k| {
            let (u, v) = grid(k);
            (if (k + k / 16) % 2 == 0 { 1.1 } else { 0.9 }, 1.0, u, v)
        }));
        assert!(noisy < 0.01, "{noisy}");
    }

    /// The ratio is to the median of the others (the middle two's mean).
    #[test]
    fn the_ratio_is_to_the_others_median() {
        let values = [0.4, 0.1, 0.2, 0.3, f64::NAN];
        assert!((ratio_to_the_others(&values, 0) - 0.4 / 0.2).abs() < 1e-12);
        assert!((ratio_to_the_others(&values, 1) - 0.1 / 0.3).abs() < 1e-12);
        assert!(ratio_to_the_others(&values, 4).is_nan());
        assert!(ratio_to_the_others(&[0.1], 0).is_nan());
    }
}
