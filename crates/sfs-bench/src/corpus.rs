//! `sfs-bench --part corpus`: the rates of the tool's automatic decisions (the
//! depth unit and the albedo) over a randomized corpus of uniform-albedo
//! renders: the Sombrero, the three meshes and the shared face's shape
//! (the tool's own seven-photograph reconstruction, shaded as a depth map),
//! at random sizes, lit from the optical centre, by a flash beside the
//! lens, or by one LED of a rig of aimed LEDs (aimed at the object with
//! random errors), with and without cast shadows, with and without noise.
//! Each is solved at the defaults (the depth unit and the albedo decided
//! by the tool; the rig listed as a camera file lists it) and with
//! `--albedo 1`. A textured share (patch and line albedos) shows what the
//! albedo decision gains. A second draw scores the start's denoising
//! (`corpus_denoise`). Writes corpus.md and corpus.json.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use glam::DVec3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use sfs_core::camera::Intrinsics;
use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::light::{LightModel, PointLight};
use sfs_core::model::{LevelGeometry, reproject};
use sfs_core::params::{AlbedoChoice, SolverParams};
use sfs_core::scene::photometric::{albedo_pattern, led_ring};
use sfs_core::scene::{self, Scene};
use sfs_core::solver::calibrate::median_depth;
use sfs_core::solver::depth_unit::{DistanceCues, UnitSource, solve_photograph};
use sfs_core::solver::photometric::compare_single;
use sfs_core::solver::{Method, Problem};

use super::shared::BenchArgs;

/// Renders in the corpus (uniform albedo), and textured ones beside.
const CASES: usize = 120;
const TEXTURED: usize = 30;
/// With `--quick`.
const QUICK_CASES: usize = 30;
const QUICK_TEXTURED: usize = 8;
/// The depth unit is right within this (relative) of the true distance.
const UNIT_TOLERANCE: f64 = 0.25;
/// The defaults are "as albedo 1" within this normal error (degrees) or
/// this share of RSE.
const SAME_DEG: f64 = 1.0;
const SAME_RSE: f64 = 0.05;

/// One render of the corpus.
#[derive(Clone, Debug, Serialize)]
pub struct CorpusRow {
    /// Case number (its seed).
    pub case: usize,
    /// Scene name.
    pub scene: String,
    /// Image size.
    pub size: String,
    /// `centred`, `flash` or `rig of N`.
    pub light: String,
    /// Cast shadows rendered.
    pub shadows: bool,
    /// Noise sigma on the 8-bit scale.
    pub noise: f64,
    /// `uniform`, `patches` or `lines`.
    pub albedo: String,
    /// Which cue set the depth unit at the defaults.
    pub unit_source: String,
    /// Solved median depth over the true one, minus 1 (NaN with a centred
    /// light: its unit is the intensity scale's).
    pub distance_error: f64,
    /// Whether the albedo decision used its estimate.
    pub albedo_used: bool,
    /// The decision's misfit ratio (NaN when none).
    pub misfit_ratio: f64,
    /// Mean normal error at the defaults and with `--albedo 1`, degrees.
    pub normal_error_deg: f64,
    pub normal_error_one_deg: f64,
    /// RSE after the best depth factor, at the defaults and with albedo 1.
    pub rse: f64,
    pub rse_one: f64,
    /// The decision's raw sums (absent when nothing was compared).
    pub evidence: Option<sfs_core::solver::albedo_fit::Evidence>,
}

/// `corpus.json`.
#[derive(Debug, Serialize)]
struct CorpusReport {
    /// The draw (`--seed`, 0 by default).
    seed: u64,
    /// The image sides drawn from (`--corpus-sides`).
    sides: Vec<usize>,
    rows: Vec<CorpusRow>,
    /// The start's denoising decision (`corpus_denoise`).
    start_denoise: Vec<super::corpus_denoise::DenoiseRow>,
    skipped: Vec<String>,
}

