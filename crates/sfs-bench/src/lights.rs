//! The lights table of `sfs-bench`: each scene rendered with its light at the
//! optical centre and with lights beside the lens (a flash, an anisotropic
//! LED, a ring of four), solved at the defaults with the lights where they
//! are (s known; s from one known distance; s estimated), and with the light
//! wrongly assumed at the centre: what the light model buys and what
//! ignoring the light costs.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::light::PointLight;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{Scene, mesh, sombrero::sombrero_lit};
use sfs_core::solver::calibrate::{
    KnownDepth, SCALE_TOLERANCE, estimate_intensity_scale, solve_with_known_depths,
};
use sfs_core::solver::{Method, Problem, solve};

use super::scenes::problem;

/// One scene under one light set-up.
#[derive(Clone, Debug, Serialize)]
pub struct LightRow {
    /// Scene name.
    pub scene: String,
    /// Image size `WxH`.
    pub size: String,
    /// The light set-up.
    pub setup: String,
    /// RSE with the lights where they are and the true `s`.
    pub rse: f64,
    /// RSE with `s` from the true distance of the object's middle pixel.
    pub known_depth_rse: f64,
    /// The solved depth's relative error at that pixel.
    pub known_depth_pixel_error: f64,
    /// Solves the known distance took.
    pub known_depth_solves: usize,
    /// RSE with `s` estimated by the search.
    pub auto_rse: f64,
    /// Estimated `s` over the true one.
    pub auto_scale_ratio: f64,
    /// Whether the search called `s` determined.
    pub auto_determined: bool,
    /// Whether that verdict was right: determined exactly when the estimate
    /// is within the promised factor (1.15) of the true `s`.
    pub verdict_right: bool,
    /// RSE with the light assumed at the optical centre.
    pub ignored_rse: f64,
    /// Seconds of the solve with the lights (best of two).
    pub seconds: f64,
    /// Seconds of the same image solved with the light at the optical
    /// centre (best of two).
    pub centred_seconds: f64,
}

/// The set-ups, in units of the scene (the mesh's largest side = 1, the
/// object about 2 away): name and lights.
fn setups() -> Vec<(&'static str, Vec<PointLight>)> {
    let at = |position: [f64; 3], direction: Option<[f64; 3]>, mu: f64| PointLight {
        position,
        direction,
        mu,
        intensity: 1.0,
    };
    vec![
        ("centred", vec![]),
        ("flash 0.5 beside", vec![at([0.5, 0.0, 0.0], None, 0.0)]),
        (
            "LED 0.5 above, mu 1",
            vec![at([0.0, -0.5, 0.0], Some([0.0, 0.24, 0.97]), 1.0)],
        ),
        (
            "ring of 4 at 0.3",
            vec![
                at([0.3, 0.0, 0.0], None, 0.0),
                at([-0.3, 0.0, 0.0], None, 0.0),
                at([0.0, 0.3, 0.0], None, 0.0),
                at([0.0, -0.3, 0.0], None, 0.0),
            ],
        ),
    ]
}

/// The scene `name` at `side` pixels (Suzanne twice as wide) under
/// `lights` (the albedo part renders with it too).
pub(super) fn render(
    name: &str,
    meshes: &Path,
    side: usize,
    lights: &[PointLight],
) -> Result<Scene> {
    let Some(file) = super::scenes::mesh_file(name)? else {
        return Ok(sombrero_lit(side, side, lights));
    };
    let path = meshes.join(file);
    let width = if name == "suzanne" { 2 * side } else { side };
    mesh::load_obj(&path)
        .and_then(|m| mesh::render_lit(&m, width, side, &mesh::Placement::default(), lights, name))
        .with_context(|| format!("{name}: {}", path.display()))
}

/// RSE and the best of two solves' seconds.
fn rse_of(problem: &Problem, params: &SolverParams, scene: &Scene) -> Result<(f64, f64)> {
    let mut best = f64::INFINITY;
    let mut rse = f64::NAN;
    for _ in 0..2 {
        let start = Instant::now();
        let solution = solve(problem, params, &mut ())?;
        best = best.min(start.elapsed().as_secs_f64());
        rse = metrics::rse(&solution.depth, &scene.depth_gt)?;
    }
    Ok((rse, best))
}

/// The middle object pixel of a scene (for the known distance).
fn middle_pixel(scene: &Scene) -> Option<(usize, usize)> {
    let (w, h) = scene.depth_gt.size();
    let mut pixels: Vec<(usize, usize)> = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .filter(|&(c, r)| scene.depth_gt.at(c, r).is_finite())
        .collect();
    pixels.sort_by_key(|&(c, r)| {
        let (dc, dr) = (c as i64 - w as i64 / 2, r as i64 - h as i64 / 2);
        dc * dc + dr * dr
    });
    pixels.first().copied()
}

