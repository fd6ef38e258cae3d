//! The image-formation model and the discrete energy (METHOD.md sections 1-3):
//! reflectance, upwind derivatives, the residual `D`, its derivatives, the
//! Charbonnier smoothness term and the reprojection of a depth map.
//!
//! Everything here is a pure function of its arguments; the solver builds on it.

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Grid, Weights};

/// Where a pixel sits on the image plane at some pyramid level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelRay {
    /// Image-plane x of the pixel centre, full-resolution pixels.
    pub x_px: f64,
    /// Image-plane y of the pixel centre, full-resolution pixels.
    pub y_px: f64,
    /// Focal length, pixels.
    pub focal_px: f64,
}

impl PixelRay {
    /// `Q(x) = f / sqrt(|x|^2 + f^2)`: cosine of the angle between the ray and
    /// the optical axis.
    #[inline]
    pub fn q(&self) -> f64 {
        self.focal_px
            / (self.x_px * self.x_px + self.y_px * self.y_px + self.focal_px * self.focal_px).sqrt()
    }
}

/// A reflectance model: the predicted image value of a surface point given by
/// its depth and depth gradient (paper contribution (ii): any model plugs in).
pub trait Reflectance: Sync {
    /// Predicted linear image value at `ray` for Cartesian depth `depth` and
    /// depth gradient `(dz_dx, dz_dy)` (depth units per full-resolution pixel).
    fn radiance(&self, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64;

    /// The radiance and its exact partial derivatives
    /// `[R, dR/dz, dR/dzx, dR/dzy]`, if the model provides them. Models that
    /// return `None` can only be solved with numeric derivatives.
    fn radiance_with_partials(
        &self,
        _ray: &PixelRay,
        _depth: f64,
        _dz_dx: f64,
        _dz_dy: f64,
    ) -> Option<[f64; 4]> {
        None
    }
}

/// Lambertian surface lit by a point light at the optical centre with 1/r^2
/// fall-off: `R = s Q^3 / (z W)`, `W = sqrt(f^2 |grad z|^2 + (grad z . x + z)^2)`
/// (paper Eq. 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambertian {
    /// Intensity scale `s` (albedo times light power).
    pub intensity_scale: f64,
}

impl Lambertian {
    #[inline]
    fn parts(ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> (f64, f64) {
        let t = dz_dx * ray.x_px + dz_dy * ray.y_px + depth;
        let f2 = ray.focal_px * ray.focal_px;
        let w2 = f2 * (dz_dx * dz_dx + dz_dy * dz_dy) + t * t;
        (t, w2)
    }
}

impl Reflectance for Lambertian {
    #[inline]
    fn radiance(&self, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64 {
        let (_, w2) = Self::parts(ray, depth, dz_dx, dz_dy);
        let q = ray.q();
        self.intensity_scale * q * q * q / (depth * w2.sqrt())
    }

    #[inline]
    fn radiance_with_partials(
        &self,
        ray: &PixelRay,
        depth: f64,
        dz_dx: f64,
        dz_dy: f64,
    ) -> Option<[f64; 4]> {
        let (t, w2) = Self::parts(ray, depth, dz_dx, dz_dy);
        let q = ray.q();
        let r = self.intensity_scale * q * q * q / (depth * w2.sqrt());
        let f2 = ray.focal_px * ray.focal_px;
        let d_dz = -r * (1.0 / depth + t / w2);
        let d_dzx = -r * (f2 * dz_dx + t * ray.x_px) / w2;
        let d_dzy = -r * (f2 * dz_dy + t * ray.y_px) / w2;
        Some([r, d_dz, d_dzx, d_dzy])
    }
}

/// Which one-sided difference the upwind scheme picked along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Branch {
    /// Backward difference `(z(x) - z(x-h)) / h`.
    Backward,
    /// Forward difference `(z(x+h) - z(x)) / h`.
    Forward,
    /// Zero derivative.
    Zero,
}

/// Upwind choice along one axis (paper Eqs. 9-11) with the neighbours that
/// exist (inside the image and, in object mode, on the object).
///
/// With both neighbours: `m = max(D- z, -D+ z, 0)`, the backward difference if
/// `m = D- z > 0`, the forward one (sign restored) if `m = -D+ z > 0`, else 0.
/// With only one neighbour the inner one-sided difference is used whatever its
/// sign: dropping it would give the pixel a false zero slope (METHOD.md
/// section 8). With none the derivative is 0.
#[inline]
pub fn upwind(minus: Option<f64>, centre: f64, plus: Option<f64>, spacing: f64) -> (Branch, f64) {
    match (minus, plus) {
        (Some(m), Some(p)) => {
            let backward = (centre - m) / spacing;
            let forward = (p - centre) / spacing;
            if backward > 0.0 && backward >= -forward {
                (Branch::Backward, backward)
            } else if -forward > 0.0 {
                (Branch::Forward, forward)
            } else {
                (Branch::Zero, 0.0)
            }
        }
        (Some(m), None) => (Branch::Backward, (centre - m) / spacing),
        (None, Some(p)) => (Branch::Forward, (p - centre) / spacing),
        (None, None) => (Branch::Zero, 0.0),
    }
}

/// The derivative along one axis for a frozen branch.
#[inline]
pub fn one_sided(branch: Branch, minus: f64, centre: f64, plus: f64, spacing: f64) -> f64 {
    match branch {
        Branch::Backward => (centre - minus) / spacing,
        Branch::Forward => (plus - centre) / spacing,
        Branch::Zero => 0.0,
    }
}

/// The 5-point neighbourhood of a pixel: depth values and which neighbours
/// exist. Missing neighbours carry the centre value (never read).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbourhood {
    /// Depth at the pixel.
    pub centre: f64,
    /// Depth at `(i-1, j)`, if that pixel is in the domain.
    pub left: Option<f64>,
    /// Depth at `(i+1, j)`, if in the domain.
    pub right: Option<f64>,
    /// Depth at `(i, j-1)`, if in the domain.
    pub up: Option<f64>,
    /// Depth at `(i, j+1)`, if in the domain.
    pub down: Option<f64>,
}

