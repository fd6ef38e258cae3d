//! `sfs-bench --part reflectance`: each scene rendered as Lambert, Oren-Nayar
//! (roughness 0.2, 0.4) and Blinn-Phong (k_s 0.3, shininess 10, 30), solved
//! at the defaults with the matched model, as Lambertian and with
//! `--reflectance auto`; and the shared face photograph solved with each
//! model (its nose tip's distance given). Writes reflectance.md and
//! reflectance.json.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::material::Material;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::{Scene, mesh, sombrero::sombrero_shaded};
use sfs_core::solver::Method;
use sfs_core::solver::calibrate::{KnownDepth, solve_with_known_depths};

use super::markdown::table;
use super::scenes::{problem, timed_solve};
use super::shared::{BenchArgs, wanted};

/// One scene of one material solved with one model.
#[derive(Clone, Debug, Serialize)]
pub struct ReflectanceRow {
    /// Scene name.
    pub scene: String,
    /// Image size `WxH`.
    pub size: String,
    /// The material the scene was rendered with.
    pub material: Material,
    /// `matched`, `lambert` or `auto`.
    pub solver: String,
    /// RSE of the solve.
    pub rse: f64,
    /// RIE of the solve (its own model against the image).
    pub rie: f64,
    /// RSE over the same scene rendered Lambertian and solved as such.
    pub rse_over_lambert_scene: f64,
    /// The material the solve used (auto: the fitted one, Lambert when
    /// undetermined).
    pub used: Material,
    /// Auto only: the best candidate and whether the fit called it determined.
    pub best: Option<Material>,
    /// Auto only.
    pub determined: Option<bool>,
    /// Seconds of the solve (with auto, the fit included).
    pub seconds: f64,
}

/// The face photograph solved with one model.
#[derive(Clone, Debug, Serialize)]
pub struct FaceRow {
    /// The material solved with.
    pub material: Material,
    /// RIE over trusted pixels.
    pub rie: f64,
    /// Share of trusted pixels off by more than 15 %.
    pub poor_share: f64,
    /// Median depth of the brightest 1 % of trusted object pixels (the
    /// highlights on the nose and forehead) behind the nose tip, mm.
    pub highlight_behind_nose_mm: f64,
    /// Depth behind the nose tip at the forehead, cheeks and chin
    /// landmarks, mm.
    pub landmarks_behind_nose_mm: Vec<f64>,
    /// Seconds (the known distance's scale search included).
    pub seconds: f64,
}

/// The whole part.
#[derive(Clone, Debug, Serialize)]
pub struct ReflectanceReport {
    /// Every scene, material and solver.
    pub rows: Vec<ReflectanceRow>,
    /// The face with each model (empty when the photographs are missing).
    pub face: Vec<FaceRow>,
    /// What could not run.
    pub skipped: Vec<String>,
}

/// The materials of the table (Lambert first: the reference).
fn materials() -> Vec<Material> {
    vec![
        Material::Lambert,
        Material::OrenNayar { roughness_rad: 0.2 },
        Material::OrenNayar { roughness_rad: 0.4 },
        Material::BlinnPhong {
            specular: 0.3,
            shininess: 10.0,
        },
        Material::BlinnPhong {
            specular: 0.3,
            shininess: 30.0,
        },
    ]
}

/// Renders `name` (sombrero or a mesh of `meshes`, as the robustness part
/// names them) with `material`.
fn render(name: &str, meshes: &Path, size: (usize, usize), material: Material) -> Result<Scene> {
    let (w, h) = size;
    let Some(file) = super::scenes::mesh_file(name)? else {
        return Ok(sombrero_shaded(w, h, &[], material));
    };
    let path = meshes.join(file);
    let mesh = mesh::load_obj(&path).with_context(|| format!("{name}: {}", path.display()))?;
    Ok(mesh::render_shaded(
        &mesh,
        w,
        h,
        &mesh::Placement::default(),
        &[],
        material,
        name,
    )?)
}

