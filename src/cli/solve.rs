//! `sfs-studio solve`: recover depth from an image and write depth, mesh,
//! reprojection and a JSON report.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use serde::Serialize;
use serde_json::json;

use sfs_core::grid::Grid;
use sfs_core::io::{self, SrgbMode};
use sfs_core::memory;
use sfs_core::metrics;
use sfs_core::model_fit;
use sfs_core::params::{self as parameters, AlbedoChoice, InitialDepth, SolverParams};
use sfs_core::photo::{
    self, CameraSpec, LightSpec, PhotoInput, PhotoReport, ScaleSpec, Vignetting,
};
use sfs_core::solver::{self, IterationReport, SolveObserver};

/// Arguments of `solve`. Defaults are the paper's where it gives one.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SolveArgs {
    /// Input photograph(s): 8/16-bit PNG, TIFF or JPEG, read as linear values
    /// in [0, 1] (colour converted to luminance). Several photographs of one
    /// scene, each with other lights on, are summed in linear light (as if
    /// the lights were on together).
    #[arg(required = true, num_args = 1..)]
    pub images: Vec<PathBuf>,
    /// Camera file: scene.json (width, height, focal, cx, cy or K,
    /// intensity_scale, lights) or a near_ps calibration.json; intrinsics
    /// given for another image size (width/height, or
    /// calibration_width/height) are scaled to the image.
    #[arg(long, conflicts_with_all = ["focal", "cx", "cy"])]
    pub camera: Option<PathBuf>,
    /// Focal length in pixels of the photograph as given (instead of --camera).
    #[arg(long)]
    pub focal: Option<f64>,
    /// Principal point column in pixels [default: (width-1)/2].
    #[arg(long, requires = "focal")]
    pub cx: Option<f64>,
    /// Principal point row in pixels [default: (height-1)/2].
    #[arg(long, requires = "focal")]
    pub cy: Option<f64>,
    /// Intensity scale s (albedo x light power x gain), or `auto`: estimated
    /// with lights off the centre (depth is then metric, in the lights'
    /// units); with a centred light auto means s = 1 unless --known-depth
    /// fixes the depth unit [default: the camera file's, else auto].
    #[arg(long, value_name = "S|auto")]
    pub intensity_scale: Option<String>,
    /// A known distance: the surface at pixel X,Y (of the photograph as
    /// given) is Z depth units away. Sets the depth scale (and s) with a
    /// centred light, and s with lights anywhere. Repeatable: several
    /// points are met in relative least squares, each one's residual
    /// reported.
    #[arg(long, value_name = "X,Y,Z", value_parser = super::parse_floats::<3>)]
    pub known_depth: Vec<[f64; 3]>,
    /// The object is about this far from the camera (its median depth, in
    /// the camera file's unit, e.g. mm): sets the depth unit (and s) as
    /// --known-depth does, without picking a pixel [default: from the
    /// set-up (where its LEDs are aimed) or the photograph's shading].
    #[arg(long, value_name = "DEPTH", conflicts_with = "known_depth")]
    pub distance: Option<f64>,
    /// Where the lights are.
    #[command(flatten)]
    pub lights: super::LightArgs,
    /// Object mask image (white = object, black = no surface) [default: every pixel].
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Confidence image in [0, 1] (black = do not trust, e.g. highlights) [default: 1].
    #[arg(long)]
    pub confidence: Option<PathBuf>,
    /// Lower the confidence of saturated highlights, near-black and
    /// cast-shadow pixels and the silhouette band (combined with
    /// --confidence by the minimum); written as confidence_used.png.
    #[arg(long)]
    pub auto_confidence: bool,
    /// sRGB decoding: `on`, `off`, or `auto` (on for JPEG and 8-bit
    /// photographs, off for 16-bit and float images and for PNGs marked
    /// linear, as everything `synth` writes). `--srgb` alone means on.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on")]
    pub srgb: SrgbArg,
    /// A frame with every light off (same camera settings), subtracted from
    /// each photograph.
    #[arg(long, value_name = "FILE")]
    pub ambient: Option<PathBuf>,
    /// Vignetting correction: `cos4` (the pinhole's natural fall-off) or a
    /// flat-field image (a uniform white target) [default: none].
    #[arg(long, value_name = "cos4|FILE")]
    pub vignetting: Option<String>,
    /// The surface's albedo: `auto` (estimated with the shape, kept only
    /// where it explains the photograph better than albedo 1; writes
    /// albedo.npy and albedo.png; --albedo-edge is its prior's weight),
    /// `1` (the paper's: all brightness is shading) or FILE, a known albedo
    /// map (linear, relative) divided out, pixels with albedo below 0.02
    /// not trusted.
    #[arg(long, value_name = "auto|1|FILE", default_value = "auto")]
    pub albedo: String,
    /// Solve at a working size whose longest side is at most N pixels (area
    /// averaging; intrinsics and masks scaled alike); outputs are at the
    /// working size. 0: the full size.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_SIDE)]
    pub max_side: usize,
    /// Initial depth: `fast-marching` (default: fast marching on the image,
    /// denoised when noisy, then refined at full resolution; with lights off
    /// the centre marched in the lights' own frame, or, for lights more than
    /// 20 degrees off the camera seen from the object, the plane that best
    /// fits the image, refined through the pyramid), `from-image` (the
    /// paper's constant depth from the brightest
    /// pixel, then the whole pyramid), a number (a constant depth, depth
    /// units), or a `.npy` depth map of the working size.
    #[arg(long, value_name = "fast-marching|from-image|Z|FILE.npy")]
    pub init_depth: Option<String>,
    /// The scheme: `linearised` (the paper's, default), `explicit` (Ju et
    /// al.'s gradient descent on the same energy) or `fast-marching`
    /// (Prados-Faugeras by fast marching, centred light only; ignores the
    /// confidence and the energy's parameters).
    #[arg(long, value_enum, default_value = "linearised")]
    pub method: MethodArg,
    /// Solver parameters (one option per entry of the parameter table).
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// Ground-truth folder written by `synth`: adds rse and rie to the report.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// No progress bar, notes, summary or fit lines; warnings are still
    /// printed.
    #[arg(long, short)]
    pub quiet: bool,
    /// Output folder (created if needed): depth.npy, depth16.png,
    /// reprojection.png, residual.png, occlusion_edges.png, mesh.ply,
    /// report.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Photometric stereo: the photographs are a set of one object, each
    /// taken by a light of its own (a camera file whose `lights` name each
    /// image, or one --light per photograph in order); solved for depth,
    /// normals and albedo (normals.npy/png, albedo.npy/png,
    /// residual_NN.png per photograph). --mask and --confidence apply to
    /// every photograph; --ambient is subtracted from each.
    #[arg(long)]
    pub photometric_stereo: bool,
    /// With --photometric-stereo: a confidence image for one photograph of
    /// the set (repeatable), combined with --confidence.
    #[arg(long, value_name = "IMAGE=FILE", requires = "photometric_stereo")]
    pub photo_confidence: Vec<String>,
    /// With --photometric-stereo: also solve this photograph of the set
    /// alone with the single-image method (the table's parameters apply
    /// to it) and report how far its shape is from the set's
    /// (single_depth.npy).
    #[arg(long, value_name = "IMAGE", requires = "photometric_stereo")]
    pub compare_single: Option<PathBuf>,
    /// With --photometric-stereo: the smoothness weight (relative: second
    /// derivatives of the log-depth times f^2), or `auto` (from the
    /// photographs' noise).
    #[arg(long, value_name = "auto|A", default_value = "auto")]
    pub ps_smoothness: String,
    /// With --photometric-stereo: the Cauchy scale of the residuals
    /// relative to the brightness, or `auto` (from the residuals).
    #[arg(long, value_name = "auto|S", default_value = "auto")]
    pub ps_robust_scale: String,
    /// With --photometric-stereo: do not trace cast shadows of the current
    /// surface (attached shadows, saturation and outliers are still left
    /// out).
    #[arg(long, requires = "photometric_stereo")]
    pub ps_no_cast_shadows: bool,
}

