//! `sfs-studio solve`: recover depth from an image and write depth, mesh,
//! reprojection and a JSON report.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use serde_json::json;

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::io::{self, OutputStage};
use crate::metrics;
use crate::params::{self as parameters, InitialDepth, SolverParams};
use crate::solver::{self, IterationReport, Problem, SolveObserver};

/// Arguments of `solve`. Defaults are the paper's where it gives one.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SolveArgs {
    /// Input image: 8/16-bit PNG, TIFF or JPEG, read as linear values in [0, 1]
    /// (colour converted to luminance).
    pub image: PathBuf,
    /// Camera file (scene.json keys: width, height, focal, cx, cy,
    /// intensity_scale; all in pixels except the scale).
    #[arg(long, conflicts_with_all = ["focal", "cx", "cy"])]
    pub camera: Option<PathBuf>,
    /// Focal length in pixels (instead of --camera).
    #[arg(long)]
    pub focal: Option<f64>,
    /// Principal point column in pixels [default: (width-1)/2].
    #[arg(long, requires = "focal")]
    pub cx: Option<f64>,
    /// Principal point row in pixels [default: (height-1)/2].
    #[arg(long, requires = "focal")]
    pub cy: Option<f64>,
    /// Intensity scale s (albedo x light power) [default: the camera file's, else 1].
    #[arg(long)]
    pub intensity_scale: Option<f64>,
    /// Object mask image (white = object, black = no surface) [default: every pixel].
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Confidence image in [0, 1] (black = do not trust, e.g. highlights) [default: 1].
    #[arg(long)]
    pub confidence: Option<PathBuf>,
    /// Linearise an sRGB-encoded photograph before solving.
    #[arg(long)]
    pub srgb: bool,
    /// Initial depth: `fast-marching` (default: fast marching on the image,
    /// denoised when noisy, then refined at full resolution), `from-image`
    /// (the paper's constant depth from the brightest pixel, then the whole
    /// pyramid), a number (a constant depth, depth units), or a `.npy` depth
    /// map to refine at full resolution.
    #[arg(long, value_name = "fast-marching|from-image|Z|FILE.npy")]
    pub init_depth: Option<String>,
    /// The scheme: `linearised` (the paper's, default), `explicit` (Ju et
    /// al.'s gradient descent on the same energy) or `fast-marching`
    /// (Prados-Faugeras by fast marching; ignores the confidence and the
    /// energy's parameters).
    #[arg(long, value_enum, default_value = "linearised")]
    pub method: MethodArg,
    /// Solver parameters (one option per entry of the parameter table).
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// Ground-truth folder written by `synth`: adds rse and rie to the report.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Output folder (created if needed): depth.npy, depth16.png,
    /// reprojection.png, mesh.ply, report.json.
    #[arg(long)]
    pub out: PathBuf,
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
        Ok(params)
    }
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

/// Ground truth of a synth folder.
pub struct GroundTruth {
    /// Depth, NaN on the background.
    pub depth: Grid<f64>,
    /// Noise-free image.
    pub image: Grid<f64>,
}

