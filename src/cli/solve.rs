//! `sfs-studio solve`: recover depth from an image and write depth, mesh,
//! reprojection and a JSON report.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use sfs_core::io::SrgbMode;
use sfs_core::io::ground_truth::{self, check_ground_truth, read_ground_truth};
use sfs_core::metrics;
use sfs_core::model_fit;
use sfs_core::output::many;
use sfs_core::params::{self as parameters, InitialDepth, SolverParams};
use sfs_core::photo::{self, PhotoInput};
use sfs_core::photograph_solve::SolvedPhotograph;
use sfs_core::photograph_solve::options::SolveOptions;
use sfs_core::solver::{self, IterationReport, SolveObserver};

/// Arguments of `solve`. Defaults are the paper's where it gives one.
#[derive(Clone, Debug, Args)]
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
    #[arg(long, value_name = "X,Y,Z", value_parser = super::parse::parse_floats::<3>)]
    pub known_depth: Vec<[f64; 3]>,
    /// The object is about this far from the camera (its median depth, in
    /// the camera file's unit, e.g. mm): sets the depth unit (and s) as
    /// --known-depth does, without picking a pixel [default: from the
    /// set-up (where its LEDs are aimed) or the photograph's shading].
    #[arg(long, value_name = "DEPTH", conflicts_with = "known_depth")]
    pub distance: Option<f64>,
    /// Where the lights are.
    #[command(flatten)]
    pub lights: super::lights::LightArgs,
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
    pub params: super::params::ParamArgs,
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
    #[arg(
        long,
        required_unless_present = "out_dir",
        default_value = ".",
        hide_default_value = true
    )]
    pub out: PathBuf,
    /// Many photographs, each solved alone (instead of --out): the
    /// photographs given, those of a folder (PNG, JPEG, TIFF) or of a
    /// pattern (`'DIR/*.png'`), each into DIR/NAME (its file name less the
    /// extension), with one progress bar and one summary table (file,
    /// seconds, fit, warnings) on stdout.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["out", "photometric_stereo", "init_depth"])]
    pub out_dir: Option<PathBuf>,
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

/// The default working size of `solve` (longest side, pixels): the
/// core's.
pub use sfs_core::photograph_solve::options::DEFAULT_MAX_SIDE;

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
    /// The options as the core reads them (the command line's syntax
    /// ends here; every check in the user's terms is the core's).
    pub fn options(&self) -> Result<SolveOptions> {
        Ok(SolveOptions {
            camera_file: self.camera.clone(),
            focal_px: self.focal,
            cx_px: self.cx,
            cy_px: self.cy,
            intensity_scale: self.intensity_scale.clone(),
            known_depth: self.known_depth.clone(),
            distance: self.distance,
            lights: self.lights.lights()?,
            light_index: self.lights.indices.clone(),
            mask: self.mask.clone(),
            confidence: self.confidence.clone(),
            auto_confidence: self.auto_confidence,
            srgb: self.srgb.mode(),
            ambient: self.ambient.clone(),
            vignetting: self.vignetting.clone(),
            albedo: self.albedo.clone(),
            max_side: self.max_side,
            init_depth: self.init_depth.clone(),
            method: self.method.method(),
            table: self.params.given().to_vec(),
        })
    }

    /// Solver parameters from the arguments for the working size
    /// `image_size`.
    pub fn params(&self, image_size: (usize, usize)) -> Result<SolverParams> {
        Ok(self.options()?.params(image_size)?)
    }
}

/// Progress on a terminal.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    kappa: usize,
}

