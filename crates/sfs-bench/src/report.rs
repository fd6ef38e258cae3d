//! Writing the paper part's report: `report.json` (the typed [`Report`])
//! and `report.md` (Tables 1-3 beside the paper's numbers, the speed-ups at
//! equal RSE, peak memory, Figs. 2-4, then the robustness and lights
//! sections). Reads only what the run gathered; draws nothing.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use super::figures;
use super::markdown::{table, table_head, write_markdown};
use super::paper_table::paper;
use super::shared::{
    ALPHA_CLEAN, ALPHA_NOISY, NOISE_SEED, NOISE_SIGMA, POST_WEIGHT, TV_ITERATIONS,
};
use super::{lights, like_for_like, robustness};
use sfs_core::memory::proc_mib;

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
    /// Table 1 like for like: mesh and depth-map renders at the defaults.
    pub like_for_like: Vec<like_for_like::LikeRow>,
    /// Scenes that could not be run, and why.
    pub skipped: Vec<String>,
    /// Wall time of the whole benchmark.
    pub total_seconds: f64,
}

/// What report.md states about the run besides report.json.
pub(super) struct Conditions {
    /// The explicit scheme's budget per solve on the small scenes, seconds
    /// (a fifth of it on the high-resolution one).
    pub(super) explicit_seconds: f64,
    /// Whether the peak memory was reset before every solve.
    pub(super) peak_reset: bool,
}

/// The machine the report is made on: cores, CPU model, memory.
pub(super) fn machine() -> Machine {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map_or_else(|| "unknown".to_string(), |(_, v)| v.trim().to_string());
    let memory_mib = proc_mib("/proc/meminfo", "MemTotal").unwrap_or(f64::NAN);
    Machine {
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        cpu,
        memory_mib,
    }
}

/// A number to five decimals; a dash for NaN (not reported).
fn fmt(v: f64) -> String {
    if v.is_nan() {
        "–".into()
    } else {
        format!("{v:.5}")
    }
}

/// The row of `method` on `scene` at `noise`.
fn find<'a>(rows: &'a [Row], scene: &str, noise: f64, method: &str) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.scene == scene && r.noise == noise && r.method == method)
}

/// Writes `report.json` and `report.md` into `out`.
pub(super) fn write(out: &Path, report: &Report, conditions: &Conditions) -> Result<()> {
    let json = out.join("report.json");
    sfs_core::io::write_json(&json, report)
        .with_context(|| format!("cannot write {}", json.display()))?;
    write_markdown(out, "report", &markdown(report, conditions))
}

/// report.md.
fn markdown(report: &Report, conditions: &Conditions) -> String {
    let mut md = String::new();
    header(&mut md, report, conditions);
    let scenes = scenes(report);
    table1(&mut md, report, &scenes);
    md.push_str(&like_for_like::markdown(&report.like_for_like));
    table2(&mut md, report, &scenes);
    table3(&mut md, report, &scenes);
    speedups(&mut md, report);
    rse_figures(&mut md, report, &scenes);
    peak_memory(&mut md, report, conditions);
    figures_2_to_4(&mut md, report);
    md.push_str(&robustness::markdown(&report.robustness));
    md.push_str(&lights::markdown(&report.lights));
    md
}

/// The title, command, machine, the settings of the paper part and the
/// scenes skipped.
fn header(md: &mut String, report: &Report, conditions: &Conditions) {
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
        conditions.explicit_seconds,
        conditions.explicit_seconds / 5.0
    );
    if !report.skipped.is_empty() {
        let _ = writeln!(md, "Skipped: {}.\n", report.skipped.join("; "));
    }
}

/// The scenes of the rows, in their order.
fn scenes(report: &Report) -> Vec<String> {
    let mut scenes: Vec<String> = Vec::new();
    for r in &report.rows {
        if !scenes.contains(&r.scene) {
            scenes.push(r.scene.clone());
        }
    }
    scenes
}

