//! What a solve's input is made of ([`PhotoInput`] with its camera,
//! lights and scale) and why it can fail ([`PhotoError`]): the plain data
//! the folder's module and its `camera` child share, below both
//! (re-exported as `photo::PhotoInput` and so on). Uses `io`, `light`,
//! `memory` and the sibling `corrections` (vignetting).

use std::path::{Path, PathBuf};

use crate::io::{IoError, SrgbMode};
use crate::light::PointLight;
use crate::memory::{self, MemoryError};

use super::corrections::Vignetting;

/// Where the camera's intrinsics come from.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSpec {
    /// A camera file (`scene.json` keys or a near_ps `calibration.json`);
    /// intrinsics for another size of the same image are scaled.
    File(PathBuf),
    /// A focal length in pixels of the photograph as given, and optionally
    /// the principal point (default: the image centre, `(w - 1) / 2`).
    Focal {
        /// Focal length, pixels.
        focal_px: f64,
        /// Principal point column, pixels.
        cx_px: Option<f64>,
        /// Principal point row, pixels.
        cy_px: Option<f64>,
    },
    /// The photograph's EXIF focal length (35 mm equivalent, 36 mm across
    /// the long side). Without one: a 50 mm-equivalent guess when `guess`
    /// (said in the report), else an error asking for a camera.
    Exif {
        /// Whether a missing EXIF focal length may be guessed.
        guess: bool,
    },
}

/// Which lights were on.
#[derive(Clone, Debug, PartialEq)]
pub enum LightSpec {
    /// The camera file's lights: those numbered in `picks` (summed), else
    /// the one marked as taking each photograph (several photographs: their
    /// lights summed), else all when they are not tied to images; no camera
    /// file or no lights in it: one light at the optical centre. A light
    /// that cannot be told is an error.
    CameraFile {
        /// LED numbers switched on (empty: decide from the image names).
        picks: Vec<u32>,
    },
    /// As [`LightSpec::CameraFile`] without picks, but where the file
    /// cannot tell which light took the photograph, one light at the
    /// optical centre (said in the report) instead of an error: the
    /// viewer's choice, where the user can still pick.
    CameraFileOrCentred,
    /// These lights (empty: one light at the optical centre).
    Given(Vec<PointLight>),
}

/// Where the intensity scale `s` comes from.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ScaleSpec {
    /// The camera file's `intensity_scale`, else unknown.
    #[default]
    FromCamera,
    /// Unknown: the solve estimates it (lights off the centre) or takes 1.
    Auto,
    /// This value.
    Given(f64),
}

/// Everything a solve's input is made of.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotoInput {
    /// The photographs (several: lights on together, summed in linear light).
    pub images: Vec<PathBuf>,
    /// sRGB decoding.
    pub srgb: SrgbMode,
    /// The camera's intrinsics.
    pub camera: CameraSpec,
    /// The lights.
    pub lights: LightSpec,
    /// The intensity scale.
    pub intensity_scale: ScaleSpec,
    /// Object mask image (white = object), at the photograph's size or the
    /// working size.
    pub object_mask: Option<PathBuf>,
    /// Confidence image in [0, 1], at the photograph's size or the working
    /// size.
    pub confidence: Option<PathBuf>,
    /// Lower the confidence of highlights, near-black and cast-shadow pixels
    /// and the silhouette band (combined with `confidence` by the minimum).
    pub auto_confidence: bool,
    /// A frame with every light off, subtracted from each photograph.
    pub ambient: Option<PathBuf>,
    /// Vignetting correction.
    pub vignetting: Vignetting,
    /// A known albedo map (linear, relative), divided out.
    pub albedo: Option<PathBuf>,
    /// Largest side of the working size (area averaging); `None`: full size.
    pub max_side: Option<usize>,
    /// The pyramid's total pixels over the working size's, for the memory
    /// guard (see [`crate::solver::pyramid::pyramid_factor`]).
    pub pyramid_factor: f64,
    /// How the user sets the working size, followed by a number in the
    /// notes and the memory guard's way out (`--max-side`, or "a working
    /// size (Camera panel) of").
    pub max_side_setting: String,
    /// Photometric stereo: the photographs are a set, each taken by a light
    /// of its own (the camera file's `image` names, or one given light per
    /// photograph in order), kept apart instead of summed.
    pub photometric_stereo: bool,
    /// Whether the given lights' intensities were measured (with
    /// [`LightSpec::Given`]; a camera file says so itself). Without them a
    /// set's intensities are estimated.
    pub given_intensities: bool,
    /// A confidence image per photograph of a set (same order as
    /// `images`; empty or `None`: none), combined with `confidence`.
    pub photo_confidence: Vec<Option<PathBuf>>,
}

impl PhotoInput {
    /// One photograph, its camera from EXIF (no guess), lights and scale
    /// from no camera file, no masks or corrections, full size.
    pub fn new(image: impl Into<PathBuf>) -> Self {
        Self {
            images: vec![image.into()],
            srgb: SrgbMode::Auto,
            camera: CameraSpec::Exif { guess: false },
            lights: LightSpec::CameraFile { picks: Vec::new() },
            intensity_scale: ScaleSpec::FromCamera,
            object_mask: None,
            confidence: None,
            auto_confidence: false,
            ambient: None,
            vignetting: Vignetting::None,
            albedo: None,
            max_side: None,
            pyramid_factor: memory::DEFAULT_PYRAMID_FACTOR,
            max_side_setting: "--max-side".into(),
            photometric_stereo: false,
            given_intensities: false,
            photo_confidence: Vec::new(),
        }
    }

    /// Photograph `k` of a set as an input of its own: the same camera,
    /// masks, ambient frame, corrections and working size, its own
    /// confidence file (else the set's) and its own light (its given one,
    /// or the camera file's by its name). `None` when there is no `k`-th.
    pub fn one_of_set(&self, k: usize) -> Option<PhotoInput> {
        let image = self.images.get(k)?;
        let lights = match &self.lights {
            LightSpec::Given(lights) => LightSpec::Given(vec![*lights.get(k)?]),
            other => other.clone(),
        };
        Some(PhotoInput {
            images: vec![image.clone()],
            lights,
            photometric_stereo: false,
            given_intensities: false,
            photo_confidence: Vec::new(),
            confidence: self
                .photo_confidence
                .get(k)
                .cloned()
                .flatten()
                .or_else(|| self.confidence.clone()),
            ..self.clone()
        })
    }

    /// Every file this input reads (photographs, camera file, masks,
    /// ambient frame, flat field, albedo).
    pub fn files(&self) -> Vec<&Path> {
        let camera = match &self.camera {
            CameraSpec::File(path) => Some(path.as_path()),
            _ => None,
        };
        let flat = match &self.vignetting {
            Vignetting::FlatField(path) => Some(path.as_path()),
            _ => None,
        };
        self.images
            .iter()
            .map(PathBuf::as_path)
            .chain(camera)
            .chain(self.object_mask.as_deref())
            .chain(self.confidence.as_deref())
            .chain(self.ambient.as_deref())
            .chain(flat)
            .chain(self.albedo.as_deref())
            .chain(self.photo_confidence.iter().flatten().map(PathBuf::as_path))
            .collect()
    }
}

/// Why a photograph could not become a problem; the message names the file
/// or the setting at fault.
#[derive(Debug, thiserror::Error)]
pub enum PhotoError {
    /// A file could not be read or is unusable.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The solve would not fit the free memory.
    #[error(transparent)]
    Memory(#[from] MemoryError),
    /// The input is incomplete or inconsistent.
    #[error("{0}")]
    Input(String),
}
