//! `sfs-bench --part speed`: time, peak memory, bytes per pixel, RSE and the
//! RSE-over-time curve of the defaults at the paper's size, at 1920x1080
//! and (with `--large`) at 18 megapixels, side by side with fast marching
//! and the paper's fixed schedule (constant start, whole pyramid) in the
//! same run; and the solver's responsiveness: the time to the first level
//! and how long a cancellation takes to stop it. Writes `speed.md`,
//! `speed.json` and one curve figure per size.

use std::fmt::Write as _;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use serde::Serialize;

use super::figures::{self, Figure, LogLogPlot, Series};
use super::markdown::table;
use super::shared::{BenchArgs, CurveRecorder, reset_peak_memory};
use sfs_core::memory::proc_mib;
use sfs_core::params::{InitialDepth, LinearSolver, SolverParams};
use sfs_core::scene::Scene;
use sfs_core::solver::fast_marching::FastMarchingParams;
use sfs_core::solver::{LevelResult, Method, Problem, Solution, SolveObserver, solve_method};

/// One solve.
#[derive(Debug, Serialize)]
pub struct SpeedRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// `defaults`, `fixed counts`, `multigrid`, `paper schedule` or `fast
    /// marching`.
    pub method: String,
    /// Wall-clock seconds of the solve.
    pub seconds: f64,
    /// Growth of the peak resident set during the solve, MiB.
    pub peak_growth_mib: f64,
    /// That growth per image pixel, bytes.
    pub bytes_per_pixel: f64,
    /// RSE against the ground truth.
    pub rse: f64,
    /// RIE against the noise-free image (the model's reprojection over the
    /// ground-truth mask).
    pub rie: f64,
    /// Seconds from the start to the first level reported.
    pub first_level_seconds: Option<f64>,
    /// `(seconds, RSE)` at every level reported.
    pub curve: Vec<(f64, f64)>,
    /// Inner iterations (linear solves) run.
    pub inner_iterations: usize,
    /// SOR sweeps or V-cycles run.
    pub linear_iterations: usize,
}

/// The linear solvers on one system: the first Gauss-Newton system at the
/// fast-marching start of a scene, solved from zero by SOR and by V-cycles.
#[derive(Debug, Serialize)]
pub struct ConvergenceRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// Residual after 10 SOR sweeps (the paper's count) over the initial one.
    pub sor_after_10: f64,
    /// Residual after 40 SOR sweeps over the initial one.
    pub sor_after_40: f64,
    /// Residual reduction per sweep over sweeps 30 to 40.
    pub sor_factor_late: f64,
    /// Residual after 1 V-cycle over the initial one.
    pub cycle_after_1: f64,
    /// Residual after 4 V-cycles over the initial one.
    pub cycle_after_4: f64,
    /// Residual reduction per cycle over cycles 2 to 4.
    pub cycle_factor_late: f64,
    /// Seconds per SOR sweep.
    pub seconds_per_sweep: f64,
    /// Seconds per V-cycle (its residual check excluded).
    pub seconds_per_cycle: f64,
    /// Seconds to build the Galerkin hierarchy.
    pub hierarchy_seconds: f64,
}

/// How long a cancellation took to stop a solve.
#[derive(Debug, Serialize)]
pub struct CancelRow {
    /// `WxH`.
    pub size: String,
    /// When the cancellation was requested, seconds after the start.
    pub requested_at_seconds: f64,
    /// From the request to the solver's return, milliseconds.
    pub stop_ms: f64,
}

/// The whole speed report.
#[derive(Debug, Serialize)]
pub struct SpeedReport {
    /// The command line.
    pub command: String,
    /// Every solve.
    pub rows: Vec<SpeedRow>,
    /// Cancellation latencies.
    pub cancels: Vec<CancelRow>,
    /// SOR against V-cycles on the same systems.
    pub convergence: Vec<ConvergenceRow>,
    /// Issue 50's rows of photographs and decisions (`speed_photo`).
    pub photographs: Vec<super::speed_photo::PhotoSpeedRow>,
    /// Scenes not run (missing meshes).
    pub skipped: Vec<String>,
}

