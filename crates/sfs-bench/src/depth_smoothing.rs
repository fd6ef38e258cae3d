//! The paper's post-processing (its Table 2, the `+post` rows), usable
//! with any method: smoothing of a depth map with the second-order
//! Charbonnier regulariser of the energy. The pre-processing (TV denoising)
//! is `sfs_core::denoise`. Only the benchmark uses it: the tool's own solves
//! never post-process.

use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::model::{PixelRay, Reflectance};
use sfs_core::params::{Alpha, DomainMode, InitialDepth, SolverParams, StepControl, Units};
use sfs_core::solver::{Problem, SolveError, solve_with_model};

/// The identity "reflectance" `R = z / scale`: with it the linearised solver
/// minimises `sum ((z0 - z) / scale)^2 + alpha sum Psi(S^2)`.
struct DepthFidelity {
    scale: f64,
}

impl Reflectance for DepthFidelity {
    fn radiance(&self, _ray: &PixelRay, depth: f64, _gx: f64, _gy: f64) -> f64 {
        depth / self.scale
    }

    fn radiance_with_partials(
        &self,
        _ray: &PixelRay,
        depth: f64,
        _gx: f64,
        _gy: f64,
    ) -> Option<[f64; 4]> {
        Some([depth / self.scale, 1.0 / self.scale, 0.0, 0.0])
    }
}

/// Smooths a depth map (NaN off the object) with the energy's regulariser:
/// the minimiser of `sum_object (z - z0)^2 + weight sum Psi(S^2)`, with the
/// energy's second-order Charbonnier term (`lambda` from `params`, read in
/// pixel units like `weight`), solved by the same linearised solver on the object pixels
/// only, started from `z0`.
///
/// # Errors
/// The solver's, e.g. when no pixel has a finite depth.
pub fn smooth_depth(
    depth: &Grid<f64>,
    camera: Intrinsics,
    weight: f64,
    params: &SolverParams,
) -> Result<Grid<f64>, SolveError> {
    let object = depth.map(|z| z.is_finite() && *z > 0.0);
    let largest = depth
        .as_slice()
        .iter()
        .filter(|z| z.is_finite())
        .fold(0.0f64, |a, &z| a.max(z.abs()));
    if largest <= 0.0 {
        return Err(SolveError::Input(
            "depth smoothing: the depth map has no finite positive value".into(),
        ));
    }
    // Keep the "image" below 1 so that it is not mistaken for saturation.
    let scale = 2.0 * largest;
    let image = depth.map(|&z| {
        if z.is_finite() && z > 0.0 {
            z / scale
        } else {
            0.0
        }
    });
    let problem = Problem {
        image,
        camera,
        intensity_scale: 1.0,
        object_mask: Some(object.clone()),
        confidence: None,
        lights: Vec::new(),
    };
    let smoothing = SolverParams {
        alpha: Alpha::Value(weight / (scale * scale)),
        units: Units::Paper,
        domain: DomainMode::Object,
        initial_depth: InitialDepth::Map(depth.clone()),
        step_control: StepControl::Backtracking,
        dz_limit: largest,
        kappa: params.kappa.max(10),
        kappa_max: params.kappa_max.max(10),
        ..params.clone()
    };
    // The solution's depth is already NaN off the object mask.
    let solution = solve_with_model(&problem, &smoothing, &DepthFidelity { scale }, &mut ())?;
    Ok(solution.depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use sfs_core::scene::{add_noise, sombrero::sombrero};

    #[test]
    fn depth_smoothing_removes_noise_and_keeps_the_shape() {
        let scene = sombrero(64, 64);
        let noisy = add_noise(&scene.depth_gt.map(|z| z / 4.0), 6.0, 2).map(|v| v * 4.0);
        let smoothed = smooth_depth(
            &noisy,
            Intrinsics::centred(64.0, 64, 64),
            100.0,
            &SolverParams::default(),
        )
        .expect("smoothing");
        let before = sfs_core::metrics::rse(&noisy, &scene.depth_gt).expect("sizes");
        let after = sfs_core::metrics::rse(&smoothed, &scene.depth_gt).expect("sizes");
        eprintln!("smoothing: RSE {before} -> {after}");
        assert!(after < 0.6 * before, "RSE {before} -> {after}");
    }
}
