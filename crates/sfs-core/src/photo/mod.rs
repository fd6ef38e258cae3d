//! The one way a photograph becomes a solver [`Problem`], for the command
//! line and the viewer alike: [`PhotoInput`] says what to read and how
//! (photographs, camera file or focal length or EXIF, lights, masks, ambient
//! frame, vignetting, albedo, sRGB, working size), [`prepare`] reads and
//! corrects it and returns the problem with a [`PhotoReport`] of every
//! decision and its reason.
//!
//! Order of the work: the photograph's size from its header, the camera and
//! lights, the memory guard (before any pixel is decoded), the corrections
//! ([`corrections`]), the working size (area averaging, the intrinsics and
//! masks scaled alike), the masks ([`read_mask_at`], the one reader of mask
//! files), then the suggested confidence when asked for.
//!
//! Several photographs are summed in linear light, and the sum is saturated
//! only where one of them was: the pipeline records where any input was
//! saturated ([`PreparedPhoto::clipped`]), gives those pixels confidence 0,
//! and where the sum passes the top of the range elsewhere divides it and
//! the lights' intensities by a power of two (exact; [`PhotoReport::sum_divisor`])
//! so that the solver's rule for one photograph (a value at the top of the
//! range is clipped) no longer applies to it. One photograph is read exactly
//! as before. When each photograph has its own light (a camera file's
//! `image` names), each one's corrected image is kept ([`PreparedPhoto::photos`])
//! for the fit per photograph ([`fit_per_photo`]).

mod camera;
pub mod corrections;
pub mod folder;
mod input;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::io::{self, IoError};
use crate::light::{LightModel, PointLight};
use crate::memory::{self, MemoryError};
use crate::model::{self, LevelGeometry};
use crate::model_fit::{self, ModelFit, Photographs, Suggestion};
use crate::resample::{resize_area, scale_intrinsics, working_size};
use crate::solver::Problem;
use crate::solver::problem::SATURATED;

pub use camera::{CameraSource, exif_focal_35mm};
pub use corrections::{MIN_ALBEDO, Vignetting, cos4};
pub use input::{CameraSpec, LightSpec, PhotoError, PhotoInput, ScaleSpec};

/// The camera as decided, for the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraReport {
    /// Focal length at the working size, pixels.
    pub focal: f64,
    /// Principal point column at the working size, pixels.
    pub cx: f64,
    /// Principal point row at the working size, pixels.
    pub cy: f64,
    /// Where the intrinsics came from.
    pub source: CameraSource,
    /// The intensity scale the problem starts from.
    pub intensity_scale: f64,
    /// Whether it was given (option or camera file); if not, it is 1 or
    /// estimated by the solve.
    pub intensity_scale_given: bool,
    /// The unit of depth, when the camera file says it.
    pub units: Option<String>,
}

/// Every decision [`prepare`] took, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PhotoReport {
    /// The photographs.
    pub images: Vec<PathBuf>,
    /// The photograph's own width.
    pub full_width: usize,
    /// The photograph's own height.
    pub full_height: usize,
    /// The working width.
    pub width: usize,
    /// The working height.
    pub height: usize,
    /// Whether sRGB decoding was applied.
    pub srgb: bool,
    /// Why.
    pub srgb_reason: String,
    /// The ambient frame subtracted.
    pub ambient: Option<PathBuf>,
    /// Share of pixels that went below zero after the ambient subtraction
    /// (clamped to 0).
    pub ambient_clamped_share: f64,
    /// The vignetting correction (`cos4` or the flat field's path).
    pub vignetting: Option<String>,
    /// The albedo map divided out.
    pub albedo: Option<PathBuf>,
    /// Share of pixels whose albedo was too low to divide by (confidence 0).
    pub albedo_untrusted_share: f64,
    /// The object mask.
    pub mask: Option<PathBuf>,
    /// The confidence image.
    pub confidence: Option<PathBuf>,
    /// What the suggested confidence lowered, when asked for.
    pub auto_confidence: Option<Suggestion>,
    /// The camera.
    pub camera: CameraReport,
    /// The lights switched on (empty: one at the optical centre); with
    /// several photographs their intensities are divided by `sum_divisor`
    /// like the sum.
    pub lights: Vec<PointLight>,
    /// Every light of the camera file with a principal direction, on or off
    /// for this photograph (intensities as listed): the rig whose aim is
    /// a cue to the object's distance (`solver::depth_unit`). Empty without
    /// a camera file or when the lights were given.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub rig_lights: Vec<PointLight>,
    /// Float photographs (no fixed white): the power of two their values
    /// and the lights' intensities were multiplied by, so that the
    /// brightest trusted object pixel lies in [1/2, 1) (exact; a given
    /// intensity scale keeps its meaning in the files' units). `None` for
    /// integer photographs, read on [0, 1].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub float_scale: Option<f64>,
    /// Several photographs: the power of two their sum (and the lights'
    /// intensities) was divided by so that no trusted value the photographs
    /// did not clip reaches the top of the range (1 when none did); the
    /// problem's image is the sum divided by it. `None` for one photograph.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sum_divisor: Option<f64>,
    /// Several photographs: the share of the object's pixels saturated in
    /// at least one of them (given confidence 0). `None` for one
    /// photograph, whose saturated pixels the solver finds by their value.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clipped_share: Option<f64>,
    /// Sentences for the summary: each decision that is not the obvious one,
    /// with its reason (in a solve's report they are its `notes`).
    #[serde(skip)]
    pub notes: Vec<String>,
}