/// Records the curve and the first level's time.
struct Recorder<'a> {
    curve: CurveRecorder<'a>,
    started: Instant,
    first_level: Option<f64>,
}

impl SolveObserver for Recorder<'_> {
    fn on_level(&mut self, result: &LevelResult) {
        self.first_level
            .get_or_insert_with(|| self.started.elapsed().as_secs_f64());
        self.curve.on_level(result);
    }
}

/// Cancels once `flag` is set.
struct Cancel(Arc<AtomicBool>);

impl SolveObserver for Cancel {
    fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

fn problem(scene: &Scene) -> Problem {
    super::scenes::problem(scene, scene.image.clone())
}

/// The scenes: name, size.
fn cases(args: &BenchArgs, large: bool) -> Vec<(&'static str, (usize, usize))> {
    let mut cases = vec![
        ("sombrero", (256, 256)),
        ("bunny", (256, 256)),
        ("dragon", (256, 256)),
        ("dragon", (1920, 1080)),
    ];
    if large {
        cases.push(("dragon", (5184, 3456)));
        // Issue 50's 18 MP row.
        cases.push(("sombrero", (5184, 3456)));
    }
    if args.quick {
        cases.retain(|(_, (w, _))| *w <= 256);
    }
    cases
        .into_iter()
        .filter(|(name, _)| super::shared::wanted(args, name))
        .collect()
}

fn measure(
    scene: &Scene,
    name: &str,
    method_name: &str,
    method: &Method,
    params: &SolverParams,
) -> Result<(SpeedRow, Solution)> {
    let problem = problem(scene);
    let (w, h) = scene.image.size();
    release_freed_memory();
    reset_peak_memory();
    let before_mib = proc_mib("/proc/self/status", "VmRSS").unwrap_or(f64::NAN);
    let mut recorder = Recorder {
        curve: CurveRecorder {
            truth: &scene.depth_gt,
            full_domain: scene.object_mask.clone(),
            points: Vec::new(),
            overhead: Duration::ZERO,
        },
        started: Instant::now(),
        first_level: None,
    };
    let started = Instant::now();
    let solution = solve_method(&problem, params, method, &mut recorder)
        .with_context(|| format!("{name} {w}x{h} with {method_name} failed"))?;
    let seconds = started
        .elapsed()
        .saturating_sub(recorder.curve.overhead)
        .as_secs_f64();
    let peak_mib = proc_mib("/proc/self/status", "VmHWM").unwrap_or(f64::NAN);
    let growth = (peak_mib - before_mib).max(0.0);
    let errors = scene
        .centred_errors(&solution.depth)
        .with_context(|| format!("scoring {name} failed"))?;
    let row = SpeedRow {
        scene: name.into(),
        size: format!("{w}x{h}"),
        method: method_name.into(),
        seconds,
        peak_growth_mib: growth,
        bytes_per_pixel: growth * 1024.0 * 1024.0 / (w * h) as f64,
        rse: errors.rse,
        rie: errors.rie,
        first_level_seconds: recorder.first_level,
        curve: recorder.curve.points,
        inner_iterations: solution.phases.inner_iterations,
        linear_iterations: solution.phases.linear_iterations,
    };
    Ok((row, solution))
}

/// SOR sweeps against V-cycles on the first Gauss-Newton system at the
/// fast-marching start of `scene` (`fast_marching`, that method's solution;
/// object domain, the alpha and lambda in pixel units of `defaults`, the
/// default solve's).
fn convergence(
    scene: &Scene,
    name: &str,
    fast_marching: &Solution,
    defaults: &Solution,
) -> Result<ConvergenceRow> {
    use sfs_core::cancel::{Cancel, Uncancelled};
    use sfs_core::model::{Derivatives, LevelGeometry};
    use sfs_core::solver::multigrid::{Multigrid, Smoother, Sor};
    use sfs_core::solver::pyramid::PyramidLevel;
    use sfs_core::solver::system::LinearSystem;
    let problem = problem(scene);
    let (w, h) = scene.image.size();
    let omega = SolverParams::default().omega;
    let level = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, scene.camera),
        image: std::borrow::Cow::Borrowed(&scene.image),
        confidence: sfs_core::grid::Confidence::Binary(scene.object_mask.clone()),
        domain: scene.object_mask.clone(),
    };
    let depth = fast_marching
        .depth
        .map(|&z| if z.is_finite() { z } else { 1.0 });
    let model = problem.model(sfs_core::material::Material::Lambert);
    let fresh = || -> Result<LinearSystem> {
        let mut system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
        anyhow::ensure!(
            system
                .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
                .uncancelled(),
            "no exact derivatives"
        );
        system
            .add_smoothness(
                &level,
                &depth,
                defaults.alpha_px,
                defaults.lambda_px,
                Cancel::NEVER,
            )
            .uncancelled();
        Ok(system)
    };
    let mut residual_buffer = Vec::new();
    let mut residual = |system: &LinearSystem| {
        residual_buffer.resize(system.dz_padded.len(), 0.0);
        system.residual_into(&mut residual_buffer).sqrt()
    };
    let mut sor = fresh()?;
    let initial = residual(&sor);
    let smoother = Sor { omega };
    let timer = Instant::now();
    smoother.smooth(&mut sor, 10);
    let mut seconds = timer.elapsed().as_secs_f64();
    let after_10 = residual(&sor);
    let timer = Instant::now();
    smoother.smooth(&mut sor, 20);
    seconds += timer.elapsed().as_secs_f64();
    let after_30 = residual(&sor);
    let timer = Instant::now();
    smoother.smooth(&mut sor, 10);
    seconds += timer.elapsed().as_secs_f64();
    let after_40 = residual(&sor);
    let mut mg_system = fresh()?;
    let timer = Instant::now();
    let mut multigrid = Multigrid::build(&mg_system, SolverParams::default().smoothing_sweeps);
    let hierarchy_seconds = timer.elapsed().as_secs_f64();
    let mut cycle_seconds = 0.0;
    let mut after = Vec::new();
    for _ in 0..4 {
        let timer = Instant::now();
        multigrid.cycle(&mut mg_system, &Multigrid::SMOOTHER);
        cycle_seconds += timer.elapsed().as_secs_f64();
        after.push(residual(&mg_system));
    }
    let ratio = |r: f64| r / initial.max(f64::MIN_POSITIVE);
    Ok(ConvergenceRow {
        scene: name.into(),
        size: format!("{w}x{h}"),
        sor_after_10: ratio(after_10),
        sor_after_40: ratio(after_40),
        sor_factor_late: (after_40 / after_30.max(f64::MIN_POSITIVE)).powf(0.1),
        cycle_after_1: ratio(after[0]),
        cycle_after_4: ratio(after[3]),
        cycle_factor_late: (after[3] / after[0].max(f64::MIN_POSITIVE)).powf(1.0 / 3.0),
        seconds_per_sweep: seconds / 40.0,
        seconds_per_cycle: cycle_seconds / 4.0,
        hierarchy_seconds,
    })
}

