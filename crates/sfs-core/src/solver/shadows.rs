//! Shadows as information, not brightness: with lights off the optical
//! centre, the object pixels no light reaches (near-black against the
//! image's reference brightness; in noise, within the noise of black in the
//! pixel and in its 5x5 mean) are taken out of the data term before the
//! solve, and the solve reports them. A light at the optical centre sees
//! every point it lights: nothing is taken out. The viewer's and the CLI's
//! "suggest confidence" use the same detection ([`shadow_mask`]).

use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::LevelGeometry;
use crate::params::{DomainMode, ProblemScales};

use super::problem::{Problem, SolveError};
use super::pyramid::PyramidLevel;

/// The shadow taken out of `level` (the full image of `problem`, its
/// confidence lowered to 0 there; `None` with the light at the optical
/// centre) and the image's relative noise level, estimated after black
/// pixels went (a black region reads as noise-free and would lower the
/// automatic alpha) and before pixels within the noise of black go.
pub(crate) fn take_out(
    problem: &Problem,
    level: &mut PyramidLevel,
    scales: &ProblemScales,
    cancel: Cancel<'_>,
) -> Result<(Option<Grid<bool>>, f64), Cancelled> {
    let (w, h) = problem.image.size();
    let mut shadow = (!problem.light_is_centred()).then(|| Grid::filled(w, h, false));
    if let Some(shadow) = &mut shadow {
        take_out_shadows(
            problem,
            level,
            shadow,
            shadow_threshold(scales.intensity),
            cancel,
        )?;
    }
    let relative_noise = super::auto_alpha::relative_noise(level, scales, cancel)?;
    if let Some(shadow) = &mut shadow
        && SHADOW_NOISE_SIGMAS * relative_noise > SHADOW_BLACK
    {
        take_out_noisy_shadows(
            problem,
            level,
            shadow,
            scales.intensity * SHADOW_NOISE_SIGMAS * relative_noise,
            scales.intensity * SHADOW_MEAN_SIGMAS * relative_noise,
            cancel,
        )?;
    }
    Ok((shadow, relative_noise))
}

/// The object pixels a solve of `problem` takes out of the data term as
/// shadow (see the module); `None` with the light at the optical centre.
/// Validates the problem as the solve does.
pub fn shadow_mask(
    problem: &Problem,
    domain: DomainMode,
    cancel: Cancel<'_>,
) -> Result<Option<Grid<bool>>, SolveError> {
    if problem.light_is_centred() {
        return Ok(None);
    }
    let (domain, confidence) = problem.validate(domain, None, cancel)?;
    let scales = problem.scales(&confidence, cancel)?;
    let (w, h) = problem.image.size();
    let mut level = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, problem.camera),
        image: std::borrow::Cow::Borrowed(&problem.image),
        confidence: Confidence::from_grid(confidence, cancel)?,
        domain,
    };
    Ok(take_out(problem, &mut level, &scales, cancel)?.0)
}

/// Below this share of the image's reference brightness (a patch facing
/// the light at the median depth) a pixel is black: the light does not
/// reach it (`N . L` of 0.02 is 89 degrees).
pub const SHADOW_BLACK: f64 = 0.02;
/// In noise, a shadow pixel is at most this many noise levels bright...
pub const SHADOW_NOISE_SIGMAS: f64 = 3.0;
/// ... and the mean of its 5x5 neighbourhood on the object at most this
/// many: black clipped at 0 has a mean of 0.4 noise levels, and 25 pixels
/// average its spread (0.58) down to 0.12.
pub const SHADOW_MEAN_SIGMAS: f64 = 0.6;
/// Half the side of that neighbourhood.
const SHADOW_MEAN_RADIUS: usize = 2;

/// The brightness at or below which an object pixel is black, from the
/// reference brightness `intensity_ref` (as `auto_alpha` reads it):
/// [`SHADOW_BLACK`] of it. Scales with the exposure, so the same pixels are
/// shadow at every exposure.
pub fn shadow_threshold(intensity_ref: f64) -> f64 {
    intensity_ref * SHADOW_BLACK
}

