//! `solve --photometric-stereo`: a set of photographs, each lit by its own
//! light, read through the one photo pipeline and solved for depth, normals
//! and albedo; optionally one photograph of the set solved alone with the
//! single-image method and compared with the set's shape.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::Serialize;

use super::solve::SolveArgs;
use crate::output::OutputStage;
use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::params::photometric::{PS_ROBUST_SCALE, PS_SMOOTHNESS, PsRule, ps_spec};
use sfs_core::photo::{self, CameraSpec, PhotoInput, PhotoReport};
use sfs_core::scene::photometric::{albedo_error, mean_angle_deg};
use sfs_core::solver::photometric::{
    self as ps, PhotoResult, PhotometricParams, PhotometricSolution, SingleComparison,
};
use sfs_core::solver::{self, LevelResult, SolveObserver};

/// `--NAME TEXT` for the core's photometric-stereo parameter `name`
/// ([`sfs_core::params::PS_PARAMS`]): `auto` (`None`) or a number under the
/// entry's one rule and message (`--ps-robust-scale -1` said "non-negative",
/// then 0 "positive"). `positive`: the rule the caller expects (above 0,
/// else at least 0); a caller that disagrees with the table is refused.
fn auto_or_number(text: &str, name: &str, positive: bool) -> Result<Option<f64>> {
    let expected = if positive {
        PsRule::Positive
    } else {
        PsRule::NonNegative
    };
    let Some(spec) = ps_spec(name).filter(|s| s.rule == expected) else {
        bail!("--{name}: not a photometric-stereo parameter with the rule {expected:?}");
    };
    spec.parse(text)
        .map_err(|_| anyhow::anyhow!("--{name} {text}: {}", spec.accepted()))
}

/// The set's settings from the options.
fn params(args: &SolveArgs) -> Result<PhotometricParams> {
    Ok(PhotometricParams {
        alpha: auto_or_number(&args.ps_smoothness, PS_SMOOTHNESS.name, false)?,
        // The Cauchy scale divides the residuals: it must be above 0.
        robust_scale: auto_or_number(&args.ps_robust_scale, PS_ROBUST_SCALE.name, true)?,
        cast_shadows: !args.ps_no_cast_shadows,
        ..PhotometricParams::default()
    })
}

/// Refuses the single-image options a set does not take.
fn refuse_single_options(args: &SolveArgs) -> Result<()> {
    let refuse = |option: &str, why: &str| -> Result<()> {
        bail!("{option} does not apply to --photometric-stereo: {why}")
    };
    if !args.known_depth.is_empty() {
        refuse(
            "--known-depth",
            "the lights' fall-off fixes a set's depth unit",
        )?;
    }
    if args.init_depth.is_some() {
        refuse(
            "--init-depth",
            "a set starts from the best of a range of distances",
        )?;
    }
    if args.method != super::solve::MethodArg::Linearised {
        refuse("--method", "a set is solved by its own linearised scheme")?;
    }
    if args.auto_confidence {
        refuse(
            "--auto-confidence",
            "a set leaves out shadows, saturation and outliers per photograph itself",
        )?;
    }
    // The table's options set the single-image solver: with
    // --compare-single they apply to that photograph's solve, without it
    // they would change nothing.
    if args.compare_single.is_none() {
        if let Some(name) = args.params.given_names().next() {
            refuse(&format!("--{name}"), &table_option_in_set(name))?;
        }
        if args.albedo.trim() == "1" {
            refuse(
                "--albedo 1",
                "a set always estimates its albedo with the shape (albedo.npy); --albedo \
                 applies to --compare-single",
            )?;
        }
    }
    if args.intensity_scale.is_some() && args.compare_single.is_none() {
        refuse(
            "--intensity-scale",
            "a set needs no intensity scale (its albedo absorbs it); it applies to \
             --compare-single",
        )?;
    }
    Ok(())
}

