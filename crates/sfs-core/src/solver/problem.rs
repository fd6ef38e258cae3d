//! What every scheme shares: the [`Problem`] it is asked to explain, the
//! [`Solution`] it returns, the reports it sends to a [`SolveObserver`] and
//! the checks of the input. The schemes (`driver`, `explicit`,
//! `fast_marching`) depend on this module, never on each other.

use std::time::Duration;

use serde::Serialize;

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::light::{LightModel, PointLight};
use crate::material::Material;
use crate::model::{Energy, LevelGeometry};
use crate::params::{DomainMode, ParamError, ProblemScales};

/// Image values at or above this are clipped (the top of a file's range,
/// which the readers map to 1): such pixels get confidence 0.
pub const SATURATED: f64 = 1.0;

/// Smallest accepted image side.
pub const MIN_IMAGE_SIDE: usize = 3;

/// The largest depth a solve may return: above [`crate::params::DEPTH_RANGE`] (a solve may
/// move beyond its start) and below float32's largest value (depth.npy).
pub const MAX_SOLVED_DEPTH: f64 = 1e30;

/// The smallest depth a solve may return: below [`crate::params::DEPTH_RANGE`]
/// (a solve may move beyond its start) and above float32's smallest normal
/// value, 1.2e-38 (depth.npy): an absurd principal point solved to depths
/// of 1e-200 that the file held as an all-zero depth.
pub const MIN_SOLVED_DEPTH: f64 = 1e-30;

/// Why the depths `values` (NaN left out) are no surface: none at all, or
/// one outside `[MIN_SOLVED_DEPTH, MAX_SOLVED_DEPTH]` (infinities too).
/// `None`: a surface. (A constant depth is not refused here: a solve whose
/// light points away from the object returns its start, with a warning
/// about the light.)
pub(crate) fn depth_divergence(values: &[f64]) -> Option<String> {
    use rayon::prelude::*;
    let (z_min, z_max) = (MIN_SOLVED_DEPTH, MAX_SOLVED_DEPTH);
    if values.is_empty() {
        return Some("no pixel has a depth".into());
    }
    let outside = |z: &&f64| !(**z >= z_min && **z <= z_max);
    if let Some(example) = values.par_iter().with_min_len(8192).find_first(outside) {
        return Some(format!(
            "{} of {} depths are not in [{z_min:e}, {z_max:e}] (e.g. {example:e}); check the \
             intensity scale, the camera and the parameters",
            values.par_iter().with_min_len(8192).filter(outside).count(),
            values.len()
        ));
    }
    None
}

/// What the solver is asked to explain.
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Linear image values (>= 0, finite).
    pub image: Grid<f64>,
    /// Camera at full resolution.
    pub camera: Intrinsics,
    /// Intensity scale `s`.
    pub intensity_scale: f64,
    /// Pixels that see the object (`None`: every pixel).
    pub object_mask: Option<Grid<bool>>,
    /// Confidence in [0, 1] (`None`: 1 everywhere).
    pub confidence: Option<Grid<f64>>,
    /// The lights switched on, camera frame, units of depth (empty: the
    /// paper's single light at the optical centre).
    pub lights: Vec<PointLight>,
}

/// Why a solve did not produce a depth map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// A parameter is out of range.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The input cannot be solved; the message names the problem.
    #[error("invalid input: {0}")]
    Input(String),
    /// The observer asked to stop.
    #[error("cancelled")]
    Cancelled,
    /// The solve ended with depths no output can hold (infinite, not
    /// positive, beyond [`MAX_SOLVED_DEPTH`], or none at all); nothing is
    /// returned rather than a surface that is not one.
    #[error("the solve diverged: {0}")]
    Diverged(String),
}

/// A pass that stopped on the observer's request stops the solve.
impl From<Cancelled> for SolveError {
    fn from(_: Cancelled) -> Self {
        SolveError::Cancelled
    }
}

