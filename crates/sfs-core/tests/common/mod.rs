//! What the symmetry tests share.

use sfs_core::grid::Grid;

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
