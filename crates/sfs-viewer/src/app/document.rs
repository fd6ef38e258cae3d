//! The open image and everything that belongs to it: camera (and where it
//! came from), masks, ground truth. Loading is all-or-nothing: a failure
//! leaves the previous document untouched and returns a message naming the
//! file.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::mask_edit::Masks;
use sfs_core::camera::Intrinsics;
use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::light::PointLight;
use sfs_core::resample::resize_area;

/// Where the camera values came from.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSource {
    /// A camera JSON file (`scene.json` keys).
    File(PathBuf),
    /// EXIF focal length in 35 mm equivalent.
    Exif {
        /// The EXIF value in millimetres.
        focal_35mm: f64,
    },
    /// No information: a 50 mm-equivalent guess.
    Guess,
    /// Edited in the camera panel.
    Manual,
}

impl CameraSource {
    /// Short description for the camera panel.
    pub fn describe(&self) -> String {
        match self {
            CameraSource::File(p) => format!("from {}", p.display()),
            CameraSource::Exif { focal_35mm } => {
                format!("from EXIF ({focal_35mm:.0} mm, 35 mm equivalent)")
            }
            CameraSource::Guess => "guessed (50 mm equivalent): set the focal length".into(),
            CameraSource::Manual => "edited".into(),
        }
    }
}

/// Camera intrinsics and intensity scale as the panel edits them.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraState {
    /// Focal length in pixels.
    pub focal_px: f64,
    /// Principal point column in pixels.
    pub cx_px: f64,
    /// Principal point row in pixels.
    pub cy_px: f64,
    /// Intensity scale `s`.
    pub intensity_scale: f64,
    /// The lights of the camera file that took this image (empty: one
    /// light at the optical centre).
    pub lights: Vec<PointLight>,
    /// Whether `intensity_scale` was given (camera file or the panel); when
    /// not and the lights are off the centre, the worker estimates it.
    pub scale_given: bool,
    /// Whether the solve uses [`CameraState::lights`] (off: the paper's
    /// centred light, to compare).
    pub use_lights: bool,
    /// Origin of the values.
    pub source: CameraSource,
}

impl CameraState {
    /// The lights the solve uses.
    pub fn solve_lights(&self) -> Vec<PointLight> {
        if self.use_lights {
            self.lights.clone()
        } else {
            Vec::new()
        }
    }

    /// Pinhole intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            focal_px: self.focal_px,
            principal_x_px: self.cx_px,
            principal_y_px: self.cy_px,
        }
    }

    /// Horizontal field of view in degrees for an image `width_px` wide.
    pub fn horizontal_fov_deg(&self, width_px: usize) -> f64 {
        self.intrinsics().horizontal_fov_deg(width_px)
    }
}

/// An open image with its camera, masks and optional ground truth.
pub struct Document {
    /// The image file.
    pub path: PathBuf,
    /// Linear image values.
    pub image: Grid<f64>,
    /// Whether the file was read as sRGB and linearised.
    pub srgb: bool,
    /// Why (decided from the file, or asked for).
    pub srgb_reason: String,
    /// The photograph's own size (the image is at the working size).
    pub full_size: (usize, usize),
    /// Camera and intensity scale.
    pub camera: CameraState,
    /// Object and confidence masks with undo history.
    pub masks: Masks,
    /// Ground-truth depth (a `synth` folder's `depth_gt.npy`).
    pub ground_truth: Option<Grid<f64>>,
    /// Messages about what was found beside the image (for the status line).
    pub notes: Vec<String>,
}