/// The scenes a case is drawn from.
const SCENES: [&str; 5] = ["sombrero", "bunny", "dragon", "suzanne", "face"];

/// Runs the part and writes `corpus.md` and `corpus.json`.
pub fn run(args: &BenchArgs) -> Result<()> {
    let (cases, textured) = if args.quick {
        (QUICK_CASES, QUICK_TEXTURED)
    } else {
        (CASES, TEXTURED)
    };
    if args.corpus_sides.is_empty() || args.corpus_sides.contains(&0) {
        anyhow::bail!("--corpus-sides: give one or more positive image sides, as 32,64");
    }
    let face = face_depth(&args.real).ok();
    let mut skipped = Vec::new();
    if face.is_none() {
        skipped.push("face (the shared photographs are missing)".to_owned());
    }
    let mut rows = Vec::new();
    for case in 0..cases + textured {
        // Seed 0 is the historical draw (case k seeded by k).
        let draw = args.seed.unwrap_or(0);
        let mut rng = StdRng::seed_from_u64(draw.wrapping_mul(1_000_003).wrapping_add(case as u64));
        let name = SCENES[rng.random_range(0..SCENES.len())];
        let side = args.corpus_sides[rng.random_range(0..args.corpus_sides.len())];
        let albedo = if case < cases {
            "uniform"
        } else if case % 2 == 0 {
            "patches"
        } else {
            "lines"
        };
        let row = match one_case(args, face.as_ref(), case, name, side, albedo, &mut rng) {
            Ok(row) => row,
            Err(e) => {
                let why = format!("case {case} ({name}): {e:#}");
                eprintln!("  skipped {why}");
                skipped.push(why);
                continue;
            }
        };
        eprintln!(
            "  {case} {} {} {} shadows {} noise {} {}: unit {} {:+.0} %, albedo {} {:.1} / {:.1} deg",
            row.scene,
            row.size,
            row.light,
            row.shadows,
            row.noise,
            row.albedo,
            row.unit_source,
            100.0 * row.distance_error,
            if row.albedo_used { "used" } else { "1" },
            row.normal_error_deg,
            row.normal_error_one_deg
        );
        rows.push(row);
    }
    let scenes: Vec<&str> = SCENES
        .iter()
        .copied()
        .filter(|&name| name != "face" || face.is_some())
        .collect();
    let start_denoise = super::corpus_denoise::run(
        args,
        &|name, side, lights| render(args, face.as_ref(), name, side, lights),
        &scenes,
        &mut skipped,
    );
    let report = CorpusReport {
        seed: args.seed.unwrap_or(0),
        sides: args.corpus_sides.clone(),
        rows,
        start_denoise,
        skipped,
    };
    sfs_core::io::write_json(&args.out.join("corpus.json"), &report)?;
    std::fs::write(args.out.join("corpus.md"), markdown(&report))
        .with_context(|| format!("cannot write {}", args.out.join("corpus.md").display()))?;
    Ok(())
}

/// The face's shape: the seven photographs' reconstruction at 256 px, in
/// millimetres, with its camera (NaN off the face).
fn face_depth(real: &Path) -> Result<(Grid<f64>, Intrinsics)> {
    let face =
        super::face::face_set(real, Some(256))?.context("the shared photographs are missing")?;
    Ok((face.solution.depth, face.prepared.problem.camera))
}

/// A scene of the face's shape under `lights`, shaded as a depth map
/// (brightest pixel 0.9), at its own 256 px.
fn face_scene(depth: &Grid<f64>, camera: Intrinsics, lights: &[PointLight]) -> Result<Scene> {
    let (w, h) = depth.size();
    let domain = depth.map(|z| z.is_finite() && *z > 0.0);
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let shading = reproject(
        &LightModel::new(1.0, lights),
        &geometry,
        &domain,
        depth,
        Cancel::NEVER,
    )
    .uncancelled();
    let top = shading.as_slice().iter().copied().fold(0.0, f64::max);
    anyhow::ensure!(top > 0.0, "the face is unlit");
    Ok(Scene {
        name: "face".into(),
        camera,
        intensity_scale: 0.9 / top,
        image: shading.map(|v| 0.9 * v / top),
        depth_gt: depth.clone(),
        object_mask: domain,
        normals: None,
        lights: lights.to_vec(),
        material: sfs_core::material::Material::Lambert,
    })
}

