//! `sfs-studio bench`: the paper's experiments side by side in one run. It
//! renders the scenes, runs every method on them (clean, noisy, with pre- and
//! post-processing), and writes `report.md`, `report.json` and the figures.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;

use super::figures::{self, Canvas, Series, Shade};

mod lights;
mod robustness;
mod speed;
use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::depth_smoothing;
use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{self, Scene, mesh, sombrero::sombrero};
use sfs_core::solver::{
    ExplicitParams, FastMarchingParams, LevelResult, Method, Problem, Solution, SolveObserver,
    pyramid, solve_method,
};

/// Arguments of `bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Folder with stanford-bunny.obj, dragon.obj and suzanne.obj; mesh
    /// scenes whose file is missing are skipped (and listed in the report).
    #[arg(long, default_value = "../shared/meshes", value_parser = super::parse_path)]
    pub meshes: PathBuf,
    /// A few minutes in all: every scene at a quarter of its size per side,
    /// a 5 s budget for the explicit scheme.
    #[arg(long)]
    pub quick: bool,
    /// Only these scenes (comma separated): sombrero, bunny, dragon,
    /// suzanne, highres.
    #[arg(long, value_delimiter = ',')]
    pub scenes: Option<Vec<String>>,
    /// Time budget of the explicit scheme per solve, in seconds (default 150,
    /// quick 5); the high-resolution scene gets a fifth of it.
    #[arg(long, value_name = "SECONDS")]
    pub explicit_seconds: Option<f64>,
    /// Which part to run: `paper` (the paper's tables and figures in its own
    /// units), `robustness` (the defaults over scenes, sizes, noise and
    /// exposure), `lights`, `all` (these four) or `speed` (time, memory and
    /// RSE over time at 256x256 and 1920x1080, with fast marching and the
    /// paper's schedule; writes speed.md and speed.json).
    #[arg(long, value_enum, default_value = "all")]
    pub part: Part,
    /// With `--part speed`: also an 18-megapixel (5184x3456) scene.
    #[arg(long)]
    pub large: bool,
    /// Output folder (created if needed).
    #[arg(long, value_parser = super::parse_path)]
    pub out: PathBuf,
}

/// `bench --part`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Part {
    /// Everything.
    All,
    /// The paper's experiments.
    Paper,
    /// The robustness table of the defaults.
    Robustness,
    /// Lights beside the lens: the light model against ignoring the light.
    Lights,
    /// Time, memory, RSE over time and responsiveness at several sizes.
    Speed,
}

/// Smoothness weight of the variational methods on clean images (pixel units).
const ALPHA_CLEAN: f64 = 100.0;
/// On noisy images (sigma 20).
const ALPHA_NOISY: f64 = 2000.0;
/// Noise of the noisy images, on the 0..255 scale, and its seed.
const NOISE_SIGMA: f64 = 20.0;
const NOISE_SEED: u64 = 1;
/// Weight of the depth post-processing (depth units squared, pixel units).
const POST_WEIGHT: f64 = 100.0;
/// Primal-dual iterations of the TV pre-processing.
const TV_ITERATIONS: usize = 200;

/// The paper's figures for one scene (Tables 1-3; NaN: not reported).
struct Paper {
    /// `[Vogel, Ju, ours]` RSE and RIE on clean images.
    clean_rse: [f64; 3],
    clean_rie: [f64; 3],
    /// The same on noisy images.
    noisy_rse: [f64; 3],
    noisy_rie: [f64; 3],
    /// Table 2: `[Vogel pre, Vogel post, ours pre, ours post]`.
    processed_rse: [f64; 4],
    /// Table 3 runtimes, seconds: `[Vogel, Ju, ours]`.
    seconds: [f64; 3],
}

