//! Photometric-stereo sets with ground truth: one scene rendered under each
//! of several LEDs alone, times a textured albedo, with cast shadows, at one
//! common exposure; and the LED rings and albedo patterns they use.

use std::f64::consts::PI;

use glam::DVec3;

use super::Scene;
use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::light::PointLight;
use crate::occlusion::cast_shadow;

/// A set of photographs of one surface, one light each, with the truth.
#[derive(Clone, Debug)]
pub struct PhotometricSet {
    /// The scene's name.
    pub name: String,
    /// Intrinsics.
    pub camera: Intrinsics,
    /// Depth along the optical axis; NaN on the background.
    pub depth_gt: Grid<f64>,
    /// The normals the images were shaded with; NaN on the background.
    pub normals_gt: Grid<[f64; 3]>,
    /// The albedo (relative, max 1).
    pub albedo_gt: Grid<f64>,
    /// The object.
    pub object_mask: Grid<bool>,
    /// The photographs, linear, in [0, 0.9].
    pub images: Vec<Grid<f64>>,
    /// Each one's light (intensity 1).
    pub lights: Vec<PointLight>,
    /// The intensity scale `s`: image = `s albedo` times the irradiance.
    pub intensity_scale: f64,
    /// Where each photograph's light is hidden by the surface.
    pub cast: Vec<Grid<bool>>,
}

/// `count` LEDs on a ring around the line from the camera to `target`,
/// each `off_axis_deg` off that line seen from the target, at `distance`
/// from it, pointing at it with anisotropy `mu`. The angles around the ring
/// are spread evenly (the first at the top right, 20 degrees in).
pub fn led_ring(
    count: usize,
    target: [f64; 3],
    distance: f64,
    off_axis_deg: &[f64],
    mu: f64,
) -> Vec<PointLight> {
    let target = DVec3::from_array(target);
    let axis = -target.normalize_or(DVec3::Z);
    let side = axis.cross(DVec3::Y).normalize_or(DVec3::X);
    let up = side.cross(axis);
    (0..count)
        .map(|k| {
            let around = 2.0 * PI * k as f64 / count as f64 + 20f64.to_radians();
            let off = off_axis_deg[k % off_axis_deg.len().max(1)].to_radians();
            let direction_from_target = (axis * off.cos()
                + (side * around.cos() + up * around.sin()) * off.sin())
            .normalize();
            let position = target + direction_from_target * distance;
            PointLight {
                position: position.to_array(),
                direction: Some((-direction_from_target).to_array()),
                mu,
                intensity: 1.0,
            }
        })
        .collect()
}

/// The LEDs of the benchmark's and `synth`'s sets: `count` LEDs on a ring
/// around the line from the camera to `target`, at 0.75 of the target's
/// distance from it (between the camera and the object, as in the shared
/// near_ps rig), their angles off that line spread evenly over 10 to 45
/// degrees, Lambertian emitters (`mu = 1`) aimed at the target.
pub fn standard_leds(count: usize, target: [f64; 3]) -> Vec<PointLight> {
    let distance = 0.75 * DVec3::from_array(target).length();
    let angles: Vec<f64> = (0..count)
        .map(|k| {
            if count > 1 {
                10.0 + 35.0 * k as f64 / (count - 1) as f64
            } else {
                25.0
            }
        })
        .collect();
    led_ring(count, target, distance, &angles, 1.0)
}

/// An albedo pattern of the image plane in [0.35, 1]: `patches` (a few
/// albedos in soft-edged cells), `lines` (thin dark strokes on 0.9) or
/// `smooth` (a slow gradient with ripples).
pub fn albedo_pattern(width: usize, height: usize, kind: &str) -> Grid<f64> {
    let side = width.max(height) as f64;
    Grid::from_fn(width, height, |c, r| {
        let (u, v) = (c as f64 / side, r as f64 / side);
        match kind {
            "lines" => {
                let stroke = ((u * 9.0 + 0.3 * (v * 7.0).sin()).fract() - 0.5).abs() * side / 9.0;
                if stroke < 0.9 { 0.35 } else { 0.9 }
            }
            "smooth" => 0.65 + 0.25 * (u * 4.0).sin() * (v * 3.0).cos() + 0.08 * (u * 17.0).sin(),
            _ => {
                let cell = ((u * 5.0).floor() as i64 * 7 + (v * 5.0).floor() as i64 * 3) % 4;
                [0.9, 0.55, 0.75, 0.4][cell.rem_euclid(4) as usize]
            }
        }
    })
}

