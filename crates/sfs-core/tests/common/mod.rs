//! What the symmetry tests share.

use sfs_core::grid::Grid;
use sfs_core::light::PointLight;
use sfs_core::scene::Scene;
use sfs_core::solver::Problem;

/// Round-off only: the solver computes in f64 with an f32 SOR.
pub const ROUND_OFF: f64 = 1e-4;

/// Largest relative difference between `depth` times `factor` and `reference`.
pub fn largest_relative_difference(depth: &Grid<f64>, factor: f64, reference: &Grid<f64>) -> f64 {
    depth
        .as_slice()
        .iter()
        .zip(reference.as_slice())
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (a * factor - b).abs() / b.abs())
        .fold(0.0, f64::max)
}

/// The problem of `scene`'s camera and object mask with `image`, its
/// intensity scale and `lights` (no confidence map).
pub fn problem(
    scene: &Scene,
    image: Grid<f64>,
    intensity_scale: f64,
    lights: &[PointLight],
) -> Problem {
    Problem {
        image,
        camera: scene.camera,
        intensity_scale,
        object_mask: Some(scene.object_mask.clone()),
        confidence: None,
        lights: lights.to_vec(),
    }
}
