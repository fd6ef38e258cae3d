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
}
