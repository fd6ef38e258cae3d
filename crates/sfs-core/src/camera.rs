//! Pinhole camera intrinsics in pixel units (METHOD.md section 1).

use serde::{Deserialize, Serialize};

/// Pinhole intrinsics at full image resolution, all in pixels.
///
/// Pixel (column `i`, row `j`) has image-plane coordinates
/// `x = i - principal_x_px`, `y = j - principal_y_px`; the surface point of a
/// pixel with depth `z` is `(z x / f, z y / f, z)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length `f` in pixels.
    pub focal_px: f64,
    /// Principal point column `cx` in pixels.
    pub principal_x_px: f64,
    /// Principal point row `cy` in pixels.
    pub principal_y_px: f64,
}

impl Intrinsics {
    /// Intrinsics with the default principal point `((width-1)/2, (height-1)/2)`.
    pub fn centred(focal_px: f64, width: usize, height: usize) -> Self {
        Self {
            focal_px,
            principal_x_px: (width as f64 - 1.0) / 2.0,
            principal_y_px: (height as f64 - 1.0) / 2.0,
        }
    }

    /// Image-plane coordinates `(x, y)` of pixel centre `(column, row)`.
    #[inline]
    pub fn image_xy(&self, column: f64, row: f64) -> (f64, f64) {
        (column - self.principal_x_px, row - self.principal_y_px)
    }

    /// The camera-space point (same length unit as `depth`) of a pixel at
    /// image-plane coordinates `(x, y)` with Cartesian depth `depth`.
    #[inline]
    pub fn back_project(&self, x: f64, y: f64, depth: f64) -> [f64; 3] {
        [depth * x / self.focal_px, depth * y / self.focal_px, depth]
    }

    /// Horizontal field of view in degrees for an image `width_px` wide.
    pub fn horizontal_fov_deg(&self, width_px: usize) -> f64 {
        2.0 * (width_px as f64 / (2.0 * self.focal_px))
            .atan()
            .to_degrees()
    }
}
