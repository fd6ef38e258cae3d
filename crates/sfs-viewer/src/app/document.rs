//! The open image and everything that belongs to it: what it was read with
//! (the core's [`PhotoInput`]: camera file, masks, ambient frame,
//! vignetting, albedo, sRGB, working size), camera (and where it came from),
//! masks, ground truth, and the distances the user knows (pixels of the
//! photograph, checked and converted to the working size for the solve as
//! `solve --known-depth` converts them). Every read goes through the
//! core's photo pipeline ([`photo::prepare`]), the command line's too.
//! Loading is all-or-nothing: a failure leaves the previous document
//! untouched and returns a message naming the file.
//!
//! A photometric-stereo set (a folder whose camera file names its
//! photographs, or several photographs) is one document too: the same
//! pipeline keeps its photographs apart ([`PhotoInput::photometric_stereo`]),
//! the document's image is their mean, the painted masks apply to all of
//! them, and each photograph has a confidence layer of its own
//! ([`PhotoSet`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::mask_edit::{ImagePoint, Masks};
use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::io::{self, SrgbMode};
use sfs_core::light::PointLight;
use sfs_core::params::SolverParams;
use sfs_core::photo::folder::{SetFolder, camera_file_in};
use sfs_core::photo::{
    self, CameraSpec, LightSpec, PhotoInput, PhotoReport, PreparedPhoto, ScaleSpec, Vignetting,
};
use sfs_core::photograph_solve::PhotographSolve;
use sfs_core::solver::Problem;
use sfs_core::solver::calibrate::KnownDepth;
use sfs_core::solver::photometric::PhotometricProblem;

pub use sfs_core::photograph_solve::KnownDistance;

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

