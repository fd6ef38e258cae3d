//! Which surface points of a depth map the surface itself hides from a
//! point light: a ray march through the depth map toward the light (the
//! object taken as solid behind what the camera sees). Used to render cast
//! shadows (`scene::shadow`) and to check the solver's shadows against its
//! own surface (`march` is the one ray march, shared with the solver's
//! shadow bound). Depends on the grid, the camera and glam only.

use glam::DVec3;

use crate::camera::Intrinsics;
use crate::grid::Grid;

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
    cast_shadow_where(depth, camera, light, None)
}

/// [`cast_shadow`] at the pixels where `only` holds (all with `None`); the
/// others are false.
pub fn cast_shadow_where(
    depth: &Grid<f64>,
    camera: Intrinsics,
    light: [f64; 3],
    only: Option<&Grid<bool>>,
) -> Grid<bool> {
    use rayon::prelude::*;
    let (w, h) = depth.size();
    let light = DVec3::from_array(light);
    let max_steps = 8 * (w + h);
    let rows: Vec<Vec<bool>> = (0..h)
        .into_par_iter()
        .map(|r| {
            (0..w)
                .map(|c| {
                    let z = *depth.at(c, r);
                    if !z.is_finite() || z <= 0.0 || only.is_some_and(|o| !*o.at(c, r)) {
                        return false;
                    }
                    let (x, y) = camera.image_xy(c as f64, r as f64);
                    let start = DVec3::from_array(camera.back_project(x, y, z));
                    for (p, u, v) in march(start, light, camera, max_steps) {
                        let (cu, cv) = (u.round(), v.round());
                        if cu < 0.0 || cv < 0.0 || cu >= w as f64 || cv >= h as f64 {
                            return false;
                        }
                        if (u - c as f64).hypot(v - r as f64) > SELF_PX {
                            let surface = *depth.at(cu as usize, cv as usize);
                            if surface.is_finite() && surface < p.z * (1.0 - OCCLUSION_TOLERANCE) {
                                return true;
                            }
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

/// The samples of a march along the segment from `start` toward `light`
/// (camera frame, units of depth): each sample's point and its image
/// position (full-resolution column and row), about every [`STEP_PX`]
/// pixels of the segment's image and at least every 1/32 of the segment.
/// Ends with the sample at the light, where the segment reaches the
/// camera's plane, or after `max_steps` samples. The one march of
/// [`cast_shadow`] and of the solver's shadow bound.
pub(crate) fn march(
    start: DVec3,
    light: DVec3,
    camera: Intrinsics,
    max_steps: usize,
) -> impl Iterator<Item = (DVec3, f64, f64)> {
    let f = camera.focal_px;
    let towards = light - start;
    let at = move |t: f64| start + towards * t;
    let (mut t, mut steps) = (0.0, 0);
    std::iter::from_fn(move || {
        if t >= 1.0 || steps >= max_steps {
            return None;
        }
        steps += 1;
        let p = at(t);
        if p.z <= 0.0 {
            return None;
        }
        // The image speed of the march, pixels per unit t.
        let speed_x = f * (towards.x * p.z - p.x * towards.z) / (p.z * p.z);
        let speed_y = f * (towards.y * p.z - p.y * towards.z) / (p.z * p.z);
        let speed = speed_x.hypot(speed_y);
        // Along the viewing ray the image stands still: no surface can
        // come between (a light behind the camera's own ray); step in
        // depth instead.
        let dt = if speed > 1e-12 {
            (STEP_PX / speed).min(MAX_DT)
        } else {
            MAX_DT
        };
        t = (t + dt).min(1.0);
        let p = at(t);
        if p.z <= 0.0 {
            t = 1.0;
            return None;
        }
        Some((
            p,
            f * p.x / p.z + camera.principal_x_px,
            f * p.y / p.z + camera.principal_y_px,
        ))
    })
}