/// Upwind branches of a pixel along x and y, frozen for linearisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Branches {
    /// Branch along x.
    pub x: Branch,
    /// Branch along y.
    pub y: Branch,
}

/// Grid spacings of a pyramid level, in full-resolution pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spacing {
    /// `hx`.
    pub x: f64,
    /// `hy`.
    pub y: f64,
}

impl Neighbourhood {
    /// Upwind branches and the gradient `(dz/dx, dz/dy)` at the current values.
    #[inline]
    pub fn upwind(&self, h: Spacing) -> (Branches, f64, f64) {
        let (bx, gx) = upwind(self.left, self.centre, self.right, h.x);
        let (by, gy) = upwind(self.up, self.centre, self.down, h.y);
        (Branches { x: bx, y: by }, gx, gy)
    }

    /// The values `[centre, left, right, up, down]`, missing ones replaced by
    /// the centre value.
    #[inline]
    pub fn values(&self) -> [f64; 5] {
        let c = self.centre;
        [
            c,
            self.left.unwrap_or(c),
            self.right.unwrap_or(c),
            self.up.unwrap_or(c),
            self.down.unwrap_or(c),
        ]
    }
}

/// Indices into a 5-point stencil `[centre, left, right, up, down]`.
pub mod slot {
    /// The pixel itself.
    pub const CENTRE: usize = 0;
    /// `(i-1, j)`.
    pub const LEFT: usize = 1;
    /// `(i+1, j)`.
    pub const RIGHT: usize = 2;
    /// `(i, j-1)`.
    pub const UP: usize = 3;
    /// `(i, j+1)`.
    pub const DOWN: usize = 4;
}

/// Gradient of 5 stencil values `[c, l, r, u, d]` for frozen branches.
#[inline]
pub fn frozen_gradient(values: &[f64; 5], branches: Branches, h: Spacing) -> (f64, f64) {
    (
        one_sided(branches.x, values[1], values[0], values[2], h.x),
        one_sided(branches.y, values[3], values[0], values[4], h.y),
    )
}