/// Hands the heap that earlier solves freed back to the system, so that the
/// next solve's peak growth is its own (glibc keeps freed memory resident
/// and reuses it otherwise, and the growth would read near zero).
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns free heap pages to the kernel; it
    // takes no pointers and is safe to call at any time from any thread.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Starts the default solve of `scene`, cancels it after `after`, returns
/// how long it took to stop.
fn cancel_latency(scene: &Scene, after: Duration) -> CancelRow {
    let flag = Arc::new(AtomicBool::new(false));
    let problem = problem(scene);
    let params = SolverParams::default();
    let observer_flag = Arc::clone(&flag);
    let (done_tx, done_rx) = crossbeam_channel::bounded::<Instant>(1);
    let handle = std::thread::spawn(move || {
        let mut observer = Cancel(observer_flag);
        let _ = sfs_core::solver::solve(&problem, &params, &mut observer);
        let _ = done_tx.send(Instant::now());
    });
    let started = Instant::now();
    std::thread::sleep(after);
    let requested = Instant::now();
    flag.store(true, Ordering::Relaxed);
    let stopped = done_rx.recv().unwrap_or(requested);
    let _ = handle.join();
    let (w, h) = scene.image.size();
    CancelRow {
        size: format!("{w}x{h}"),
        requested_at_seconds: requested.duration_since(started).as_secs_f64(),
        stop_ms: stopped.saturating_duration_since(requested).as_secs_f64() * 1e3,
    }
}