/// The default working size of `solve` (longest side, pixels): 1920x1080
/// solves at full size, an 18 MP photograph at 2000x1333.
pub const DEFAULT_MAX_SIDE: usize = 2000;

/// `--srgb`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SrgbArg {
    /// Always decode sRGB.
    On,
    /// Values are linear.
    Off,
    /// Decide from the file.
    Auto,
}

impl SrgbArg {
    /// The reader's mode.
    pub fn mode(self) -> SrgbMode {
        match self {
            SrgbArg::On => SrgbMode::On,
            SrgbArg::Off => SrgbMode::Off,
            SrgbArg::Auto => SrgbMode::Auto,
        }
    }
}

/// `--method`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// The linearised coarse-to-fine Gauss-Newton scheme (the paper's).
    Linearised,
    /// Gradient descent on the same energy (Ju et al.).
    Explicit,
    /// Fast marching for the Prados-Faugeras equation.
    FastMarching,
}

impl MethodArg {
    /// The solver's method.
    pub fn method(self) -> solver::Method {
        match self {
            MethodArg::Linearised => solver::Method::Linearised,
            MethodArg::Explicit => solver::Method::Explicit(solver::ExplicitParams::default()),
            MethodArg::FastMarching => {
                solver::Method::FastMarching(solver::FastMarchingParams::default())
            }
        }
    }
}

impl SolveArgs {
    /// Solver parameters from the arguments (validated by the solver).
    pub fn params(&self, image_size: (usize, usize)) -> Result<SolverParams> {
        let mut params = self.params.to_params()?;
        params.initial_depth = parse_initial_depth(self.init_depth.as_deref(), image_size)?;
        params.albedo = self.albedo_choice();
        Ok(params)
    }

    /// `--albedo FILE`: the map the pipeline divides out (`None` for `auto`
    /// and `1`).
    pub fn albedo_file(&self) -> Option<PathBuf> {
        let text = self.albedo.trim();
        if text.eq_ignore_ascii_case("auto") || text == "1" {
            None
        } else {
            Some(PathBuf::from(text))
        }
    }