/// One photograph of a sum with a light of its own, for the fit per
/// photograph ([`fit_per_photo`]).
#[derive(Clone, Debug)]
pub struct SummedPhoto {
    /// The photograph.
    pub path: PathBuf,
    /// The index of its light in the problem's lights (and the report's).
    pub light_index: usize,
    /// That light with its intensity on this photograph's own scale (the
    /// problem's light times the sum's divisor): `s` times its irradiance
    /// explains the photograph alone.
    pub light: PointLight,
    /// Its own corrected linear image at the working size (ambient frame,
    /// vignetting and albedo as for the sum).
    pub image: Grid<f64>,
    /// Where it was saturated, at the working size.
    pub clipped: Grid<bool>,
}

/// How well a solved depth explains one photograph of a sum under its own
/// light alone (the `model_fit_per_photo` entries of a solve's report).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PhotoFit {
    /// The photograph.
    pub image: PathBuf,
    /// The index of its light in the report's `lights`.
    pub light_index: usize,
    /// The fit summary against this photograph alone.
    #[serde(flatten)]
    pub fit: ModelFit,
}

/// A photograph ready for the solver.
#[derive(Clone, Debug)]
pub struct PreparedPhoto {
    /// The problem at the working size (intensity scale 1 when unknown).
    pub problem: Problem,
    /// The photograph's intrinsics at its own size.
    pub full_camera: Intrinsics,
    /// Whether the intensity scale was given.
    pub intensity_scale_given: bool,
    /// Whether a correction or `auto_confidence` made the confidence (not
    /// only a confidence file).
    pub confidence_derived: bool,
    /// What was decided and why.
    pub report: PhotoReport,
    /// Several photographs: where any of them was saturated, at the working
    /// size (those pixels have confidence 0); `None` for one photograph.
    pub clipped: Option<Grid<bool>>,
    /// Several photographs each taken by a light of its own (a camera
    /// file's `image` names): each one, in the order given; else empty.
    pub photos: Vec<SummedPhoto>,
    /// Whether the lights' relative intensities were measured (a camera
    /// file's `intensity` or `rgb_intensity` for every light, or given
    /// intensities).
    pub intensities_measured: bool,
}

impl PreparedPhoto {
    /// What the photograph's set-up says of the object's distance (a given
    /// intensity scale, the rig's aimed lights), for
    /// [`crate::solver::depth_unit::solve_photograph`]; the fronts add what
    /// the user says (known distances, the object's distance).
    pub fn distance_cues(&self) -> crate::solver::depth_unit::DistanceCues {
        crate::solver::depth_unit::DistanceCues {
            scale_given: self.intensity_scale_given,
            rig_lights: self.report.rig_lights.clone(),
            ..Default::default()
        }
    }

    /// The working size.
    pub fn size(&self) -> (usize, usize) {
        self.problem.image.size()
    }

