//! The end of a set's solve: depth, normals, albedo and each photograph's
//! fit at the finest level, and the check that the result is a surface.

use std::time::Instant;

use glam::DVec3;

use super::level::{LEFT_OUT_OFF, LEFT_OUT_ROBUST, LEFT_OUT_SHADOW, LEFT_OUT_UNTRUSTED, USED};
use super::level::{Level, MAX_PHOTOS, Observation, Shared};
use super::run::depth_grid;
use super::set::{PhotoResult, PhotometricProblem, PhotometricSolution};
use crate::grid::Grid;
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
    pub(super) start: Instant,
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