/// [`take_out_shadows`] in noise: trusted object pixels at most `pixel_max`
/// bright whose 5x5 object neighbourhood averages at most `mean_max`.
fn take_out_noisy_shadows(
    problem: &Problem,
    level: &mut PyramidLevel,
    shadow: &mut Grid<bool>,
    pixel_max: f64,
    mean_max: f64,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    let (w, h) = problem.image.size();
    let object = problem.object_mask.as_ref();
    let on = |c: usize, r: usize| object.is_none_or(|m| *m.at(c, r));
    // Integral images of the object's brightness and pixel count.
    let mut sum = vec![0.0; (w + 1) * (h + 1)];
    let mut count = vec![0.0; (w + 1) * (h + 1)];
    for r in 0..h {
        if r % 64 == 0 {
            cancel.check()?;
        }
        for c in 0..w {
            let (v, n) = if on(c, r) {
                (*problem.image.at(c, r), 1.0)
            } else {
                (0.0, 0.0)
            };
            let q = (r + 1) * (w + 1) + c + 1;
            sum[q] = v + sum[q - 1] + sum[q - (w + 1)] - sum[q - (w + 1) - 1];
            count[q] = n + count[q - 1] + count[q - (w + 1)] - count[q - (w + 1) - 1];
        }
    }
    let boxed = |table: &[f64], c: usize, r: usize| {
        let (c0, r0) = (
            c.saturating_sub(SHADOW_MEAN_RADIUS),
            r.saturating_sub(SHADOW_MEAN_RADIUS),
        );
        let (c1, r1) = (
            (c + SHADOW_MEAN_RADIUS + 1).min(w),
            (r + SHADOW_MEAN_RADIUS + 1).min(h),
        );
        table[r1 * (w + 1) + c1] - table[r0 * (w + 1) + c1] - table[r1 * (w + 1) + c0]
            + table[r0 * (w + 1) + c0]
    };
    take_out_where(problem, level, shadow, cancel, |c, r| {
        *problem.image.at(c, r) <= pixel_max && boxed(&sum, c, r) <= mean_max * boxed(&count, c, r)
    })
}

/// Sets the confidence of the trusted object pixels of `level` whose
/// brightness is at most `threshold` to 0 (shadow: no light reaches them,
/// so there is no brightness to match), marks them in `shadow` and returns
/// how many.
fn take_out_shadows(
    problem: &Problem,
    level: &mut PyramidLevel,
    shadow: &mut Grid<bool>,
    threshold: f64,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    take_out_where(problem, level, shadow, cancel, |c, r| {
        *problem.image.at(c, r) <= threshold
    })
}

/// Sets the confidence of the trusted object pixels of `level` where
/// `dark(column, row)` to 0, marks them in `shadow`, returns how many.
fn take_out_where(
    problem: &Problem,
    level: &mut PyramidLevel,
    shadow: &mut Grid<bool>,
    cancel: Cancel<'_>,
    dark: impl Fn(usize, usize) -> bool,
) -> Result<usize, Cancelled> {
    let (w, h) = problem.image.size();
    let object = problem.object_mask.as_ref();
    let mut count = 0;
    let mut confidence = Grid::filled(w, h, 0.0);
    for r in 0..h {
        if r % 64 == 0 {
            cancel.check()?;
        }
        for c in 0..w {
            let q = r * w + c;
            let weight = level.confidence.weight(q);
            let on_object = object.is_none_or(|m| *m.at(c, r));
            // (pixels already taken out have weight 0: not counted again)
            let taken = weight > 0.0 && on_object && dark(c, r);
            count += usize::from(taken);
            if taken {
                *shadow.at_mut(c, r) = true;
            }
            *confidence.at_mut(c, r) = if taken { 0.0 } else { weight };
        }
    }
    if count > 0 {
        level.confidence = Confidence::from_grid(confidence, cancel)?;
    }
    Ok(count)
}
