//! `sfs-bench --part shadows`: what the defaults make of shadows. Each scene at
//! 256x256 (quick: 128x128), clean and at noise sigma 20, lit by one light
//! 30 and 45 degrees off the axis
//! (seen from the object's centre, at the centre's distance), the scale `s`
//! known, rendered with cast shadows (`scene::shadow`), against the same
//! scene with a hand mask of exactly the shadowed pixels at confidence 0,
//! and against the same light without cast shadows. Targets: automatic
//! handling within 1.1x of the hand mask and within 1.5x of the scene
//! without shadows; the share of object pixels whose depth leaves the range
//! the truth spans (widened by 10 % of it) is reported. Writes `shadows.md`
//! and `shadows.json`.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::grid::Grid;
use sfs_core::light::PointLight;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{Scene, mesh, shadow, sombrero};
use sfs_core::solver::{Problem, Solution};

use super::markdown::{SceneReport, markdown_head, skipped_meshes, table};
use super::scenes::{self, noisy, timed_solve};
use super::shared::{BenchArgs, wanted_renders};

/// Automatic handling within this factor of the hand mask.
const HAND_MASK_FACTOR: f64 = 1.1;
/// And within this factor of the scene without shadows.
const NO_SHADOW_FACTOR: f64 = 1.5;
/// The depth range a solve may use: the truth's, widened by this share of
/// it on both sides.
const RANGE_MARGIN: f64 = 0.1;

/// One scene and light angle.
#[derive(Clone, Debug, Serialize)]
pub struct ShadowRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// The light's angle off the axis, seen from the object's centre.
    pub angle_deg: f64,
    /// Noise sigma on the 0..255 scale.
    pub noise: f64,
    /// Share of the object's pixels that no light reaches.
    pub shadow_share: f64,
    /// RSE at the defaults with the shadows.
    pub rse_shadows: f64,
    /// RSE with a hand mask of exactly the shadowed pixels at confidence 0.
    pub rse_hand_mask: f64,
    /// RSE of the same light without cast shadows.
    pub rse_no_shadows: f64,
    /// RSE with shadows and `--shadow-bound on` (the surface held behind
    /// what its shadow says).
    pub rse_shadow_bound: f64,
    /// `rse_shadows / rse_hand_mask` (target at most 1.1).
    pub ratio_to_hand_mask: f64,
    /// `rse_shadows / rse_no_shadows` (target at most 1.5).
    pub ratio_to_no_shadows: f64,
    /// Share of object pixels whose depth (with shadows, at the defaults)
    /// leaves the truth's range widened by 10 % of it.
    pub out_of_range_share: f64,
    /// Wall time of the solve with shadows.
    pub seconds: f64,
}

/// The part's report.
pub type ShadowsReport = SceneReport<ShadowRow>;

/// The light `angle_deg` off the axis, seen from a centre at depth
/// `centre_depth` on the axis, at that distance from it (to the right).
fn light_at(angle_deg: f64, centre_depth: f64) -> PointLight {
    let a = angle_deg.to_radians();
    PointLight {
        position: [centre_depth * a.sin(), 0.0, centre_depth * (1.0 - a.cos())],
        ..PointLight::CENTRED
    }
}

/// The scene `name` lit by `light`, with cast shadows or without; with
/// them, also the pixels no light reaches.
fn render(
    name: &str,
    meshes: &Path,
    side: usize,
    light: &PointLight,
    shadows: bool,
) -> Result<(Scene, Option<Grid<bool>>)> {
    let file = scenes::mesh_file(name)?;
    let loaded = match file {
        Some(file) => {
            let path = meshes.join(file);
            Some(mesh::load_obj(&path).with_context(|| format!("{name}: {}", path.display()))?)
        }
        None => None,
    };
    let render = |lights: &[PointLight]| -> Result<Scene> {
        match &loaded {
            Some(m) => Ok(mesh::render_lit(
                m,
                side,
                side,
                &mesh::Placement::default(),
                lights,
                name,
            )?),
            None => Ok(sombrero::sombrero_lit(side, side, lights)),
        }
    };
    let lights = std::slice::from_ref(light);
    if shadows {
        let (scene, shadow) = shadow::with_cast_shadows(render, lights)?;
        Ok((scene, Some(shadow)))
    } else {
        Ok((render(lights)?, None))
    }
}

/// The problem of `scene` under its own lights with noise of `noise` and
/// `confidence`.
fn problem(scene: &Scene, noise: f64, confidence: Option<Grid<f64>>) -> Problem {
    Problem {
        confidence,
        lights: scene.lights.clone(),
        ..scenes::problem(scene, noisy(&scene.image, noise))
    }
}

fn solved(problem: &Problem, what: &str) -> Result<(Solution, f64)> {
    timed_solve(problem, &SolverParams::default(), what)
}

