//! Running the paper's experiments (`--part paper`, and with `robustness`
//! and `lights` the parts of `all`): renders the scenes, runs every method
//! on them (clean, noisy, with pre- and post-processing, Figs. 2-4), and
//! hands what it measured to `report` and what it drew to `paper_figures`.

use sfs_core::cancel::{Cancel, Uncancelled};
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use super::depth_smoothing;
use super::figures::Figure;
use super::paper_figures;
use super::report::{self, Conditions, Curve, Report, Row, SpeedUp};
use super::scenes::problem;
use super::shared::{
    ALPHA_CLEAN, ALPHA_NOISY, BenchArgs, CurveRecorder, NOISE_SEED, NOISE_SIGMA, POST_WEIGHT, Part,
    TV_ITERATIONS, reset_peak_memory, wanted, wanted_renders,
};
use super::{lights, robustness};
use sfs_core::grid::Grid;
use sfs_core::memory::proc_mib;
use sfs_core::params::SolverParams;
use sfs_core::scene::{self, Scene, mesh, sombrero::sombrero};
use sfs_core::solver::{
    ExplicitParams, FastMarchingParams, Method, Problem, Solution, solve_method,
};

/// A scene with what the bench needs of it.
struct BenchScene {
    name: String,
    scene: Scene,
    noisy: Grid<f64>,
    small: bool,
}

/// One solve to run: an image of a scene, its noise, the method and what
/// comes before and after it.
struct Job<'a> {
    image: &'a Grid<f64>,
    noise: f64,
    method: &'a Method,
    alpha: f64,
    /// Per-pixel confidence (0: inpainted).
    confidence: Option<Grid<f64>>,
    /// TV denoising before the solve.
    pre: bool,
    /// Depth smoothing after it.
    post: bool,
}

impl<'a> Job<'a> {
    /// `method` on `image` with smoothness weight `alpha`, nothing before or
    /// after it.
    fn new(image: &'a Grid<f64>, noise: f64, method: &'a Method, alpha: f64) -> Self {
        Self {
            image,
            noise,
            method,
            alpha,
            confidence: None,
            pre: false,
            post: false,
        }
    }

    /// The method's name in the report: `linearised`, `explicit`,
    /// `fast_marching`, with `+pre` / `+post`.
    fn name(&self) -> String {
        let mut name = self.method.name().to_string();
        if self.pre {
            name.push_str("+pre");
        }
        if self.post {
            name.push_str("+post");
        }
        name
    }
}

/// What a solve gave.
struct Outcome {
    row: Row,
    depth: Grid<f64>,
    reprojection: Grid<f64>,
    curve: Vec<(f64, f64)>,
}

/// Runs the solves: the explicit scheme's budget and whether the peak
/// memory can be reset before each.
struct Runner {
    explicit_seconds: f64,
    peak_reset: bool,
}

impl Runner {
    fn new(args: &BenchArgs) -> Self {
        Self {
            explicit_seconds: args
                .explicit_seconds
                .unwrap_or(if args.quick { 5.0 } else { 150.0 }),
            peak_reset: reset_peak_memory(),
        }
    }

    /// What report.md states about the run besides report.json.
    fn conditions(&self) -> Conditions {
        Conditions {
            explicit_seconds: self.explicit_seconds,
            peak_reset: self.peak_reset,
        }
    }

    /// Runs `job` on `sfs-bench`: its time (pre- and post-processing included,
    /// the RSE recording excluded), peak memory, errors and curve.
    fn run(&self, bench: &BenchScene, job: Job<'_>) -> Result<Outcome> {
        let scene = &bench.scene;
        let name = job.name();
        eprintln!(
            "  {} {}x{} noise {} {name}",
            bench.name,
            scene.image.width(),
            scene.image.height(),
            job.noise
        );
        let (noise, method, alpha, post) = (job.noise, job.method, job.alpha, job.post);
        reset_peak_memory();
        let solved = solve_timed(bench, job, &name)?;
        let peak_mib = proc_mib("/proc/self/status", "VmHWM").unwrap_or(f64::NAN);
        let depth = solved.solution.depth;
        let errors = scene
            .centred_errors(&depth)
            .with_context(|| format!("scoring {} failed", bench.name))?;
        let reprojection = if post {
            reproject(scene, &depth)
        } else {
            solved.solution.reprojection
        };
        Ok(Outcome {
            row: Row {
                scene: bench.name.clone(),
                size: format!("{}x{}", scene.image.width(), scene.image.height()),
                noise,
                method: name,
                alpha: (!matches!(method, Method::FastMarching(_))).then_some(alpha),
                rse: errors.rse,
                rie: errors.rie,
                seconds: solved.seconds,
                peak_mib,
                iterations: solved.solution.iterations,
                budget_exhausted: solved.solution.budget_exhausted,
            },
            depth,
            reprojection,
            curve: solved.curve,
        })
    }

