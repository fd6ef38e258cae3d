//! `sfs-bench --part real`: the guard of the photograph path. Every shared LED
//! photograph of the face solved as the README's command solves it (the
//! defaults: the depth unit decided by the tool), with `--distance` 10 %
//! off the truth either way, and with `--known-depth` at the nose; each
//! against the tool's own photometric-stereo result from the seven
//! photographs (mean normal error, the object's distance, relief,
//! seconds). Then renders of that reconstructed face (uniform albedo and
//! the set's albedo, each LED, cast shadows) solved at the defaults against
//! their truth. Writes real.md and real.json. `--scenes led4,render-led4`
//! picks photographs and renders.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::light::{LightModel, PointLight};
use sfs_core::model::{LevelGeometry, reproject};
use sfs_core::occlusion::cast_shadow;
use sfs_core::params::{AlbedoChoice, SolverParams};
use sfs_core::photo;
use sfs_core::solver::calibrate::median_depth;
use sfs_core::solver::depth_unit::{DepthUnit, DistanceCues, solve_photograph};
use sfs_core::solver::photometric::compare_single;
use sfs_core::solver::{Method, Problem, Solution};

use super::markdown::table;
use super::shared::{BenchArgs, wanted};

/// The photographs' working size with `--quick` (the defaults solve them
/// at their own 1296x864).
const QUICK_SIDE: usize = 648;

/// One solve of a face photograph or render against its truth.
#[derive(Clone, Debug, Serialize)]
pub struct RealRow {
    /// The photograph (`led4`) or render (`render led4 uniform`).
    pub image: String,
    /// How the depth unit was set: `defaults`, `distance x0.9`,
    /// `distance x1.1`, `known depth`.
    pub setting: String,
    /// Which cue set the unit (the tool's decision).
    pub unit_source: String,
    /// Mean angle between the solved and the true normals, degrees.
    pub mean_normal_error_deg: f64,
    /// The solved median depth over the true one, minus 1.
    pub distance_error: f64,
    /// The solved surface's relief: its depth range (2nd to 98th
    /// percentile) over its median depth.
    pub relief: f64,
    /// The truth's relief, the same way.
    pub true_relief: f64,
    /// Whether `--albedo auto` used its estimate.
    pub albedo_used: bool,
    /// Seconds of the whole solve (decisions included).
    pub seconds: f64,
}

/// `real.json`.
#[derive(Debug, Serialize)]
struct RealReport {
    /// The working size the photographs were solved at.
    size: String,
    /// The seven-photograph reconstruction's median depth, mm.
    truth_distance_mm: f64,
    rows: Vec<RealRow>,
}