impl Document {
    /// Opens `path`; a `scene.json`, `mask.png` and `depth_gt.npy` beside it
    /// (a `synth` folder) are picked up; EXIF gives the focal length of a
    /// photograph without a camera file.
    ///
    /// `srgb`: `None` decides from the file (`--srgb auto`); a photograph
    /// whose longest side exceeds `max_side` is area-averaged down to it, the
    /// camera and the mask beside it scaled alike.
    pub fn open(path: &Path, srgb: Option<bool>, max_side: Option<usize>) -> Result<Self> {
        let mode = match srgb {
            None => io::SrgbMode::Auto,
            Some(true) => io::SrgbMode::On,
            Some(false) => io::SrgbMode::Off,
        };
        // Refused before decoding when it would not fit the free memory (a
        // header that cannot be read is reported by the decoder below).
        if let Ok(full) = io::image_size(path) {
            let working = sfs_core::resample::working_size(full.0, full.1, max_side);
            sfs_core::memory::check_solve(&sfs_core::memory::SolvePlan {
                what: format!(
                    "opening {} ({}x{}, solved at {}x{})",
                    path.display(),
                    full.0,
                    full.1,
                    working.0,
                    working.1
                ),
                full,
                working,
                images: 1,
                pyramid_factor: sfs_core::memory::DEFAULT_PYRAMID_FACTOR,
                smaller: &|side| {
                    format!("set the working size (Camera panel) to {side} px or less")
                },
                otherwise: "open a smaller image",
            })?;
        }
        let (full, srgb, srgb_reason) = io::read_photo(path, mode)
            .with_context(|| format!("cannot open image {}", path.display()))?;
        let full_size = full.size();
        let (w, h) = sfs_core::resample::working_size(full_size.0, full_size.1, max_side);
        let image = resize_area(&full, w, h, Cancel::NEVER).uncancelled();
        drop(full);
        let mut notes = Vec::new();
        if (w, h) != full_size {
            notes.push(format!(
                "working at {w}x{h} (area-averaged from {}x{}; the working size is in the \
                 Camera panel)",
                full_size.0, full_size.1
            ));
        }
        let folder = path.parent().unwrap_or(Path::new("."));
        // A synth folder's scene.json, or a near_ps calibration.json.
        let beside = ["scene.json", "calibration.json"]
            .iter()
            .map(|name| folder.join(name))
            .find(|p| p.is_file())
            .unwrap_or_else(|| folder.join("scene.json"));
        let camera = if beside.is_file() {
            match read_camera_for(&beside, (w, h), path) {
                Ok(c) => c,
                Err(e) => {
                    notes.push(format!("ignored {}: {e:#}", beside.display()));
                    camera_from_exif_or_guess(path, w, h)
                }
            }
        } else {
            camera_from_exif_or_guess(path, w, h)
        };
        let mut masks = Masks::new(w, h);
        let mask_beside = folder.join("mask.png");
        if mask_beside.is_file() && mask_beside != path {
            match load_object_mask(&mask_beside, full_size, (w, h)) {
                Ok(loaded) => {
                    masks = loaded;
                    notes.push(format!("object mask from {}", mask_beside.display()));
                }
                Err(e) => notes.push(format!("ignored {}: {e:#}", mask_beside.display())),
            }
        }
        let gt_path = folder.join("depth_gt.npy");
        let ground_truth = if gt_path.is_file() {
            match io::read_npy(&gt_path) {
                Ok(g) if g.size() == (w, h) => {
                    notes.push(format!("ground truth from {}", gt_path.display()));
                    Some(g)
                }
                Ok(g) => {
                    notes.push(format!(
                        "ignored {}: {}x{} but the image is {w}x{h}",
                        gt_path.display(),
                        g.width(),
                        g.height()
                    ));
                    None
                }
                Err(e) => {
                    notes.push(format!("ignored {}: {e}", gt_path.display()));
                    None
                }
            }
        } else {
            None
        };
        Ok(Self {
            path: path.to_path_buf(),
            image,
            srgb,
            srgb_reason,
            full_size,
            camera,
            masks,
            ground_truth,
            notes,
        })
    }

    /// Image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        self.image.size()
    }

    /// Replaces the camera from a JSON file (keys of `scene.json`); the
    /// intrinsics must match the image size.
    pub fn load_camera(&mut self, path: &Path) -> Result<()> {
        self.camera = read_camera_for(path, self.size(), &self.path)?;
        Ok(())
    }

    /// Re-reads the image with or without sRGB linearisation; on failure
    /// nothing changes.
    pub fn set_srgb(&mut self, srgb: bool) -> Result<()> {
        let image = io::read_image(&self.path, srgb)
            .with_context(|| format!("cannot re-read {}", self.path.display()))?;
        if image.size() != self.full_size {
            bail!("{} changed size on disk", self.path.display());
        }
        let (w, h) = self.image.size();
        self.image = resize_area(&image, w, h, Cancel::NEVER).uncancelled();
        self.srgb = srgb;
        self.srgb_reason = if srgb {
            "sRGB decoding on (set in the Camera panel)".into()
        } else {
            "read as linear (set in the Camera panel)".into()
        };
        Ok(())
    }
}

/// The object mask at `path` (of the photograph's `full` size) at the
/// working size `working` (area-averaged, then `>= 0.5`).
fn load_object_mask(path: &Path, full: (usize, usize), working: (usize, usize)) -> Result<Masks> {
    let values = io::read_mask(path)?;
    if values.size() != full {
        bail!(
            "{}x{} but the photograph is {}x{}",
            values.width(),
            values.height(),
            full.0,
            full.1
        );
    }
    let object = resize_area(&values, working.0, working.1, Cancel::NEVER)
        .uncancelled()
        .map(|&v| v >= 0.5);
    Ok(Masks::from_layers(
        Grid::filled(working.0, working.1, 1.0f32),
        object,
    )?)
}

