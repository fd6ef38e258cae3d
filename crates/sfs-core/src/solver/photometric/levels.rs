//! The set's levels: the finest from the photographs, coarser ones by area
//! averaging, a per-pixel value brought to a finer level, and the
//! brightness and noise measured on the finest.

use rayon::prelude::*;

use super::level::Level;
use super::set::PhotometricProblem;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::resample::{resize_area, scale_intrinsics};

/// The finest level: the photographs with their weights.
pub(super) fn finest_level(problem: &PhotometricProblem) -> Level {
    let (w, h) = problem.photos[0].image.size();
    let domain: Vec<bool> = match &problem.object_mask {
        Some(mask) => mask.as_slice().to_vec(),
        None => vec![true; w * h],
    };
    // The photographs side by side (each one's values in its own order).
    let images = problem
        .photos
        .par_iter()
        .map(|p| p.image.as_slice().iter().map(|v| v.max(0.0)).collect())
        .collect();
    let weights = problem
        .photos
        .par_iter()
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
pub(super) fn coarsen(finer: &Level, w: usize, h: usize) -> Level {
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
        .par_iter()
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
        .par_iter()
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
pub(super) fn reference_brightness(level: &Level) -> Option<f64> {
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
pub(super) fn noise_sigma(problem: &PhotometricProblem, level: &Level) -> f64 {
    let (w, h) = (level.width, level.height);
    let mut sigmas: Vec<f64> = problem
        .photos
        .par_iter()
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

/// A per-pixel value of a coarser level brought to a finer one (bilinear
/// over the coarse domain).
pub(super) fn upsample(values: &[f64], coarse: &Level, fine: &Level) -> Vec<f64> {
    let grid = Grid::from_vec(coarse.width, coarse.height, values.to_vec())
        .unwrap_or_else(|| Grid::filled(coarse.width, coarse.height, 0.0));
    let coarse_domain = Grid::from_vec(coarse.width, coarse.height, coarse.domain.clone())
        .unwrap_or_else(|| Grid::filled(coarse.width, coarse.height, true));
    let fine_domain = Grid::from_vec(fine.width, fine.height, fine.domain.clone())
        .unwrap_or_else(|| Grid::filled(fine.width, fine.height, true));
    crate::solver::pyramid::upsample_depth(&grid, &coarse_domain, &fine_domain).into_vec()
}
