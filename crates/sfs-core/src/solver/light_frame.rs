//! The fast-marching start for lights off the optical centre, marched in the
//! light's own frame.
//!
//! Fast marching solves the model of a light at the optical centre. A point
//! light anywhere is at the optical centre of a *virtual* camera placed at
//! the light: seen from there, the same surface has the same brightness at
//! each of its points, and the model is the paper's (METHOD.md section 9
//! with `S` the virtual camera's origin). So the image is carried over to a
//! virtual camera at the light (looking at the object, with the real
//! camera's pixel size at the object), fast marching solves it there, and
//! the marched surface is carried back to the real camera's pixels.
//!
//! Carrying a pixel between the two cameras needs its depth (parallax): the
//! first pass uses the fronto-parallel plane that best explains the image,
//! the second the surface of the first. Parallax scales with the light's
//! offset times the depth's relative error, so two passes suffice for the
//! set-ups served (a flash, LEDs or a ring beside the lens).
//!
//! Several lights are replaced by one at their intensity-weighted centroid
//! (a ring around the lens marches as a centred light); what does not depend
//! on the surface's normal (each LED's anisotropy, each light's distance) is
//! divided out of the image before marching, with the normal facing that
//! centroid. The linearised scheme then refines the start with the true
//! lights.

use glam::{DMat3, DVec3};

use crate::camera::Intrinsics;
use crate::cancel::Cancel;
use crate::grid::Grid;
use crate::light::PointLight;

use super::fast_marching::{FastMarchingParams, march};
use super::problem::SolveError;

/// The virtual camera at a light: origin, rotation (rows: its x, y and
/// optical axes in the real camera's frame) and pinhole intrinsics (on a
/// grid that spans the object's projection, see `LightFrame::passes`).
struct VirtualCamera {
    origin: DVec3,
    rotation: DMat3,
    intrinsics: Intrinsics,
}

impl VirtualCamera {
    /// Looking from `origin` at `target`, with the real camera's pixel size
    /// at `target` and `target` at the real camera's pixel of it.
    fn looking_at(origin: DVec3, target: DVec3, real: Intrinsics) -> Option<Self> {
        let axis = (target - origin).normalize_or_zero();
        let down = DVec3::Y - DVec3::Y.dot(axis) * axis;
        let down = down.normalize_or_zero();
        if axis == DVec3::ZERO || down == DVec3::ZERO || target.z <= 0.0 {
            return None;
        }
        let right = down.cross(axis);
        let rotation = DMat3::from_cols(right, down, axis).transpose();
        let (cx, cy) = project(real, target)?;
        Some(Self {
            origin,
            rotation,
            intrinsics: Intrinsics {
                focal_px: real.focal_px * (target - origin).length() / target.z,
                principal_x_px: cx,
                principal_y_px: cy,
            },
        })
    }

    /// The virtual pixel `(column, row)` of a real-frame point.
    fn project(&self, point: DVec3) -> Option<(f64, f64)> {
        project(self.intrinsics, self.rotation * (point - self.origin))
    }

    /// The real-frame point at virtual pixel `(column, row)` and virtual
    /// depth `depth` (along its optical axis).
    fn point(&self, column: f64, row: f64, depth: f64) -> DVec3 {
        let (x, y) = self.intrinsics.image_xy(column, row);
        let local = DVec3::from_array(self.intrinsics.back_project(x, y, depth));
        self.origin + self.rotation.transpose() * local
    }
}

/// The pixel `(column, row)` of a camera-frame point in front of the camera.
fn project(camera: Intrinsics, point: DVec3) -> Option<(f64, f64)> {
    (point.z > 0.0).then(|| {
        (
            camera.principal_x_px + camera.focal_px * point.x / point.z,
            camera.principal_y_px + camera.focal_px * point.y / point.z,
        )
    })
}