/// Runs the speed part into `args.out`.
pub fn run(args: &BenchArgs, large: bool) -> Result<SpeedReport> {
    let mut rows = Vec::new();
    let mut cancels = Vec::new();
    let mut convergence_rows = Vec::new();
    let mut skipped = Vec::new();
    let defaults = SolverParams::default();
    // The defaults before adaptive stopping (every count run).
    let fixed_counts = SolverParams::default().with_fixed_schedule();
    let multigrid = SolverParams {
        linear_solver: LinearSolver::Multigrid,
        linear_tolerance: 0.1,
        ..SolverParams::default()
    };
    let paper_schedule = SolverParams {
        initial_depth: InitialDepth::FromImage,
        ..SolverParams::default()
    }
    .with_fixed_schedule();
    // The refinement stopped once the depth has settled (issue 50's lever,
    // off by default: the same RSE, a worse image fit).
    let settling = SolverParams {
        step_tolerance: 1e-4,
        ..SolverParams::default()
    };
    let fm = Method::FastMarching(FastMarchingParams::default());
    for (name, size) in cases(args, large) {
        let scene = match super::scenes::render(name, &args.meshes, size.0, size.1) {
            Ok(scene) => scene,
            Err(e) => {
                skipped.push(format!("{name} {}x{}: {e:#}", size.0, size.1));
                continue;
            }
        };
        eprintln!("speed: {name} {}x{}", size.0, size.1);
        let (default_row, default_solution) =
            measure(&scene, name, "defaults", &Method::Linearised, &defaults)?;
        let (fm_row, fm_solution) = measure(&scene, name, "fast marching", &fm, &defaults)?;
        if size.0 * size.1 <= 4_000_000 {
            convergence_rows.push(convergence(&scene, name, &fm_solution, &default_solution)?);
        }
        drop((default_solution, fm_solution));
        let mut group = vec![default_row, fm_row];
        for (label, params) in [
            ("fixed counts", &fixed_counts),
            ("multigrid", &multigrid),
            ("step tolerance 1e-4", &settling),
        ] {
            group.push(measure(&scene, name, label, &Method::Linearised, params)?.0);
        }
        // The paper's schedule at 18 MP takes about an hour: left out there.
        if size.0 * size.1 <= 4_000_000 {
            group.push(
                measure(
                    &scene,
                    name,
                    "paper schedule",
                    &Method::Linearised,
                    &paper_schedule,
                )?
                .0,
            );
        }
        if size.0 * size.1 > 1_000_000 {
            cancels.push(cancel_latency(&scene, Duration::from_millis(500)));
        }
        let figure = format!("speed-{name}-{}x{}.png", size.0, size.1);
        curve_plot(
            &group,
            &format!("RSE over time: {name} {}x{}", size.0, size.1),
        )?
        .save(&args.out.join(&figure))?;
        rows.extend(group);
    }
    // Issue 50's rows of photographs and decisions: not in the quick run
    // (each takes seconds to minutes).
    let photographs = if args.quick {
        Vec::new()
    } else {
        eprintln!("speed: the photographs' and decisions' rows");
        super::speed_photo::rows(args, &mut skipped)?
    };
    let report = SpeedReport {
        command: super::shared::command_line(),
        rows,
        cancels,
        convergence: convergence_rows,
        photographs,
        skipped,
    };
    super::markdown::write_part(&args.out, "speed", &report, &markdown(&report))?;
    Ok(report)
}

