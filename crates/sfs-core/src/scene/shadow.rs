//! Cast shadows for synthetic scenes: which surface points of a depth map
//! the surface itself hides from a point light (a ray march through the
//! depth map toward the light), and a scene rendered with them, so that
//! every shadow case has ground truth. Attached shadows (`N . L <= 0`) are
//! already black in the local shading; these are the others.

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::light::PointLight;

use super::Scene;

/// A ray sample hides behind the surface when the depth map there is nearer
/// than the sample by more than this share of the sample's depth.
const OCCLUSION_TOLERANCE: f64 = 2e-3;
/// Samples within this many pixels of the starting pixel are its own
/// neighbourhood, not an occluder.
const SELF_PX: f64 = 1.5;
/// The march advances about this many pixels per sample.
const STEP_PX: f64 = 0.5;
/// At least this many samples per segment (a segment whose image is short).
const MAX_DT: f64 = 1.0 / 32.0;

/// True at the pixels of `depth` (Cartesian depth, NaN off the object) whose
/// surface point cannot see `light` (camera frame, units of depth): the
/// segment from the point to the light passes behind the surface that the
/// depth map shows (the object taken as solid behind what the camera
/// sees). Sampled every half pixel of the segment's image, nearest pixel;
/// a light at the optical centre casts no visible shadow.
pub fn cast_shadow(depth: &Grid<f64>, camera: Intrinsics, light: [f64; 3]) -> Grid<bool> {
    use rayon::prelude::*;
    let (w, h) = depth.size();
    let f = camera.focal_px;
    let project = |p: [f64; 3]| {
        (
            f * p[0] / p[2] + camera.principal_x_px,
            f * p[1] / p[2] + camera.principal_y_px,
        )
    };
    let max_steps = 8 * (w + h);
    let rows: Vec<Vec<bool>> = (0..h)
        .into_par_iter()
        .map(|r| {
            (0..w)
                .map(|c| {
                    let z = *depth.at(c, r);
                    if !z.is_finite() || z <= 0.0 {
                        return false;
                    }
                    let (x, y) = camera.image_xy(c as f64, r as f64);
                    let start = camera.back_project(x, y, z);
                    let towards = [
                        light[0] - start[0],
                        light[1] - start[1],
                        light[2] - start[2],
                    ];
                    let mut t = 0.0;
                    for _ in 0..max_steps {
                        let at = |t: f64| {
                            [
                                start[0] + t * towards[0],
                                start[1] + t * towards[1],
                                start[2] + t * towards[2],
                            ]
                        };
                        let p = at(t);
                        if p[2] <= 0.0 {
                            return false;
                        }
                        // The image speed of the march, pixels per unit t.
                        let speed_x = f * (towards[0] * p[2] - p[0] * towards[2]) / (p[2] * p[2]);
                        let speed_y = f * (towards[1] * p[2] - p[1] * towards[2]) / (p[2] * p[2]);
                        let speed = speed_x.hypot(speed_y);
                        // Along the viewing ray the image stands still: no
                        // surface can come between (a light behind the
                        // camera's own ray); step in depth instead.
                        let dt = if speed > 1e-12 {
                            (STEP_PX / speed).min(MAX_DT)
                        } else {
                            MAX_DT
                        };
                        t = (t + dt).min(1.0);
                        let p = at(t);
                        if p[2] <= 0.0 {
                            return false;
                        }
                        let (u, v) = project(p);
                        let (cu, cv) = (u.round(), v.round());
                        if cu < 0.0 || cv < 0.0 || cu >= w as f64 || cv >= h as f64 {
                            return false;
                        }
                        if (u - c as f64).hypot(v - r as f64) > SELF_PX {
                            let surface = *depth.at(cu as usize, cv as usize);
                            if surface.is_finite() && surface < p[2] * (1.0 - OCCLUSION_TOLERANCE) {
                                return true;
                            }
                        }
                        if t >= 1.0 {
                            return false;
                        }
                    }
                    false
                })
                .collect()
        })
        .collect();
    let mut out = Grid::filled(w, h, false);
    for (r, row) in rows.into_iter().enumerate() {
        for (c, shadowed) in row.into_iter().enumerate() {
            *out.at_mut(c, r) = shadowed;
        }
    }
    out
}

/// A scene lit by `lights` with cast shadows, from a renderer of the local
/// shading (`render(lights)`, e.g. [`super::sombrero::sombrero_lit`] or
/// [`super::mesh::render_lit`]): each light's image is rendered alone,
/// darkened where [`cast_shadow`] hides its light, and the lights summed at
/// the exposure of the full render. Returns the scene and, per pixel, true
/// where no light reaches the object (cast or attached shadow of every
/// light). With no lights (one at the optical centre) nothing is hidden.
pub fn with_cast_shadows<E>(
    render: impl Fn(&[PointLight]) -> Result<Scene, E>,
    lights: &[PointLight],
) -> Result<(Scene, Grid<bool>), E> {
    let mut scene = render(lights)?;
    let (w, h) = scene.image.size();
    let mut lit = Grid::filled(w, h, false);
    if lights.is_empty() {
        for (l, (&i, &o)) in lit.as_mut_slice().iter_mut().zip(
            scene
                .image
                .as_slice()
                .iter()
                .zip(scene.object_mask.as_slice()),
        ) {
            *l = o && i > 0.0;
        }
    } else {
        let mut image = Grid::filled(w, h, 0.0);
        for light in lights {
            let alone = render(std::slice::from_ref(light))?;
            let hidden = cast_shadow(&scene.depth_gt, scene.camera, light.position);
            // This light's share at the full render's exposure.
            let k = scene.intensity_scale / alone.intensity_scale;
            for q in 0..w * h {
                let value = alone.image.as_slice()[q];
                if !hidden.as_slice()[q] && value > 0.0 {
                    image.as_mut_slice()[q] += k * value;
                    lit.as_mut_slice()[q] = true;
                }
            }
        }
        scene.image = image;
    }
    let shadow = Grid::from_fn(w, h, |c, r| *scene.object_mask.at(c, r) && !*lit.at(c, r));
    Ok((scene, shadow))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_casts_a_shadow_away_from_the_light_and_none_towards_it() {
        // A floor at depth 2 with a raised block (depth 1.6) in the middle
        // columns; a light to the left, nearer the camera: the floor just
        // right of the block is hidden, the floor left of it, the block's
        // top and the floor far right (the ray passes in front) are lit.
        let (w, h) = (64, 16);
        let camera = Intrinsics::centred(64.0, w, h);
        let depth = Grid::from_fn(w, h, |c, _| if (28..36).contains(&c) { 1.6 } else { 2.0 });
        let hidden = cast_shadow(&depth, camera, [-1.0, 0.0, 0.5]);
        let row = 8;
        assert!(*hidden.at(38, row), "just right of the block");
        assert!(!*hidden.at(20, row), "left of the block");
        assert!(!*hidden.at(32, row), "on the block");
        assert!(!*hidden.at(60, row), "far right: the shadow ends");
    }

    #[test]
    fn a_light_at_the_optical_centre_casts_no_shadow() {
        let (w, h) = (32, 32);
        let camera = Intrinsics::centred(32.0, w, h);
        let depth = Grid::from_fn(w, h, |c, r| {
            2.0 + 0.3 * ((c as f64) * 0.7).sin() * (r as f64 * 0.5).cos()
        });
        let hidden = cast_shadow(&depth, camera, [0.0, 0.0, 0.0]);
        assert!(hidden.as_slice().iter().all(|&s| !s));
    }
}