/// Residual `D = I - R(z, grad z)` with frozen branches.
#[inline]
pub fn residual<M: Reflectance + ?Sized>(
    model: &M,
    ray: &PixelRay,
    image_value: f64,
    values: &[f64; 5],
    branches: Branches,
    h: Spacing,
) -> f64 {
    let (gx, gy) = frozen_gradient(values, branches, h);
    image_value - model.radiance(ray, values[0], gx, gy)
}

/// Adds the chain rule of one axis to `jac` (derivatives of `D = I - R`):
/// `r_g_over_h` is `dR/dz_axis / h_axis`; a backward difference depends on the
/// pixel and its `minus` neighbour, a forward one on the pixel and its `plus`
/// neighbour.
#[inline]
fn add_axis(jac: &mut [f64; 5], branch: Branch, r_g_over_h: f64, minus: usize, plus: usize) {
    match branch {
        Branch::Backward => {
            jac[slot::CENTRE] -= r_g_over_h;
            jac[minus] = r_g_over_h;
        }
        Branch::Forward => {
            jac[slot::CENTRE] += r_g_over_h;
            jac[plus] = -r_g_over_h;
        }
        Branch::Zero => {}
    }
}

/// How the derivatives of `D` with respect to the stencil depths are computed.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Derivatives {
    /// Exact derivatives from [`Reflectance::radiance_with_partials`].
    Exact,
    /// Central differences, perturbing each stencil depth by `+-h_z` with the
    /// upwind branches frozen (the paper's choice, `h_z = 1e-12`).
    Numeric {
        /// Perturbation `h_z` in depth units.
        h_z: f64,
    },
}

/// Residual `D` and its derivatives `dD/dz_q` for the 5 stencil slots
/// `[centre, left, right, up, down]`, with the branches frozen. Slots whose
/// difference is not used get 0.
///
/// Returns `None` when the model has no exact derivatives and `Exact` was asked.
#[inline]
pub fn residual_and_jacobian<M: Reflectance + ?Sized>(
    model: &M,
    ray: &PixelRay,
    image_value: f64,
    values: &[f64; 5],
    branches: Branches,
    h: Spacing,
    derivatives: Derivatives,
) -> Option<(f64, [f64; 5])> {
    match derivatives {
        Derivatives::Exact => {
            let (gx, gy) = frozen_gradient(values, branches, h);
            let [r, r_z, r_gx, r_gy] = model.radiance_with_partials(ray, values[0], gx, gy)?;
            let mut jac = [0.0; 5];
            // D = I - R: every derivative carries a minus sign.
            jac[slot::CENTRE] = -r_z;
            add_axis(&mut jac, branches.x, r_gx / h.x, slot::LEFT, slot::RIGHT);
            add_axis(&mut jac, branches.y, r_gy / h.y, slot::UP, slot::DOWN);
            Some((image_value - r, jac))
        }
        Derivatives::Numeric { h_z } => {
            let d = residual(model, ray, image_value, values, branches, h);
            let mut jac = [0.0; 5];
            let used = [
                true,
                branches.x == Branch::Backward,
                branches.x == Branch::Forward,
                branches.y == Branch::Backward,
                branches.y == Branch::Forward,
            ];
            for (k, slot_jac) in jac.iter_mut().enumerate() {
                if !used[k] {
                    continue;
                }
                let mut plus = *values;
                plus[k] += h_z;
                let mut minus = *values;
                minus[k] -= h_z;
                let d_plus = residual(model, ray, image_value, &plus, branches, h);
                let d_minus = residual(model, ray, image_value, &minus, branches, h);
                *slot_jac = (d_plus - d_minus) / (2.0 * h_z);
            }
            Some((d, jac))
        }
    }
}

/// Charbonnier penaliser `Psi(s^2) = 2 lambda^2 sqrt(1 + s^2 / lambda^2)`.
#[inline]
pub fn charbonnier(s2: f64, lambda: f64) -> f64 {
    2.0 * lambda * lambda * (1.0 + s2 / (lambda * lambda)).sqrt()
}

/// Its derivative with respect to `s^2`: `Psi'(s^2) = 1 / sqrt(1 + s^2 / lambda^2)`.
#[inline]
pub fn charbonnier_derivative(s2: f64, lambda: f64) -> f64 {
    1.0 / (1.0 + s2 / (lambda * lambda)).sqrt()
}

