//! `--reflectance auto`: the reflectance models compared on the image
//! (METHOD.md section 10), on a coarse working copy before the solve.
//!
//! Every candidate material is solved on the working copy at the user's
//! parameters and each solve's energy (data term plus smoothness: how well
//! a smooth surface of that material explains the image) and residual are
//! reported. The fit never decides: one photograph does not determine the
//! material. A shape absorbs almost any brightness-versus-slope curve, and
//! the energy is biased: a material that steepens the image's contrast (a
//! broad Blinn-Phong lobe) flattens the surface and lowers the energy of
//! any image. Measured on renders of known material (`bench --part
//! reflectance`), every rule tried called a wrong material determined on
//! some scene: the energy gain with a residual no worse (Blinn-Phong on
//! Lambertian Suzanne and Dragon renders, by 57 % at 64 px), the same
//! found again on a copy of two thirds the size (Suzanne), and a null test
//! against the same fit on the Lambertian solve's own image (the Dragon).
//! So the solve stays Lambertian and the report says which model fitted
//! best and by how much; the user chooses the model.

use std::time::Instant;

use super::problem::{Problem, SolveError, SolveObserver};
use super::working::{Forward, relative_residual, working_copy};
use crate::material::Material;
use crate::params::SolverParams;

/// Longest side of the working copy the candidates are solved on, pixels.
pub const FIT_SIDE: usize = 128;

pub use super::fits::{MaterialFit, MaterialTrial};

/// The candidates: every model of [`crate::material::MODELS`] that
/// `auto` tries, over its [`crate::material::Model::fit_grid`] (Lambert,
/// Oren-Nayar over its roughness, Blinn-Phong over its weight and
/// shininess).
pub fn candidates() -> Vec<Material> {
    crate::material::MODELS
        .iter()
        .flat_map(|model| model.fit_candidates())
        .collect()
}

/// Compares the candidate materials on `problem` at `params` (whose
/// reflectance is ignored) on a working copy of side [`FIT_SIDE`] (the
/// image's own when smaller).
///
/// # Errors
/// As [`super::solve`] (cancellation included).
pub fn fit_material(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<MaterialFit, SolveError> {
    let start = Instant::now();
    let (w, h) = problem.image.size();
    let side = w.max(h).min(FIT_SIDE);
    let work = working_copy(problem, side);
    let mut scored = Vec::new();
    for material in candidates() {
        let trial_params = params.clone().with_material(material);
        let solution = super::driver::solve(&work, &trial_params, &mut Forward(observer))?;
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
    let energy_gain = 1.0 - best.relative_energy / lambert.relative_energy;
    let summary = if best.material.is_lambert() {
        format!("of the models compared on a {side} px copy, Lambert explains the image best")
    } else {
        format!(
            "the image does not determine the material: on a {side} px copy {} fits best, \
             its energy {:.0} % below Lambert's (residual {:.4} against {:.4}), but such a \
             gain is found on Lambertian renders too (a shape absorbs the material); solved \
             as Lambertian. If you know the surface is rough or glossy, choose its model",
            best.material.describe(),
            100.0 * energy_gain,
            best.relative_residual,
            lambert.relative_residual
        )
    };
    Ok(MaterialFit {
        material: Material::Lambert,
        best: best.material,
        determined: false,
        energy_gain,
        trials,
        working_side: side,
        seconds: start.elapsed().as_secs_f64(),
        summary,
    })
}

/// `params` with `auto` resolved: the fit (when asked for) and the
/// parameters of the material it chose; `params` unchanged otherwise.
///
/// # Errors
/// As [`fit_material`].
pub fn resolve(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<(SolverParams, Option<MaterialFit>), SolveError> {
    if params.fixed_material().is_some() {
        return Ok((params.clone(), None));
    }
    let fit = fit_material(problem, params, observer)?;
    Ok((params.clone().with_material(fit.material), Some(fit)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The models' table gives the candidates the hand-written list gave,
    /// in its order (a fit's ranking and ties depend on it).
    #[test]
    fn the_candidates_are_the_former_list_in_its_order() {
        let mut former = vec![Material::Lambert];
        for roughness_rad in [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8] {
            former.push(Material::OrenNayar { roughness_rad });
        }
        for specular in [0.1, 0.3, 0.6, 1.0] {
            for shininess in [5.0, 10.0, 20.0, 40.0, 80.0] {
                former.push(Material::BlinnPhong {
                    specular,
                    shininess,
                });
            }
        }
        assert_eq!(candidates(), former);
    }
}
