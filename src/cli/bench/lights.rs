//! The lights table of `bench`: each scene rendered with its light at the
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
use sfs_core::solver::calibrate::{estimate_intensity_scale, scale_to_known_depth};
use sfs_core::solver::{Problem, solve};

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
    /// RSE with `s` estimated by the search.
    pub auto_rse: f64,
    /// Estimated `s` over the true one.
    pub auto_scale_ratio: f64,
    /// Whether the search called `s` determined.
    pub auto_determined: bool,
    /// RSE with the light assumed at the optical centre.
    pub ignored_rse: f64,
    /// Seconds of the solve with the lights.
    pub seconds: f64,
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

fn render(name: &str, meshes: &Path, side: usize, lights: &[PointLight]) -> Result<Scene> {
    let file = match name {
        "sombrero" => return Ok(sombrero_lit(side, side, lights)),
        "bunny" => "stanford-bunny.obj",
        "dragon" => "dragon.obj",
        "suzanne" => "suzanne.obj",
        other => anyhow::bail!("no scene called {other}"),
    };
    let path = meshes.join(file);
    let width = if name == "suzanne" { 2 * side } else { side };
    mesh::load_obj(&path)
        .and_then(|m| mesh::render_lit(&m, width, side, &mesh::Placement::default(), lights, name))
        .with_context(|| format!("{name}: {}", path.display()))
}

fn rse_of(problem: &Problem, params: &SolverParams, scene: &Scene) -> Result<(f64, f64)> {
    let start = Instant::now();
    let solution = solve(problem, params, &mut ())?;
    let seconds = start.elapsed().as_secs_f64();
    Ok((metrics::rse(&solution.depth, &scene.depth_gt)?, seconds))
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
                image: scene.image.clone(),
                camera: scene.camera,
                intensity_scale: scene.intensity_scale,
                object_mask: Some(scene.object_mask.clone()),
                confidence: None,
                lights: lights.clone(),
            };
            let (rse, seconds) = rse_of(&problem, &params, &scene)?;
            let (known_depth_rse, auto_rse, auto_scale_ratio, auto_determined) =
                if problem.light_is_centred() {
                    (rse, f64::NAN, f64::NAN, false)
                } else {
                    // s from one known distance: a few solves moving s until
                    // the middle pixel lands there.
                    let mut trial = Problem {
                        intensity_scale: 1.0,
                        ..problem.clone()
                    };
                    let mut known = f64::NAN;
                    if let Some((c, r)) = middle_pixel(&scene) {
                        let truth = *scene.depth_gt.at(c, r);
                        for _ in 0..8 {
                            let depth = solve(&trial, &params, &mut ())?.depth;
                            known = metrics::rse(&depth, &scene.depth_gt)?;
                            match scale_to_known_depth(&depth, c, r, truth) {
                                Some(k) if (k - 1.0).abs() > 1e-3 => {
                                    trial.intensity_scale *= k * k;
                                }
                                _ => break,
                            }
                        }
                    }
                    let estimate = estimate_intensity_scale(&problem, &params, &mut ())?;
                    let estimated = Problem {
                        intensity_scale: estimate.intensity_scale,
                        ..problem.clone()
                    };
                    let (auto, _) = rse_of(&estimated, &params, &scene)?;
                    (
                        known,
                        auto,
                        estimate.intensity_scale / scene.intensity_scale,
                        estimate.well_determined,
                    )
                };
            let ignored = Problem {
                lights: Vec::new(),
                ..problem.clone()
            };
            let (ignored_rse, _) = rse_of(&ignored, &params, &scene)?;
            rows.push(LightRow {
                scene: name.to_owned(),
                size: format!("{}x{}", scene.image.width(), scene.image.height()),
                setup: setup.to_owned(),
                rse,
                known_depth_rse,
                auto_rse,
                auto_scale_ratio,
                auto_determined,
                ignored_rse,
                seconds,
            });
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
         | scene | size | lights | RSE (s known) | RSE (s from one distance) | RSE (s auto) | s auto / true | determined | RSE light ignored | seconds |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.4} | {:.4} | {:.4} | {:.2} | {} | {:.4} | {:.2} |",
            r.scene,
            r.size,
            r.setup,
            r.rse,
            r.known_depth_rse,
            r.auto_rse,
            r.auto_scale_ratio,
            if r.auto_determined { "yes" } else { "no" },
            r.ignored_rse,
            r.seconds
        );
    }
    md
}