/// RSE over time of every method of one size, titled `title`.
fn curve_plot(rows: &[SpeedRow], title: &str) -> Result<Figure> {
    const COLOURS: [[u8; 3]; 5] = [
        [31, 90, 200],
        [40, 150, 60],
        [150, 150, 150],
        [230, 150, 30],
        [210, 40, 40],
    ];
    let series: Vec<Series> = rows
        .iter()
        .zip(COLOURS)
        .map(|(row, colour)| Series {
            colour,
            label: &row.method,
            points: &row.curve,
        })
        .collect();
    let all = || rows.iter().flat_map(|r| r.curve.iter());
    LogLogPlot {
        title,
        x_name: "seconds",
        y_name: "RSE",
        x_range: figures::decades(all().map(|p| p.0)),
        y_range: figures::decades(all().map(|p| p.1)),
        series: &series,
    }
    .draw()
}

fn markdown(report: &SpeedReport) -> String {
    let mut md = String::from("# Speed\n\n");
    let _ = writeln!(md, "`{}`\n", report.command);
    table(
        &mut md,
        "| scene | size | method | seconds | x fast marching | first level (s) | peak growth (MiB) | bytes/px | RSE | RIE | inner its | sweeps / cycles |",
        &report.rows,
        |row| {
            let fm = report
                .rows
                .iter()
                .find(|r| r.scene == row.scene && r.size == row.size && r.method == "fast marching")
                .map(|r| r.seconds);
            format!(
                "| {} | {} | {} | {:.3} | {} | {} | {:.0} | {:.0} | {:.4} | {:.4} | {} | {} |",
                row.scene,
                row.size,
                row.method,
                row.seconds,
                fm.map_or("–".into(), |f| format!(
                    "{:.1}",
                    row.seconds / f.max(1e-9)
                )),
                row.first_level_seconds
                    .map_or("–".into(), |t| format!("{t:.3}")),
                row.peak_growth_mib,
                row.bytes_per_pixel,
                row.rse,
                row.rie,
                row.inner_iterations,
                row.linear_iterations
            )
        },
    );
    if !report.convergence.is_empty() {
        md.push_str(
            "\nThe linear solvers on one system (the first Gauss-Newton system at the \
             fast-marching start), from zero: residual over the initial one.\n\n",
        );
        table(
            &mut md,
            "| scene | size | 10 SOR sweeps | 40 sweeps | per sweep (30-40) | s/sweep | 1 V-cycle | 4 V-cycles | per cycle (2-4) | s/cycle | hierarchy (s) |",
            &report.convergence,
            |c| {
                format!(
                    "| {} | {} | {:.3} | {:.3} | {:.3} | {:.4} | {:.3} | {:.4} | {:.3} | {:.4} | {:.3} |",
                    c.scene,
                    c.size,
                    c.sor_after_10,
                    c.sor_after_40,
                    c.sor_factor_late,
                    c.seconds_per_sweep,
                    c.cycle_after_1,
                    c.cycle_after_4,
                    c.cycle_factor_late,
                    c.seconds_per_cycle,
                    c.hierarchy_seconds
                )
            },
        );
    }
    if !report.cancels.is_empty() {
        md.push_str(
            "\n| size | cancel requested at (s) | stopped after (ms) |\n| --- | --- | --- |\n",
        );
        for c in &report.cancels {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.1} |",
                c.size, c.requested_at_seconds, c.stop_ms
            );
        }
    }
    md.push_str(&issue_50_targets(report));
    for s in &report.skipped {
        let _ = writeln!(md, "\nskipped: {s}");
    }
    md
}