/// Runs the lights table on `scenes` at `side` pixels (missing meshes are
/// added to `skipped`).
pub fn run(
    scenes: &[&str],
    meshes: &Path,
    side: usize,
    skipped: &mut Vec<String>,
) -> Result<Vec<LightRow>> {
    let params = SolverParams::default();
    let mut rows = Vec::new();
    for &name in scenes {
        for (setup, lights) in setups() {
            let scene = match render(name, meshes, side, &lights) {
                Ok(scene) => scene,
                Err(e) => {
                    skipped.push(format!("lights: {e:#}"));
                    break;
                }
            };
            let problem = Problem {
                lights: lights.clone(),
                ..problem(&scene, scene.image.clone())
            };
            let (rse, seconds) = rse_of(&problem, &params, &scene)?;
            let mut row = LightRow {
                scene: name.to_owned(),
                size: format!("{}x{}", scene.image.width(), scene.image.height()),
                setup: setup.to_owned(),
                rse,
                known_depth_rse: rse,
                known_depth_pixel_error: 0.0,
                known_depth_solves: 0,
                auto_rse: f64::NAN,
                auto_scale_ratio: f64::NAN,
                auto_determined: false,
                verdict_right: true,
                ignored_rse: f64::NAN,
                seconds,
                centred_seconds: f64::NAN,
            };
            if !problem.light_is_centred() {
                // s from one known distance (the middle pixel's true depth),
                // the search starting from s = 1.
                if let Some((c, r)) = middle_pixel(&scene) {
                    let truth = *scene.depth_gt.at(c, r);
                    let mut trial = Problem {
                        intensity_scale: 1.0,
                        ..problem.clone()
                    };
                    let point = KnownDepth {
                        column_px: c as f64,
                        row_px: r as f64,
                        depth: truth,
                    };
                    let (solution, fit) = solve_with_known_depths(
                        &mut trial,
                        &params,
                        &Method::Linearised,
                        &[point],
                        &mut (),
                    )?;
                    row.known_depth_rse = metrics::rse(&solution.depth, &scene.depth_gt)?;
                    row.known_depth_pixel_error = fit.points[0].relative_residual;
                    row.known_depth_solves = fit.solves;
                }
                let estimate = estimate_intensity_scale(&problem, &params, &mut ())?;
                let estimated = Problem {
                    intensity_scale: estimate.intensity_scale,
                    ..problem.clone()
                };
                row.auto_rse = rse_of(&estimated, &params, &scene)?.0;
                row.auto_scale_ratio = estimate.intensity_scale / scene.intensity_scale;
                row.auto_determined = estimate.well_determined;
                let within = row.auto_scale_ratio <= SCALE_TOLERANCE
                    && row.auto_scale_ratio >= 1.0 / SCALE_TOLERANCE;
                row.verdict_right = row.auto_determined == within;
            }
            let ignored = Problem {
                lights: Vec::new(),
                ..problem.clone()
            };
            (row.ignored_rse, row.centred_seconds) = rse_of(&ignored, &params, &scene)?;
            rows.push(row);
        }
    }
    Ok(rows)
}
/// The table as markdown.
pub fn markdown(rows: &[LightRow]) -> String {
    let mut md = String::new();
    if rows.is_empty() {
        return md;
    }
    let _ = writeln!(
        md,
        "\n## Lights beside the lens (defaults, the lights where they are)\n\n\
         s known: RSE with the true s. From one distance: the middle object pixel's true \
         depth given (`--known-depth`), the search starting from s = 1; its error at that \
         pixel and the solves it took. Auto: s estimated by the search; determined: its \
         verdict; right: whether the verdict was (determined exactly when within 1.15x of the \
         true s). Ignored: the light assumed at the optical centre. Time: the best of two \
         solves with the lights, and of the same image with the light at the centre.\n\n\
         | scene | size | lights | RSE s known | RSE from one distance | pixel error | solves | RSE s auto | s auto / true | determined | right | RSE light ignored | seconds | centred seconds | ratio |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.4} | {:.4} | {:+.2} % | {} | {:.4} | {:.2} | {} | {} | {:.4} | {:.2} | {:.2} | {:.2} |",
            r.scene,
            r.size,
            r.setup,
            r.rse,
            r.known_depth_rse,
            100.0 * r.known_depth_pixel_error,
            r.known_depth_solves,
            r.auto_rse,
            r.auto_scale_ratio,
            if r.auto_determined { "yes" } else { "no" },
            if r.verdict_right { "yes" } else { "NO" },
            r.ignored_rse,
            r.seconds,
            r.centred_seconds,
            r.seconds / r.centred_seconds,
        );
    }
    md
}