/// Reported after every outer iteration.
#[derive(Clone, Debug, Serialize)]
pub struct IterationReport {
    /// Level index, 0 = coarsest.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// Level width.
    pub width: usize,
    /// Level height.
    pub height: usize,
    /// Outer iteration within the level, from 0.
    pub iteration: usize,
    /// Energy after the update.
    pub energy: Energy,
    /// Largest `|dz|` applied (after cropping).
    pub max_step: f64,
    /// Time since the solve started.
    #[serde(serialize_with = "seconds")]
    pub elapsed: Duration,
}

/// Reported after every level: its depth and reprojection at its own size.
/// The grids are shared, not copied, by every clone (the worker's event,
/// the viewer's latest level and its mesh preparation hold one copy).
#[derive(Clone, Debug)]
pub struct LevelResult {
    /// Level index, 0 = coarsest.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// Depth at this level's size; NaN outside the domain.
    pub depth: std::sync::Arc<Grid<f64>>,
    /// Reprojected image at this level's size.
    pub reprojection: std::sync::Arc<Grid<f64>>,
    /// This level's grid and camera: [`LevelGeometry::back_project`] turns
    /// a level pixel and its depth into a camera-space point.
    pub geometry: LevelGeometry,
    /// Number of pixels in this level's domain (for energy per pixel).
    pub domain_pixels: usize,
    /// Energy at the end of the level.
    pub energy: Energy,
    /// Time since the solve started.
    pub elapsed: Duration,
}

impl LevelResult {
    /// The level's total energy per domain pixel: comparable across levels
    /// (the total grows with the pixel count), so convergence reads as such.
    pub fn energy_per_pixel(&self) -> f64 {
        self.energy.total / self.domain_pixels.max(1) as f64
    }
}

/// Per-level summary kept in a [`Solution`].
#[derive(Clone, Debug, Serialize)]
pub struct LevelReport {
    /// Level width.
    pub width: usize,
    /// Level height.
    pub height: usize,
    /// Energies after each outer iteration.
    pub energies: Vec<f64>,
    /// Seconds spent on this level.
    pub seconds: f64,
}

/// Seconds spent in each phase of a solve, and the work counted.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct PhaseTimes {
    /// Linearising the data term and building its part of the system.
    pub linearise_seconds: f64,
    /// Evaluating Psi' and assembling the full system (every inner iteration).
    pub assemble_seconds: f64,
    /// The linear solves: SOR sweeps or V-cycles, with their residual
    /// checks (the multigrid hierarchy's construction excluded).
    pub linear_seconds: f64,
    /// Building the multigrid hierarchies (Galerkin coarse operators).
    pub hierarchy_seconds: f64,
    /// Cropping, applying and (with backtracking) re-evaluating the update.
    pub update_seconds: f64,
    /// Inner iterations (linear solves) run, over all levels.
    pub inner_iterations: usize,
    /// SOR sweeps (linear solver `sor`) or V-cycles (`multigrid`) run.
    pub linear_iterations: usize,
}

impl PhaseTimes {
    /// Adds another part's times and counts (a walked start's, its
    /// refinement's).
    pub fn add(&mut self, other: &PhaseTimes) {
        self.linearise_seconds += other.linearise_seconds;
        self.assemble_seconds += other.assemble_seconds;
        self.linear_seconds += other.linear_seconds;
        self.hierarchy_seconds += other.hierarchy_seconds;
        self.update_seconds += other.update_seconds;
        self.inner_iterations += other.inner_iterations;
        self.linear_iterations += other.linear_iterations;
    }
}

/// The image's noise level as a solve read it, relative to the brightness
/// scale `I_ref` (robust Immerkaer estimates, `crate::denoise`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NoiseReading {
    /// Over every trusted object pixel: what the automatic alpha and the
    /// shadows read.
    pub relative: f64,
    /// Over the brightest quarter of them, where the surface's own detail
    /// shows least; read only where `relative` is above
    /// [`crate::params::FAST_MARCHING_DENOISE_ABOVE`] (NaN, `null` in JSON,
    /// otherwise).
    pub relative_facing: f64,
}