    /// How the solver takes the albedo: estimated for `auto`, else 1 (a
    /// given map is already divided out).
    pub fn albedo_choice(&self) -> AlbedoChoice {
        if self.albedo.trim().eq_ignore_ascii_case("auto") {
            AlbedoChoice::Auto
        } else {
            AlbedoChoice::One
        }
    }

    /// Refuses `--albedo` and `--vignetting` values that are neither one of
    /// their words nor an existing file, naming the value and what is
    /// accepted (`--albedo 0` said "cannot read image 0").
    pub fn check_word_or_file_options(&self) -> Result<()> {
        if let Some(file) = self.albedo_file() {
            check_word_or_file(
                "albedo",
                &self.albedo,
                &file,
                "`auto`, `1` or FILE (an image, or a .npy such as the albedo.npy a solve writes)",
            )?;
        }
        if let Some(text) = &self.vignetting
            && !matches!(text.as_str(), "none" | "cos4")
        {
            check_word_or_file(
                "vignetting",
                text,
                Path::new(text),
                "`cos4`, `none` or FILE (a flat-field image)",
            )?;
        }
        Ok(())
    }

    /// `--albedo-edge` is the albedo prior's weight, used by `--albedo auto`
    /// only: given with `--albedo 1` or a known albedo map it would change
    /// nothing, and is refused (as `--roughness` without its reflectance).
    pub fn refuse_unused_albedo_edge(&self) -> Result<()> {
        if self.albedo_choice() != AlbedoChoice::Auto
            && self.params.given_names().any(|n| n == "albedo-edge")
        {
            bail!(
                "--albedo-edge belongs to --albedo auto (the estimated albedo's prior); with \
                 --albedo {} no albedo is estimated, so it would change nothing",
                self.albedo
            );
        }
        Ok(())
    }
}

/// `--NAME TEXT`: `file` must exist, else the error lists what is
/// `accepted`.
fn check_word_or_file(name: &str, text: &str, file: &Path, accepted: &str) -> Result<()> {
    if file.is_file() {
        return Ok(());
    }
    let what = if file.exists() {
        "is not a file"
    } else {
        "is neither one of its words nor an existing file"
    };
    bail!("--{name} {text}: {what}; accepted: {accepted}")
}

/// `--init-depth`: a method, a number or a `.npy` file of the image's size.
pub fn parse_initial_depth(text: Option<&str>, image_size: (usize, usize)) -> Result<InitialDepth> {
    let Some(text) = text else {
        return Ok(InitialDepth::FastMarching);
    };
    if text.eq_ignore_ascii_case("fast-marching") {
        return Ok(InitialDepth::FastMarching);
    }
    if text.eq_ignore_ascii_case("from-image") {
        return Ok(InitialDepth::FromImage);
    }
    if let Ok(z) = text.parse::<f64>() {
        return Ok(InitialDepth::Constant(z));
    }
    let map = io::read_npy(Path::new(text)).with_context(|| {
        format!("--init-depth {text}: not a method, a number or a readable .npy")
    })?;
    if map.size() != image_size {
        bail!(
            "--init-depth {text} is {}x{} but the image is {}x{}",
            map.width(),
            map.height(),
            image_size.0,
            image_size.1
        );
    }
    Ok(InitialDepth::Map(map))
}

/// A depth or distance as the user reads it: four decimals for moderate
/// values, scientific notation for very small or large ones (`1e-6` was
/// printed as "0.0000").
pub fn shown(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-2..1e6).contains(&v.abs()) {
        format!("{v:.4e}")
    } else {
        format!("{v:.4}")
    }
}

/// Ground truth of a synth folder.
pub struct GroundTruth {
    /// Depth, NaN on the background.
    pub depth: Grid<f64>,
    /// Noise-free image.
    pub image: Grid<f64>,
}

/// Refuses `--gt DIR` that cannot be the ground truth before anything is
/// solved, in the user's terms: no such folder, or a folder without the
/// files `synth` writes (`depth_gt.npy`, and `image16.png` for one
/// photograph, `with_image`).
pub fn check_ground_truth(dir: &Path, with_image: bool) -> Result<()> {
    if !dir.is_dir() {
        bail!(
            "--gt {}: no such folder (--gt takes a folder written by `synth`)",
            dir.display()
        );
    }
    let wanted: &[(&str, &str)] = if with_image {
        &[
            ("depth_gt.npy", "the true depth"),
            ("image16.png", "the noise-free render"),
        ]
    } else {
        &[("depth_gt.npy", "the true depth")]
    };
    for (file, what) in wanted {
        if !dir.join(file).is_file() {
            bail!(
                "--gt {}: the folder has no {file} ({what} that `synth` writes); --gt takes a \
                 folder written by `synth`",
                dir.display()
            );
        }
    }
    Ok(())
}