/// Reads `DIR/depth_gt.npy` and `DIR/image16.png`.
pub fn read_ground_truth(dir: &Path) -> Result<GroundTruth> {
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

/// Reads a mask image and checks its size.
fn read_sized_mask(path: &Path, what: &str, size: (usize, usize)) -> Result<Grid<f64>> {
    let mask = io::read_mask(path)?;
    if mask.size() != size {
        bail!(
            "{what} {} is {}x{} but the image is {}x{}",
            path.display(),
            mask.width(),
            mask.height(),
            size.0,
            size.1
        );
    }
    Ok(mask)
}

/// Runs `solve`.
pub fn run(args: &SolveArgs) -> Result<()> {
    let image = io::read_image(&args.image, args.srgb)?;
    let size = image.size();
    let (camera, file_scale) = match (&args.camera, args.focal) {
        (Some(path), _) => {
            let file = io::read_camera(path)?;
            file.validate(path)?;
            if (file.width, file.height) != size {
                bail!(
                    "camera file {} is for {}x{} images but {} is {}x{}",
                    path.display(),
                    file.width,
                    file.height,
                    args.image.display(),
                    size.0,
                    size.1
                );
            }
            (file.intrinsics(), Some(file.intensity_scale))
        }
        (None, Some(focal)) => {
            let mut camera = Intrinsics::centred(focal, size.0, size.1);
            if let Some(cx) = args.cx {
                camera.principal_x_px = cx;
            }
            if let Some(cy) = args.cy {
                camera.principal_y_px = cy;
            }
            (camera, None)
        }
        (None, None) => bail!("no camera: give --camera FILE or --focal F (pixels)"),
    };
    let intensity_scale = args.intensity_scale.or(file_scale).unwrap_or(1.0);
    let object_mask = match &args.mask {
        Some(path) => Some(read_sized_mask(path, "mask", size)?.map(|&v| v >= 0.5)),
        None => None,
    };
    let confidence = match &args.confidence {
        Some(path) => Some(read_sized_mask(path, "confidence", size)?),
        None => None,
    };
    let ground_truth = match &args.gt {
        Some(dir) => {
            let gt = read_ground_truth(dir)?;
            if gt.depth.size() != size {
                bail!(
                    "ground truth in {} does not match the image size",
                    dir.display()
                );
            }
            Some(gt)
        }
        None => None,
    };
    let params = args.params(size)?;
    let problem = Problem {
        image,
        camera,
        intensity_scale,
        object_mask,
        confidence,
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
        kappa: params.kappa,
    };
    let solution = solver::solve_method(&problem, &params, &args.method.method(), &mut progress);
    if let Some(bar) = &progress.bar {
        bar.finish_and_clear();
    }
    let solution = solution.with_context(|| format!("cannot solve {}", args.image.display()))?;
    let errors = match &ground_truth {
        Some(gt) => Some(metrics::errors(
            &solution.depth,
            &gt.depth,
            &gt.image,
            camera,
            intensity_scale,
        )?),
        None => None,
    };

    let mut stage = OutputStage::new(&args.out)?;
    io::write_npy_f32(&stage.path("depth.npy"), &solution.depth)?;
    io::write_png16(&stage.path("reprojection.png"), &solution.reprojection)?;
    let depth_range = io::write_depth_png16(&stage.path("depth16.png"), &solution.depth)?;
    io::write_depth_ply(
        &stage.path("mesh.ply"),
        &solution.depth,
        &camera,
        Some(&solution.reprojection),
    )?;
    let report = json!({
        "input": {
            "image": args.image,
            "width": size.0,
            "height": size.1,
            "srgb": args.srgb,
            "mask": args.mask,
            "confidence": args.confidence,
            "camera": {
                "focal": camera.focal_px,
                "cx": camera.principal_x_px,
                "cy": camera.principal_y_px,
                "intensity_scale": intensity_scale,
            },
        },
        "parameters": params_json(&params, args),
        "alpha_used": solution.alpha,
        "alpha_px": solution.alpha_px,
        "lambda_px": solution.lambda_px,
        "scales": solution.scales,
        "initial_depth": solution.initial_depth,
        "levels": solution.levels,
        "phases": solution.phases,
        "final_energy": solution.final_energy,
        "seconds": solution.seconds,
        "depth16_png_range": depth_range.map(|(near, far)| json!({"near_white": near, "far_black": far})),
        "rse": errors.map(|e| e.rse),
        "rie": errors.map(|e| e.rie),
    });
    io::write_json(&stage.path("report.json"), &report)?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", args.out.display()))?;
    let levels = solution.levels.len();
    let mut summary = format!(
        "solved {} in {:.2} s ({} level{}{}{}) -> {}",
        args.image.display(),
        solution.seconds,
        levels,
        if levels == 1 { "" } else { "s" },
        if matches!(params.initial_depth, InitialDepth::FastMarching) {
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
        eprintln!("{summary}");
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