/// Share of object pixels whose depth leaves the truth's range widened by
/// [`RANGE_MARGIN`] of it.
fn out_of_range_share(depth: &Grid<f64>, scene: &Scene) -> f64 {
    let truth = scene.depth_gt.finite_values();
    let low = truth.iter().copied().fold(f64::INFINITY, f64::min);
    let high = truth.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let margin = RANGE_MARGIN * (high - low);
    let (mut out, mut count) = (0usize, 0usize);
    for (z, t) in depth.as_slice().iter().zip(scene.depth_gt.as_slice()) {
        if t.is_finite() {
            count += 1;
            out += usize::from(!(z.is_finite() && *z >= low - margin && *z <= high + margin));
        }
    }
    out as f64 / count.max(1) as f64
}

fn row(name: &str, meshes: &Path, side: usize, angle_deg: f64, noise: f64) -> Result<ShadowRow> {
    eprintln!("  shadows {name} {side}x{side} light {angle_deg} deg noise {noise}");
    // The object's centre depth: 2 for the Sombrero and for the placed
    // meshes (their box centre at twice their largest side).
    let light = light_at(angle_deg, 2.0);
    let (with, shadow) = render(name, meshes, side, &light, true)?;
    let shadow = shadow.context("the shadowed render returns its shadow")?;
    let (without, _) = render(name, meshes, side, &light, false)?;
    let object = with.object_mask.as_slice().iter().filter(|&&o| o).count();
    let shadowed = shadow.as_slice().iter().filter(|&&s| s).count();
    let rse = |s: &Solution, scene: &Scene| metrics::rse(&s.depth, &scene.depth_gt);
    let (auto, seconds) = solved(&problem(&with, noise, None), name)?;
    let hand = shadow.map(|&s| if s { 0.0 } else { 1.0 });
    let (masked, _) = solved(&problem(&with, noise, Some(hand)), name)?;
    let (plain, _) = solved(&problem(&without, noise, None), name)?;
    let bounded_params = SolverParams {
        shadow_bound: true,
        ..SolverParams::default()
    };
    let (bounded, _) = timed_solve(&problem(&with, noise, None), &bounded_params, name)?;
    let rse_shadows = rse(&auto, &with)?;
    let rse_hand_mask = rse(&masked, &with)?;
    let rse_no_shadows = rse(&plain, &without)?;
    Ok(ShadowRow {
        scene: name.into(),
        size: format!("{side}x{side}"),
        angle_deg,
        noise,
        shadow_share: shadowed as f64 / object.max(1) as f64,
        rse_shadows,
        rse_hand_mask,
        rse_no_shadows,
        rse_shadow_bound: rse(&bounded, &with)?,
        ratio_to_hand_mask: rse_shadows / rse_hand_mask,
        ratio_to_no_shadows: rse_shadows / rse_no_shadows,
        out_of_range_share: out_of_range_share(&auto.depth, &with),
        seconds,
    })
}

/// Runs the part and writes `shadows.md` and `shadows.json` into `args.out`.
pub fn run(args: &BenchArgs) -> Result<ShadowsReport> {
    let side = if args.quick { 128 } else { 256 };
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for name in wanted_renders(args) {
        'scene: for angle_deg in [30.0, 45.0] {
            for noise in [0.0, 20.0] {
                let result = row(name, &args.meshes, side, angle_deg, noise);
                let Some(row) = scenes::or_skip(name, result, &mut skipped)? else {
                    break 'scene;
                };
                rows.push(row);
            }
        }
    }
    SceneReport::write(&args.out, "shadows", rows, skipped, markdown)
}

/// The report as markdown: a table.
fn markdown(report: &ShadowsReport) -> String {
    let mut md = markdown_head("Shadows: what the light never reaches", &report.command);
    let _ = writeln!(
        md,
        "Targets: RSE with shadows <= {HAND_MASK_FACTOR} x RSE with the exact hand mask, and <= {NO_SHADOW_FACTOR} x RSE of the same light without cast shadows. Out of range: object pixels whose depth leaves the truth's range widened by {:.0} % of it. The last RSE is with shadows and `--shadow-bound on` (not the default).\n",
        100.0 * RANGE_MARGIN
    );
    let flag = |ratio: f64, target: f64| if ratio <= target { "" } else { " **missed**" };
    table(
        &mut md,
        "| scene | size | light | noise | in shadow | RSE shadows | RSE hand mask | RSE no shadows | / hand mask | / no shadows | out of range | seconds | RSE shadow bound |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {:.0}° | {} | {:.1} % | {:.4} | {:.4} | {:.4} | {:.2}{} | {:.2}{} | {:.1} % | {:.2} | {:.4} |",
                r.scene,
                r.size,
                r.angle_deg,
                r.noise,
                100.0 * r.shadow_share,
                r.rse_shadows,
                r.rse_hand_mask,
                r.rse_no_shadows,
                r.ratio_to_hand_mask,
                flag(r.ratio_to_hand_mask, HAND_MASK_FACTOR),
                r.ratio_to_no_shadows,
                flag(r.ratio_to_no_shadows, NO_SHADOW_FACTOR),
                100.0 * r.out_of_range_share,
                r.seconds,
                r.rse_shadow_bound
            )
        },
    );
    skipped_meshes(&mut md, &report.skipped);
    md
}