/// Largest angle at the object between the camera and the lights'
/// centroid, in degrees, for which the start is marched in the light's
/// frame. Beyond it (LEDs far beside the lens, nearer the object than the
/// camera) the light's camera sees the object at grazing angles, and the
/// start came out worse than the plane walked up the pyramid (the shared
/// face's LEDs are 33-61 degrees off).
pub const MAX_FRAME_ANGLE_DEG: f64 = 20.0;
/// Largest distance of a light in front of the camera (along the optical
/// axis), as a share of the object's, for which the start is marched in the
/// light's frame. The centred march that starts the passes puts the surface
/// about as far from the camera as it is from the light: in front of a
/// light more than half-way to the object, facing away from it, and the
/// passes do not carry that parallax over. A Sombrero disc 2 away with an
/// LED 0.1 off the axis (`tests/lights.rs`) at depth 0, 0.2, 0.4, 0.6, 0.8
/// and 1.05: the light's frame gave RSE 0.018, 0.015, 0.026, 0.074, 0.44
/// (the surface at 1.1) and 0.57 (at 0.86), the plane up the pyramid 0.096
/// at 0.6, 0.071 at 0.8 and 0.062 at 1.05. The shared face's LEDs are at
/// 60 % of its distance: with LED 4 and the scale of a 648 px known-depth
/// search the march put the face 29 cm away, in front of the LED, at 56
/// times the energy of a constant start at 66 cm.
pub const MAX_FRAME_DEPTH_SHARE: f64 = 1.0 / 3.0;
/// Pixels sampled for the plane that places the object.
const PLANE_SAMPLES: usize = 4096;

/// Whether the start for `problem` (lights off the centre) is marched in
/// the light's frame: every light is within [`MAX_FRAME_ANGLE_DEG`] of the
/// camera as seen from the object's centre, placed by the fronto-parallel plane that best explains the
/// trusted pixels of `level` (the full image; `guess` centres the plane's
/// scan).
pub(crate) fn serves(
    problem: &super::problem::Problem,
    level: &super::pyramid::PyramidLevel,
    guess: f64,
    material: crate::material::Material,
) -> bool {
    let (w, h) = (level.geometry.width, level.geometry.height);
    let on = |q: usize| {
        level.domain.as_slice()[q] && problem.object_mask.as_ref().is_none_or(|m| m.as_slice()[q])
    };
    let trusted: Vec<usize> = (0..w * h)
        .filter(|&q| on(q) && level.confidence.at(q % w, q / w) > 0.0)
        .collect();
    let stride = trusted.len().div_ceil(PLANE_SAMPLES).max(1);
    let pixels: Vec<_> = trusted
        .iter()
        .step_by(stride)
        .map(|&q| {
            (
                level.geometry.ray(q % w, q / w),
                *level.image.at(q % w, q / w),
            )
        })
        .collect();
    if pixels.is_empty() {
        return false;
    }
    let depth = super::plane_start::plane_fit(
        &pixels,
        &problem.model(material),
        guess,
        super::plane_start::nearest_object_depth(&problem.lights),
    );
    let camera = problem.camera;
    let (mut sum, mut count) = (DVec3::ZERO, 0usize);
    for q in (0..w * h).filter(|&q| on(q)) {
        let (x, y) = camera.image_xy((q % w) as f64, (q / w) as f64);
        sum += DVec3::new(x / camera.focal_px, y / camera.focal_px, 1.0);
        count += 1;
    }
    faces_the_frame(&problem.lights, depth * sum / count.max(1) as f64)
}

/// Whether every light is within [`MAX_FRAME_ANGLE_DEG`] of the camera as
/// seen from `centre` (a camera-frame point of the object) and at most
/// [`MAX_FRAME_DEPTH_SHARE`] of its depth in front of the camera: then their
/// centroid stands for them (a ring around the lens). Lights spread wider
/// (the shared face's seven LEDs, centroid near the axis but each 33-61
/// degrees off) are not one light anywhere.
pub(crate) fn faces_the_frame(lights: &[PointLight], centre: DVec3) -> bool {
    lights.iter().all(|l| {
        (-centre)
            .angle_between(DVec3::from_array(l.position) - centre)
            .to_degrees()
            <= MAX_FRAME_ANGLE_DEG
            && l.position[2] <= MAX_FRAME_DEPTH_SHARE * centre.z
    })
}

/// The one light standing for `lights`: their intensity-weighted centroid
/// and total intensity.
fn centroid(lights: &[PointLight]) -> (DVec3, f64) {
    let total: f64 = lights.iter().map(|l| l.intensity).sum();
    let at = lights
        .iter()
        .map(|l| l.intensity * DVec3::from_array(l.position))
        .sum::<DVec3>()
        / total.max(f64::MIN_POSITIVE);
    (at, total)
}

