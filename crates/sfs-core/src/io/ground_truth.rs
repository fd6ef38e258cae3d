//! A ground-truth folder written by `synth` (`--gt DIR`): the true depth
//! (`depth_gt.npy`) and, for one photograph, the noise-free render
//! (`image16.png`). Checked before anything is solved, in the user's
//! terms, for every front.

use std::path::Path;

use crate::grid::Grid;

/// Why a folder cannot be the ground truth: a message naming the folder
/// and the file it lacks, in the command line's words (`--gt DIR`).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct GroundTruthError(pub String);

impl From<super::error::IoError> for GroundTruthError {
    fn from(e: super::error::IoError) -> Self {
        Self(e.to_string())
    }
}

/// The ground truth of a `synth` folder.
#[derive(Clone, Debug)]
pub struct GroundTruth {
    /// Depth, NaN on the background.
    pub depth: Grid<f64>,
    /// Noise-free image.
    pub image: Grid<f64>,
}

/// Refuses `--gt DIR` that cannot be the ground truth before anything is
/// solved: no such folder, or a folder without the files `synth` writes
/// (`depth_gt.npy`, and `image16.png` for one photograph, `with_image`).
pub fn check_ground_truth(dir: &Path, with_image: bool) -> Result<(), GroundTruthError> {
    if !dir.is_dir() {
        return Err(GroundTruthError(format!(
            "--gt {}: no such folder (--gt takes a folder written by `synth`)",
            dir.display()
        )));
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
            return Err(GroundTruthError(format!(
                "--gt {}: the folder has no {file} ({what} that `synth` writes); --gt takes a \
                 folder written by `synth`",
                dir.display()
            )));
        }
    }
    Ok(())
}

/// Reads `DIR/depth_gt.npy` and `DIR/image16.png` (of one size).
pub fn read_ground_truth(dir: &Path) -> Result<GroundTruth, GroundTruthError> {
    check_ground_truth(dir, true)?;
    let depth = super::npy::read_npy(&dir.join("depth_gt.npy"))?;
    let image = super::image::read_image(&dir.join("image16.png"), false)?;
    if depth.size() != image.size() {
        return Err(GroundTruthError(format!(
            "ground truth in {}: depth_gt.npy is {}x{} but image16.png is {}x{}",
            dir.display(),
            depth.width(),
            depth.height(),
            image.width(),
            image.height()
        )));
    }
    Ok(GroundTruth { depth, image })
}

/// Refuses ground truth of another size than the working size the
/// photograph is solved at.
pub fn check_size(
    truth: &GroundTruth,
    dir: &Path,
    size: (usize, usize),
) -> Result<(), GroundTruthError> {
    if truth.depth.size() == size {
        return Ok(());
    }
    Err(GroundTruthError(format!(
        "ground truth in {} is {}x{} but the image is solved at {}x{}",
        dir.display(),
        truth.depth.width(),
        truth.depth.height(),
        size.0,
        size.1
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder that is not `synth`'s is refused naming the file it lacks.
    #[test]
    fn a_folder_without_synths_files_names_what_it_lacks() {
        let dir = tempfile::tempdir().expect("temp dir");
        let err = check_ground_truth(dir.path(), true).expect_err("empty folder");
        assert!(err.0.contains("has no depth_gt.npy"), "{err}");
        let err = check_ground_truth(&dir.path().join("none"), false).expect_err("no folder");
        assert!(err.0.contains("no such folder"), "{err}");
    }
}
