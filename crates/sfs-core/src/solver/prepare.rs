//! The preparation every variational scheme shares: the validated problem's
//! pyramid, its scales (what relative parameters refer to), the automatic
//! alpha, the smoothness weights in pixel units, the update crop and the
//! initial depth (constant, a map, or fast marching on the denoised image),
//! so that the linearised and the explicit scheme minimise the same discrete
//! energy from the same start; and the per-level energy and result both
//! report.

use std::time::Instant;

use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::{self, Derivatives, Energy, LevelGeometry, Reflectance};
use crate::params::{
    Alpha, FAST_MARCHING_DENOISE_ABOVE, InitialDepth, ProblemScales, SolverParams, StartDenoise,
    Units,
};

pub use super::plane_start::nearest_object_depth;
use super::plane_start::plane_fit;
use super::problem::{
    LevelResult, NoiseReading, Problem, Solution, SolveError, SolveObserver, check_cancelled,
    masked,
};
use super::pyramid::{self, PyramidLevel};

/// A validated problem ready for a coarse-to-fine scheme: its pyramid
/// (coarsest first), the initial depth on the coarsest level and the
/// smoothness weights in pixel units. Shared by every variational scheme so
/// that they minimise the same discrete energy on the same levels.
pub(crate) struct Prepared<'a> {
    /// Levels, coarsest first; the last one is the full image.
    pub levels: Vec<PyramidLevel<'a>>,
    /// Levels already sent to the observer (a preview).
    pub shown: usize,
    /// Initial depth on the coarsest level.
    pub depth: Grid<f64>,
    /// The constant initial depth (or the warm start's mean).
    pub initial_depth: f64,
    /// `alpha` in pixel units.
    pub alpha: f64,
    /// `lambda` in pixel units.
    pub lambda: f64,
    /// The problem's scales (what relative units refer to).
    pub scales: ProblemScales,
    /// The alpha used, in the parameters' units (the chosen one for auto).
    pub alpha_used: f64,
    /// The per-pixel crop of the updates.
    pub crop: Crop,
    /// Derivatives with `h_z` in depth units.
    pub derivatives: Derivatives,
    /// The solve refines a full-resolution start (fast marching or a map)
    /// on the full image alone, instead of walking the pyramid up from a
    /// constant.
    pub refines_warm_start: bool,
    /// That full-resolution start is refined across holes (object pixels of
    /// confidence below [`super::holes::HOLE_CONFIDENCE`] wider than a
    /// speck) in an image that does not read noisy (see
    /// [`StartDenoise::Auto`]): the level runs `kappa_holes`
    /// iterations and [`LinearSolver::Auto`] is multigrid.
    ///
    /// [`LinearSolver::Auto`]: crate::params::LinearSolver::Auto
    pub refines_holes: bool,
    /// Whether the fast-marching start marched a denoised image; `None`
    /// when no fast-marching start was marched.
    pub start_denoised: Option<bool>,
    /// The image's noise as read here (whether it reads noisy:
    /// [`NoiseReading::reads_noisy`]).
    pub noise: NoiseReading,
    /// Other full-resolution starts that compete with `depth` where holes
    /// leave the start ambiguous (see `fast_marching_start`); empty
    /// otherwise.
    pub alternatives: Vec<Grid<f64>>,
    /// With lights off the optical centre, the object pixels taken out of
    /// the data term as shadow (see [`take_out_shadows`]); `None` with the
    /// light at the optical centre.
    pub shadow: Option<Grid<bool>>,
    /// The problem's lights (empty: the paper's light at the optical
    /// centre); the shadow's bound is taken toward them.
    pub lights: &'a [crate::light::PointLight],
    /// Whether the full-resolution surface is held behind the shadow's
    /// bound ([`SolverParams::shadow_bound`]).
    pub shadow_bound: bool,
    /// The walk on a working copy that gave the start (see [`WALK_SIDE`]):
    /// its levels' reports, phases and iterations, which are the solve's
    /// too; `None` for every other start.
    pub walked: Option<WalkedStart>,
}

/// The longest side of the working copy on which the default start walks
/// the pyramid where fast marching cannot serve (lights far off the
/// optical centre, a material whose brightness does not grow as the
/// surface turns to the light): on an image more than twice as large, the
/// walk's fine levels cost nearly all of its time (the shared face at
/// 1296x864: 39 levels at eta 0.9, the top eight 80 % of the time) while
/// each level's iterations lower its energy by about 1 %. The walk runs on a
/// working copy of this side (area-averaged, the parameters unchanged), and
/// its surface is refined at full size as a warm start (the fast-marching
/// start's schedule). `--init-depth from-image` keeps the paper's walk over
/// the whole pyramid.
pub const WALK_SIDE: usize = 256;

