//! `sfs-studio view` (and no subcommand): open the viewer.

use std::path::PathBuf;

use anyhow::{Result, anyhow};
use clap::Args;

use sfs_viewer::app::ViewerOptions;

/// Options of `sfs-studio view`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct ViewArgs {
    /// Image to open (8/16-bit PNG, TIFF, JPEG). A `scene.json`,
    /// `mask.png` and `depth_gt.npy` beside it (a `synth` folder) are used.
    #[arg(value_parser = super::parse_path)]
    pub image: PathBuf,
    /// Camera file (keys of `synth`'s scene.json).
    #[arg(long, value_parser = super::parse_path)]
    pub camera: Option<PathBuf>,
    /// Object mask PNG (255 = object).
    #[arg(long, value_parser = super::parse_path)]
    pub mask: Option<PathBuf>,
    /// sRGB decoding: `on`, `off` or `auto` (on for JPEG and 8-bit
    /// photographs, off for 16-bit, float and linear-marked PNGs); `--srgb`
    /// alone means on.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on")]
    pub srgb: super::solve::SrgbArg,
    /// Smoothness weight alpha in relative units, or `auto` (else the
    /// remembered value; default auto).
    #[arg(long)]
    pub alpha: Option<String>,
    /// Working size: a longer image side is area-averaged down to this many
    /// pixels before solving (0 = full size; else the remembered value,
    /// default 1500).
    #[arg(long, value_name = "PIXELS")]
    pub max_side: Option<usize>,
    /// Save a screenshot here once the solve has finished, then exit.
    #[arg(long, value_name = "PATH.png", value_parser = super::parse_path)]
    pub screenshot: Option<PathBuf>,
    /// Write UI frame-time statistics (JSON) here on exit.
    #[arg(long, value_name = "PATH.json", value_parser = super::parse_path)]
    pub stats: Option<PathBuf>,
    /// With --stats: after the first solve, change alpha this many times and
    /// time each change to the first new level on screen.
    #[arg(long, default_value_t = 0)]
    pub latency_trials: usize,
    /// Window size in points, WIDTHxHEIGHT.
    #[arg(long, value_parser = super::parse_size, default_value = "1280x800")]
    pub window: (usize, usize),
}

/// Opens the viewer on `args.image`.
pub fn run(args: &ViewArgs) -> Result<()> {
    let alpha = match &args.alpha {
        Some(text) => {
            let spec = sfs_core::params::table::spec("alpha")
                .ok_or_else(|| anyhow!("no alpha in the parameter table"))?;
            Some(match spec.parse(text)? {
                sfs_core::params::ParamValue::Real(v) => sfs_core::params::Alpha::Value(v),
                _ => sfs_core::params::Alpha::Auto,
            })
        }
        None => None,
    };
    if !args.image.is_file() {
        return Err(anyhow!("image {} does not exist", args.image.display()));
    }
    let options = ViewerOptions {
        image: Some(args.image.clone()),
        camera: args.camera.clone(),
        mask: args.mask.clone(),
        srgb: match args.srgb {
            super::solve::SrgbArg::On => Some(true),
            super::solve::SrgbArg::Off => Some(false),
            super::solve::SrgbArg::Auto => None,
        },
        alpha,
        max_side: args.max_side,
        screenshot: args.screenshot.clone(),
        stats: args.stats.clone(),
        latency_trials: args.latency_trials,
        ..ViewerOptions::default()
    };
    launch(options, args.window)
}

/// Opens the viewer on the built-in sample.
pub fn run_sample(screenshot: Option<PathBuf>) -> Result<()> {
    launch(
        ViewerOptions {
            screenshot,
            ..ViewerOptions::default()
        },
        (1280, 800),
    )
}

fn launch(options: ViewerOptions, window: (usize, usize)) -> Result<()> {
    sfs_viewer::app::run_window(options, window)
}