impl NoiseReading {
    /// The image reads noisy: both readings above
    /// [`crate::params::FAST_MARCHING_DENOISE_ABOVE`]. What
    /// `StartDenoise::Auto` decides, and what keeps a start refined across
    /// holes on the schedule without holes.
    pub fn reads_noisy(&self) -> bool {
        use crate::params::FAST_MARCHING_DENOISE_ABOVE as ABOVE;
        self.relative > ABOVE && self.relative_facing > ABOVE
    }
}

/// The result of a solve.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Full-resolution depth; NaN outside the object.
    pub depth: Grid<f64>,
    /// Reprojected image; 0 outside the object.
    pub reprojection: Grid<f64>,
    /// Energy of the initial depth at the coarsest level and of the result.
    pub initial_energy: Energy,
    /// Final energy at full resolution.
    pub final_energy: Energy,
    /// Levels, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Where the time went.
    pub phases: PhaseTimes,
    /// Constant initial depth used (or the warm start's mean).
    pub initial_depth: f64,
    /// Wall time.
    pub seconds: f64,
    /// Outer iterations (linearised), gradient steps (explicit) or 1 (fast
    /// marching).
    pub iterations: usize,
    /// True when a time or iteration budget stopped the scheme early.
    pub budget_exhausted: bool,
    /// With lights off the optical centre, the object pixels the solve took
    /// out of the data term as shadow (no light reaches them: near-black
    /// against the image's reference brightness and its noise); `None`
    /// with the light at the optical centre or for fast marching.
    pub shadow: Option<Grid<bool>>,
    /// The smoothness weight used, in the parameters' units (the chosen one
    /// when alpha was `auto`); NaN for methods without one.
    pub alpha: f64,
    /// The same in pixel units.
    pub alpha_px: f64,
    /// Charbonnier `lambda` in pixel units.
    pub lambda_px: f64,
    /// The problem's scales that relative parameters refer to.
    pub scales: ProblemScales,
    /// The material the surface was solved as (METHOD.md section 10).
    pub material: Material,
    /// With `--reflectance auto`, how the material was fitted; `None`
    /// when it was given.
    pub material_fit: Option<super::fits::MaterialFit>,
    /// With `--albedo auto`, the estimated albedo and whether the solve
    /// used it ([`super::albedo_fit`]); `None` otherwise.
    pub albedo_fit: Option<super::fits::AlbedoFit>,
    /// Whether the fast-marching start marched a TV-denoised image
    /// (`--start-denoise`); `None` when the solve marched no such start.
    pub start_denoised: Option<bool>,
    /// The image's noise as the solve read it; `None` for fast marching.
    pub noise: Option<NoiseReading>,
    /// The parameters set away from their defaults that this solve left
    /// without effect, each `--NAME VALUE: why` (the path it took skipped
    /// them, or their decisions came out as the defaults' would have).
    pub unused_parameters: Vec<String>,
}

fn seconds<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(d.as_secs_f64())
}

impl Solution {
    /// The solution if its depth holds at least one value and every value
    /// that is not NaN (NaN: off the object) is positive and at most
    /// [`MAX_SOLVED_DEPTH`], and its reprojection is finite.
    pub(crate) fn checked(self) -> Result<Self, SolveError> {
        use rayon::prelude::*;
        // Only the object's depths (NaN: off the object).
        let values: Vec<f64> = self
            .depth
            .as_slice()
            .par_iter()
            .with_min_len(8192)
            .copied()
            .filter(|z| !z.is_nan())
            .collect();
        if let Some(why) = depth_divergence(&values) {
            return Err(SolveError::Diverged(why));
        }
        if self
            .reprojection
            .as_slice()
            .par_iter()
            .with_min_len(8192)
            .any(|v| !v.is_finite())
        {
            return Err(SolveError::Diverged(
                "the reprojection is not finite".into(),
            ));
        }
        Ok(self)
    }
}