    /// The photograph's own size.
    pub fn full_size(&self) -> (usize, usize) {
        (self.report.full_width, self.report.full_height)
    }

    /// What the fit summary needs to know of the photographs behind the
    /// problem's image: one photograph, or a sum saturated where
    /// [`Self::clipped`] says, on the scale [`PhotoReport::sum_divisor`]
    /// divided it to.
    pub fn photographs(&self) -> Photographs<'_> {
        Photographs {
            saturated: self.clipped.as_ref(),
            scale: self.report.sum_divisor.unwrap_or(1.0),
        }
    }
}

/// The fit of a solution's depth (NaN off its domain) to each photograph
/// of `photos` alone: its own corrected image against the reprojection
/// under its own light with the solve's intensity scale `intensity_scale`
/// and material, over the solve's `confidence`. The problem's brightness
/// scale (the solution's, of the sum as divided by `sum_divisor`) is shared
/// out among the photographs by their lights' intensities. `camera`: the
/// intrinsics at the working size.
pub fn fit_per_photo(
    photos: &[SummedPhoto],
    solution: &crate::solver::Solution,
    camera: Intrinsics,
    intensity_scale: f64,
    confidence: Option<&Grid<f64>>,
    sum_divisor: f64,
) -> Vec<PhotoFit> {
    let depth = &solution.depth;
    let intensity_ref = solution.scales.intensity;
    let (w, h) = depth.size();
    let domain = depth.map(|z| z.is_finite());
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let total: f64 = photos.iter().map(|p| p.light.intensity).sum();
    photos
        .iter()
        .filter(|p| p.image.size() == (w, h) && p.clipped.size() == (w, h))
        .map(|photo| {
            let model =
                LightModel::with_material(intensity_scale, &[photo.light], solution.material);
            let reprojection =
                model::reproject(&model, &geometry, &domain, depth, Cancel::NEVER).uncancelled();
            let share = if total > 0.0 {
                photo.light.intensity / total
            } else {
                1.0
            };
            let fit = model_fit::measure_photographs(
                &photo.image,
                &reprojection,
                &domain,
                confidence,
                intensity_ref * sum_divisor * share,
                Photographs {
                    saturated: Some(&photo.clipped),
                    scale: 1.0,
                },
            );
            PhotoFit {
                image: photo.path.clone(),
                light_index: photo.light_index,
                fit,
            }
        })
        .collect()
}

/// Reads a mask or confidence image for a photograph of `full` pixels solved
/// at `working` pixels: an image of the photograph's size is area-averaged
/// to the working size, one of the working size is taken as it is. Values in
/// [0, 1]. The one reader of mask files.
///
/// # Errors
/// An unreadable file, or one of neither size; the message names `what`,
/// the file and the sizes.
pub fn read_mask_at(
    path: &Path,
    what: &str,
    full: (usize, usize),
    working: (usize, usize),
) -> Result<Grid<f64>, IoError> {
    let mask = io::read_mask(path)?;
    if mask.size() == working {
        return Ok(mask);
    }
    if mask.size() == full {
        // Averaging weights sum to 1 up to rounding: 1.0000000000000002 is
        // not a confidence, so the average is clamped to [0, 1].
        return Ok(resize_area(&mask, working.0, working.1, Cancel::NEVER)
            .uncancelled()
            .map(|v| v.clamp(0.0, 1.0)));
    }
    let working_too = if working == full {
        String::new()
    } else {
        format!(" (or the working size {}x{})", working.0, working.1)
    };
    Err(IoError::BadImage {
        path: path.to_path_buf(),
        reason: format!(
            "the {what} is {}x{} but the photograph is {}x{}{working_too}",
            mask.width(),
            mask.height(),
            full.0,
            full.1
        ),
    })
}

