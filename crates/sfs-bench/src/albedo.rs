//! `sfs-bench --part albedo`: shape and albedo from one photograph. Each scene
//! (Sombrero, Bunny, Dragon, Suzanne; 256 px, Suzanne twice as wide; quick:
//! 64 px) is rendered with the light at the optical centre and with a flash
//! beside the lens, times each albedo pattern of `synth --ps-leds`
//! (uniform, patches, lines, smooth; normalised to a maximum of 1), clean
//! and at noise sigma 5. Each is solved at the defaults with albedo 1, with
//! `--albedo auto`, with the true albedo divided out, and with the true
//! albedo 3 % off per cell (how exactly a given albedo must be known); the
//! columns are the four RSEs, whether auto used its estimate (and the
//! misfit ratio that decided), the albedo's median error
//! (`scene::photometric::albedo_error`, up to one scale) and auto's
//! seconds. With the shared photographs, each LED's photograph alone at
//! half size (its scale from the nose's distance in the seven-photo
//! photometric-stereo depth) with albedo 1, auto and the set's albedo
//! given, each against the set (mean normal angle, depth range), and the
//! pictures `albedo-face-*.png`. Writes `albedo.md` and `albedo.json`.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;

use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::light::PointLight;
use sfs_core::metrics;
use sfs_core::params::{AlbedoChoice, SolverParams};
use sfs_core::photo;
use sfs_core::scene::Scene;
use sfs_core::scene::photometric::{albedo_error, albedo_pattern, albedo_with_cell_error};
use sfs_core::solver::albedo_fit::divide_out;
use sfs_core::solver::calibrate::solve_with_known_depths;
use sfs_core::solver::photometric::{SingleComparison, compare_single};
use sfs_core::solver::{Method, Problem, Solution, solve};

use super::lights::render;
use super::scenes::{noisy, or_skip, problem, timed_solve};
use super::shared::{BenchArgs, wanted, wanted_renders};

/// Seed of the true albedo's cell errors.
const SEED: u64 = 1;
/// The noise of the noisy rows, on the 0..255 scale.
const NOISE: f64 = 5.0;
/// The log standard deviation of the per-cell error of the true albedo's
/// second solve (3 %).
const CELL_ERROR: f64 = 0.03;
/// The draws of that error whose median RSE is reported.
const CELL_ERROR_DRAWS: u64 = 3;
/// The cells per side of that error (the `patches` pattern's).
const ERROR_CELLS: usize = 5;
/// The albedo patterns.
const PATTERNS: [&str; 4] = ["uniform", "patches", "lines", "smooth"];

/// One render solved three ways.
#[derive(Clone, Debug, Serialize)]
pub struct AlbedoRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// `centred` or `beside`.
    pub light: String,
    /// The albedo pattern.
    pub pattern: String,
    /// Noise sigma on the 0..255 scale.
    pub noise: f64,
    /// RSE with albedo 1.
    pub rse_one: f64,
    /// RSE with `--albedo auto`.
    pub rse_auto: f64,
    /// RSE with the true albedo divided out.
    pub rse_true: f64,
    /// RSE with the true albedo divided out, each of its 5x5 cells of the
    /// image plane off by its own factor (log standard deviation
    /// [`CELL_ERROR`]; the median over [`CELL_ERROR_DRAWS`] draws): how
    /// exactly a given albedo must be known.
    pub rse_true_cell_error: f64,
    /// Whether auto used its estimate.
    pub auto_used: bool,
    /// The estimate's misfit over albedo 1's (NaN: no edge found).
    pub misfit_ratio: f64,
    /// Whether the decision was a close call (within
    /// `albedo_fit::CLOSE_MARGIN` of its bar).
    pub close_call: bool,
    /// Median relative error of auto's albedo (the estimate when used,
    /// else 1) against the truth, up to one scale.
    pub albedo_error: f64,
    /// The same of albedo 1.
    pub albedo_error_one: f64,
    /// Seconds of the auto solve.
    pub seconds: f64,
}