/// Why a single-image solver option (an entry of the parameter table)
/// does nothing to a set, and the option that does its job there, if any.
fn table_option_in_set(name: &str) -> String {
    let does = match name {
        "alpha" | "lambda" => {
            "a set's smoothness weight is --ps-smoothness (`auto` or a number)".to_owned()
        }
        "shadow-bound" => "a set leaves each photograph's shadows out of its data itself \
                           (--ps-no-cast-shadows stops tracing cast shadows)"
            .to_owned(),
        _ if name == "reflectance" || sfs_core::material::model_of_param(name).is_some() => {
            "a set is solved as a Lambertian surface whose albedo it estimates".to_owned()
        }
        "albedo-edge" => {
            "a set estimates its albedo per pixel from all its photographs together".to_owned()
        }
        "units" => "a set's smoothness is relative (--ps-smoothness)".to_owned(),
        _ => "a set is solved by its own scheme (its options are the --ps-* ones)".to_owned(),
    };
    format!(
        "{does}; the option sets the single-image solver and applies only with \
         --compare-single"
    )
}

/// The input of a set: the pipeline's input of the options, kept apart,
/// with each photograph's own confidence.
fn set_input(args: &SolveArgs) -> Result<PhotoInput> {
    let mut input = match folder_set(args)? {
        Some(folder) => {
            let mut input = args.photo_input_of(&folder.images)?;
            if matches!(input.camera, CameraSpec::Exif { .. }) {
                input.camera = CameraSpec::File(folder.camera);
            }
            let beside = |name: &str| {
                Some(folder.dir.join(name)).filter(|p| p.is_file() && !folder.images.contains(p))
            };
            if input.object_mask.is_none() {
                input.object_mask = beside("mask.png");
            }
            if input.ambient.is_none() {
                input.ambient = beside("ambient.png");
            }
            if !args.quiet {
                eprintln!(
                    "the set in {}: {} photographs named by {}{}{}",
                    folder.dir.display(),
                    input.images.len(),
                    match &input.camera {
                        CameraSpec::File(file) => file.display().to_string(),
                        _ => "the camera file".into(),
                    },
                    input
                        .object_mask
                        .as_ref()
                        .map_or_else(String::new, |m| format!(", object mask {}", m.display())),
                    input
                        .ambient
                        .as_ref()
                        .map_or_else(String::new, |a| format!(", ambient frame {}", a.display()))
                );
            }
            input
        }
        None => args.photo_input()?,
    };
    let images = input.images.clone();
    input.photometric_stereo = true;
    input.given_intensities = !args.lights.intensities.is_empty();
    if !args.photo_confidence.is_empty() {
        let mut each: Vec<Option<PathBuf>> = vec![None; images.len()];
        for given in &args.photo_confidence {
            let Some((image, file)) = given.split_once('=') else {
                bail!("--photo-confidence {given}: expected IMAGE=FILE");
            };
            let k = find_image(&images, Path::new(image)).with_context(|| {
                format!("--photo-confidence {given}: {image} is not one of the photographs")
            })?;
            if each[k].is_some() {
                bail!("--photo-confidence: {image} is given twice");
            }
            each[k] = Some(PathBuf::from(file));
        }
        input.photo_confidence = each;
    }
    Ok(input)
}

/// A set given as one folder (`solve --photometric-stereo DIR`).
struct FolderSet {
    dir: PathBuf,
    /// The photographs the camera file's lights name, in their order.
    images: Vec<PathBuf>,
    /// The folder's camera file.
    camera: PathBuf,
}

/// The set a folder holds when the one path given is a folder, found as
/// `view DIR` finds it (`sfs_core::photo::folder::SetFolder`): the
/// photographs its `scene.json` or `calibration.json` names by their
/// lights; its `mask.png` and `ambient.png` are used where the options
/// name none. `None` for photographs.
fn folder_set(args: &SolveArgs) -> Result<Option<FolderSet>> {
    let [dir] = args.images.as_slice() else {
        return Ok(None);
    };
    if !dir.is_dir() {
        return Ok(None);
    }
    let found = sfs_core::photo::folder::SetFolder::find(dir)?;
    Ok(Some(FolderSet {
        dir: dir.clone(),
        images: found.images,
        camera: found.camera,
    }))
}