    /// The explicit scheme with a budget: the finest level runs until the
    /// budget is spent (no convergence test there: its energy keeps falling
    /// slowly long after a relative decrease of 1e-6 per check).
    fn explicit(&self, seconds: f64) -> Method {
        Method::Explicit(ExplicitParams {
            max_seconds: Some(seconds),
            snapshot_seconds: Some((seconds / 40.0).max(0.05)),
            finest_tolerance: 0.0,
            ..ExplicitParams::default()
        })
    }
}

/// A solve with its pre- and post-processing, timed.
struct Solved {
    /// The solution, its depth post-processed where asked.
    solution: Solution,
    /// RSE over time.
    curve: Vec<(f64, f64)>,
    /// Wall time, pre- and post-processing included, the RSE recording
    /// excluded.
    seconds: f64,
}

/// Denoises (`job.pre`), solves, smooths the depth (`job.post`) and times
/// it all; `name` is the job's name for messages.
fn solve_timed(bench: &BenchScene, job: Job<'_>, name: &str) -> Result<Solved> {
    let scene = &bench.scene;
    let params = SolverParams::paper(job.alpha);
    let start = Instant::now();
    let input = if job.pre {
        sfs_core::denoise::tv_denoise(
            job.image,
            sfs_core::denoise::default_tv_weight(job.image),
            TV_ITERATIONS,
            Cancel::NEVER,
        )
        .uncancelled()
    } else {
        job.image.clone()
    };
    let problem = Problem {
        confidence: job.confidence,
        ..problem(scene, input)
    };
    let mut recorder = CurveRecorder {
        truth: &scene.depth_gt,
        full_domain: scene.object_mask.clone(),
        points: Vec::new(),
        overhead: Duration::ZERO,
    };
    let mut solution = solve_method(&problem, &params, job.method, &mut recorder)
        .with_context(|| format!("{} with {name} failed", bench.name))?;
    if job.post {
        solution.depth =
            depth_smoothing::smooth_depth(&solution.depth, scene.camera, POST_WEIGHT, &params)
                .with_context(|| format!("post-processing {} failed", bench.name))?;
    }
    let seconds = start
        .elapsed()
        .saturating_sub(recorder.overhead)
        .as_secs_f64();
    Ok(Solved {
        solution,
        curve: recorder.points,
        seconds,
    })
}

/// The image `depth` gives under the scene's light (a post-processed depth
/// has no reprojection of its own).
fn reproject(scene: &Scene, depth: &Grid<f64>) -> Grid<f64> {
    let model = sfs_core::model::Lambertian {
        intensity_scale: scene.intensity_scale,
    };
    let (w, h) = depth.size();
    let geometry = sfs_core::model::LevelGeometry::new(w, h, w, h, scene.camera);
    let domain = depth.map(|z| z.is_finite());
    let filled = depth.map(|z| if z.is_finite() { *z } else { 1.0 });
    sfs_core::model::reproject(&model, &geometry, &domain, &filled, Cancel::NEVER).uncancelled()
}

/// Time after which a curve stays at or below `rse` (linear interpolation at
/// its last crossing), if it ends there. Curves need not fall monotonically
/// (an upsampled coarse level can score better than the next finer one), so
/// the first touch would flatter a scheme that later drifts away.
fn time_to_reach(points: &[(f64, f64)], rse: f64) -> Option<f64> {
    let last = points.last()?;
    if last.1 > rse {
        return None;
    }
    let above = points.iter().rposition(|p| p.1 > rse);
    Some(match above {
        None => points[0].0,
        Some(i) => {
            let ((t0, e0), (t1, e1)) = (points[i], points[i + 1]);
            if (e0 - e1).abs() < 1e-300 {
                t1
            } else {
                t0 + (t1 - t0) * (e0 - rse) / (e0 - e1)
            }
        }
    })
}

