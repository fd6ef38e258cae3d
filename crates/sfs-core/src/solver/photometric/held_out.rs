//! Each photograph of a set held out and predicted from the others (issue
//! 48): the set is solved again without it, briefly, at a coarse level,
//! and its photograph compared with what that surface and albedo predict
//! under its light as given. A wrong intensity in the camera file (or a
//! wrong exposure) shows as a scale, an ambient frame or black level only
//! this photograph carries as an offset. The whole-set fit cannot show
//! them: the surface compromises and spreads the fault over every
//! photograph. Judged by [`super::held_out_warning`].

use glam::DVec3;
use rayon::prelude::*;

use super::level::{Level, MAX_PHOTOS, Observation, Scales, Shared, USED, light_vector};
use super::run::{LevelRun, run_level};
use crate::light::PointLight;
use crate::solver::problem::{SolveError, SolveObserver};
use crate::solver::working::CancelOnly;

/// The held-out check runs on the finest level whose longest side is at
/// most this many pixels (the shape there is what the check needs, and a
/// photograph's scale or offset is the same at every size).
pub(super) const HELD_OUT_SIDE: usize = 64;
/// Sets of fewer photographs are not checked: four leave three to solve
/// with, which determine albedo and slopes with nothing over, and in the
/// corpus (docs/photometric-fit.md) 11 of 23 clean 4-LED sets named a
/// photograph.
pub(super) const HELD_OUT_MIN_PHOTOS: usize = 5;
/// Linearisations of each solve without one photograph (from the set's
/// surface at that level).
const HELD_OUT_ITERATIONS: usize = 4;

/// What the other photographs predict of one photograph `I` (the
/// prediction `P`), over its lit, trusted object pixels: `I = scale P` or
/// `I = P + offset`, whichever fits better.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HeldOutFit {
    /// Observed over predicted (the fitted slope). NaN: not measured.
    pub scale: f64,
    /// The fitted offset over the photograph's brightness (its 99th
    /// percentile on those pixels). NaN: not measured.
    pub offset: f64,
    /// Whether the offset explains the photograph better than the scale
    /// (the smaller residual of the two one-parameter fits).
    pub offset_better: bool,
    /// How well the other photographs fit each other without it: their
    /// relative residual `||prediction - I|| / ||I||` over their used
    /// observations. The photograph at fault is the one without which the
    /// others fit best. NaN: not measured.
    pub rest_residual: f64,
}

impl HeldOutFit {
    /// Not measured.
    pub const NONE: HeldOutFit = HeldOutFit {
        scale: f64::NAN,
        offset: f64::NAN,
        offset_better: false,
        rest_residual: f64::NAN,
    };
}

/// The state of the set's solve at the level the check runs on.
pub(super) struct Snapshot {
    pub zeta: Vec<f64>,
    pub m: Vec<f64>,
    pub intensities: Vec<f64>,
    pub cast: Vec<Vec<bool>>,
    pub scales: Scales,
}

/// Each photograph held out in turn: the set without it solved from
/// `snapshot` on `level` (at most [`HELD_OUT_ITERATIONS`] linearisations;
/// the distance is the set's, which the linearisations move), and the photograph fitted against that
/// surface's prediction. A set of fewer than [`HELD_OUT_MIN_PHOTOS`]
/// photographs: [`HeldOutFit::NONE`] for each.
pub(super) fn held_out_fits(
    level: &Level,
    lights: &[PointLight],
    snapshot: &Snapshot,
    observer: &mut dyn SolveObserver,
) -> Result<Vec<HeldOutFit>, SolveError> {
    let count = level.photos();
    if count < HELD_OUT_MIN_PHOTOS {
        return Ok(vec![HeldOutFit::NONE; count]);
    }
    // Each photograph's check on its own thread, the observer heard for
    // cancellation only (the checks report nothing), read in order.
    let shared_observer: &dyn SolveObserver = observer;
    let fit_without = |k: usize| -> Result<HeldOutFit, SolveError> {
        let without = |all: &[Vec<f64>]| -> Vec<Vec<f64>> {
            all.iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, v)| v.clone())
                .collect()
        };
        let others = Level {
            width: level.width,
            height: level.height,
            camera: level.camera,
            domain: level.domain.clone(),
            images: without(&level.images),
            weights: without(&level.weights),
        };
        let other_lights: Vec<PointLight> = skip(lights, k);
        let mut other_intensities: Vec<f64> = skip(&snapshot.intensities, k);
        let other_cast: Vec<Vec<bool>> = if snapshot.cast.len() == count {
            skip(&snapshot.cast, k)
        } else {
            Vec::new()
        };
        let mut zeta = snapshot.zeta.clone();
        let mut m = snapshot.m.clone();
        run_level(
            &others,
            &other_lights,
            &mut other_intensities,
            false,
            &other_cast,
            snapshot.scales,
            &mut zeta,
            &mut m,
            LevelRun {
                max_iterations: HELD_OUT_ITERATIONS,
                search_distance: false,
                report: None,
            },
            &mut CancelOnly(shared_observer),
        )?;
        let shared = Shared::new(
            &other_lights,
            &other_intensities,
            &other_cast,
            snapshot.scales,
        );
        let cast = snapshot.cast.get(k).map(Vec::as_slice);
        let rest_residual = used_residual(&others, &shared, &zeta, &m);
        let fit = fit_held_out(
            level,
            &others,
            &shared,
            &zeta,
            &m,
            k,
            (&lights[k], snapshot.intensities[k]),
            cast,
        );
        Ok(HeldOutFit {
            rest_residual,
            ..fit
        })
    };
    (0..count).into_par_iter().map(fit_without).collect()
}