/// Receives progress from the solver; every method has a no-op default.
///
/// Observers are `Send`: the solve runs on a worker of rayon's pool.
pub trait SolveObserver: Send + Sync {
    /// After every outer iteration.
    fn on_iteration(&mut self, _report: &IterationReport) {}
    /// After every level.
    fn on_level(&mut self, _result: &LevelResult) {}
    /// Polled between SOR sweeps; returning true stops the solve with
    /// [`SolveError::Cancelled`].
    fn is_cancelled(&self) -> bool {
        false
    }
    /// The store of solved working copies this solve's pipeline shares
    /// ([`SolveMemo`]); none by default. An observer that wraps another
    /// passes the other's on.
    fn memo(&self) -> Option<std::sync::Arc<SolveMemo>> {
        None
    }
}

/// An observer that ignores everything.
impl SolveObserver for () {}

/// How many solves a [`SolveMemo`] keeps.
pub const MEMO_ENTRIES: usize = 8;

/// The largest problem (in pixels) a [`SolveMemo`] keeps: the working
/// copies of 256 px on a side that a photograph's searches, its albedo
/// decision and its walked start solve.
pub const MEMO_MAX_PIXELS: usize = 256 * 256;

/// The solves of working copies that one photograph's pipeline shares, so
/// that a copy solved once at a scale is not solved again: the search of
/// the depth unit solves a 256 px copy, the full-size solve then walks the
/// same copy for its start and the albedo decision solves it with albedo 1.
/// A solve (`solver::driver`) whose observer offers one and whose problem
/// has at most [`MEMO_MAX_PIXELS`] pixels returns the kept solution of an
/// equal problem and parameters, its observer hearing the same iterations
/// and levels again; its time and phases then count no work. Kept for one
/// pipeline (`depth_unit::solve_photograph`), [`MEMO_ENTRIES`] at most.
pub struct SolveMemo(
    pub(crate) super::memo::Memo<(Problem, crate::params::SolverParams), RememberedSolve>,
);

impl Default for SolveMemo {
    fn default() -> Self {
        SolveMemo(super::memo::Memo::new(MEMO_ENTRIES))
    }
}

/// A kept solve: what it returned and what its observer heard.
#[derive(Clone)]
pub(crate) struct RememberedSolve {
    pub solution: Solution,
    pub effects: super::unused::Effects,
    pub events: Vec<ObserverEvent>,
}

/// One message a solve sent its observer.
#[derive(Clone)]
pub(crate) enum ObserverEvent {
    Iteration(IterationReport),
    Level(LevelResult),
}

impl Problem {
    /// The reflectance model of this problem's lights and intensity scale
    /// for a surface of `material` (a solve's: `SolverParams::material`).
    pub fn model(&self, material: Material) -> LightModel {
        LightModel::with_material(self.intensity_scale, &self.lights, material)
    }

    /// The intensity scale the brightness of a Lambertian patch facing the
    /// light at distance `r` is `/ r^2` of: with every light at the optical
    /// centre, `s` times their summed intensity (they act as one light;
    /// a sum of photographs divided by a power of two, a light given an
    /// intensity); `s` otherwise (the paper's light, or lights elsewhere).
    pub fn centred_scale(&self) -> f64 {
        if !self.lights.is_empty() && self.light_is_centred() {
            self.intensity_scale * self.lights.iter().map(|l| l.intensity).sum::<f64>()
        } else {
            self.intensity_scale
        }
    }

    /// True when every light sits at the optical centre (the paper's model).
    pub fn light_is_centred(&self) -> bool {
        crate::light::is_centred(&self.lights)
    }