/// Power law `rse = a t^b` fitted (least squares in log-log) to the last half
/// of a curve (by time); the time it predicts for `rse`, if the curve still
/// falls (`b < -0.05`) and the prediction lies within 1000 times its span.
fn extrapolate(points: &[(f64, f64)], rse: f64) -> Option<f64> {
    let end = points.last()?.0;
    let tail: Vec<(f64, f64)> = points
        .iter()
        .filter(|(t, e)| *t >= 0.5 * end && *t > 0.0 && *e > 0.0)
        .map(|(t, e)| (t.ln(), e.ln()))
        .collect();
    if tail.len() < 3 {
        return None;
    }
    let n = tail.len() as f64;
    let (sx, sy) = tail
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = tail.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    // A nearly flat tail (slower than t^-0.05) predicts nothing useful.
    if slope > -0.05 {
        return None;
    }
    let intercept = my - slope * mx;
    let t = ((rse.ln() - intercept) / slope).exp();
    // Beyond a thousand times the recorded span it is a guess, not a trend.
    (t.is_finite() && t <= 1000.0 * end).then_some(t)
}

/// Linearised (`lin`) against explicit (`exp`) at equal RSE.
fn speedup(scene: &str, noise: f64, lin: &Outcome, exp: &Outcome) -> SpeedUp {
    // The curves' last points are the final depths (before post-processing).
    let lin_rse = lin.row.rse;
    let exp_rse = exp.row.rse;
    let common = lin_rse.max(exp_rse);
    let lin_t = time_to_reach(&lin.curve, common).unwrap_or(lin.row.seconds);
    let exp_t = time_to_reach(&exp.curve, common).unwrap_or(exp.row.seconds);
    let extrapolated = (exp_rse > lin_rse && exp.row.budget_exhausted)
        .then(|| extrapolate(&exp.curve, lin_rse))
        .flatten();
    let lin_full = time_to_reach(&lin.curve, lin_rse).unwrap_or(lin.row.seconds);
    SpeedUp {
        scene: scene.into(),
        noise,
        linearised_rse: lin_rse,
        explicit_rse: exp_rse,
        common_rse: common,
        linearised_seconds: lin_t,
        explicit_seconds: exp_t,
        ratio: exp_t / lin_t.max(1e-9),
        extrapolated_explicit_seconds: extrapolated,
        extrapolated_ratio: extrapolated.map(|t| t / lin_full.max(1e-9)),
    }
}

/// Loads the scenes `--scenes` asks for (a quarter of the size per side with
/// `--quick`) with their noisy images; the missing ones go to `skipped`.
fn scenes(args: &BenchArgs, skipped: &mut Vec<String>) -> Vec<BenchScene> {
    let divisor = if args.quick { 4 } else { 1 };
    // (name, mesh file, full size, one of the paper's small scenes)
    type Spec<'a> = (&'a str, Option<&'a str>, (usize, usize), bool);
    let specs: [Spec; 5] = [
        ("sombrero", None, (256, 256), true),
        ("bunny", Some("stanford-bunny.obj"), (256, 256), true),
        ("dragon", Some("dragon.obj"), (256, 256), true),
        ("suzanne", Some("suzanne.obj"), (512, 256), true),
        ("highres", Some("dragon.obj"), (1080, 1920), false),
    ];
    let mut out = Vec::new();
    for (name, file, (w, h), small) in specs {
        if !wanted(args, name) {
            continue;
        }
        let (w, h) = (w / divisor, h / divisor);
        let scene = match file {
            None => Ok(sombrero(w, h)),
            Some(file) => {
                let path = args.meshes.join(file);
                mesh::load_obj(&path)
                    .and_then(|m| mesh::render(&m, w, h, &mesh::Placement::default(), name))
                    .map_err(|e| format!("{name}: {} ({e})", path.display()))
            }
        };
        match scene {
            Ok(scene) => {
                let noisy = scene::add_noise(&scene.image, NOISE_SIGMA, NOISE_SEED);
                out.push(BenchScene {
                    name: name.into(),
                    scene,
                    noisy,
                    small,
                });
            }
            Err(e) => {
                eprintln!("skipping {e}");
                skipped.push(e);
            }
        }
    }
    out
}

/// What the paper's experiments have gathered so far.
#[derive(Default)]
struct Gathered {
    rows: Vec<Row>,
    curves: Vec<Curve>,
    speedups: Vec<SpeedUp>,
    /// Figure files written, relative to the output folder.
    figures: Vec<String>,
    skipped: Vec<String>,
}

impl Gathered {
    /// Writes `figure` as `out/name` and lists it.
    fn figure(&mut self, out: &Path, name: &str, figure: &Figure) -> Result<()> {
        figure.save(&out.join(name))?;
        self.figures.push(name.into());
        Ok(())
    }
}

