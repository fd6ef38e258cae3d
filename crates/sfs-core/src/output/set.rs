//! What a photometric-stereo set's solve writes, once for every front (the
//! command line's `solve --photometric-stereo` and the Python package's
//! `photometric_stereo`): its `report.json` ([`set_report`]), its files
//! ([`write_set`]: depth, normals, albedo, mesh, a residual picture per
//! photograph), its errors against a `synth` folder's truth
//! ([`set_errors`]).
//!
//! Uses: `io` (the formats and the ground truth), `photo` (the pipeline's
//! report), `solver::photometric` (the solution), `scene::photometric`
//! (the normal and albedo errors), `metrics`.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::OutputStage;
use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::io::{self, IoError, ground_truth::GroundTruthError};
use crate::photo::PhotoReport;
use crate::scene::photometric::{albedo_error, mean_angle_deg};
use crate::solver::photometric::{
    self as ps, PhotoResult, PhotometricParams, PhotometricSolution, SingleComparison,
};

/// Errors against a render's ground truth (`--gt DIR`: `depth_gt.npy`, and
/// `normals_gt.npy` and `albedo_gt.npy` when there).
#[derive(Clone, Debug, Serialize)]
pub struct SetErrors {
    /// Relative surface error of the depth.
    pub rse: f64,
    /// Mean angle between the normals and the true ones, degrees.
    pub mean_normal_error_deg: Option<f64>,
    /// Median relative error of the albedo.
    pub albedo_median_relative_error: Option<f64>,
}

/// The single-image solve of one photograph of the set, compared with the
/// set's shape (`--compare-single`).
#[derive(Clone, Debug, Serialize)]
pub struct SingleReport {
    /// The photograph.
    pub image: PathBuf,
    /// Seconds of its solve.
    pub seconds: f64,
    /// The intensity scale it used.
    pub intensity_scale: f64,
    /// Whether that scale was estimated (not given, not the centred light's).
    pub intensity_scale_estimated: bool,
    /// How far its shape is from the set's (`None`: no common pixel).
    #[serde(flatten)]
    pub comparison: Option<SingleComparison>,
}

/// One photograph's entry in the report.
#[derive(Serialize)]
struct PhotoEntry<'a> {
    /// Its residual picture.
    residual_png: String,
    #[serde(flatten)]
    fit: &'a PhotoResult,
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
    levels: &'a [crate::solver::LevelReport],
    iterations: usize,
    linear_solves: crate::solver::photometric::LinearSolves,
    final_energy: &'a crate::model::Energy,
    seconds: f64,
    depth_range: Option<[f64; 2]>,
    depth16_png_range: Option<[f64; 2]>,
    albedo_relative: bool,
    albedo_png_white: f64,
    photographs: Vec<PhotoEntry<'a>>,
    single_image: Option<&'a SingleReport>,
    errors: Option<&'a SetErrors>,
    warnings: &'a [String],
}

/// The name of photograph `k`'s residual picture (`residual_01.png`, ...).
pub fn residual_name(k: usize) -> String {
    format!("residual_{:02}.png", k + 1)
}

/// The albedo shown white in `albedo.png`: 1 for an absolute albedo, else
/// its 99th percentile (the report says which).
pub fn albedo_white(solution: &PhotometricSolution) -> f64 {
    if !solution.albedo_relative {
        return 1.0;
    }
    ps::positive_quantile(&solution.albedo, 0.99).unwrap_or(1.0)
}