/// One row of issue 50's table that this part measures: the solve at the
/// defaults of `scene` (`None`: any scene) at `size`, its baseline and its
/// targets.
struct Target {
    scene: Option<&'static str>,
    size: &'static str,
    today: &'static str,
    /// At most this many seconds (`None`: at most the issue's fast-marching
    /// time of the same scene and size, `fast_marching_seconds`).
    seconds: Option<f64>,
    fast_marching_seconds: f64,
    /// At most this many bytes per pixel.
    bytes_per_pixel: Option<f64>,
}

/// Issue 50's rows of the single-image solve, each measured next to its
/// target (the bench's bytes per pixel are the solve's growth of the peak,
/// the issue's the whole `solve` process's: docs/speed.md has both).
const ISSUE_50_TARGETS: [Target; 3] = [
    Target {
        scene: Some("sombrero"),
        size: "256x256",
        today: "0.08 s (fast marching 0.05 s)",
        seconds: None,
        fast_marching_seconds: 0.05,
        bytes_per_pixel: None,
    },
    Target {
        scene: None,
        size: "1920x1080",
        today: "1.57 s, 213 B/px",
        seconds: Some(1.0),
        fast_marching_seconds: f64::NAN,
        bytes_per_pixel: Some(120.0),
    },
    Target {
        scene: None,
        size: "5184x3456",
        today: "30.1 s, 135 B/px",
        seconds: Some(15.0),
        fast_marching_seconds: f64::NAN,
        bytes_per_pixel: Some(120.0),
    },
];

/// The issue-50 table: each target row next to the default solves of this
/// run that it concerns ("not run" where none).
fn issue_50_targets(report: &SpeedReport) -> String {
    let mut md = String::from(
        "\nIssue 50's targets (the defaults):\n\n\
         | scene | size | issue's today | target | now | met |\n\
         | --- | --- | --- | --- | --- | --- |\n",
    );
    for target in &ISSUE_50_TARGETS {
        let seconds = target.seconds.unwrap_or(target.fast_marching_seconds);
        let goal = match target.bytes_per_pixel {
            Some(bytes) => format!("≤ {seconds} s, ≤ {bytes} B/px"),
            None => format!("≤ {seconds} s (the issue's fast marching)"),
        };
        let rows: Vec<&SpeedRow> = report
            .rows
            .iter()
            .filter(|r| {
                r.method == "defaults"
                    && r.size == target.size
                    && target.scene.is_none_or(|s| s == r.scene)
            })
            .collect();
        if rows.is_empty() {
            let scene = target.scene.unwrap_or("any");
            let _ = writeln!(
                md,
                "| {scene} | {} | {} | {goal} | not run | – |",
                target.size, target.today
            );
        }
        for row in rows {
            let met = row.seconds <= seconds
                && target
                    .bytes_per_pixel
                    .is_none_or(|bytes| row.bytes_per_pixel <= bytes);
            let _ = writeln!(
                md,
                "| {} | {} | {} | {goal} | {:.3} s, {:.0} B/px | {} |",
                row.scene,
                row.size,
                target.today,
                row.seconds,
                row.bytes_per_pixel,
                if met { "yes" } else { "no" }
            );
        }
    }
    if !report.photographs.is_empty() {
        md.push_str(
            "\nIssue 50's rows of photographs and decisions (from the files, as the command \
             line and the viewer run them):\n\n\
             | what | issue's today | target | now | met |\n\
             | --- | --- | --- | --- | --- |\n",
        );
        for row in &report.photographs {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} |",
                row.what,
                row.today,
                row.target,
                row.now,
                if row.met { "yes" } else { "no" }
            );
        }
    }
    md
}