/// Runs the part and writes reflectance.md and reflectance.json.
pub fn run(args: &BenchArgs) -> Result<()> {
    let divisor = if args.quick { 4 } else { 1 };
    let specs: [(&str, (usize, usize)); 4] = [
        ("sombrero", (256, 256)),
        ("bunny", (256, 256)),
        ("dragon", (256, 256)),
        ("suzanne", (512, 256)),
    ];
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for (name, (w, h)) in specs {
        if !wanted(args, name) {
            continue;
        }
        let size = (w / divisor, h / divisor);
        let mut lambert_rse = f64::NAN;
        for material in materials() {
            let scene = match render(name, &args.meshes, size, material) {
                Ok(scene) => scene,
                Err(e) => {
                    eprintln!("skipping {e:#}");
                    skipped.push(format!("{e:#}"));
                    break;
                }
            };
            let solvers: &[&str] = if material.is_lambert() {
                &["matched", "auto"]
            } else {
                &["matched", "lambert", "auto"]
            };
            for &solver in solvers {
                let params = match solver {
                    "matched" => SolverParams::default().with_material(material),
                    "lambert" => SolverParams::default(),
                    _ => SolverParams {
                        reflectance: sfs_core::params::ReflectanceChoice::Auto,
                        ..SolverParams::default()
                    },
                };
                let (solution, seconds) =
                    timed_solve(&problem(&scene, scene.image.clone()), &params, name)?;
                let rse = metrics::rse(&solution.depth, &scene.depth_gt)?;
                let model = sfs_core::light::LightModel::with_material(
                    scene.intensity_scale,
                    &scene.lights,
                    solution.material,
                );
                let rie = metrics::errors_with_model(
                    &solution.depth,
                    &scene.depth_gt,
                    &scene.image,
                    scene.camera,
                    &model,
                )?
                .rie;
                if material.is_lambert() && solver == "matched" {
                    lambert_rse = rse;
                }
                let fit = solution.material_fit.as_ref();
                eprintln!(
                    "reflectance: {name} {} solved {solver}: RSE {rse:.4}{}",
                    material.describe(),
                    fit.map(|f| format!(" ({})", f.summary)).unwrap_or_default()
                );
                rows.push(ReflectanceRow {
                    scene: name.to_owned(),
                    size: format!("{}x{}", size.0, size.1),
                    material,
                    solver: solver.to_owned(),
                    rse,
                    rie,
                    rse_over_lambert_scene: rse / lambert_rse,
                    used: solution.material,
                    best: fit.map(|f| f.best),
                    determined: fit.map(|f| f.determined),
                    seconds,
                });
            }
        }
    }
    let face = if wanted(args, "face") || args.scenes.is_none() {
        match face(&args.real, divisor) {
            Ok(rows) => rows,
            Err(e) => {
                eprintln!("skipping the face: {e:#}");
                skipped.push(format!("face: {e:#}"));
                Vec::new()
            }
        }
    } else {
        Vec::new()
    };
    let report = ReflectanceReport {
        rows,
        face,
        skipped,
    };
    super::markdown::write_part(&args.out, "reflectance", &report, &markdown(&report))?;
    Ok(())
}

/// Landmarks of the face photograph (full-size pixels): forehead, the two
/// cheeks, the chin; and the nose tip with its distance, mm.
const LANDMARKS_PX: [(f64, f64); 4] = [
    (650.0, 300.0),
    (560.0, 470.0),
    (740.0, 470.0),
    (650.0, 600.0),
];
const NOSE_PX: (f64, f64) = (650.0, 450.0);
const NOSE_MM: f64 = 640.0;
/// Working size of the face solves (a third of 1296 per side).
const FACE_SIDE: usize = 432;

/// The shared LED-4 photograph of a face with each model, the nose tip's
/// distance known.
fn face(real: &Path, divisor: usize) -> Result<Vec<FaceRow>> {
    use sfs_core::photo::{self, CameraSpec, PhotoInput};
    let folder = real.join("near_ps_human1");
    let mut input = PhotoInput::new(folder.join("led4.png"));
    input.camera = CameraSpec::File(folder.join("calibration.json"));
    input.object_mask = Some(folder.join("mask.png"));
    input.ambient = Some(folder.join("ambient.png"));
    input.max_side = Some(FACE_SIDE / divisor);
    let prepared = photo::prepare(&input)
        .with_context(|| format!("cannot read the face in {}", folder.display()))?;
    let (fw, _) = prepared.full_size();
    let (ww, wh) = prepared.size();
    let k = ww as f64 / fw as f64;
    let at = |(c, r): (f64, f64)| ((c * k).round() as usize, (r * k).round() as usize);
    let mut rows = Vec::new();
    for material in [
        Material::Lambert,
        Material::OrenNayar { roughness_rad: 0.3 },
        Material::BlinnPhong {
            specular: 0.3,
            shininess: 20.0,
        },
    ] {
        let params = SolverParams::default().with_material(material);
        let mut problem = prepared.problem.clone();
        let (nc, nr) = at(NOSE_PX);
        let point = KnownDepth {
            column_px: nc as f64,
            row_px: nr as f64,
            depth: NOSE_MM,
        };
        let started = Instant::now();
        let (solution, _) = solve_with_known_depths(
            &mut problem,
            &params,
            &Method::Linearised,
            &[point],
            &mut (),
        )?;
        let seconds = started.elapsed().as_secs_f64();
        let domain = solution.depth.map(|z| z.is_finite());
        let fit = sfs_core::model_fit::measure_photographs(
            &problem.image,
            &solution.reprojection,
            &domain,
            problem.confidence.as_ref(),
            solution.scales.intensity,
            sfs_core::model_fit::Photographs {
                saturated: prepared.clipped.as_ref(),
                scale: prepared.report.sum_divisor.unwrap_or(1.0),
            },
        );
        let nose = *solution.depth.at(nc, nr);
        // The brightest 1 % of trusted object pixels.
        let mut lit: Vec<(f64, f64)> = (0..ww * wh)
            .filter(|&q| domain.as_slice()[q])
            .filter(|&q| {
                problem
                    .confidence
                    .as_ref()
                    .is_none_or(|c| c.as_slice()[q] >= 0.5)
            })
            .map(|q| (problem.image.as_slice()[q], solution.depth.as_slice()[q]))
            .collect();
        lit.sort_by(|a, b| b.0.total_cmp(&a.0));
        let top = (lit.len() / 100).max(1).min(lit.len());
        let mut depths: Vec<f64> = lit[..top].iter().map(|p| p.1).collect();
        depths.sort_by(f64::total_cmp);
        let highlight = depths.get(depths.len() / 2).copied().unwrap_or(f64::NAN);
        rows.push(FaceRow {
            material,
            rie: fit.rie_trusted,
            poor_share: fit.poor_share,
            highlight_behind_nose_mm: highlight - nose,
            landmarks_behind_nose_mm: LANDMARKS_PX
                .iter()
                .map(|&p| {
                    let (c, r) = at(p);
                    solution.depth.at(c.min(ww - 1), r.min(wh - 1)) - nose
                })
                .collect(),
            seconds,
        });
        eprintln!(
            "reflectance: face {}: RIE {:.3}, {:.0} % badly explained, highlights {:+.0} mm \
             behind the nose",
            material.describe(),
            fit.rie_trusted,
            100.0 * fit.poor_share,
            highlight - nose
        );
    }
    Ok(rows)
}

