//! The fronto-parallel plane a start begins from: the depth of the plane
//! whose rendering best fits a set of pixels ([`plane_fit`]) and the
//! nearest depth an object lit by the given lights is assumed to be at
//! ([`nearest_object_depth`]). Shared by the core's start (`prepare`) and
//! the light-frame start (`light_frame`), below both. Uses `model` and
//! `light` only.

use crate::model::{self, Reflectance};

/// The depth `z0 >= nearest` of the fronto-parallel plane whose rendering
/// under `model` best fits `pixels` (ray and brightness) in least squares:
/// a scan over six decades around `guess`, refined by golden sections on
/// `log z0`.
pub(crate) fn plane_fit<M: Reflectance>(
    pixels: &[(model::PixelRay, f64)],
    model: &M,
    guess: f64,
    nearest: f64,
) -> f64 {
    let floor = nearest.max(0.0);
    let cost = |log_z: f64| -> f64 {
        let z = log_z.exp();
        if z < floor {
            return f64::INFINITY;
        }
        pixels
            .iter()
            .map(|(ray, i)| {
                let d = i - model.radiance(ray, z, 0.0, 0.0);
                d * d
            })
            .sum()
    };
    if pixels.is_empty() || !(guess.is_finite() && guess > 0.0) {
        return guess.max(1e-9);
    }
    let centre = guess.ln();
    let (steps, span) = (121, 3.0 * std::f64::consts::LN_10);
    let step = 2.0 * span / (steps - 1) as f64;
    let best = (0..steps)
        .map(|k| centre - span + k as f64 * step)
        .map(|log_z| (log_z, cost(log_z)))
        .filter(|(_, c)| c.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(centre, |(log_z, _)| log_z);
    let (mut a, mut b) = (best - step, best + step);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..40 {
        let (m1, m2) = (b - ratio * (b - a), a + ratio * (b - a));
        if cost(m1) <= cost(m2) {
            b = m2;
        } else {
            a = m1;
        }
    }
    (0.5 * (a + b)).exp()
}

/// The nearest distance an object lit by `lights` is assumed to be at: every
/// light within 45 degrees of the optical axis as seen from the object
/// (`z >= S_z + |S_xy|`). A plane nearer than that, lit at grazing angles,
/// can explain a smooth image as well as the true distance does; the
/// set-ups this tool serves (a flash or LEDs beside the lens) light the
/// object from the camera's side.
pub fn nearest_object_depth(lights: &[crate::light::PointLight]) -> f64 {
    lights
        .iter()
        .map(|l| l.position[2] + l.off_axis())
        .fold(0.0, f64::max)
}