impl From<&photo::CameraSource> for CameraSource {
    fn from(source: &photo::CameraSource) -> Self {
        match source {
            photo::CameraSource::File { path } => CameraSource::File(path.clone()),
            photo::CameraSource::Exif { focal_35mm } => CameraSource::Exif {
                focal_35mm: *focal_35mm,
            },
            photo::CameraSource::Guess => CameraSource::Guess,
            photo::CameraSource::Given => CameraSource::Manual,
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
    /// The camera the photo pipeline decided (intrinsics at the working
    /// size).
    fn from_prepared(prepared: &PreparedPhoto) -> Self {
        let camera = prepared.problem.camera;
        let lights = prepared.problem.lights.clone();
        Self {
            focal_px: camera.focal_px,
            cx_px: camera.principal_x_px,
            cy_px: camera.principal_y_px,
            intensity_scale: prepared.problem.intensity_scale,
            scale_given: prepared.intensity_scale_given,
            use_lights: !lights.is_empty(),
            lights,
            source: CameraSource::from(&prepared.report.camera.source),
        }
    }

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

/// How to open an image: the files and corrections beside the photograph
/// itself (`None`: found beside the image, or none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OpenOptions {
    /// Read as sRGB (`None`: decide from the file).
    pub srgb: Option<bool>,
    /// Longest side of the working size (`None`: full size).
    pub max_side: Option<usize>,
    /// A camera file (`None`: a `scene.json` or `calibration.json` beside
    /// the image, else EXIF, else a guess).
    pub camera: Option<PathBuf>,
    /// An object mask (`None`: a `mask.png` beside the image, if any).
    pub mask: Option<PathBuf>,
    /// A frame with every light off, subtracted.
    pub ambient: Option<PathBuf>,
    /// Vignetting correction.
    pub vignetting: Vignetting,
    /// A known albedo map, divided out.
    pub albedo: Option<PathBuf>,
    /// A confidence mask (grey PNG, 0 = untrusted .. 255 = trusted, at the
    /// photograph's size or the working size), the confidence layer's
    /// start (`None`: all trusted).
    pub confidence: Option<PathBuf>,
}

/// The photographs of a photometric-stereo set, each with its own light,
/// and each one's own confidence layer.
pub struct PhotoSet {
    /// The set as the photo pipeline built it
    /// ([`photo::photometric_problem`]); a solve gets it with the painted
    /// masks, the camera as edited and each photograph's layer
    /// ([`Document::set_problem`]).
    pub problem: PhotometricProblem,
    /// Each photograph's file, in the set's order.
    pub paths: Vec<PathBuf>,
    /// Each photograph's own confidence layer (painted or loaded), in the
    /// set's order; only their confidence layers are used.
    pub photo_masks: Vec<Masks>,
}

impl PhotoSet {
    /// Each photograph's short name (its file name).
    pub fn names(&self) -> Vec<String> {
        self.paths.iter().map(|p| file_name(p)).collect()
    }

    /// A number that changes with every edit of any photograph's layer.
    pub fn revision(&self) -> u64 {
        self.photo_masks.iter().fold(0u64, |sum, m| {
            sum.wrapping_mul(31).wrapping_add(m.revision())
        })
    }
}

/// A path's file name (the whole path when it has none).
pub fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// An open image with its camera, masks and optional ground truth.
pub struct Document {
    /// The image file.
    pub path: PathBuf,
    /// What the image was read with; changing a correction reads it again
    /// through the same pipeline ([`Document::reread`]).
    pub input: PhotoInput,
    /// Linear image values at the working size, corrected.
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
    /// What the photo pipeline decided, and why.
    pub report: PhotoReport,
    /// Where a photograph was clipped (saturated), working size.
    pub clipped: Option<Grid<bool>>,
    /// The photographs of a sum, each with its own light (the fit per
    /// photograph).
    pub photos: Vec<sfs_core::photo::SummedPhoto>,
    /// Messages about what was found beside the image (for the status line).
    pub notes: Vec<String>,
    /// Distances the user knows, in pixels of the photograph, in the order
    /// given (at most one per pixel); not empty, they set the depth scale.
    pub known_depths: Vec<KnownDistance>,
    /// The object's distance the user gives (its median depth, the
    /// camera's unit): sets the depth unit when no known distance does.
    pub object_distance: Option<f64>,
    /// A photometric-stereo set (`None`: one image). `path` is then the
    /// set's folder and `image` the mean of its photographs.
    pub set: Option<PhotoSet>,
}

/// The photo pipeline's input for opening `path` in the viewer, with the
/// files found beside it (a `synth` folder's `scene.json` and `mask.png`, a
/// near_ps `calibration.json`) where `options` names none; also the camera
/// file found beside it and whether the object mask was found beside it.
pub fn viewer_input(path: &Path, options: &OpenOptions) -> (PhotoInput, Option<PathBuf>, bool) {
    let folder = path.parent().unwrap_or(Path::new("."));
    let camera_beside = camera_file_in(folder);
    let mask_beside = Some(folder.join("mask.png")).filter(|m| m.is_file() && m != path);
    let camera = match (&options.camera, &camera_beside) {
        (Some(file), _) | (None, Some(file)) => CameraSpec::File(file.clone()),
        (None, None) => CameraSpec::Exif { guess: true },
    };
    let input = PhotoInput {
        images: vec![path.to_path_buf()],
        srgb: match options.srgb {
            None => SrgbMode::Auto,
            Some(true) => SrgbMode::On,
            Some(false) => SrgbMode::Off,
        },
        camera,
        lights: LightSpec::CameraFileOrCentred,
        intensity_scale: ScaleSpec::FromCamera,
        object_mask: options.mask.clone().or_else(|| mask_beside.clone()),
        confidence: options.confidence.clone(),
        auto_confidence: false,
        ambient: options.ambient.clone(),
        vignetting: options.vignetting.clone(),
        albedo: options.albedo.clone(),
        max_side: options.max_side,
        pyramid_factor: sfs_core::memory::DEFAULT_PYRAMID_FACTOR,
        max_side_setting: "a working size (Camera panel) of".into(),
        photometric_stereo: false,
        given_intensities: false,
        photo_confidence: Vec::new(),
    };
    let found_mask = options.mask.is_none() && mask_beside.is_some();
    (input, camera_beside, found_mask)
}

/// The photographs of a set folder (`sfs_core::photo::folder::SetFolder`):
/// those its camera file's lights name that are present, in their order.
///
/// # Errors
/// As [`SetFolder::find`].
pub fn set_images_in(folder: &Path) -> Result<Vec<PathBuf>> {
    Ok(SetFolder::find(folder)?.images)
}

/// The photo pipeline's input for opening `images` as a photometric-stereo
/// set: as [`viewer_input`] for one image (camera file and `mask.png`
/// beside the first, where `options` names none), the photographs kept
/// apart; with `ambient_beside`, an `ambient.png` beside them is the
/// ambient frame (a set folder). Also the camera file found beside and
/// whether the object mask was found beside.
pub fn set_input(
    images: &[PathBuf],
    options: &OpenOptions,
    ambient_beside: bool,
) -> (PhotoInput, Option<PathBuf>, bool) {
    let first = images.first().cloned().unwrap_or_default();
    let (mut input, camera_beside, found_mask) = viewer_input(&first, options);
    let folder = first.parent().unwrap_or(Path::new("."));
    input.images = images.to_vec();
    if input
        .object_mask
        .as_ref()
        .is_some_and(|m| images.contains(m))
    {
        input.object_mask = None;
    }
    let ambient = folder.join("ambient.png");
    if ambient_beside && input.ambient.is_none() && ambient.is_file() && !images.contains(&ambient)
    {
        input.ambient = Some(ambient);
    }
    input.photometric_stereo = true;
    input.albedo = None;
    let found_mask = found_mask && input.object_mask.is_some();
    (input, camera_beside, found_mask)
}

/// Runs the photo pipeline; a camera file, mask, ambient frame, flat field
/// or albedo that breaks it (the error names it) is left out with a note
/// and the image opens without it. Only the photograph itself failing is an
/// error. A camera file left out gives way to `camera_beside` (once), else
/// to EXIF or a guess.
fn prepare_lenient(
    mut input: PhotoInput,
    mut camera_beside: Option<PathBuf>,
    notes: &mut Vec<String>,
) -> Result<(PhotoInput, PreparedPhoto)> {
    loop {
        let error = match photo::prepare(&input) {
            Ok(prepared) => return Ok((input, prepared)),
            Err(e) => e.to_string(),
        };
        let names = |path: &Path| error.contains(&path.display().to_string());
        let mut ignored = |path: &Path| notes.push(format!("ignored {}: {error}", path.display()));
        if let CameraSpec::File(file) = &input.camera
            && names(file)
        {
            ignored(file);
            input.camera = match camera_beside.take().filter(|beside| beside != file) {
                Some(beside) => CameraSpec::File(beside),
                None => CameraSpec::Exif { guess: true },
            };
        } else if let Some(mask) = input.object_mask.take_if(|m| names(m)) {
            ignored(&mask);
        } else if let Some(confidence) = input.confidence.take_if(|c| names(c)) {
            ignored(&confidence);
        } else if let Some(ambient) = input.ambient.take_if(|a| names(a)) {
            ignored(&ambient);
        } else if let Vignetting::FlatField(flat) = &input.vignetting
            && names(flat)
        {
            ignored(flat);
            input.vignetting = Vignetting::None;
        } else if let Some(albedo) = input.albedo.take_if(|a| names(a)) {
            ignored(&albedo);
        } else {
            return Err(anyhow::anyhow!(error))
                .with_context(|| format!("cannot open image {}", input.images[0].display()));
        }
    }
}

/// The masks the pipeline read (object mask; confidence from a lost albedo),
/// as editable layers.
fn masks_of(prepared: &PreparedPhoto) -> Result<Masks> {
    let (w, h) = prepared.size();
    let object = prepared
        .problem
        .object_mask
        .clone()
        .unwrap_or_else(|| Grid::filled(w, h, true));
    let confidence = prepared
        .problem
        .confidence
        .as_ref()
        .map_or_else(|| Grid::filled(w, h, 1.0f32), |c| c.map(|&v| v as f32));
    Ok(Masks::from_layers(confidence, object)?)
}

impl Document {
    /// Opens what `paths` name: one image; a folder (a photometric-stereo
    /// set: the photographs its camera file's lights name, with its
    /// `mask.png` and `ambient.png`); or several images (a set, camera file
    /// and mask found beside the first).
    pub fn open_paths(paths: &[PathBuf], options: &OpenOptions) -> Result<Self> {
        match paths {
            [] => anyhow::bail!("nothing to open"),
            [folder] if folder.is_dir() => {
                let images = set_images_in(folder)?;
                Self::open_set(folder, &images, options, true)
            }
            [image] => Self::open(image, options),
            images => {
                if let Some(folder) = images.iter().find(|p| p.is_dir()) {
                    anyhow::bail!(
                        "{} is a folder: open a set as one folder or as several photographs",
                        folder.display()
                    );
                }
                let folder = images[0].parent().unwrap_or(Path::new(".")).to_path_buf();
                Self::open_set(&folder, images, options, false)
            }
        }
    }

    /// Opens `images` as one photometric-stereo set (`folder`: the
    /// document's path, its autosave's key) through the photo pipeline,
    /// each photograph with the light its camera file names for it; the
    /// document's image is the photographs' mean. A file of `options` that
    /// cannot be used is left out with a note.
    pub fn open_set(
        folder: &Path,
        images: &[PathBuf],
        options: &OpenOptions,
        ambient_beside: bool,
    ) -> Result<Self> {
        let (input, camera_beside, found_mask) = set_input(images, options, ambient_beside);
        let mut notes = Vec::new();
        let (input, prepared) = prepare_lenient(input, camera_beside, &mut notes)?;
        let problem = photo::photometric_problem(&prepared, &input)
            .with_context(|| format!("cannot open the set in {}", folder.display()))?;
        notes.extend(prepared.report.notes.iter().cloned());
        if let Some(mask) = &input.object_mask
            && found_mask
        {
            notes.push(format!("object mask from {}", mask.display()));
        }
        if let Some(ambient) = &input.ambient {
            notes.push(format!("ambient frame {}", ambient.display()));
        }
        notes.push(format!(
            "photometric-stereo set of {} photographs, each with its own light",
            problem.photos.len()
        ));
        let (w, h) = prepared.size();
        let image = mean_image(&problem, (w, h));
        // Saturation is each photograph's own (left out of that photograph
        // only): the painted confidence starts from the confidence file
        // alone, not from the pipeline's sum, where a pixel saturated in
        // one photograph is untrusted in all.
        let confidence = match &input.confidence {
            Some(path) => {
                photo::read_mask_at(path, "confidence mask", prepared.full_size(), (w, h))?
                    .map(|&v| v as f32)
            }
            None => Grid::filled(w, h, 1.0f32),
        };
        let object = prepared
            .problem
            .object_mask
            .clone()
            .unwrap_or_else(|| Grid::filled(w, h, true));
        let masks = Masks::from_layers(confidence, object)?;
        let photo_masks = problem
            .photos
            .iter()
            .map(|p| {
                let confidence = p
                    .confidence
                    .as_ref()
                    .map_or_else(|| Grid::filled(w, h, 1.0f32), |c| c.map(|&v| v as f32));
                Masks::from_layers(confidence, Grid::filled(w, h, true))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            path: folder.to_path_buf(),
            camera: CameraState::from_prepared(&prepared),
            masks,
            srgb: prepared.report.srgb,
            srgb_reason: prepared.report.srgb_reason.clone(),
            full_size: prepared.full_size(),
            clipped: prepared.clipped,
            photos: prepared.photos,
            report: prepared.report,
            image,
            input: input.clone(),
            ground_truth: None,
            notes,
            known_depths: Vec::new(),
            object_distance: None,
            set: Some(PhotoSet {
                problem,
                paths: input.images.clone(),
                photo_masks,
            }),
        })
    }

    /// The set's problem as a solve of the document now gets it: the
    /// painted object mask and confidence for every photograph, each
    /// photograph's own layer as its confidence (none where it trusts every
    /// pixel), the camera as edited; the intensity scale when it was given
    /// (the albedo is then absolute). `None` for one image.
    pub fn set_problem(&self) -> Option<PhotometricProblem> {
        let set = self.set.as_ref()?;
        let mut problem = set.problem.clone();
        problem.camera = self.camera.intrinsics();
        problem.object_mask = self.masks.object_for_solver();
        problem.confidence = self.masks.confidence_for_solver();
        for (photo, masks) in problem.photos.iter_mut().zip(&set.photo_masks) {
            photo.confidence = masks.confidence_for_solver();
        }
        problem.intensity_scale = self
            .camera
            .scale_given
            .then_some(self.camera.intensity_scale);
        Some(problem)
    }

    /// The photo pipeline's input for solving photograph `index` of the set
    /// alone with the single-image method: that photograph, the set's
    /// camera file (its light found by its name), mask and corrections.
    pub fn single_input(&self, index: usize) -> Option<PhotoInput> {
        let set = self.set.as_ref()?;
        let input = self.input.one_of_set(index)?;
        // The viewer's rule for one photograph: an unnamed light is the
        // centred one until the user picks one.
        (input.images.first() == set.paths.get(index)).then_some(PhotoInput {
            lights: LightSpec::CameraFileOrCentred,
            ..input
        })
    }

    /// Opens `path` through the photo pipeline with `options` (a file of
    /// `options` that cannot be used is left out with a note); a
    /// `scene.json` or `calibration.json`, a `mask.png` and a `depth_gt.npy`
    /// beside it (a `synth` folder, a near_ps folder) are picked up where
    /// `options` names none; EXIF gives the focal length of a photograph
    /// without a camera file, else it is guessed.
    pub fn open(path: &Path, options: &OpenOptions) -> Result<Self> {
        let (input, camera_beside, found_mask) = viewer_input(path, options);
        let mut notes = Vec::new();
        let (input, prepared) = prepare_lenient(input, camera_beside, &mut notes)?;
        let (w, h) = prepared.size();
        let full_size = prepared.full_size();
        notes.extend(prepared.report.notes.iter().cloned());
        if let Some(mask) = &input.object_mask
            && found_mask
        {
            notes.push(format!("object mask from {}", mask.display()));
        }
        let folder = path.parent().unwrap_or(Path::new("."));
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
        let masks = masks_of(&prepared)?;
        Ok(Self {
            path: path.to_path_buf(),
            camera: CameraState::from_prepared(&prepared),
            masks,
            srgb: prepared.report.srgb,
            srgb_reason: prepared.report.srgb_reason.clone(),
            full_size,
            clipped: prepared.clipped,
            photos: prepared.photos,
            report: prepared.report,
            image: prepared.problem.image,
            input,
            ground_truth,
            notes,
            known_depths: Vec::new(),
            object_distance: None,
            set: None,
        })
    }

    /// The unit of depth the camera file names, else `"depth units"`.
    pub fn depth_units(&self) -> &str {
        self.report.camera.units.as_deref().unwrap_or("depth units")
    }

    /// The photograph's pixel under `point` (continuous coordinates of the
    /// working-size image, as the input panel maps the pointer); `None`
    /// outside the image.
    pub fn photo_pixel(&self, point: ImagePoint) -> Option<(usize, usize)> {
        let (w, h) = self.size();
        let (fw, fh) = self.full_size;
        let x = (f64::from(point[0]) * fw as f64 / w as f64).floor();
        let y = (f64::from(point[1]) * fh as f64 / h as f64).floor();
        (x >= 0.0 && y >= 0.0 && x < fw as f64 && y < fh as f64).then_some((x as usize, y as usize))
    }

    /// The working-size pixel of a photograph pixel, as `solve
    /// --known-depth` converts it: `((x + 0.5) * w / W - 0.5).round()`.
    pub fn working_pixel(&self, column_px: f64, row_px: f64) -> (f64, f64) {
        sfs_core::photograph_solve::working_pixel(self.full_size, self.size(), column_px, row_px)
    }

    /// The point as the solver takes it (working-size pixel), or why it
    /// cannot be used: a distance that is not positive and finite, a pixel
    /// outside the photograph or off the object mask.
    pub fn check_known_depth(&self, point: &KnownDistance) -> Result<KnownDepth, String> {
        sfs_core::photograph_solve::known_depth(
            point,
            self.full_size,
            self.size(),
            Some(self.masks.object()),
        )
        .map_err(|e| {
            format!(
                "known distance at pixel ({}, {}): {e}",
                point.column_px, point.row_px
            )
        })
    }

    /// Adds a known distance after [`Self::check_known_depth`] (replacing
    /// the one at the same pixel); a refused point changes nothing.
    pub fn set_known_depth(&mut self, point: KnownDistance) -> Result<(), String> {
        self.check_known_depth(&point)?;
        let same = |p: &KnownDistance| p.column_px == point.column_px && p.row_px == point.row_px;
        match self.known_depths.iter_mut().find(|p| same(p)) {
            Some(existing) => *existing = point,
            None => self.known_depths.push(point),
        }
        Ok(())
    }

    /// A number that changes with every mask edit: the painted layers and
    /// a set's photographs' own.
    pub fn mask_revision(&self) -> u64 {
        let own = self.set.as_ref().map_or(0, PhotoSet::revision);
        self.masks.revision() ^ own.rotate_left(17)
    }

    /// The layers the mask tools paint into, with the image flood fill and
    /// threshold read: the set-wide masks (`photo` `None`, or one image),
    /// or photograph `photo`'s own layer (only its confidence is used)
    /// with that photograph.
    pub fn paint_target(&mut self, photo: Option<usize>) -> (&mut Masks, &Grid<f64>) {
        match (photo, &mut self.set) {
            (Some(k), Some(set)) if k < set.photo_masks.len() && k < set.problem.photos.len() => {
                (&mut set.photo_masks[k], &set.problem.photos[k].image)
            }
            _ => (&mut self.masks, &self.image),
        }
    }

    /// Image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        self.image.size()
    }

    /// The problem a solve of the document as it is now gets: the image,
    /// the camera as edited, the painted masks.
    pub fn problem(&self) -> Problem {
        Problem {
            image: self.image.clone(),
            camera: self.camera.intrinsics(),
            intensity_scale: self.camera.intensity_scale,
            object_mask: self.masks.object_for_solver(),
            confidence: self.masks.confidence_for_solver(),
            lights: self.camera.solve_lights(),
        }
    }

    /// The solve of the document as it is now, with `params`: the problem
    /// ([`Self::problem`]), the pipeline's report and clipping, the known
    /// distances (which win over the object's distance) — the same job the
    /// command line's `solve` runs.
    pub fn photograph_solve(&self, params: SolverParams) -> PhotographSolve {
        PhotographSolve {
            problem: self.problem(),
            params,
            method: sfs_core::solver::Method::Linearised,
            initial_depth_given: None,
            photo: self.report.clone(),
            full_size: self.full_size,
            clipped: self.clipped.clone(),
            photos: self.photos.clone(),
            scale_given: self.camera.scale_given,
            confidence_derived: false,
            known_distances: self.known_depths.clone(),
            distance: self
                .object_distance
                .filter(|_| self.known_depths.is_empty()),
        }
    }

    /// Reads the image again through the photo pipeline with `change` made
    /// to its input (sRGB, ambient frame, vignetting, albedo, camera file).
    /// The painted masks stay (where a new albedo cannot be trusted, the
    /// confidence is lowered, one undo step); the camera is the new one
    /// when `change` set a camera file, else the edited one stays. On
    /// failure nothing changes.
    pub fn reread(&mut self, change: impl FnOnce(&mut PhotoInput)) -> Result<()> {
        let mut input = self.input.clone();
        change(&mut input);
        let camera_changed = input.camera != self.input.camera;
        let prepared = photo::prepare(&input)
            .with_context(|| format!("cannot re-read {}", self.path.display()))?;
        if prepared.size() != self.size() {
            anyhow::bail!(
                "{} changed size on disk ({}x{} now); open it again",
                self.path.display(),
                prepared.full_size().0,
                prepared.full_size().1
            );
        }
        if input.albedo.is_some()
            && input.albedo != self.input.albedo
            && let Some(confidence) = &prepared.problem.confidence
        {
            self.masks.lower_confidence(confidence)?;
        }
        // A set is read again as a set: its photographs apart, its image
        // their mean; the photographs' own layers stay.
        let set_problem = match &self.set {
            Some(_) => Some(
                photo::photometric_problem(&prepared, &input)
                    .with_context(|| format!("cannot re-read {}", self.path.display()))?,
            ),
            None => None,
        };
        if camera_changed {
            self.camera = CameraState::from_prepared(&prepared);
        }
        self.srgb = prepared.report.srgb;
        self.srgb_reason = prepared.report.srgb_reason.clone();
        self.report = prepared.report;
        self.clipped = prepared.clipped;
        self.photos = prepared.photos;
        match (set_problem, &mut self.set) {
            (Some(problem), Some(set)) => {
                self.image = mean_image(&problem, prepared.problem.image.size());
                set.problem = problem;
            }
            _ => self.image = prepared.problem.image,
        }
        self.input = input;
        Ok(())
    }

    /// Replaces the camera from a JSON file (keys of `scene.json`), read
    /// through the photo pipeline; intrinsics for another size of the image
    /// are scaled.
    pub fn load_camera(&mut self, path: &Path) -> Result<()> {
        self.reread(|input| input.camera = CameraSpec::File(path.to_path_buf()))
    }

    /// Re-reads the image with or without sRGB linearisation; on failure
    /// nothing changes.
    pub fn set_srgb(&mut self, srgb: bool) -> Result<()> {
        self.reread(|input| {
            input.srgb = if srgb { SrgbMode::On } else { SrgbMode::Off };
        })?;
        self.srgb_reason = if srgb {
            "sRGB decoding on (set in the Camera panel)".into()
        } else {
            "read as linear (set in the Camera panel)".into()
        };
        Ok(())
    }
}

/// The mean of a set's photographs (what its mean prediction, the
/// solver's reprojection, is compared with).
fn mean_image(problem: &PhotometricProblem, (w, h): (usize, usize)) -> Grid<f64> {
    let n = problem.photos.len().max(1) as f64;
    let mut mean = Grid::filled(w, h, 0.0);
    for photo in problem.photos.iter().filter(|p| p.image.size() == (w, h)) {
        for (m, v) in mean.as_mut_slice().iter_mut().zip(photo.image.as_slice()) {
            *m += v / n;
        }
    }
    mean
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

    fn sample() -> PathBuf {
        sample_image_path().unwrap_or_else(|| panic!("assets/sombrero/image16.png is missing"))
    }

    fn open(path: &Path, options: &OpenOptions) -> Document {
        Document::open(path, options).unwrap_or_else(|e| panic!("{e:#}"))
    }

    #[test]
    fn sample_opens_with_camera_and_ground_truth() {
        let doc = open(
            &sample(),
            &OpenOptions {
                srgb: Some(false),
                ..OpenOptions::default()
            },
        );
        assert!(matches!(doc.camera.source, CameraSource::File(_)));
        assert!(doc.ground_truth.is_some());
        assert_eq!(doc.size(), (256, 256));
        assert!(doc.input.object_mask.is_some(), "mask.png beside");
    }

    #[test]
    fn bad_files_give_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let bad = dir.path().join("not-an-image.png");
        std::fs::write(&bad, b"hello").unwrap_or_else(|e| panic!("{e}"));
        let err = match Document::open(&bad, &OpenOptions::default()) {
            Ok(_) => panic!("opened a non-image"),
            Err(e) => format!("{e:#}"),
        };
        assert!(err.contains("not-an-image.png"), "{err}");
        let mut doc = open(&sample(), &OpenOptions::default());
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
        // Asked for at opening, the same file is left out with a note and
        // the image opens.
        let doc = open(
            &sample(),
            &OpenOptions {
                camera: Some(camera.clone()),
                ambient: Some(bad.clone()),
                ..OpenOptions::default()
            },
        );
        assert!(
            doc.notes
                .iter()
                .any(|n| n.contains("ignored") && n.contains("cam.json"))
        );
        assert!(doc.notes.iter().any(|n| n.contains("not-an-image.png")));
        assert_eq!(doc.input.ambient, None);
        assert!(
            matches!(doc.input.camera, CameraSpec::File(_)),
            "the scene.json beside"
        );
    }

