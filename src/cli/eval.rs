//! `sfs-studio eval`: RSE and RIE of a depth map against a synth folder.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use sfs_core::io;
use sfs_core::light::LightModel;
use sfs_core::metrics;

/// Arguments of `eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Depth map (.npy, H x W, NaN where there is no object).
    #[arg(long)]
    pub depth: PathBuf,
    /// Folder written by `synth` (depth_gt.npy, image16.png, scene.json).
    #[arg(long)]
    pub gt: PathBuf,
    /// The material the RIE is measured with [default: scene.json's, else
    /// lambert].
    #[command(flatten)]
    pub material: super::lights::MaterialArgs,
}

/// Runs `eval`: prints `{"rse": .., "rie": ..}`.
pub fn run(args: &EvalArgs) -> Result<()> {
    let depth = io::read_npy(&args.depth)?;
    let gt = sfs_core::io::ground_truth::read_ground_truth(&args.gt)?;
    let camera_path = args.gt.join("scene.json");
    let camera = sfs_core::camera_file::read_camera(&camera_path)?;
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
    let intrinsics = camera.intrinsics_for(&camera_path, gt.depth.size())?;
    let (lights, _) = camera.lights_for(&camera_path, &[], None)?;
    let material = match args.material.material()? {
        Some(m) => m,
        None => camera
            .material
            .map(|m| {
                m.validated()
                    .map_err(|e| anyhow::anyhow!("{}: material: {e}", camera_path.display()))
            })
            .transpose()?
            .unwrap_or_default(),
    };
    let model = LightModel::with_material(camera.intensity_scale.unwrap_or(1.0), &lights, material);
    let errors = metrics::errors_with_model(&depth, &gt.depth, &gt.image, intrinsics, &model)
        .with_context(|| format!("cannot evaluate {}", args.depth.display()))?;
    println!("{}", serde_json::to_string(&errors)?);
    Ok(())
}