/// The surface held as a camera-frame point per pixel of one camera's
/// `w x h` grid (`point`, `None` off it), drawn into another camera's
/// pixels: triangles between
/// neighbouring points (none across a depth step of more than
/// [`MAX_STEP`]), the nearest surface kept. Returns the target's depth
/// along its optical axis (NaN where nothing was drawn) and `value`
/// interpolated (in the target's pixels, `1/z` perspective-correct).
fn draw(
    (w, h): (usize, usize),
    point: impl Fn(usize, usize) -> Option<DVec3>,
    value: impl Fn(usize, usize) -> f64,
    target: &VirtualCamera,
    (target_width, target_height): (usize, usize),
) -> (Grid<f64>, Grid<f64>) {
    let mut depth = Grid::filled(target_width, target_height, f64::INFINITY);
    let mut drawn = Grid::filled(target_width, target_height, f64::NAN);
    // Each point in the target's frame: pixel, depth and value.
    let local = |c: usize, r: usize| -> Option<(f64, f64, f64, f64)> {
        let point = point(c, r)?;
        let inside = target.rotation * (point - target.origin);
        let (pc, pr) = project(target.intrinsics, inside)?;
        Some((pc, pr, inside.z, value(c, r)))
    };
    for r in 0..h.saturating_sub(1) {
        for c in 0..w.saturating_sub(1) {
            let corners = [
                local(c, r),
                local(c + 1, r),
                local(c, r + 1),
                local(c + 1, r + 1),
            ];
            for [a, b, d] in [[0, 1, 2], [1, 3, 2]] {
                let (Some(a), Some(b), Some(d)) = (corners[a], corners[b], corners[d]) else {
                    continue;
                };
                let (near, far) = (a.2.min(b.2).min(d.2), a.2.max(b.2).max(d.2));
                if far > near * (1.0 + MAX_STEP) {
                    continue;
                }
                fill_triangle([a, b, d], &mut depth, &mut drawn);
            }
        }
    }
    let depth = depth.map(|&z| if z.is_finite() { z } else { f64::NAN });
    (depth, drawn)
}

/// Largest relative depth difference within one drawn triangle.
const MAX_STEP: f64 = 0.05;

/// Rasterises one triangle (pixel, depth, value per corner) into `depth`
/// (nearest kept) and `drawn`, at pixel centres inside it.
fn fill_triangle(corners: [(f64, f64, f64, f64); 3], depth: &mut Grid<f64>, drawn: &mut Grid<f64>) {
    let (w, h) = depth.size();
    let [(x0, y0, z0, v0), (x1, y1, z1, v1), (x2, y2, z2, v2)] = corners;
    let area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
    if area.abs() < 1e-12 {
        return;
    }
    let lo_c = x0.min(x1).min(x2).ceil().max(0.0);
    let hi_c = x0.max(x1).max(x2).floor().min(w as f64 - 1.0);
    let lo_r = y0.min(y1).min(y2).ceil().max(0.0);
    let hi_r = y0.max(y1).max(y2).floor().min(h as f64 - 1.0);
    if lo_c > hi_c || lo_r > hi_r {
        return;
    }
    for r in lo_r as usize..=hi_r as usize {
        for c in lo_c as usize..=hi_c as usize {
            let (px, py) = (c as f64, r as f64);
            let l1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / area;
            let l2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / area;
            let l0 = 1.0 - l1 - l2;
            const EDGE: f64 = -1e-9;
            if l0 < EDGE || l1 < EDGE || l2 < EDGE {
                continue;
            }
            // 1/z is affine in the image of a planar triangle.
            let inverse = l0 / z0 + l1 / z1 + l2 / z2;
            if inverse <= 0.0 {
                continue;
            }
            let z = 1.0 / inverse;
            if z < *depth.at(c, r) {
                *depth.at_mut(c, r) = z;
                *drawn.at_mut(c, r) = z * (l0 * v0 / z0 + l1 * v1 / z1 + l2 * v2 / z2);
            }
        }
    }
}

