//! Every file name the tool writes into an output folder, in one place:
//! `solve`, `solve --photometric-stereo` and `synth` (one image or a set)
//! each stage their output with this one list, so a run removes what an
//! earlier run of any of them left in the folder and this run does not
//! write (a single-image solve's `reprojection.png` after a set's solve, a
//! set's `normals.png` after a single-image one, `noisy8.png` after a run
//! without noise). Only these names are ever removed, and only those the
//! previous run there wrote (its manifest), never a file the run reads.

use std::path::Path;

use super::stage::OutputStage;
use crate::io::IoError;

/// The most photographs of a set whose numbered files are named here
/// (`residual_NN.png`, `ledNN.png`, `clean_ledNN.png`).
pub const MAX_SET: usize = 64;

/// The fixed names.
const FIXED: &[&str] = &[
    // solve (one photograph)
    "depth.npy",
    "reprojection.png",
    "input_linear.png",
    "residual.png",
    "confidence_used.png",
    "shadow.png",
    "occlusion_edges.png",
    "depth16.png",
    "mesh.ply",
    "albedo.npy",
    "albedo.png",
    "report.json",
    // solve --photometric-stereo (also depth, mesh, albedo, report)
    "normals.npy",
    "normals.png",
    "single_depth.npy",
    "single_depth16.png",
    // synth (also shadow.png)
    "image16.png",
    "image8.png",
    "noisy8.png",
    "confidence.png",
    "mask.png",
    "depth_gt.npy",
    "scene.json",
    // synth --ps-leds (also mask, depth_gt, scene)
    "normals_gt.npy",
    "albedo_gt.npy",
];

/// Every file name the tool may write into an output folder.
pub fn all() -> Vec<String> {
    FIXED
        .iter()
        .map(|s| (*s).to_owned())
        .chain((1..=MAX_SET).flat_map(|k| {
            [
                format!("residual_{k:02}.png"),
                format!("led{k:02}.png"),
                format!("clean_led{k:02}.png"),
            ]
        }))
        .collect()
}

/// Starts staging a command's output into `dir` with the tool's list of
/// output names ([`all`]).
pub fn stage(dir: &Path) -> Result<OutputStage, IoError> {
    let owned = all();
    let owned: Vec<&str> = owned.iter().map(String::as_str).collect();
    OutputStage::new(dir, &owned)
}

/// The files of a ground-truth folder (`--gt DIR`) a solve reads: kept
/// when the output folder is that folder.
pub fn ground_truth_files(dir: &Path) -> Vec<std::path::PathBuf> {
    [
        "depth_gt.npy",
        "image16.png",
        "normals_gt.npy",
        "albedo_gt.npy",
    ]
    .iter()
    .map(|name| dir.join(name))
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every name a run writes is on the one list: a name written but not
    /// listed would survive a run of another kind.
    #[test]
    fn the_list_holds_every_kind_of_runs_names_once() {
        let all = all();
        for name in [
            "reprojection.png",
            "normals.png",
            "residual_03.png",
            "noisy8.png",
            "led12.png",
            "clean_led64.png",
        ] {
            assert!(all.iter().any(|n| n == name), "{name}");
        }
        let mut sorted = all.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), all.len(), "a name listed twice");
    }
}