    /// An explicit object mask at the photograph's size is scaled to a
    /// smaller working size as `solve` scales it, not dropped (the probe of
    /// issue 23: a mask named otherwise than `mask.png`).
    #[test]
    fn an_explicit_full_size_mask_is_scaled_to_the_working_size() {
        let dir = tempfile::tempdir().expect("temp dir");
        let image = dir.path().join("photo.png");
        std::fs::copy(sample(), &image).expect("copies the sample");
        // The left half is object.
        let mask = dir.path().join("m_left.png");
        let left = Grid::from_fn(256, 256, |c, _| c < 128);
        sfs_core::io::write_mask_png(&mask, &left).expect("writes the mask");
        let doc = open(
            &image,
            &OpenOptions {
                max_side: Some(128),
                mask: Some(mask.clone()),
                ..OpenOptions::default()
            },
        );
        assert_eq!(doc.size(), (128, 128));
        let object = doc.masks.object();
        assert!(*object.at(10, 64) && !*object.at(118, 64));
        let count = object.as_slice().iter().filter(|&&o| o).count();
        assert_eq!(count, 64 * 128);
    }

    #[test]
    fn known_distances_convert_as_the_command_line_does_and_bad_ones_are_refused() {
        // The 256x256 sample at a working size of 128.
        let mut doc = open(
            &sample(),
            &OpenOptions {
                max_side: Some(128),
                ..OpenOptions::default()
            },
        );
        assert_eq!((doc.size(), doc.full_size), ((128, 128), (256, 256)));
        // A click at working coordinates (50.3, 70.9): photograph pixel
        // (100, 141), working pixel ((100.5 / 2 - 0.5).round(), ...).
        assert_eq!(doc.photo_pixel([50.3, 70.9]), Some((100, 141)));
        assert_eq!(doc.photo_pixel([-0.1, 3.0]), None);
        assert_eq!(doc.photo_pixel([128.0, 3.0]), None);
        assert_eq!(doc.working_pixel(100.0, 141.0), (50.0, 70.0));
        let point = KnownDistance {
            column_px: 100.0,
            row_px: 141.0,
            depth: 2.0,
        };
        let solver = doc
            .check_known_depth(&point)
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            (solver.column_px, solver.row_px, solver.depth),
            (50.0, 70.0, 2.0)
        );
        // `point` moved to column `c`, and why a point is refused (empty
        // if it is taken).
        let at_column = |c: f64| KnownDistance {
            column_px: c,
            ..point
        };
        let refusal =
            |doc: &mut Document, p: KnownDistance| doc.set_known_depth(p).err().unwrap_or_default();
        for depth in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let reason = refusal(&mut doc, KnownDistance { depth, ..point });
            assert!(reason.contains("positive number"), "{reason}");
        }
        let reason = refusal(&mut doc, at_column(256.0));
        assert!(reason.contains("outside"), "{reason}");
        assert!(doc.known_depths.is_empty(), "refused points change nothing");
        doc.set_known_depth(point).unwrap_or_else(|e| panic!("{e}"));
        // The same pixel again replaces its distance.
        doc.set_known_depth(KnownDistance {
            depth: 3.0,
            ..point
        })
        .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(doc.known_depths.len(), 1);
        assert_eq!(doc.known_depths[0].depth, 3.0);
        // Off the object (painted as background): refused, and a point
        // given before the mask changed stops the solve with the reason.
        doc.masks.clear(crate::mask_edit::Layer::Object);
        doc.masks.invert(crate::mask_edit::Layer::Object);
        assert!(doc.masks.object().as_slice().iter().all(|&o| !o));
        let reason = doc
            .photograph_solve(SolverParams::default())
            .known_depths()
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(reason.contains("off the object"), "{reason}");
        let reason = refusal(&mut doc, at_column(10.0));
        assert!(reason.contains("off the object"), "{reason}");
        assert_eq!(doc.known_depths.len(), 1);
    }

    #[test]
    fn corrections_reread_the_image_and_keep_the_painted_masks() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let mut doc = open(&sample(), &OpenOptions::default());
        let (w, h) = doc.size();
        let before = doc.image.clone();
        doc.masks.clear(crate::mask_edit::Layer::Object);
        let painted = doc.masks.object().clone();
        let ambient = dir.path().join("ambient.png");
        io::write_png16(&ambient, &Grid::filled(w, h, 0.01)).unwrap_or_else(|e| panic!("{e}"));
        doc.reread(|input| input.ambient = Some(ambient.clone()))
            .unwrap_or_else(|e| panic!("{e:#}"));
        assert_eq!(doc.report.ambient.as_deref(), Some(ambient.as_path()));
        let expected = before.map(|&v| (v - 0.01).max(0.0));
        for (a, b) in doc.image.as_slice().iter().zip(expected.as_slice()) {
            assert!((a - b).abs() < 1e-4, "{a} vs {b}");
        }
        assert_eq!(doc.masks.object(), &painted, "the painted mask stays");
        // A flat field of the wrong size changes nothing.
        let small = dir.path().join("flat.png");
        io::write_png16(&small, &Grid::filled(3, 3, 0.5)).unwrap_or_else(|e| panic!("{e}"));
        let image = doc.image.clone();
        let err = doc
            .reread(|input| input.vignetting = Vignetting::FlatField(small.clone()))
            .err()
            .map(|e| format!("{e:#}"))
            .unwrap_or_default();
        assert!(err.contains("flat.png"), "{err}");
        assert_eq!(doc.image, image);
        assert_eq!(doc.input.vignetting, Vignetting::None);
    }

    #[test]
    fn a_folder_or_several_photographs_open_as_one_set() {
        let dir = tempfile::tempdir().expect("temp dir");
        let images = crate::test_sets::write_set(dir.path());
        let side = crate::test_sets::SIDE;
        // The folder: the photographs its scene.json names, mask.png beside.
        let folder = Document::open_paths(&[dir.path().to_path_buf()], &OpenOptions::default())
            .unwrap_or_else(|e| panic!("{e:#}"));
        let set = folder.set.as_ref().expect("a set");
        assert_eq!(set.paths, images);
        assert_eq!(set.problem.photos.len(), crate::test_sets::PHOTOS);
        assert_eq!(set.names()[0], "led1.png");
        assert_eq!(folder.size(), (side, side));
        assert_eq!(folder.path, dir.path());
        assert!(folder.input.photometric_stereo);
        assert!(folder.input.object_mask.is_some(), "mask.png beside");
        // Its image is the photographs' mean.
        let mean: f64 = set
            .problem
            .photos
            .iter()
            .map(|p| p.image.at(24, 20))
            .sum::<f64>()
            / set.problem.photos.len() as f64;
        assert!((folder.image.at(24, 20) - mean).abs() < 1e-12);
        // Several photographs: the same set.
        let listed = Document::open_paths(&images, &OpenOptions::default())
            .unwrap_or_else(|e| panic!("{e:#}"));
        let listed_set = listed.set.as_ref().expect("a set");
        assert_eq!(listed_set.paths, images);
        for (a, b) in listed_set.problem.photos.iter().zip(&set.problem.photos) {
            assert_eq!(a.image, b.image);
            assert_eq!(a.light, b.light);
        }
        // One of them alone is one image, as before.
        let single = Document::open_paths(&images[..1], &OpenOptions::default())
            .unwrap_or_else(|e| panic!("{e:#}"));
        assert!(single.set.is_none());
        assert_eq!(single.camera.lights.len(), 1, "its own light, by its name");
        // A folder without a camera file says so and opens nothing.
        let empty = tempfile::tempdir().expect("temp dir");
        let error = Document::open_paths(&[empty.path().to_path_buf()], &OpenOptions::default())
            .err()
            .map(|e| format!("{e:#}"))
            .unwrap_or_default();
        assert!(error.contains("scene.json"), "{error}");
    }

    #[test]
    fn painted_masks_and_a_photographs_own_layer_reach_the_sets_problem() {
        let dir = tempfile::tempdir().expect("temp dir");
        crate::test_sets::write_set(dir.path());
        let mut doc = Document::open_paths(&[dir.path().to_path_buf()], &OpenOptions::default())
            .unwrap_or_else(|e| panic!("{e:#}"));
        let untouched = doc.set_problem().expect("a set");
        assert!(untouched.photos.iter().all(|p| p.confidence.is_none()));
        assert!(untouched.confidence.is_none());
        let revision = doc.mask_revision();
        // Photograph 2's own layer: a rectangle of confidence 0.
        let (masks, image) = doc.paint_target(Some(1));
        assert_eq!(
            image.size(),
            (crate::test_sets::SIDE, crate::test_sets::SIDE)
        );
        assert!(masks.fill_rect(
            crate::mask_edit::Layer::Confidence,
            crate::mask_edit::Mode::Paint,
            [10.0, 10.0],
            [20.0, 20.0],
        ));
        assert_ne!(
            doc.mask_revision(),
            revision,
            "an edit of a photograph's layer counts"
        );
        // The set-wide object mask: a column painted as background.
        let (masks, _) = doc.paint_target(None);
        masks.fill_rect(
            crate::mask_edit::Layer::Object,
            crate::mask_edit::Mode::Paint,
            [0.0, 0.0],
            [3.0, 48.0],
        );
        let problem = doc.set_problem().expect("a set");
        let own = problem.photos[1]
            .confidence
            .as_ref()
            .expect("its own layer");
        assert_eq!(*own.at(15, 15), 0.0);
        assert_eq!(*own.at(30, 30), 1.0);
        assert!(
            problem
                .photos
                .iter()
                .enumerate()
                .all(|(k, p)| k == 1 || p.confidence.is_none())
        );
        let object = problem.object_mask.as_ref().expect("the object mask");
        assert!(!*object.at(1, 24), "painted background");
        assert!(*object.at(24, 24));
        sfs_core::solver::photometric::validate(&problem).unwrap_or_else(|e| panic!("{e}"));
    }
}
