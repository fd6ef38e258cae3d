//! What the data terms leave out, decided from the surface as it stands:
//! the Cauchy scale of the residuals and each photograph's cast shadows.

use rayon::prelude::*;

use super::level::{Level, MAX_PHOTOS, Observation, Scales, Shared};
use super::run::depth_grid;
use crate::light::PointLight;

/// Cast shadows are traced on a copy of the surface at most this many
/// pixels on its longest side (shadows are large; tracing is quadratic).
const SHADOW_SIDE: usize = 128;
/// The Cauchy scale never falls below this share of the brightness (a
/// render's residuals are round-off).
const MIN_ROBUST_SCALE: f64 = 5e-3;

/// The Cauchy scale from the residuals of the current surface: 2.385 (95 %
/// efficiency under Gaussian noise) times the MAD's estimate of their
/// spread, at least [`MIN_ROBUST_SCALE`] of the brightness.
#[allow(clippy::too_many_arguments)]
pub(super) fn auto_robust_scale(
    dark_level: f64,
    level: &Level,
    lights: &[PointLight],
    intensities: &[f64],
    cast: &[Vec<bool>],
    zeta: &[f64],
    m: &[f64],
    brightness: f64,
) -> f64 {
    let shared = Shared::new(
        lights,
        intensities,
        cast,
        Scales {
            robust_scale: 1e3 * brightness,
            dark_level,
            brightness,
            alpha: 0.0,
            lambda: 1.0,
        },
    );
    let pixels = level.domain.iter().filter(|&&d| d).count().max(1);
    let stride = (pixels / 20_000).max(1);
    let mut residuals: Vec<f64> = (0..zeta.len())
        .into_par_iter()
        .step_by(stride)
        .flat_map_iter(|p| {
            let mut out = Vec::new();
            if level.domain[p] {
                let mut obs = [Observation::default(); MAX_PHOTOS];
                let n = level.observe(&shared, zeta, p, 0.0, &mut obs).n;
                let fit = Level::fit_pixel(&shared, &mut obs[..n], m[p]);
                for o in &obs[..n] {
                    if o.weight > 0.0 {
                        out.push((fit.m * o.u - o.value).abs());
                    }
                }
            }
            out
        })
        .collect();
    let floor = MIN_ROBUST_SCALE * brightness;
    if residuals.is_empty() {
        return floor;
    }
    let k = residuals.len() / 2;
    let (_, median, _) = residuals.select_nth_unstable_by(k, f64::total_cmp);
    (2.385 * 1.4826 * *median).max(floor)
}

/// Cast shadows per photograph, traced at one size.
#[derive(Clone, Default)]
pub(super) struct CastShadows {
    size: (usize, usize),
    masks: Vec<Vec<bool>>,
}

/// Each photograph's cast shadow for `level`: traced on the surface at this
/// level when it is at most [`SHADOW_SIDE`] pixels (or nothing was traced
/// yet), else the last traced one kept. Lights at the optical centre cast
/// none.
pub(super) fn cast_shadows(
    level: &Level,
    lights: &[PointLight],
    zeta: &[f64],
    previous: CastShadows,
) -> CastShadows {
    if level.width.max(level.height) > SHADOW_SIDE && !previous.masks.is_empty() {
        return previous;
    }
    let depth = depth_grid(level, zeta);
    let masks = lights
        .iter()
        .map(|light| {
            if light.is_centred() {
                return vec![false; zeta.len()];
            }
            crate::occlusion::cast_shadow(&depth, level.camera, light.position).into_vec()
        })
        .collect();
    CastShadows {
        size: (level.width, level.height),
        masks,
    }
}

/// Shadow masks (traced at any size) resampled to `level` by the nearest
/// pixel.
pub(super) fn cast_for(cast: &CastShadows, level: &Level) -> Vec<Vec<bool>> {
    let (w, h) = (level.width, level.height);
    let (mw, mh) = cast.size;
    cast.masks
        .iter()
        .map(|mask| {
            if (mw, mh) == (w, h) {
                return mask.clone();
            }
            (0..w * h)
                .map(|p| {
                    let (c, r) = (p % w, p / w);
                    let mc = (((c as f64 + 0.5) * mw as f64 / w as f64) as usize).min(mw - 1);
                    let mr = (((r as f64 + 0.5) * mh as f64 / h as f64) as usize).min(mh - 1);
                    mask[mr * mw + mc]
                })
                .collect()
        })
        .collect()
}