/// Reads `DIR/depth_gt.npy` and `DIR/image16.png`.
pub fn read_ground_truth(dir: &Path) -> Result<GroundTruth> {
    check_ground_truth(dir, true)?;
    let depth = io::read_npy(&dir.join("depth_gt.npy"))?;
    let image = io::read_image(&dir.join("image16.png"), false)?;
    if depth.size() != image.size() {
        bail!(
            "ground truth in {}: depth_gt.npy is {}x{} but image16.png is {}x{}",
            dir.display(),
            depth.width(),
            depth.height(),
            image.width(),
            image.height()
        );
    }
    Ok(GroundTruth { depth, image })
}

/// Progress on a terminal.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    kappa: usize,
}

impl SolveObserver for Progress {
    fn on_iteration(&mut self, report: &IterationReport) {
        if let Some(bar) = &self.bar {
            bar.set_length((report.levels * self.kappa) as u64);
            bar.set_position((report.level * self.kappa + report.iteration + 1) as u64);
            bar.set_message(format!(
                "level {}/{} {}x{}  E = {:.4e}",
                report.level + 1,
                report.levels,
                report.width,
                report.height,
                report.energy.total
            ));
        }
    }
}

impl SolveArgs {
    /// The photo pipeline's input these arguments describe.
    pub fn photo_input(&self) -> Result<PhotoInput> {
        self.photo_input_of(&self.images)
    }

    /// The photo pipeline's input these arguments describe, for `images`
    /// (the photographs a folder holds, say).
    pub fn photo_input_of(&self, images: &[PathBuf]) -> Result<PhotoInput> {
        let camera = match (&self.camera, self.focal) {
            (Some(path), _) => CameraSpec::File(path.clone()),
            (None, Some(focal_px)) => CameraSpec::Focal {
                focal_px,
                cx_px: self.cx,
                cy_px: self.cy,
            },
            (None, None) => CameraSpec::Exif { guess: false },
        };
        let lights = match self.lights.lights()? {
            Some(lights) => {
                if !self.lights.indices.is_empty() {
                    bail!("give either --light X,Y,Z or --light-index K (a camera file's lights)");
                }
                LightSpec::Given(lights)
            }
            None => {
                let picks = &self.lights.indices;
                if let Some(twice) = picks
                    .iter()
                    .enumerate()
                    .find_map(|(k, i)| picks[..k].contains(i).then_some(*i))
                {
                    bail!(
                        "--light-index {twice} is given twice: each LED is on once (give each \
                         number once)"
                    );
                }
                LightSpec::CameraFile {
                    picks: picks.clone(),
                }
            }
        };
        let intensity_scale = match self.intensity_scale.as_deref() {
            None => ScaleSpec::FromCamera,
            Some(text) if text.eq_ignore_ascii_case("auto") => ScaleSpec::Auto,
            Some(text) => ScaleSpec::Given(text.parse().map_err(|_| {
                anyhow::anyhow!("--intensity-scale {text}: not a number or `auto`")
            })?),
        };
        self.check_word_or_file_options()?;
        self.refuse_unused_albedo_edge()?;
        let vignetting = Vignetting::from_option(self.vignetting.as_deref());
        // The table's parameters (eta, min-level-side) size the pyramid.
        let table_params = self.params.to_params()?;
        let max_side = (self.max_side > 0).then_some(self.max_side);
        let pyramid_factor = |(w, h): (usize, usize)| {
            sfs_core::solver::pyramid::pyramid_factor(
                w,
                h,
                table_params.eta,
                table_params.min_level_side,
            )
        };
        let first = images.first().map(PathBuf::as_path);
        let full = first.and_then(|p| io::photo_size(p).ok());
        Ok(PhotoInput {
            images: images.to_vec(),
            srgb: self.srgb.mode(),
            camera,
            lights,
            intensity_scale,
            object_mask: self.mask.clone(),
            confidence: self.confidence.clone(),
            auto_confidence: self.auto_confidence,
            ambient: self.ambient.clone(),
            vignetting,
            albedo: self.albedo_file(),
            max_side,
            pyramid_factor: full.map_or(memory::DEFAULT_PYRAMID_FACTOR, |(w, h)| {
                pyramid_factor(sfs_core::resample::working_size(w, h, max_side))
            }),
            max_side_setting: "--max-side".into(),
            photometric_stereo: false,
            given_intensities: false,
            photo_confidence: Vec::new(),
        })
    }
}

/// The depth picture's range, for the report.
#[derive(Debug, Serialize)]
struct DepthRange {
    /// Depth shown white.
    near_white: f64,
    /// Depth shown black.
    far_black: f64,
}

/// The input as solved: the photo pipeline's report (with the intensity
/// scale the solve ended with) and the known distance.
#[derive(Debug, Serialize)]
struct SolveInput {
    #[serde(flatten)]
    photo: PhotoReport,
    /// `--known-depth` as given (pixels of the photograph as given).
    known_depth: Vec<[f64; 3]>,
    /// `--distance` as given.
    distance: Option<f64>,
}

/// A known distance is met when the solved depth there is within this share.
const KNOWN_DEPTH_MET: f64 = 0.005;