/// Reads a camera file for the image at `image` (intrinsics scaled to
/// `size`); its light is the camera file's light whose `image` is its file
/// name (or the file's only light, or all of a synthetic set-up's).
pub fn read_camera_for(path: &Path, size: (usize, usize), image: &Path) -> Result<CameraState> {
    let file = sfs_core::camera_file::read_camera(path)?;
    let name = image.file_name().map(|n| n.to_string_lossy().into_owned());
    let lights = match file.lights_for(path, &[], name.as_deref()) {
        Ok((lights, _)) => lights,
        Err(_) if !file.lights.is_empty() => Vec::new(),
        Err(e) => return Err(e.into()),
    };
    // Intrinsics calibrated for another size of the same image are scaled.
    let camera = file.intrinsics_for(path, size)?;
    Ok(CameraState {
        focal_px: camera.focal_px,
        cx_px: camera.principal_x_px,
        cy_px: camera.principal_y_px,
        intensity_scale: file.intensity_scale.unwrap_or(1.0),
        scale_given: file.intensity_scale.is_some(),
        use_lights: !lights.is_empty(),
        lights,
        source: CameraSource::File(path.to_path_buf()),
    })
}

/// Focal length from EXIF's 35 mm equivalent (36 mm across the long side),
/// or a 50 mm-equivalent guess; principal point at the centre; `s = 1`.
fn camera_from_exif_or_guess(path: &Path, width: usize, height: usize) -> CameraState {
    let long_side = width.max(height) as f64;
    let (focal_px, source) = match exif_focal_35mm(path) {
        Some(f35) => (
            f35 / 36.0 * long_side,
            CameraSource::Exif { focal_35mm: f35 },
        ),
        None => (50.0 / 36.0 * long_side, CameraSource::Guess),
    };
    CameraState {
        focal_px,
        cx_px: (width as f64 - 1.0) / 2.0,
        cy_px: (height as f64 - 1.0) / 2.0,
        intensity_scale: 1.0,
        scale_given: false,
        lights: Vec::new(),
        use_lights: false,
        source,
    }
}

/// `FocalLengthIn35mmFilm` from the file's EXIF, if any.
pub fn exif_focal_35mm(path: &Path) -> Option<f64> {
    let file = std::fs::File::open(path).ok()?;
    let mut reader = std::io::BufReader::new(file);
    let exif = exif::Reader::new().read_from_container(&mut reader).ok()?;
    let field = exif.get_field(exif::Tag::FocalLengthIn35mmFilm, exif::In::PRIMARY)?;
    let value = field.value.get_uint(0)? as f64;
    (value > 0.0).then_some(value)
}

/// The built-in sample (the Sombrero with its camera file and ground truth):
/// `assets/sombrero/image16.png` under the working directory or, failing
/// that, under the workspace the binary was built from.
pub fn sample_image_path() -> Option<PathBuf> {
    let relative = Path::new("assets").join("sombrero").join("image16.png");
    let candidates = [
        relative.clone(),
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("..")
            .join(&relative),
    ];
    candidates.into_iter().find(|p| p.is_file())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_opens_with_camera_and_ground_truth() {
        let Some(path) = sample_image_path() else {
            panic!("assets/sombrero/image16.png is missing");
        };
        let doc = match Document::open(&path, Some(false), None) {
            Ok(d) => d,
            Err(e) => panic!("{e:#}"),
        };
        assert!(matches!(doc.camera.source, CameraSource::File(_)));
        assert!(doc.ground_truth.is_some());
        assert_eq!(doc.size(), (256, 256));
    }

    #[test]
    fn bad_files_give_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let bad = dir.path().join("not-an-image.png");
        std::fs::write(&bad, b"hello").unwrap_or_else(|e| panic!("{e}"));
        let err = match Document::open(&bad, Some(false), None) {
            Ok(_) => panic!("opened a non-image"),
            Err(e) => format!("{e:#}"),
        };
        assert!(err.contains("not-an-image.png"), "{err}");
        let Some(sample) = sample_image_path() else {
            panic!("sample missing")
        };
        let mut doc = match Document::open(&sample, Some(false), None) {
            Ok(d) => d,
            Err(e) => panic!("{e:#}"),
        };
        let camera = dir.path().join("cam.json");
        std::fs::write(&camera, br#"{"width": 256, "height": 256, "focal": 100}"#)
            .unwrap_or_else(|e| panic!("{e}"));
        let before = doc.camera.clone();
        let err = match doc.load_camera(&camera) {
            Ok(()) => panic!("accepted a camera file with missing keys"),
            Err(e) => format!("{e:#}"),
        };
        assert!(err.contains("cam.json"), "{err}");
        assert_eq!(doc.camera, before);
    }
}