    /// Checks sizes and values (and the size of `initial_depth_map`, when a
    /// solve starts from one); returns the domain that `domain` asks for (the
    /// object, or every pixel) and the confidence (0 off the object and on
    /// clipped pixels, see [`SATURATED`]). Its passes over the pixels run by
    /// rows in parallel, polling `cancel` per row.
    pub(crate) fn validate(
        &self,
        domain: DomainMode,
        initial_depth_map: Option<&Grid<f64>>,
        cancel: Cancel<'_>,
    ) -> Result<(Grid<bool>, Grid<f64>), SolveError> {
        use rayon::prelude::*;
        let (w, h) = self.image.size();
        let bad = |m: String| Err(SolveError::Input(m));
        if w < MIN_IMAGE_SIDE || h < MIN_IMAGE_SIDE {
            return bad(format!(
                "image is {w}x{h}; at least {MIN_IMAGE_SIDE}x{MIN_IMAGE_SIDE} pixels are needed"
            ));
        }
        self.camera.check_for(w, h).map_err(SolveError::Input)?;
        let s = self.intensity_scale;
        let (s_min, s_max) = crate::params::INTENSITY_SCALE_RANGE;
        if !(s.is_finite() && (s_min..=s_max).contains(&s)) {
            return bad(format!(
                "intensity scale must lie in [{s_min:e}, {s_max:e}] (got {s:e})"
            ));
        }
        for (k, light) in self.lights.iter().enumerate() {
            light.validated(k + 1).map_err(SolveError::Input)?;
        }
        let invalid = |v: &f64| !v.is_finite() || *v < 0.0;
        let first_bad_row = self
            .image
            .as_slice()
            .par_chunks(w)
            .with_min_len(rows_per_task(w))
            .position_first(|row| !cancel.is_cancelled() && row.iter().any(invalid));
        cancel.check()?;
        if let Some(bad_value) = first_bad_row.and_then(|r| {
            self.image.as_slice()[r * w..(r + 1) * w]
                .iter()
                .find(|v| invalid(v))
        }) {
            return bad(format!(
                "image contains an invalid value {bad_value} (values must be finite and >= 0)"
            ));
        }
        let wrong_size = |what: &str, (mw, mh): (usize, usize)| {
            bad(format!("{what} is {mw}x{mh} but the image is {w}x{h}"))
        };
        let object = match &self.object_mask {
            Some(m) if m.size() != (w, h) => return wrong_size("object mask", m.size()),
            Some(m) => m.clone(),
            None => Grid::filled(w, h, true),
        };
        let given = match &self.confidence {
            Some(c) if c.size() != (w, h) => return wrong_size("confidence", c.size()),
            Some(c) => {
                if c.as_slice().iter().any(|v| !(0.0..=1.0).contains(v)) {
                    return bad("confidence values must lie in [0, 1]".into());
                }
                Some(c)
            }
            None => None,
        };
        // 0 off the object; a clipped pixel only says "at least this
        // bright": the model cannot match it, so it is not trusted either
        // (as if painted with confidence 0).
        let mut confidence = Grid::filled(w, h, 0.0);
        let image = self.image.as_slice();
        let (objects, trusted, saturated, brightest) = confidence
            .as_mut_slice()
            .par_chunks_mut(w)
            .enumerate()
            .with_min_len(rows_per_task(w))
            .map(|(r, row)| {
                let mut counts = (0usize, 0usize, 0usize, 0.0f64);
                if cancel.is_cancelled() {
                    return counts;
                }
                for (c, out) in row.iter_mut().enumerate() {
                    if !*object.at(c, r) {
                        continue;
                    }
                    counts.0 += 1;
                    let trust = given.map_or(1.0, |g| *g.at(c, r));
                    if trust > 0.0 {
                        let v = image[r * w + c];
                        counts.1 += 1;
                        counts.3 = counts.3.max(v);
                        if v >= SATURATED {
                            counts.2 += 1;
                            continue;
                        }
                    }
                    *out = trust;
                }
                counts
            })
            .reduce(
                || (0, 0, 0, 0.0),
                |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3.max(b.3)),
            );
        cancel.check()?;
        if objects == 0 {
            return bad("the object mask is empty".into());
        }
        if trusted == 0 {
            return bad("no pixel is both on the object and trusted (confidence > 0)".into());
        }
        if brightest <= 0.0 {
            return bad(
                "the image is black on every trusted object pixel: there is no shading to explain"
                    .into(),
            );
        }
        if saturated * 2 > trusted {
            return bad(format!(
                "the image is saturated: {saturated} of {trusted} trusted object pixels are at the maximum value; \
                 lower the exposure or mask the saturated region (confidence 0)"
            ));
        }
        if let Some(map) = initial_depth_map
            && map.size() != (w, h)
        {
            return bad(format!(
                "initial depth map is {}x{} but the image is {w}x{h}",
                map.width(),
                map.height()
            ));
        }
        let domain = match domain {
            DomainMode::Object => object,
            DomainMode::Paper => Grid::filled(w, h, true),
        };
        Ok((domain, confidence))
    }

    /// The scales of [`ProblemScales`]: the median over trusted object
    /// pixels (confidence > 0, brightness > 0) of the "facing the light"
    /// depth `Q sqrt(s / I)`, and `I_ref = s / Z^2`. `confidence` is already
    /// 0 off the object; [`Self::validate`] guarantees a trusted pixel with
    /// brightness > 0. By rows in parallel, polling `cancel` per row.
    pub(crate) fn scales(
        &self,
        confidence: &Grid<f64>,
        cancel: Cancel<'_>,
    ) -> Result<ProblemScales, Cancelled> {
        let w = self.image.width();
        let s = self.centred_scale();
        let camera = self.camera;
        let facing = |r: usize, out: &mut Vec<f64>| {
            for c in 0..w {
                let v = *self.image.at(c, r);
                if *confidence.at(c, r) > 0.0 && v > 0.0 {
                    let q = crate::model::PixelRay {
                        x_px: c as f64 - camera.principal_x_px,
                        y_px: r as f64 - camera.principal_y_px,
                        focal_px: camera.focal_px,
                    }
                    .q();
                    out.push(q * (s / v).sqrt());
                }
            }
        };
        let median =
            crate::selection::kth_smallest(self.image.height(), facing, |n| n / 2, cancel)?;
        let depth = median.unwrap_or(1.0);
        Ok(ProblemScales {
            depth,
            intensity: s / (depth * depth),
            focal_px: camera.focal_px,
        })
    }
}