/// The longest image side above which the walk runs on a copy of
/// [`WALK_SIDE`] (twice it: below, the copy would save little).
pub const WALK_ABOVE_SIDE: usize = 2 * WALK_SIDE;

/// What the working copy's walk ran, carried into the solve's report.
pub(crate) struct WalkedStart {
    /// The copy's levels, coarsest first.
    pub reports: Vec<super::problem::LevelReport>,
    /// Its phases.
    pub phases: super::problem::PhaseTimes,
    /// Its outer iterations.
    pub iterations: usize,
    /// What its decisions did (for the unused options).
    pub effects: super::unused::Effects,
}

/// Solves a working copy of the problem by the same scheme and parameters
/// (the start of [`WALK_SIDE`]); given to [`prepare`] by the scheme, so that
/// the preparation does not import it.
pub(crate) type Walker<'w> = dyn FnMut(
        &Problem,
        &mut dyn SolveObserver,
    ) -> Result<(Solution, super::unused::Effects), SolveError>
    + 'w;

/// Passes the working copy's levels on to the user's observer as the first
/// levels of the solve (one level follows: the refinement at full size),
/// timed from the solve's start.
struct WalkLevels<'a> {
    observer: &'a mut dyn SolveObserver,
    start: Instant,
    shown: usize,
}

impl SolveObserver for WalkLevels<'_> {
    fn on_iteration(&mut self, report: &super::problem::IterationReport) {
        self.observer
            .on_iteration(&super::problem::IterationReport {
                levels: report.levels + 1,
                elapsed: self.start.elapsed(),
                ..report.clone()
            });
    }
    fn on_level(&mut self, result: &LevelResult) {
        self.shown = self.shown.max(result.level + 1);
        self.observer.on_level(&LevelResult {
            levels: result.levels + 1,
            elapsed: self.start.elapsed(),
            ..result.clone()
        });
    }
    fn is_cancelled(&self) -> bool {
        self.observer.is_cancelled()
    }
    fn memo(&self) -> Option<std::sync::Arc<super::problem::SolveMemo>> {
        self.observer.memo()
    }
}

impl Prepared<'_> {
    /// The initial depth, moved out (an empty grid is left behind).
    pub fn take_depth(&mut self) -> Grid<f64> {
        std::mem::replace(&mut self.depth, Grid::filled(0, 0, 0.0))
    }
}

/// The per-pixel limit on one update `|dz|`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Crop {
    /// At most this many depth units.
    Absolute(f64),
    /// At most this fraction of the pixel's depth.
    Relative(f64),
}

impl Crop {
    /// The largest step allowed at depth `z`.
    #[inline]
    pub(crate) fn limit(self, z: f64) -> f64 {
        match self {
            Crop::Absolute(limit) => limit,
            Crop::Relative(fraction) => fraction * z.abs(),
        }
    }
}

