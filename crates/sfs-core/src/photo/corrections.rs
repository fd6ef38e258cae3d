//! The corrections of a photograph's values: several exposures summed in
//! linear light, an ambient (dark) frame subtracted, vignetting (cos^4 or a
//! flat-field image) and a known albedo divided out, then area-averaged to
//! the working size.

use std::path::{Path, PathBuf};

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::io::{self, IoError, SrgbMode};

/// Albedo values below this are not trusted (division would amplify noise):
/// such pixels get confidence 0.
pub const MIN_ALBEDO: f64 = 0.02;

use crate::resample::{resize_area, working_size};

/// The natural vignetting of a pinhole camera: `cos^4` of the angle between
/// a pixel's ray and the optical axis, per pixel.
pub fn cos4(camera: Intrinsics, width: usize, height: usize) -> Grid<f64> {
    let f2 = camera.focal_px * camera.focal_px;
    Grid::from_fn(width, height, |c, r| {
        let (x, y) = camera.image_xy(c as f64, r as f64);
        let q2 = f2 / (x * x + y * y + f2);
        q2 * q2
    })
}

/// How to correct the image for the lens's fall-off towards the corners.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Vignetting {
    /// No correction (default).
    #[default]
    None,
    /// Divide by `cos^4` of the ray angle.
    Cos4,
    /// Divide by a flat-field image (a photograph of a uniform white target,
    /// normalised to mean 1 over the image).
    FlatField(PathBuf),
}

impl Vignetting {
    /// The correction an option names: nothing or `none`, `cos4`, else the
    /// path of a flat-field image.
    pub fn from_option(text: Option<&str>) -> Self {
        match text {
            None | Some("none") => Vignetting::None,
            Some("cos4") => Vignetting::Cos4,
            Some(file) => Vignetting::FlatField(PathBuf::from(file)),
        }
    }
}

/// The files and corrections that make a photograph's values.
#[derive(Clone, Debug)]
pub(super) struct Corrections<'a> {
    /// The photographs (one, or several summed: lights on together).
    pub images: &'a [PathBuf],
    /// sRGB decoding.
    pub srgb: SrgbMode,
    /// A frame with every light off, subtracted from each photograph.
    pub ambient: Option<&'a Path>,
    /// Vignetting correction.
    pub vignetting: &'a Vignetting,
    /// A known albedo map (values in [0, 1], relative), divided out.
    pub albedo: Option<&'a Path>,
    /// Largest side of the working size (area averaging); `None`: full size.
    pub max_side: Option<usize>,
}

/// A photograph's corrected values at the working size.
#[derive(Clone, Debug)]
pub(super) struct Photo {
    /// Linear image at the working size, corrected.
    pub image: Grid<f64>,
    /// Confidence 0 where a correction made a pixel unusable (albedo below
    /// [`MIN_ALBEDO`]), else 1; `None` when nothing was lost.
    pub lost: Option<Grid<f64>>,
    /// Whether sRGB decoding was applied, and why.
    pub srgb: (bool, String),
    /// Share of pixels that went below zero after the ambient subtraction
    /// (clamped to 0).
    pub ambient_clamped: f64,
}

fn read_sized(
    path: &Path,
    what: &str,
    size: (usize, usize),
    mode: SrgbMode,
) -> Result<Grid<f64>, IoError> {
    let (grid, _, _) = io::read_photo(path, mode)?;
    if grid.size() != size {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!(
                "the {what} is {}x{} but the photograph is {}x{}",
                grid.width(),
                grid.height(),
                size.0,
                size.1
            ),
        });
    }
    Ok(grid)
}

/// Loads and corrects the photographs of `setup` (the camera is needed for
/// the cos^4 correction and is that of the full-size photograph).
///
/// # Errors
/// An unreadable file, or one whose size differs from the first
/// photograph's; the message names the file.
pub(super) fn load(setup: &Corrections<'_>, camera: Option<Intrinsics>) -> Result<Photo, IoError> {
    let Some(first) = setup.images.first() else {
        return Err(IoError::BadImage {
            path: PathBuf::from("(none)"),
            reason: "no photograph given".into(),
        });
    };
    let (mut image, srgb, why) = io::read_photo(first, setup.srgb)?;
    let size = image.size();
    let mode = if srgb { SrgbMode::On } else { SrgbMode::Off };
    for path in &setup.images[1..] {
        let more = read_sized(path, "photograph", size, mode)?;
        image = image.zip_map(&more, |a, b| a + b);
    }
    let mut ambient_clamped = 0.0;
    if let Some(path) = setup.ambient {
        let ambient = read_sized(path, "ambient frame", size, mode)?;
        let frames = setup.images.len() as f64;
        let mut clamped = 0usize;
        image = image.zip_map(&ambient, |a, b| {
            let v = a - frames * b;
            if v < 0.0 {
                clamped += 1;
            }
            v.max(0.0)
        });
        ambient_clamped = clamped as f64 / image.len().max(1) as f64;
    }
    if let Vignetting::FlatField(path) = setup.vignetting {
        let flat = read_sized(path, "flat field", size, mode)?;
        let mean = flat.as_slice().iter().sum::<f64>() / flat.len().max(1) as f64;
        if mean.is_nan() || mean <= 0.0 {
            return Err(IoError::BadImage {
                path: path.clone(),
                reason: "the flat field is black".into(),
            });
        }
        image = image.zip_map(&flat, |a, b| if *b > 0.0 { a * mean / b } else { 0.0 });
    }
    if let (Vignetting::Cos4, Some(camera)) = (setup.vignetting, camera) {
        let fall_off = cos4(camera, size.0, size.1);
        image = image.zip_map(&fall_off, |a, b| a / b);
    }
    let mut lost = None;
    if let Some(path) = setup.albedo {
        let albedo = read_sized(path, "albedo", size, SrgbMode::Off)?;
        image = image.zip_map(&albedo, |a, b| if *b >= MIN_ALBEDO { a / b } else { 0.0 });
        lost = Some(albedo.map(|&b| if b >= MIN_ALBEDO { 1.0 } else { 0.0 }));
    }
    let (w, h) = working_size(size.0, size.1, setup.max_side);
    let resize = |grid: &Grid<f64>| resize_area(grid, w, h, Cancel::NEVER).uncancelled();
    let image = resize(&image);
    let lost = lost.map(|l| resize(&l).map(|&v| if v >= 0.999 { 1.0 } else { 0.0 }));
    Ok(Photo {
        image,
        lost,
        srgb: (srgb, why),
        ambient_clamped,
    })
}
