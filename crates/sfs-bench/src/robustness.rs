//! The robustness table of `sfs-bench`: the default settings (alpha auto,
//! relative units, fast-marching start) on every scene at several sizes,
//! noise levels and exposures, beside the best alpha of a sweep over four
//! decades, the solve started from the true depth and fast marching alone;
//! and the default's RSE over a series of image sizes of the same scenes.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::params::{Alpha, InitialDepth, SolverParams};
use sfs_core::scene::Scene;
use sfs_core::solver::{FastMarchingParams, solve, solve_fast_marching};

use super::scenes::{noisy, problem, render, timed_solve};

/// One scene at one size, noise level and exposure.
#[derive(Clone, Debug, Serialize)]
pub struct RobustnessRow {
    /// Scene name.
    pub scene: String,
    /// Image size `WxH`.
    pub size: String,
    /// Noise sigma on the 0..255 scale (before the exposure).
    pub noise: f64,
    /// The image (and its noise) times this, the intensity scale unchanged:
    /// the same shape at depth `/ sqrt(exposure)`; RSE is measured on the
    /// result times `sqrt(exposure)`.
    pub exposure: f64,
    /// RSE at the default settings.
    pub default_rse: f64,
    /// The alpha the default chose (relative units).
    pub chosen_alpha: f64,
    /// The lowest RSE of the sweep (alpha = chosen times 10^(k/2), k = -4..4).
    pub best_rse: f64,
    /// The alpha that gave it.
    pub best_alpha: f64,
    /// `default_rse / best_rse`.
    pub ratio_to_best: f64,
    /// RSE of the default solve started from the true depth (how far the
    /// energy's own minimiser is from the truth).
    pub truth_start_rse: f64,
    /// RSE of fast marching alone (on the raw image).
    pub fast_marching_rse: f64,
    /// Wall time of the default solve.
    pub seconds: f64,
}

/// The default RSE of one scene at one size (clean, exposure 1).
#[derive(Clone, Debug, Serialize)]
pub struct SizeRow {
    /// Scene name.
    pub scene: String,
    /// Image size `WxH`.
    pub size: String,
    /// RSE at the default settings.
    pub rse: f64,
    /// Wall time of the solve.
    pub seconds: f64,
}

/// What the robustness part measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Robustness {
    /// Scene x size x noise x exposure.
    pub rows: Vec<RobustnessRow>,
    /// Scene x size, clean.
    pub sizes: Vec<SizeRow>,
}

/// The dimmed exposure.
const DIM: f64 = 0.1;

/// RSE of `depth` times `factor` against the scene's truth.
fn rse(depth: &Grid<f64>, factor: f64, scene: &Scene) -> Result<f64> {
    Ok(metrics::rse(&depth.map(|z| z * factor), &scene.depth_gt)?)
}

/// One row: the default, the sweep, the truth start and fast marching.
fn row(
    name: &str,
    scene: &Scene,
    noise: f64,
    exposure: f64,
    sweep: &[f64],
) -> Result<RobustnessRow> {
    let (w, h) = scene.image.size();
    eprintln!("  robustness {name} {w}x{h} noise {noise} exposure {exposure}");
    let image = noisy(&scene.image, noise);
    let problem = problem(scene, image.map(|v| v * exposure));
    let back = exposure.sqrt();
    let defaults = SolverParams::default();
    let (solution, seconds) = timed_solve(&problem, &defaults, name)?;
    let default_rse = rse(&solution.depth, back, scene)?;
    let chosen_alpha = solution.alpha;
    let mut best = (default_rse, chosen_alpha);
    for factor in sweep {
        let params = SolverParams {
            alpha: Alpha::Value(chosen_alpha * factor),
            ..defaults.clone()
        };
        let swept = solve(&problem, &params, &mut ())
            .with_context(|| format!("alpha sweep of {name} failed"))?;
        let value = rse(&swept.depth, back, scene)?;
        if value < best.0 {
            best = (value, chosen_alpha * factor);
        }
    }
    let truth = SolverParams {
        initial_depth: InitialDepth::Map(scene.depth_gt.map(|z| z / back)),
        ..defaults
    };
    let from_truth = solve(&problem, &truth, &mut ())
        .with_context(|| format!("truth start of {name} failed"))?;
    let fast = solve_fast_marching(&problem, &FastMarchingParams::default(), &mut ())
        .with_context(|| format!("fast marching on {name} failed"))?;
    Ok(RobustnessRow {
        scene: name.into(),
        size: format!("{w}x{h}"),
        noise,
        exposure,
        default_rse,
        chosen_alpha,
        best_rse: best.0,
        best_alpha: best.1,
        ratio_to_best: default_rse / best.0,
        truth_start_rse: rse(&from_truth.depth, back, scene)?,
        fast_marching_rse: rse(&fast.depth, back, scene)?,
        seconds,
    })
}