/// Validates `problem` and `params` and builds the pyramid and initial depth;
/// with `preview` (a scheme that shows its start as a level of its own),
/// before a fast-marching start on a large image, sends the start's preview
/// to `observer` (level 0 of 3: preview, start, refined; timed from
/// `start`).
///
/// With `walker` (a scheme that can solve a working copy), where the
/// default start cannot march a photograph more than [`WALK_ABOVE_SIDE`] on a side,
/// the start is `walker`'s solve of a working copy, its levels shown to
/// `observer` as the solve's first.
pub(crate) fn prepare<'a>(
    problem: &'a Problem,
    params: &SolverParams,
    preview: Option<Instant>,
    walker: Option<&mut Walker<'_>>,
    observer: &mut dyn SolveObserver,
) -> Result<Prepared<'a>, SolveError> {
    params.validate()?;
    // `auto` is resolved before any solve (`solver::material_fit`).
    let material = params.material();
    let initial_depth_map = match &params.initial_depth {
        InitialDepth::Map(map) => Some(map),
        _ => None,
    };
    let (domain, confidence) = problem.validate(
        params.domain,
        initial_depth_map,
        Cancel::new(&|| observer.is_cancelled()),
    )?;
    check_cancelled(observer)?;
    let (w, h) = problem.image.size();
    let scales = problem.scales(&confidence, Cancel::new(&|| observer.is_cancelled()))?;
    if let InitialDepth::Constant(z0) = params.initial_depth {
        crate::params::check_constant_initial_depth(z0, scales.depth)?;
    }
    let mut finest = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, problem.camera),
        image: std::borrow::Cow::Borrowed(&problem.image),
        // One byte per pixel where no partial confidence is painted.
        confidence: Confidence::from_grid(confidence, Cancel::new(&|| observer.is_cancelled()))?,
        domain,
    };
    let (shadow, relative_noise) = super::shadows::take_out(
        problem,
        &mut finest,
        &scales,
        Cancel::new(&|| observer.is_cancelled()),
    )?;
    // The image reads noisy where the noise over all trusted pixels and over
    // the brightest quarter of them (where the surface's own detail shows
    // least) are both above the threshold: the fast-marching start is then
    // denoised (`StartDenoise::Auto`), and holes get the schedule without
    // holes (see `refines_holes`). A clean render of a finely faceted
    // surface reads above it over all pixels alone (docs/paper-table1.md).
    let relative_facing = match relative_noise > FAST_MARCHING_DENOISE_ABOVE {
        true => super::auto_alpha::relative_facing_noise(
            &finest,
            &scales,
            Cancel::new(&|| observer.is_cancelled()),
        )?,
        false => f64::NAN,
    };
    let noise = NoiseReading {
        relative: relative_noise,
        relative_facing,
    };
    let reads_noisy = noise.reads_noisy();
    let start_denoised = match params.start_denoise {
        StartDenoise::Auto => reads_noisy,
        StartDenoise::On => true,
        StartDenoise::Off => false,
    };
    let alpha_used = match params.alpha {
        Alpha::Value(alpha) => alpha,
        Alpha::Auto => {
            let relative = super::auto_alpha::choose(relative_noise);
            match params.units {
                Units::Relative => relative,
                Units::Paper => scales.alpha_px(relative),
            }
        }
    };
    let (alpha, lambda, crop, derivatives) = match params.units {
        Units::Relative => (
            scales.alpha_px(alpha_used),
            scales.lambda_px(params.lambda),
            Crop::Relative(params.dz_limit),
            match params.derivatives {
                Derivatives::Numeric { h_z } => Derivatives::Numeric {
                    h_z: h_z * scales.depth,
                },
                exact => exact,
            },
        ),
        Units::Paper => (
            alpha_used,
            params.lambda,
            Crop::Absolute(params.dz_limit),
            params.derivatives,
        ),
    };
    // Fast marching knows only the centred light. Lights beside the lens
    // (within `light_frame::MAX_FRAME_ANGLE_DEG` of the camera, seen from
    // the object, and at most `light_frame::MAX_FRAME_DEPTH_SHARE` of the
    // way to it) are centred in their own frame, where the start is
    // marched (`light_frame`); lights farther off start from the plane that
    // best explains the image, refined through the whole pyramid (the
    // paper's path).
    // A material whose brightness does not grow as the surface turns to
    // the light (rough Oren-Nayar) has no fast marching: the constant or
    // plane start of the paper's path.
    let fast_marching_start_wanted = matches!(params.initial_depth, InitialDepth::FastMarching)
        && material.centred_is_monotone()
        && (problem.light_is_centred()
            || super::light_frame::serves(problem, &finest, scales.depth, material));
    // That start takes seconds on a photograph: its preview goes out first.
    let mut shown = match preview {
        Some(start) if fast_marching_start_wanted && problem.light_is_centred() => usize::from(
            super::preview::send_preview(problem, material, 3, start, observer)?,
        ),
        _ => 0,
    };
    // Where the default start cannot march a large image, it walks the
    // pyramid on a working copy (see `WALK_SIDE`).
    let walk_wanted = match params.initial_depth {
        InitialDepth::FastMarching => !fast_marching_start_wanted,
        InitialDepth::Walk => true,
        _ => false,
    } && w.max(h) > WALK_ABOVE_SIDE;
    let (walked, walked_depth) = match walker {
        Some(walker) if walk_wanted => {
            let copy = super::working::working_copy(problem, WALK_SIDE);
            let mut levels = WalkLevels {
                observer: &mut *observer,
                start: preview.unwrap_or_else(Instant::now),
                shown: 0,
            };
            let (solution, effects) = walker(&copy, &mut levels)?;
            shown = levels.shown;
            let coarse_domain = solution.depth.map(|z| z.is_finite());
            let depth = pyramid::upsample_depth(&solution.depth, &coarse_domain, &finest.domain);
            let walked = WalkedStart {
                reports: solution.levels,
                phases: solution.phases,
                iterations: solution.iterations,
                effects,
            };
            (Some(walked), Some(depth))
        }
        _ => (None, None),
    };
    let cancelled = || observer.is_cancelled();
    let cancel = Cancel::new(&cancelled);
    // With holes, fast marching offers more than one start (see
    // `fast_marching_start`): the first is the start, the others are
    // alternatives the scheme may pick by energy.
    let (fast_marching, alternatives) = match fast_marching_start_wanted {
        true => {
            let mut candidates = fast_marching_start(
                problem,
                material,
                &finest,
                relative_noise * scales.intensity,
                start_denoised,
                shadow.as_ref(),
                cancel,
            )?
            .into_iter();
            let first = candidates.next();
            let mut alternatives = Vec::new();
            for candidate in candidates {
                alternatives.push(fill_warm_start(&candidate, cancel)?.0);
            }
            (first, alternatives)
        }
        _ => (None, Vec::new()),
    };
    let warm = match &params.initial_depth {
        InitialDepth::Map(map) => Some(map),
        InitialDepth::FastMarching | InitialDepth::Walk => {
            fast_marching.as_ref().or(walked_depth.as_ref())
        }
        _ => None,
    };
    let sizes = if warm.is_some() {
        vec![(w, h)]
    } else {
        pyramid::level_sizes(w, h, params.eta, params.min_level_side)
    };
    if sizes.len() > pyramid::MAX_LEVELS {
        return Err(SolveError::Param(crate::params::ParamError {
            name: "eta",
            value: params.eta.to_string(),
            reason: format!(
                "gives {} pyramid levels at {w}x{h} (at most {}); lower eta or raise min-level-side",
                sizes.len(),
                pyramid::MAX_LEVELS
            ),
        }));
    }
    let mut levels = vec![finest];
    for &(lw, lh) in &sizes[1..] {
        cancel.check()?;
        let geometry = LevelGeometry::new(lw, lh, w, h, problem.camera);
        let Some(finer) = levels.last() else { break };
        let source = if params.anti_alias_sigma == 0.0 {
            &levels[0]
        } else {
            finer
        };
        let next = pyramid::downsample(source, geometry, params.anti_alias_sigma);
        if !next.domain.as_slice().iter().any(|&d| d) {
            break; // the object vanished at this size: stop coarsening
        }
        levels.push(next);
    }
    levels.reverse(); // coarsest first

    let coarsest = &levels[0];
    let (depth, initial_depth) = match (&params.initial_depth, warm) {
        (_, Some(map)) => fill_warm_start(map, cancel)?,
        (InitialDepth::Constant(z0), None) => (
            Grid::filled(coarsest.geometry.width, coarsest.geometry.height, *z0),
            *z0,
        ),
        _ if !problem.light_is_centred() => {
            let z0 = initial_depth_plane_fit(
                coarsest,
                &problem.model(material),
                scales.depth,
                nearest_object_depth(&problem.lights),
            );
            (
                Grid::filled(coarsest.geometry.width, coarsest.geometry.height, z0),
                z0,
            )
        }
        _ => {
            // A coarsest level with no bright trusted pixel left (they
            // averaged away) takes the same formula's median over the full
            // image, which validation guarantees exists.
            let z0 = initial_depth_from_image(
                coarsest,
                problem.centred_scale() * material.facing_gain(),
            )
            .unwrap_or(scales.depth);
            (
                Grid::filled(coarsest.geometry.width, coarsest.geometry.height, z0),
                z0,
            )
        }
    };
    // A warm start is refined on the full image alone (the only level).
    // Its holes get the longer, multigrid schedule only on a clean image:
    // in noise (where the start is denoised too) the SOR sweeps' damping is
    // part of the regularisation the automatic alpha was measured with, and
    // a converged solve fitted the noise (the noisy Sombrero's band 0.041
    // against 0.017).
    let refines_holes = warm.is_some()
        && !reads_noisy
        && levels
            .last()
            .is_some_and(|l| has_wide_holes(problem, l, shadow.as_ref()));
    Ok(Prepared {
        levels,
        shown,
        depth,
        initial_depth,
        alpha,
        lambda,
        scales,
        alpha_used,
        crop,
        derivatives,
        refines_warm_start: warm.is_some(),
        refines_holes,
        start_denoised: fast_marching_start_wanted.then_some(start_denoised),
        noise,
        alternatives,
        shadow,
        lights: &problem.lights,
        shadow_bound: params.shadow_bound,
        walked,
    })
}

