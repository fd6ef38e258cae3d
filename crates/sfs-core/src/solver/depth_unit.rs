//! The depth unit of one photograph: the one decision, for the command
//! line, the viewer and the photometric-stereo mode's single photograph,
//! of what fixes the intensity scale `s` and with it the object's
//! distance.
//!
//! With every light at the optical centre `s` only sets the unit (depth
//! times `k` for `s` times `k^2`); with a light beside the lens the depth is
//! metric and `s` a real unknown that one photograph's shading rarely
//! decides (a tilt of the surface absorbs much of the light's offset).
//! The cues, strongest first:
//!
//! 1. what the user says: known distances at pixels (`--known-depth`), or
//!    the object's distance (`--distance`, its median depth), met by
//!    searching `s` ([`calibrate::solve_meeting`]); a measured `s`;
//! 2. the photograph's shading, where it decides
//!    ([`calibrate::estimate_intensity_scale`]'s `well_determined`);
//! 3. where the set-up aims its lights: a rig's LEDs are pointed at where
//!    the object will be, so the point their principal axes pass closest
//!    to ([`rig_aim`], two or more lights of the camera file, on or off for
//!    this photograph) is the object's distance to within
//!    [`RIG_AIM_PRECISION`]; one aimed light's axis where it crosses the
//!    optical axis ([`light_axis`]) to within [`LIGHT_AXIS_PRECISION`];
//! 4. otherwise a guess (the shading search's best), said as one.
//!
//! [`solve_photograph`] takes the cues, solves, and returns the
//! [`DepthUnit`]: which cue set the unit, how precisely, and its words.

use std::sync::Arc;

use glam::{DMat3, DVec3};
use serde::Serialize;

use crate::light::PointLight;
use crate::params::SolverParams;

use super::calibrate::{self, DistanceTarget, KnownDepth, KnownDepthFit, ScaleEstimate};
use super::problem::{Problem, Solution, SolveError, SolveMemo, SolveObserver};

/// The precision promised for a distance set by a rig's aim point
/// (relative). Measured: the shared face sits 21 % behind its rig's aim
/// point; the corpus of `bench --part depth-unit` (LEDs aimed at the
/// object's centre with random errors of up to 15 % of the distance) is
/// reported there.
pub const RIG_AIM_PRECISION: f64 = 0.25;
/// The precision promised for a distance set by one aimed light's axis
/// (relative): the shared face's seven LEDs alone put it 9-34 % short.
pub const LIGHT_AXIS_PRECISION: f64 = 0.5;
/// The precision of a distance the shading determined (relative):
/// [`calibrate::SCALE_TOLERANCE`] in `s`, about half of it in depth.
pub const SHADING_PRECISION: f64 = 0.15;
/// Axes whose root-mean-square distance from their closest point exceeds
/// this share of its depth do not aim at one place.
const MAX_AIM_SPREAD: f64 = 0.35;
/// Axes whose directions span less than this (the smallest eigenvalue of
/// the mean of `I - d d^T`) are too nearly parallel to cross.
const MIN_AIM_SPAN: f64 = 0.01;

/// What the user and the set-up say of the object's distance.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DistanceCues {
    /// Pixels of the solved (working-size) image whose depth is known.
    pub known_depths: Vec<KnownDepth>,
    /// The object's distance: the solved surface's median depth.
    pub distance: Option<f64>,
    /// Whether the intensity scale was given (measured): it sets the unit.
    pub scale_given: bool,
    /// Every light of the rig with a principal direction, on or off for
    /// this photograph (`photo::PhotoReport::rig_lights`).
    pub rig_lights: Vec<PointLight>,
}

/// Which cue set the depth unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UnitSource {
    /// Every light at the optical centre and no distance given: the unit
    /// is the intensity scale's (the paper's convention), not metric.
    CentredLight,
    /// A measured intensity scale.
    GivenScale,
    /// Known distances at pixels.
    KnownDepths,
    /// The object's distance, given.
    Distance,
    /// The photograph's shading determined it.
    Shading,
    /// The point a rig's lights are aimed at.
    RigAim,
    /// Where one aimed light's axis crosses the optical axis.
    LightAxis,
    /// Nothing decided: the shading search's best, a guess.
    Guess,
}