/// The clean image of `sfs-bench`: every method, the speed-up at equal RSE,
/// the RSE-over-time curves and their figure, and Fig. 4 for the
/// high-resolution scene.
fn clean_image(runner: &Runner, bench: &BenchScene, out: &Path, got: &mut Gathered) -> Result<()> {
    let clean = &bench.scene.image;
    let budget = if bench.small {
        runner.explicit_seconds
    } else {
        runner.explicit_seconds / 5.0
    };
    let explicit = runner.explicit(budget);
    let fm = Method::FastMarching(FastMarchingParams::default());
    let lin = runner.run(
        bench,
        Job::new(clean, 0.0, &Method::Linearised, ALPHA_CLEAN),
    )?;
    let exp = runner.run(bench, Job::new(clean, 0.0, &explicit, ALPHA_CLEAN))?;
    let fmm = runner.run(bench, Job::new(clean, 0.0, &fm, ALPHA_CLEAN))?;
    got.speedups.push(speedup(&bench.name, 0.0, &lin, &exp));
    for o in [&lin, &exp] {
        got.curves.push(Curve {
            scene: bench.name.clone(),
            noise: 0.0,
            method: o.row.method.clone(),
            points: o.curve.clone(),
        });
    }
    let plot = paper_figures::rse_time(&bench.name, &lin.curve, &exp.curve)?;
    got.figure(out, &format!("rse_time_{}.png", bench.name), &plot)?;
    if !bench.small {
        let fig4 = paper_figures::fig4(
            &bench.scene,
            [&lin.depth, &lin.reprojection],
            [&fmm.depth, &fmm.reprojection],
        )?;
        got.figure(out, "fig4_highres.png", &fig4)?;
    }
    got.rows.extend([lin.row, exp.row, fmm.row]);
    Ok(())
}

/// The noisy image of `sfs-bench`: every method, the speed-up at equal RSE, then
/// the linearised method and fast marching with pre- and post-processing.
fn noisy_image(runner: &Runner, bench: &BenchScene, got: &mut Gathered) -> Result<()> {
    let noisy = &bench.noisy;
    let explicit = runner.explicit(runner.explicit_seconds);
    let fm = Method::FastMarching(FastMarchingParams::default());
    let job = |method| Job::new(noisy, NOISE_SIGMA, method, ALPHA_NOISY);
    let lin = runner.run(bench, job(&Method::Linearised))?;
    let exp = runner.run(bench, job(&explicit))?;
    got.speedups
        .push(speedup(&bench.name, NOISE_SIGMA, &lin, &exp));
    got.rows.extend([lin.row, exp.row]);
    got.rows.push(runner.run(bench, job(&fm))?.row);
    for method in [&Method::Linearised, &fm] {
        for (pre, post) in [(true, false), (false, true)] {
            let processed = Job {
                pre,
                post,
                ..job(method)
            };
            got.rows.push(runner.run(bench, processed)?.row);
        }
    }
    Ok(())
}

/// Fig. 2: the Bunny (if it was run) for increasing alpha; `(alpha, RSE,
/// RIE)` of each.
fn alpha_sweep(
    runner: &Runner,
    benches: &[BenchScene],
    out: &Path,
    got: &mut Gathered,
) -> Result<Vec<(f64, f64, f64)>> {
    let Some(bunny) = benches.iter().find(|b| b.name == "bunny") else {
        return Ok(Vec::new());
    };
    let image = &bunny.scene.image;
    let mut sweep = Vec::new();
    let mut reprojections = Vec::new();
    for alpha in [1.0, 100.0, 1e4, 1e6] {
        let o = runner.run(bunny, Job::new(image, 0.0, &Method::Linearised, alpha))?;
        sweep.push((alpha, o.row.rse, o.row.rie));
        reprojections.push((alpha, o.reprojection));
    }
    let figure = paper_figures::fig2(image, &reprojections)?;
    got.figure(out, "fig2_bunny_alpha.png", &figure)?;
    Ok(sweep)
}

/// Fig. 3: Suzanne (if it was run) with a large inpainted region; the RSE
/// with the region and without it. The inpainted solve joins the rows.
fn inpainting(
    runner: &Runner,
    benches: &[BenchScene],
    out: &Path,
    got: &mut Gathered,
) -> Result<Option<(f64, f64)>> {
    let Some(suzanne) = benches.iter().find(|b| b.name == "suzanne") else {
        return Ok(None);
    };
    let image = &suzanne.scene.image;
    let (w, h) = image.size();
    let holes = scene::disc_confidence(w, h, 0.5, 0.3, 0.28);
    let job = || Job::new(image, 0.0, &Method::Linearised, ALPHA_CLEAN);
    let full = runner.run(suzanne, job())?;
    let masked = runner.run(
        suzanne,
        Job {
            confidence: Some(holes.clone()),
            ..job()
        },
    )?;
    let figure = paper_figures::fig3(image, &holes, &masked.reprojection, &full.reprojection)?;
    got.figure(out, "fig3_suzanne_inpainting.png", &figure)?;
    let rse = (masked.row.rse, full.row.rse);
    let mut row = masked.row;
    row.method = "linearised (inpainting)".into();
    got.rows.push(row);
    Ok(Some(rse))
}