/// The fast-marching starts of [`InitialDepth::FastMarching`] (NaN off the
/// object): untrusted object pixels filled by diffusion from trusted ones
/// (fast marching has no confidence), the image TV-denoised with weight
/// `noise_sigma` when `denoise`, then fast marching on the object. With
/// holes (untrusted object pixels, confidence below
/// [`super::holes::HOLE_CONFIDENCE`]) a second start follows, marched on
/// the trusted pixels alone, and both take the thin-plate fill of their
/// trusted depth across the holes; the scheme picks one by energy.
fn fast_marching_start(
    problem: &Problem,
    material: crate::material::Material,
    finest: &PyramidLevel,
    noise_sigma: f64,
    denoise: bool,
    shadow: Option<&Grid<bool>>,
    cancel: Cancel<'_>,
) -> Result<Vec<Grid<f64>>, SolveError> {
    // Fast marching reads only the object, so only untrusted object pixels
    // need filling; with denoising the background is filled too, so that
    // TV does not pull the silhouette towards the (black) background. At
    // 1920x1080 the background's diffusion cost a quarter of a second.
    use rayon::prelude::*;
    use std::borrow::Cow;
    let (w, h) = problem.image.size();
    let object = problem.object_mask.as_ref();
    let on_object = |q: usize| object.is_none_or(|m| m.as_slice()[q]);
    let mut known = Grid::filled(w, h, false);
    // Polled per chunk: at 18 MP one pass is tens of milliseconds.
    const CHUNK: usize = 8192;
    let unknown = known
        .as_mut_slice()
        .par_chunks_mut(CHUNK)
        .enumerate()
        .map(|(k, chunk)| {
            if cancel.is_cancelled() {
                return 0;
            }
            let mut unknown = 0;
            for (i, known) in chunk.iter_mut().enumerate() {
                let q = k * CHUNK + i;
                *known = finest.confidence.weight(q) >= 0.5 || (!denoise && !on_object(q));
                unknown += usize::from(!*known);
            }
            unknown
        })
        .sum::<usize>();
    cancel.check()?;
    // Nothing to fill and no denoising: the problem's own image (no copy).
    let mut image = Cow::Borrowed(&problem.image);
    if unknown > 0 {
        image = Cow::Owned(crate::denoise::fill_unknown(
            &problem.image,
            &known,
            cancel,
        )?);
    }
    drop(known);
    if denoise {
        image = Cow::Owned(crate::denoise::tv_denoise(
            &image,
            noise_sigma,
            TV_ITERATIONS,
            cancel,
        )?);
    }
    // The problem is validated already; the start needs only the depth (no
    // reprojection, energy or second validation: seconds at 18 megapixels).
    let everywhere;
    let object: &Grid<bool> = match object {
        Some(mask) => mask,
        None => {
            everywhere = Grid::filled(w, h, true);
            &everywhere
        }
    };
    let settings = super::fast_marching::FastMarchingParams::for_material(material);
    // Lights at the optical centre act as one of their summed intensity.
    let marched_scale = problem.centred_scale();
    let march = |image: &Grid<f64>, object: &Grid<bool>| -> Result<Grid<f64>, SolveError> {
        if !problem.light_is_centred()
            && let Some(depth) = super::light_frame::march_from_the_light(
                image,
                object,
                problem.camera,
                problem.intensity_scale,
                &problem.lights,
                &settings,
                cancel,
            )?
        {
            return Ok(depth);
        }
        super::fast_marching::march(
            image,
            problem.camera,
            object,
            marched_scale,
            &settings,
            cancel,
        )
        .map(|(depth, _)| depth)
    };
    let mut candidates = vec![march(&image, object)?];
    // What the image cannot tell is filled in depth: the smoothest surface
    // that continues the trusted one. Two starts compete (the lower energy
    // after one step wins, see the driver's `pick_start`): marched across the image diffused into the
    // holes (a region beyond a hole inherits the surface marched through
    // it, right where the hole hides no turn of the surface), and marched
    // on the trusted pixels alone (each region beyond a hole from its own
    // brightest points, right where the diffused image misleads; slivers
    // too small to hold a point facing the light are filled instead).
    // Holes are untrusted object pixels (the background is no hole: its
    // start is the mean, as without holes). Without any, nothing more is
    // allocated or computed.
    let on_object_at = |q: usize| finest.domain.as_slice()[q] && object.as_slice()[q];
    if has_holes(problem, finest, shadow) {
        let on_object = Grid::from_fn(w, h, |c, r| on_object_at(r * w + c));
        let trusted = Grid::from_fn(w, h, |c, r| {
            *on_object.at(c, r)
                && finest.confidence.weight(r * w + c) >= super::holes::HOLE_CONFIDENCE
        });
        let mut separate = march(&image, &trusted)?;
        let mut anchored = trusted.clone();
        super::holes::drop_small_regions(&mut anchored, super::holes::MIN_REGION_SHARE);
        super::holes::thin_plate_fill(&mut separate, &on_object, &anchored, cancel)?;
        super::holes::thin_plate_fill(&mut candidates[0], &on_object, &trusted, cancel)?;
        // A third start marches on the image the filled surface would show
        // in the holes: where a hole hides the point that faces the light
        // (a dome's top, a plane's foot point), the first two start from the
        // rim as if it faced the light; the continued surface turns inside
        // the hole, and its image gives fast marching that point back.
        let shown = crate::model::reproject(
            &problem.model(material),
            &finest.geometry,
            &on_object,
            &candidates[0],
            cancel,
        )?;
        let continued_image = Grid::from_fn(w, h, |c, r| match *trusted.at(c, r) {
            false if *on_object.at(c, r) => *shown.at(c, r),
            _ => *image.at(c, r),
        });
        drop(shown);
        let mut continued = march(&continued_image, object)?;
        drop(continued_image);
        super::holes::thin_plate_fill(&mut continued, &on_object, &trusted, cancel)?;
        candidates.push(separate);
        candidates.push(continued);
    }
    drop(image);
    for solved in &mut candidates {
        // NaN off the object, in place.
        crate::grid::for_rows(solved.as_mut_slice(), w, cancel, |r, depth| {
            for (c, z) in depth.iter_mut().enumerate() {
                if !object.at(c, r) {
                    *z = f64::NAN;
                }
            }
        })?;
    }
    Ok(candidates)
}

