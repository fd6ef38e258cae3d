//! `solve --photometric-stereo`: a set of photographs, each lit by its own
//! light, read through the one photo pipeline and solved for depth, normals
//! and albedo; optionally one photograph of the set solved alone with the
//! single-image method and compared with the set's shape.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::solve::SolveArgs;
use crate::output::OutputStage;
use sfs_core::io;
use sfs_core::output::set::{self as set_out, SetErrors, SingleReport};
use sfs_core::photo::{self, CameraSpec, PhotoInput, PhotoReport};
use sfs_core::solver::photometric::{self as ps, PhotometricParams, PhotometricSolution};
use sfs_core::solver::{self, LevelResult, SolveObserver};

/// The set's settings from the options (read by the core).
fn params(args: &SolveArgs) -> Result<PhotometricParams> {
    Ok(sfs_core::photograph_solve::options::photometric_params(
        &args.ps_smoothness,
        &args.ps_robust_scale,
        args.ps_no_cast_shadows,
    )?)
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

/// Runs `solve --photometric-stereo`.
pub fn run(args: &SolveArgs) -> Result<()> {
    refuse_single_options(args)?;
    let params = params(args)?;
    if let Some(dir) = &args.gt {
        sfs_core::io::ground_truth::check_ground_truth(dir, false)?;
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
        Some(dir) => Some(set_out::set_errors(dir, &solution)?),
        None => None,
    };
    let report = set_out::set_report(
        &prepared.report,
        &params,
        &solution,
        single.as_ref(),
        errors.as_ref(),
        &warnings,
    )?;
    set_out::write_set(&mut stage, &camera, &solution, &report)?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", args.out.display()))?;
    if !args.quiet {
        print_summary(
            args,
            &prepared.report,
            single.as_ref(),
            errors.as_ref(),
            &solution,
        );
    }
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }
    Ok(())
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
    single: Option<&SingleReport>,
    errors: Option<&SetErrors>,
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
    if let Some([near, far]) = ps::depth_range(&solution.depth) {
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
    if let Some(single) = single
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
    if let Some(e) = errors {
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
