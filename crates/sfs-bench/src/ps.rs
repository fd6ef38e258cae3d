//! `sfs-bench --part ps`: near-light photometric stereo at the defaults. Renders
//! (the Sombrero and the meshes, a patch albedo painted on, 3, 4 and 8 LEDs
//! 10 to 45 degrees off the line to the object with mu = 1, cast shadows,
//! noise sigma 0 and 5) measured against their truth; the invariances
//! (exposure of every photograph, the depth unit); and the shared face (its
//! seven photographs, ambient subtracted, through the photo pipeline) with
//! its pictures, depth range and one LED's single-image solve compared.
//! Writes ps.md, ps.json and face-*.png.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::io;
use sfs_core::light::PointLight;
use sfs_core::metrics;
use sfs_core::photo::{self, PhotoInput};
use sfs_core::scene::photometric::{
    PhotometricSet, albedo_error, albedo_pattern, mean_angle_deg, render_set, standard_leds,
};
use sfs_core::scene::{Scene, add_noise, mesh, sombrero::sombrero_lit};
use sfs_core::solver::photometric::{
    PhotometricParams, PhotometricProblem, PhotometricSolution, SetPhoto, compare_single,
    depth_range, positive_quantile, solve_photometric,
};

use super::markdown::{table, titled_table};
use super::shared::{BenchArgs, wanted, wanted_renders};

/// The noise levels (0..255 scale) and their seed.
const NOISE: [f64; 2] = [0.0, 5.0];
const NOISE_SEED: u64 = 7;
/// The LED counts.
const LEDS: [usize; 3] = [3, 4, 8];

/// One render solved.
#[derive(Clone, Debug, Serialize)]
pub struct PsRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// LEDs (photographs).
    pub leds: usize,
    /// Noise sigma on the 0..255 scale.
    pub noise: f64,
    /// Mean angle between the solved and the true normals, degrees.
    pub normal_error_deg: f64,
    /// RSE of the depth.
    pub rse: f64,
    /// Median relative albedo error after the one best scale.
    pub albedo_error: f64,
    /// Seconds of the solve.
    pub seconds: f64,
    /// Mean share of the object's observations used.
    pub used_share: f64,
}

/// An invariance: the same set with every photograph's exposure or the
/// depth unit changed.
#[derive(Clone, Debug, Serialize)]
pub struct InvarianceRow {
    /// What changed.
    pub change: String,
    /// Largest relative depth difference against the reference solve
    /// (after the depth unit's factor).
    pub max_relative_depth_difference: f64,
    /// Mean normal angle between the two solves, degrees.
    pub normal_difference_deg: f64,
}

/// The shared face.
#[derive(Clone, Debug, Serialize)]
pub struct FaceRow {
    /// Photographs.
    pub photographs: usize,
    /// Working size.
    pub size: String,
    /// Seconds of the solve (reading excluded).
    pub seconds: f64,
    /// Depth, 2nd and 98th percentile, mm.
    pub depth_mm: [f64; 2],
    /// Their difference, mm.
    pub depth_range_mm: f64,
    /// Each photograph's relative residual and used share.
    pub photos: Vec<(String, f64, f64)>,
    /// LED 4 alone with the single-image method against the set.
    pub single_led4: Option<sfs_core::solver::photometric::SingleComparison>,
}

/// The whole part.
#[derive(Clone, Debug, Serialize)]
pub struct PsReport {
    /// Every render.
    pub rows: Vec<PsRow>,
    /// The invariances.
    pub invariances: Vec<InvarianceRow>,
    /// The face (absent when the photographs are missing).
    pub face: Option<FaceRow>,
    /// What could not run.
    pub skipped: Vec<String>,
}

/// A scene's renderer under given lights, and the object's centre.
type Renderer = Box<dyn Fn(&[PointLight]) -> Result<Scene>>;

fn renderer(args: &BenchArgs, name: &str, side: usize) -> Result<Option<(Renderer, String)>> {
    if name == "sombrero" {
        return Ok(Some((
            Box::new(move |lights: &[PointLight]| Ok(sombrero_lit(side, side, lights))),
            format!("{side}x{side}"),
        )));
    }
    let Some(file) = super::scenes::mesh_file(name)? else {
        return Ok(None);
    };
    let path = args.meshes.join(file);
    if !path.is_file() {
        return Ok(None);
    }
    let mesh = mesh::load_obj(&path)?;
    let width = if name == "suzanne" { 2 * side } else { side };
    let label = name.to_owned();
    Ok(Some((
        Box::new(move |lights: &[PointLight]| {
            Ok(mesh::render_lit(
                &mesh,
                width,
                side,
                &mesh::Placement::default(),
                lights,
                &label,
            )?)
        }),
        format!("{width}x{side}"),
    )))
}