/// Where a rig's lights point: the point nearest to all their principal
/// axes (least squares), in the camera frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Aim {
    /// The point, units of depth.
    pub point: [f64; 3],
    /// The axes' root-mean-square distance from it, units of depth.
    pub spread: f64,
    /// The lights whose axes were crossed.
    pub lights: usize,
}

/// The depth unit a solve used: which cue set it, the distance it said,
/// how precisely, and what the solve made of it.
#[derive(Clone, Debug, Serialize)]
pub struct DepthUnit {
    /// The cue.
    pub source: UnitSource,
    /// The object's distance the cue said (median depth), units of depth;
    /// NaN where the cue says a scale, not a distance.
    pub cue_distance: f64,
    /// The cue's relative precision (0: exact or given; NaN: unknown).
    pub precision: f64,
    /// The solved surface's median depth.
    pub solved_distance: f64,
    /// The intensity scale the solve used.
    pub intensity_scale: f64,
    /// The rig's aim point, where there is one (also when another cue
    /// decided).
    pub aim: Option<Aim>,
    /// The shading search, where it ran.
    pub shading: Option<ScaleEstimate>,
    /// How the solve met known distances or the given distance.
    pub fit: Option<KnownDepthFit>,
}

impl DepthUnit {
    /// The decision in one line, `unit` the depth unit's name ("mm").
    pub fn words(&self, unit: &str) -> String {
        let pm = |p: f64| {
            if p.is_finite() && p > 0.0 {
                format!(" ± {:.0} %", 100.0 * p)
            } else {
                String::new()
            }
        };
        match self.source {
            UnitSource::CentredLight => format!(
                "depth unit from the intensity scale s = {:.4e} (light at the optical centre: \
                 the depth is in s's unit; give the object's distance for a metric one)",
                self.intensity_scale
            ),
            UnitSource::GivenScale => format!(
                "depth unit from the given intensity scale s = {:.4e}: object at {:.0} {unit}",
                self.intensity_scale, self.solved_distance
            ),
            UnitSource::KnownDepths => {
                let points = self.fit.as_ref().map_or(0, |f| f.points.len());
                format!(
                    "depth unit from the known distance{}: object at {:.0} {unit}",
                    if points == 1 { "" } else { "s" },
                    self.solved_distance,
                )
            }
            UnitSource::Distance => format!(
                "depth unit from the given object distance {:.0} {unit} (solved: {:.0} {unit})",
                self.cue_distance, self.solved_distance
            ),
            UnitSource::Shading => format!(
                "depth unit from the photograph's shading: object at {:.0} {unit}{}",
                self.solved_distance,
                pm(self.precision)
            ),
            UnitSource::RigAim => format!(
                "depth unit from the LEDs' aim point ({} lights): object at {:.0} {unit}{}",
                self.aim.map_or(0, |a| a.lights),
                self.cue_distance,
                pm(self.precision)
            ),
            UnitSource::LightAxis => format!(
                "depth unit from where the light is aimed: object at {:.0} {unit}{}",
                self.cue_distance,
                pm(self.precision)
            ),
            UnitSource::Guess => format!(
                "depth unit guessed: object at about {:.0} {unit} (nothing fixes it)",
                self.solved_distance
            ),
        }
    }

    /// A warning when the unit is a guess or loosely fixed, with the one
    /// thing to do; `None` otherwise.
    pub fn warning(&self, unit: &str) -> Option<String> {
        match self.source {
            UnitSource::Guess => Some(format!(
                "this image does not determine the intensity scale, so the depth unit is a guess \
                 (the object about {:.0} {unit} away could be much nearer or farther): give the \
                 object's distance (--distance) or a pixel's (--known-depth X,Y,Z)",
                self.solved_distance
            )),
            UnitSource::LightAxis => Some(format!(
                "the depth unit comes from where the light is aimed alone ({:.0} {unit} ± {:.0} \
                 %): give the object's distance (--distance) for a better one",
                self.cue_distance,
                100.0 * LIGHT_AXIS_PRECISION
            )),
            _ => None,
        }
    }

    /// Whether the user should give the distance: the unit is a guess or
    /// fixed only within [`RIG_AIM_PRECISION`] or worse.
    pub fn wants_distance(&self) -> bool {
        matches!(
            self.source,
            UnitSource::Guess | UnitSource::LightAxis | UnitSource::RigAim
        )
    }
}

