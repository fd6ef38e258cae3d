//! `--reflectance auto`: the material fitted to the image (METHOD.md
//! section 10) on a coarse working copy, before the solve.
//!
//! Every candidate material is solved on the working copy at the user's
//! parameters; each solve's energy (data term plus smoothness, the model's
//! own measure of how well a smooth surface of that material explains the
//! image) is compared. With the light at the camera a shape can absorb much
//! of any brightness-versus-slope curve, so the image often says little:
//! the fit reports every candidate's energy and residual and calls the
//! winner *determined* only when it beats Lambert clearly in energy and is
//! no worse in residual ([`DETERMINED_GAIN`]); otherwise Lambert is kept.

use std::time::Instant;

use serde::Serialize;

use super::calibrate::{Forward, working_copy};
use super::problem::{Problem, SolveError, SolveObserver};
use crate::material::Material;
use crate::params::SolverParams;

/// Longest side of the working copy the candidates are solved on, pixels.
pub const FIT_SIDE: usize = 128;

/// The best candidate is called determined when its energy is at most this
/// share of Lambert's and its data residual is no larger than Lambert's: a
/// smoother surface explains the image at least as well. A lower energy
/// alone is no evidence: a material that steepens the image's contrast
/// (a broad Blinn-Phong lobe) always flattens the surface a little, and
/// won by 2-6 % on Lambertian renders.
pub const DETERMINED_GAIN: f64 = 0.85;

/// One candidate of the fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MaterialTrial {
    /// The material solved.
    pub material: Material,
    /// The solve's final energy on the working copy (relative to the
    /// best candidate's: 1 for the best).
    pub relative_energy: f64,
    /// `sqrt(sum c (I - R)^2 / sum c I^2)` of that solve.
    pub relative_residual: f64,
}

/// What `--reflectance auto` found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaterialFit {
    /// The material the solve used: the best candidate when determined,
    /// Lambert otherwise.
    pub material: Material,
    /// The best candidate, determined or not.
    pub best: Material,
    /// True when the image told the best candidate apart (see the module).
    pub determined: bool,
    /// Every candidate, best first.
    pub trials: Vec<MaterialTrial>,
    /// Side of the working copy, pixels.
    pub working_side: usize,
    /// Seconds the fit took.
    pub seconds: f64,
    /// The finding in one sentence.
    pub summary: String,
}

/// The candidates: Lambert, Oren-Nayar over its roughness and Blinn-Phong
/// over its weight and shininess.
pub fn candidates() -> Vec<Material> {
    let mut out = vec![Material::Lambert];
    for roughness_rad in [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8] {
        out.push(Material::OrenNayar { roughness_rad });
    }
    for specular in [0.1, 0.3, 0.6, 1.0] {
        for shininess in [5.0, 10.0, 20.0, 40.0, 80.0] {
            out.push(Material::BlinnPhong {
                specular,
                shininess,
            });
        }
    }
    out
}

/// Fits the material of `problem` at `params` (whose reflectance is
/// ignored) on a working copy of side [`FIT_SIDE`].
///
/// # Errors
/// As [`super::solve`] (cancellation included).
pub fn fit_material(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<MaterialFit, SolveError> {
    let start = Instant::now();
    let work = working_copy(problem, FIT_SIDE);
    let working_side = work.image.width().max(work.image.height());
    let mut scored = Vec::new();
    for material in candidates() {
        let trial_params = params.clone().with_material(material);
        let solution = super::solve(&work, &trial_params, &mut Forward(observer))?;
        let residual = relative_residual(&work, &solution);
        scored.push((material, solution.final_energy.total, residual));
    }
    scored.sort_by(|a, b| a.1.total_cmp(&b.1));
    let best_energy = scored[0].1.max(f64::MIN_POSITIVE);
    let trials: Vec<MaterialTrial> = scored
        .iter()
        .map(|&(material, energy, relative_residual)| MaterialTrial {
            material,
            relative_energy: energy / best_energy,
            relative_residual,
        })
        .collect();
    let best = trials[0];
    let lambert = trials
        .iter()
        .find(|t| t.material.is_lambert())
        .copied()
        .unwrap_or(best);
    // Determined: a smoother surface explains the image at least as well.
    let determined = !best.material.is_lambert()
        && best.relative_energy <= DETERMINED_GAIN * lambert.relative_energy
        && best.relative_residual <= lambert.relative_residual;
    let material = if determined {
        best.material
    } else {
        Material::Lambert
    };
    let gain = 100.0 * (1.0 - 1.0 / lambert.relative_energy);
    let summary = if best.material.is_lambert() {
        "the image is explained best as Lambertian".to_string()
    } else if determined {
        format!(
            "fitted {}: its energy is {gain:.0} % below Lambert's, its residual {:.4} \
             against {:.4} (the candidates are a grid: roughness in steps of 0.1 rad, \
             shininess in factors of 2)",
            best.material.describe(),
            best.relative_residual,
            lambert.relative_residual
        )
    } else {
        format!(
            "the image does not determine the material: {} fits best, but its energy is \
             only {gain:.0} % below Lambert's (residual {:.4} against {:.4}); solved as \
             Lambertian. If you know the surface is rough or glossy, choose its model",
            best.material.describe(),
            best.relative_residual,
            lambert.relative_residual
        )
    };
    Ok(MaterialFit {
        material,
        best: best.material,
        determined,
        trials,
        working_side,
        seconds: start.elapsed().as_secs_f64(),
        summary,
    })
}

/// `sqrt(sum c (I - R)^2 / sum c I^2)` over the solved pixels.
fn relative_residual(problem: &Problem, solution: &super::Solution) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for q in 0..problem.image.len() {
        if !solution.depth.as_slice()[q].is_finite() {
            continue;
        }
        let c = problem.confidence.as_ref().map_or(1.0, |c| c.as_slice()[q]);
        let (i, r) = (
            problem.image.as_slice()[q],
            solution.reprojection.as_slice()[q],
        );
        num += c * (i - r) * (i - r);
        den += c * i * i;
    }
    (num / den.max(f64::MIN_POSITIVE)).sqrt()
}