/// The problem of a rendered set (noise added per photograph).
fn set_problem(set: &PhotometricSet, noise: f64) -> PhotometricProblem {
    let photos = set
        .images
        .iter()
        .zip(&set.lights)
        .enumerate()
        .map(|(k, (image, light))| SetPhoto {
            name: format!("led{}", k + 1),
            image: if noise > 0.0 {
                add_noise(image, noise, NOISE_SEED + k as u64)
            } else {
                image.clone()
            },
            light: *light,
            saturated: None,
            confidence: None,
        })
        .collect();
    PhotometricProblem {
        photos,
        camera: set.camera,
        object_mask: Some(set.object_mask.clone()),
        confidence: None,
        intensities_known: true,
        intensity_scale: None,
    }
}

fn solve(problem: &PhotometricProblem) -> Result<PhotometricSolution> {
    solve_photometric(problem, &PhotometricParams::default(), &mut ())
        .context("photometric stereo failed")
}

/// Runs the part.
pub fn run(args: &BenchArgs) -> Result<()> {
    let side = if args.quick { 64 } else { 256 };
    let mut report = PsReport {
        rows: Vec::new(),
        invariances: Vec::new(),
        face: None,
        skipped: Vec::new(),
    };
    for name in wanted_renders(args) {
        let Some((render, size)) = renderer(args, name, side)? else {
            report.skipped.push(format!(
                "{name}: its mesh is not in {}",
                args.meshes.display()
            ));
            continue;
        };
        let target = if name == "sombrero" {
            [0.0, 0.0, 2.0]
        } else {
            [0.0, 0.0, mesh::Placement::default().distance]
        };
        for leds in LEDS {
            let lights = standard_leds(leds, target);
            let probe = render(&[])?;
            let (w, h) = probe.image.size();
            let albedo = albedo_pattern(w, h, "patches");
            let set = render_set(&render, &lights, &albedo, true)?;
            for noise in NOISE {
                let problem = set_problem(&set, noise);
                let started = Instant::now();
                let solution = solve(&problem)?;
                let seconds = started.elapsed().as_secs_f64();
                let row = PsRow {
                    scene: name.into(),
                    size: size.clone(),
                    leds,
                    noise,
                    normal_error_deg: mean_angle_deg(
                        &solution.normals,
                        &set.normals_gt,
                        &set.object_mask,
                    ),
                    rse: metrics::rse(&solution.depth, &set.depth_gt)?,
                    albedo_error: albedo_error(&solution.albedo, &set.albedo_gt, &set.object_mask),
                    seconds,
                    used_share: solution.photos.iter().map(|p| p.used_share).sum::<f64>()
                        / solution.photos.len().max(1) as f64,
                };
                eprintln!(
                    "ps {name} {size} {leds} LEDs noise {noise}: normals {:.2} deg, RSE {:.5}, \
                     albedo {:.2} %, {:.2} s",
                    row.normal_error_deg,
                    row.rse,
                    100.0 * row.albedo_error,
                    row.seconds
                );
                report.rows.push(row);
            }
        }
        if name == "sombrero" {
            report.invariances = invariances(&set_for_invariances(&*render)?)?;
        }
    }
    if wanted(args, "face") {
        match face(args)? {
            Some(row) => report.face = Some(row),
            None => report.skipped.push(format!(
                "face: near_ps_human1 is not in {}",
                args.real.display()
            )),
        }
    }
    super::markdown::write_part(&args.out, "ps", &report, &markdown(&report))?;
    Ok(())
}

/// The Sombrero under 4 LEDs, for the invariances.
fn set_for_invariances(render: &dyn Fn(&[PointLight]) -> Result<Scene>) -> Result<PhotometricSet> {
    let lights = standard_leds(4, [0.0, 0.0, 2.0]);
    let probe = render(&[])?;
    let (w, h) = probe.image.size();
    render_set(render, &lights, &albedo_pattern(w, h, "patches"), true)
}

/// The same set with every photograph at half the exposure, and with the
/// depth unit 10 times smaller (lights' positions times 10), against the
/// reference solve.
fn invariances(set: &PhotometricSet) -> Result<Vec<InvarianceRow>> {
    let reference = solve(&set_problem(set, 0.0))?;
    let compare = |change: &str, other: &PhotometricSolution, unit: f64| InvarianceRow {
        change: change.into(),
        max_relative_depth_difference: reference
            .depth
            .as_slice()
            .iter()
            .zip(other.depth.as_slice())
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (b / unit - a).abs() / a)
            .fold(0.0, f64::max),
        normal_difference_deg: mean_angle_deg(
            &reference.normals,
            &other.normals,
            &reference.depth.map(|z| z.is_finite()),
        ),
    };
    let mut rows = Vec::new();
    let mut darker = set_problem(set, 0.0);
    for photo in &mut darker.photos {
        photo.image = photo.image.map(|v| 0.5 * v);
    }
    rows.push(compare("exposure x0.5", &solve(&darker)?, 1.0));
    let mut units = set_problem(set, 0.0);
    for photo in &mut units.photos {
        photo.light.position = photo.light.position.map(|v| 10.0 * v);
    }
    rows.push(compare(
        "depth unit /10 (lights x10)",
        &solve(&units)?,
        10.0,
    ));
    Ok(rows)
}

