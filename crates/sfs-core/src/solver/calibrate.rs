//! The intensity scale `s` when it is not known (`--intensity-scale auto`).
//!
//! With every light at the optical centre `s` only sets the depth scale
//! (image and `s` times `k^2` give depth times `k`, exactly): one known
//! distance fixes it ([`solve_with_known_depths`]). With a light off the centre
//! the depth is metric and `s` is a real unknown: [`estimate_intensity_scale`]
//! searches the object distance `Z` whose scale `s(Z)` (a plane at `Z`
//! renders to the image's median brightness) lets the solver explain the
//! image best, on a small working copy of the problem.

use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::grid::Grid;
use crate::params::SolverParams;

use super::problem::{Problem, SolveError, SolveObserver};
use super::working::{CancelOnly, Forward, relative_residual, working_copy};

/// Longest side of the working copy the scale is searched on.
pub const SEARCH_SIDE: usize = 128;

/// The result of [`estimate_intensity_scale`].
#[derive(Clone, Debug, Serialize)]
pub struct ScaleEstimate {
    /// The estimated `s`.
    pub intensity_scale: f64,
    /// The object distance (median depth of the working solve) it implies.
    pub depth: f64,
    /// `(s, depth, relative residual)` of every trial, in search order.
    pub trials: Vec<(f64, f64, f64)>,
    /// True only when every trial more than [`SCALE_TOLERANCE`] away from
    /// the estimate, on both sides, explains the image worse by
    /// [`DETERMINED_RISE`]; false says the image does not determine `s`
    /// (give it, or `--known-depth`), and the depth unit is a guess.
    pub well_determined: bool,
}

/// The working copy of `problem` at [`SEARCH_SIDE`].
fn small(problem: &Problem) -> Problem {
    working_copy(problem, SEARCH_SIDE)
}