/// One case: render, solve at the defaults and with albedo 1, measure.
fn one_case(
    args: &BenchArgs,
    face: Option<&(Grid<f64>, Intrinsics)>,
    case: usize,
    name: &str,
    side: usize,
    albedo: &str,
    rng: &mut StdRng,
) -> Result<CorpusRow> {
    // The object's centre and distance, from an unlit render.
    let probe = render(args, face, name, side, &[])?;
    let distance = median_depth(&probe.depth_gt);
    let (w, h) = probe.depth_gt.size();
    let centre = centre_of(&probe);
    let kind = rng.random_range(0..4);
    let (light, lights, rig): (String, Vec<PointLight>, Vec<PointLight>) = match kind {
        0 => ("centred".into(), Vec::new(), Vec::new()),
        1 => {
            // A flash beside the lens: 3-20 % of the distance off the axis.
            let off = distance * rng.random_range(0.03..0.2);
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            let flash = PointLight {
                position: [off * angle.cos(), off * angle.sin(), 0.0],
                ..PointLight::CENTRED
            };
            ("flash".into(), vec![flash], Vec::new())
        }
        _ => {
            // A rig of 3-8 LEDs between the camera and the object, aimed at
            // the object's centre with an error of up to 15 % of the
            // distance; the photograph lit by one of them.
            let count = rng.random_range(3..=8);
            let ring_distance = rng.random_range(0.4..0.8) * centre.length();
            let angles: Vec<f64> = (0..count).map(|_| rng.random_range(10.0..45.0)).collect();
            let aimed = led_ring(count, centre.to_array(), ring_distance, &angles, 1.0);
            let rig: Vec<PointLight> = aimed
                .iter()
                .map(|l| {
                    let error = DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ) * 0.15
                        * distance
                        / 3f64.sqrt();
                    let at = centre + error;
                    let position = DVec3::from_array(l.position);
                    PointLight {
                        direction: Some((at - position).normalize().to_array()),
                        ..*l
                    }
                })
                .collect();
            let on = rig[rng.random_range(0..count)];
            (format!("rig of {count}"), vec![on], rig)
        }
    };
    let shadows = !lights.is_empty() && rng.random_bool(0.5);
    let noise = [0.0, 0.0, 2.0, 5.0, 10.0][rng.random_range(0..5)];
    let rendered = if shadows {
        scene::shadow::with_cast_shadows(|l| render(args, face, name, side, l), &lights)?.0
    } else {
        render(args, face, name, side, &lights)?
    };
    let truth_albedo = match albedo {
        "uniform" => Grid::filled(w, h, 1.0),
        pattern => albedo_pattern(w, h, pattern),
    };
    let clean = rendered.image.zip_map(&truth_albedo, |i, a| i * a);
    let draw = args.seed.unwrap_or(0);
    let image = if noise > 0.0 {
        scene::add_noise(
            &clean,
            noise,
            draw.wrapping_mul(1_000_003).wrapping_add(case as u64),
        )
    } else {
        clean
    };
    let problem = Problem {
        image,
        camera: rendered.camera,
        intensity_scale: if lights.is_empty() {
            rendered.intensity_scale
        } else {
            1.0
        },
        object_mask: Some(rendered.object_mask.clone()),
        confidence: None,
        lights: lights.clone(),
    };
    let cues = DistanceCues {
        rig_lights: rig,
        ..DistanceCues::default()
    };
    let defaults = SolverParams {
        albedo: AlbedoChoice::Auto,
        ..SolverParams::default()
    };
    let one = SolverParams {
        albedo: AlbedoChoice::One,
        ..SolverParams::default()
    };
    let mut p = problem.clone();
    let (solved, unit) = solve_photograph(&mut p, &defaults, &Method::Linearised, &cues, &mut ())?;
    let mut p = problem;
    let (solved_one, _) = solve_photograph(&mut p, &one, &Method::Linearised, &cues, &mut ())?;
    let compare = |depth: &Grid<f64>| {
        compare_single(&rendered.depth_gt, depth, rendered.camera)
            .map_or((f64::NAN, f64::NAN), |c| {
                (c.mean_normal_angle_deg, c.rse_to_set_scaled)
            })
    };
    let (normal_error_deg, rse) = compare(&solved.depth);
    let (normal_error_one_deg, rse_one) = compare(&solved_one.depth);
    let distance_error = if unit.source == UnitSource::CentredLight {
        f64::NAN
    } else {
        median_depth(&solved.depth) / distance - 1.0
    };
    Ok(CorpusRow {
        case,
        scene: name.into(),
        size: format!("{w}x{h}"),
        light,
        shadows,
        noise,
        albedo: albedo.into(),
        unit_source: format!("{:?}", unit.source),
        distance_error,
        albedo_used: solved.albedo_fit.as_ref().is_some_and(|f| f.used),
        misfit_ratio: solved
            .albedo_fit
            .as_ref()
            .map_or(f64::NAN, |f| f.misfit_ratio),
        evidence: solved.albedo_fit.as_ref().map(|f| f.evidence),
        normal_error_deg,
        normal_error_one_deg,
        rse,
        rse_one,
    })
}