/// The shared face: the seven photographs through the photo pipeline.
fn face(args: &BenchArgs) -> Result<Option<FaceRow>> {
    let Some(input) = super::face::face_input(&args.real, None) else {
        return Ok(None);
    };
    let images = input.images.clone();
    let prepared = photo::prepare(&input)?;
    let problem = photo::photometric_problem(&prepared, &input)?;
    let started = Instant::now();
    let solution = solve(&problem)?;
    let seconds = started.elapsed().as_secs_f64();
    let depth_mm = depth_range(&solution.depth).unwrap_or([f64::NAN; 2]);
    io::write_rgb_png8(
        &args.out.join("face-normals.png"),
        &solution.normals.map(|n| sfs_core::colour::normal_rgb(*n)),
    )?;
    let white = positive_quantile(&solution.albedo, 0.99).unwrap_or(1.0);
    io::write_png8(
        &args.out.join("face-albedo.png"),
        &solution.albedo.map(|a| {
            if a.is_finite() {
                (a / white).sqrt()
            } else {
                0.0
            }
        }),
    )?;
    io::write_depth_png16(&args.out.join("face-depth.png"), &solution.depth)?;
    let single_led4 = single(&input, &prepared, &solution, 3)?;
    Ok(Some(FaceRow {
        photographs: images.len(),
        size: format!("{}x{}", prepared.size().0, prepared.size().1),
        seconds,
        depth_mm,
        depth_range_mm: depth_mm[1] - depth_mm[0],
        photos: solution
            .photos
            .iter()
            .map(|p| {
                let name = Path::new(&p.name)
                    .file_name()
                    .map_or(p.name.clone(), |n| n.to_string_lossy().into_owned());
                (name, p.relative_residual, p.used_share)
            })
            .collect(),
        single_led4,
    }))
}

/// Photograph `k` of the set alone, single-image method at the defaults
/// (its scale estimated, as `solve` does), against the set.
fn single(
    set: &PhotoInput,
    prepared: &photo::PreparedPhoto,
    solution: &PhotometricSolution,
    k: usize,
) -> Result<Option<sfs_core::solver::photometric::SingleComparison>> {
    let Some(input) = set.one_of_set(k) else {
        return Ok(None);
    };
    let one = photo::prepare(&input)?;
    let cues = one.distance_cues();
    let mut problem = one.problem;
    let (single, _) = sfs_core::solver::depth_unit::solve_photograph(
        &mut problem,
        &sfs_core::params::SolverParams::default(),
        &sfs_core::solver::Method::Linearised,
        &cues,
        &mut (),
    )?;
    Ok(compare_single(
        &solution.depth,
        &single.depth,
        prepared.problem.camera,
    ))
}

fn markdown(report: &PsReport) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Near-light photometric stereo at the defaults\n\nRenders with a patch albedo, \
         LEDs 10-45 degrees off the line to the object (mu = 1, at 0.75 of its distance), \
         cast shadows; normals against the normals each image was shaded with; albedo up to \
         one scale.\n"
    );
    table(
        &mut md,
        "| scene | size | LEDs | noise | normal error (deg) | RSE | albedo error | seconds |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {} | {:.2} | {:.5} | {:.2} % | {:.2} |",
                r.scene,
                r.size,
                r.leds,
                r.noise,
                r.normal_error_deg,
                r.rse,
                100.0 * r.albedo_error,
                r.seconds
            )
        },
    );
    titled_table(
        &mut md,
        "\n## Invariances (Sombrero, 4 LEDs)\n",
        "| change | largest relative depth difference | mean normal difference (deg) |",
        &report.invariances,
        |r| {
            format!(
                "| {} | {:.2e} | {:.2e} |",
                r.change, r.max_relative_depth_difference, r.normal_difference_deg
            )
        },
    );
    if let Some(f) = &report.face {
        let _ = writeln!(
            md,
            "\n## The shared face ({} photographs, {}, ambient subtracted)\n\nSolved in {:.2} \
             s; depth {:.1} to {:.1} mm (2nd to 98th percentile), a range of {:.1} mm. \
             Pictures: face-normals.png, face-albedo.png (square root for viewing), \
             face-depth.png.\n\n| photograph | relative residual | used |\n| --- | --- | --- |",
            f.photographs, f.size, f.seconds, f.depth_mm[0], f.depth_mm[1], f.depth_range_mm
        );
        for (name, residual, used) in &f.photos {
            let _ = writeln!(md, "| {name} | {residual:.3} | {:.0} % |", 100.0 * used);
        }
        if let Some(c) = &f.single_led4 {
            let _ = writeln!(
                md,
                "\nLED 4 alone (single-image method, its scale estimated): RSE to the set \
                 {:.3} ({:.3} after scaling by {:.3}), mean normal angle {:.1} deg (median \
                 {:.1}), depth range {:.1} mm against the set's {:.1} mm.",
                c.rse_to_set,
                c.rse_to_set_scaled,
                c.scale_to_set,
                c.mean_normal_angle_deg,
                c.median_normal_angle_deg,
                c.single_depth_range,
                c.set_depth_range
            );
        }
    }
    for s in &report.skipped {
        let _ = writeln!(md, "\nskipped: {s}");
    }
    md
}
