//! The camera, lights and intensity scale of a photograph, decided from a
//! camera file, a given focal length or the file's EXIF, with the reason for
//! each decision.

use std::path::Path;

use serde::Serialize;

use super::input::{CameraSpec, LightSpec, PhotoError, PhotoInput, ScaleSpec};
use crate::camera::Intrinsics;
use crate::camera_file::{self, CameraFile};
use crate::light::PointLight;

/// Where the intrinsics came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum CameraSource {
    /// A camera file.
    File {
        /// The file.
        path: std::path::PathBuf,
    },
    /// A focal length given in pixels.
    Given,
    /// The photograph's EXIF focal length in 35 mm equivalent.
    Exif {
        /// The EXIF value, millimetres.
        focal_35mm: f64,
    },
    /// No information: a 50 mm-equivalent guess.
    Guess,
}

/// The camera, lights and scale decided for a photograph of its own size.
pub(super) struct Decided {
    /// Intrinsics at the photograph's own size.
    pub camera: Intrinsics,
    pub source: CameraSource,
    pub lights: Vec<PointLight>,
    /// Every light the camera file lists with a position and a principal
    /// direction (on or off for this photograph): where a rig aims them
    /// says where the object is (`solver::depth_unit`).
    pub rig_lights: Vec<PointLight>,
    /// `Some(s)` when given (option or camera file); `None`: unknown.
    pub intensity_scale: Option<f64>,
    /// The unit of depth, when the camera file says it.
    pub units: Option<String>,
    /// Whether the lights' relative intensities were measured.
    pub intensities_measured: bool,
    /// Sentences for the summary and the report.
    pub notes: Vec<String>,
}

/// `FocalLengthIn35mmFilm` from the file's EXIF, if any.
pub fn exif_focal_35mm(path: &Path) -> Option<f64> {
    let file = std::fs::File::open(path).ok()?;
    let mut reader = std::io::BufReader::new(file);
    let exif = exif::Reader::new().read_from_container(&mut reader).ok()?;
    let field = exif.get_field(exif::Tag::FocalLengthIn35mmFilm, exif::In::PRIMARY)?;
    let value = f64::from(field.value.get_uint(0)?);
    (value > 0.0).then_some(value)
}

/// Decides the camera, lights and scale of `input` for a photograph of
/// `full_size` pixels.
pub(super) fn decide(input: &PhotoInput, full_size: (usize, usize)) -> Result<Decided, PhotoError> {
    let mut notes = Vec::new();
    let mut file: Option<(&Path, CameraFile)> = None;
    let (camera, source) = match &input.camera {
        CameraSpec::File(path) => {
            let read = camera_file::read_camera(path)?;
            let camera = read.intrinsics_for(path, full_size)?;
            if (read.width, read.height) != full_size {
                notes.push(format!(
                    "intrinsics of {} ({}x{}) scaled to the {}x{} photograph: f = {:.2} px, \
                     c = ({:.2}, {:.2})",
                    path.display(),
                    read.width,
                    read.height,
                    full_size.0,
                    full_size.1,
                    camera.focal_px,
                    camera.principal_x_px,
                    camera.principal_y_px
                ));
            }
            file = Some((path.as_path(), read));
            let source = CameraSource::File {
                path: path.to_path_buf(),
            };
            (camera, source)
        }
        CameraSpec::Focal {
            focal_px,
            cx_px,
            cy_px,
        } => {
            let smallest = crate::camera::MIN_FOCAL_PER_SIDE * full_size.0.max(full_size.1) as f64;
            if !(focal_px.is_finite() && *focal_px >= smallest && *focal_px < 1e9) {
                return Err(PhotoError::Input(format!(
                    "--focal {focal_px:?}: must be a number of pixels in [{smallest}, 1e9) for the \
                     {}x{} photograph (below {} of its longest side the field of view nears 180 \
                     degrees, which the model cannot represent)",
                    full_size.0,
                    full_size.1,
                    crate::camera::MIN_FOCAL_PER_SIDE
                )));
            }
            let mut camera = Intrinsics::centred(*focal_px, full_size.0, full_size.1);
            if let Some(cx) = cx_px {
                camera.principal_x_px = *cx;
            }
            if let Some(cy) = cy_px {
                camera.principal_y_px = *cy;
            }
            camera
                .check_for(full_size.0, full_size.1)
                .map_err(|reason| PhotoError::Input(format!("--focal/--cx/--cy: {reason}")))?;
            (camera, CameraSource::Given)
        }
        CameraSpec::Exif { guess } => from_exif(&input.images[0], full_size, *guess, &mut notes)?,
    };
    let lights = decide_lights(input, file.as_ref(), &mut notes)?;
    let rig_lights = match (&input.lights, &file) {
        (LightSpec::Given(_), _) | (_, None) => Vec::new(),
        (_, Some((_, f))) => f
            .lights
            .iter()
            .enumerate()
            .filter_map(|(k, e)| e.light().validated(k + 1).ok())
            .filter(|l| l.direction.is_some())
            .collect(),
    };
    let intensities_measured = match (&input.lights, &file) {
        (LightSpec::Given(_), _) => input.given_intensities,
        (_, Some((_, f))) => f
            .lights
            .iter()
            .all(|e| e.intensity.is_some() || e.rgb_intensity.is_some()),
        (_, None) => true,
    };
    let intensity_scale = match input.intensity_scale {
        ScaleSpec::Given(s) => {
            let (s_min, s_max) = crate::params::INTENSITY_SCALE_RANGE;
            if !(s.is_finite() && (s_min..=s_max).contains(&s)) {
                return Err(PhotoError::Input(format!(
                    "--intensity-scale {s}: must be a number in [{s_min:e}, {s_max:e}]"
                )));
            }
            Some(s)
        }
        ScaleSpec::Auto => None,
        ScaleSpec::FromCamera => match file.as_ref() {
            Some((path, f)) => match f.intensity_scale {
                Some(s) if !f.intensity_scale_measured && !crate::light::is_centred(&lights) => {
                    notes.push(format!(
                        "the intensity scale {s} in {} is not marked measured \
                         (\"intensity_scale_measured\": true): with lights off the optical \
                         centre it decides the depth unit, so it is treated as unknown",
                        path.display()
                    ));
                    None
                }
                other => other,
            },
            None => None,
        },
    };
    Ok(Decided {
        camera,
        source,
        lights,
        rig_lights,
        intensity_scale,
        units: file.and_then(|(_, f)| f.units),
        intensities_measured,
        notes,
    })
}