/// A set's `report.json`: the pipeline's report `input`, the settings
/// `params`, the solution, the single-image comparison, the ground truth's
/// errors and the warnings.
///
/// # Errors
/// The report cannot be made JSON (a map key that is not text).
pub fn set_report(
    input: &PhotoReport,
    params: &PhotometricParams,
    solution: &PhotometricSolution,
    single: Option<&SingleReport>,
    errors: Option<&SetErrors>,
    warnings: &[String],
) -> Result<serde_json::Value, serde_json::Error> {
    let auto_or = |v: Option<f64>| v.map_or_else(|| serde_json::json!("auto"), |v| v.into());
    let report = SetReport {
        mode: "photometric_stereo",
        input,
        parameters: serde_json::json!({
            "smoothness": auto_or(params.alpha),
            "robust_scale": auto_or(params.robust_scale),
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
        linear_solves: solution.linear,
        final_energy: &solution.energy,
        seconds: solution.seconds,
        depth_range: ps::depth_range(&solution.depth),
        depth16_png_range: io::depth_range(&solution.depth).map(|(near, far)| [near, far]),
        albedo_relative: solution.albedo_relative,
        albedo_png_white: albedo_white(solution),
        photographs: solution
            .photos
            .iter()
            .enumerate()
            .map(|(k, fit)| PhotoEntry {
                residual_png: residual_name(k),
                fit,
            })
            .collect(),
        single_image: single,
        errors,
        warnings,
    };
    serde_json::to_value(&report)
}

/// Writes a set's solve into `stage`: depth.npy, depth16.png, normals.npy
/// and .png, albedo.npy and .png, mesh.ply (coloured by the albedo), a
/// residual picture per photograph, and `report` as report.json. The
/// caller commits.
///
/// # Errors
/// A file that cannot be written, named.
pub fn write_set(
    stage: &mut OutputStage,
    camera: &Intrinsics,
    solution: &PhotometricSolution,
    report: &serde_json::Value,
) -> Result<(), IoError> {
    io::write_npy_f32(&stage.path("depth.npy"), &solution.depth)?;
    io::write_depth_png16(&stage.path("depth16.png"), &solution.depth)?;
    io::write_npy_f32_vec3(&stage.path("normals.npy"), &solution.normals)?;
    io::write_rgb_png8(
        &stage.path("normals.png"),
        &solution.normals.map(|n| crate::colour::normal_rgb(*n)),
    )?;
    io::write_npy_f32(&stage.path("albedo.npy"), &solution.albedo)?;
    let white = albedo_white(solution);
    let shown = solution
        .albedo
        .map(|a| if a.is_finite() { a / white } else { 0.0 });
    io::write_png16(&stage.path("albedo.png"), &shown)?;
    io::write_depth_ply(
        &stage.path("mesh.ply"),
        &solution.depth,
        camera,
        Some(&shown),
    )?;
    // I - R: grey 0.5 explained, +-0.5 is +-4 Cauchy scales.
    let span = 8.0 * solution.robust_scale * solution.brightness;
    for (k, fit) in solution.photos.iter().enumerate() {
        io::write_png8(
            &stage.path(&residual_name(k)),
            &fit.residual
                .map(|r| if r.is_finite() { 0.5 + r / span } else { 0.5 }),
        )?;
    }
    io::write_json(&stage.path("report.json"), report)
}

/// The set's errors against the `synth` folder `dir`.
///
/// # Errors
/// A file that cannot be read, or of another size than the solve.
pub fn set_errors(
    dir: &Path,
    solution: &PhotometricSolution,
) -> Result<SetErrors, GroundTruthError> {
    let depth = io::read_npy(&dir.join("depth_gt.npy"))?;
    if depth.size() != solution.depth.size() {
        return Err(GroundTruthError(format!(
            "ground truth in {} is {}x{} but the set is solved at {}x{}",
            dir.display(),
            depth.width(),
            depth.height(),
            solution.depth.width(),
            solution.depth.height()
        )));
    }
    let rse = crate::metrics::rse(&solution.depth, &depth)
        .map_err(|e| GroundTruthError(format!("ground truth in {}: {e}", dir.display())))?;
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
fn read_normals(
    path: &Path,
    size: (usize, usize),
) -> Result<Option<Grid<[f64; 3]>>, GroundTruthError> {
    if !path.is_file() {
        return Ok(None);
    }
    let normals = io::read_npy_vec3(path)?;
    if normals.size() != size {
        return Err(GroundTruthError(format!(
            "{}: {}x{} normals for a {}x{} solve",
            path.display(),
            normals.width(),
            normals.height(),
            size.0,
            size.1
        )));
    }
    Ok(Some(normals))
}
