//! Pre- and post-processing usable with any method (the paper's Table 2):
//! TV (ROF) denoising of the input image, and smoothing of a depth map with
//! the second-order Charbonnier regulariser of the energy.

use crate::grid::Grid;
use crate::model::Reflectance;
use crate::params::{DomainMode, InitialDepth, SolverParams, StepControl};
use crate::solver::{Problem, SolveError, solve_with_model};

/// Noise standard deviation of an image (same units as its values), by
/// Immerkaer's estimator ("Fast noise variance estimation", CVIU 1996): the
/// mean absolute response to the Laplacian difference mask
/// `[1 -2 1; -2 4 -2; 1 -2 1]`, which cancels smooth content, times
/// `sqrt(pi/2) / 6`.
pub fn estimate_noise_sigma(image: &Grid<f64>) -> f64 {
    let (w, h) = image.size();
    if w < 3 || h < 3 {
        return 0.0;
    }
    let z = |c: usize, r: usize| *image.at(c, r);
    let mut sum = 0.0;
    for r in 1..h - 1 {
        for c in 1..w - 1 {
            let v = z(c - 1, r - 1) - 2.0 * z(c, r - 1) + z(c + 1, r - 1) - 2.0 * z(c - 1, r)
                + 4.0 * z(c, r)
                - 2.0 * z(c + 1, r)
                + z(c - 1, r + 1)
                - 2.0 * z(c, r + 1)
                + z(c + 1, r + 1);
            sum += v.abs();
        }
    }
    (std::f64::consts::PI / 2.0).sqrt() * sum / (6.0 * ((w - 2) * (h - 2)) as f64)
}

/// TV (ROF) denoising: the minimiser of
/// `1/2 sum (u - f)^2 + weight sum |grad u|` (isotropic TV, forward
/// differences, Neumann boundary), by the accelerated primal-dual algorithm of
/// Chambolle and Pock (2011, Algorithm 2, the data term being 1-strongly
/// convex). `weight <= 0` returns the image unchanged.
pub fn tv_denoise(image: &Grid<f64>, weight: f64, iterations: usize) -> Grid<f64> {
    let (w, h) = image.size();
    if !(weight > 0.0 && weight.is_finite()) || w == 0 || h == 0 {
        return image.clone();
    }
    let f = image.as_slice();
    let n = w * h;
    let mut u = f.to_vec();
    let mut u_bar = u.clone();
    let (mut px, mut py) = (vec![0.0; n], vec![0.0; n]);
    // ||grad||^2 <= 8.
    let (mut tau, mut sigma) = (0.25f64, 0.5f64);
    for _ in 0..iterations {
        // Dual ascent and projection onto |p| <= weight.
        for r in 0..h {
            for c in 0..w {
                let q = r * w + c;
                let gx = if c + 1 < w {
                    u_bar[q + 1] - u_bar[q]
                } else {
                    0.0
                };
                let gy = if r + 1 < h {
                    u_bar[q + w] - u_bar[q]
                } else {
                    0.0
                };
                let (nx, ny) = (px[q] + sigma * gx, py[q] + sigma * gy);
                let scale = ((nx * nx + ny * ny).sqrt() / weight).max(1.0);
                px[q] = nx / scale;
                py[q] = ny / scale;
            }
        }
        // Primal descent: u = (u + tau div p + tau f) / (1 + tau).
        let theta = 1.0 / (1.0 + 2.0 * tau).sqrt();
        for r in 0..h {
            for c in 0..w {
                let q = r * w + c;
                let dx = if c + 1 < w { px[q] } else { 0.0 } - if c > 0 { px[q - 1] } else { 0.0 };
                let dy = if r + 1 < h { py[q] } else { 0.0 } - if r > 0 { py[q - w] } else { 0.0 };
                let new = (u[q] + tau * (dx + dy) + tau * f[q]) / (1.0 + tau);
                u_bar[q] = new + theta * (new - u[q]);
                u[q] = new;
            }
        }
        tau *= theta;
        sigma /= theta;
    }
    Grid::from_vec(w, h, u).unwrap_or_else(|| image.clone())
}

/// The default TV weight for an image: its estimated noise level
/// ([`estimate_noise_sigma`]).
pub fn default_tv_weight(image: &Grid<f64>) -> f64 {
    estimate_noise_sigma(image)
}

/// The identity "reflectance" `R = z / scale`: with it the linearised solver
/// minimises `sum ((z0 - z) / scale)^2 + alpha sum Psi(S^2)`.
struct DepthFidelity {
    scale: f64,
}

impl Reflectance for DepthFidelity {
    fn radiance(&self, _ray: &crate::model::PixelRay, depth: f64, _gx: f64, _gy: f64) -> f64 {
        depth / self.scale
    }

    fn radiance_with_partials(
        &self,
        _ray: &crate::model::PixelRay,
        depth: f64,
        _gx: f64,
        _gy: f64,
    ) -> Option<[f64; 4]> {
        Some([depth / self.scale, 1.0 / self.scale, 0.0, 0.0])
    }
}

/// Smooths a depth map (NaN off the object) with the energy's regulariser:
/// the minimiser of `sum_object (z - z0)^2 + weight sum Psi(S^2)`, with the
/// energy's second-order Charbonnier term (`lambda` from `params`, alpha in
/// pixel units), solved by the same linearised solver on the object pixels
/// only, started from `z0`.
///
/// # Errors
/// The solver's, e.g. when no pixel has a finite depth.
pub fn smooth_depth(
    depth: &Grid<f64>,
    camera: crate::camera::Intrinsics,
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
    };
    let smoothing = SolverParams {
        alpha: weight / (scale * scale),
        domain: DomainMode::Object,
        initial_depth: InitialDepth::Map(depth.clone()),
        step_control: StepControl::Backtracking,
        dz_limit: largest,
        kappa: params.kappa.max(10),
        ..params.clone()
    };
    // The solution's depth is already NaN off the object mask.
    let solution = solve_with_model(&problem, &smoothing, &DepthFidelity { scale }, &mut ())?;
    Ok(solution.depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::scene::{add_noise, sombrero::sombrero};

    #[test]
    fn noise_estimate_finds_the_added_noise() {
        let scene = sombrero(128, 128);
        let noisy = add_noise(&scene.image, 20.0, 5);
        let sigma = estimate_noise_sigma(&noisy) * 255.0;
        assert!((sigma - 20.0).abs() < 2.0, "estimated {sigma}");
        assert!(estimate_noise_sigma(&scene.image) * 255.0 < 1.0);
    }

    #[test]
    fn tv_denoising_brings_a_noisy_image_closer_to_the_clean_one() {
        let scene = sombrero(96, 96);
        let noisy = add_noise(&scene.image, 20.0, 9);
        let error = |g: &Grid<f64>| {
            g.as_slice()
                .iter()
                .zip(scene.image.as_slice())
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let denoised = tv_denoise(&noisy, default_tv_weight(&noisy), 200);
        assert!(
            error(&denoised) < 0.5 * error(&noisy),
            "{} -> {}",
            error(&noisy),
            error(&denoised)
        );
        assert_eq!(tv_denoise(&noisy, 0.0, 10), noisy);
    }

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
        let before = crate::metrics::rse(&noisy, &scene.depth_gt).expect("sizes");
        let after = crate::metrics::rse(&smoothed, &scene.depth_gt).expect("sizes");
        eprintln!("smoothing: RSE {before} -> {after}");
        assert!(after < 0.6 * before, "RSE {before} -> {after}");
    }
}
