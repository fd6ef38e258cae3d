//! The inequality a shadow carries, used as a one-sided bound on depth: a
//! pixel no light reaches lies where the surface hides it from every light
//! (a cast shadow) or where it turns away beyond the terminator (an
//! attached shadow). Either way its surface point lies behind the ray from
//! the light through some lit surface point between it and the light, as
//! the image shows them (the occluder's edge, or the terminator). The data
//! term cannot say so (a shadow pixel has no brightness to match, and the
//! smoothness fill may bridge a shadow in front of the light), so with
//! `shadow_bound` on, the shadow pixels that the full-resolution surface
//! would light are pushed back onto that ray, checked against the surface
//! the solve ended with. Off by default: measured no better (docs/holes-and-shadows.md,
//! "Shadows"). Depends on the grid, the lights, `occlusion::march`, glam
//! and the pyramid only.

use glam::DVec3;
use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Grid, Weights};
use crate::light::PointLight;

use super::holes::HOLE_CONFIDENCE;
use super::pyramid::PyramidLevel;

/// The bound is lowered by this share of itself: the image shows the
/// occluder's edge only to the nearest pixel.
const BOUND_TOLERANCE: f64 = 2e-3;
/// A bound farther than this multiple of the level's deepest point is no
/// bound (a ray grazing the viewing ray meets it far away).
const BOUND_REACH: f64 = 1.5;
/// Samples within this many level pixels of the shadow pixel are its own
/// neighbourhood, not an occluder.
const SELF_PX: f64 = 1.5;

/// Pushes every shadow pixel of `level` that lies in front of its bound
/// back onto it (see the module); `shadow` is the full image's shadow,
/// sampled at each level pixel's centre. Only lit, trusted pixels count as
/// occluders: the depth of the rest is the fill's guess. Returns how many
/// pixels moved.
pub(crate) fn enforce(
    level: &PyramidLevel,
    shadow: &Grid<bool>,
    lights: &[PointLight],
    depth: &mut Grid<f64>,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    let geometry = level.geometry;
    let (w, h) = (geometry.width, geometry.height);
    let (full_w, full_h) = shadow.size();
    let lights: Vec<DVec3> = lights
        .iter()
        .filter(|l| l.intensity > 0.0)
        .map(|l| DVec3::from_array(l.position))
        .collect();
    if lights.is_empty() || depth.size() != (w, h) {
        return Ok(0);
    }
    // The full image's shadow at each level pixel's centre.
    let in_shadow = Grid::from_fn(w, h, |c, r| {
        let column = ((c as f64 + 0.5) * geometry.spacing.x - 0.5).round();
        let row = ((r as f64 + 0.5) * geometry.spacing.y - 0.5).round();
        let (column, row) = (
            (column.max(0.0) as usize).min(full_w - 1),
            (row.max(0.0) as usize).min(full_h - 1),
        );
        *level.domain.at(c, r) && *shadow.at(column, row)
    });
    if !in_shadow.as_slice().iter().any(|&s| s) {
        return Ok(0);
    }
    // Occluders: lit, trusted pixels only (the depth of the others is the
    // fill's guess, which may itself bridge the shadow).
    let occluder = Grid::from_fn(w, h, |c, r| {
        let q = r * w + c;
        level.domain.as_slice()[q]
            && !in_shadow.as_slice()[q]
            && level.confidence.weight(q) >= HOLE_CONFIDENCE
    });
    let deepest = depth
        .as_slice()
        .iter()
        .zip(level.domain.as_slice())
        .filter(|(z, d)| **d && z.is_finite())
        .map(|(z, _)| *z)
        .fold(0.0, f64::max);
    let reach = BOUND_REACH * deepest;
    let surface = &*depth;
    let bounds: Vec<Vec<(usize, f64)>> = (0..h)
        .into_par_iter()
        .map(|r| {
            if cancel.is_cancelled() {
                return Vec::new();
            }
            (0..w)
                .filter(|&c| *in_shadow.at(c, r))
                .filter_map(|c| {
                    let z = *surface.at(c, r);
                    if !(z.is_finite() && z > 0.0) {
                        return None;
                    }
                    let bound = lights
                        .iter()
                        .filter_map(|&light| {
                            bound_toward(level, surface, &occluder, c, r, z, light, reach)
                        })
                        .fold(f64::NEG_INFINITY, f64::max);
                    let bound = bound * (1.0 - BOUND_TOLERANCE);
                    (bound.is_finite() && z < bound).then_some((c, bound))
                })
                .collect()
        })
        .collect();
    cancel.check()?;
    let mut moved = 0;
    for (r, row) in bounds.into_iter().enumerate() {
        for (c, bound) in row {
            *depth.at_mut(c, r) = bound;
            moved += 1;
        }
    }
    Ok(moved)
}