/// Table 1: RSE and RIE of every method, clean and noisy, beside the
/// paper's.
fn table1(md: &mut String, report: &Report, scenes: &[String]) {
    let methods = [
        ("linearised", 2usize),
        ("explicit", 1),
        ("fast_marching", 0),
    ];

    let _ = writeln!(md, "## Table 1: RSE and RIE, clean and noisy\n");
    table_head(
        md,
        "| scene | noise | method | RSE | RIE | paper RSE | paper RIE |",
    );
    for scene in scenes {
        let p = paper(scene);
        for noise in [0.0, NOISE_SIGMA] {
            for (method, k) in methods {
                if let Some(r) = find(&report.rows, scene, noise, method) {
                    let (pr, pi) = p.map_or((f64::NAN, f64::NAN), |p| {
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
}

/// Table 2: the noisy images with pre- and post-processing.
fn table2(md: &mut String, report: &Report, scenes: &[String]) {
    let _ = writeln!(
        md,
        "\n## Table 2: noisy images with pre-processing (TV denoising) and post-processing (depth smoothing)\n"
    );
    let _ = writeln!(
        md,
        "Pre: ROF/TV denoising, weight = the image's estimated noise level (Immerkaer), {TV_ITERATIONS} primal-dual iterations. \
         Post: the depth smoothed with the energy's second-order Charbonnier term, weight {POST_WEIGHT}.\n"
    );
    table_head(
        md,
        "| scene | method | RSE | +pre | +post | paper RSE | paper +pre | paper +post |",
    );
    for scene in scenes {
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
            let (po, pp, pq) = p.map_or((f64::NAN, f64::NAN, f64::NAN), |p| {
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
}

/// Table 3: runtimes on the clean images.
fn table3(md: &mut String, report: &Report, scenes: &[String]) {
    let _ = writeln!(md, "\n## Table 3: runtimes in this run (clean images)\n");
    table_head(
        md,
        "| scene | linearised s | explicit s | fast marching s | explicit / linearised | linearised / fast marching | paper: ours, Ju, Vogel s |",
    );
    for scene in scenes {
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
}

/// Linearised against explicit at equal RSE.
fn speedups(md: &mut String, report: &Report) {
    let _ = writeln!(md, "\n### Linearised against explicit at equal RSE\n");
    let _ = writeln!(
        md,
        "Both schemes minimise the same energy from the same start. \"common RSE\" is the larger of the two final RSEs, which both reached; \
         the times are when each reached it for good (the last crossing of its RSE-over-time curve; recording excluded). Where the explicit scheme ran out of budget above the linearised RSE, \
         a power law fitted to the last half of its RSE-over-time curve gives an **extrapolated** time to the linearised RSE.\n"
    );
    table(
        md,
        "| scene | noise | linearised RSE | explicit RSE | common RSE | linearised s | explicit s | speed-up (measured) | explicit s to linearised RSE (extrapolated) | speed-up (extrapolated) |",
        &report.speedups,
        |s| {
            format!(
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
            )
        },
    );
}

/// The list of RSE-over-time figures with their ranges.
fn rse_figures(md: &mut String, report: &Report, scenes: &[String]) {
    let _ = writeln!(
        md,
        "\nRSE over time (log-log; blue linearised, red explicit; every point a level or a snapshot):\n"
    );
    for scene in scenes {
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
}

/// Peak resident memory per method.
fn peak_memory(md: &mut String, report: &Report, conditions: &Conditions) {
    let _ = writeln!(md, "\n## Peak memory per method\n");
    let _ = writeln!(
        md,
        "Peak resident memory of the whole process during each solve{} (includes the scenes held by the bench), largest over the run:\n",
        if conditions.peak_reset {
            ", reset before every solve"
        } else {
            " (could not be reset: a running maximum)"
        }
    );
    table_head(md, "| method | peak MiB |");
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
}

/// Figs. 2-4 with their captions, where they were made.
fn figures_2_to_4(md: &mut String, report: &Report) {
    if !report.alpha_sweep.is_empty() {
        let _ = writeln!(
            md,
            "\n## Fig. 2: the Bunny reprojected for increasing alpha\n"
        );
        let _ = writeln!(
            md,
            "![Fig. 2](fig2_bunny_alpha.png)\n\nLeft to right: input, then alpha:\n"
        );
        table_head(md, "| alpha | RSE | RIE |");
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
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(noise: f64, method: &str, rse: f64, seconds: f64) -> Row {
        Row {
            scene: "sombrero".into(),
            size: "64x64".into(),
            noise,
            method: method.into(),
            alpha: Some(if noise == 0.0 {
                ALPHA_CLEAN
            } else {
                ALPHA_NOISY
            }),
            rse,
            rie: rse / 10.0,
            seconds,
            peak_mib: 100.0 + seconds,
            iterations: 1,
            budget_exhausted: method == "explicit",
        }
    }

    #[test]
    fn report_md_sets_each_solve_beside_the_paper_and_json_keeps_the_rows() {
        let report = Report {
            command: "sfs-bench --quick".into(),
            quick: true,
            machine: Machine {
                cores: 2,
                cpu: "cpu".into(),
                memory_mib: 1024.0,
            },
            rows: vec![
                row(0.0, "linearised", 0.01, 0.5),
                row(0.0, "explicit", 0.02, 5.0),
                row(0.0, "fast_marching", 0.03, 0.1),
                row(NOISE_SIGMA, "linearised", 0.04, 0.5),
                row(NOISE_SIGMA, "linearised+pre", 0.05, 0.6),
            ],
            curves: Vec::new(),
            speedups: Vec::new(),
            alpha_sweep: Vec::new(),
            inpainting: None,
            figures: Vec::new(),
            robustness: robustness::Robustness::default(),
            lights: Vec::new(),
            like_for_like: Vec::new(),
            skipped: vec!["dragon: no mesh".into()],
            total_seconds: 12.0,
        };
        let conditions = Conditions {
            explicit_seconds: 5.0,
            peak_reset: true,
        };
        let md = markdown(&report, &conditions);
        for line in [
            "Skipped: dragon: no mesh.",
            "budget of 5 s per solve (1 s on the high-resolution scene)",
            // Table 1: ours beside the paper's ours, Ju and Vogel.
            "| sombrero 64x64 | 0 | linearised | 0.01000 | 0.00100 | 0.00768 | 0.00925 |",
            "| sombrero 64x64 | 0 | explicit (budget) | 0.02000 | 0.00200 | 0.00318 | 0.00209 |",
            "| sombrero 64x64 | 20 | linearised | 0.04000 | 0.00400 | 0.01542 | 0.03851 |",
            // Table 2: no +post row, a dash.
            "| sombrero | linearised | 0.04000 | 0.05000 | – | 0.01542 | 0.01741 | 0.01538 |",
            // Table 3: explicit / linearised 10x, linearised / fast marching 5x.
            "| sombrero 64x64 | 0.50 | 5.0 (budget spent) | 0.10 | 10x | 5.0x | 17, 29113, 1 |",
            "| explicit | 105 |",
        ] {
            assert!(md.contains(line), "no {line:?} in\n{md}");
        }
        assert!(!md.contains("## Fig. 2"), "no sweep, no Fig. 2");

        let dir = tempfile::tempdir().expect("temp dir");
        write(dir.path(), &report, &conditions).expect("written");
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("report.json")).expect("report.json"),
        )
        .expect("JSON");
        assert_eq!(json["rows"].as_array().map(Vec::len), Some(5));
        assert_eq!(json["rows"][1]["budget_exhausted"], true);
        let written = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
        assert_eq!(written, md);
        assert!(write(&dir.path().join("missing"), &report, &conditions).is_err());
    }
}