/// The index of `wanted` among `images` (the same path, or the same file
/// name).
fn find_image(images: &[PathBuf], wanted: &Path) -> Option<usize> {
    images.iter().position(|p| p == wanted).or_else(|| {
        let name = wanted.file_name()?;
        let matches: Vec<usize> = images
            .iter()
            .enumerate()
            .filter(|(_, p)| p.file_name() == Some(name))
            .map(|(k, _)| k)
            .collect();
        (matches.len() == 1).then(|| matches[0])
    })
}

/// Progress: one line per level on a terminal.
struct Levels {
    quiet: bool,
}

impl SolveObserver for Levels {
    fn on_level(&mut self, result: &LevelResult) {
        if !self.quiet && std::io::stderr().is_terminal() {
            eprintln!(
                "level {}/{} ({}x{}) done at {:.2} s",
                result.level + 1,
                result.levels,
                result.geometry.width,
                result.geometry.height,
                result.elapsed.as_secs_f64()
            );
        }
    }
}

/// One photograph's entry in the report.
#[derive(Serialize)]
struct PhotoEntry<'a> {
    /// Its residual picture.
    residual_png: String,
    #[serde(flatten)]
    fit: &'a PhotoResult,
}

/// Errors against a render's ground truth (`--gt DIR`: `depth_gt.npy`, and
/// `normals_gt.npy` and `albedo_gt.npy` when there).
#[derive(Serialize)]
struct SetErrors {
    rse: f64,
    mean_normal_error_deg: Option<f64>,
    albedo_median_relative_error: Option<f64>,
}

/// The single-image solve of one photograph of the set, compared.
#[derive(Serialize)]
struct SingleReport {
    image: PathBuf,
    seconds: f64,
    intensity_scale: f64,
    intensity_scale_estimated: bool,
    #[serde(flatten)]
    comparison: Option<SingleComparison>,
}

/// `report.json` of a set.
#[derive(Serialize)]
struct SetReport<'a> {
    mode: &'static str,
    input: &'a PhotoReport,
    parameters: serde_json::Value,
    intensities_estimated: bool,
    alpha_used: f64,
    robust_scale_used: f64,
    brightness: f64,
    initial_depth: f64,
    distances_tried: &'a [(f64, f64)],
    levels: &'a [solver::LevelReport],
    iterations: usize,
    final_energy: &'a sfs_core::model::Energy,
    seconds: f64,
    depth_range: Option<[f64; 2]>,
    depth16_png_range: Option<[f64; 2]>,
    albedo_relative: bool,
    albedo_png_white: f64,
    photographs: Vec<PhotoEntry<'a>>,
    single_image: Option<SingleReport>,
    errors: Option<SetErrors>,
    warnings: &'a [String],
}