fn paper(scene: &str) -> Option<Paper> {
    let p = match scene {
        "sombrero" => Paper {
            clean_rse: [0.00301, 0.00318, 0.00768],
            clean_rie: [0.00495, 0.00209, 0.00925],
            noisy_rse: [0.19530, 0.05118, 0.01542],
            noisy_rie: [0.27254, 0.13239, 0.03851],
            processed_rse: [0.02008, 0.19197, 0.01741, 0.01538],
            seconds: [1.0, 29113.0, 17.0],
        },
        "bunny" => Paper {
            clean_rse: [0.00266, 0.00439, 0.00928],
            clean_rie: [0.00154, 0.00007, 0.00327],
            noisy_rse: [0.10973, 0.03235, 0.01359],
            noisy_rie: [0.17347, 0.15279, 0.12285],
            processed_rse: [0.01434, 0.06164, 0.01470, 0.01357],
            seconds: [1.0, 23969.0, 11.0],
        },
        "dragon" => Paper {
            clean_rse: [0.00422, 0.01376, 0.02904],
            clean_rie: [0.00255, 0.00028, 0.02333],
            noisy_rse: [0.12240, 0.05395, 0.03391],
            noisy_rie: [0.19409, 0.18767, 0.17732],
            processed_rse: [0.04623, 0.08226, 0.03322, 0.03390],
            seconds: [1.0, 25350.0, 12.0],
        },
        "suzanne" => Paper {
            clean_rse: [0.00253, 0.00251, 0.00696],
            clean_rie: [0.00082, 0.00002, 0.00224],
            noisy_rse: [0.12134, 0.01256, 0.00826],
            noisy_rie: [0.16783, 0.14302, 0.12038],
            processed_rse: [0.01245, 0.06169, 0.00917, 0.00824],
            seconds: [2.0, 48395.0, 21.0],
        },
        "highres" => Paper {
            clean_rse: [0.01593, f64::NAN, 0.02930],
            clean_rie: [0.00067, f64::NAN, 0.03414],
            noisy_rse: [f64::NAN; 3],
            noisy_rie: [f64::NAN; 3],
            processed_rse: [f64::NAN; 4],
            seconds: [33.0, f64::NAN, 340.0],
        },
        _ => return None,
    };
    Some(p)
}

/// One solve of the report.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Scene name.
    pub scene: String,
    /// Image size `WxH`.
    pub size: String,
    /// Noise sigma on the 0..255 scale (0: clean).
    pub noise: f64,
    /// `linearised`, `explicit`, `fast_marching`, with `+pre` / `+post`.
    pub method: String,
    /// Smoothness weight (pixel units); `null` for fast marching.
    pub alpha: Option<f64>,
    /// Relative surface error.
    pub rse: f64,
    /// Relative image error against the clean image.
    pub rie: f64,
    /// Wall time of the method including pre/post-processing.
    pub seconds: f64,
    /// Peak resident memory of the process during the solve, MiB.
    pub peak_mib: f64,
    /// Iterations (outer, gradient steps or 1).
    pub iterations: usize,
    /// Whether a budget stopped the method.
    pub budget_exhausted: bool,
}

/// RSE over time of one solve.
#[derive(Clone, Debug, Serialize)]
pub struct Curve {
    /// Scene name.
    pub scene: String,
    /// Noise sigma.
    pub noise: f64,
    /// Method name.
    pub method: String,
    /// `(seconds, rse)`, the solve's own time (recording excluded).
    pub points: Vec<(f64, f64)>,
}

/// Linearised against explicit at equal RSE.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedUp {
    /// Scene name.
    pub scene: String,
    /// Noise sigma.
    pub noise: f64,
    /// Final RSE of each.
    pub linearised_rse: f64,
    /// Final RSE of the explicit scheme within its budget.
    pub explicit_rse: f64,
    /// The RSE both reached (the larger final RSE).
    pub common_rse: f64,
    /// Seconds each needed to reach it for good (last crossing).
    pub linearised_seconds: f64,
    /// Seconds the explicit scheme needed to reach it.
    pub explicit_seconds: f64,
    /// `explicit_seconds / linearised_seconds`.
    pub ratio: f64,
    /// When the explicit scheme did not reach the linearised RSE within its
    /// budget: the time a power law fitted to the last half of its curve
    /// predicts for it (an extrapolation, not a measurement).
    pub extrapolated_explicit_seconds: Option<f64>,
    /// That time over the linearised time.
    pub extrapolated_ratio: Option<f64>,
}

/// The machine the report was made on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Logical cores available.
    pub cores: usize,
    /// CPU model from /proc/cpuinfo.
    pub cpu: String,
    /// Total memory, MiB.
    pub memory_mib: f64,
}

/// `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The command line that made it.
    pub command: String,
    /// Quick mode.
    pub quick: bool,
    /// The machine.
    pub machine: Machine,
    /// Every solve.
    pub rows: Vec<Row>,
    /// RSE over time of the variational methods.
    pub curves: Vec<Curve>,
    /// Linearised against explicit at equal RSE.
    pub speedups: Vec<SpeedUp>,
    /// Fig. 2: `(alpha, rse, rie)` of the Bunny.
    pub alpha_sweep: Vec<(f64, f64, f64)>,
    /// Fig. 3: RSE with and without the inpainted region.
    pub inpainting: Option<(f64, f64)>,
    /// Figure files, relative to the report.
    pub figures: Vec<String>,
    /// The defaults over scenes, sizes, noise and exposure.
    pub robustness: robustness::Robustness,
    /// Lights beside the lens.
    pub lights: Vec<lights::LightRow>,
    /// Scenes that could not be run, and why.
    pub skipped: Vec<String>,
    /// Wall time of the whole benchmark.
    pub total_seconds: f64,
}

