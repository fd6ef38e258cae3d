//! `sfs-bench --part speed`'s rows of issue 50 where a user waits for more
//! than the solver: the albedo decision on a large render (its time over
//! albedo 1's), the shared face's LED 4 at its full size with a known
//! distance and as the viewer opens it (the time to the first surface
//! shown and to the end), and the face's seven photographs by photometric
//! stereo. Each through the same core calls the command line and the
//! viewer make (photograph preparation included), next to its target.

use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::params::{AlbedoChoice, SolverParams};
use sfs_core::photo;
use sfs_core::photograph_solve::PhotographSolve;
use sfs_core::solver::photometric::{PhotometricParams, solve_photometric};
use sfs_core::solver::{LevelResult, Method, SolveObserver, solve_method};

use super::shared::BenchArgs;

/// One of the rows.
#[derive(Debug, Serialize)]
pub struct PhotoSpeedRow {
    /// What was timed.
    pub what: String,
    /// The measurement before the round.
    pub today: String,
    /// The target.
    pub target: String,
    /// What this run measured.
    pub now: String,
    /// Whether the target is met.
    pub met: bool,
}

/// Records when the first level arrives.
struct FirstLevel {
    started: Instant,
    first: Option<f64>,
}

impl SolveObserver for FirstLevel {
    fn on_level(&mut self, _result: &LevelResult) {
        self.first
            .get_or_insert_with(|| self.started.elapsed().as_secs_f64());
    }
}

/// The rows this run can measure: the albedo row needs the meshes, the
/// face rows the shared photographs (`--real`); the others are skipped
/// with why.
pub fn rows(args: &BenchArgs, skipped: &mut Vec<String>) -> Result<Vec<PhotoSpeedRow>> {
    let mut rows = Vec::new();
    match super::scenes::render("dragon", &args.meshes, 1920, 1080) {
        Ok(scene) => rows.push(albedo_row(&scene)?),
        Err(e) => skipped.push(format!(
            "the albedo decision's row (dragon 1920x1080): {e:#}"
        )),
    }
    match face_led4(args) {
        Some(input) => {
            rows.push(face_row(&input, Some(640.0))?);
            rows.push(face_row(&input, None)?);
        }
        None => skipped.push(format!(
            "the face's rows: no near_ps_human1/led4.png and calibration.json under {}",
            args.real.display()
        )),
    }
    if let Some(input) = super::face::face_input(&args.real, None) {
        rows.push(set_row(&input)?);
    }
    Ok(rows)
}

/// `--albedo auto` against `--albedo 1` on one render: the decision's cost.
fn albedo_row(scene: &sfs_core::scene::Scene) -> Result<PhotoSpeedRow> {
    let problem = super::scenes::problem(scene, scene.image.clone());
    let time = |albedo: AlbedoChoice| -> Result<(f64, bool)> {
        let params = SolverParams {
            albedo,
            ..SolverParams::default()
        };
        let started = Instant::now();
        let solution = solve_method(&problem, &params, &Method::Linearised, &mut ())
            .context("the Dragon 1920x1080 failed")?;
        let used = solution.albedo_fit.as_ref().is_some_and(|f| f.used);
        Ok((started.elapsed().as_secs_f64(), used))
    };
    let (one, _) = time(AlbedoChoice::One)?;
    let (auto, used) = time(AlbedoChoice::Auto)?;
    let ratio = auto / one.max(1e-9);
    Ok(PhotoSpeedRow {
        what: "`--albedo auto` vs `--albedo 1`, 1920x1080 Dragon render".into(),
        today: "12.3 vs 3.3 s (3.7x)".into(),
        target: "≤ 1.3x".into(),
        now: format!(
            "{auto:.2} vs {one:.2} s ({ratio:.2}x; the estimate {})",
            if used { "used" } else { "not used" }
        ),
        met: ratio <= 1.3,
    })
}

/// The shared face's LED 4 alone at its full size: the set's input
/// (its calibration, mask and ambient photograph) cut to that photograph,
/// as the README's command reads it; `None` without it.
fn face_led4(args: &BenchArgs) -> Option<photo::PhotoInput> {
    let set = super::face::face_input(&args.real, None)?;
    let k = set
        .images
        .iter()
        .position(|p| p.file_name().is_some_and(|n| n == "led4.png"))?;
    set.one_of_set(k)
}

/// LED 4 from its files to the finished solve at the command line's
/// defaults (`--albedo auto`), with `distance` given or (`None`) as the
/// viewer opens it: the time to the first level shown and to the end.
fn face_row(input: &photo::PhotoInput, distance: Option<f64>) -> Result<PhotoSpeedRow> {
    let started = Instant::now();
    let prepared = photo::prepare(input).context("preparing LED 4")?;
    let params = SolverParams {
        albedo: AlbedoChoice::Auto,
        ..SolverParams::default()
    };
    let job = PhotographSolve {
        distance,
        ..PhotographSolve::from_prepared(prepared, params, Method::Linearised)
    };
    let (w, h) = job.problem.image.size();
    let mut observer = FirstLevel {
        started,
        first: None,
    };
    let solved = job.run(&mut observer).context("solving LED 4")?;
    let seconds = started.elapsed().as_secs_f64();
    let first = observer.first.unwrap_or(f64::NAN);
    let unit = solved
        .depth_unit
        .as_ref()
        .map_or("no unit".into(), |u| format!("{:?}", u.source));
    Ok(match distance {
        Some(d) => PhotoSpeedRow {
            what: format!("the face's LED 4, {w}x{h}, `--distance {d}`"),
            today: "136 s (2-5 min with albedo)".into(),
            target: "≤ 10 s".into(),
            now: format!("{seconds:.1} s (first level at {first:.2} s; unit: {unit})"),
            met: seconds <= 10.0,
        },
        None => PhotoSpeedRow {
            what: format!("the face's LED 4, {w}x{h}, as the viewer opens it (defaults)"),
            today: "10 s in the solve (21 s to the finished window)".into(),
            target: "≤ 5 s, first surface ≤ 0.5 s".into(),
            now: format!("{seconds:.1} s, first surface at {first:.2} s (unit: {unit})"),
            met: seconds <= 5.0 && first <= 0.5,
        },
    })
}

/// The face's photographs by photometric stereo at the set's defaults,
/// from the files.
fn set_row(input: &photo::PhotoInput) -> Result<PhotoSpeedRow> {
    let started = Instant::now();
    let prepared = photo::prepare(input).context("preparing the face's set")?;
    let problem = photo::photometric_problem(&prepared, input)?;
    let solution = solve_photometric(&problem, &PhotometricParams::default(), &mut ())?;
    let seconds = started.elapsed().as_secs_f64();
    Ok(PhotoSpeedRow {
        what: format!(
            "the face, {} photographs, photometric stereo",
            problem.photos.len()
        ),
        today: "12.9 s (its CG capped at 60 iterations, short of its tolerance)".into(),
        target: "≤ 5 s, converged".into(),
        now: format!(
            "{seconds:.1} s ({:.1} s in the solve; {} of {} linear solves capped short of their \
             tolerance, {} iterations)",
            solution.seconds,
            solution.linear.capped,
            solution.linear.solves,
            solution.linear.iterations
        ),
        met: seconds <= 5.0 && solution.linear.capped == 0,
    })
}