/// Runs `solve --photometric-stereo`.
pub fn run(args: &SolveArgs) -> Result<()> {
    refuse_single_options(args)?;
    let params = params(args)?;
    if let Some(dir) = &args.gt {
        super::solve::check_ground_truth(dir, false)?;
    }
    let input = set_input(args)?;
    let compare = match &args.compare_single {
        Some(image) => Some(find_image(&input.images, image).with_context(|| {
            format!(
                "--compare-single {}: not one of the photographs of the set",
                image.display()
            )
        })?),
        None => None,
    };
    let prepared = photo::prepare(&input)?;
    let problem = photo::photometric_problem(&prepared, &input)?;
    let mut stage = super::outputs::stage(&args.out)?;
    let truth: Vec<PathBuf> = args
        .gt
        .iter()
        .flat_map(|dir| super::outputs::ground_truth_files(dir))
        .collect();
    stage.keep_inputs(
        input
            .files()
            .into_iter()
            .chain(truth.iter().map(PathBuf::as_path)),
    );
    let camera = prepared.problem.camera;
    let solution = ps::solve_photometric(&problem, &params, &mut Levels { quiet: args.quiet })
        .with_context(|| format!("cannot solve the set of {} photographs", input.images.len()))?;
    let mut warnings = ps::warnings(&solution);

    io::write_npy_f32(&stage.path("depth.npy"), &solution.depth)?;
    let depth16 = io::write_depth_png16(&stage.path("depth16.png"), &solution.depth)?;
    io::write_npy_f32_vec3(&stage.path("normals.npy"), &solution.normals)?;
    io::write_rgb_png8(
        &stage.path("normals.png"),
        &solution.normals.map(|n| sfs_core::colour::normal_rgb(*n)),
    )?;
    io::write_npy_f32(&stage.path("albedo.npy"), &solution.albedo)?;
    let white = albedo_white(&solution);
    io::write_png16(
        &stage.path("albedo.png"),
        &solution
            .albedo
            .map(|a| if a.is_finite() { a / white } else { 0.0 }),
    )?;
    io::write_depth_ply(
        &stage.path("mesh.ply"),
        &solution.depth,
        &camera,
        Some(
            &solution
                .albedo
                .map(|a| if a.is_finite() { a / white } else { 0.0 }),
        ),
    )?;
    let mut photographs = Vec::new();
    for (k, fit) in solution.photos.iter().enumerate() {
        let name = format!("residual_{:02}.png", k + 1);
        // I - R: grey 0.5 explained, +-0.5 is +-4 Cauchy scales.
        let span = 8.0 * solution.robust_scale * solution.brightness;
        io::write_png8(
            &stage.path(&name),
            &fit.residual
                .map(|r| if r.is_finite() { 0.5 + r / span } else { 0.5 }),
        )?;
        photographs.push(PhotoEntry {
            residual_png: name,
            fit,
        });
    }
    let single = match compare {
        Some(k) => Some(solve_single(
            args, &input, k, &solution, camera, &mut stage,
        )?),
        None => None,
    };
    if let Some(single) = &single
        && single.comparison.is_none()
    {
        warnings.push(format!(
            "the single-image solve of {} shares no pixel with the set's: nothing to compare",
            single.image.display()
        ));
    }
    let errors = match &args.gt {
        Some(dir) => Some(ground_truth_errors(dir, &solution)?),
        None => None,
    };
    let range = ps::depth_range(&solution.depth);
    let report = SetReport {
        mode: "photometric_stereo",
        input: &prepared.report,
        parameters: serde_json::json!({
            "smoothness": args.ps_smoothness,
            "robust_scale": args.ps_robust_scale,
            "cast_shadows": params.cast_shadows,
            "iterations_per_level": params.iterations,
            "lambda": params.lambda,
        }),
        intensities_estimated: solution.intensities_estimated,
        alpha_used: solution.alpha,
        robust_scale_used: solution.robust_scale,
        brightness: solution.brightness,
        initial_depth: solution.initial_depth,
        distances_tried: &solution.distances_tried,
        levels: &solution.levels,
        iterations: solution.iterations,
        final_energy: &solution.energy,
        seconds: solution.seconds,
        depth_range: range,
        depth16_png_range: depth16.map(|(near, far)| [near, far]),
        albedo_relative: solution.albedo_relative,
        albedo_png_white: white,
        photographs,
        single_image: single,
        errors,
        warnings: &warnings,
    };
    io::write_json(&stage.path("report.json"), &report)?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", args.out.display()))?;
    if !args.quiet {
        print_summary(args, &prepared.report, &report, &solution);
    }
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }
    Ok(())
}

/// The albedo shown white in `albedo.png`: 1 for an absolute albedo, else
/// its 99th percentile (the report says which).
fn albedo_white(solution: &PhotometricSolution) -> f64 {
    if !solution.albedo_relative {
        return 1.0;
    }
    ps::positive_quantile(&solution.albedo, 0.99).unwrap_or(1.0)
}