/// The point nearest to the principal axes of `lights` (those with a
/// direction; at least two), when they aim at one place in front of the
/// camera: their directions span enough ([`MIN_AIM_SPAN`]), every light
/// points towards it, and their spread about it is at most
/// [`MAX_AIM_SPREAD`] of its depth.
pub fn rig_aim(lights: &[PointLight]) -> Option<Aim> {
    let axes: Vec<(DVec3, DVec3)> = lights
        .iter()
        .filter_map(|l| {
            let d = DVec3::from_array(l.direction?).normalize_or_zero();
            (d != DVec3::ZERO).then(|| (DVec3::from_array(l.position), d))
        })
        .collect();
    if axes.len() < 2 {
        return None;
    }
    let n = axes.len() as f64;
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for (p, d) in &axes {
        let m = DMat3::IDENTITY - outer(*d, *d);
        a += m;
        b += m * *p;
    }
    if smallest_eigenvalue(a * (1.0 / n)) < MIN_AIM_SPAN {
        return None;
    }
    let point = a.inverse() * b;
    if !(point.is_finite() && point.z > 0.0) {
        return None;
    }
    let mut sum = 0.0;
    for (p, d) in &axes {
        let t = (point - *p).dot(*d);
        if t <= 0.0 {
            return None;
        }
        sum += (*p + *d * t - point).length_squared();
    }
    let spread = (sum / n).sqrt();
    (spread <= MAX_AIM_SPREAD * point.z).then_some(Aim {
        point: point.to_array(),
        spread,
        lights: axes.len(),
    })
}

/// The depth at which one aimed light's axis passes closest to the optical
/// axis, when it does so in front of both the camera and the light, within
/// [`MAX_AIM_SPREAD`] of that depth of the axis, and the light is not
/// aimed along the optical axis.
pub fn light_axis(light: &PointLight) -> Option<f64> {
    let d = DVec3::from_array(light.direction?).normalize_or_zero();
    let p = DVec3::from_array(light.position);
    let across = d.truncate().length_squared();
    if across < 1e-4 {
        return None;
    }
    let t = -p.truncate().dot(d.truncate()) / across;
    let q = p + d * t;
    (t > 0.0 && q.z > 0.0 && q.truncate().length() <= MAX_AIM_SPREAD * q.z).then_some(q.z)
}

fn outer(u: DVec3, v: DVec3) -> DMat3 {
    DMat3::from_cols(u * v.x, u * v.y, u * v.z)
}

/// The smallest eigenvalue of a symmetric positive semi-definite matrix
/// (0 when singular): the inverse of the largest of its inverse, by power
/// iteration.
fn smallest_eigenvalue(m: DMat3) -> f64 {
    if m.determinant().abs() < 1e-15 {
        return 0.0;
    }
    let inverse = m.inverse();
    let mut v = DVec3::new(0.577, 0.578, 0.579);
    let mut largest = 0.0;
    for _ in 0..100 {
        let w = inverse * v;
        largest = w.length();
        if !(largest.is_finite() && largest > 0.0) {
            return 0.0;
        }
        v = w / largest;
    }
    1.0 / largest
}

/// The aim of the lights that say where the object is: the rig's (the
/// camera file's lights with a direction), else those of this photograph.
fn aim_of(problem: &Problem, cues: &DistanceCues) -> Option<Aim> {
    rig_aim(&cues.rig_lights).or_else(|| rig_aim(&problem.lights))
}

