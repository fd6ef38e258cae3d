//! A photometric-stereo folder: its camera file (`scene.json`, else
//! `calibration.json`) and the photographs its lights name. The one reader
//! of a set folder, for `view DIR` and `solve --photometric-stereo DIR`.

use std::path::{Path, PathBuf};

use super::input::PhotoError;

/// What a set folder holds.
#[derive(Clone, Debug, PartialEq)]
pub struct SetFolder {
    /// The folder's camera file.
    pub camera: PathBuf,
    /// The photographs its lights name (`image`) that are present, in the
    /// lights' order.
    pub images: Vec<PathBuf>,
}

/// The camera file a folder holds: `scene.json` (what `synth` writes),
/// else `calibration.json` (near_ps); `None` when it holds neither.
pub fn camera_file_in(folder: &Path) -> Option<PathBuf> {
    ["scene.json", "calibration.json"]
        .iter()
        .map(|name| folder.join(name))
        .find(|p| p.is_file())
}

impl SetFolder {
    /// The set `folder` holds.
    ///
    /// # Errors
    /// No camera file, one that cannot be read, or fewer than two named
    /// photographs present (the message names the folder and the file).
    pub fn find(folder: &Path) -> Result<Self, PhotoError> {
        let camera = camera_file_in(folder).ok_or_else(|| {
            PhotoError::Input(format!(
                "{} holds no scene.json or calibration.json: a photometric-stereo folder needs \
                 a camera file whose lights name each photograph (`image`)",
                folder.display()
            ))
        })?;
        let file = crate::camera_file::read_camera(&camera)?;
        let images: Vec<PathBuf> = file
            .lights
            .iter()
            .filter_map(|light| light.image.as_ref())
            .map(|name| folder.join(name))
            .filter(|p| p.is_file())
            .collect();
        if images.len() < 2 {
            return Err(PhotoError::Input(format!(
                "{} names {} photograph{} present in {}: a photometric-stereo set needs at least \
                 2, each named by its light's `image`",
                camera.display(),
                images.len(),
                if images.len() == 1 { "" } else { "s" },
                folder.display()
            )));
        }
        Ok(Self { camera, images })
    }
}