/// Runs the robustness table on `scenes` (names; missing meshes are added to
/// `skipped`). Quick: a quarter of the sizes, exposure 1 only, a sweep of
/// five values two decades wide, no high-resolution scene.
pub fn run(
    scenes: &[&str],
    meshes: &Path,
    quick: bool,
    skipped: &mut Vec<String>,
) -> Result<Robustness> {
    let mut out = Robustness::default();
    let sweep: Vec<f64> = if quick {
        vec![0.1, 0.316, 3.16, 10.0]
    } else {
        (-4..=4)
            .filter(|k| *k != 0)
            .map(|k| 10f64.powf(f64::from(k) / 2.0))
            .collect()
    };
    let exposures: &[f64] = if quick { &[1.0] } else { &[1.0, DIM] };
    for &name in scenes {
        // Suzanne is twice as wide as high, as in the paper.
        let aspect = if name == "suzanne" { 2 } else { 1 };
        let sides: &[usize] = if quick { &[32, 64] } else { &[64, 256] };
        for &side in sides {
            let scene = match render(name, meshes, side * aspect, side) {
                Ok(scene) => scene,
                Err(e) => {
                    skipped.push(format!("robustness: {e:#}"));
                    break;
                }
            };
            for noise in [0.0, 20.0] {
                for &exposure in exposures {
                    out.rows.push(row(name, &scene, noise, exposure, &sweep)?);
                }
            }
        }
        if !quick && name == "dragon" {
            let scene = render(name, meshes, 1080, 1920)?;
            for noise in [0.0, 20.0] {
                out.rows.push(row(name, &scene, noise, 1.0, &sweep)?);
            }
        }
        let sizes: &[(usize, usize)] = if quick {
            &[(48, 48), (96, 96)]
        } else {
            &[
                (128, 128),
                (256, 256),
                (512, 512),
                (1024, 1024),
                (1920, 1080),
            ]
        };
        for &(w, h) in sizes {
            let Ok(scene) = render(name, meshes, w, h) else {
                break;
            };
            eprintln!("  size {name} {w}x{h}");
            let (solution, seconds) = timed_solve(
                &problem(&scene, scene.image.clone()),
                &SolverParams::default(),
                &format!("{name} at {w}x{h}"),
            )?;
            out.sizes.push(SizeRow {
                scene: name.into(),
                size: format!("{w}x{h}"),
                rse: rse(&solution.depth, 1.0, &scene)?,
                seconds,
            });
        }
    }
    Ok(out)
}

/// The report's robustness section (empty when the part was not run).
pub fn markdown(robustness: &Robustness) -> String {
    let mut md = String::new();
    if robustness.rows.is_empty() && robustness.sizes.is_empty() {
        return md; // --part paper
    }
    let _ = writeln!(
        md,
        "\n## Robustness: the defaults (alpha auto, relative units, fast-marching start)\n"
    );
    let _ = writeln!(
        md,
        "Best alpha: the lowest RSE of a sweep of alpha over four decades around the chosen one \
         (x3.16 steps). Exposure k: the image and its noise times k, the intensity scale \
         unchanged (the same shape at depth / sqrt(k)). Truth start: the default solve started \
         from the true depth.\n"
    );
    super::markdown::table(
        &mut md,
        "| scene | size | noise | exposure | default RSE | chosen alpha | best RSE (alpha) | default / best | truth start | fast marching | seconds |",
        &robustness.rows,
        |r| {
            format!(
                "| {} | {} | {} | {} | {:.4} | {:.2e} | {:.4} ({:.2e}) | {:.2} | {:.4} | {:.4} | {:.2} |",
                r.scene,
                r.size,
                r.noise,
                r.exposure,
                r.default_rse,
                r.chosen_alpha,
                r.best_rse,
                r.best_alpha,
                r.ratio_to_best,
                r.truth_start_rse,
                r.fast_marching_rse,
                r.seconds
            )
        },
    );
    super::markdown::titled_table(
        &mut md,
        "\n### The default over image sizes (clean, same field of view)\n",
        "| scene | size | RSE | seconds |",
        &robustness.sizes,
        |r| {
            format!(
                "| {} | {} | {:.4} | {:.2} |",
                r.scene, r.size, r.rse, r.seconds
            )
        },
    );
    md
}