/// Intrinsics from EXIF's 35 mm equivalent (36 mm across the long side), or
/// a 50 mm-equivalent guess when allowed; principal point at the centre.
fn from_exif(
    image: &Path,
    full_size: (usize, usize),
    guess: bool,
    notes: &mut Vec<String>,
) -> Result<(Intrinsics, CameraSource), PhotoError> {
    let long_side = full_size.0.max(full_size.1) as f64;
    let (focal_px, source) = match exif_focal_35mm(image) {
        Some(f35) => {
            let focal_px = f35 / 36.0 * long_side;
            notes.push(format!(
                "focal length from the EXIF of {}: {f35:.0} mm (35 mm equivalent), \
                 f = {focal_px:.1} px; the principal point at the image centre",
                image.display()
            ));
            (focal_px, CameraSource::Exif { focal_35mm: f35 })
        }
        None if guess => {
            let focal_px = 50.0 / 36.0 * long_side;
            notes.push(format!(
                "no camera file and no EXIF focal length in {}: a 50 mm-equivalent guess, \
                 f = {focal_px:.1} px; set the focal length",
                image.display()
            ));
            (focal_px, CameraSource::Guess)
        }
        None => {
            return Err(PhotoError::Input(format!(
                "no camera: {} has no EXIF focal length; give --camera FILE or --focal F (pixels)",
                image.display()
            )));
        }
    };
    Ok((
        Intrinsics::centred(focal_px, full_size.0, full_size.1),
        source,
    ))
}

/// The lights switched on, with a note saying which.
fn decide_lights(
    input: &PhotoInput,
    file: Option<&(&Path, CameraFile)>,
    notes: &mut Vec<String>,
) -> Result<Vec<PointLight>, PhotoError> {
    let picks: &[u32] = match &input.lights {
        LightSpec::Given(lights) => return Ok(lights.clone()),
        LightSpec::CameraFile { picks } => picks,
        LightSpec::CameraFileOrCentred => &[],
    };
    let Some((path, file)) = file.filter(|(_, f)| !f.lights.is_empty()) else {
        if !picks.is_empty() {
            return Err(PhotoError::Input(
                "--light-index needs a camera file that lists lights (--camera)".into(),
            ));
        }
        return Ok(Vec::new());
    };
    let names: Vec<String> = input
        .images
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let chosen = if picks.is_empty() && names.len() > 1 {
        // Several photographs: each one's own light, summed.
        let mut each = Vec::new();
        for name in &names {
            let marked = file
                .lights
                .iter()
                .filter(|e| e.image.as_deref() == Some(name.as_str()))
                .count();
            if input.photometric_stereo && marked != 1 {
                // --light-index is refused with a set: say what the set
                // needs instead.
                return Err(PhotoError::Input(format!(
                    "{}: {} of its {} lights {} marked as taking {name}: each photograph of a \
                     photometric-stereo set needs exactly one light whose `image` is its file \
                     name (add \"image\": \"{name}\" to the light that took it)",
                    path.display(),
                    if marked == 0 {
                        "none".to_string()
                    } else {
                        marked.to_string()
                    },
                    file.lights.len(),
                    if marked > 1 { "are" } else { "is" },
                )));
            }
            let (one, _) = file.lights_for(path, &[], Some(name))?;
            let number = file
                .lights
                .iter()
                .enumerate()
                .find(|(_, e)| e.image.as_deref() == Some(name.as_str()))
                .map(|(k, e)| e.led.unwrap_or(k as u32 + 1));
            match (one.len(), number) {
                (1, Some(n)) => each.push(n),
                _ => {
                    return Err(PhotoError::Input(format!(
                        "{}: cannot tell which light took {name}; give --light-index K for \
                         each light that was on",
                        path.display()
                    )));
                }
            }
        }
        file.lights_for(path, &each, None)
    } else {
        file.lights_for(path, picks, names.first().map(String::as_str))
    };
    match chosen {
        Ok((lights, said)) => {
            notes.push(format!("lights: {said}"));
            Ok(lights)
        }
        Err(e) if input.lights == LightSpec::CameraFileOrCentred => {
            notes.push(format!(
                "{e}; solved with one light at the optical centre until one is chosen"
            ));
            Ok(Vec::new())
        }
        Err(e) => Err(e.into()),
    }
}