/// A scene with what the bench needs of it.
struct BenchScene {
    name: String,
    scene: Scene,
    noisy: Grid<f64>,
    small: bool,
}

/// Records RSE whenever a level (or a snapshot) arrives.
struct CurveRecorder<'a> {
    truth: &'a Grid<f64>,
    full_domain: Grid<bool>,
    points: Vec<(f64, f64)>,
    overhead: Duration,
}

impl SolveObserver for CurveRecorder<'_> {
    fn on_level(&mut self, result: &LevelResult) {
        let started = Instant::now();
        let level_domain = result.depth.map(|z| z.is_finite());
        let full = pyramid::upsample_depth(&result.depth, &level_domain, &self.full_domain);
        let full = sfs_core::solver::problem::masked(&full, &self.full_domain, Cancel::NEVER)
            .uncancelled();
        if let Ok(rse) = metrics::rse(&full, self.truth) {
            let t = result.elapsed.saturating_sub(self.overhead).as_secs_f64();
            self.points.push((t, rse));
        }
        self.overhead += started.elapsed();
    }
}

/// Resets the process's peak resident set (Linux `clear_refs` 5); false
/// where that is not possible.
fn reset_peak_memory() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The value of a `key: N kB` line of a /proc file, in MiB (NaN if absent).
fn proc_mib(file: &str, key: &str) -> f64 {
    std::fs::read_to_string(file)
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn machine() -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map_or_else(|| "unknown".to_string(), |(_, v)| v.trim().to_string());
    let memory_mib = proc_mib("/proc/meminfo", "MemTotal:");
    Machine {
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        cpu,
        memory_mib,
    }
}

/// What a solve gave.
struct Outcome {
    row: Row,
    depth: Grid<f64>,
    reprojection: Grid<f64>,
    curve: Vec<(f64, f64)>,
}

struct Runner {
    explicit_seconds: f64,
    peak_reset: bool,
}