/// The parts that measure the defaults, as `--part` asks: the robustness
/// table and the lights table.
fn defaults_parts(
    args: &BenchArgs,
    skipped: &mut Vec<String>,
) -> Result<(robustness::Robustness, Vec<lights::LightRow>)> {
    let names: Vec<&str> = wanted_renders(args).collect();
    let robustness = if matches!(args.part, Part::Paper | Part::Lights) {
        robustness::Robustness::default()
    } else {
        robustness::run(&names, &args.meshes, args.quick, skipped)?
    };
    let lights = if matches!(args.part, Part::All | Part::Lights) {
        let side = if args.quick { 48 } else { 256 };
        lights::run(&names, &args.meshes, side, skipped)?
    } else {
        Vec::new()
    };
    Ok((robustness, lights))
}

/// Runs every part but `speed` as `args.part` asks and writes report.json,
/// report.md and the figures into `args.out`.
pub(super) fn run(args: &BenchArgs, started: Instant) -> Result<()> {
    let runner = Runner::new(args);
    let mut got = Gathered::default();
    let benches = if matches!(args.part, Part::Robustness | Part::Lights) {
        Vec::new()
    } else {
        scenes(args, &mut got.skipped)
    };
    for bench in &benches {
        eprintln!("{}:", bench.name);
        clean_image(&runner, bench, &args.out, &mut got)?;
        if bench.small {
            noisy_image(&runner, bench, &mut got)?;
        }
    }
    let alpha_sweep = alpha_sweep(&runner, &benches, &args.out, &mut got)?;
    let inpainting = inpainting(&runner, &benches, &args.out, &mut got)?;
    let (robustness, lights) = defaults_parts(args, &mut got.skipped)?;
    let like_for_like = if matches!(args.part, Part::All | Part::Paper) {
        let names: Vec<&str> = wanted_renders(args).collect();
        super::like_for_like::run(&names, &args.meshes, args.quick, &mut got.skipped)?
    } else {
        Vec::new()
    };
    let report = Report {
        command: super::shared::command_line(),
        quick: args.quick,
        machine: report::machine(),
        rows: got.rows,
        curves: got.curves,
        speedups: got.speedups,
        alpha_sweep,
        inpainting,
        figures: got.figures,
        robustness,
        lights,
        like_for_like,
        skipped: got.skipped,
        total_seconds: started.elapsed().as_secs_f64(),
    };
    report::write(&args.out, &report, &runner.conditions())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_to_reach_interpolates_and_extrapolation_follows_a_power_law() {
        let curve = [(1.0, 0.1), (2.0, 0.05), (4.0, 0.02)];
        assert_eq!(time_to_reach(&curve, 0.2), Some(1.0));
        let t = time_to_reach(&curve, 0.03).expect("reached");
        assert!((t - (2.0 + 2.0 * 2.0 / 3.0)).abs() < 1e-12);
        assert_eq!(time_to_reach(&curve, 0.01), None);
        // A curve that dips early and comes back counts from its last crossing.
        let dipping = [(1.0, 0.02), (2.0, 0.08), (4.0, 0.03)];
        assert_eq!(time_to_reach(&dipping, 0.05), Some(2.0 + 2.0 * 0.6));
        assert_eq!(time_to_reach(&dipping, 0.025), None);
        // rse = 0.1 / t: reaching 0.001 takes t = 100.
        let law: Vec<(f64, f64)> = (1..=20).map(|i| (i as f64, 0.1 / i as f64)).collect();
        let t = extrapolate(&law, 0.001).expect("decreasing");
        assert!((t - 100.0).abs() < 1e-6, "{t}");
        let flat: Vec<(f64, f64)> = (1..=20).map(|i| (i as f64, 0.1)).collect();
        assert_eq!(extrapolate(&flat, 0.001), None);
    }

    #[test]
    fn job_names_carry_pre_and_post() {
        let image = Grid::from_fn(2, 2, |_, _| 0.5);
        let job = Job::new(&image, 0.0, &Method::Linearised, ALPHA_CLEAN);
        assert_eq!(job.name(), "linearised");
        let fm = Method::FastMarching(FastMarchingParams::default());
        let job = Job {
            pre: true,
            post: true,
            ..Job::new(&image, NOISE_SIGMA, &fm, ALPHA_NOISY)
        };
        assert_eq!(job.name(), "fast_marching+pre+post");
    }
}