/// `report.json`: everything a solve decided and measured.
#[derive(Debug, Serialize)]
struct SolveReport<'a> {
    input: SolveInput,
    /// Which cue set the depth unit, how precisely, the shading search and
    /// how the solve met `--known-depth` (working-size pixels) or
    /// `--distance`.
    depth_unit: &'a solver::depth_unit::DepthUnit,
    notes: &'a [String],
    parameters: serde_json::Value,
    /// The material the surface was solved as (with `--reflectance auto`,
    /// the fitted one).
    material: sfs_core::material::Material,
    /// With `--reflectance auto`: every candidate and the verdict.
    material_fit: Option<&'a solver::material_fit::MaterialFit>,
    /// With `--albedo auto`: the estimate and whether the solve used it.
    albedo_fit: Option<&'a solver::albedo_fit::AlbedoFit>,
    alpha_used: f64,
    alpha_px: f64,
    lambda_px: f64,
    scales: &'a sfs_core::params::ProblemScales,
    initial_depth: f64,
    levels: &'a [solver::LevelReport],
    phases: &'a solver::PhaseTimes,
    final_energy: &'a sfs_core::model::Energy,
    seconds: f64,
    model_fit: &'a model_fit::ModelFit,
    /// Several photographs, each with its own light: the fit of the depth
    /// to each one alone under its light.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    model_fit_per_photo: &'a [photo::PhotoFit],
    /// Share of the object taken out of the data term as shadow (lights off
    /// the optical centre only; shadow.png marks it).
    shadow_share: Option<f64>,
    /// Options given that this input leaves without effect (each also a
    /// warning).
    unused_options: &'a [String],
    warnings: &'a [String],
    depth16_png_range: Option<DepthRange>,
    rse: Option<f64>,
    rie: Option<f64>,
}