/// Renders the set: `render` gives the scene under one light (its image at
/// any exposure, with its `intensity_scale`); each image is brought to the
/// irradiance, multiplied by `albedo`, darkened where the surface hides its
/// light (when `shadows`), and all are scaled by one `s` so the brightest
/// value of the set is 0.9.
///
/// # Errors
/// The renderer's error.
pub fn render_set<E>(
    render: impl Fn(&[PointLight]) -> Result<Scene, E>,
    lights: &[PointLight],
    albedo: &Grid<f64>,
    shadows: bool,
) -> Result<PhotometricSet, E> {
    let mut raw = Vec::new();
    let mut first: Option<Scene> = None;
    let mut cast = Vec::new();
    for light in lights {
        let scene = render(std::slice::from_ref(light))?;
        let hidden = if shadows {
            cast_shadow(&scene.depth_gt, scene.camera, light.position)
        } else {
            Grid::filled(scene.image.width(), scene.image.height(), false)
        };
        let s = scene.intensity_scale;
        let image = Grid::from_fn(scene.image.width(), scene.image.height(), |c, r| {
            if *hidden.at(c, r) {
                0.0
            } else {
                scene.image.at(c, r) / s * albedo.at(c, r)
            }
        });
        raw.push(image);
        cast.push(hidden);
        if first.is_none() {
            first = Some(scene);
        }
    }
    // No lights: the scene's truth with no photograph.
    let scene = match first {
        Some(scene) => scene,
        None => render(&[])?,
    };
    let brightest = raw
        .iter()
        .flat_map(|g| g.as_slice().iter().copied())
        .fold(0.0, f64::max);
    // 1 without a photograph (or a black set).
    let s = if brightest > 0.0 {
        0.9 / brightest
    } else {
        1.0
    };
    let images = raw.iter().map(|g| g.map(|v| v * s)).collect();
    let object = scene.object_mask.clone();
    Ok(PhotometricSet {
        name: scene.name.clone(),
        camera: scene.camera,
        normals_gt: scene
            .normals
            .clone()
            .unwrap_or_else(|| scene.depth_gt.map(|_| [f64::NAN; 3])),
        depth_gt: scene.depth_gt,
        albedo_gt: albedo.zip_map(&object, |a, &o| if o { *a } else { f64::NAN }),
        object_mask: object,
        images,
        lights: lights.to_vec(),
        intensity_scale: s,
        cast,
    })
}

/// The mean angle in degrees between two normal fields over the pixels
/// where `mask` holds and both are finite; NaN when there is none.
pub fn mean_angle_deg(a: &Grid<[f64; 3]>, b: &Grid<[f64; 3]>, mask: &Grid<bool>) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for ((na, nb), &m) in a.as_slice().iter().zip(b.as_slice()).zip(mask.as_slice()) {
        let (u, v) = (DVec3::from_array(*na), DVec3::from_array(*nb));
        if m && u.is_finite() && v.is_finite() && u.length() > 0.0 && v.length() > 0.0 {
            sum += u.angle_between(v).to_degrees();
            count += 1;
        }
    }
    if count == 0 {
        f64::NAN
    } else {
        sum / count as f64
    }
}

/// `albedo` with an error of its own in each cell of a `cells` x `cells`
/// grid of the image plane (the cells of the `patches` pattern at 5): each
/// cell multiplied by `exp(N(0, log_sigma))` from `seed`. What a given
/// albedo a few per cent off does to a solve (`bench --part albedo`).
pub fn albedo_with_cell_error(
    albedo: &Grid<f64>,
    cells: usize,
    log_sigma: f64,
    seed: u64,
) -> Grid<f64> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let cells = cells.max(1);
    let factors: Vec<f64> = (0..cells * cells)
        .map(|_| (log_sigma * rng.sample::<f64, _>(rand_distr::StandardNormal)).exp())
        .collect();
    let side = albedo.width().max(albedo.height()).max(1) as f64;
    let cell = |p: usize| ((p as f64 / side * cells as f64) as usize).min(cells - 1);
    let (w, h) = albedo.size();
    Grid::from_fn(w, h, |c, r| {
        albedo.at(c, r) * factors[cell(r) * cells + cell(c)]
    })
}

