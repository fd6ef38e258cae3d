//! The analytic Sombrero scene of METHOD.md section 7.

use std::f64::consts::PI;

use super::Scene;
use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::light::{LightModel, PointLight};
use crate::material::Material;
use crate::model::{PixelRay, Reflectance};

/// Intensity scale of the Sombrero scene.
pub const SOMBRERO_INTENSITY_SCALE: f64 = 2.0;

/// Depth and exact gradient `(z, dz/dx, dz/dy)` of the Sombrero at image-plane
/// coordinates `(x, y)` (pixels) for an image `width` pixels wide.
pub fn sombrero_depth(x_px: f64, y_px: f64, width: usize) -> (f64, f64, f64) {
    let half = width as f64 / 2.0;
    let radius_px = (x_px * x_px + y_px * y_px).sqrt();
    let rho = 3.0 * PI * radius_px / half;
    // g(rho) = sin(rho)/rho and g'(rho), with series near 0.
    let (g, g_prime_over_rho) = if rho < 1e-4 {
        (1.0 - rho * rho / 6.0, -1.0 / 3.0 + rho * rho / 30.0)
    } else {
        let g = rho.sin() / rho;
        (g, (rho * rho.cos() - rho.sin()) / (rho * rho * rho))
    };
    let depth = 2.0 - 0.5 * g;
    // dz/dx = -0.5 g'(rho) drho/dx, drho/dx = (3 pi / half) x / radius
    //       = -0.5 (g'/rho) (3 pi / half)^2 x.
    let k = 3.0 * PI / half;
    let common = -0.5 * g_prime_over_rho * k * k;
    (depth, common * x_px, common * y_px)
}

/// Renders the Sombrero at `width` x `height` (`f = width`, default principal
/// point, `s = 2`, every pixel foreground).
pub fn sombrero(width: usize, height: usize) -> Scene {
    sombrero_lit(width, height, &[])
}

/// [`sombrero`] lit by `lights` (camera frame, units of depth; empty: the
/// paper's light at the optical centre, `s = 2`). With lights given, `s` is
/// chosen so the brightest pixel is 0.9 (as meshes are rendered), so that a
/// ring of lights does not saturate.
pub fn sombrero_lit(width: usize, height: usize, lights: &[PointLight]) -> Scene {
    sombrero_shaded(width, height, lights, Material::Lambert)
}

/// [`sombrero_lit`] for a surface of `material` (METHOD.md section 10);
/// with lights given or a material other than Lambert, `s` is chosen so the
/// brightest pixel is 0.9.
pub fn sombrero_shaded(
    width: usize,
    height: usize,
    lights: &[PointLight],
    material: Material,
) -> Scene {
    let camera = Intrinsics::centred(width as f64, width, height);
    let model = LightModel::with_material(SOMBRERO_INTENSITY_SCALE, lights, material);
    let mut depth_gt = Grid::filled(width, height, 0.0);
    let mut normals = Grid::filled(width, height, [0.0; 3]);
    let image = Grid::from_fn(width, height, |c, r| {
        let (x_px, y_px) = camera.image_xy(c as f64, r as f64);
        let (z, zx, zy) = sombrero_depth(x_px, y_px, width);
        *depth_gt.at_mut(c, r) = z;
        let n = glam::DVec3::new(
            camera.focal_px * zx,
            camera.focal_px * zy,
            -(z + x_px * zx + y_px * zy),
        );
        *normals.at_mut(c, r) = n.normalize().to_array();
        let ray = PixelRay {
            x_px,
            y_px,
            focal_px: camera.focal_px,
        };
        model.radiance(&ray, z, zx, zy)
    });
    let brightest = image.as_slice().iter().copied().fold(0.0, f64::max);
    let paper = lights.is_empty() && material.is_lambert();
    let (image, intensity_scale) = if paper || brightest.is_nan() || brightest <= 0.0 {
        (image, SOMBRERO_INTENSITY_SCALE)
    } else {
        let k = 0.9 / brightest;
        (image.map(|v| v * k), SOMBRERO_INTENSITY_SCALE * k)
    };
    Scene {
        name: "sombrero".into(),
        camera,
        intensity_scale,
        image,
        depth_gt,
        object_mask: Grid::filled(width, height, true),
        normals: Some(normals),
        lights: lights.to_vec(),
        material,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_shared_definition() {
        let scene = sombrero(256, 256);
        let (lo, hi) = scene
            .depth_gt
            .as_slice()
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &z| (a.min(z), b.max(z)));
        assert!(
            (lo - 1.50).abs() < 0.01 && (hi - 2.11).abs() < 0.01,
            "{lo} {hi}"
        );
        // At the exact centre I = s / z^2 = 2 / 1.5^2 = 0.889; the nearest
        // pixel centres lie 0.7 px away, where the slope costs 0.6 %.
        let brightest = scene.image.as_slice().iter().cloned().fold(0.0, f64::max);
        assert!(
            brightest < 2.0 / 2.25 && brightest > 0.99 * 2.0 / 2.25,
            "{brightest}"
        );
        let (z, zx, zy) = sombrero_depth(0.0, 0.0, 256);
        assert_eq!((z, zx, zy), (1.5, 0.0, 0.0));
    }

    #[test]
    fn gradient_is_exact() {
        for (x, y) in [(3.0, -7.0), (40.5, 12.0), (-90.0, 70.0), (1e-7, 0.0)] {
            let (_, zx, zy) = sombrero_depth(x, y, 256);
            let e = 1e-5;
            let nx =
                (sombrero_depth(x + e, y, 256).0 - sombrero_depth(x - e, y, 256).0) / (2.0 * e);
            let ny =
                (sombrero_depth(x, y + e, 256).0 - sombrero_depth(x, y - e, 256).0) / (2.0 * e);
            assert!(
                (zx - nx).abs() < 1e-8 && (zy - ny).abs() < 1e-8,
                "{zx} {nx} {zy} {ny}"
            );
        }
    }
}