/// Runs the part and writes `real.md` and `real.json`.
pub fn run(args: &BenchArgs) -> Result<()> {
    let face = super::face::face_set(&args.real, args.quick.then_some(QUICK_SIDE))?
        .context("--part real needs the shared face: near_ps_human1/calibration.json is missing")?;
    eprintln!("  photometric stereo of {} photographs", face.images.len());
    let (images, set, prepared, problem, ps) = (
        face.images,
        face.input,
        face.prepared,
        face.problem,
        face.solution,
    );
    let truth = ps.depth.clone();
    let camera = prepared.problem.camera;
    let truth_distance = median_depth(&truth);
    let (w, h) = truth.size();
    // The nearest point of the set's surface: the nose.
    let known = super::face::nearest_point(&truth).context("the set solved no surface")?;
    // The command line's defaults: the albedo decided (`--albedo auto`).
    let params = SolverParams {
        albedo: AlbedoChoice::Auto,
        ..SolverParams::default()
    };
    let mut rows = Vec::new();
    for (k, image) in images.iter().enumerate() {
        let name = stem(image);
        let Some(input) = set.one_of_set(k).filter(|_| wanted(args, &name)) else {
            continue;
        };
        let one = photo::prepare(&input)?;
        let settings: [(&str, DistanceCues); 4] = [
            ("defaults", one.distance_cues()),
            (
                "distance x0.9",
                DistanceCues {
                    distance: Some(0.9 * truth_distance),
                    ..one.distance_cues()
                },
            ),
            (
                "distance x1.1",
                DistanceCues {
                    distance: Some(1.1 * truth_distance),
                    ..one.distance_cues()
                },
            ),
            (
                "known depth",
                DistanceCues {
                    known_depths: vec![known],
                    ..one.distance_cues()
                },
            ),
        ];
        for (setting, cues) in settings {
            let mut problem = one.problem.clone();
            let (row, unit) =
                solved_row(&name, setting, &mut problem, &cues, &params, &truth, camera)?;
            eprintln!(
                "  {name} {setting}: {:.1} deg, distance {:+.0} % ({:?}), {:.1} s",
                row.mean_normal_error_deg,
                100.0 * row.distance_error,
                unit.source,
                row.seconds
            );
            rows.push(row);
        }
    }
    // Renders of the reconstructed face: each LED alone, cast shadows,
    // uniform albedo and the set's; the rig is the camera file's.
    let set_albedo = super::face::relative_albedo(&ps.albedo);
    let rig = prepared.report.rig_lights.clone();
    let domain = truth.map(|z| z.is_finite() && *z > 0.0);
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    for (k, light) in problem.photos.iter().map(|p| &p.light).enumerate() {
        let name = stem(&images[k]);
        if !wanted(args, &format!("render-{name}")) {
            continue;
        }
        let light = PointLight {
            intensity: 1.0,
            ..*light
        };
        let shading = reproject(
            &LightModel::new(1.0, std::slice::from_ref(&light)),
            &geometry,
            &domain,
            &truth,
            Cancel::NEVER,
        )
        .uncancelled();
        let hidden = cast_shadow(&truth, camera, light.position);
        for (albedo_name, albedo) in [("uniform", None), ("set-albedo", Some(&set_albedo))] {
            let lit = Grid::from_fn(w, h, |c, r| {
                if *hidden.at(c, r) || !*domain.at(c, r) {
                    0.0
                } else {
                    shading.at(c, r) * albedo.map_or(1.0, |a| *a.at(c, r))
                }
            });
            let top = lit.as_slice().iter().copied().fold(0.0, f64::max);
            let mut problem = Problem {
                image: lit.map(|v| 0.9 * v / top.max(f64::MIN_POSITIVE)),
                camera,
                intensity_scale: 1.0,
                object_mask: Some(domain.clone()),
                confidence: None,
                lights: vec![light],
            };
            let cues = DistanceCues {
                rig_lights: rig.clone(),
                ..DistanceCues::default()
            };
            let image = format!("render {name} {albedo_name}");
            let (row, _) = solved_row(
                &image,
                "defaults",
                &mut problem,
                &cues,
                &params,
                &truth,
                camera,
            )?;
            eprintln!(
                "  {image}: {:.1} deg, distance {:+.0} %, albedo used {}",
                row.mean_normal_error_deg,
                100.0 * row.distance_error,
                row.albedo_used
            );
            rows.push(row);
        }
    }
    let report = RealReport {
        size: format!("{w}x{h}"),
        truth_distance_mm: truth_distance,
        rows,
    };
    super::markdown::write_part(&args.out, "real", &report, &markdown(&report))?;
    Ok(())
}

/// A file's stem.
fn stem(path: &std::path::Path) -> String {
    path.file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned())
}

/// Solves `problem` with `cues` (single-image method, linearised) and
/// measures the solve against the set's `truth` as the row of `image` at
/// `setting`, its seconds the solve's; the depth unit it decided beside.
fn solved_row(
    image: &str,
    setting: &str,
    problem: &mut Problem,
    cues: &DistanceCues,
    params: &SolverParams,
    truth: &Grid<f64>,
    camera: sfs_core::camera::Intrinsics,
) -> Result<(RealRow, DepthUnit)> {
    let started = Instant::now();
    let (solution, unit) = solve_photograph(problem, params, &Method::Linearised, cues, &mut ())?;
    let seconds = started.elapsed().as_secs_f64();
    let row = row_of(image, setting, truth, &solution, &unit, camera, seconds);
    Ok((row, unit))
}