/// The median relative error of an albedo against the truth after the one
/// scale that best matches them (the median ratio): an albedo is known up
/// to the intensity scale. Over `mask` where both are finite and positive.
pub fn albedo_error(albedo: &Grid<f64>, truth: &Grid<f64>, mask: &Grid<bool>) -> f64 {
    let pairs: Vec<(f64, f64)> = albedo
        .as_slice()
        .iter()
        .zip(truth.as_slice())
        .zip(mask.as_slice())
        .filter(|((a, t), m)| **m && a.is_finite() && t.is_finite() && **a > 0.0 && **t > 0.0)
        .map(|((a, t), _)| (*a, *t))
        .collect();
    let median = |mut v: Vec<f64>| {
        if v.is_empty() {
            return f64::NAN;
        }
        let k = v.len() / 2;
        *v.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let k = median(pairs.iter().map(|(a, t)| t / a).collect());
    median(pairs.iter().map(|(a, t)| (a * k / t - 1.0).abs()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cell_error_is_constant_per_cell_and_of_its_size() {
        let truth = albedo_pattern(100, 100, "patches");
        let off = albedo_with_cell_error(&truth, 5, 0.03, 7);
        let log_ratio = |c: usize, r: usize| (off.at(c, r) / truth.at(c, r)).ln();
        // Constant within a cell (20 px here), different between cells.
        assert!((log_ratio(0, 0) - log_ratio(19, 19)).abs() < 1e-12);
        assert!((log_ratio(0, 0) - log_ratio(20, 0)).abs() > 1e-6);
        let spread: Vec<f64> = (0..5)
            .flat_map(|i| (0..5).map(move |j| (10 + 20 * i, 10 + 20 * j)))
            .map(|(c, r)| log_ratio(c, r))
            .collect();
        let rms = (spread.iter().map(|v| v * v).sum::<f64>() / 25.0).sqrt();
        assert!(rms > 0.01 && rms < 0.06, "rms {rms}");
        assert_eq!(off, albedo_with_cell_error(&truth, 5, 0.03, 7), "seeded");
    }

    #[test]
    fn the_ring_is_where_it_says() {
        let target = [0.0, 0.0, 2.0];
        let lights = led_ring(4, target, 1.5, &[10.0, 45.0], 1.0);
        for (k, light) in lights.iter().enumerate() {
            let to_light = DVec3::from_array(light.position) - DVec3::from_array(target);
            assert!((to_light.length() - 1.5).abs() < 1e-12);
            let off = to_light
                .angle_between(-DVec3::from_array(target))
                .to_degrees();
            let want = if k % 2 == 0 { 10.0 } else { 45.0 };
            assert!((off - want).abs() < 1e-9, "{off}");
            let d = DVec3::from_array(light.direction.unwrap());
            assert!((d + to_light.normalize()).length() < 1e-12);
        }
    }

    #[test]
    fn errors_measure_what_they_say() {
        let mask = Grid::filled(2, 1, true);
        let a = Grid::from_vec(2, 1, vec![[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]]).unwrap();
        let tilt = 10f64.to_radians();
        let b =
            Grid::from_vec(2, 1, vec![[0.0, 0.0, -1.0], [tilt.sin(), 0.0, -tilt.cos()]]).unwrap();
        assert!((mean_angle_deg(&a, &b, &mask) - 5.0).abs() < 1e-9);
        let truth = Grid::from_vec(2, 1, vec![0.5, 1.0]).unwrap();
        let scaled = truth.map(|v| 3.0 * v);
        assert!(albedo_error(&scaled, &truth, &mask) < 1e-12);
    }
}
