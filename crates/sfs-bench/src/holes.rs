//! `sfs-bench --part holes`: what the defaults make of what the image cannot
//! tell. Each scene at 256x256 (quick: 128x128), clean and at noise sigma 20,
//! with four holes of confidence 0 (a disc, a horizontal band, the
//! silhouette band, random blobs over 20 % of the object), against the same
//! scene without a hole and against the harmonic fill of the TRUE depth
//! across the same hole (a plain smooth continuation). The target: RSE with
//! the hole at most 1.2 x sqrt(RSE without^2 + RSE of the harmonic fill^2).
//! Writes `holes.md` and `holes.json`.

use std::fmt::Write as _;

use anyhow::Result;
use serde::Serialize;

use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{self, Scene};
use sfs_core::solver::Problem;

use super::markdown::{SceneReport, markdown_head, skipped_meshes, table};
use super::scenes::{noisy, problem, render_or_skip, timed_solve};
use super::shared::{BenchArgs, wanted_renders};

/// Seed of the blobs.
const SEED: u64 = 1;
/// How much worse than the reference a hole may come back.
const TARGET_FACTOR: f64 = 1.2;

/// One scene, noise and hole.
#[derive(Clone, Debug, Serialize)]
pub struct HoleRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// Noise sigma on the 0..255 scale.
    pub noise: f64,
    /// The hole's shape.
    pub hole: String,
    /// Share of the object's pixels in the hole.
    pub hole_share: f64,
    /// RSE at the defaults without the hole.
    pub rse_no_hole: f64,
    /// RSE at the defaults with the hole (confidence 0 there).
    pub rse_hole: f64,
    /// RSE of the harmonic fill of the true depth across the hole.
    pub rse_harmonic_fill: f64,
    /// `1.2 sqrt(rse_no_hole^2 + rse_harmonic_fill^2)`.
    pub target: f64,
    /// `rse_hole / target` (at most 1 meets it).
    pub ratio_to_target: f64,
    /// Wall time of the solve with the hole.
    pub seconds: f64,
}

/// The part's report.
pub type HolesReport = SceneReport<HoleRow>;

/// The four holes of a scene: name and confidence (0 in the hole).
fn holes(scene: &Scene) -> Vec<(&'static str, Grid<f64>)> {
    let (w, h) = scene.image.size();
    let side = w.min(h) as f64;
    vec![
        ("disc", scene::disc_confidence(w, h, 0.5, 0.45, 0.14)),
        ("band", scene::band_confidence(w, h, 0.45, 0.1)),
        (
            "silhouette",
            scene::silhouette_band_confidence(
                &scene.object_mask,
                ((0.03 * side).round() as usize).max(1),
            ),
        ),
        (
            "blobs",
            scene::blob_confidence(&scene.object_mask, 0.2, SEED),
        ),
    ]
}

/// RSE of a solve at the defaults.
fn default_rse(problem: &Problem, scene: &Scene, what: &str) -> Result<(f64, f64)> {
    let (solution, seconds) = timed_solve(problem, &SolverParams::default(), what)?;
    Ok((metrics::rse(&solution.depth, &scene.depth_gt)?, seconds))
}

/// The rows of one scene.
fn scene_rows(name: &str, scene: &Scene) -> Result<Vec<HoleRow>> {
    let (w, h) = scene.image.size();
    let object_pixels = scene.object_mask.as_slice().iter().filter(|&&o| o).count();
    let mut rows = Vec::new();
    for noise in [0.0, 20.0] {
        let image = noisy(&scene.image, noise);
        let plain = problem(scene, image.clone());
        let (rse_no_hole, _) = default_rse(&plain, scene, name)?;
        for (hole, confidence) in holes(scene) {
            eprintln!("  holes {name} {w}x{h} noise {noise} {hole}");
            let in_hole =
                |c: usize, r: usize| *scene.object_mask.at(c, r) && *confidence.at(c, r) == 0.0;
            let hole_pixels = (0..h)
                .flat_map(|r| (0..w).map(move |c| (c, r)))
                .filter(|&(c, r)| in_hole(c, r))
                .count();
            let known = Grid::from_fn(w, h, |c, r| !in_hole(c, r));
            let fill = scene::harmonic_fill(&scene.depth_gt, &known);
            let rse_harmonic_fill = metrics::rse(&fill, &scene.depth_gt)?;
            let with_hole = Problem {
                confidence: Some(confidence),
                ..problem(scene, image.clone())
            };
            let (rse_hole, seconds) = default_rse(&with_hole, scene, name)?;
            let target = TARGET_FACTOR * rse_no_hole.hypot(rse_harmonic_fill);
            rows.push(HoleRow {
                scene: name.into(),
                size: format!("{w}x{h}"),
                noise,
                hole: hole.into(),
                hole_share: hole_pixels as f64 / object_pixels.max(1) as f64,
                rse_no_hole,
                rse_hole,
                rse_harmonic_fill,
                target,
                ratio_to_target: rse_hole / target,
                seconds,
            });
        }
    }
    Ok(rows)
}

/// Runs the part and writes `holes.md` and `holes.json` into `args.out`.
pub fn run(args: &BenchArgs) -> Result<HolesReport> {
    let side = if args.quick { 128 } else { 256 };
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for name in wanted_renders(args) {
        let Some(scene) = render_or_skip(name, &args.meshes, side, side, &mut skipped)? else {
            continue;
        };
        rows.extend(scene_rows(name, &scene)?);
    }
    SceneReport::write(&args.out, "holes", rows, skipped, markdown)
}

/// The report as markdown: a table.
fn markdown(report: &HolesReport) -> String {
    let mut md = markdown_head("Holes: what the image cannot tell", &report.command);
    let _ = writeln!(
        md,
        "Target: RSE with the hole <= {TARGET_FACTOR} x sqrt(RSE without^2 + RSE of the harmonic fill of the true depth^2).\n"
    );
    table(
        &mut md,
        "| scene | size | noise | hole | share | RSE no hole | RSE hole | harmonic fill | target | ratio | seconds |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {} | {:.0} % | {:.4} | {:.4} | {:.4} | {:.4} | {:.2}{} | {:.2} |",
                r.scene,
                r.size,
                r.noise,
                r.hole,
                100.0 * r.hole_share,
                r.rse_no_hole,
                r.rse_hole,
                r.rse_harmonic_fill,
                r.target,
                r.ratio_to_target,
                if r.ratio_to_target <= 1.0 {
                    ""
                } else {
                    " **missed**"
                },
                r.seconds
            )
        },
    );
    skipped_meshes(&mut md, &report.skipped);
    md
}