/// The row of one solve against `truth`.
fn row_of(
    image: &str,
    setting: &str,
    truth: &Grid<f64>,
    solution: &Solution,
    unit: &DepthUnit,
    camera: sfs_core::camera::Intrinsics,
    seconds: f64,
) -> RealRow {
    let comparison = compare_single(truth, &solution.depth, camera);
    let median = median_depth(&solution.depth);
    RealRow {
        image: image.into(),
        setting: setting.into(),
        unit_source: format!("{:?}", unit.source),
        mean_normal_error_deg: comparison
            .as_ref()
            .map_or(f64::NAN, |c| c.mean_normal_angle_deg),
        distance_error: median / median_depth(truth) - 1.0,
        relief: comparison
            .as_ref()
            .map_or(f64::NAN, |c| c.single_depth_range / median),
        true_relief: comparison
            .as_ref()
            .map_or(f64::NAN, |c| c.set_depth_range / median_depth(truth)),
        albedo_used: solution.albedo_fit.as_ref().is_some_and(|f| f.used),
        seconds,
    }
}

/// The report as markdown: one table per setting, and the means.
fn markdown(report: &RealReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# The shared face at the defaults\n\nEach photograph solved alone at {} against the \
         tool's photometric-stereo result from all seven (median depth {:.0} mm). `defaults`: \
         the README's command, nothing added; `distance x0.9`/`x1.1`: `--distance` 10 % short \
         of / beyond the truth; `known depth`: `--known-depth` at the nose. Renders: the \
         reconstructed face lit by each LED with cast shadows, solved at the defaults.\n",
        report.size, report.truth_distance_mm
    );
    table(
        &mut md,
        "| image | setting | unit from | mean normal error (deg) | distance error | relief \
         (truth) | albedo used | seconds |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {:.1} | {:+.0} % | {:.3} ({:.3}) | {} | {:.1} |",
                r.image,
                r.setting,
                r.unit_source,
                r.mean_normal_error_deg,
                100.0 * r.distance_error,
                r.relief,
                r.true_relief,
                if r.albedo_used { "yes" } else { "no" },
                r.seconds
            )
        },
    );
    let _ = writeln!(
        md,
        "\n| group | mean normal error (deg) | worst | mean distance error | worst |\n| --- | \
         --- | --- | --- | --- |"
    );
    let mut groups: Vec<(String, Vec<&RealRow>)> = Vec::new();
    for r in &report.rows {
        let group = if r.image.starts_with("render") {
            format!(
                "renders, {}",
                r.image.rsplit_once(' ').map_or("", |(_, a)| a)
            )
        } else {
            format!("photographs, {}", r.setting)
        };
        match groups.iter_mut().find(|(g, _)| *g == group) {
            Some((_, rows)) => rows.push(r),
            None => groups.push((group, vec![r])),
        }
    }
    for (group, rows) in groups {
        let n = rows.len().max(1) as f64;
        let mean = rows.iter().map(|r| r.mean_normal_error_deg).sum::<f64>() / n;
        let worst = rows
            .iter()
            .map(|r| r.mean_normal_error_deg)
            .fold(0.0, f64::max);
        let mean_d = rows.iter().map(|r| r.distance_error.abs()).sum::<f64>() / n;
        let worst_d = rows
            .iter()
            .map(|r| r.distance_error.abs())
            .fold(0.0, f64::max);
        let _ = writeln!(
            md,
            "| {group} | {mean:.1} | {worst:.1} | {:.0} % | {:.0} % |",
            100.0 * mean_d,
            100.0 * worst_d
        );
    }
    md
}