/// One photograph of the face alone against the seven photographs.
#[derive(Clone, Debug, Serialize)]
pub struct FaceAlbedoRow {
    /// The photograph's file stem (`led4`).
    pub photograph: String,
    /// `albedo 1`, `auto` or `the set's albedo given`.
    pub albedo: String,
    /// Whether auto used its estimate (auto only).
    pub auto_used: Option<bool>,
    /// The comparison with the set's depth.
    pub comparison: Option<SingleComparison>,
    /// Seconds of the solve (its known-depth search included).
    pub seconds: f64,
}

/// The part's report.
#[derive(Clone, Debug, Serialize)]
pub struct AlbedoReport {
    /// The command line.
    pub command: String,
    /// The renders.
    pub rows: Vec<AlbedoRow>,
    /// The shared face (empty when its photographs are missing).
    pub face: Vec<FaceAlbedoRow>,
    /// Scenes that could not be rendered.
    pub skipped: Vec<String>,
}

/// The lights of the two set-ups, in units of the scene.
fn setups() -> [(&'static str, Vec<PointLight>); 2] {
    [
        ("centred", Vec::new()),
        (
            "beside",
            vec![PointLight {
                position: [0.3, 0.0, 0.0],
                direction: None,
                mu: 0.0,
                intensity: 1.0,
            }],
        ),
    ]
}

/// A problem of `scene` with `image` under `lights`.
fn problem_of(scene: &Scene, image: Grid<f64>, lights: &[PointLight]) -> Problem {
    Problem {
        lights: lights.to_vec(),
        ..problem(scene, image)
    }
}

/// The albedo a solve used (auto's estimate when used, else 1), NaN off
/// its surface.
fn albedo_used(solution: &Solution) -> Grid<f64> {
    match &solution.albedo_fit {
        Some(fit) => fit.used_albedo(&solution.depth),
        None => solution
            .depth
            .map(|z| if z.is_finite() { 1.0 } else { f64::NAN }),
    }
}

/// Runs the part and writes `albedo.md` and `albedo.json`.
pub fn run(args: &BenchArgs) -> Result<()> {
    let side = if args.quick { 64 } else { 256 };
    let auto = SolverParams {
        albedo: AlbedoChoice::Auto,
        ..SolverParams::default()
    };
    let one = SolverParams::default();
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for name in wanted_renders(args) {
        for (light, lights) in setups() {
            // The first failure skips the scene: each name is added once.
            let scene = render(name, &args.meshes, side, &lights);
            let Some(scene) = or_skip(name, scene, &mut skipped)? else {
                break;
            };
            let (w, h) = scene.image.size();
            let mut clean_cell_error = None;
            for pattern in PATTERNS {
                let truth = if pattern == "uniform" {
                    Grid::filled(w, h, 1.0)
                } else {
                    albedo_pattern(w, h, pattern)
                };
                let top = truth.as_slice().iter().copied().fold(0.0, f64::max);
                let truth = truth.map(|a| a / top);
                let clean = scene.image.zip_map(&truth, |i, a| i * a);
                for noise in [0.0, NOISE] {
                    let image = noisy(&clean, noise);
                    let divided = image.zip_map(&truth, |i, a| i / a);
                    let rse = |solution: &Solution| metrics::rse(&solution.depth, &scene.depth_gt);
                    let plain = solve(&problem_of(&scene, image.clone(), &lights), &one, &mut ())?;
                    let (estimated, seconds) =
                        timed_solve(&problem_of(&scene, image.clone(), &lights), &auto, name)?;
                    let given = solve(&problem_of(&scene, divided, &lights), &one, &mut ())?;
                    // Divided by the truth, a clean render is the uniform
                    // render whatever the pattern: its error is solved once.
                    let rse_true_cell_error = match clean_cell_error {
                        Some(known) if noise == 0.0 => known,
                        _ => {
                            let found = cell_error_rse(&scene, &image, &truth, &lights, &one)?;
                            if noise == 0.0 {
                                clean_cell_error = Some(found);
                            }
                            found
                        }
                    };
                    let fit = estimated.albedo_fit.as_ref();
                    let row = AlbedoRow {
                        scene: name.into(),
                        size: format!("{w}x{h}"),
                        light: light.into(),
                        pattern: pattern.into(),
                        noise,
                        rse_one: rse(&plain)?,
                        rse_auto: rse(&estimated)?,
                        rse_true: rse(&given)?,
                        rse_true_cell_error,
                        auto_used: fit.is_some_and(|f| f.used),
                        misfit_ratio: fit.map_or(f64::NAN, |f| f.misfit_ratio),
                        close_call: fit.is_some_and(|f| f.is_close_call()),
                        albedo_error: albedo_error(
                            &albedo_used(&estimated),
                            &truth,
                            &scene.object_mask,
                        ),
                        albedo_error_one: albedo_error(
                            &Grid::filled(w, h, 1.0),
                            &truth,
                            &scene.object_mask,
                        ),
                        seconds,
                    };
                    eprintln!(
                        "  {name} {light} {pattern} sigma {noise}: RSE albedo 1 {:.4}, auto {:.4}{}, true {:.4}, misfit x{:.2}",
                        row.rse_one,
                        row.rse_auto,
                        if row.auto_used { " (used)" } else { "" },
                        row.rse_true,
                        row.misfit_ratio
                    );
                    rows.push(row);
                }
            }
        }
    }
    let face = if wanted(args, "face") && !args.quick {
        face(args)?
    } else {
        Vec::new()
    };
    let report = AlbedoReport {
        command: super::shared::command_line(),
        rows,
        face,
        skipped,
    };
    super::markdown::write_part(&args.out, "albedo", &report, &markdown(&report))?;
    Ok(())
}

/// The median RSE over [`CELL_ERROR_DRAWS`] draws of `image` of `scene`
/// divided by `truth` with a per-cell error ([`CELL_ERROR`]), solved with
/// `params`.
fn cell_error_rse(
    scene: &Scene,
    image: &Grid<f64>,
    truth: &Grid<f64>,
    lights: &[PointLight],
    params: &SolverParams,
) -> Result<f64> {
    let mut rses = Vec::new();
    for draw in 0..CELL_ERROR_DRAWS {
        let off = albedo_with_cell_error(truth, ERROR_CELLS, CELL_ERROR, SEED + draw);
        let divided = image.zip_map(&off, |i, a| i / a);
        let solution = solve(&problem_of(scene, divided, lights), params, &mut ())?;
        rses.push(metrics::rse(&solution.depth, &scene.depth_gt)?);
    }
    rses.sort_by(f64::total_cmp);
    Ok(rses[rses.len() / 2])
}

/// The working size of the face's solves (half the photographs' width).
const FACE_SIDE: usize = 648;

/// Each photograph of the set alone with albedo 1, auto and the set's
/// albedo, each scaled by the nose's distance in the seven-photo depth,
/// against that depth.
fn face(args: &BenchArgs) -> Result<Vec<FaceAlbedoRow>> {
    let Some(face) = super::face::face_set(&args.real, Some(FACE_SIDE))? else {
        return Ok(Vec::new());
    };
    let (images, set, prepared, ps) = (face.images, face.input, face.prepared, face.solution);
    // The nearest point of the set's surface: the nose.
    let Some(nose) = super::face::nearest_point(&ps.depth) else {
        return Ok(Vec::new());
    };
    let known = [nose];
    let set_albedo = super::face::relative_albedo(&ps.albedo);
    io::write_png16(&args.out.join("albedo-face-set.png"), &set_albedo)?;
    let mut rows = Vec::new();
    for (k, image) in images.iter().enumerate() {
        let Some(input) = set.one_of_set(k) else {
            continue;
        };
        let name = image
            .file_stem()
            .map_or_else(|| format!("{k}"), |s| s.to_string_lossy().into_owned());
        let one = photo::prepare(&input)?;
        for (label, params, albedo) in [
            ("albedo 1", SolverParams::default(), None),
            (
                "auto",
                SolverParams {
                    albedo: AlbedoChoice::Auto,
                    ..SolverParams::default()
                },
                None,
            ),
            (
                "the set's albedo given",
                SolverParams::default(),
                Some(&set_albedo),
            ),
        ] {
            // Divided out (the known distance searches the scale).
            let mut problem = match albedo {
                Some(albedo) => divide_out(&one.problem, albedo).0,
                None => one.problem.clone(),
            };
            let started = Instant::now();
            let (solution, _) = solve_with_known_depths(
                &mut problem,
                &params,
                &Method::Linearised,
                &known,
                &mut (),
            )?;
            let seconds = started.elapsed().as_secs_f64();
            if label == "auto" {
                // White off the surface, as the set's picture.
                let used = albedo_used(&solution).map(|a| if a.is_finite() { *a } else { 1.0 });
                io::write_png16(
                    &args.out.join(format!("albedo-face-auto-{name}.png")),
                    &used,
                )?;
            }
            let row = FaceAlbedoRow {
                photograph: name.clone(),
                albedo: label.into(),
                auto_used: (label == "auto")
                    .then(|| solution.albedo_fit.as_ref().is_some_and(|f| f.used)),
                comparison: compare_single(&ps.depth, &solution.depth, prepared.problem.camera),
                seconds,
            };
            eprintln!(
                "  face {name} {label}: {:.1} deg",
                row.comparison
                    .as_ref()
                    .map_or(f64::NAN, |c| c.mean_normal_angle_deg)
            );
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The report as markdown.
fn markdown(report: &AlbedoReport) -> String {
    let mut md = super::markdown::markdown_head("Albedo from one photograph", &report.command);
    super::markdown::table(
        &mut md,
        &format!(
            "| scene | size | light | albedo | noise | RSE albedo 1 | RSE auto | RSE true albedo | \
             RSE true albedo, 3 % off per cell | auto used (misfit ratio; close: within {} of the \
             bar) | albedo error auto / 1 | auto s |",
            sfs_core::solver::albedo_fit::CLOSE_MARGIN
        ),
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {} ({:.2}{}) | {:.3} / {:.3} | {:.2} |",
                r.scene,
                r.size,
                r.light,
                r.pattern,
                r.noise,
                r.rse_one,
                r.rse_auto,
                r.rse_true,
                r.rse_true_cell_error,
                if r.auto_used { "yes" } else { "no" },
                r.misfit_ratio,
                if r.close_call { ", close" } else { "" },
                r.albedo_error,
                r.albedo_error_one,
                r.seconds
            )
        },
    );
    if !report.face.is_empty() {
        let _ = writeln!(
            md,
            "\n## The shared face: each photograph alone against the seven\n"
        );
        super::markdown::table(
            &mut md,
            "| photograph | albedo | auto used | mean / median normal angle (deg) | \
             depth range single / set | s |",
            &report.face,
            |f| {
                let (angles, ranges) =
                    f.comparison
                        .as_ref()
                        .map_or(("-".to_string(), "-".to_string()), |c| {
                            (
                                format!(
                                    "{:.1} / {:.1}",
                                    c.mean_normal_angle_deg, c.median_normal_angle_deg
                                ),
                                format!("{:.1} / {:.1}", c.single_depth_range, c.set_depth_range),
                            )
                        });
                format!(
                    "| {} | {} | {} | {angles} | {ranges} | {:.1} |",
                    f.photograph,
                    f.albedo,
                    f.auto_used.map_or("-", |u| if u { "yes" } else { "no" }),
                    f.seconds
                )
            },
        );
        let _ = writeln!(
            md,
            "\nMean over the photographs of the mean normal angle:\n"
        );
        for label in ["albedo 1", "auto", "the set's albedo given"] {
            let angles: Vec<f64> = report
                .face
                .iter()
                .filter(|f| f.albedo == label)
                .filter_map(|f| f.comparison.as_ref().map(|c| c.mean_normal_angle_deg))
                .collect();
            if !angles.is_empty() {
                let _ = writeln!(
                    md,
                    "- {label}: {:.1} deg over {}",
                    angles.iter().sum::<f64>() / angles.len() as f64,
                    angles.len()
                );
            }
        }
    }
    super::markdown::skipped_meshes(&mut md, &report.skipped);
    md
}