/// The median brightness over the object and the model's brightness of a
/// fronto-parallel plane at `depth` with `s = 1`, both at the object's pixels.
fn plane_ratio(problem: &Problem, depth: f64) -> Option<f64> {
    let (w, h) = problem.image.size();
    let unit = crate::light::LightModel::new(1.0, &problem.lights);
    let geometry = crate::model::LevelGeometry::new(w, h, w, h, problem.camera);
    let mut ratios = Vec::new();
    for r in 0..h {
        for c in 0..w {
            let on = problem.object_mask.as_ref().is_none_or(|m| *m.at(c, r));
            let trusted = problem
                .confidence
                .as_ref()
                .is_none_or(|m| *m.at(c, r) > 0.0);
            let i = *problem.image.at(c, r);
            if on && trusted && i > 0.0 {
                let rendered = crate::model::Reflectance::radiance(
                    &unit,
                    &geometry.ray(c, r),
                    depth,
                    0.0,
                    0.0,
                );
                if rendered > 0.0 {
                    ratios.push(i / rendered);
                }
            }
        }
    }
    if ratios.is_empty() {
        return None;
    }
    let middle = ratios.len() / 2;
    Some(*ratios.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// A trial solve of `work` at the intensity scale that shows a plane at
/// depth `exp(log_z)` with the image's median brightness: `(s, median
/// depth, relative residual sqrt(sum c (I - R)^2 / sum c I^2))`; `None`
/// where no pixel gives that scale. It hears only `observer`'s
/// cancellation (a trial is never solved twice: not kept in the memo).
fn trial_at(
    work: &Problem,
    log_z: f64,
    params: &SolverParams,
    observer: &dyn SolveObserver,
) -> Result<Option<(f64, f64, f64)>, SolveError> {
    let Some(s) = plane_ratio(work, log_z.exp()) else {
        return Ok(None);
    };
    let scaled = Problem {
        intensity_scale: s,
        ..work.clone()
    };
    let solution = super::method::solve(&scaled, params, &mut CancelOnly(observer))?;
    let mut depths = solution.depth.finite_values();
    let middle = depths.len() / 2;
    let depth = if depths.is_empty() {
        f64::NAN
    } else {
        *depths.select_nth_unstable_by(middle, f64::total_cmp).1
    };
    Ok(Some((s, depth, relative_residual(&scaled, &solution))))
}

/// Estimates `s` for a problem whose lights are off the optical centre (see
/// the module docs). The object distance is searched from the nearest the
/// lights allow ([`super::plane_start::nearest_object_depth`], at least half the
/// farthest light's distance from the camera) to 20 times that distance
/// (beyond, every light looks centred):
/// nine trials spaced evenly in `log Z`, then golden sections around the
/// best; `problem.intensity_scale` is ignored.
///
/// # Errors
/// As [`super::solve`]; `SolveError::Input` for centred lights (where `s`
/// is a choice of depth unit, not an unknown).
pub fn estimate_intensity_scale(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<ScaleEstimate, SolveError> {
    // `auto` is only a report (the solve stays Lambertian): the trials run
    // as Lambert, not comparing the materials again in each.
    let resolved = params.without_fit();
    let params = &resolved;
    if problem.light_is_centred() {
        return Err(SolveError::Input(
            "with every light at the optical centre the intensity scale only sets the depth \
             unit: give --known-depth, or any scale"
                .into(),
        ));
    }
    let work = small(problem);
    let reach = problem
        .lights
        .iter()
        .map(|l| DVec3::from_array(l.position).length())
        .fold(0.0, f64::max);
    let nearest = super::plane_start::nearest_object_depth(&problem.lights).max(0.5 * reach);
    let (lo, hi) = (nearest.ln(), (20.0 * reach).ln());
    let mut trials = Vec::new();
    // Each trial is kept; its value is its residual (infinite where there
    // is none).
    let keep = |found: Option<(f64, f64, f64)>, trials: &mut Vec<(f64, f64, f64)>| match found {
        None => f64::INFINITY,
        Some(trial) => {
            trials.push(trial);
            if trial.2.is_finite() {
                trial.2
            } else {
                f64::INFINITY
            }
        }
    };
    let steps = 9;
    let step = (hi - lo) / (steps - 1) as f64;
    // The grid's trials are independent: solved side by side (each a small
    // solve that leaves a core idle), then read in order.
    let shared: &dyn SolveObserver = &*observer;
    let grid = (0..steps)
        .into_par_iter()
        .map(|k| {
            let log_z = lo + k as f64 * step;
            Ok((log_z, trial_at(&work, log_z, params, shared)?))
        })
        .collect::<Result<Vec<_>, SolveError>>()?;
    let mut best = (lo, f64::INFINITY, 0usize);
    for (k, (log_z, found)) in grid.into_iter().enumerate() {
        let value = keep(found, &mut trials);
        if value < best.1 {
            best = (log_z, value, k);
        }
    }
    let evaluate = |log_z: f64, trials: &mut Vec<(f64, f64, f64)>| -> Result<f64, SolveError> {
        Ok(keep(trial_at(&work, log_z, params, shared)?, trials))
    };
    let (mut a, mut b) = (best.0 - step, best.0 + step);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut m1, mut m2) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut f1, mut f2) = (evaluate(m1, &mut trials)?, evaluate(m2, &mut trials)?);
    for _ in 0..5 {
        if f1 <= f2 {
            b = m2;
            m2 = m1;
            f2 = f1;
            m1 = b - ratio * (b - a);
            f1 = evaluate(m1, &mut trials)?;
        } else {
            a = m1;
            m1 = m2;
            f1 = f2;
            m2 = a + ratio * (b - a);
            f2 = evaluate(m2, &mut trials)?;
        }
    }
    let (s, depth, _) = trials
        .iter()
        .copied()
        .filter(|t| t.2.is_finite())
        .min_by(|x, y| x.2.total_cmp(&y.2))
        .ok_or_else(|| SolveError::Input("no trial scale explained the image".into()))?;
    let well_determined = determined(&trials, s);
    Ok(ScaleEstimate {
        intensity_scale: s,
        depth,
        trials,
        well_determined,
    })
}

/// Smallest rise of the relative residual, over the best trial's, that
/// every trial with a scale more than [`SCALE_TOLERANCE`] away must show
/// for the estimate to count as determined.
pub const DETERMINED_RISE: f64 = 0.25;
/// The largest relative residual of the best trial for which the estimate
/// can count as determined (the model explains the image within 2 %).
pub const MAX_DETERMINING_RESIDUAL: f64 = 0.02;
/// The accuracy a determined estimate promises: within this factor of the
/// best trial's `s`.
pub const SCALE_TOLERANCE: f64 = 1.15;

/// Whether `trials` (`(s, depth, residual)`) determine `s` near `best`:
/// the best explains the image within [`MAX_DETERMINING_RESIDUAL`], trials
/// exist on both sides beyond [`SCALE_TOLERANCE`], and every trial
/// beyond it explains the image worse by at least [`DETERMINED_RISE`] of the
/// best residual. A tilt of the surface absorbs much of a light's offset at
/// no smoothness cost, so on single renders the residual is flat over
/// decades of `s`; the old test (an inner minimum 10 % below the trials two
/// steps away) called 4 of 12 wrong estimates determined.
fn determined(trials: &[(f64, f64, f64)], best: f64) -> bool {
    let Some(least) = trials
        .iter()
        .map(|t| t.2)
        .filter(|r| r.is_finite())
        .min_by(f64::total_cmp)
    else {
        return false;
    };
    let beyond =
        |t: &&(f64, f64, f64)| t.0 > best * SCALE_TOLERANCE || t.0 < best / SCALE_TOLERANCE;
    // A model that does not explain the image determines nothing: the shared
    // face (LED 4, no ambient frame) had a sharp minimum at 2.6 m, its
    // residual 0.047, against 0.14 near the true 0.64 m.
    if least > MAX_DETERMINING_RESIDUAL {
        return false;
    }
    let below = trials.iter().filter(beyond).any(|t| t.0 < best);
    let above = trials.iter().filter(beyond).any(|t| t.0 > best);
    below
        && above
        && trials
            .iter()
            .filter(beyond)
            .all(|t| t.2.is_finite() && t.2 >= least * (1.0 + DETERMINED_RISE))
}

/// A distance the user knows: the surface at pixel `(column_px, row_px)` of
/// the solved image lies at depth `depth` (the camera's depth unit).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct KnownDepth {
    /// Pixel column in the solved image.
    pub column_px: f64,
    /// Pixel row in the solved image.
    pub row_px: f64,
    /// Its known depth.
    pub depth: f64,
}

/// How a solve met its known depths.
#[derive(Clone, Debug, Serialize)]
pub struct KnownDepthFit {
    /// The intensity scale the solve ended with.
    pub intensity_scale: f64,
    /// Each known point: where it is, the given and the solved depth and
    /// the relative residual `(solved - given) / given`.
    pub points: Vec<KnownDepthResidual>,
    /// The object's distance given (`--distance`: the solved surface's
    /// median depth) and the solved one; `None` for known points.
    pub median_depth: Option<MedianResidual>,
    /// Root mean square of the relative residuals.
    pub rms_relative_residual: f64,
    /// Solves it took.
    pub solves: usize,
    /// False when the scale search stopped before the least-squares factor
    /// settled within [`KNOWN_DEPTH_TOLERANCE`].
    pub converged: bool,
    /// How precisely the points fix the scale, measured on the search's
    /// own solves (lights off the centre; `None` with a centred light,
    /// where the rescaling is exact, or when the search settled in fewer
    /// than four solves near its scale: its secant met the points at
    /// once, and a measure would cost solves of its own).
    pub scale_precision: Option<ScalePrecision>,
}

