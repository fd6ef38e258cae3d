//! Synthetic scenes with ground truth: the analytic Sombrero (METHOD.md
//! section 7) and OBJ meshes rendered in perspective, plus noise and
//! inpainting regions.

use crate::camera::Intrinsics;
use crate::grid::Grid;

pub mod mesh;
pub mod sombrero;

/// A synthetic scene: a noise-free linear image with its exact depth.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Short name, e.g. `sombrero` or the mesh file stem.
    pub name: String,
    /// Camera intrinsics at full resolution.
    pub camera: Intrinsics,
    /// Intensity scale `s` (albedo times light power) used to render the image.
    pub intensity_scale: f64,
    /// Linear image values `I` in [0, 1]; 0 on the background.
    pub image: Grid<f64>,
    /// Ground-truth Cartesian depth along the optical axis; NaN on the background.
    pub depth_gt: Grid<f64>,
    /// True where the pixel sees the object.
    pub object_mask: Grid<bool>,
    /// The lights it was rendered with (empty: one at the optical centre).
    pub lights: Vec<crate::light::PointLight>,
}

/// Adds Gaussian noise of standard deviation `sigma_255` (on the 0..255 scale)
/// to a linear image, seeded for reproducibility, and quantises the result to
/// 8 bits in [0, 1] (what `noisy8.png` stores). Background pixels get noise too,
/// as a camera would.
pub fn add_noise(image: &Grid<f64>, sigma_255: f64, seed: u64) -> Grid<f64> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    image.map(|&v| {
        let noisy = v * 255.0 + sigma_255 * rng.sample::<f64, _>(rand_distr::StandardNormal);
        noisy.round().clamp(0.0, 255.0) / 255.0
    })
}

/// A disc-shaped inpainting region for the paper's Fig. 3 case: confidence 0
/// inside the disc, 1 elsewhere. Centre and radius are fractions of the image
/// width and height (`centre_x`, `centre_y`) and of the smaller side (`radius`).
pub fn disc_confidence(
    width: usize,
    height: usize,
    centre_x: f64,
    centre_y: f64,
    radius: f64,
) -> Grid<f64> {
    let (cx, cy) = (centre_x * width as f64, centre_y * height as f64);
    let r = radius * width.min(height) as f64;
    Grid::from_fn(width, height, |c, row| {
        let (dx, dy) = (c as f64 + 0.5 - cx, row as f64 + 0.5 - cy);
        if dx * dx + dy * dy < r * r { 0.0 } else { 1.0 }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_seeded_and_has_the_requested_spread() {
        let image = Grid::filled(200, 200, 0.5);
        let a = add_noise(&image, 20.0, 7);
        assert_eq!(a, add_noise(&image, 20.0, 7));
        assert_ne!(a, add_noise(&image, 20.0, 8));
        let n = a.len() as f64;
        let mean = a.as_slice().iter().sum::<f64>() / n;
        let sd = (a.as_slice().iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt() * 255.0;
        assert!(
            (mean - 0.5).abs() < 0.005 && (sd - 20.0).abs() < 0.5,
            "{mean} {sd}"
        );
    }

    #[test]
    fn disc_covers_its_area() {
        let c = disc_confidence(100, 100, 0.5, 0.5, 0.2);
        let holes = c.as_slice().iter().filter(|&&v| v == 0.0).count() as f64;
        assert!(
            (holes - std::f64::consts::PI * 400.0).abs() < 40.0,
            "{holes}"
        );
    }
}