/// Reads and corrects the photograph(s) of `input` into a solver problem,
/// with the report of what was decided.
///
/// # Errors
/// A file that cannot be read or does not fit the photograph, a camera or
/// lights that cannot be decided, a solve that would not fit the memory;
/// the message names the file or setting.
pub fn prepare(input: &PhotoInput) -> Result<PreparedPhoto, PhotoError> {
    let Some(first) = input.images.first() else {
        return Err(PhotoError::Input("no photograph given".into()));
    };
    let full_size = io::photo_size(first)?;
    crate::memory::return_large_frees_to_the_system();
    let mut decided = camera::decide(input, full_size)?;
    if let Some(orientation) = io::exif_orientation(first) {
        decided.notes.push(format!(
            "{} carries the EXIF orientation {orientation:?}: read upright ({}x{}), as photo \
             viewers show it; masks and the other inputs are taken as drawn on the upright \
             photograph",
            first.display(),
            full_size.0,
            full_size.1
        ));
    }
    if input.photometric_stereo {
        check_set(input, &decided.lights)?;
    }
    let working = working_size(full_size.0, full_size.1, input.max_side);
    let least = crate::solver::problem::MIN_IMAGE_SIDE;
    if working != full_size && (working.0 < least || working.1 < least) {
        // Named as what the user set: the solver only sees "the image".
        return Err(PhotoError::Input(format!(
            "the working size ({} {}) is {}x{}; at least {least}x{least} pixels are needed: \
             give a larger {} (0 for the full size, {}x{})",
            input.max_side_setting,
            input.max_side.unwrap_or(0),
            working.0,
            working.1,
            input.max_side_setting,
            full_size.0,
            full_size.1
        )));
    }
    let own_lights = lights_per_photograph(input, &decided.lights);
    check_memory(input, full_size, own_lights)?;
    let vignetting = &input.vignetting;
    let mut photo = corrections::load(
        &corrections::Corrections {
            images: &input.images,
            srgb: input.srgb,
            ambient: input.ambient.as_deref(),
            vignetting,
            albedo: input.albedo.as_deref(),
            max_side: input.max_side,
            keep_each: own_lights,
        },
        Some(decided.camera),
    )?;
    let size = photo.image.size();
    let camera = scale_intrinsics(decided.camera, full_size, size);
    if size != full_size {
        decided.notes.push(format!(
            "solved at {}x{} (area-averaged from {}x{}; {} 0 for the full size)",
            size.0, size.1, full_size.0, full_size.1, input.max_side_setting
        ));
    }
    let object_mask = match &input.object_mask {
        Some(path) => Some(read_mask_at(path, "mask", full_size, size)?.map(|&v| v >= 0.5)),
        None => None,
    };
    let mut confidence = match &input.confidence {
        Some(path) => Some(read_mask_at(path, "confidence", full_size, size)?),
        None => None,
    };
    let mut albedo_untrusted_share = 0.0;
    if let Some(lost) = &photo.lost {
        let untrusted = lost.as_slice().iter().filter(|&&v| v < 1.0).count();
        albedo_untrusted_share = untrusted as f64 / lost.len().max(1) as f64;
        confidence = Some(match confidence {
            Some(c) => c.zip_map(lost, |a, b| a.min(*b)),
            None => lost.clone(),
        });
    }
    let mut lights = decided.lights;
    let float_scale = photo.float.then(|| {
        scale_float_photo(
            &mut photo,
            &mut lights,
            object_mask.as_ref(),
            confidence.as_ref(),
        )
    });
    if let Some(scale) = float_scale {
        let which = match input.images.as_slice() {
            [one] => format!("{} holds", one.display()),
            _ => "the photographs hold".into(),
        };
        let scaled = if scale == 1.0 {
            "its brightest trusted object pixel already lies in [1/2, 1)".to_owned()
        } else {
            format!(
                "multiplied by 2^{} (exact) so that the brightest trusted object pixel lies in \
                 [1/2, 1), the lights' intensities alike (a given intensity scale keeps its \
                 meaning in the file's units)",
                scale.log2().round() as i64
            )
        };
        decided.notes.push(format!(
            "{which} float samples, which have no fixed white: read on their own scale ({scaled}); \
             no pixel is taken for saturated by its value"
        ));
    }
    for (path, samples) in &photo.negatives {
        decided.notes.push(format!(
            "{} holds negative values (noise below a dark level?) at {} pixels ({:.2} % of the \
             image): read as 0",
            path.display(),
            samples.negative_pixels,
            100.0 * samples.negative_share
        ));
    }
    let mut clipped_share = None;
    if let Some(clipped) = &photo.clipped {
        if input.photometric_stereo {
            // A set leaves each photograph's saturated pixels out of that
            // photograph alone: the set's confidence stays as given.
            let mut unused = confidence.clone();
            clipped_share = untrust_clipped(
                clipped,
                object_mask.as_ref(),
                &mut unused,
                &mut decided.notes,
            )
            .ok();
        } else {
            clipped_share = Some(untrust_clipped(
                clipped,
                object_mask.as_ref(),
                &mut confidence,
                &mut decided.notes,
            )?);
        }
    }
    let mut suggestion = None;
    if input.auto_confidence {
        let object = object_mask
            .clone()
            .unwrap_or_else(|| Grid::filled(size.0, size.1, true));
        let photographs = Photographs {
            saturated: photo.clipped.as_ref(),
            scale: 1.0,
        };
        let (suggested, counts) =
            model_fit::suggest_confidence_photographs(&photo.image, &object, None, photographs);
        confidence = Some(match confidence {
            Some(c) => c.zip_map(&suggested, |a, b| a.min(*b)),
            None => suggested,
        });
        suggestion = Some(counts);
    }
    let mut image = photo.image;
    let mut sum_divisor = None;
    if let Some(clipped) = &photo.clipped {
        let divisor = sum_divisor_for(&image, clipped, object_mask.as_ref(), confidence.as_ref());
        if divisor > 1.0 {
            // Exact: a power of two scales every value and intensity alike.
            image = image.map(|v| v / divisor);
            if lights.is_empty() {
                lights.push(PointLight {
                    intensity: 1.0 / divisor,
                    ..PointLight::CENTRED
                });
            } else {
                for light in &mut lights {
                    light.intensity /= divisor;
                }
            }
            if input.images.len() == 1 {
                decided.notes.push(format!(
                    "with the albedo or the vignetting divided out, the photograph passes the top \
                     of its range where it was not saturated as taken: it and the light's \
                     intensity are divided by {divisor}, so that the solver does not take it for \
                     clipped (the images written are divided too; a relative albedo's scale goes \
                     into the intensity scale)"
                ));
            } else if !input.photometric_stereo {
                decided.notes.push(format!(
                    "the sum of the {} photographs passes the top of one photograph's range where \
                 none was saturated: it and the lights' intensities are divided by {divisor}, \
                 so that the solver does not take it for clipped (the images written are the \
                 sum / {divisor})",
                    input.images.len()
                ));
            }
        }
        sum_divisor = Some(divisor);
    }
    let divisor = sum_divisor.unwrap_or(1.0);
    let photos: Vec<SummedPhoto> = if own_lights {
        input
            .images
            .iter()
            .zip(photo.each)
            .enumerate()
            .filter_map(|(k, (path, each))| {
                let mut light = *lights.get(k)?;
                light.intensity *= divisor;
                Some(SummedPhoto {
                    path: path.clone(),
                    light_index: k,
                    light,
                    image: each.image?,
                    clipped: each.clipped,
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    if input.images.len() > 1 && !own_lights {
        decided.notes.push(
            "no model fit per photograph: which light took which photograph is known only \
             from a camera file's `image` names"
                .into(),
        );
    }
    let (srgb, srgb_reason) = photo.srgb;
    let intensity_scale = decided.intensity_scale.unwrap_or(1.0);
    let report = PhotoReport {
        images: input.images.clone(),
        full_width: full_size.0,
        full_height: full_size.1,
        width: size.0,
        height: size.1,
        srgb,
        srgb_reason,
        ambient: input.ambient.clone(),
        ambient_clamped_share: photo.ambient_clamped,
        vignetting: match vignetting {
            Vignetting::None => None,
            Vignetting::Cos4 => Some("cos4".into()),
            Vignetting::FlatField(path) => Some(path.display().to_string()),
        },
        albedo: input.albedo.clone(),
        albedo_untrusted_share,
        mask: input.object_mask.clone(),
        confidence: input.confidence.clone(),
        auto_confidence: suggestion,
        camera: CameraReport {
            focal: camera.focal_px,
            cx: camera.principal_x_px,
            cy: camera.principal_y_px,
            source: decided.source,
            intensity_scale,
            intensity_scale_given: decided.intensity_scale.is_some(),
            units: decided.units,
        },
        lights: lights.clone(),
        rig_lights: decided.rig_lights,
        float_scale,
        sum_divisor,
        clipped_share,
        notes: decided.notes,
    };
    let clipped_any = photo
        .clipped
        .as_ref()
        .is_some_and(|c| c.as_slice().iter().any(|&v| v));
    Ok(PreparedPhoto {
        problem: Problem {
            image,
            camera,
            intensity_scale,
            object_mask,
            confidence,
            lights,
        },
        full_camera: decided.camera,
        intensity_scale_given: decided.intensity_scale.is_some(),
        confidence_derived: photo.lost.is_some() || input.auto_confidence || clipped_any,
        report,
        clipped: photo.clipped,
        photos,
        intensities_measured: decided.intensities_measured,
    })
}

/// Refuses what cannot be a photometric-stereo set before any pixel is
/// decoded: fewer than two photographs, or lights that are not one per
/// photograph.
fn check_set(input: &PhotoInput, lights: &[PointLight]) -> Result<(), PhotoError> {
    if input.images.len() < 2 {
        return Err(PhotoError::Input(format!(
            "photometric stereo needs at least 2 photographs, each with its own light; got {}",
            input
                .images
                .first()
                .map_or("none".into(), |p| p.display().to_string())
        )));
    }
    if input.albedo.is_some() {
        return Err(PhotoError::Input(
            "a photometric-stereo set finds the albedo itself: --albedo is for one photograph"
                .into(),
        ));
    }
    if let LightSpec::Given(given) = &input.lights
        && given.len() != input.images.len()
    {
        return Err(PhotoError::Input(format!(
            "{} photographs but {} lights: give one --light per photograph, in the same order",
            input.images.len(),
            given.len()
        )));
    }
    if let LightSpec::CameraFile { picks } = &input.lights
        && !picks.is_empty()
    {
        return Err(PhotoError::Input(
            "--light-index picks lights that are on together; a photometric-stereo set takes \
             each photograph's own light from the camera file's `image` names"
                .into(),
        ));
    }
    if lights.len() != input.images.len() {
        return Err(PhotoError::Input(format!(
            "{} photographs but {} lights: each photograph of a set needs its own light (a \
             camera file whose `lights` name each image, or one --light per photograph)",
            input.images.len(),
            lights.len()
        )));
    }
    for (k, (a, la)) in input.images.iter().zip(lights).enumerate() {
        for (b, lb) in input.images[..k].iter().zip(lights) {
            if la.position == lb.position {
                return Err(PhotoError::Input(format!(
                    "{} and {} have the same light (at {:?}): each photograph of a set must be \
                     lit from a different place",
                    b.display(),
                    a.display(),
                    la.position
                )));
            }
        }
    }
    if !input.photo_confidence.is_empty() && input.photo_confidence.len() != input.images.len() {
        return Err(PhotoError::Input(format!(
            "{} per-photograph masks for {} photographs",
            input.photo_confidence.len(),
            input.images.len()
        )));
    }
    Ok(())
}

/// The photometric-stereo problem of a prepared set (see
/// [`PhotoInput::photometric_stereo`]): each photograph's corrected image
/// at the working size with its light and saturation, its own confidence
/// file read at the working size, the set's mask and confidence.
///
/// # Errors
/// A set without a light per photograph, an unreadable per-photograph
/// mask, or an invalid set (the message names the photograph).
pub fn photometric_problem(
    prepared: &PreparedPhoto,
    input: &PhotoInput,
) -> Result<crate::solver::photometric::PhotometricProblem, PhotoError> {
    use crate::solver::photometric::{PhotometricProblem, SetPhoto, validate};
    if prepared.photos.len() != input.images.len() || input.images.len() < 2 {
        return Err(PhotoError::Input(
            "these photographs are not a set with a light each (solve them with \
             --photometric-stereo and a camera file that names each image, or one --light per \
             photograph)"
                .into(),
        ));
    }
    let working = prepared.size();
    let full = prepared.full_size();
    let mut photos = Vec::with_capacity(prepared.photos.len());
    for (k, photo) in prepared.photos.iter().enumerate() {
        let confidence = match input.photo_confidence.get(k) {
            Some(Some(path)) => Some(read_mask_at(path, "photograph's mask", full, working)?),
            _ => None,
        };
        photos.push(SetPhoto {
            name: photo.path.display().to_string(),
            image: photo.image.clone(),
            light: photo.light,
            saturated: Some(photo.clipped.clone()),
            confidence,
        });
    }
    let problem = PhotometricProblem {
        photos,
        camera: prepared.problem.camera,
        object_mask: prepared.problem.object_mask.clone(),
        confidence: prepared.problem.confidence.clone(),
        intensities_known: prepared.intensities_measured,
        intensity_scale: prepared
            .intensity_scale_given
            .then_some(prepared.problem.intensity_scale),
    };
    validate(&problem).map_err(|e| PhotoError::Input(e.to_string()))?;
    Ok(problem)
}

/// Whether the lights decided for `input` are one per photograph, in the
/// photographs' order: several photographs, lights from the camera file
/// without picks (each photograph's own light by its `image` name, see
/// `camera::decide_lights`), one light each.
fn lights_per_photograph(input: &PhotoInput, lights: &[PointLight]) -> bool {
    let from_names = match &input.lights {
        LightSpec::CameraFile { picks } => picks.is_empty(),
        LightSpec::CameraFileOrCentred => true,
        LightSpec::Given(_) => false,
    };
    let given_each = input.photometric_stereo && matches!(input.lights, LightSpec::Given(_));
    (given_each || from_names && matches!(input.camera, CameraSpec::File(_)))
        && input.images.len() > 1
        && lights.len() == input.images.len()
        && input.images.iter().all(|p| p.file_name().is_some())
}

/// A sum's saturated pixels (`clipped`: where any photograph was) get
/// confidence 0, whatever the sum's value; returns their share of the
/// object. Refuses a sum saturated on more than half of its trusted object
/// pixels, as the solver refuses such a photograph.
fn untrust_clipped(
    clipped: &Grid<bool>,
    object: Option<&Grid<bool>>,
    confidence: &mut Option<Grid<f64>>,
    notes: &mut Vec<String>,
) -> Result<f64, PhotoError> {
    let (mut objects, mut trusted, mut saturated, mut on_object) = (0usize, 0usize, 0usize, 0usize);
    for (q, &c) in clipped.as_slice().iter().enumerate() {
        if !object.is_none_or(|o| o.as_slice()[q]) {
            continue;
        }
        objects += 1;
        on_object += usize::from(c);
        if confidence.as_ref().is_none_or(|t| t.as_slice()[q] > 0.0) {
            trusted += 1;
            saturated += usize::from(c);
        }
    }
    if trusted > 0 && saturated * 2 > trusted {
        return Err(PhotoError::Input(format!(
            "the photographs are saturated: {saturated} of {trusted} trusted object pixels are \
             at the maximum value in at least one of them; lower the exposure or mask the \
             saturated region (confidence 0)"
        )));
    }
    if clipped.as_slice().iter().any(|&c| c) {
        let keep = clipped.map(|&c| if c { 0.0 } else { 1.0 });
        *confidence = Some(match confidence.take() {
            Some(c) => c.zip_map(&keep, |a, b| a.min(*b)),
            None => keep,
        });
    }
    let share = on_object as f64 / objects.max(1) as f64;
    if on_object > 0 {
        notes.push(format!(
            "{:.1} % of the object is saturated in at least one photograph: not trusted \
             (confidence 0); elsewhere the sum is trusted whatever its value",
            100.0 * share
        ));
    }
    Ok(share)
}

/// Scales a float photograph (`photo`: its values on their own scale) by
/// the power of two that puts its brightest trusted object pixel (on the
/// object, confidence > 0) in [1/2, 1): the image, each photograph of a sum
/// and the lights' intensities (`lights`; none: the centred light, added
/// with that intensity), so the model still explains the image with the
/// same intensity scale. Returns the factor (1 when no trusted pixel is
/// lit). Exact: a power of two scales every value alike.
fn scale_float_photo(
    photo: &mut corrections::Photo,
    lights: &mut Vec<PointLight>,
    object: Option<&Grid<bool>>,
    confidence: Option<&Grid<f64>>,
) -> f64 {
    let image = &photo.image;
    let top = (0..image.len())
        .filter(|&q| {
            object.is_none_or(|o| o.as_slice()[q])
                && confidence.is_none_or(|c| c.as_slice()[q] > 0.0)
        })
        .map(|q| image.as_slice()[q])
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let scale = power_of_two_into_half_one(top);
    if scale != 1.0 {
        photo.image = photo.image.map(|v| v * scale);
        for each in &mut photo.each {
            if let Some(own) = &mut each.image {
                *own = own.map(|v| v * scale);
            }
        }
        if lights.is_empty() {
            lights.push(PointLight {
                intensity: scale,
                ..PointLight::CENTRED
            });
        } else {
            for light in lights.iter_mut() {
                light.intensity *= scale;
            }
        }
    }
    scale
}

/// The power of two `2^-e` with `value * 2^-e` in [1/2, 1); 1 for a value
/// that is not positive and finite. The exponent stays within +-1000, far
/// beyond any photograph's values, so the factor is a normal number.
fn power_of_two_into_half_one(value: f64) -> f64 {
    if !(value > 0.0 && value.is_finite()) {
        return 1.0;
    }
    const LIMIT: i32 = 1000;
    let mut exponent = (value.log2().floor() as i32).saturating_add(1);
    // `log2` may round across a power of two: settle on the exact one.
    while exponent > -LIMIT && value * 2f64.powi(-exponent) < 0.5 {
        exponent -= 1;
    }
    while exponent < LIMIT && value * 2f64.powi(-exponent) >= 1.0 {
        exponent += 1;
    }
    2f64.powi(-exponent.clamp(-LIMIT, LIMIT))
}

/// The power of two a sum must be divided by so that no pixel the solver
/// would trust (on the object, confidence > 0) and no photograph clipped
/// reaches [`SATURATED`], the solver's mark of a clipped photograph: 1 when
/// none does.
fn sum_divisor_for(
    image: &Grid<f64>,
    clipped: &Grid<bool>,
    object: Option<&Grid<bool>>,
    confidence: Option<&Grid<f64>>,
) -> f64 {
    let top = (0..image.len())
        .filter(|&q| {
            !clipped.as_slice()[q]
                && object.is_none_or(|o| o.as_slice()[q])
                && confidence.is_none_or(|c| c.as_slice()[q] > 0.0)
        })
        .map(|q| image.as_slice()[q])
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut divisor = 1.0f64;
    // 2^1000 is far beyond any sum of photographs in [0, 1] and their
    // corrections; the bound only keeps the loop finite.
    while top / divisor >= SATURATED && divisor < 2f64.powi(1000) {
        divisor *= 2.0;
    }
    divisor
}

/// Refuses a solve that would not fit the free memory, before any pixel is
/// decoded, with the working size that would. Several photographs keep, at
/// the working size, where each was saturated (1 byte a pixel each, and
/// their union) and, with lights of their own (`own_lights`), each one's
/// corrected image (8 bytes a pixel each): charged as that many bytes of
/// pyramid levels beyond the default's.
fn check_memory(
    input: &PhotoInput,
    full: (usize, usize),
    own_lights: bool,
) -> Result<(), MemoryError> {
    let working = working_size(full.0, full.1, input.max_side);
    let what = if working == full {
        format!("solving {}x{} pixels", full.0, full.1)
    } else {
        format!(
            "solving {}x{} pixels (working size of {}x{})",
            working.0, working.1, full.0, full.1
        )
    };
    let photographs = input.images.len();
    let pyramid_factor = if photographs > 1 {
        let each = if own_lights { 1.0 + 8.0 } else { 1.0 };
        let bytes_per_pixel = photographs as f64 * each + 1.0;
        input.pyramid_factor.max(memory::DEFAULT_PYRAMID_FACTOR)
            + bytes_per_pixel / memory::LEVEL_BYTES_PER_PIXEL as f64
    } else {
        input.pyramid_factor
    };
    memory::check_solve(&memory::SolvePlan {
        what,
        full,
        working,
        images: input.images.len(),
        pyramid_factor,
        smaller: &|side| {
            format!(
                "solve at a smaller working size with {} {side} or less",
                input.max_side_setting
            )
        },
        otherwise: "use a smaller image",
    })
}

#[cfg(test)]
mod tests;