/// How precisely known distances fix the intensity scale with lights off
/// the centre, measured on the solves of the search itself: a
/// least-squares line of the log of the points' solved depth against
/// `log s` through the solves within [`PRECISION_WINDOW`] of the scale
/// found. The discrete solve's depth is not a smooth function of `s` (its
/// adaptive stops and branches): on the shared face (LED 4, 648 px) scales
/// 0.05 % apart put the nose 2.4 % apart. Its scatter about the line,
/// divided by the line's slope, is how far the scale could be moved and
/// still meet the points as well.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ScalePrecision {
    /// `d log z / d log s` at the points, the line's slope (exactly 0.5
    /// with a centred light; smaller where a change of `s` is taken up by
    /// the shape rather than the distance).
    pub depth_per_scale: f64,
    /// The points' relative scatter about the line (root mean square, with
    /// the line's two degrees of freedom taken out).
    pub depth_scatter: f64,
    /// The relative uncertainty of the scale: `depth_scatter /
    /// depth_per_scale`; infinite when the depth does not grow with `s`
    /// (by at least [`MIN_DEPTH_PER_SCALE`]).
    pub scale_uncertainty: f64,
    /// The solves the line was fitted to.
    pub solves: usize,
}

/// Solves within this of the found scale (in `log s`: a factor 1.22)
/// measure its precision.
pub const PRECISION_WINDOW: f64 = 0.2;
/// At least this many solves in the window measure a precision.
const PRECISION_SOLVES: usize = 4;
/// A slope of the depth against the scale below this (a tenth of a
/// centred light's 0.5) is taken as none.
pub const MIN_DEPTH_PER_SCALE: f64 = 0.05;
/// A scale uncertain by more than this (relative) is said to be loosely
/// fixed: on the shared face (LED 2, 648 px) two scales 2.7 % apart that
/// both met the nose moved the normals by 2 degrees.
pub const LOOSE_SCALE: f64 = 0.1;

impl ScalePrecision {
    /// The precision from the search's solves `(log s, log k)` (`k` the
    /// least-squares factor onto the points, `1 / depth` up to a constant)
    /// around `log_s_found`; `None` with fewer than [`PRECISION_SOLVES`] in
    /// [`PRECISION_WINDOW`] or no spread of `s` among them.
    fn from_solves(solves: &[(f64, f64)], log_s_found: f64) -> Option<Self> {
        let near: Vec<(f64, f64)> = solves
            .iter()
            .copied()
            .filter(|(x, y)| {
                x.is_finite() && y.is_finite() && (x - log_s_found).abs() <= PRECISION_WINDOW
            })
            .collect();
        let n = near.len();
        if n < PRECISION_SOLVES {
            return None;
        }
        let mean_x = near.iter().map(|p| p.0).sum::<f64>() / n as f64;
        let mean_y = near.iter().map(|p| p.1).sum::<f64>() / n as f64;
        let sxx: f64 = near.iter().map(|p| (p.0 - mean_x).powi(2)).sum();
        if sxx.sqrt() < 1e-6 {
            return None;
        }
        let sxy: f64 = near.iter().map(|p| (p.0 - mean_x) * (p.1 - mean_y)).sum();
        let slope = sxy / sxx;
        let residual: f64 = near
            .iter()
            .map(|p| (p.1 - mean_y - slope * (p.0 - mean_x)).powi(2))
            .sum();
        let depth_scatter = (residual / (n - 2) as f64).sqrt();
        // `log k = log given - log z`: the depth's slope is the opposite.
        let depth_per_scale = -slope;
        let scale_uncertainty = if depth_per_scale >= MIN_DEPTH_PER_SCALE {
            depth_scatter / depth_per_scale
        } else {
            f64::INFINITY
        };
        Some(Self {
            depth_per_scale,
            depth_scatter,
            scale_uncertainty,
            solves: n,
        })
    }

    /// Whether the scale is loosely fixed (uncertain by more than
    /// [`LOOSE_SCALE`]).
    pub fn is_loose(&self) -> bool {
        self.scale_uncertainty.is_nan() || self.scale_uncertainty > LOOSE_SCALE
    }

    /// The warning a loosely fixed scale gets (its words and why they
    /// matter), `None` when it is not loose; one text for the command line
    /// and the viewer.
    pub fn warning(&self, points: usize) -> Option<String> {
        self.is_loose().then(|| {
            format!(
                "{}: the shape depends on the scale, so it is only as good as that",
                self.words(points)
            )
        })
    }

    /// The precision in plain words, for a fit to `points` known
    /// distances.
    pub fn words(&self, points: usize) -> String {
        let (fixes, does, at) = if points == 1 {
            (
                "the known distance fixes",
                "the known distance does",
                "there",
            )
        } else {
            (
                "the known distances fix",
                "the known distances do",
                "at them",
            )
        };
        if self.scale_uncertainty.is_finite() {
            format!(
                "{fixes} the scale to about ±{:.1} % (the solved depth {at} moves by \
                 ±{:.1} % between nearly equal scales, over {} solves)",
                100.0 * self.scale_uncertainty,
                100.0 * self.depth_scatter,
                self.solves
            )
        } else {
            format!(
                "{does} not fix the scale here: over {} solves the solved depth {at} did \
                 not grow with the scale (slope {:.3}, scatter ±{:.1} %)",
                self.solves,
                self.depth_per_scale,
                100.0 * self.depth_scatter
            )
        }
    }
}

/// The object's distance after the solve: the given and the solved median
/// depth.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MedianResidual {
    /// The distance given.
    pub given: f64,
    /// The solved surface's median depth.
    pub solved: f64,
    /// `(solved - given) / given`.
    pub relative_residual: f64,
}

/// One known point after the solve.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct KnownDepthResidual {
    /// Pixel column in the solved image.
    pub column_px: f64,
    /// Pixel row in the solved image.
    pub row_px: f64,
    /// The depth given.
    pub given: f64,
    /// The solved depth there.
    pub solved: f64,
    /// `(solved - given) / given`.
    pub relative_residual: f64,
}

/// The least-squares factor settles when it is within this of 1.
pub const KNOWN_DEPTH_TOLERANCE: f64 = 2e-3;
/// The object's distance (`--distance`, or a cue of the set-up) is met
/// within this: it is "about" that far, and each full-size solve of the
/// shared face costs 25 s.
pub const MEDIAN_TOLERANCE: f64 = 0.02;
/// At most this many solves search the scale with lights off the centre.
const KNOWN_DEPTH_SOLVES: usize = 12;