/// Pixel `q` of `level` (the full image of `problem`) is an object pixel
/// of its domain: `Some(true)` where its confidence is below
/// [`super::holes::HOLE_CONFIDENCE`] (a hole), `Some(false)` where it is
/// trusted, `None` off the object (the background is no hole) and on
/// `shadow` (no light reaches it: the image says no more there).
fn hole_at(
    problem: &Problem,
    level: &PyramidLevel,
    shadow: Option<&Grid<bool>>,
    q: usize,
) -> Option<bool> {
    let on_object = level.domain.as_slice()[q]
        && problem.object_mask.as_ref().is_none_or(|m| m.as_slice()[q])
        && !shadow.is_some_and(|s| s.as_slice()[q]);
    on_object.then(|| level.confidence.weight(q) < super::holes::HOLE_CONFIDENCE)
}

/// Whether `level` (the full image of `problem`) has a hole pixel. Stops
/// at the first.
fn has_holes(problem: &Problem, level: &PyramidLevel, shadow: Option<&Grid<bool>>) -> bool {
    (0..level.domain.as_slice().len()).any(|q| hole_at(problem, level, shadow, q) == Some(true))
}

/// Whether `level` (the full image of `problem`) has a hole wider than a
/// speck: a hole pixel none of whose four neighbours is a trusted object
/// pixel. Clipped pixels of a noisy image are untrusted specks, not holes:
/// their neighbours carry the data. Stops at the first.
fn has_wide_holes(problem: &Problem, level: &PyramidLevel, shadow: Option<&Grid<bool>>) -> bool {
    let (w, h) = (level.geometry.width, level.geometry.height);
    let trusted = |q: usize| hole_at(problem, level, shadow, q) == Some(false);
    (0..w * h).any(|q| {
        let (c, r) = (q % w, q / w);
        hole_at(problem, level, shadow, q) == Some(true)
            && !(c > 0 && trusted(q - 1))
            && !(c + 1 < w && trusted(q + 1))
            && !(r > 0 && trusted(q - w))
            && !(r + 1 < h && trusted(q + w))
    })
}