/// Geometry of one pyramid level: its size, grid spacing and camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelGeometry {
    /// Columns at this level.
    pub width: usize,
    /// Rows at this level.
    pub height: usize,
    /// Grid spacing in full-resolution pixels.
    pub spacing: Spacing,
    /// Full-resolution camera.
    pub camera: Intrinsics,
}

impl LevelGeometry {
    /// Geometry of a `width` x `height` level of a full-resolution image of
    /// `full_width` x `full_height` pixels.
    pub fn new(
        width: usize,
        height: usize,
        full_width: usize,
        full_height: usize,
        camera: Intrinsics,
    ) -> Self {
        Self {
            width,
            height,
            spacing: Spacing {
                x: full_width as f64 / width as f64,
                y: full_height as f64 / height as f64,
            },
            camera,
        }
    }

    /// The camera-space point (units of `depth`) of level pixel
    /// `(column, row)` at Cartesian depth `depth`.
    #[inline]
    pub fn back_project(&self, column: usize, row: usize, depth: f64) -> [f64; 3] {
        let ray = self.ray(column, row);
        self.camera.back_project(ray.x_px, ray.y_px, depth)
    }

    /// The ray of level pixel `(column, row)`: the centre of the area it
    /// covers, in full-resolution image-plane coordinates.
    #[inline]
    pub fn ray(&self, column: usize, row: usize) -> PixelRay {
        let full_column = (column as f64 + 0.5) * self.spacing.x - 0.5;
        let full_row = (row as f64 + 0.5) * self.spacing.y - 0.5;
        let (x_px, y_px) = self.camera.image_xy(full_column, full_row);
        PixelRay {
            x_px,
            y_px,
            focal_px: self.camera.focal_px,
        }
    }
}

/// The 5-point neighbourhood of `(column, row)` within `domain`.
#[inline]
pub fn neighbourhood(
    depth: &Grid<f64>,
    domain: &Grid<bool>,
    column: usize,
    row: usize,
) -> Neighbourhood {
    let (w, h) = depth.size();
    let get = |c: usize, r: usize| domain.at(c, r).then(|| *depth.at(c, r));
    Neighbourhood {
        centre: *depth.at(column, row),
        left: if column > 0 {
            get(column - 1, row)
        } else {
            None
        },
        right: if column + 1 < w {
            get(column + 1, row)
        } else {
            None
        },
        up: if row > 0 { get(column, row - 1) } else { None },
        down: if row + 1 < h {
            get(column, row + 1)
        } else {
            None
        },
    }
}

/// The second derivatives `(z_xx, z_xy, z_yy)` at a pixel (central
/// differences), each only where its stencil lies entirely in `domain`
/// (natural boundary conditions); `None` where it does not.
#[inline]
pub fn second_derivatives(
    depth: &Grid<f64>,
    domain: &Grid<bool>,
    column: usize,
    row: usize,
    h: Spacing,
) -> (Option<f64>, Option<f64>, Option<f64>) {
    let (w, hgt) = depth.size();
    let (c, r) = (column, row);
    let inside = |c: usize, r: usize| *domain.at(c, r);
    let z = |c: usize, r: usize| *depth.at(c, r);
    let xx = (c > 0 && c + 1 < w && inside(c - 1, r) && inside(c + 1, r))
        .then(|| (z(c - 1, r) - 2.0 * z(c, r) + z(c + 1, r)) / (h.x * h.x));
    let yy = (r > 0 && r + 1 < hgt && inside(c, r - 1) && inside(c, r + 1))
        .then(|| (z(c, r - 1) - 2.0 * z(c, r) + z(c, r + 1)) / (h.y * h.y));
    let xy = (c > 0
        && c + 1 < w
        && r > 0
        && r + 1 < hgt
        && inside(c - 1, r - 1)
        && inside(c + 1, r - 1)
        && inside(c - 1, r + 1)
        && inside(c + 1, r + 1))
    .then(|| {
        (z(c + 1, r + 1) - z(c + 1, r - 1) - z(c - 1, r + 1) + z(c - 1, r - 1)) / (4.0 * h.x * h.y)
    });
    (xx, xy, yy)
}