/// The share of the image's longer side within which a known point's
/// solved depth is read (the median of the solved depths in that window):
/// the discrete solve's depth at one pixel is not a smooth function of `s`
/// (on the shared face, scales 0.05 % apart put the nose's pixel 2.4 %
/// apart), and the same share at every size reads the same patch of the
/// object.
pub const POINT_WINDOW_SHARE: f64 = 0.005;

/// The solved depth at `(column, row)`: the median of the finite positive
/// depths within [`POINT_WINDOW_SHARE`] of the longer side (the pixel
/// itself below 100 px); `None` when the pixel is outside the image or
/// not on the solved surface.
pub fn depth_near(depth: &Grid<f64>, column: f64, row: f64) -> Option<f64> {
    let (c, r) = (column.round(), row.round());
    if !(c >= 0.0 && r >= 0.0) {
        return None;
    }
    let (c, r) = (c as usize, r as usize);
    let (w, h) = depth.size();
    let usable = |z: f64| z.is_finite() && z > 0.0;
    if c >= w || r >= h || !usable(*depth.at(c, r)) {
        return None;
    }
    let radius = (POINT_WINDOW_SHARE * w.max(h) as f64).round() as usize;
    let mut near = Vec::with_capacity((2 * radius + 1).pow(2));
    for y in r.saturating_sub(radius)..(r + radius + 1).min(h) {
        for x in c.saturating_sub(radius)..(c + radius + 1).min(w) {
            let z = *depth.at(x, y);
            if usable(z) {
                near.push(z);
            }
        }
    }
    let middle = near.len() / 2;
    Some(*near.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// The median of a depth map's finite positive values (NaN when none).
pub fn median_depth(depth: &Grid<f64>) -> f64 {
    let mut depths = depth.finite_positive_values();
    if depths.is_empty() {
        return f64::NAN;
    }
    let middle = depths.len() / 2;
    *depths.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// Solved depth at each known point ([`depth_near`]); an error naming the
/// points when one is off the solved surface or outside the image.
fn depths_at(depth: &Grid<f64>, points: &[KnownDepth]) -> Result<Vec<f64>, SolveError> {
    points
        .iter()
        .map(|p| depth_near(depth, p.column_px, p.row_px))
        .collect::<Option<_>>()
        .ok_or_else(|| {
            SolveError::Input(format!(
                "known depth: a pixel ({}) is not on the solved surface (inside the object mask \
                 and the image)",
                points
                    .iter()
                    .map(|p| format!("{},{}", p.column_px, p.row_px))
                    .collect::<Vec<_>>()
                    .join("; ")
            ))
        })
}

/// What a scale search meets: known points, or the object's median depth
/// (`--distance`).
#[derive(Clone, Debug, PartialEq)]
pub enum DistanceTarget {
    /// Pixels whose depth is known.
    Points(Vec<KnownDepth>),
    /// The median depth of the solved surface (the object's distance).
    Median(f64),
}

impl DistanceTarget {
    /// The factor `k` that scales a solved `depth` onto the target (`k z`
    /// meets it): relative least squares over the points, or the given
    /// median over the solved one.
    fn factor(&self, depth: &Grid<f64>) -> Result<f64, SolveError> {
        match self {
            Self::Points(points) => Ok(least_squares_factor(&depths_at(depth, points)?, points)),
            Self::Median(distance) => {
                let median = median_depth(depth);
                if median.is_finite() && median > 0.0 {
                    Ok(distance / median)
                } else {
                    Err(SolveError::Input(
                        "object distance: the solve left no surface to measure".into(),
                    ))
                }
            }
        }
    }

    /// The same target on a copy of `(sw, sh)` pixels of an image of
    /// `(w, h)`.
    fn at_size(&self, (w, h): (usize, usize), (sw, sh): (usize, usize)) -> Self {
        match self {
            Self::Points(points) => Self::Points(
                points
                    .iter()
                    .map(|p| KnownDepth {
                        column_px: ((p.column_px + 0.5) * sw as f64 / w as f64 - 0.5).round(),
                        row_px: ((p.row_px + 0.5) * sh as f64 / h as f64 - 0.5).round(),
                        depth: p.depth,
                    })
                    .collect(),
            ),
            Self::Median(distance) => Self::Median(*distance),
        }
    }

    /// How near 1 the factor must come: [`KNOWN_DEPTH_TOLERANCE`] for
    /// points, [`MEDIAN_TOLERANCE`] for the object's distance.
    fn tolerance(&self) -> f64 {
        match self {
            Self::Points(_) => KNOWN_DEPTH_TOLERANCE,
            Self::Median(_) => MEDIAN_TOLERANCE,
        }
    }

    /// Refuses a target the image cannot meet within
    /// [`crate::params::INTENSITY_SCALE_RANGE`]: meeting it needs the
    /// intensity scale `needed`, and depth grows as `sqrt(s)`. The error
    /// names the known depth (or distance) and the depths that fit, not the
    /// intensity scale the user never gave.
    fn check_reach(&self, needed: f64) -> Result<(), SolveError> {
        let (s_min, s_max) = crate::params::INTENSITY_SCALE_RANGE;
        if needed.is_finite() && (s_min..=s_max).contains(&needed) {
            return Ok(());
        }
        let depth = self.mean_depth();
        let (low, high) = (
            depth * (s_min / needed).sqrt(),
            depth * (s_max / needed).sqrt(),
        );
        let what = match self {
            Self::Points(points) => match points.as_slice() {
                [p] => format!(
                    "known depth {} at pixel {},{}",
                    crate::params::ParamValue::Real(p.depth),
                    p.column_px,
                    p.row_px
                ),
                _ => format!(
                    "known depths (mean {})",
                    crate::params::ParamValue::Real(depth)
                ),
            },
            Self::Median(distance) => format!(
                "object distance {}",
                crate::params::ParamValue::Real(*distance)
            ),
        };
        Err(SolveError::Input(format!(
            "{what} is out of this image's reach: a surface that far (or near) would need an \
             intensity scale of {needed:.4e}, beyond [{s_min:e}, {s_max:e}]; distances from \
             about {low:.4e} to {high:.4e} fit (check the depth's unit)"
        )))
    }

    /// The mean of the given depths.
    fn mean_depth(&self) -> f64 {
        match self {
            Self::Points(points) => {
                points.iter().map(|p| p.depth).sum::<f64>() / points.len().max(1) as f64
            }
            Self::Median(distance) => *distance,
        }
    }

    /// An error for a target with nothing to meet or a depth that is not
    /// positive and finite.
    fn check(&self) -> Result<(), SolveError> {
        match self {
            Self::Points(points) => {
                if points.is_empty() {
                    return Err(SolveError::Input("no known depth given".into()));
                }
                if let Some(p) = points
                    .iter()
                    .find(|p| !(p.depth.is_finite() && p.depth > 0.0))
                {
                    return Err(SolveError::Input(format!(
                        "known depth at pixel {},{}: the distance must be positive, not {}",
                        p.column_px, p.row_px, p.depth
                    )));
                }
                Ok(())
            }
            Self::Median(distance) if !(distance.is_finite() && *distance > 0.0) => Err(
                SolveError::Input(format!("object distance {distance}: must be positive")),
            ),
            Self::Median(_) => Ok(()),
        }
    }
}

/// The factor `k` that scales `solved` onto `given` in relative least
/// squares: `min sum ((k z_i - Z_i) / Z_i)^2`.
fn least_squares_factor(solved: &[f64], points: &[KnownDepth]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (z, p) in solved.iter().zip(points) {
        let ratio = z / p.depth;
        num += ratio;
        den += ratio * ratio;
    }
    num / den.max(f64::MIN_POSITIVE)
}

/// Longest side of the working copy a known distance's scale is first
/// searched on (images more than twice as large).
const KNOWN_DEPTH_SEARCH_SIDE: usize = 256;

/// A secant slope of `log k` over `log s` below this in size is flat: the
/// depth moves as `sqrt(s)` (slope -1/2) where the shading holds it, and a
/// tenth of that is not following `s`.
const FLAT_SLOPE: f64 = 0.05;
/// A flat slope ends a search once measured over a change of `s` by at
/// least this factor (the shared face's LED 1 at 648 px: `k` 0.690 from
/// `s` x1 to x1/400, then a jump to another branch; 25 solves before).
const FLAT_STEP: f64 = 1.1;

/// The secant search of `s` (lights off the centre) from
/// `problem.intensity_scale` until the factor onto `target` is within
/// `tolerance` of 1, at most `max_solves` solves, the first
/// secant step along `slope_hint` (`d log k / d log s`): the
/// [`ScaleSearch`], the solution of the best solve (the factor nearest 1;
/// the discrete solve's depth is not exactly monotone in `s`) and the last
/// slope the secant measured (or the hint).
fn search_scale(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    target: &DistanceTarget,
    (max_solves, tolerance): (usize, f64),
    slope_hint: f64,
    observer: &mut dyn SolveObserver,
) -> Result<(ScaleSearch, super::problem::Solution, f64), SolveError> {
    let mut best_solution = super::method::solve_method(problem, params, method, observer)?;
    let mut solves = 1;
    let mut k = target.factor(&best_solution.depth)?;
    let mut tried = vec![(problem.intensity_scale.ln(), k.ln())];
    let mut best = (problem.intensity_scale, k);
    // (log s, log k) of the previous solve: the secant's line.
    let mut previous: Option<(f64, f64)> = None;
    let mut measured = slope_hint;
    while (k - 1.0).abs() >= tolerance && solves < max_solves {
        let (log_s, log_k) = (problem.intensity_scale.ln(), k.ln());
        // Depth grows about as sqrt(s): log k = slope (log s - log s*).
        let slope = match previous {
            Some((s0, k0)) if (log_s - s0).abs() > 1e-12 => {
                let slope = (log_k - k0) / (log_s - s0);
                if slope < -0.05 {
                    measured = slope;
                    slope
                } else if slope.abs() < FLAT_SLOPE && (log_s - s0).abs() >= FLAT_STEP.ln() {
                    // The depth did not follow a change of `s` large enough
                    // to show (it should move as sqrt(s)): something else
                    // holds it (the lights, where the surface must stay
                    // beyond them). More solves only walk `s` away; the
                    // best one is kept and the search reports it unmet.
                    break;
                } else {
                    slope_hint
                }
            }
            _ => slope_hint,
        };
        previous = Some((log_s, log_k));
        // A step of at most a factor 4 in s.
        let step = (-log_k / slope).clamp(-4f64.ln(), 4f64.ln());
        let next = (log_s + step).exp();
        let (s_min, s_max) = crate::params::INTENSITY_SCALE_RANGE;
        if !(s_min..=s_max).contains(&next) {
            // Out of range on the way: named by the scale the target needs
            // (depth growing as the slope says), beyond it too.
            target.check_reach((log_s - log_k / slope).exp())?;
        }
        problem.intensity_scale = next;
        let solution = super::method::solve_method(problem, params, method, observer)?;
        solves += 1;
        k = target.factor(&solution.depth)?;
        tried.push((problem.intensity_scale.ln(), k.ln()));
        if k.ln().abs() < best.1.ln().abs() {
            best = (problem.intensity_scale, k);
            best_solution = solution;
        }
    }
    let converged = (best.1 - 1.0).abs() < tolerance;
    let search = ScaleSearch {
        intensity_scale: best.0,
        converged,
        solves,
        precision: ScalePrecision::from_solves(&tried, best.0.ln()),
    };
    Ok((search, best_solution, measured))
}

/// What a scale search found (or the exact rescaling with a centred
/// light): the best solve's scale, whether it met the target within the
/// tolerance, the solves it took and the precision they measure.
struct ScaleSearch {
    intensity_scale: f64,
    converged: bool,
    solves: usize,
    precision: Option<ScalePrecision>,
}

/// The point of the surface the target speaks of, in the camera frame:
/// the known points' mean, or the principal point's ray at the distance.
fn target_centre(problem: &Problem, target: &DistanceTarget) -> DVec3 {
    let camera = problem.camera;
    match target {
        DistanceTarget::Points(points) => {
            points
                .iter()
                .map(|p| {
                    let (x, y) = camera.image_xy(p.column_px, p.row_px);
                    DVec3::from_array(camera.back_project(x, y, p.depth))
                })
                .sum::<DVec3>()
                / points.len().max(1) as f64
        }
        DistanceTarget::Median(distance) => DVec3::new(0.0, 0.0, *distance),
    }
}

/// `params` with the start every solve of a distance search uses: lights
/// far beside the lens (seen from the target) start from the plane up the
/// pyramid in every solve, and so do the albedo decision's trial solves.
/// (A constant start at the target's distance instead was measured on the
/// shared face and made it worse: LED 4 with the nose known 28 to 49
/// degrees.)
/// Left to each solve's own guess of the distance, the start would switch
/// with `s` and the depth jump between them; and the albedo decision,
/// started from the march, compared solutions on another branch than the
/// search's (the shared face with LED 4 at 648 px: albedo 1's trial solve
/// 29 cm away, in front of the LED, against the searched 66 cm).
fn search_params(
    problem: &Problem,
    params: &SolverParams,
    target: &DistanceTarget,
) -> SolverParams {
    match params.initial_depth {
        crate::params::InitialDepth::FastMarching
            if !problem.light_is_centred()
                && !super::light_frame::faces_the_frame(
                    &problem.lights,
                    target_centre(problem, target),
                ) =>
        {
            SolverParams {
                initial_depth: crate::params::InitialDepth::Walk,
                ..params.clone()
            }
        }
        _ => params.clone(),
    }
}

/// Solves `problem` so that its depth meets `points` in relative least
/// squares, by moving the intensity scale (`problem.intensity_scale` ends as
/// the one used): [`solve_meeting`] with [`DistanceTarget::Points`].
///
/// # Errors
/// As [`solve_meeting`].
pub fn solve_with_known_depths(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    points: &[KnownDepth],
    observer: &mut dyn SolveObserver,
) -> Result<(super::problem::Solution, KnownDepthFit), SolveError> {
    solve_meeting(
        problem,
        params,
        method,
        &DistanceTarget::Points(points.to_vec()),
        observer,
    )
}

/// Solves `problem` so that its depth meets `target` (known points, or the
/// object's median depth), by moving the intensity scale
/// (`problem.intensity_scale` ends as the one used). With every light at
/// the optical centre `s` only scales the depth (depth times `k`, `s`
/// times `k^2`): one more solve and the exact rescaling. With lights
/// elsewhere the depth is metric and `s` is searched (secant steps on
/// `log s` against `log k`): first on a working copy of
/// [`KNOWN_DEPTH_SEARCH_SIDE`] pixels, then at the full size along the
/// copy's slope, each to the target's tolerance
/// ([`KNOWN_DEPTH_TOLERANCE`] for points, [`MEDIAN_TOLERANCE`] for the
/// object's distance). (Warm-starting the full-size solves from the
/// copy's best made each one level and the shared face's known distance
/// 7-9 s at 1296x864, but cost 2-5 degrees of normal error on it: LED 4
/// with the nose known 23.4 to 28.4 at 648 px. Not kept.)
///
/// With `--albedo auto` the albedo is decided once, at the scale the search
/// found with albedo 1 ([`super::albedo_fit`]; on a large image the working
/// copy's, whose full-size solve is then made only if the estimate is not
/// used as judged); when it is used, the search runs again on the image
/// divided by it, starting where albedo 1's search corrected the plane's
/// guess to, so every solve of a search solves one model. When the estimate fitted better at that scale but fell
/// short of the margin, it is searched on its own scale too and the two
/// solutions are compared on the full photograph by the same rule.
///
/// # Errors
/// As [`super::solve_method`]; `SolveError::Input` when there is no point,
/// a given depth is not positive and finite, or a point is not on the
/// solved surface.
pub fn solve_meeting(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    target: &DistanceTarget,
    observer: &mut dyn SolveObserver,
) -> Result<(super::problem::Solution, KnownDepthFit), SolveError> {
    target.check()?;
    let params = &search_params(problem, params, target);
    let copy = search_copy(problem, params, method, target, 1.0, observer);
    if params.albedo != crate::params::AlbedoChoice::Auto {
        return search_full(problem, params, method, target, copy.slope, observer);
    }
    // The albedo is decided at the scale the search found with albedo 1:
    // the working copy's where one was searched (a full-size solve at that
    // scale is only read when the estimate is not used as judged), else
    // the full size's.
    let mut first = if copy.ran {
        None
    } else {
        Some(search_full(
            problem, params, method, target, copy.slope, observer,
        )?)
    };
    let first_solves = first.as_ref().map_or(0, |(_, fit)| fit.solves);
    let (divided, albedo) = super::albedo_fit::apply(problem, params, observer)?;
    let mut albedo_one =
        |problem: &mut Problem, observer: &mut dyn SolveObserver| match first.take() {
            Some(first) => Ok(first),
            None => search_full(problem, params, method, target, copy.slope, observer),
        };
    let Some(mut albedo) = albedo else {
        return albedo_one(problem, observer);
    };
    // Judged at albedo 1's scale, an estimate that fitted better but fell
    // short is searched on its own scale too: albedo 1's is the one that
    // puts albedo 1's shape (dark albedo read as slopes) at the known
    // distances. The two searched solutions are then compared on the
    // photograph at its full size.
    let judged = albedo.used;
    let (mut divided, divisor) = match divided {
        Some(divided) => (divided, albedo.divisor),
        None => match albedo.albedo.as_ref().filter(|_| albedo.misfit_ratio < 1.0) {
            Some(estimate) => super::albedo_fit::divide_out(problem, estimate),
            None => {
                let (mut solution, fit) = albedo_one(problem, observer)?;
                albedo.restore(&mut solution);
                return Ok((solution, fit));
            }
        },
    };
    // The divided photograph's search starts where albedo 1's plane guess
    // was corrected to (the same photograph, the same miss of the plane).
    let divided_copy = search_copy(
        &mut divided,
        params,
        method,
        target,
        copy.over_plane,
        observer,
    );
    let (mut again, mut fit_again) = search_full(
        &mut divided,
        params,
        method,
        target,
        divided_copy.slope,
        observer,
    )?;
    albedo.multiply_back(divisor, &mut again);
    let mut solves_one = first_solves;
    if !judged {
        let (mut solution, fit) = albedo_one(problem, observer)?;
        albedo.decide(super::albedo_fit::misfit_ratio(problem, &solution, &again));
        if !albedo.used {
            albedo.restore(&mut solution);
            return Ok((solution, fit));
        }
        solves_one = fit.solves;
        albedo.divisor = divisor;
        let (w, h) = problem.image.size();
        albedo.working_side = w.max(h);
        albedo
            .summary
            .push_str(" (each at the scale its own search found)");
    }
    problem.intensity_scale = divided.intensity_scale * divisor;
    fit_again.intensity_scale = problem.intensity_scale;
    fit_again.solves += solves_one;
    again.albedo_fit = Some(albedo);
    Ok((again, fit_again))
}

/// Where a search on a working copy left the intensity scale (see
/// [`search_copy`]).
#[derive(Clone, Copy, Debug)]
struct CopySearch {
    /// The copy was searched (lights off the centre, a large image).
    ran: bool,
    /// The slope of log depth over log scale it measured (-1/2 unmeasured).
    slope: f64,
    /// The scale it found over the plane's (`plane_ratio`): how far the
    /// plane's guess missed on this photograph.
    over_plane: f64,
}

/// The first part of a search with lights off the centre: the intensity
/// scale set where a plane at the target's mean depth shows the image's
/// median brightness (times `over_plane`: what another search of the same
/// photograph found), then, on an image more than twice
/// [`KNOWN_DEPTH_SEARCH_SIDE`], to what the search of a working copy finds
/// (each solve there a fraction of the cost). Centred lights: nothing.
fn search_copy(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    target: &DistanceTarget,
    over_plane: f64,
    observer: &mut dyn SolveObserver,
) -> CopySearch {
    let mut found = CopySearch {
        ran: false,
        slope: -0.5,
        over_plane: 1.0,
    };
    if problem.light_is_centred() {
        return found;
    }
    // With lights off the centre the depth is metric.
    let plane = plane_ratio(problem, target.mean_depth()).filter(|s| s.is_finite() && *s > 0.0);
    if let Some(s) = plane {
        problem.intensity_scale = s * over_plane;
    }
    let (w, h) = problem.image.size();
    if w.max(h) > 2 * KNOWN_DEPTH_SEARCH_SIDE {
        let mut copy = working_copy(problem, KNOWN_DEPTH_SEARCH_SIDE);
        let scaled = target.at_size((w, h), copy.image.size());
        if let Ok((search, _, measured)) = search_scale(
            &mut copy,
            &params.without_fit(),
            method,
            &scaled,
            (KNOWN_DEPTH_SOLVES, target.tolerance()),
            found.slope,
            &mut Forward(observer),
        ) {
            problem.intensity_scale = search.intensity_scale;
            found = CopySearch {
                ran: true,
                slope: measured,
                over_plane: plane.map_or(1.0, |s| search.intensity_scale / s),
            };
        }
    }
    found
}

/// The search at the full size from the problem's intensity scale (after
/// [`search_copy`], with the slope it measured), and its fit to the target.
fn search_full(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    target: &DistanceTarget,
    slope: f64,
    observer: &mut dyn SolveObserver,
) -> Result<(super::problem::Solution, KnownDepthFit), SolveError> {
    // `auto` searches as Lambert (what it stands for: the fit only
    // reports) and compares the materials once, at the scale found.
    let resolved = params.without_fit();
    let auto = params.fixed_material().is_none();
    let user_params = params;
    let params = &resolved;
    let (search, mut solution) = if problem.light_is_centred() {
        let mut solution = super::method::solve_method(problem, params, method, observer)?;
        let mut solves = 1;
        let k = target.factor(&solution.depth)?;
        if (k - 1.0).abs() >= KNOWN_DEPTH_TOLERANCE {
            target.check_reach(problem.intensity_scale * k * k)?;
            problem.intensity_scale *= k * k;
            solution = super::method::solve_method(problem, params, method, observer)?;
            solves += 1;
        }
        // Exact up to round-off: the last factor is applied to the depth.
        let k = target.factor(&solution.depth)?;
        solution.depth = solution.depth.map(|z| z * k);
        let exact = ScaleSearch {
            intensity_scale: problem.intensity_scale,
            converged: true,
            solves,
            precision: None,
        };
        (exact, solution)
    } else {
        let (search, solution, _) = search_scale(
            problem,
            params,
            method,
            target,
            (KNOWN_DEPTH_SOLVES, target.tolerance()),
            slope,
            observer,
        )?;
        problem.intensity_scale = search.intensity_scale;
        (search, solution)
    };
    if auto {
        solution.material_fit = Some(super::material_fit::fit_material(
            problem,
            user_params,
            observer,
        )?);
    }
    let (points, median) = match target {
        DistanceTarget::Points(points) => {
            let solved = depths_at(&solution.depth, points)?;
            let residuals: Vec<KnownDepthResidual> = solved
                .iter()
                .zip(points)
                .map(|(&z, p)| KnownDepthResidual {
                    column_px: p.column_px,
                    row_px: p.row_px,
                    given: p.depth,
                    solved: z,
                    relative_residual: (z - p.depth) / p.depth,
                })
                .collect();
            (residuals, None)
        }
        DistanceTarget::Median(distance) => {
            let solved = median_depth(&solution.depth);
            (
                Vec::new(),
                Some(MedianResidual {
                    given: *distance,
                    solved,
                    relative_residual: (solved - distance) / distance,
                }),
            )
        }
    };
    let relative: Vec<f64> = points
        .iter()
        .map(|r| r.relative_residual)
        .chain(median.iter().map(|m| m.relative_residual))
        .collect();
    let rms = (relative.iter().map(|r| r * r).sum::<f64>() / relative.len().max(1) as f64).sqrt();
    Ok((
        solution,
        KnownDepthFit {
            intensity_scale: problem.intensity_scale,
            points,
            median_depth: median,
            rms_relative_residual: rms,
            solves: search.solves,
            converged: search.converged,
            scale_precision: search.precision,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Trials `(s, depth, residual)` at `s = 2^k` with residual `curve(k)`.
    fn trials(curve: impl Fn(f64) -> f64) -> Vec<(f64, f64, f64)> {
        (-4..=4)
            .map(|k| {
                let k = f64::from(k) * 0.5;
                (2f64.powf(k), 1.0, curve(k))
            })
            .collect()
    }

    /// Solves `(log s, log k)` at `log s = 0.05 j` around 0 with
    /// `log k = -slope log s + noise(j)`.
    fn solves(slope: f64, noise: impl Fn(i32) -> f64) -> Vec<(f64, f64)> {
        (-3..=3)
            .map(|j| {
                let x = 0.05 * f64::from(j);
                (x, -slope * x + noise(j))
            })
            .collect()
    }

    /// +-1 % in turn, uncorrelated with `j` over -3..=3.
    fn alternating(j: i32) -> f64 {
        if j.rem_euclid(2) == 0 { 0.01 } else { -0.01 }
    }

    /// `--known-depth 64,64,1e30` blamed the intensity scale, which the
    /// user never gave: the known depth is named, with the depths that fit.
    #[test]
    fn a_known_depth_out_of_reach_is_named_with_the_depths_that_fit() {
        let target = DistanceTarget::Points(vec![KnownDepth {
            column_px: 24.0,
            row_px: 20.0,
            depth: 1e30,
        }]);
        assert!(target.check_reach(1.0).is_ok());
        let err = target
            .check_reach(1e60)
            .expect_err("out of reach")
            .to_string();
        assert!(err.contains("known depth 1e30 at pixel 24,20"), "{err}");
        assert!(err.contains("to 1.0000e15 fit"), "{err}");
        assert!(!err.starts_with("intensity scale"), "{err}");
        let far = DistanceTarget::Median(1e-20);
        let err = far
            .check_reach(1e-40)
            .expect_err("out of reach")
            .to_string();
        assert!(err.contains("object distance 1e-20"), "{err}");
    }

    #[test]
    fn the_scale_s_precision_is_the_depth_s_scatter_over_its_slope() {
        // A centred light's exact law: no scatter, no uncertainty.
        let exact = ScalePrecision::from_solves(&solves(0.5, |_| 0.0), 0.0).expect("measured");
        assert!((exact.depth_per_scale - 0.5).abs() < 1e-12);
        assert!(exact.depth_scatter < 1e-12 && exact.scale_uncertainty < 1e-12);
        assert!(!exact.is_loose());
        // Alternating +-1 % about a slope of 0.25: about 4 % of the scale.
        let noisy = ScalePrecision::from_solves(&solves(0.25, alternating), 0.0).expect("measured");
        assert!((noisy.depth_scatter - 0.01).abs() < 0.003, "{noisy:?}");
        assert!((noisy.scale_uncertainty - 0.04).abs() < 0.015, "{noisy:?}");
        assert!(!noisy.is_loose());
        // The same scatter on a slope of 0.06: loosely fixed; no slope: not at all.
        let weak = ScalePrecision::from_solves(&solves(0.06, alternating), 0.0).expect("measured");
        assert!(weak.is_loose(), "{weak:?}");
        assert!(weak.warning(1).is_some() && noisy.warning(1).is_none());
        let flat = ScalePrecision::from_solves(&solves(0.0, alternating), 0.0).expect("measured");
        assert!(flat.scale_uncertainty.is_infinite() && flat.is_loose());
        assert!(
            flat.words(1).contains("distance does not fix"),
            "{}",
            flat.words(1)
        );
        assert!(
            flat.words(2).contains("distances do not fix"),
            "{}",
            flat.words(2)
        );
        assert!(
            noisy
                .words(2)
                .starts_with("the known distances fix the scale to about ±4"),
            "{}",
            noisy.words(2)
        );
        // Only the solves within the window count: three are too few.
        let far: Vec<(f64, f64)> = solves(0.5, |_| 0.0)
            .iter()
            .map(|&(x, y)| (x + 0.35, y))
            .collect();
        assert_eq!(ScalePrecision::from_solves(&far, 0.0), None);
        assert_eq!(ScalePrecision::from_solves(&[(0.0, 0.0); 6], 0.0), None);
    }

    #[test]
    fn only_a_sharp_inner_minimum_determines_the_scale() {
        // Sharp: every trial beyond 1.15x explains the image 25 % worse.
        assert!(determined(&trials(|k| 0.01 * (1.0 + k * k)), 1.0));
        // As sharp, but the model explains the image only within 10 %.
        assert!(!determined(&trials(|k| 0.1 * (1.0 + k * k)), 1.0));
        // Flat within a few per cent over decades: not determined.
        assert!(!determined(&trials(|k| 0.01 * (1.0 + 0.01 * k * k)), 1.0));
        // A minimum at the end of the range: nothing beyond it on one side.
        assert!(!determined(&trials(|k| 0.01 * (3.0 - k)), 4.0));
        // One far trial as good as the best: two minima, not determined.
        assert!(!determined(
            &trials(|k| if k == 2.0 { 0.01 } else { 0.01 * (1.0 + k * k) }),
            1.0
        ));
        // No finite residual at all.
        assert!(!determined(&trials(|_| f64::NAN), 1.0));
    }
}