/// Solves one photograph with its depth unit decided from `cues` (see the
/// module docs); `problem.intensity_scale` ends as the one used.
///
/// # Errors
/// `SolveError::Input` when both known distances and an object distance
/// are given; else as [`calibrate::solve_meeting`],
/// [`calibrate::estimate_intensity_scale`] and [`super::solve_method`].
pub fn solve_photograph(
    problem: &mut Problem,
    params: &SolverParams,
    method: &super::method::Method,
    cues: &DistanceCues,
    observer: &mut dyn SolveObserver,
) -> Result<(Solution, DepthUnit), SolveError> {
    if !cues.known_depths.is_empty() && cues.distance.is_some() {
        return Err(SolveError::Input(
            "known distances at pixels and the object's distance both set the depth unit: give \
             one"
            .into(),
        ));
    }
    // Every solve below shares one store of solved working copies.
    let mut shared = SharesMemo {
        memo: observer.memo().unwrap_or_default(),
        observer,
    };
    let observer: &mut dyn SolveObserver = &mut shared;
    let aim = aim_of(problem, cues);
    // Lights off the centre: every cue but a given scale is searched with
    // trial solves (seconds on a photograph) before the solve shows a
    // level; a quick look goes out first.
    let searches = !cues.known_depths.is_empty() || cues.distance.is_some() || !cues.scale_given;
    if searches && !problem.light_is_centred() {
        send_walk_preview(problem, params, observer)?;
    }
    let mut unit = DepthUnit {
        source: UnitSource::Guess,
        cue_distance: f64::NAN,
        precision: f64::NAN,
        solved_distance: f64::NAN,
        intensity_scale: problem.intensity_scale,
        aim,
        shading: None,
        fit: None,
    };
    let meet = |problem: &mut Problem,
                target: DistanceTarget,
                observer: &mut dyn SolveObserver|
     -> Result<(Solution, KnownDepthFit), SolveError> {
        calibrate::solve_meeting(problem, params, method, &target, observer)
    };
    let solution = if !cues.known_depths.is_empty() {
        let (solution, fit) = meet(
            problem,
            DistanceTarget::Points(cues.known_depths.clone()),
            observer,
        )?;
        unit.source = UnitSource::KnownDepths;
        unit.precision = 0.0;
        unit.fit = Some(fit);
        solution
    } else if let Some(distance) = cues.distance {
        let (solution, fit) = meet(problem, DistanceTarget::Median(distance), observer)?;
        unit.source = UnitSource::Distance;
        unit.cue_distance = distance;
        unit.precision = 0.0;
        unit.fit = Some(fit);
        solution
    } else if problem.light_is_centred() || cues.scale_given {
        unit.source = if cues.scale_given {
            UnitSource::GivenScale
        } else {
            UnitSource::CentredLight
        };
        unit.precision = 0.0;
        super::method::solve_method(problem, params, method, observer)?
    } else {
        let shading = calibrate::estimate_intensity_scale(problem, params, observer)?;
        let axis = || {
            let mut aimed = problem.lights.iter().filter_map(light_axis);
            match (aimed.next(), aimed.next()) {
                (Some(z), None) => Some(z),
                _ => None,
            }
        };
        let solution = if shading.well_determined {
            problem.intensity_scale = shading.intensity_scale;
            unit.source = UnitSource::Shading;
            unit.cue_distance = shading.depth;
            unit.precision = SHADING_PRECISION;
            super::method::solve_method(problem, params, method, observer)?
        } else if let Some(aim) = aim {
            let (solution, fit) = meet(problem, DistanceTarget::Median(aim.point[2]), observer)?;
            unit.source = UnitSource::RigAim;
            unit.cue_distance = aim.point[2];
            unit.precision = RIG_AIM_PRECISION;
            unit.fit = Some(fit);
            solution
        } else if let Some(z) = axis() {
            let (solution, fit) = meet(problem, DistanceTarget::Median(z), observer)?;
            unit.source = UnitSource::LightAxis;
            unit.cue_distance = z;
            unit.precision = LIGHT_AXIS_PRECISION;
            unit.fit = Some(fit);
            solution
        } else {
            problem.intensity_scale = shading.intensity_scale;
            unit.source = UnitSource::Guess;
            unit.cue_distance = shading.depth;
            super::method::solve_method(problem, params, method, observer)?
        };
        unit.shading = Some(shading);
        solution
    };
    unit.intensity_scale = problem.intensity_scale;
    unit.solved_distance = calibrate::median_depth(&solution.depth);
    Ok((solution, unit))
}

/// Passes everything on and offers one [`SolveMemo`] to every solve of a
/// photograph's pipeline.
struct SharesMemo<'a> {
    observer: &'a mut dyn SolveObserver,
    memo: Arc<SolveMemo>,
}

impl SolveObserver for SharesMemo<'_> {
    fn on_iteration(&mut self, report: &super::problem::IterationReport) {
        self.observer.on_iteration(report);
    }
    fn on_level(&mut self, result: &super::problem::LevelResult) {
        self.observer.on_level(result);
    }
    fn is_cancelled(&self) -> bool {
        self.observer.is_cancelled()
    }
    fn memo(&self) -> Option<Arc<SolveMemo>> {
        Some(Arc::clone(&self.memo))
    }
}

/// The longest side of the quick look [`send_walk_preview`] solves.
pub const PREVIEW_WALK_SIDE: usize = 128;