pub(crate) use crate::grid::rows_per_task;

/// `Err(SolveError::Cancelled)` once `observer` asks to stop: polled between
/// the long single passes over an image (each about a second at 18
/// megapixels).
pub(crate) fn check_cancelled(observer: &dyn SolveObserver) -> Result<(), SolveError> {
    if observer.is_cancelled() {
        Err(SolveError::Cancelled)
    } else {
        Ok(())
    }
}

/// How long [`free_on_pool`] leaves its job to other workers before it runs
/// it itself.
const FREE_HANDOVER: std::time::Duration = std::time::Duration::from_millis(10);

/// Frees `value` on rayon's pool (tens of milliseconds for a level's linear
/// system at 18 megapixels) and waits until it is gone, polling `observer`'s
/// cancellation meanwhile (`Err` once cancelled; the value is then freed
/// later). The memory is back before the caller allocates more, so the
/// solve's peak does not depend on how soon another thread gets to it.
/// An idle worker frees it while this one polls (run here, the job would be
/// tens of milliseconds without a poll). Where no other worker takes it
/// within [`FREE_HANDOVER`] (a pool of one thread, or every worker busy,
/// perhaps waiting likewise in other solves) this worker runs it itself:
/// waiting on, they would wait on each other.
pub(crate) fn free_on_pool<T: Send + 'static>(
    value: T,
    observer: &dyn SolveObserver,
) -> Result<(), SolveError> {
    use std::sync::mpsc::{RecvTimeoutError, TryRecvError};
    let (done, freed) = std::sync::mpsc::channel::<()>();
    rayon::spawn(move || {
        drop(value);
        drop(done);
    });
    let handed = std::time::Instant::now();
    loop {
        if freed.try_recv() != Err(TryRecvError::Empty) {
            return Ok(());
        }
        check_cancelled(observer)?;
        if handed.elapsed() >= FREE_HANDOVER && rayon::yield_now() == Some(rayon::Yield::Executed) {
            continue;
        }
        if freed.recv_timeout(std::time::Duration::from_millis(2)) != Err(RecvTimeoutError::Timeout)
        {
            return Ok(());
        }
    }
}