/// Primal-dual iterations of the TV denoising before the fast-marching start.
const TV_ITERATIONS: usize = 200;

/// The constant initial depth of [`InitialDepth::FromImage`] on a level: the
/// brightest trusted domain pixel `b` is assumed to face the light,
/// `z0 = Q_b sqrt(s / I_b)`; `None` when the level has no trusted domain
/// pixel brighter than black.
pub fn initial_depth_from_image(level: &PyramidLevel, intensity_scale: f64) -> Option<f64> {
    let (w, h) = level.image.size();
    let mut best = (0.0, 1.0);
    for r in 0..h {
        for c in 0..w {
            let v = *level.image.at(c, r);
            if *level.domain.at(c, r) && level.confidence.at(c, r) > 0.0 && v > best.0 {
                best = (v, level.geometry.ray(c, r).q());
            }
        }
    }
    (best.0 > 0.0).then(|| best.1 * (intensity_scale / best.0).sqrt())
}

/// The constant initial depth for lights anywhere: the fronto-parallel
/// plane `z = z0 >= nearest` whose rendering best fits the trusted domain
/// pixels of `level` in least squares (a scan over six decades around
/// `guess`, refined by golden sections on `log z0`).
pub fn initial_depth_plane_fit<M: Reflectance>(
    level: &PyramidLevel,
    model: &M,
    guess: f64,
    nearest: f64,
) -> f64 {
    let (w, h) = level.image.size();
    let pixels: Vec<(model::PixelRay, f64)> = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .filter(|&(c, r)| *level.domain.at(c, r) && level.confidence.at(c, r) > 0.0)
        .map(|(c, r)| (level.geometry.ray(c, r), *level.image.at(c, r)))
        .collect();
    plane_fit(&pixels, model, guess, nearest)
}

