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
use crate::model::Derivatives;
use crate::params::{DomainMode, InitialDepth, SmoothnessUnits, SolverParams, StepControl};
use crate::solver::{self, IterationReport, Problem, SolveObserver};

/// How dD/dz is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DerivativesArg {
    /// Exact (analytic) derivatives.
    Exact,
    /// Central differences with step --h-z (the paper's).
    Numeric,
}

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
    /// Smoothness weight alpha, in --smoothness-units (pixel units: 30 to 300
    /// suited clean 256x256 images, about 2000 noisy ones; the paper used
    /// 0.003 to 3).
    #[arg(long, default_value_t = SolverParams::default().alpha)]
    pub alpha: f64,
    /// Charbonnier contrast lambda (paper: 1e-3).
    #[arg(long, default_value_t = SolverParams::default().lambda)]
    pub lambda: f64,
    /// Units of alpha and lambda: `pixel` (the paper's) or `normalized` (the
    /// same values give the same smoothness at any image size; they refer to
    /// a 256 px focal length: alpha_px = alpha (f/256)^4, lambda_px = lambda (256/f)^2).
    #[arg(long, value_enum, default_value = "pixel")]
    pub smoothness_units: SmoothnessUnitsArg,
    /// Pyramid downsampling factor eta in (0, 1) (paper: 0.9).
    #[arg(long, default_value_t = SolverParams::default().eta)]
    pub eta: f64,
    /// Outer Gauss-Newton iterations kappa per level (paper: 5).
    #[arg(long, default_value_t = SolverParams::default().kappa)]
    pub kappa: usize,
    /// Inner fixed-point iterations l_max on Psi' (paper: 9).
    #[arg(long, default_value_t = SolverParams::default().inner_iterations)]
    pub inner_iters: usize,
    /// SOR sweeps per inner iteration (paper: 10).
    #[arg(long, default_value_t = SolverParams::default().sor_iterations)]
    pub sor_iters: usize,
    /// SOR relaxation omega in (0, 2).
    #[arg(long, default_value_t = SolverParams::default().omega)]
    pub omega: f64,
    /// Largest depth change per pixel and outer iteration, depth units (paper: 0.01).
    #[arg(long, default_value_t = SolverParams::default().dz_limit)]
    pub dz_limit: f64,
    /// Initial depth: a number (constant depth, depth units) or a .npy depth
    /// map to refine at full resolution [default: from the brightest pixel].
    #[arg(long, value_name = "Z|FILE.npy")]
    pub init_depth: Option<String>,
    /// Derivatives of the residual.
    #[arg(long, value_enum, default_value = "exact")]
    pub derivatives: DerivativesArg,
    /// Perturbation h_z of numeric derivatives, depth units (paper: 1e-12).
    #[arg(long, default_value_t = 1e-12)]
    pub h_z: f64,
    /// Smallest side of the coarsest pyramid level, pixels.
    #[arg(long, default_value_t = SolverParams::default().min_level_side)]
    pub min_level_side: usize,
    /// `paper`: every pixel carries depth, the background only has
    /// confidence 0 (lowest RSE at the default alpha); `object`: only mask
    /// pixels do (better image fit, faster).
    #[arg(long, value_enum, default_value = "paper")]
    pub domain: DomainArg,
    /// `crop` (the paper's) or `backtracking` (crop, then halve the step
    /// until the energy does not increase).
    #[arg(long, value_enum, default_value = "backtracking")]
    pub step_control: StepControlArg,
    /// Pyramid anti-aliasing sigma_0 (0: sample every level from the full
    /// image, keeping bright peaks).
    #[arg(long, default_value_t = SolverParams::default().anti_alias_sigma)]
    pub anti_alias: f64,
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

/// `--smoothness-units`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SmoothnessUnitsArg {
    /// Per full-resolution pixel (the paper's).
    Pixel,
    /// Resolution independent.
    Normalized,
}

/// `--domain`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DomainArg {
    /// Object pixels only.
    Object,
    /// Every pixel, background with confidence 0.
    Paper,
}

/// `--step-control`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StepControlArg {
    /// Per-pixel crop.
    Crop,
    /// Crop and backtrack on the energy.
    Backtracking,
}

impl SolveArgs {
    /// Solver parameters from the arguments (validated by the solver).
    pub fn params(&self, image_size: (usize, usize)) -> Result<SolverParams> {
        let initial_depth = match &self.init_depth {
            None => InitialDepth::FromImage,
            Some(text) => match text.parse::<f64>() {
                Ok(z) => InitialDepth::Constant(z),
                Err(_) => {
                    let map = io::read_npy(Path::new(text))?;
                    if map.size() != image_size {
                        bail!(
                            "initial depth {text} is {}x{} but the image is {}x{}",
                            map.width(),
                            map.height(),
                            image_size.0,
                            image_size.1
                        );
                    }
                    InitialDepth::Map(map)
                }
            },
        };
        Ok(SolverParams {
            alpha: self.alpha,
            lambda: self.lambda,
            smoothness_units: match self.smoothness_units {
                SmoothnessUnitsArg::Pixel => SmoothnessUnits::Pixel,
                SmoothnessUnitsArg::Normalized => SmoothnessUnits::Normalized,
            },
            eta: self.eta,
            kappa: self.kappa,
            inner_iterations: self.inner_iters,
            sor_iterations: self.sor_iters,
            omega: self.omega,
            dz_limit: self.dz_limit,
            derivatives: match self.derivatives {
                DerivativesArg::Exact => Derivatives::Exact,
                DerivativesArg::Numeric => Derivatives::Numeric { h_z: self.h_z },
            },
            min_level_side: self.min_level_side,
            domain: match self.domain {
                DomainArg::Object => DomainMode::Object,
                DomainArg::Paper => DomainMode::Paper,
            },
            initial_depth,
            step_control: match self.step_control {
                StepControlArg::Crop => StepControl::Crop,
                StepControlArg::Backtracking => StepControl::Backtracking,
            },
            anti_alias_sigma: self.anti_alias,
        })
    }
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
    let solution = solver::solve(&problem, &params, &mut progress);
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
    let mut summary = format!(
        "solved {} in {:.2} s ({} levels) -> {}",
        args.image.display(),
        solution.seconds,
        solution.levels.len(),
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

/// Every parameter as JSON, for the report.
fn params_json(params: &SolverParams, args: &SolveArgs) -> serde_json::Value {
    json!({
        "alpha": params.alpha,
        "lambda": params.lambda,
        "smoothness_units": params.smoothness_units,
        "eta": params.eta,
        "kappa": params.kappa,
        "inner_iterations": params.inner_iterations,
        "sor_iterations": params.sor_iterations,
        "omega": params.omega,
        "dz_limit": params.dz_limit,
        "derivatives": params.derivatives,
        "min_level_side": params.min_level_side,
        "domain": params.domain,
        "step_control": params.step_control,
        "anti_alias_sigma": params.anti_alias_sigma,
        "initial_depth": args.init_depth.clone().unwrap_or_else(|| "from_image".into()),
    })
}