/// Keeps the last level a solve shows; passes cancellation through.
struct LastLevel<'a> {
    observer: &'a mut dyn SolveObserver,
    last: Option<super::problem::LevelResult>,
}

impl SolveObserver for LastLevel<'_> {
    fn on_level(&mut self, result: &super::problem::LevelResult) {
        self.last = Some(result.clone());
    }
    fn is_cancelled(&self) -> bool {
        self.observer.is_cancelled()
    }
    fn memo(&self) -> Option<std::sync::Arc<super::problem::SolveMemo>> {
        self.observer.memo()
    }
}

/// Sends a quick look of a photograph larger than
/// [`PREVIEW_ABOVE_PIXELS`](super::preview::PREVIEW_ABOVE_PIXELS) to
/// `observer` as level 0 of 1, before the searches of its depth unit: the
/// linearised walk on a working copy of [`PREVIEW_WALK_SIDE`] at the
/// problem's present intensity scale (albedo 1, the material as a search
/// solves it). Its unit is not yet decided; the solve's own levels replace
/// it. A copy that cannot be solved sends nothing; cancellation is passed
/// on.
fn send_walk_preview(
    problem: &Problem,
    params: &SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<(), SolveError> {
    let started = std::time::Instant::now();
    let (w, h) = problem.image.size();
    if w * h <= super::preview::PREVIEW_ABOVE_PIXELS {
        return Ok(());
    }
    let copy = super::working::working_copy(problem, PREVIEW_WALK_SIDE);
    let quick = SolverParams {
        albedo: crate::params::AlbedoChoice::One,
        initial_depth: crate::params::InitialDepth::Walk,
        ..params.without_fit()
    };
    let mut last = LastLevel {
        observer: &mut *observer,
        last: None,
    };
    match super::driver::solve(&copy, &quick, &mut last) {
        Err(SolveError::Cancelled) => return Err(SolveError::Cancelled),
        Err(_) => return Ok(()),
        Ok(_) => {}
    }
    if let Some(level) = last.last {
        observer.on_level(&super::problem::LevelResult {
            level: 0,
            levels: 1,
            elapsed: started.elapsed(),
            ..level
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn aimed(position: [f64; 3], at: [f64; 3]) -> PointLight {
        let d = (DVec3::from_array(at) - DVec3::from_array(position)).normalize();
        PointLight {
            position,
            direction: Some(d.to_array()),
            mu: 1.0,
            intensity: 1.0,
        }
    }

    #[test]
    fn lights_aimed_at_one_point_cross_there() {
        let target = [10.0, -20.0, 600.0];
        let lights = [
            aimed([-200.0, 0.0, 400.0], target),
            aimed([200.0, -100.0, 450.0], target),
            aimed([0.0, 180.0, 420.0], target),
        ];
        let aim = rig_aim(&lights).expect("an aim");
        for (a, b) in aim.point.iter().zip(target) {
            assert!((a - b).abs() < 1e-9, "{aim:?}");
        }
        assert!(aim.spread < 1e-9 && aim.lights == 3);
        // One light's axis crosses the optical axis where it aims.
        let on_axis = aimed([-200.0, 0.0, 400.0], [0.0, 0.0, 650.0]);
        assert!((light_axis(&on_axis).expect("crosses") - 650.0).abs() < 1e-9);
    }

    #[test]
    fn parallel_diverging_or_backward_axes_aim_nowhere() {
        let parallel = [
            PointLight {
                position: [-100.0, 0.0, 0.0],
                direction: Some([0.0, 0.0, 1.0]),
                mu: 1.0,
                intensity: 1.0,
            },
            PointLight {
                position: [100.0, 0.0, 0.0],
                direction: Some([0.0, 0.0, 1.0]),
                mu: 1.0,
                intensity: 1.0,
            },
        ];
        assert_eq!(rig_aim(&parallel), None);
        assert_eq!(light_axis(&parallel[0]), None);
        // Aimed behind the camera.
        let back = [
            aimed([-100.0, 0.0, 10.0], [0.0, 0.0, -500.0]),
            aimed([100.0, 0.0, 10.0], [0.0, 0.0, -500.0]),
        ];
        assert_eq!(rig_aim(&back), None);
        // Lights without a direction, or only one: no rig.
        assert_eq!(rig_aim(&[PointLight::CENTRED, PointLight::CENTRED]), None);
        assert_eq!(rig_aim(&parallel[..1]), None);
    }
}
