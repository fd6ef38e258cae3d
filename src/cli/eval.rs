//! `sfs-studio eval`: RSE and RIE of a depth map against a synth folder.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use crate::io;
use crate::metrics;

/// Arguments of `eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Depth map (.npy, H x W, NaN where there is no object).
    #[arg(long)]
    pub depth: PathBuf,
    /// Folder written by `synth` (depth_gt.npy, image16.png, scene.json).
    #[arg(long)]
    pub gt: PathBuf,
}

/// Runs `eval`: prints `{"rse": .., "rie": ..}`.
pub fn run(args: &EvalArgs) -> Result<()> {
    let depth = io::read_npy(&args.depth)?;
    let gt = super::solve::read_ground_truth(&args.gt)?;
    let camera_path = args.gt.join("scene.json");
    let camera = io::read_camera(&camera_path)?;
    camera.validate(&camera_path)?;
    if depth.size() != gt.depth.size() {
        bail!(
            "depth {} is {}x{} but the ground truth is {}x{}",
            args.depth.display(),
            depth.width(),
            depth.height(),
            gt.depth.width(),
            gt.depth.height()
        );
    }
    let errors = metrics::errors(
        &depth,
        &gt.depth,
        &gt.image,
        camera.intrinsics(),
        camera.intensity_scale,
    )?;
    println!("{}", serde_json::to_string(&errors)?);
    Ok(())
}