/// Errors against `--gt DIR`.
fn ground_truth_errors(dir: &Path, solution: &PhotometricSolution) -> Result<SetErrors> {
    let depth = io::read_npy(&dir.join("depth_gt.npy"))?;
    if depth.size() != solution.depth.size() {
        bail!(
            "ground truth in {} is {}x{} but the set is solved at {}x{}",
            dir.display(),
            depth.width(),
            depth.height(),
            solution.depth.width(),
            solution.depth.height()
        );
    }
    let rse = sfs_core::metrics::rse(&solution.depth, &depth)?;
    let mask = depth.map(|z| z.is_finite());
    let normals = read_normals(&dir.join("normals_gt.npy"), depth.size())?;
    let albedo = match dir.join("albedo_gt.npy") {
        path if path.is_file() => Some(io::read_npy(&path)?),
        _ => None,
    };
    Ok(SetErrors {
        rse,
        mean_normal_error_deg: normals.map(|n| mean_angle_deg(&solution.normals, &n, &mask)),
        albedo_median_relative_error: albedo
            .filter(|a| a.size() == depth.size())
            .map(|a| albedo_error(&solution.albedo, &a, &mask)),
    })
}

/// `normals_gt.npy` (H x W x 3) when present.
fn read_normals(path: &Path, size: (usize, usize)) -> Result<Option<Grid<[f64; 3]>>> {
    if !path.is_file() {
        return Ok(None);
    }
    let normals = io::read_npy_vec3(path)?;
    if normals.size() != size {
        bail!(
            "{}: {}x{} normals for a {}x{} solve",
            path.display(),
            normals.width(),
            normals.height(),
            size.0,
            size.1
        );
    }
    Ok(Some(normals))
}

/// Solves photograph `k` of the set alone with the single-image method
/// (through the same pipeline: its own light by its name, the same camera,
/// mask, ambient frame and working size), writes its depth and compares.
fn solve_single(
    args: &SolveArgs,
    set: &PhotoInput,
    k: usize,
    solution: &PhotometricSolution,
    camera: sfs_core::camera::Intrinsics,
    stage: &mut OutputStage,
) -> Result<SingleReport> {
    let image = set.images[k].clone();
    let context = || format!("--compare-single {}", image.display());
    let input = set.one_of_set(k).with_context(context)?;
    let prepared = photo::prepare(&input).with_context(context)?;
    let cues = prepared.distance_cues();
    let mut problem = prepared.problem;
    let single_params = args.params(problem.image.size())?;
    let (single, unit) = solver::depth_unit::solve_photograph(
        &mut problem,
        &single_params,
        &args.method.method(),
        &cues,
        &mut (),
    )
    .with_context(|| format!("--compare-single {}: cannot solve it", image.display()))?;
    let estimated = !matches!(
        unit.source,
        solver::depth_unit::UnitSource::GivenScale | solver::depth_unit::UnitSource::CentredLight
    );
    io::write_npy_f32(&stage.path("single_depth.npy"), &single.depth)?;
    io::write_depth_png16(&stage.path("single_depth16.png"), &single.depth)?;
    Ok(SingleReport {
        image,
        seconds: single.seconds,
        intensity_scale: problem.intensity_scale,
        intensity_scale_estimated: estimated,
        comparison: ps::compare_single(&solution.depth, &single.depth, camera),
    })
}