/// The scene `name` at `side` under `lights`.
fn render(
    args: &BenchArgs,
    face: Option<&(Grid<f64>, Intrinsics)>,
    name: &str,
    side: usize,
    lights: &[PointLight],
) -> Result<Scene> {
    if name == "face" {
        let (depth, camera) = face.context("the face's shape is missing")?;
        let (w, h) = depth.size();
        let (sw, sh) = if w >= h {
            (side, (side * h).div_ceil(w))
        } else {
            ((side * w).div_ceil(h), side)
        };
        let small = sfs_core::resample::resize_area(depth, sw, sh, Cancel::NEVER).uncancelled();
        let camera = sfs_core::resample::scale_intrinsics(*camera, (w, h), (sw, sh));
        return face_scene(&small, camera, lights);
    }
    super::lights::render(name, &args.meshes, side, lights)
}

/// The object's centre in the camera frame: its median depth on the ray
/// through the mean object pixel.
fn centre_of(scene: &Scene) -> DVec3 {
    let (w, h) = scene.depth_gt.size();
    let (mut sum_c, mut sum_r, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for r in 0..h {
        for c in 0..w {
            if scene.depth_gt.at(c, r).is_finite() {
                sum_c += c as f64;
                sum_r += r as f64;
                n += 1.0;
            }
        }
    }
    let z = median_depth(&scene.depth_gt);
    let (x, y) = scene
        .camera
        .image_xy(sum_c / n.max(1.0), sum_r / n.max(1.0));
    DVec3::from_array(scene.camera.back_project(x, y, z))
}

/// The report: rates first, then every case.
fn markdown(report: &CorpusReport) -> String {
    let mut md = String::new();
    let uniform: Vec<&CorpusRow> = report
        .rows
        .iter()
        .filter(|r| r.albedo == "uniform")
        .collect();
    let textured: Vec<&CorpusRow> = report
        .rows
        .iter()
        .filter(|r| r.albedo != "uniform")
        .collect();
    let rate = |rows: &[&CorpusRow], f: &dyn Fn(&CorpusRow) -> bool| {
        let n = rows.iter().filter(|r| f(r)).count();
        format!(
            "{n} of {} ({:.1} %)",
            rows.len(),
            100.0 * n as f64 / rows.len().max(1) as f64
        )
    };
    let same = |r: &CorpusRow| {
        (r.normal_error_deg - r.normal_error_one_deg).abs() <= SAME_DEG
            || (r.rse / r.rse_one - 1.0).abs() <= SAME_RSE
    };
    let _ = writeln!(
        md,
        "# The automatic decisions over a randomized corpus\n\n{} uniform-albedo renders and {} \
         textured ones (draw {}, `--seed`; scenes, sides {:?} px, lights centred / a flash beside \
         the lens / one LED of an aimed rig, cast shadows, noise 0-10 of 255), each solved at the \
         defaults and with `--albedo 1`.\n",
        uniform.len(),
        textured.len(),
        report.seed,
        report.sides,
    );
    let _ = writeln!(md, "## The albedo decision on uniform albedo\n");
    let _ = writeln!(
        md,
        "- false positives (the estimate used): {}",
        rate(&uniform, &|r| r.albedo_used)
    );
    let _ = writeln!(
        md,
        "- the defaults as `--albedo 1` (within {SAME_DEG} deg or {:.0} % RSE): {}",
        100.0 * SAME_RSE,
        rate(&uniform, &same)
    );
    let _ = writeln!(md, "\n## The albedo decision on textured albedo\n");
    let _ = writeln!(
        md,
        "- the estimate used: {}",
        rate(&textured, &|r| r.albedo_used)
    );
    let mean = |rows: &[&CorpusRow], f: &dyn Fn(&CorpusRow) -> f64| {
        rows.iter().map(|r| f(r)).sum::<f64>() / rows.len().max(1) as f64
    };
    let _ = writeln!(
        md,
        "- mean normal error: {:.2} deg at the defaults, {:.2} with albedo 1",
        mean(&textured, &|r| r.normal_error_deg),
        mean(&textured, &|r| r.normal_error_one_deg)
    );
    let _ = writeln!(md, "\n## The depth unit (lights off the centre)\n");
    let mut sources: Vec<String> = report
        .rows
        .iter()
        .filter(|r| r.distance_error.is_finite())
        .map(|r| r.unit_source.clone())
        .collect();
    sources.sort();
    sources.dedup();
    let _ = writeln!(
        md,
        "| unit from | renders | within {:.0} % | median abs error |\n| --- | --- | --- | --- |",
        100.0 * UNIT_TOLERANCE
    );
    for source in sources {
        let rows: Vec<&CorpusRow> = report
            .rows
            .iter()
            .filter(|r| r.distance_error.is_finite() && r.unit_source == source)
            .collect();
        let mut errors: Vec<f64> = rows.iter().map(|r| r.distance_error.abs()).collect();
        errors.sort_by(f64::total_cmp);
        let _ = writeln!(
            md,
            "| {source} | {} | {} | {:.0} % |",
            rows.len(),
            rate(&rows, &|r| r.distance_error.abs() <= UNIT_TOLERANCE),
            100.0 * errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN)
        );
    }
    super::corpus_denoise::markdown(&report.start_denoise, &mut md);
    let _ = writeln!(
        md,
        "\n## Every case of the albedo and depth-unit corpus\n\n| case | scene | size | light | shadows | noise | albedo | unit from | \
         distance error | albedo used | normal error (deg) | albedo 1 (deg) | RSE | albedo 1 \
         |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in &report.rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {:+.0} % | {} | {:.2} | {:.2} | {:.4} | \
             {:.4} |",
            r.case,
            r.scene,
            r.size,
            r.light,
            if r.shadows { "yes" } else { "no" },
            r.noise,
            r.albedo,
            r.unit_source,
            100.0 * r.distance_error,
            if r.albedo_used { "yes" } else { "no" },
            r.normal_error_deg,
            r.normal_error_one_deg,
            r.rse,
            r.rse_one
        );
    }
    if !report.skipped.is_empty() {
        let _ = writeln!(md, "\nSkipped: {}", report.skipped.join("; "));
    }
    md
}