/// Replaces non-finite or non-positive values of a warm start by the mean.
/// Polls `cancel` per row.
fn fill_warm_start(map: &Grid<f64>, cancel: Cancel<'_>) -> Result<(Grid<f64>, f64), Cancelled> {
    let valid = |z: f64| z.is_finite() && z > 0.0;
    let w = map.width().max(1);
    // Summed in order (the mean is the same to the bit as one pass's).
    let mut sum = 0.0;
    let mut count = 0usize;
    for (r, row) in map.as_slice().chunks(w).enumerate() {
        if r % 64 == 0 {
            cancel.check()?;
        }
        for &z in row.iter().filter(|&&z| valid(z)) {
            sum += z;
            count += 1;
        }
    }
    let mean = sum / count.max(1) as f64;
    let mut filled = Grid::filled(map.width(), map.height(), 0.0);
    crate::grid::for_rows(filled.as_mut_slice(), w, cancel, |r, out| {
        for (c, out) in out.iter_mut().enumerate() {
            let z = *map.at(c, r);
            *out = if valid(z) { z } else { mean };
        }
    })?;
    Ok((filled, mean))
}

/// A level's depth (NaN off its domain) and reprojection, as observers get
/// them; both passes poll `cancel` per row.
#[allow(clippy::too_many_arguments)]
pub(crate) fn level_result<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    index: usize,
    levels: usize,
    energy: Energy,
    start: Instant,
    cancel: Cancel<'_>,
) -> Result<LevelResult, Cancelled> {
    Ok(LevelResult {
        level: index,
        levels,
        depth: std::sync::Arc::new(masked(depth, &level.domain, cancel)?),
        reprojection: std::sync::Arc::new(model::reproject(
            model,
            &level.geometry,
            &level.domain,
            depth,
            cancel,
        )?),
        geometry: level.geometry,
        domain_pixels: {
            use rayon::prelude::*;
            level.domain.as_slice().par_iter().filter(|&&d| d).count()
        },
        energy,
        elapsed: start.elapsed(),
    })
}

/// Energy of a level, polling `cancel` per row.
pub(crate) fn level_energy<M: Reflectance>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    alpha: f64,
    lambda: f64,
    cancel: Cancel<'_>,
) -> Result<Energy, Cancelled> {
    model::energy(
        model,
        &level.geometry,
        &level.image,
        &level.confidence,
        &level.domain,
        depth,
        alpha,
        lambda,
        cancel,
    )
}