/// The summary on the terminal.
fn print_summary(
    args: &SolveArgs,
    input: &PhotoReport,
    report: &SetReport<'_>,
    solution: &PhotometricSolution,
) {
    for note in &input.notes {
        eprintln!("{note}");
    }
    let units = input.camera.units.as_deref().unwrap_or("depth units");
    eprintln!(
        "solved a set of {} photographs ({}x{}) in {:.2} s ({} levels, {} linearisations) -> {}",
        solution.photos.len(),
        input.width,
        input.height,
        solution.seconds,
        solution.levels.len(),
        solution.iterations,
        args.out.display()
    );
    if let Some([near, far]) = report.depth_range {
        eprintln!(
            "depth {near:.4}..{far:.4} {units} (2nd to 98th percentile; range {:.4} {units}), \
             started from {:.4} {units}",
            far - near,
            solution.initial_depth
        );
    }
    for photo in &solution.photos {
        eprintln!(
            "  {}: intensity {:.3}{}, residual {:.3}, used {:.0} %, shadow {:.0} %, untrusted \
             {:.0} %, down-weighted {:.0} %",
            photo.name,
            photo.intensity,
            if solution.intensities_estimated {
                " (estimated)"
            } else {
                ""
            },
            photo.relative_residual,
            100.0 * photo.used_share,
            100.0 * photo.shadow_share,
            100.0 * photo.untrusted_share,
            100.0 * photo.robust_share
        );
    }
    if let Some(single) = &report.single_image
        && let Some(c) = &single.comparison
    {
        eprintln!(
            "{} alone (single-image method, {:.2} s): RSE to the set {:.4} ({:.4} after scaling \
             by {:.3}), mean normal angle {:.1} deg, depth range {:.4} against the set's {:.4} \
             {units}",
            single.image.display(),
            single.seconds,
            c.rse_to_set,
            c.rse_to_set_scaled,
            c.scale_to_set,
            c.mean_normal_angle_deg,
            c.single_depth_range,
            c.set_depth_range
        );
    }
    if let Some(e) = &report.errors {
        eprintln!(
            "against the ground truth: RSE {:.5}{}{}",
            e.rse,
            e.mean_normal_error_deg
                .map_or_else(String::new, |v| format!(", mean normal error {v:.2} deg")),
            e.albedo_median_relative_error
                .map_or_else(String::new, |v| format!(
                    ", albedo median error {:.2} %",
                    100.0 * v
                ))
        );
    }
}

#[cfg(test)]
mod option_tests {
    use super::auto_or_number;

    /// `--ps-robust-scale -1` said "must be non-negative", then 0 "must be
    /// positive": one rule, one message, for every bad value.
    #[test]
    fn the_robust_scale_has_one_rule_and_one_message() {
        let message = |text: &str| {
            auto_or_number(text, "ps-robust-scale", true)
                .expect_err(text)
                .to_string()
        };
        for text in ["-1", "0", "abc", "inf"] {
            assert_eq!(
                message(text),
                format!("--ps-robust-scale {text}: must be `auto` or a positive number (above 0)")
            );
        }
        assert_eq!(
            auto_or_number("0.5", "ps-robust-scale", true).unwrap(),
            Some(0.5)
        );
        assert_eq!(
            auto_or_number("AUTO", "ps-robust-scale", true).unwrap(),
            None
        );
        assert_eq!(
            auto_or_number("0", "ps-smoothness", false).unwrap(),
            Some(0.0)
        );
    }

    /// One value out of range, refused by the command line as by the core's
    /// validation and the viewer (their tests): the table's one rule.
    #[test]
    fn an_out_of_range_value_is_refused_by_the_core_rule() {
        use sfs_core::params::photometric::PS_ROBUST_SCALE;
        use sfs_core::solver::photometric::PhotometricParams;
        let message = auto_or_number("0", "ps-robust-scale", true)
            .expect_err("0 is out of range")
            .to_string();
        assert!(message.ends_with(PS_ROBUST_SCALE.accepted()), "{message}");
        let core = PhotometricParams {
            robust_scale: Some(0.0),
            ..PhotometricParams::default()
        };
        assert_eq!(
            core.validate().expect_err("refused").name,
            "ps-robust-scale"
        );
        // A caller expecting another rule than the table's is refused.
        assert!(auto_or_number("1", "ps-robust-scale", false).is_err());
    }
}