/// Runs `solve` on one photograph (`cli::run` hands `--photometric-stereo`
/// to `cli::photometric`).
pub fn run(args: &SolveArgs) -> Result<()> {
    if args.ps_smoothness != "auto" || args.ps_robust_scale != "auto" {
        bail!("--ps-smoothness and --ps-robust-scale need --photometric-stereo");
    }
    let input = args.photo_input()?;
    // A solve that would not fit the memory is refused before any pixel is
    // decoded (in the pipeline); the destination is locked and checked
    // writable before the solve.
    if let Some(dir) = &args.gt {
        check_ground_truth(dir, true)?;
    }
    let prepared = photo::prepare(&input)?;
    let mut stage = super::outputs::stage(&args.out)?;
    let mut named: Vec<PathBuf> = args.init_depth.iter().map(PathBuf::from).collect();
    if let Some(dir) = &args.gt {
        named.extend(super::outputs::ground_truth_files(dir));
    }
    stage.keep_inputs(
        input
            .files()
            .into_iter()
            .chain(named.iter().map(PathBuf::as_path)),
    );
    let size = prepared.size();
    let full_size = prepared.full_size();
    let camera = prepared.problem.camera;
    let mut notes = prepared.report.notes.clone();
    let object_mask = prepared.problem.object_mask.clone();
    let image = &prepared.problem.image;
    if let Some(reason) = model_fit::too_dark_to_solve(image, object_mask.as_ref()) {
        // The cause, where the input names one before the image's darkness.
        let report = &prepared.report;
        let cause = if object_mask
            .as_ref()
            .is_some_and(|m| !m.as_slice().iter().any(|&o| o))
        {
            format!(
                "the object mask {} marks no pixel as object (white = object)",
                report
                    .mask
                    .as_deref()
                    .map_or_else(String::new, |p| p.display().to_string())
            )
        } else if let Some(ambient) = &report.ambient
            && !image
                .as_slice()
                .iter()
                .zip(0..)
                .any(|(&v, q)| v > 0.0 && object_mask.as_ref().is_none_or(|m| m.as_slice()[q]))
        {
            format!(
                "after subtracting the ambient frame {} the image is black on every object \
                 pixel: the ambient frame is at least as bright as the photograph there (the \
                 wrong frame, or the two swapped?)",
                ambient.display()
            )
        } else if let Some(albedo) = &report.albedo
            && report.albedo_untrusted_share >= 0.999
        {
            format!(
                "the albedo {} is zero (below the smallest albedo divided out) on every object \
                 pixel",
                albedo.display()
            )
        } else {
            reason
        };
        bail!("cannot solve {}: {cause}", args.images[0].display());
    }
    let dark = model_fit::darkness_warning(image, object_mask.as_ref());
    if let Some(warning) = &dark
        && !args.quiet
    {
        eprintln!("warning: {warning}");
    }
    let ground_truth = match &args.gt {
        Some(dir) => {
            let gt = read_ground_truth(dir)?;
            if gt.depth.size() != size {
                bail!(
                    "ground truth in {} is {}x{} but the image is solved at {}x{}",
                    dir.display(),
                    gt.depth.width(),
                    gt.depth.height(),
                    size.0,
                    size.1
                );
            }
            Some(gt)
        }
        None => None,
    };
    let params = args.params(size)?;
    let set_up_cues = prepared.distance_cues();
    let units = prepared.report.camera.units.clone();
    let mut photo_report = prepared.report.clone();
    let confidence_derived = prepared.confidence_derived;
    let mut problem = prepared.problem;
    let bar = (!args.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(1);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let mut progress = Progress {
        bar,
        kappa: params.kappa,
    };
    // The intensity scale: estimated with lights off the centre; a known
    // distance fixes it (and the depth unit).
    let known_points: Vec<solver::calibrate::KnownDepth> = args
        .known_depth
        .iter()
        .map(|&[x, y, z]| {
            let kx = size.0 as f64 / full_size.0 as f64;
            let ky = size.1 as f64 / full_size.1 as f64;
            solver::calibrate::KnownDepth {
                column_px: ((x + 0.5) * kx - 0.5).round(),
                row_px: ((y + 0.5) * ky - 0.5).round(),
                depth: z,
            }
        })
        .collect();
    let (z_min, z_max) = parameters::DEPTH_RANGE;
    for (given, p) in args.known_depth.iter().zip(&known_points) {
        let [x, y, z] = [given[0].to_string(), given[1].to_string(), shown(given[2])];
        if !(p.column_px >= 0.0
            && p.row_px >= 0.0
            && (p.column_px as usize) < size.0
            && (p.row_px as usize) < size.1
            && p.depth > 0.0
            && p.depth.is_finite())
        {
            bail!(
                "--known-depth {x},{y},{z}: the pixel must lie in the {}x{} image and the \
                 distance be positive",
                full_size.0,
                full_size.1
            );
        }
        if !(z_min..=z_max).contains(&p.depth) {
            bail!(
                "--known-depth {x},{y},{z}: the distance must lie in [{z_min:e}, {z_max:e}] depth \
                 units (check its unit)"
            );
        }
    }
    if let Some(distance) = args.distance
        && !(distance.is_finite() && distance > 0.0)
    {
        bail!("--distance {distance}: must be a positive distance (the camera file's unit)");
    }
    if (!known_points.is_empty() || args.distance.is_some())
        && let Some(given) = &args.intensity_scale
        && given != "auto"
    {
        bail!(
            "--{} and --intensity-scale {given} both set the depth unit: give one (a distance \
             searches the intensity scale)",
            if known_points.is_empty() {
                "distance"
            } else {
                "known-depth"
            }
        );
    }
    let centred = problem.light_is_centred();
    // Options that depend on the input to matter, and that this input
    // leaves without effect: reported on stderr and in report.json.
    let mut unused_options: Vec<String> = Vec::new();
    if params.shadow_bound && centred {
        unused_options.push(
            "--shadow-bound on: the light is at the optical centre, so the surface casts no \
             shadow the camera sees and there is nothing to bound"
                .into(),
        );
    }
    let method = args.method.method();
    let cues = solver::depth_unit::DistanceCues {
        known_depths: known_points,
        distance: args.distance,
        ..set_up_cues
    };
    let unit_name = units.as_deref().unwrap_or("depth units");
    let solved =
        solver::depth_unit::solve_photograph(&mut problem, &params, &method, &cues, &mut progress);
    let mut known_depth_warning = None;
    let mut loose_scale_warning = None;
    if let Ok((_, unit)) = &solved {
        notes.push(unit.words(unit_name));
        if let Some(fit) = unit.fit.as_ref().filter(|f| !f.points.is_empty()) {
            notes.push(format!(
                "depth scale from --known-depth: s = {:.4e} after {} solve{}; {}",
                fit.intensity_scale,
                fit.solves,
                if fit.solves == 1 { "" } else { "s" },
                fit.points
                    .iter()
                    .map(|p| format!(
                        "pixel {},{} given {} solved {} ({:+.2} %)",
                        p.column_px,
                        p.row_px,
                        shown(p.given),
                        shown(p.solved),
                        100.0 * p.relative_residual
                    ))
                    .collect::<Vec<_>>()
                    .join("; ")
            ));
            if let Some(precision) = &fit.scale_precision {
                let points = fit.points.len();
                match precision.warning(points) {
                    Some(warning) => loose_scale_warning = Some(warning),
                    None => notes.push(precision.words(points)),
                }
            }
            if let Some(worst) = fit
                .points
                .iter()
                .max_by(|a, b| {
                    a.relative_residual
                        .abs()
                        .total_cmp(&b.relative_residual.abs())
                })
                .filter(|p| p.relative_residual.abs() > KNOWN_DEPTH_MET)
            {
                known_depth_warning = Some(format!(
                    "--known-depth is not met: pixel {},{} (working size) is at {} for the \
                     given {} ({:+.2} %){}; the depth unit is off by about that much",
                    worst.column_px,
                    worst.row_px,
                    shown(worst.solved),
                    shown(worst.given),
                    100.0 * worst.relative_residual,
                    if fit.points.len() > 1 {
                        " (several points: they may disagree with each other)"
                    } else if fit.converged {
                        ""
                    } else {
                        " (the scale search did not settle)"
                    }
                ));
            }
        }
        if let Some(median) = unit.fit.as_ref().and_then(|f| f.median_depth)
            && median.relative_residual.abs() > KNOWN_DEPTH_MET
            && unit.source == solver::depth_unit::UnitSource::Distance
        {
            known_depth_warning = Some(format!(
                "--distance is not met: the surface's median depth is {} for the given {} \
                 ({:+.2} %); the depth unit is off by about that much",
                shown(median.solved),
                shown(median.given),
                100.0 * median.relative_residual
            ));
        }
    }
    if let Some(bar) = &progress.bar {
        bar.finish_and_clear();
    }
    // With `--albedo auto` every solve (the searches' too) estimated the
    // albedo and compared it with albedo 1 at its own scale
    // (`solver::albedo_fit`); the reprojection is the photograph's.
    let (solution, depth_unit) =
        solved.with_context(|| format!("cannot solve {}", args.images[0].display()))?;
    let model = problem.model(solution.material);
    let errors = match &ground_truth {
        Some(gt) => Some(metrics::errors_with_model(
            &solution.depth,
            &gt.depth,
            &gt.image,
            camera,
            &model,
        )?),
        None => None,
    };
    let domain = solution.depth.map(|z| z.is_finite());
    let fit_confidence = problem.confidence.clone();
    // A sum of photographs is saturated where one of them was, not where
    // its value is.
    let sum_divisor = prepared.report.sum_divisor.unwrap_or(1.0);
    let model_fit = model_fit::measure_photographs(
        &problem.image,
        &solution.reprojection,
        &domain,
        fit_confidence.as_ref(),
        solution.scales.intensity,
        model_fit::Photographs {
            saturated: prepared.clipped.as_ref(),
            scale: sum_divisor,
        },
    );
    // Geometry of the solved surface: where it grazes the view beside a
    // brighter surface (what lies behind was joined to the contour).
    let occlusion_edges = model_fit::occlusion_edges(&problem.image, &solution.depth, camera);
    let model_fit = model_fit.with_occlusion_edges(&occlusion_edges, &solution.depth);
    let model_fit_per_photo = photo::fit_per_photo(
        &prepared.photos,
        &solution,
        camera,
        problem.intensity_scale,
        fit_confidence.as_ref(),
        sum_divisor,
    );
    let residual = model_fit::residual_map(
        &problem.image,
        &solution.reprojection,
        &domain,
        solution.scales.intensity,
    );

    io::write_npy_f32(&stage.path("depth.npy"), &solution.depth)?;
    io::write_png16(&stage.path("reprojection.png"), &solution.reprojection)?;
    io::write_png16(&stage.path("input_linear.png"), &problem.image)?;
    // Residual in [-0.5, 0.5] I_ref mapped to [0, 1]: grey 0.5 = explained.
    io::write_png8(
        &stage.path("residual.png"),
        &residual.map(|v| if v.is_finite() { 0.5 + v } else { 0.5 }),
    )?;
    if let Some(c) = &problem.confidence
        && confidence_derived
    {
        io::write_png8(&stage.path("confidence_used.png"), c)?;
    }
    if let Some(shadow) = &solution.shadow {
        io::write_mask_png(&stage.path("shadow.png"), shadow)?;
    }
    io::write_mask_png(&stage.path("occlusion_edges.png"), &occlusion_edges)?;
    if let Some(fit) = &solution.albedo_fit {
        // Relative: the object's 90th percentile is 1.
        let used = fit.used_albedo(&solution.depth);
        io::write_npy_f32(&stage.path("albedo.npy"), &used)?;
        io::write_png16(
            &stage.path("albedo.png"),
            &used.map(|a| if a.is_finite() { *a } else { 0.0 }),
        )?;
    }
    let object_pixels = problem
        .object_mask
        .as_ref()
        .map_or(problem.image.len(), |m| {
            m.as_slice().iter().filter(|&&o| o).count()
        });
    let shadow_share = solution.shadow.as_ref().map(|shadow| {
        shadow.as_slice().iter().filter(|&&s| s).count() as f64 / object_pixels.max(1) as f64
    });
    let depth_range = io::write_depth_png16(&stage.path("depth16.png"), &solution.depth)?;
    io::write_depth_ply(
        &stage.path("mesh.ply"),
        &solution.depth,
        &camera,
        Some(&solution.reprojection),
    )?;
    let mut warnings: Vec<String> = model_fit.warnings.clone();
    if let Some(w) = depth_unit.warning(unit_name) {
        warnings.insert(0, w);
    }
    if let Some(w) = known_depth_warning {
        warnings.insert(0, w);
    }
    if let Some(w) = loose_scale_warning {
        warnings.insert(0, w);
    }
    if let Some(fit) = &solution.material_fit
        && !fit.best.is_lambert()
    {
        warnings.push(fit.summary.clone());
    }
    if let Some(close) = solution.albedo_fit.as_ref().and_then(|f| f.close_call()) {
        warnings.push(format!("albedo: {close}"));
    }
    warnings.extend(sfs_core::light::lights_that_miss(
        &problem.lights,
        &solution.depth,
        &camera,
    ));
    warnings.extend(unused_options.iter().map(|u| format!("unused option {u}")));
    if let Some(d) = dark
        && !warnings.iter().any(|w| w.contains("too dark"))
    {
        warnings.insert(0, d);
    }
    photo_report.camera.intensity_scale = problem.intensity_scale;
    photo_report.lights = problem.lights.clone();
    let report = SolveReport {
        input: SolveInput {
            photo: photo_report,
            known_depth: args.known_depth.clone(),
            distance: args.distance,
        },
        depth_unit: &depth_unit,
        notes: &notes,
        parameters: params_json(&params, args),
        material: solution.material,
        material_fit: solution.material_fit.as_ref(),
        albedo_fit: solution.albedo_fit.as_ref(),
        alpha_used: solution.alpha,
        alpha_px: solution.alpha_px,
        lambda_px: solution.lambda_px,
        scales: &solution.scales,
        initial_depth: solution.initial_depth,
        levels: &solution.levels,
        phases: &solution.phases,
        final_energy: &solution.final_energy,
        seconds: solution.seconds,
        model_fit: &model_fit,
        model_fit_per_photo: &model_fit_per_photo,
        shadow_share,
        unused_options: &unused_options,
        warnings: &warnings,
        depth16_png_range: depth_range.map(|(near_white, far_black)| DepthRange {
            near_white,
            far_black,
        }),
        rse: errors.map(|e| e.rse),
        rie: errors.map(|e| e.rie),
    };
    io::write_json(&stage.path("report.json"), &report)?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", args.out.display()))?;
    let levels = solution.levels.len();
    let mut summary = format!(
        "solved {} in {:.2} s ({} level{}{}{}) -> {}",
        args.images[0].display(),
        solution.seconds,
        levels,
        if levels == 1 { "" } else { "s" },
        if matches!(params.initial_depth, InitialDepth::FastMarching) && centred {
            " after the fast-marching start"
        } else {
            ""
        },
        if solution.alpha.is_finite() {
            format!(
                ", alpha {:.3e} {}",
                solution.alpha,
                match params.units {
                    parameters::Units::Relative => "relative",
                    parameters::Units::Paper => "paper units",
                }
            )
        } else {
            String::new()
        },
        args.out.display()
    );
    if let Some(e) = errors {
        summary.push_str(&format!("  rse {:.5} rie {:.5}", e.rse, e.rie));
    }
    if !args.quiet {
        for note in &notes {
            eprintln!("{note}");
        }
        eprintln!("{summary}");
        if !solution.material.is_lambert() || solution.material_fit.is_some() {
            eprintln!("reflectance: {}", solution.material.describe());
        }
        if let Some(fit) = solution
            .material_fit
            .as_ref()
            .filter(|f| f.best.is_lambert())
        {
            eprintln!(
                "material fit ({} px working copy, {:.1} s): {}",
                fit.working_side, fit.seconds, fit.summary
            );
        }
        eprintln!(
            "model fit: RIE {:.3} over trusted pixels, {:.0} % badly explained, {:.0} % \
             near-black, {:.1} % saturated",
            model_fit.rie_trusted,
            100.0 * model_fit.poor_share,
            100.0 * model_fit.near_black_share,
            100.0 * model_fit.saturated_share
        );
        for each in &model_fit_per_photo {
            let name = each.image.file_name().map_or_else(
                || each.image.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            eprintln!(
                "  {name} alone, its own light: RIE {:.3}, {:.0} % badly explained, {:.0} % \
                 near-black, {:.1} % saturated",
                each.fit.rie_trusted,
                100.0 * each.fit.poor_share,
                100.0 * each.fit.near_black_share,
                100.0 * each.fit.saturated_share
            );
        }
        if let Some(fit) = &solution.albedo_fit {
            eprintln!(
                "albedo (decided at {} px, {:.1} s): {}",
                fit.working_side, fit.seconds, fit.summary
            );
        }
        if let Some(share) = shadow_share {
            eprintln!(
                "shadow: {:.1} % of the object taken out of the data term (no light reaches it; shadow.png)",
                100.0 * share
            );
        }
    }
    // Warnings are never quiet (--quiet drops the progress, notes and
    // summary only).
    for warning in &warnings {
        eprintln!("warning: {warning}");
    }
    Ok(())
}

/// Every parameter as JSON, for the report: the table's, the method and
/// the initial depth as given.
fn params_json(params: &SolverParams, args: &SolveArgs) -> serde_json::Value {
    let mut json = parameters::table::to_json(params);
    if let Some(object) = json.as_object_mut() {
        object.insert("method".into(), json!(args.method.method().name()));
        object.insert(
            "init_depth".into(),
            json!(
                args.init_depth
                    .clone()
                    .unwrap_or_else(|| "fast-marching".into())
            ),
        );
    }
    json
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A known depth of 1e-6 was printed as "given 0.0000".
    #[test]
    fn tiny_and_huge_depths_are_shown_with_their_digits() {
        assert_eq!(shown(1e-6), "1.0000e-6");
        assert_eq!(shown(1e14), "1.0000e14");
        assert_eq!(shown(2.5), "2.5000");
        assert_eq!(shown(0.0), "0.0000");
    }
}