/// Fast marching for `lights` (not all at the optical centre) on `image`
/// over `object` with intensity scale `intensity_scale`, marched in the
/// light's frame (see the module docs): [`COARSE_PASSES`] passes on a
/// working copy (longest side [`COARSE_SIDE`] or a quarter of the image's)
/// from the centred march, then one or two (up to [`SMALL_SIDE`]) on the
/// image itself. A value at every pixel (the object's marched depth, the
/// mean elsewhere). `None` where the set-up has no light frame to march in
/// (a light not well in front of the object).
pub(crate) fn march_from_the_light(
    image: &Grid<f64>,
    object: &Grid<bool>,
    camera: Intrinsics,
    intensity_scale: f64,
    lights: &[PointLight],
    settings: &FastMarchingParams,
    cancel: Cancel<'_>,
) -> Result<Option<Grid<f64>>, SolveError> {
    let (w, h) = image.size();
    let longest = w.max(h);
    let coarse_side = COARSE_SIDE.max(longest / 4);
    let fine_passes = if longest <= SMALL_SIDE { 2 } else { 1 };
    let (cw, ch) = crate::resample::working_size(w, h, Some(coarse_side));
    let frame = LightFrame {
        camera,
        intensity_scale,
        lights,
        settings,
        cancel,
    };
    if (cw, ch) == (w, h) {
        return frame.passes(image, object, None, COARSE_PASSES + fine_passes);
    }
    let resize = |grid: &Grid<f64>| crate::resample::resize_area(grid, cw, ch, cancel);
    let as_share = |mask: &Grid<bool>| mask.map(|&m| if m { 1.0 } else { 0.0 });
    let small_object = resize(&as_share(object))?.map(|&v| v >= 0.5);
    let small = LightFrame {
        camera: crate::resample::scale_intrinsics(camera, (w, h), (cw, ch)),
        ..frame
    };
    let Some(coarse) = small.passes(&resize(image)?, &small_object, None, COARSE_PASSES)? else {
        return Ok(None);
    };
    let start = super::pyramid::upsample_depth(&coarse, &small_object, object);
    frame.passes(image, object, Some(start), fine_passes)
}

/// Passes on the working copy.
const COARSE_PASSES: usize = 3;
/// Longest side of the working copy: at least this, else a quarter of the
/// image's.
const COARSE_SIDE: usize = 128;
/// Images up to this longest side take two passes on the image itself
/// (cheap there; the second takes the parallax of the fine detail right:
/// the Sombrero with a flash beside the lens 0.0050 -> 0.0034); larger ones
/// one (their working copy is a quarter of their side already).
const SMALL_SIDE: usize = 512;

/// What every pass shares.
#[derive(Clone, Copy)]
struct LightFrame<'a> {
    camera: Intrinsics,
    intensity_scale: f64,
    lights: &'a [PointLight],
    settings: &'a FastMarchingParams,
    cancel: Cancel<'a>,
}

