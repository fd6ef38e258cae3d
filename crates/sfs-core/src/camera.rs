//! Pinhole camera intrinsics in pixel units (METHOD.md section 1).

use serde::{Deserialize, Serialize};

/// The smallest focal length, as a share of the image's longest side: below
/// it the field of view nears 180 degrees, which the model cannot represent
/// (a focal length of 1e-300 solved to an all-zero depth).
pub const MIN_FOCAL_PER_SIDE: f64 = 1e-3;

/// How far outside the image the principal point may lie, in image sides:
/// `cx` in `[-k W, (1 + k) W]`, `cy` in `[-k H, (1 + k) H]`. A real lens
/// (even a shifted tilt-shift one, or a crop far from the sensor's centre)
/// keeps it within a few sides; `--cy 1e8` put every pixel at the same
/// huge image-plane coordinate and solved to a constant depth of 1e-6
/// (`1e100`: an all-zero depth) without a word.
pub const MAX_PRINCIPAL_OFFSET_SIDES: f64 = 10.0;

/// The largest focal length, as a multiple of the image's longest side:
/// above it the field of view is below 0.006 degrees, an orthographic
/// camera the perspective model only reaches by underflow.
pub const MAX_FOCAL_PER_SIDE: f64 = 1e4;

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

    /// Checks the intrinsics for a `width` x `height` image: a focal length
    /// in `[MIN_FOCAL_PER_SIDE, MAX_FOCAL_PER_SIDE]` times the longest side
    /// (see [`MIN_FOCAL_PER_SIDE`],
    /// [`MAX_FOCAL_PER_SIDE`]) and a principal point within
    /// [`MAX_PRINCIPAL_OFFSET_SIDES`] of the image. The message names the
    /// value (`focal`, `cx`, `cy`) and the range.
    ///
    /// # Errors
    /// The first value out of its range, in words.
    pub fn check_for(&self, width: usize, height: usize) -> Result<(), String> {
        let side = width.max(height).max(1) as f64;
        let (f_min, f_max) = (MIN_FOCAL_PER_SIDE * side, MAX_FOCAL_PER_SIDE * side);
        let f = self.focal_px;
        if !(f.is_finite() && f >= f_min && f <= f_max) {
            return Err(format!(
                "focal length {f:e} px is outside [{f_min:e}, {f_max:e}] px for a \
                 {width}x{height} image ({} to {MAX_FOCAL_PER_SIDE:e} times its longest side)",
                MIN_FOCAL_PER_SIDE
            ));
        }
        let k = MAX_PRINCIPAL_OFFSET_SIDES;
        for (key, v, extent) in [
            ("cx", self.principal_x_px, width as f64),
            ("cy", self.principal_y_px, height as f64),
        ] {
            let (lo, hi) = (-k * extent, (1.0 + k) * extent);
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(format!(
                    "principal point {key} = {v:e} px is outside [{lo}, {hi}] px for a \
                     {width}x{height} image (at most {k} image sides beyond its edge)"
                ));
            }
        }
        Ok(())
    }

    /// Horizontal field of view in degrees for an image `width_px` wide.
    pub fn horizontal_fov_deg(&self, width_px: usize) -> f64 {
        2.0 * (width_px as f64 / (2.0 * self.focal_px))
            .atan()
            .to_degrees()
    }
}