/// The full-resolution depth (NaN) and reprojection (0) outside the
/// problem's object mask, as a [`Solution`] holds them.
pub(crate) fn on_object(
    problem: &Problem,
    mut depth: Grid<f64>,
    mut reprojection: Grid<f64>,
) -> (Grid<f64>, Grid<f64>) {
    use rayon::prelude::*;
    // In place, by pixels in parallel: no copies at a photograph's size.
    if let Some(object) = &problem.object_mask {
        depth
            .as_mut_slice()
            .par_iter_mut()
            .zip(reprojection.as_mut_slice().par_iter_mut())
            .zip(object.as_slice().par_iter())
            .with_min_len(8192)
            .for_each(|((z, value), &inside)| {
                if !inside {
                    *z = f64::NAN;
                    *value = 0.0;
                }
            });
    }
    (depth, reprojection)
}

/// The depth with NaN outside `domain`, by rows in parallel (the copy's
/// pages are first touched there too), polling `cancel` per row.
pub fn masked(
    depth: &Grid<f64>,
    domain: &Grid<bool>,
    cancel: Cancel<'_>,
) -> Result<Grid<f64>, Cancelled> {
    let (w, h) = depth.size();
    let mut out = Grid::filled(w, h, 0.0);
    crate::grid::for_rows(out.as_mut_slice(), w, cancel, |r, out| {
        for (c, out) in out.iter_mut().enumerate() {
            *out = if *domain.at(c, r) {
                *depth.at(c, r)
            } else {
                f64::NAN
            };
        }
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every worker of the pool waiting in `free_on_pool` at once (solves in
    /// parallel) must not wait on each other, nor a pool of one thread on
    /// itself; a cancelled observer stops the wait.
    #[test]
    fn freeing_on_the_pool_ends_when_every_worker_waits() {
        // On its own thread, so that a wait that never ends fails the test
        // (after a generous minute) instead of hanging it.
        let (done, ended) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            every_worker_waits();
            let _ = done.send(());
        });
        ended
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("free_on_pool returns");
    }

    fn every_worker_waits() {
        let pair = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("a pool of two threads");
        let (a, b) = pair.install(|| {
            rayon::join(
                || free_on_pool(vec![1u8; 1 << 22], &()),
                || free_on_pool(vec![2u8; 1 << 22], &()),
            )
        });
        assert!(a.is_ok() && b.is_ok());
        let single = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("a pool of one thread");
        assert!(
            single
                .install(|| free_on_pool(vec![3u8; 1 << 22], &()))
                .is_ok()
        );
        struct Cancelled;
        impl SolveObserver for Cancelled {
            fn is_cancelled(&self) -> bool {
                true
            }
        }
        let stopped = single.install(|| free_on_pool(vec![4u8; 1 << 22], &Cancelled));
        assert!(matches!(stopped, Err(SolveError::Cancelled)));
    }

    /// A depth map that a file would hold as zeros (an absurd principal
    /// point solved to depths of 1e-200) is "the solve diverged", as is
    /// one beyond float32 (issue 48).
    #[test]
    fn zero_tiny_and_huge_depths_are_divergence() {
        let varied: Vec<f64> = (0..64).map(|k| 1.0 + 1e-3 * f64::from(k)).collect();
        assert_eq!(depth_divergence(&varied), None);
        assert_eq!(depth_divergence(&[1e-18; 64]), None);
        for (values, words) in [
            (vec![0.0; 64], "not in"),
            (vec![1e-200; 64], "not in"),
            (
                (0..64).map(|k| 1e-200 * (1.0 + f64::from(k))).collect(),
                "not in",
            ),
            (vec![1e31; 64], "not in"),
            (Vec::new(), "no pixel"),
        ] {
            let why = depth_divergence(&values).expect("divergence");
            assert!(why.contains(words), "{why}");
        }
    }
}