/// The least depth at which level pixel `(c, r)` is hidden from `light` by
/// an occluder between it and the light: the segment from the pixel's
/// surface point (at its current depth `z`) toward the light is marched
/// through the image (`occlusion::march`), and every occluder it passes
/// over gives the depth at which the pixel's viewing ray meets the ray from
/// the light through that occluder's surface point. `None` where no
/// occluder lies on the way (or every bound is beyond `reach`).
#[allow(clippy::too_many_arguments)]
fn bound_toward(
    level: &PyramidLevel,
    surface: &Grid<f64>,
    occluder: &Grid<bool>,
    c: usize,
    r: usize,
    z: f64,
    light: DVec3,
    reach: f64,
) -> Option<f64> {
    let geometry = level.geometry;
    let (w, h) = (geometry.width, geometry.height);
    let f = geometry.camera.focal_px;
    let viewing = |column: usize, row: usize| {
        let ray = geometry.ray(column, row);
        DVec3::new(ray.x_px / f, ray.y_px / f, 1.0)
    };
    let direction = viewing(c, r);
    let mut best: Option<f64> = None;
    for (_, u, v) in crate::occlusion::march(direction * z, light, geometry.camera, 8 * (w + h)) {
        // Full-resolution image position to level pixels.
        let u = (u + 0.5) / geometry.spacing.x - 0.5;
        let v = (v + 0.5) / geometry.spacing.y - 0.5;
        let (cu, cv) = (u.round(), v.round());
        if cu < 0.0 || cv < 0.0 || cu >= w as f64 || cv >= h as f64 {
            break;
        }
        let (cu, cv) = (cu as usize, cv as usize);
        if (u - c as f64).hypot(v - r as f64) <= SELF_PX || !*occluder.at(cu, cv) {
            continue;
        }
        let depth_at = *surface.at(cu, cv);
        if !(depth_at.is_finite() && depth_at > 0.0) {
            continue;
        }
        let point = viewing(cu, cv) * depth_at;
        // Where the line from the light through `point` meets the pixel's
        // viewing ray `s direction` (least squares: the two are coplanar up
        // to the nearest pixel).
        let normal = direction.cross(point - light);
        let norm2 = normal.length_squared();
        if norm2 > 0.0 {
            let s = light.cross(point).dot(normal) / norm2;
            if s.is_finite() && s > 0.0 && s <= reach {
                best = Some(best.map_or(s, |b: f64| b.min(s)));
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::grid::Confidence;
    use crate::model::LevelGeometry;

    /// A wall at depth 1 on the left half, a floor at depth 2 on the right;
    /// a light to the left, in front of the wall's plane.
    fn step_scene() -> (PyramidLevel<'static>, Grid<f64>, [f64; 3]) {
        let (w, h) = (64, 16);
        let camera = Intrinsics::centred(64.0, w, h);
        let depth = Grid::from_fn(w, h, |c, _| if c < 32 { 1.0 } else { 2.0 });
        let level = PyramidLevel {
            geometry: LevelGeometry::new(w, h, w, h, camera),
            image: std::borrow::Cow::Owned(Grid::filled(w, h, 0.5)),
            confidence: Confidence::from_grid(Grid::filled(w, h, 1.0), Cancel::NEVER)
                .expect("never cancelled"),
            domain: Grid::filled(w, h, true),
        };
        (level, depth, [-2.0, 0.0, 0.5])
    }

    #[test]
    fn a_shadow_bridged_in_front_of_the_light_is_pushed_back_onto_the_occluders_ray() {
        let (level, truth, light) = step_scene();
        let (w, h) = truth.size();
        let shadow_truth = crate::occlusion::cast_shadow(&truth, level.geometry.camera, light);
        let shadowed = shadow_truth.as_slice().iter().filter(|&&s| s).count();
        assert!(shadowed > 50, "the wall casts a shadow on the floor");
        // A fill that bridges the shadow: the floor's shadowed part pulled
        // forward to the wall's depth, where the light would reach it.
        let mut bridged = Grid::from_fn(w, h, |c, r| match *shadow_truth.at(c, r) {
            true => 1.0,
            false => *truth.at(c, r),
        });
        let lights = [PointLight {
            position: light,
            ..PointLight::CENTRED
        }];
        let moved =
            enforce(&level, &shadow_truth, &lights, &mut bridged, Cancel::NEVER).expect("never");
        assert!(moved > 0);
        for r in 0..h {
            for c in 0..w {
                let z = *bridged.at(c, r);
                assert!(z.is_finite());
                if *shadow_truth.at(c, r) {
                    // Behind the wall's edge ray, never behind the truth.
                    assert!(
                        z > 1.0 && z <= truth.at(c, r) * (1.0 + 1e-9),
                        "({c}, {r}): {z}"
                    );
                }
            }
        }
        // The bounded surface lies on the ray that grazes the wall's edge:
        // half a percent farther back, it is in shadow again.
        let nudged = Grid::from_fn(w, h, |c, r| match *shadow_truth.at(c, r) {
            true => bridged.at(c, r) * 1.005,
            false => *bridged.at(c, r),
        });
        let again = crate::occlusion::cast_shadow(&nudged, level.geometry.camera, light);
        let kept = shadow_truth
            .as_slice()
            .iter()
            .zip(again.as_slice())
            .filter(|(t, a)| **t && **a)
            .count();
        assert!(
            kept as f64 >= 0.95 * shadowed as f64,
            "{kept} of {shadowed}"
        );
    }

    /// A ball lit from the side: its far side is in attached shadow.
    #[test]
    fn an_attached_shadow_keeps_the_truth_within_a_pixel_of_the_terminator() {
        let (w, h) = (96, 96);
        let camera = Intrinsics::centred(96.0, w, h);
        let (radius, centre_z) = (0.5, 2.0);
        let truth = Grid::from_fn(w, h, |c, r| {
            let (x, y) = camera.image_xy(c as f64, r as f64);
            let d = DVec3::new(x / 96.0, y / 96.0, 1.0);
            // The nearer intersection of the viewing ray with the ball.
            let b = d.z * centre_z;
            let disc = b * b - d.length_squared() * (centre_z * centre_z - radius * radius);
            match disc >= 0.0 {
                true => (b - disc.sqrt()) / d.length_squared(),
                false => f64::NAN,
            }
        });
        let domain = truth.map(|z| z.is_finite());
        let light = DVec3::new(-3.0, 0.0, 1.0);
        // Shadow: the ball's points facing away from the light.
        let shadow = Grid::from_fn(w, h, |c, r| {
            let z = *truth.at(c, r);
            let (x, y) = camera.image_xy(c as f64, r as f64);
            let p = DVec3::new(x / 96.0 * z, y / 96.0 * z, z);
            z.is_finite() && (p - DVec3::new(0.0, 0.0, centre_z)).dot(light - p) <= 0.0
        });
        assert!(shadow.as_slice().iter().filter(|&&s| s).count() > 200);
        let level = PyramidLevel {
            geometry: LevelGeometry::new(w, h, w, h, camera),
            image: std::borrow::Cow::Owned(Grid::filled(w, h, 0.5)),
            confidence: Confidence::from_grid(
                domain.map(|&d| f64::from(u8::from(d))),
                Cancel::NEVER,
            )
            .expect("never cancelled"),
            domain,
        };
        let mut depth = truth.clone();
        let lights = [PointLight {
            position: light.to_array(),
            ..PointLight::CENTRED
        }];
        enforce(&level, &shadow, &lights, &mut depth, Cancel::NEVER).expect("never");
        let moved_most = depth
            .as_slice()
            .iter()
            .zip(truth.as_slice())
            .filter(|(_, t)| t.is_finite())
            .map(|(z, t)| (z - t).abs() / t)
            .fold(0.0, f64::max);
        // A pixel at the ball's rim spans about 1/96 of its depth.
        assert!(
            moved_most < 0.01,
            "the truth moved by {moved_most} of its depth"
        );
    }

    #[test]
    fn the_truth_is_never_moved() {
        let (level, truth, light) = step_scene();
        let shadow = crate::occlusion::cast_shadow(&truth, level.geometry.camera, light);
        let mut depth = truth.clone();
        let lights = [PointLight {
            position: light,
            ..PointLight::CENTRED
        }];
        let moved = enforce(&level, &shadow, &lights, &mut depth, Cancel::NEVER).expect("never");
        assert_eq!(moved, 0);
        assert_eq!(depth, truth);
    }
}