/// The relative residual of all of `level`'s photographs over their used
/// observations.
fn used_residual(level: &Level, shared: &Shared<'_>, zeta: &[f64], m: &[f64]) -> f64 {
    let (mut r2, mut i2) = (0.0, 0.0);
    for (p, observed) in level.residuals(shared, zeta, m).iter().enumerate() {
        for (j, &(r, _, why)) in observed.iter().enumerate() {
            if why == USED {
                r2 += r * r;
                i2 += level.images[j][p] * level.images[j][p];
            }
        }
    }
    if i2 > 0.0 { (r2 / i2).sqrt() } else { f64::NAN }
}

/// `values` without its `k`-th.
fn skip<T: Clone>(values: &[T], k: usize) -> Vec<T> {
    values
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != k)
        .map(|(_, v)| v.clone())
        .collect()
}

/// Photograph `k` of `level` against the prediction of the surface `zeta`
/// and albedo factor `m` solved from `others` (the level without it):
/// over its trusted pixels that its light (`light`, `intensity`) reaches
/// and the others explain, its scale and offset ([`fit_line`]).
#[allow(clippy::too_many_arguments)]
fn fit_held_out(
    level: &Level,
    others: &Level,
    shared: &Shared<'_>,
    zeta: &[f64],
    m: &[f64],
    k: usize,
    (light, intensity): (&PointLight, f64),
    cast: Option<&[bool]>,
) -> HeldOutFit {
    let f = level.camera.focal_px;
    let pairs: Vec<(f64, f64)> = (0..zeta.len())
        .into_par_iter()
        .with_min_len(256)
        .filter_map(|p| {
            let weight = level.weights[k][p];
            if !level.domain[p] || weight <= 0.0 || m[p] <= 0.0 || cast.is_some_and(|c| c[p]) {
                return None;
            }
            // The gradient the others chose here, and this light's shading
            // of it.
            let mut obs = [Observation::default(); MAX_PHOTOS];
            let g = others.observe(shared, zeta, p, 0.0, &mut obs).g;
            let (x, y) = level
                .camera
                .image_xy((p % level.width) as f64, (p / level.width) as f64);
            let z = zeta[p].exp();
            let point = DVec3::new(z * x / f, z * y / f, z);
            let (l, _) = light_vector(light, intensity, point);
            let u = (f * l.x - x * l.z) * g[0] + (f * l.y - y * l.z) * g[1] - l.z;
            (u > 0.0).then(|| (m[p] * u, level.images[k][p]))
        })
        .collect();
    fit_line(&pairs)
}

/// Fewer pixels than this: no fit.
const MIN_PIXELS: usize = 16;

/// The two explanations of a photograph by its prediction, through
/// `(predicted, observed)` pairs: a scale (`observed = scale predicted`,
/// least squares) or an offset (`observed = predicted + offset`, the mean
/// difference, over the 99th percentile of the observed values), and
/// whether the offset leaves the smaller residual. Each has one
/// parameter: a line with both a slope and an intercept pivots about the
/// mean, and the prediction's own errors (the others' surface is not
/// exact) flatten its slope; through the origin they barely do.
/// [`HeldOutFit::NONE`] with too few pairs or no prediction.
fn fit_line(pairs: &[(f64, f64)]) -> HeldOutFit {
    if pairs.len() < MIN_PIXELS {
        return HeldOutFit::NONE;
    }
    let n = pairs.len() as f64;
    let (mut pp, mut po, mut difference) = (0.0, 0.0, 0.0);
    for (p, o) in pairs {
        pp += p * p;
        po += p * o;
        difference += o - p;
    }
    if pp.is_nan() || pp <= 0.0 {
        return HeldOutFit::NONE;
    }
    let scale = po / pp;
    let offset = difference / n;
    let (mut scaled, mut shifted) = (0.0, 0.0);
    for (p, o) in pairs {
        scaled += (o - scale * p).powi(2);
        shifted += (o - p - offset).powi(2);
    }
    let mut observed: Vec<f64> = pairs.iter().map(|(_, o)| *o).collect();
    let at = ((observed.len() - 1) as f64 * 0.99).round() as usize;
    let (_, top, _) = observed.select_nth_unstable_by(at, f64::total_cmp);
    if top.is_nan() || *top <= 0.0 {
        return HeldOutFit::NONE;
    }
    HeldOutFit {
        scale,
        offset: offset / *top,
        offset_better: shifted < scaled,
        rest_residual: f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A photograph at half the predicted brightness is explained by a
    /// scale of 0.5; one with a constant added, by that offset over its
    /// brightness; too few pixels, no fit.
    #[test]
    fn the_fits_separate_a_scale_from_an_offset() {
        let predicted: Vec<f64> = (0..200).map(|k| 0.1 + k as f64 / 200.0).collect();
        let halved: Vec<(f64, f64)> = predicted.iter().map(|&p| (p, 0.5 * p)).collect();
        let fit = fit_line(&halved);
        assert!(
            (fit.scale - 0.5).abs() < 1e-9 && !fit.offset_better,
            "{fit:?}"
        );
        let lifted: Vec<(f64, f64)> = predicted.iter().map(|&p| (p, p + 0.2)).collect();
        let fit = fit_line(&lifted);
        let top = lifted[(199.0f64 * 0.99).round() as usize].1;
        assert!(fit.offset_better, "{fit:?}");
        assert!((fit.offset - 0.2 / top).abs() < 1e-9, "{fit:?}");
        assert!(fit_line(&halved[..MIN_PIXELS - 1]).scale.is_nan());
    }
}