impl SolveObserver for Progress {
    fn on_iteration(&mut self, report: &IterationReport) {
        if let Some(bar) = &self.bar {
            let (done, total, message) =
                sfs_core::photograph_solve::progress_step(report, self.kappa);
            bar.set_length(total);
            bar.set_position(done);
            bar.set_message(message);
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
        Ok(self.options()?.photo_input(images)?)
    }
}

/// Runs `solve` on one photograph, or with `--out-dir` on each photograph
/// given (`cli::run` hands `--photometric-stereo` to `cli::photometric`).
pub fn run(args: &SolveArgs) -> Result<()> {
    match &args.out_dir {
        Some(dir) => run_many(args, dir),
        None => solve_one(args, true).map(|_| ()),
    }
}

/// `solve --out-dir DIR`: each photograph solved alone into `DIR/NAME`
/// (the core's [`many`] names them and makes the table), a progress bar over
/// the photographs, the summary table on stdout; an error if any failed.
fn run_many(args: &SolveArgs, out_dir: &Path) -> Result<()> {
    let photos = many::photographs(&args.images)?;
    if photos.is_empty() {
        bail!(
            "no photograph (PNG, JPEG or TIFF) in {}",
            args.images[0].display()
        );
    }
    let names = many::folder_names(&photos);
    let bar = (!args.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(photos.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let mut rows = Vec::with_capacity(photos.len());
    for (photo, name) in photos.iter().zip(&names) {
        if let Some(bar) = &bar {
            bar.set_message(name.clone());
        }
        let mut one = args.clone();
        one.images = vec![photo.clone()];
        one.out = out_dir.join(name);
        one.out_dir = None;
        one.quiet = true;
        let start = std::time::Instant::now();
        let solved = solve_one(&one, false);
        let seconds = start.elapsed().as_secs_f64();
        rows.push(match solved {
            Ok(outcome) => many::Row {
                file: photo.clone(),
                seconds,
                fit: Some(outcome.fit),
                warnings: outcome.warnings,
                error: None,
            },
            Err(e) => many::Row {
                file: photo.clone(),
                seconds,
                fit: None,
                warnings: Vec::new(),
                error: Some(format!("{e:#}")),
            },
        });
        if let Some(bar) = &bar {
            bar.inc(1);
        }
    }
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    print!("{}", many::table(&rows));
    let failed = rows.iter().filter(|r| r.error.is_some()).count();
    if failed > 0 {
        bail!(
            "{failed} of {} photographs could not be solved (the table says why)",
            rows.len()
        );
    }
    Ok(())
}

/// What one photograph's solve gives the summary table.
struct Outcome {
    /// The model fit: RIE over trusted pixels.
    fit: f64,
    /// The solve's warnings (with the darkness warning).
    warnings: Vec<String>,
}

/// One photograph's solve into `args.out`; `say_warnings`: print the
/// warnings on stderr (a solve of many puts them in its table instead).
fn solve_one(args: &SolveArgs, say_warnings: bool) -> Result<Outcome> {
    if args.ps_smoothness != "auto" || args.ps_robust_scale != "auto" {
        bail!("--ps-smoothness and --ps-robust-scale need --photometric-stereo");
    }
    let options = args.options()?;
    let input = options.photo_input(&args.images)?;
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
    let job = options.job(prepared)?;
    let camera = job.problem.camera;
    let darkness =
        model_fit::darkness_warning(&job.problem.image, job.problem.object_mask.as_ref());
    if !args.quiet
        && let Some(warning) = &darkness
    {
        eprintln!("warning: {warning}");
    }
    let ground_truth = match &args.gt {
        Some(dir) => {
            let truth = read_ground_truth(dir)?;
            ground_truth::check_size(&truth, dir, size)?;
            Some(truth)
        }
        None => None,
    };
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
        kappa: job.params.kappa,
    };
    let solved = job.run_once(&mut progress);
    if let Some(bar) = &progress.bar {
        bar.finish_and_clear();
    }
    let solved = solved.with_context(|| format!("cannot solve {}", args.images[0].display()))?;
    let solution = &solved.solution;
    let problem = &solved.problem;
    let errors = match &ground_truth {
        Some(gt) => Some(metrics::errors_with_model(
            &solution.depth,
            &gt.depth,
            &gt.image,
            camera,
            &problem.model(solution.material),
        )?),
        None => None,
    };
    sfs_core::output::write_solved(&mut stage, &solved, errors.map(|e| (e.rse, e.rie)))?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", args.out.display()))?;
    if !args.quiet {
        print_summary(args, &solved, errors.map(|e| (e.rse, e.rie)));
    }
    // Warnings are never quiet (--quiet drops the progress, notes and
    // summary only).
    if say_warnings {
        for warning in &solved.warnings {
            eprintln!("warning: {warning}");
        }
    }
    Ok(Outcome {
        fit: solved.fit.rie_trusted,
        warnings: darkness
            .into_iter()
            .chain(solved.warnings.clone())
            .collect(),
    })
}

/// The notes, the one-line summary and the fits on stderr.
fn print_summary(args: &SolveArgs, solved: &SolvedPhotograph, errors: Option<(f64, f64)>) {
    let solution = &solved.solution;
    let params = &solved.params;
    let levels = solution.levels.len();
    let mut summary = format!(
        "solved {} in {:.2} s ({} level{}{}{}) -> {}",
        args.images[0].display(),
        solution.seconds,
        levels,
        if levels == 1 { "" } else { "s" },
        if matches!(params.initial_depth, InitialDepth::FastMarching)
            && solved.problem.light_is_centred()
        {
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
    if let Some((rse, rie)) = errors {
        summary.push_str(&format!("  rse {rse:.5} rie {rie:.5}"));
    }
    for note in &solved.notes {
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
    let fit = &solved.fit;
    eprintln!(
        "model fit: RIE {:.3} over trusted pixels, {:.0} % badly explained, {:.0} % \
         near-black, {:.1} % saturated",
        fit.rie_trusted,
        100.0 * fit.poor_share,
        100.0 * fit.near_black_share,
        100.0 * fit.saturated_share
    );
    for each in &solved.fit_per_photo {
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
    if let Some(share) = solved.shadow_share {
        eprintln!(
            "shadow: {:.1} % of the object taken out of the data term (no light reaches it; shadow.png)",
            100.0 * share
        );
    }
}