impl LightFrame<'_> {
    /// `passes` passes from `start` (the centred march when `None`).
    fn passes(
        &self,
        image: &Grid<f64>,
        object: &Grid<bool>,
        start: Option<Grid<f64>>,
        passes: usize,
    ) -> Result<Option<Grid<f64>>, SolveError> {
        let LightFrame {
            camera,
            intensity_scale,
            lights,
            settings,
            cancel,
        } = *self;
        let (w, h) = image.size();
        let (light, total) = centroid(lights);
        let mut depth = match start {
            Some(depth) => depth,
            None => {
                march(
                    image,
                    camera,
                    object,
                    intensity_scale * total,
                    settings,
                    cancel,
                )?
                .0
            }
        };
        let ray = |c: usize, r: usize| {
            let (x, y) = camera.image_xy(c as f64, r as f64);
            DVec3::new(x / camera.focal_px, y / camera.focal_px, 1.0)
        };
        let on = |c: usize, r: usize| *object.at(c, r);
        for _ in 0..passes {
            cancel.check()?;
            // The object's centroid as the current surface places it.
            let (mut sum, mut count) = (DVec3::ZERO, 0usize);
            for q in (0..w * h).filter(|&q| object.as_slice()[q]) {
                sum += depth.as_slice()[q] * ray(q % w, q / w);
                count += 1;
            }
            if count == 0 {
                return Ok(None);
            }
            let target = sum / count as f64;
            // A light not well in front of the object has no frame to march
            // in (the object would not face it).
            if target.z - light.z < 0.1 * target.z {
                return Ok(None);
            }
            let Some(mut view) = VirtualCamera::looking_at(light, target, camera) else {
                return Ok(None);
            };
            let point = |c: usize, r: usize| on(c, r).then(|| *depth.at(c, r) * ray(c, r));
            // The light's camera frames the whole object: its grid spans the
            // object's projection (a pixel's margin), with at most twice the
            // image's pixel count (a coarser focal length where the light
            // sees the object larger).
            let span = |view: &VirtualCamera| {
                let (mut lo, mut hi) = (
                    (f64::INFINITY, f64::INFINITY),
                    (f64::NEG_INFINITY, f64::NEG_INFINITY),
                );
                for (c, r) in (0..h).flat_map(|r| (0..w).map(move |c| (c, r))) {
                    if let Some((pc, pr)) = point(c, r).and_then(|p| view.project(p)) {
                        lo = (lo.0.min(pc), lo.1.min(pr));
                        hi = (hi.0.max(pc), hi.1.max(pr));
                    }
                }
                (lo.0.is_finite() && hi.0.is_finite()).then(|| {
                    let (left, top) = (lo.0.floor() - 1.0, lo.1.floor() - 1.0);
                    (left, top, hi.0.ceil() + 2.0 - left, hi.1.ceil() + 2.0 - top)
                })
            };
            let Some((_, _, span_w, span_h)) = span(&view) else {
                return Ok(None);
            };
            let pixels = 2.0 * (w * h) as f64;
            if span_w * span_h > pixels {
                view.intrinsics.focal_px *= (pixels / (span_w * span_h)).sqrt();
            }
            let Some((left, top, span_w, span_h)) = span(&view) else {
                return Ok(None);
            };
            let vw = (span_w as usize).clamp(1, 2 * w);
            let vh = (span_h as usize).clamp(1, 2 * h);
            view.intrinsics.principal_x_px -= left;
            view.intrinsics.principal_y_px -= top;
            // The image as the light sees it: the current surface, carrying
            // the image, drawn into the light's camera (what the light does
            // not see is hidden behind what it does).
            let (seen_depth, mut seen) =
                draw((w, h), point, |c, r| *image.at(c, r), &view, (vw, vh));
            crate::grid::for_rows(seen.as_mut_slice(), vw, cancel, |r, row| {
                for (c, out) in row.iter_mut().enumerate() {
                    let z = *seen_depth.at(c, r);
                    if !(z.is_finite() && out.is_finite()) {
                        *out = f64::NAN;
                        continue;
                    }
                    let point = view.point(c as f64, r as f64, z);
                    let towards = light - point;
                    let d2 = towards.length_squared();
                    // What does not depend on the normal: the lights against
                    // one light of their total intensity at the centroid, for
                    // a patch facing it.
                    let factor = crate::light::irradiance(
                        lights,
                        point.to_array(),
                        (towards / d2.sqrt()).to_array(),
                    ) * d2
                        / total;
                    *out = if factor > 1e-6 {
                        *out / factor
                    } else {
                        f64::NAN
                    };
                }
            })?;
            let seen_object = seen.map(|&v| v.is_finite() && v > 0.0);
            if !seen_object.as_slice().iter().any(|&o| o) {
                return Ok(None);
            }
            let seen = seen.map(|&v| if v.is_finite() { v } else { 0.0 });
            let (marched, _) = march(
                &seen,
                view.intrinsics,
                &seen_object,
                intensity_scale * total,
                settings,
                cancel,
            )?;
            // Back to the real camera: the marched surface drawn into it;
            // what it does not cover (what the light does not see) takes the
            // thin-plate fill of what it does.
            let real = VirtualCamera {
                origin: DVec3::ZERO,
                rotation: DMat3::IDENTITY,
                intrinsics: camera,
            };
            let marched_point = |c: usize, r: usize| {
                seen_object
                    .at(c, r)
                    .then(|| view.point(c as f64, r as f64, *marched.at(c, r)))
            };
            let (back, _) = draw((vw, vh), marched_point, |_, _| 0.0, &real, (w, h));
            let mut known = Grid::filled(w, h, false);
            for (q, z) in depth.as_mut_slice().iter_mut().enumerate() {
                let drawn = back.as_slice()[q];
                if object.as_slice()[q] && drawn.is_finite() && drawn > 0.0 {
                    *z = drawn;
                    known.as_mut_slice()[q] = true;
                }
            }
            super::holes::thin_plate_fill(&mut depth, object, &known, cancel)?;
        }
        // The mean elsewhere, as fast marching leaves it.
        let (sum, count) = (0..w * h)
            .filter(|&q| object.as_slice()[q])
            .fold((0.0, 0usize), |(s, n), q| (s + depth.as_slice()[q], n + 1));
        let mean = sum / count.max(1) as f64;
        for (q, z) in depth.as_mut_slice().iter_mut().enumerate() {
            if !object.as_slice()[q] {
                *z = mean;
            }
        }
        Ok(Some(depth))
    }
}