impl Runner {
    /// Runs `method` on `image` of `bench` with optional pre/post-processing.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        bench: &BenchScene,
        image: &Grid<f64>,
        noise: f64,
        method: &Method,
        alpha: f64,
        confidence: Option<Grid<f64>>,
        pre: bool,
        post: bool,
    ) -> Result<Outcome> {
        let scene = &bench.scene;
        let params = SolverParams::paper(alpha);
        let mut name = method.name().to_string();
        if pre {
            name.push_str("+pre");
        }
        if post {
            name.push_str("+post");
        }
        eprintln!(
            "  {} {}x{} noise {noise} {name}",
            bench.name,
            scene.image.width(),
            scene.image.height()
        );
        reset_peak_memory();
        let start = Instant::now();
        let input = if pre {
            sfs_core::denoise::tv_denoise(
                image,
                sfs_core::denoise::default_tv_weight(image),
                TV_ITERATIONS,
                Cancel::NEVER,
            )
            .uncancelled()
        } else {
            image.clone()
        };
        let problem = Problem {
            image: input,
            camera: scene.camera,
            intensity_scale: scene.intensity_scale,
            object_mask: Some(scene.object_mask.clone()),
            confidence,
            lights: Vec::new(),
        };
        let mut recorder = CurveRecorder {
            truth: &scene.depth_gt,
            full_domain: scene.object_mask.clone(),
            points: Vec::new(),
            overhead: Duration::ZERO,
        };
        let solution: Solution = solve_method(&problem, &params, method, &mut recorder)
            .with_context(|| format!("{} with {name} failed", bench.name))?;
        let mut depth = solution.depth;
        if post {
            depth = depth_smoothing::smooth_depth(&depth, scene.camera, POST_WEIGHT, &params)
                .with_context(|| format!("post-processing {} failed", bench.name))?;
        }
        let seconds = start
            .elapsed()
            .saturating_sub(recorder.overhead)
            .as_secs_f64();
        let peak_mib = proc_mib("/proc/self/status", "VmHWM:");
        let errors = metrics::errors(
            &depth,
            &scene.depth_gt,
            &scene.image,
            scene.camera,
            scene.intensity_scale,
        )
        .with_context(|| format!("scoring {} failed", bench.name))?;
        let reprojection = if post {
            let model = sfs_core::model::Lambertian {
                intensity_scale: scene.intensity_scale,
            };
            let (w, h) = depth.size();
            let geometry = sfs_core::model::LevelGeometry::new(w, h, w, h, scene.camera);
            let domain = depth.map(|z| z.is_finite());
            let filled = depth.map(|z| if z.is_finite() { *z } else { 1.0 });
            sfs_core::model::reproject(&model, &geometry, &domain, &filled, Cancel::NEVER)
                .uncancelled()
        } else {
            solution.reprojection
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
                seconds,
                peak_mib,
                iterations: solution.iterations,
                budget_exhausted: solution.budget_exhausted,
            },
            depth,
            reprojection,
            curve: recorder.points,
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

/// Every scene `--scenes` can name.
const SCENE_NAMES: &[&str] = &["sombrero", "bunny", "dragon", "suzanne", "highres"];

/// Loads the scenes asked for; the missing ones go to `skipped`.
/// Whether `--scenes` asks for `name` (no `--scenes`: every scene).
fn wanted(args: &BenchArgs, name: &str) -> bool {
    args.scenes
        .as_ref()
        .is_none_or(|list| list.iter().any(|s| s.eq_ignore_ascii_case(name)))
}

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

/// Runs the benchmark and writes the report.
pub fn run(args: &BenchArgs) -> Result<()> {
    let started = Instant::now();
    if let Some(s) = args.explicit_seconds
        && !(s.is_finite() && s > 0.0)
    {
        anyhow::bail!("--explicit-seconds must be a positive number of seconds (got {s})");
    }
    if let Some(list) = &args.scenes {
        let unknown: Vec<&String> = list
            .iter()
            .filter(|s| !SCENE_NAMES.iter().any(|n| n.eq_ignore_ascii_case(s)))
            .collect();
        if !unknown.is_empty() || list.is_empty() {
            anyhow::bail!(
                "invalid --scenes {}: the scenes are {}",
                list.join(","),
                SCENE_NAMES.join(", ")
            );
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create output folder {}", args.out.display()))?;
    if args.part == Part::Speed {
        speed::run(args, args.large)?;
        eprintln!(
            "wrote {} ({:.0} s)",
            args.out.join("speed.md").display(),
            started.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let runner = Runner {
        explicit_seconds: args
            .explicit_seconds
            .unwrap_or(if args.quick { 5.0 } else { 150.0 }),
        peak_reset: reset_peak_memory(),
    };
    let mut skipped = Vec::new();
    let benches = if matches!(args.part, Part::Robustness | Part::Lights) {
        Vec::new()
    } else {
        scenes(args, &mut skipped)
    };
    let mut rows = Vec::new();
    let mut curves = Vec::new();
    let mut speedups = Vec::new();
    let mut figures_written = Vec::new();
    let fm = Method::FastMarching(FastMarchingParams::default());

    for bench in &benches {
        eprintln!("{}:", bench.name);
        let clean = &bench.scene.image;
        let budget = if bench.small {
            runner.explicit_seconds
        } else {
            runner.explicit_seconds / 5.0
        };
        // Clean image: every method.
        let lin = runner.run(
            bench,
            clean,
            0.0,
            &Method::Linearised,
            ALPHA_CLEAN,
            None,
            false,
            false,
        )?;
        let exp = runner.run(
            bench,
            clean,
            0.0,
            &runner.explicit(budget),
            ALPHA_CLEAN,
            None,
            false,
            false,
        )?;
        let fmm = runner.run(bench, clean, 0.0, &fm, ALPHA_CLEAN, None, false, false)?;
        speedups.push(speedup(&bench.name, 0.0, &lin, &exp));
        for o in [&lin, &exp] {
            curves.push(Curve {
                scene: bench.name.clone(),
                noise: 0.0,
                method: o.row.method.clone(),
                points: o.curve.clone(),
            });
        }
        let plot = format!("rse_time_{}.png", bench.name);
        rse_time_plot(&lin.curve, &exp.curve).save(&args.out.join(&plot))?;
        figures_written.push(plot);
        if !bench.small {
            let name = "fig4_highres.png";
            fig4(bench, &lin, &fmm).save(&args.out.join(name))?;
            figures_written.push(name.into());
        }
        rows.extend([lin.row, exp.row, fmm.row]);
        if !bench.small {
            continue;
        }
        // Noisy image: every method, then with pre- and post-processing.
        let noisy = &bench.noisy;
        let lin = runner.run(
            bench,
            noisy,
            NOISE_SIGMA,
            &Method::Linearised,
            ALPHA_NOISY,
            None,
            false,
            false,
        )?;
        let exp = runner.run(
            bench,
            noisy,
            NOISE_SIGMA,
            &runner.explicit(budget),
            ALPHA_NOISY,
            None,
            false,
            false,
        )?;
        speedups.push(speedup(&bench.name, NOISE_SIGMA, &lin, &exp));
        rows.extend([lin.row, exp.row]);
        rows.push(
            runner
                .run(
                    bench,
                    noisy,
                    NOISE_SIGMA,
                    &fm,
                    ALPHA_NOISY,
                    None,
                    false,
                    false,
                )?
                .row,
        );
        for method in [&Method::Linearised, &fm] {
            for (pre, post) in [(true, false), (false, true)] {
                rows.push(
                    runner
                        .run(
                            bench,
                            noisy,
                            NOISE_SIGMA,
                            method,
                            ALPHA_NOISY,
                            None,
                            pre,
                            post,
                        )?
                        .row,
                );
            }
        }
    }

    // Fig. 2: the Bunny for increasing alpha.
    let mut alpha_sweep = Vec::new();
    if let Some(bunny) = benches.iter().find(|b| b.name == "bunny") {
        let mut panels = vec![bunny.scene.image.clone()];
        for alpha in [1.0, 100.0, 1e4, 1e6] {
            let o = runner.run(
                bunny,
                &bunny.scene.image,
                0.0,
                &Method::Linearised,
                alpha,
                None,
                false,
                false,
            )?;
            alpha_sweep.push((alpha, o.row.rse, o.row.rie));
            panels.push(o.reprojection);
        }
        let row: Vec<(&Grid<f64>, Shade)> = panels
            .iter()
            .map(|g| (g, Shade::Grey([0.0, 1.0])))
            .collect();
        let name = "fig2_bunny_alpha.png";
        figures::panel_grid(&[row], 1).save(&args.out.join(name))?;
        figures_written.push(name.into());
    }

    // Fig. 3: Suzanne with a large inpainted region.
    let mut inpainting = None;
    if let Some(suzanne) = benches.iter().find(|b| b.name == "suzanne") {
        let (w, h) = suzanne.scene.image.size();
        let holes = scene::disc_confidence(w, h, 0.5, 0.3, 0.28);
        let full = runner.run(
            suzanne,
            &suzanne.scene.image,
            0.0,
            &Method::Linearised,
            ALPHA_CLEAN,
            None,
            false,
            false,
        )?;
        let masked = runner.run(
            suzanne,
            &suzanne.scene.image,
            0.0,
            &Method::Linearised,
            ALPHA_CLEAN,
            Some(holes.clone()),
            false,
            false,
        )?;
        inpainting = Some((masked.row.rse, full.row.rse));
        let degraded = Grid::from_fn(w, h, |c, r| {
            if *holes.at(c, r) == 0.0 {
                f64::NAN
            } else {
                *suzanne.scene.image.at(c, r)
            }
        });
        let name = "fig3_suzanne_inpainting.png";
        figures::panel_grid(
            &[vec![
                (&degraded, Shade::Grey([0.0, 1.0])),
                (&masked.reprojection, Shade::Grey([0.0, 1.0])),
                (&full.reprojection, Shade::Grey([0.0, 1.0])),
            ]],
            1,
        )
        .save(&args.out.join(name))?;
        figures_written.push(name.into());
        let mut row = masked.row;
        row.method = "linearised (inpainting)".into();
        rows.push(row);
    }

    let names: Vec<&str> = ["sombrero", "bunny", "dragon", "suzanne"]
        .into_iter()
        .filter(|name| wanted(args, name))
        .collect();
    let robustness = if matches!(args.part, Part::Paper | Part::Lights) {
        robustness::Robustness::default()
    } else {
        robustness::run(&names, &args.meshes, args.quick, &mut skipped)?
    };
    let lights = if matches!(args.part, Part::All | Part::Lights) {
        let side = if args.quick { 48 } else { 256 };
        lights::run(&names, &args.meshes, side, &mut skipped)?
    } else {
        Vec::new()
    };

    let report = Report {
        command: std::env::args().collect::<Vec<_>>().join(" "),
        quick: args.quick,
        machine: machine(),
        rows,
        curves,
        speedups,
        alpha_sweep,
        inpainting,
        figures: figures_written,
        robustness,
        lights,
        skipped,
        total_seconds: started.elapsed().as_secs_f64(),
    };
    sfs_core::io::write_json(&args.out.join("report.json"), &report)
        .with_context(|| format!("cannot write {}", args.out.join("report.json").display()))?;
    let markdown = markdown(&report, &runner);
    std::fs::write(args.out.join("report.md"), markdown)
        .with_context(|| format!("cannot write {}", args.out.join("report.md").display()))?;
    eprintln!(
        "wrote {} ({:.0} s)",
        args.out.join("report.md").display(),
        report.total_seconds
    );
    Ok(())
}

/// RSE over time: linearised blue, explicit red.
fn rse_time_plot(lin: &[(f64, f64)], exp: &[(f64, f64)]) -> Canvas {
    let all = || lin.iter().chain(exp);
    let x = figures::decades(all().map(|p| p.0));
    let y = figures::decades(all().map(|p| p.1));
    figures::log_log_plot(
        &[
            Series {
                colour: [31, 90, 200],
                label: "linearised",
                points: lin,
            },
            Series {
                colour: [210, 40, 40],
                label: "explicit",
                points: exp,
            },
        ],
        x,
        y,
        "seconds",
        "RSE",
    )
}

/// Fig. 4: reprojection and depth of the high-resolution scene: ground truth,
/// linearised and its difference, fast marching and its difference.
fn fig4(bench: &BenchScene, lin: &Outcome, fmm: &Outcome) -> Canvas {
    let scene = &bench.scene;
    let diff = |a: &Grid<f64>, b: &Grid<f64>| {
        Grid::from_fn(a.width(), a.height(), |c, r| {
            (a.at(c, r) - b.at(c, r)).abs()
        })
    };
    let gt_depth = &scene.depth_gt;
    let depth_range = figures::range_of([gt_depth]);
    let (dl, df) = (diff(&lin.depth, gt_depth), diff(&fmm.depth, gt_depth));
    let (il, ifm) = (
        diff(&lin.reprojection, &scene.image),
        diff(&fmm.reprojection, &scene.image),
    );
    let depth_err = [
        0.0,
        0.05 * (depth_range[1] - depth_range[0]).max(1e-9) * 4.0,
    ];
    let image_err = [0.0, 0.1];
    let step = (scene.image.width() / 270).max(1);
    figures::panel_grid(
        &[
            vec![
                (&scene.image, Shade::Grey([0.0, 1.0])),
                (&lin.reprojection, Shade::Grey([0.0, 1.0])),
                (&il, Shade::Colour(image_err)),
                (&fmm.reprojection, Shade::Grey([0.0, 1.0])),
                (&ifm, Shade::Colour(image_err)),
            ],
            vec![
                (gt_depth, Shade::Colour(depth_range)),
                (&lin.depth, Shade::Colour(depth_range)),
                (&dl, Shade::Colour(depth_err)),
                (&fmm.depth, Shade::Colour(depth_range)),
                (&df, Shade::Colour(depth_err)),
            ],
        ],
        step,
    )
}

fn fmt(v: f64) -> String {
    if v.is_nan() {
        "–".into()
    } else {
        format!("{v:.5}")
    }
}

fn find<'a>(rows: &'a [Row], scene: &str, noise: f64, method: &str) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.scene == scene && r.noise == noise && r.method == method)
}

/// report.md.
fn markdown(report: &Report, runner: &Runner) -> String {
    let mut md = String::new();
    let m = &report.machine;
    let _ = writeln!(
        md,
        "# sfs-studio benchmark: the paper's experiments side by side\n"
    );
    let _ = writeln!(
        md,
        "Command: `{}`{}  ",
        report.command,
        if report.quick {
            " (quick: quarter-size scenes)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        md,
        "Machine: {} cores, {}, {:.0} MiB memory. Total time {:.0} s.\n",
        m.cores, m.cpu, m.memory_mib, report.total_seconds
    );
    let _ = writeln!(
        md,
        "Parameters of Tables 1-3 and Figs. 2-4: the paper's (paper units, eta 0.9, kappa 5, l_max 9, 10 SOR sweeps, dz_limit 0.01, lambda 1e-3, \
         a constant initial depth from the image, the whole pyramid) with this project's step control; \
         alpha {ALPHA_CLEAN} on clean and {ALPHA_NOISY} on noisy images (pixel units, the same for every scene and for both variational methods). \
         The last section measures the defaults instead. \
         Noise: Gaussian sigma {NOISE_SIGMA} of 255, seed {NOISE_SEED}, quantised to 8 bits. RIE is measured against the clean image. \
         The explicit scheme has a budget of {:.0} s per solve ({:.0} s on the high-resolution scene). \
         The paper's numbers come from its own renders: they compare in kind, not to the digit.\n",
        runner.explicit_seconds,
        runner.explicit_seconds / 5.0
    );
    if !report.skipped.is_empty() {
        let _ = writeln!(md, "Skipped: {}.\n", report.skipped.join("; "));
    }
    let scenes: Vec<String> = {
        let mut s: Vec<String> = Vec::new();
        for r in &report.rows {
            if !s.contains(&r.scene) {
                s.push(r.scene.clone());
            }
        }
        s
    };
    let methods = [
        ("linearised", 2usize),
        ("explicit", 1),
        ("fast_marching", 0),
    ];

    let _ = writeln!(md, "## Table 1: RSE and RIE, clean and noisy\n");
    let _ = writeln!(
        md,
        "| scene | noise | method | RSE | RIE | paper RSE | paper RIE |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- | --- | --- |");
    for scene in &scenes {
        let p = paper(scene);
        for noise in [0.0, NOISE_SIGMA] {
            for (method, k) in methods {
                if let Some(r) = find(&report.rows, scene, noise, method) {
                    let (pr, pi) = p.as_ref().map_or((f64::NAN, f64::NAN), |p| {
                        if noise == 0.0 {
                            (p.clean_rse[k], p.clean_rie[k])
                        } else {
                            (p.noisy_rse[k], p.noisy_rie[k])
                        }
                    });
                    let budget = if r.budget_exhausted { " (budget)" } else { "" };
                    let _ = writeln!(
                        md,
                        "| {scene} {} | {noise} | {method}{budget} | {} | {} | {} | {} |",
                        r.size,
                        fmt(r.rse),
                        fmt(r.rie),
                        fmt(pr),
                        fmt(pi)
                    );
                }
            }
        }
    }

    let _ = writeln!(
        md,
        "\n## Table 2: noisy images with pre-processing (TV denoising) and post-processing (depth smoothing)\n"
    );
    let _ = writeln!(
        md,
        "Pre: ROF/TV denoising, weight = the image's estimated noise level (Immerkaer), {TV_ITERATIONS} primal-dual iterations. \
         Post: the depth smoothed with the energy's second-order Charbonnier term, weight {POST_WEIGHT}.\n"
    );
    let _ = writeln!(
        md,
        "| scene | method | RSE | +pre | +post | paper RSE | paper +pre | paper +post |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- | --- | --- | --- |");
    for scene in &scenes {
        let p = paper(scene);
        for (method, k) in [("linearised", 1usize), ("fast_marching", 0)] {
            let get = |suffix: &str| {
                find(
                    &report.rows,
                    scene,
                    NOISE_SIGMA,
                    &format!("{method}{suffix}"),
                )
                .map_or(f64::NAN, |r| r.rse)
            };
            if get("").is_nan() {
                continue;
            }
            let (po, pp, pq) = p.as_ref().map_or((f64::NAN, f64::NAN, f64::NAN), |p| {
                (
                    p.noisy_rse[if k == 1 { 2 } else { 0 }],
                    p.processed_rse[2 * k],
                    p.processed_rse[2 * k + 1],
                )
            });
            let _ = writeln!(
                md,
                "| {scene} | {method} | {} | {} | {} | {} | {} | {} |",
                fmt(get("")),
                fmt(get("+pre")),
                fmt(get("+post")),
                fmt(po),
                fmt(pp),
                fmt(pq)
            );
        }
    }

    let _ = writeln!(md, "\n## Table 3: runtimes in this run (clean images)\n");
    let _ = writeln!(
        md,
        "| scene | linearised s | explicit s | fast marching s | explicit / linearised | linearised / fast marching | paper: ours, Ju, Vogel s |"
    );
    let _ = writeln!(md, "| --- | --- | --- | --- | --- | --- | --- |");
    for scene in &scenes {
        let get = |method: &str| find(&report.rows, scene, 0.0, method);
        let (Some(l), Some(e), Some(f)) =
            (get("linearised"), get("explicit"), get("fast_marching"))
        else {
            continue;
        };
        let p = paper(scene).map_or([f64::NAN; 3], |p| p.seconds);
        let cut = if e.budget_exhausted {
            " (budget spent)"
        } else {
            ""
        };
        let _ = writeln!(
            md,
            "| {scene} {} | {:.2} | {:.1}{cut} | {:.2} | {:.0}x | {:.1}x | {}, {}, {} |",
            l.size,
            l.seconds,
            e.seconds,
            f.seconds,
            e.seconds / l.seconds.max(1e-9),
            l.seconds / f.seconds.max(1e-9),
            p[2],
            if p[1].is_nan() {
                "infeasible".into()
            } else {
                format!("{}", p[1])
            },
            p[0]
        );
    }

    let _ = writeln!(md, "\n### Linearised against explicit at equal RSE\n");
    let _ = writeln!(
        md,
        "Both schemes minimise the same energy from the same start. \"common RSE\" is the larger of the two final RSEs, which both reached; \
         the times are when each reached it for good (the last crossing of its RSE-over-time curve; recording excluded). Where the explicit scheme ran out of budget above the linearised RSE, \
         a power law fitted to the last half of its RSE-over-time curve gives an **extrapolated** time to the linearised RSE.\n"
    );
    let _ = writeln!(
        md,
        "| scene | noise | linearised RSE | explicit RSE | common RSE | linearised s | explicit s | speed-up (measured) | explicit s to linearised RSE (extrapolated) | speed-up (extrapolated) |"
    );
    let _ = writeln!(
        md,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for s in &report.speedups {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.2} | {:.1} | {:.0}x | {} | {} |",
            s.scene,
            s.noise,
            fmt(s.linearised_rse),
            fmt(s.explicit_rse),
            fmt(s.common_rse),
            s.linearised_seconds,
            s.explicit_seconds,
            s.ratio,
            s.extrapolated_explicit_seconds
                .map_or("–".into(), |t| format!("{t:.0}")),
            s.extrapolated_ratio
                .map_or("–".into(), |r| format!("{r:.0}x"))
        );
    }
    let _ = writeln!(
        md,
        "\nRSE over time (log-log; blue linearised, red explicit; every point a level or a snapshot):\n"
    );
    for scene in &scenes {
        let name = format!("rse_time_{scene}.png");
        if report.figures.contains(&name) {
            let range = report
                .curves
                .iter()
                .filter(|c| &c.scene == scene && c.noise == 0.0)
                .flat_map(|c| c.points.iter().copied())
                .collect::<Vec<_>>();
            let x = figures::decades(range.iter().map(|p| p.0));
            let y = figures::decades(range.iter().map(|p| p.1));
            let _ = writeln!(
                md,
                "- {scene}: ![{scene}]({name}) seconds {:.0e} to {:.0e}, RSE {:.0e} to {:.0e}",
                x[0], x[1], y[0], y[1]
            );
        }
    }

    let _ = writeln!(md, "\n## Peak memory per method\n");
    let _ = writeln!(
        md,
        "Peak resident memory of the whole process during each solve{} (includes the scenes held by the bench), largest over the run:\n",
        if runner.peak_reset {
            ", reset before every solve"
        } else {
            " (could not be reset: a running maximum)"
        }
    );
    let _ = writeln!(md, "| method | peak MiB |");
    let _ = writeln!(md, "| --- | --- |");
    let mut names: Vec<&str> = report.rows.iter().map(|r| r.method.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    for name in names {
        let peak = report
            .rows
            .iter()
            .filter(|r| r.method == name)
            .map(|r| r.peak_mib)
            .fold(f64::NAN, f64::max);
        let _ = writeln!(md, "| {name} | {peak:.0} |");
    }

    if !report.alpha_sweep.is_empty() {
        let _ = writeln!(
            md,
            "\n## Fig. 2: the Bunny reprojected for increasing alpha\n"
        );
        let _ = writeln!(
            md,
            "![Fig. 2](fig2_bunny_alpha.png)\n\nLeft to right: input, then alpha:\n"
        );
        let _ = writeln!(md, "| alpha | RSE | RIE |");
        let _ = writeln!(md, "| --- | --- | --- |");
        for (a, rse, rie) in &report.alpha_sweep {
            let _ = writeln!(md, "| {a} | {} | {} |", fmt(*rse), fmt(*rie));
        }
    }
    if let Some((masked, full)) = report.inpainting {
        let _ = writeln!(
            md,
            "\n## Fig. 3: Suzanne with a large inpainted region (c = 0)\n"
        );
        let _ = writeln!(
            md,
            "![Fig. 3](fig3_suzanne_inpainting.png)\n\nLeft to right: input with the region removed (grey), reprojection of the inpainted solve, reprojection without the region. \
             RSE {} with the region against {} without (paper: 0.00793 against 0.00696).",
            fmt(masked),
            fmt(full)
        );
    }
    if report.figures.iter().any(|f| f == "fig4_highres.png") {
        let _ = writeln!(md, "\n## Fig. 4: the high-resolution scene\n");
        let _ = writeln!(
            md,
            "![Fig. 4](fig4_highres.png)\n\nTop: reprojection (ground truth, linearised, |difference| on 0..0.1, fast marching, |difference|). \
             Bottom: depth colour-coded over the ground truth's range, and |depth difference| over 0..20% of that range. \
             Numbers: Table 1 row `highres`."
        );
    }
    md.push_str(&robustness::markdown(&report.robustness));
    md.push_str(&lights::markdown(&report.lights));
    md
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
}