/// Squared second-order smoothness `S^2 = z_xx^2 + 2 z_xy^2 + z_yy^2` at a
/// pixel, from the components of [`second_derivatives`] that exist.
pub fn smoothness_squared(
    depth: &Grid<f64>,
    domain: &Grid<bool>,
    column: usize,
    row: usize,
    h: Spacing,
) -> f64 {
    let (xx, xy, yy) = second_derivatives(depth, domain, column, row, h);
    let square = |v: Option<f64>| v.map_or(0.0, |v| v * v);
    square(xx) + 2.0 * square(xy) + square(yy)
}

/// The two parts of the energy `E = sum c D^2 + alpha sum Psi(S^2)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Energy {
    /// `sum c_p D_p^2` (current upwind branches).
    pub data: f64,
    /// `sum Psi(S_p^2)` over the domain (not yet multiplied by alpha).
    pub smoothness: f64,
    /// `data + alpha * smoothness`.
    pub total: f64,
}

/// Evaluates the energy (paper Eqs. 6-8) of `depth` on one level (rows
/// summed in parallel, polling `cancel` per row).
#[allow(clippy::too_many_arguments)]
pub fn energy<M: Reflectance + ?Sized, C: Weights + ?Sized>(
    model: &M,
    geometry: &LevelGeometry,
    image: &Grid<f64>,
    confidence: &C,
    domain: &Grid<bool>,
    depth: &Grid<f64>,
    alpha: f64,
    lambda: f64,
    cancel: Cancel<'_>,
) -> Result<Energy, Cancelled> {
    use rayon::prelude::*;
    let (data, smoothness) = (0..geometry.height)
        .into_par_iter()
        .map(|r| {
            let (mut data, mut smooth) = (0.0, 0.0);
            if cancel.is_cancelled() {
                return (data, smooth);
            }
            for c in 0..geometry.width {
                if !domain.at(c, r) {
                    continue;
                }
                let nb = neighbourhood(depth, domain, c, r);
                let (_, gx, gy) = nb.upwind(geometry.spacing);
                let d = image.at(c, r) - model.radiance(&geometry.ray(c, r), nb.centre, gx, gy);
                data += confidence.weight(r * geometry.width + c) * d * d;
                smooth += charbonnier(
                    smoothness_squared(depth, domain, c, r, geometry.spacing),
                    lambda,
                );
            }
            (data, smooth)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    cancel.check()?;
    Ok(Energy {
        data,
        smoothness,
        total: data + alpha * smoothness,
    })
}

/// Reprojects a depth map into an image `R = s Q^3 / (z W)` with the solver's
/// upwind derivatives; 0 outside `domain`. Rows in parallel, polling
/// `cancel` per row.
pub fn reproject<M: Reflectance + ?Sized>(
    model: &M,
    geometry: &LevelGeometry,
    domain: &Grid<bool>,
    depth: &Grid<f64>,
    cancel: Cancel<'_>,
) -> Result<Grid<f64>, Cancelled> {
    let (w, h) = (geometry.width, geometry.height);
    let mut out = Grid::filled(w, h, 0.0);
    crate::grid::for_rows(out.as_mut_slice(), w, cancel, |r, row| {
        for (c, out) in row.iter_mut().enumerate() {
            if !domain.at(c, r) {
                continue;
            }
            let nb = neighbourhood(depth, domain, c, r);
            let (_, gx, gy) = nb.upwind(geometry.spacing);
            let value = model.radiance(&geometry.ray(c, r), nb.centre, gx, gy);
            *out = if value.is_finite() { value } else { 0.0 };
        }
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_plane_on_axis_is_s_over_z_squared() {
        let model = Lambertian {
            intensity_scale: 2.0,
        };
        let ray = PixelRay {
            x_px: 0.0,
            y_px: 0.0,
            focal_px: 100.0,
        };
        assert!((model.radiance(&ray, 2.0, 0.0, 0.0) - 0.5).abs() < 1e-15);
    }

    #[test]
    fn upwind_branches_on_hand_made_cases() {
        // A valley (centre lowest): both one-sided slopes point up and away,
        // m = max(D-, -D+, 0) = 0.
        assert_eq!(upwind(Some(2.0), 1.0, Some(2.0), 1.0), (Branch::Zero, 0.0));
        // A ridge: D- = 1, -D+ = 1: tie goes backward.
        assert_eq!(
            upwind(Some(1.0), 2.0, Some(1.0), 1.0),
            (Branch::Backward, 1.0)
        );
        // Rising to the right: D- = 1 > 0, -D+ = -1 -> backward, slope 1.
        assert_eq!(
            upwind(Some(1.0), 2.0, Some(3.0), 1.0),
            (Branch::Backward, 1.0)
        );
        // Falling to the right: D- = -1, -D+ = 1 -> forward, slope -1.
        assert_eq!(
            upwind(Some(3.0), 2.0, Some(1.0), 1.0),
            (Branch::Forward, -1.0)
        );
        // Steeper on the right: D- = 0.5, -D+ = 2 -> forward, sign restored.
        assert_eq!(
            upwind(Some(1.5), 2.0, Some(0.0), 1.0),
            (Branch::Forward, -2.0)
        );
        // Spacing divides.
        assert_eq!(
            upwind(Some(1.0), 2.0, Some(1.5), 2.0),
            (Branch::Backward, 0.5)
        );
        // Only one neighbour: the inner one-sided difference, whatever its sign.
        assert_eq!(upwind(None, 2.0, Some(3.0), 1.0), (Branch::Forward, 1.0));
        assert_eq!(upwind(Some(3.0), 2.0, None, 1.0), (Branch::Backward, -1.0));
        assert_eq!(upwind(None, 2.0, None, 1.0), (Branch::Zero, 0.0));
    }

    #[test]
    fn charbonnier_and_derivative() {
        let lambda = 1e-3;
        assert!((charbonnier(0.0, lambda) - 2e-6).abs() < 1e-18);
        for s2 in [0.0, 1e-8, 1e-6, 1e-2, 3.0] {
            let eps = 1e-9 * (1.0 + s2);
            let numeric = (charbonnier(s2 + eps, lambda) - charbonnier(s2 - eps, lambda).max(0.0))
                / (2.0 * eps);
            let exact = charbonnier_derivative(s2, lambda);
            assert!(
                (numeric - exact).abs() < 1e-5 * exact.max(1e-3),
                "s2={s2}: {numeric} vs {exact}"
            );
        }
        assert!((charbonnier_derivative(0.0, lambda) - 1.0).abs() < 1e-15);
        // Large s: Psi ~ 2 lambda |s|, Psi' ~ lambda / |s|.
        assert!((charbonnier_derivative(1.0, lambda) - 1e-3).abs() < 1e-8);
    }

    #[test]
    fn numeric_derivatives_match_exact() {
        let model = Lambertian {
            intensity_scale: 1.7,
        };
        let ray = PixelRay {
            x_px: 37.0,
            y_px: -81.0,
            focal_px: 256.0,
        };
        let h = Spacing { x: 1.25, y: 1.5 };
        let values = [1.9, 1.87, 1.95, 1.93, 1.86];
        for bx in [Branch::Backward, Branch::Forward, Branch::Zero] {
            for by in [Branch::Backward, Branch::Forward, Branch::Zero] {
                let branches = Branches { x: bx, y: by };
                let (d_exact, j_exact) = residual_and_jacobian(
                    &model,
                    &ray,
                    0.3,
                    &values,
                    branches,
                    h,
                    Derivatives::Exact,
                )
                .expect("Lambertian has exact derivatives");
                for h_z in [1e-6, 1e-12] {
                    let (d_num, j_num) = residual_and_jacobian(
                        &model,
                        &ray,
                        0.3,
                        &values,
                        branches,
                        h,
                        Derivatives::Numeric { h_z },
                    )
                    .expect("numeric derivatives always exist");
                    assert_eq!(d_num, d_exact);
                    let scale = j_exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    let tol = if h_z < 1e-9 { 1e-3 } else { 1e-7 };
                    for k in 0..5 {
                        assert!(
                            (j_num[k] - j_exact[k]).abs() <= tol * scale,
                            "{bx:?}/{by:?} h_z={h_z} slot {k}: {} vs {}",
                            j_num[k],
                            j_exact[k]
                        );
                    }
                }
            }
        }
    }
}