/// Geometric mean of positive finite values (NaN when none).
fn geometric_mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((0.0, 0usize), |(s, n), v| (s + v.ln(), n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).exp()
    }
}

/// The report as markdown.
pub fn markdown(report: &ReflectanceReport) -> String {
    let mut md = String::from(
        "# Reflectance beyond Lambert (bench --part reflectance)\n\n\
         Each scene rendered with the material (centred light, s known), solved at the \
         defaults with the matched model, as Lambertian, and with `--reflectance auto` (the \
         models compared on a 128 px copy; the solve stays Lambertian, since one photograph \
         does not determine the material: auto's best is what fitted best, never a finding). \
         Ratio: RSE over the Lambertian scene's matched RSE (targets: matched <= 1.3, auto <= \
         1.5).\n\n",
    );
    table(
        &mut md,
        "| scene | size | material | solver | RSE | ratio | RIE | used | auto's best | determined | seconds |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {} | {:.4} | {:.2} | {:.4} | {} | {} | {} | {:.2} |",
                r.scene,
                r.size,
                r.material.describe(),
                r.solver,
                r.rse,
                r.rse_over_lambert_scene,
                r.rie,
                r.used.describe(),
                r.best.map(|m| m.describe()).unwrap_or_default(),
                r.determined
                    .map(|d| if d { "yes" } else { "no" })
                    .unwrap_or(""),
                r.seconds
            )
        },
    );
    md.push_str(
        "\n## Geometric mean of the ratio over the scenes\n\n\
         | material | matched | lambert | auto |\n| --- | --- | --- | --- |\n",
    );
    for material in materials() {
        let mean = |solver: &str| {
            geometric_mean(
                report
                    .rows
                    .iter()
                    .filter(|r| r.material == material && r.solver == solver)
                    .map(|r| r.rse_over_lambert_scene),
            )
        };
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {:.2} |",
            material.describe(),
            mean("matched"),
            mean("lambert"),
            mean("auto")
        );
    }
    if !report.face.is_empty() {
        md.push_str(
            "\n## The shared face (LED 4, 432 px working size, nose tip at 640 mm given)\n\n\
             Highlights: the median depth of the brightest 1 % of trusted pixels behind the \
             nose tip. Landmarks: forehead, left and right cheek, chin behind the nose tip \
             (a real face: some 20-60 mm).\n\n",
        );
        table(
            &mut md,
            "| model | RIE | badly explained | highlights behind nose (mm) | landmarks (mm) | seconds |",
            &report.face,
            |f| {
                format!(
                    "| {} | {:.3} | {:.1} % | {:+.0} | {} | {:.0} |",
                    f.material.describe(),
                    f.rie,
                    100.0 * f.poor_share,
                    f.highlight_behind_nose_mm,
                    f.landmarks_behind_nose_mm
                        .iter()
                        .map(|v| format!("{v:+.0}"))
                        .collect::<Vec<_>>()
                        .join(" / "),
                    f.seconds
                )
            },
        );
    }
    if !report.skipped.is_empty() {
        md.push_str("\n## Skipped\n\n");
        for s in &report.skipped {
            let _ = writeln!(md, "- {s}");
        }
    }
    md
}
