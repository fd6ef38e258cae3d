//! The corrections of a photograph's values: several exposures summed in
//! linear light (where each one was saturated recorded from its own decoded
//! values, and each one's own corrected image kept when asked for), an
//! ambient (dark) frame subtracted, vignetting (cos^4 or a flat-field image)
//! and a known albedo divided out, then area-averaged to the working size.
//!
//! Float photographs (no fixed white) are loaded on their own scale: nothing
//! is saturated by its value, and the ambient frame and the other
//! photographs of a sum must be float too (on the same scale); the pipeline
//! then scales the result ([`super::prepare`]).

use std::path::{Path, PathBuf};
use std::rc::Rc;

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::io::{self, FloatSamples, IoError, SrgbMode};
use crate::solver::problem::SATURATED;

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
    /// Several photographs: keep each one's own corrected image at the
    /// working size too (for the fit per photograph).
    pub keep_each: bool,
}

/// One photograph of several, at the working size.
#[derive(Clone, Debug)]
pub(super) struct Each {
    /// Its own corrected linear image (ambient frame, vignetting and albedo
    /// as for the sum), when [`Corrections::keep_each`].
    pub image: Option<Grid<f64>>,
    /// Where it was saturated: a working pixel any of whose source pixels
    /// was decoded at or above [`SATURATED`] (nowhere for a float
    /// photograph).
    pub clipped: Grid<bool>,
}

/// A photograph's corrected values at the working size.
#[derive(Clone, Debug)]
pub(super) struct Photo {
    /// Linear image at the working size, corrected (several photographs:
    /// their sum).
    pub image: Grid<f64>,
    /// Confidence 0 where a correction made a pixel unusable (albedo below
    /// [`MIN_ALBEDO`]), else 1; `None` when nothing was lost.
    pub lost: Option<Grid<f64>>,
    /// Whether sRGB decoding was applied, and why.
    pub srgb: (bool, String),
    /// Share of pixels that went below zero after the ambient subtraction
    /// (clamped to 0).
    pub ambient_clamped: f64,
    /// Several photographs: where any of them was saturated, at the working
    /// size (the sum's value says nothing: it may pass 1 where none was);
    /// `None` for one photograph, whose own values say it. Float
    /// photographs: nowhere (a float has no clipping level), for one too.
    pub clipped: Option<Grid<bool>>,
    /// Several photographs: each one, in the order given; empty for one.
    pub each: Vec<Each>,
    /// Whether the photographs hold float samples: the image is on their
    /// own scale (no fixed white), not on [0, 1].
    pub float: bool,
    /// Each float file read (photograph, ambient frame, flat field, albedo)
    /// that had negative samples, read as 0: the file and what it held.
    pub negatives: Vec<(PathBuf, FloatSamples)>,
}

/// How the photographs of a load were decoded, which every photograph-like
/// file must match, the float files' negative samples met so far, and the
/// correction frames kept.
struct Decoding<'a> {
    /// The first photograph.
    first: &'a Path,
    /// Its sRGB decoding.
    mode: SrgbMode,
    /// Whether its samples are floats.
    float: bool,
    /// Float files with negative samples.
    negatives: Vec<(PathBuf, FloatSamples)>,
    /// The correction frames read so far, when a load of several
    /// photographs keeps them (each is then decoded once, not once per
    /// photograph; a single photograph's frame is freed after use).
    frames: Option<Vec<FrameRead>>,
}

/// One correction frame as read: its file, role and values.
type FrameRead = (PathBuf, &'static str, Rc<Grid<f64>>, Option<FloatSamples>);

impl Decoding<'_> {
    /// [`read_sized`] of the correction frame `path` as `what`, from its
    /// first read when the load keeps frames.
    fn frame(
        &mut self,
        path: &Path,
        what: &'static str,
        size: (usize, usize),
        mode: SrgbMode,
    ) -> Result<(Rc<Grid<f64>>, Option<FloatSamples>), IoError> {
        if let Some((_, _, grid, float)) = self
            .frames
            .iter()
            .flatten()
            .find(|(p, w, _, _)| p == path && *w == what)
        {
            return Ok((Rc::clone(grid), *float));
        }
        let (grid, float) = read_sized(path, what, size, mode)?;
        let grid = Rc::new(grid);
        if let Some(frames) = &mut self.frames {
            frames.push((path.to_path_buf(), what, Rc::clone(&grid), float));
        }
        Ok((grid, float))
    }

    /// Notes a float file's negative samples (once per file).
    fn record(&mut self, path: &Path, float: Option<FloatSamples>) {
        if let Some(samples) = float.filter(|f| f.negative_pixels > 0)
            && !self.negatives.iter().any(|(p, _)| p == path)
        {
            self.negatives.push((path.to_path_buf(), samples));
        }
    }

    /// Refuses a photograph or ambient frame `path` whose samples are not
    /// of the first photograph's kind (float or integer): the two scales
    /// are unrelated.
    fn check_kind(&self, path: &Path, what: &str, float: bool) -> Result<(), IoError> {
        if float == self.float {
            return Ok(());
        }
        let kind = |f: bool| if f { "float" } else { "integer" };
        Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!(
                "the {what} holds {} samples but the photograph {} holds {} ones: a float \
                 image has no fixed white, so the two are on unrelated scales; give files of \
                 one kind",
                kind(float),
                self.first.display(),
                kind(self.float)
            ),
        })
    }
}

/// Reads `path` (the `what`) decoded in `mode`, refusing another size than
/// `size`; returns the values and, for a float image, what its samples
/// held.
fn read_sized(
    path: &Path,
    what: &str,
    size: (usize, usize),
    mode: SrgbMode,
) -> Result<(Grid<f64>, Option<FloatSamples>), IoError> {
    // A `.npy` map (the albedo.npy a solve writes) is read as its values.
    let npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let (grid, float) = if npy {
        (io::read_npy(path)?, None)
    } else {
        let photo = io::read_photo(path, mode)?;
        (photo.image, photo.float)
    };
    if grid.size() != size {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!(
                "the {what} is {}x{} but the photograph solved is {}x{}",
                grid.width(),
                grid.height(),
                size.0,
                size.1
            ),
        });
    }
    Ok((grid, float))
}

/// An image with the corrections applied, at the photograph's size.
struct Corrected {
    image: Grid<f64>,
    /// Pixels that went below zero after the ambient subtraction.
    clamped: usize,
    /// 1 where the albedo can be divided by, else 0 (with an albedo map).
    lost: Option<Grid<f64>>,
}

/// Applies the corrections of `setup` to `image`, the sum of `frames`
/// photographs of `size` pixels decoded as `decoding` says: the ambient
/// frame (of the photographs' kind) subtracted `frames` times (clamped at
/// 0), the flat field or cos^4 and the albedo divided out. The frames are
/// read through `decoding` (each file once per load of several).
fn correct(
    mut image: Grid<f64>,
    frames: usize,
    setup: &Corrections<'_>,
    size: (usize, usize),
    decoding: &mut Decoding<'_>,
    camera: Option<Intrinsics>,
) -> Result<Corrected, IoError> {
    let mode = decoding.mode;
    let mut clamped = 0usize;
    if let Some(path) = setup.ambient {
        let (ambient, float) = decoding.frame(path, "ambient frame", size, mode)?;
        decoding.check_kind(path, "ambient frame", float.is_some())?;
        decoding.record(path, float);
        let frames = frames as f64;
        image = image.zip_map(&ambient, |a, b| {
            let v = a - frames * b;
            if v < 0.0 {
                clamped += 1;
            }
            v.max(0.0)
        });
    }
    if let Vignetting::FlatField(path) = setup.vignetting {
        let (flat, float) = decoding.frame(path, "flat field", size, mode)?;
        decoding.record(path, float);
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
        let (albedo, float) = decoding.frame(path, "albedo", size, SrgbMode::Off)?;
        decoding.record(path, float);
        image = image.zip_map(&albedo, |a, b| if *b >= MIN_ALBEDO { a / b } else { 0.0 });
        lost = Some(albedo.map(|&b| if b >= MIN_ALBEDO { 1.0 } else { 0.0 }));
    }
    Ok(Corrected {
        image,
        clamped,
        lost,
    })
}

/// Loads and corrects the photographs of `setup` (the camera is needed for
/// the cos^4 correction and is that of the full-size photograph). Several
/// photographs are summed in linear light; each one's saturated pixels are
/// recorded from its decoded values before the sum, and with
/// [`Corrections::keep_each`] its own corrected image is kept.
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
    let io::DecodedPhoto {
        mut image,
        srgb,
        srgb_reason: why,
        float,
    } = io::read_photo(first, setup.srgb)?;
    let size = image.size();
    let mode = if srgb { SrgbMode::On } else { SrgbMode::Off };
    let mut decoding = Decoding {
        first,
        mode,
        float: float.is_some(),
        negatives: Vec::new(),
        frames: (setup.images.len() > 1).then(Vec::new),
    };
    decoding.record(first, float);
    // A float has no clipping level: saturation is not inferred from its
    // values.
    let is_float = decoding.float;
    let saturated = |v: f64| !is_float && v >= SATURATED;
    let (w, h) = working_size(size.0, size.1, setup.max_side);
    let resize = |grid: &Grid<f64>| resize_area(grid, w, h, Cancel::NEVER).uncancelled();
    // One of several photographs: where it is saturated (a working pixel
    // with any saturated source pixel: area weights are positive), and its
    // own corrected image when asked for.
    let one_of_several =
        |photo: &Grid<f64>, decoding: &mut Decoding<'_>| -> Result<Each, IoError> {
            let clipped = resize(&photo.map(|&v| if saturated(v) { 1.0 } else { 0.0 }));
            let image = if setup.keep_each {
                let own = correct(photo.clone(), 1, setup, size, decoding, camera)?;
                Some(resize(&own.image))
            } else {
                None
            };
            Ok(Each {
                image,
                clipped: clipped.map(|&v| v > 0.0),
            })
        };
    let several = setup.images.len() > 1;
    // Saturation is judged on the photographs as taken: a sum may pass 1
    // where none was saturated, and so may one photograph once an albedo or
    // a vignetting correction raised its values (then where it was
    // saturated as taken is kept here).
    let raised = setup.albedo.is_some() || !matches!(setup.vignetting, Vignetting::None);
    let taken_clipped = (!several && raised)
        .then(|| resize(&image.map(|&v| if saturated(v) { 1.0 } else { 0.0 })).map(|&v| v > 0.0));
    let mut each = Vec::new();
    if several {
        each.push(one_of_several(&image, &mut decoding)?);
    }
    for path in &setup.images[1..] {
        let what = format!(
            "photograph {} (the first, {}, is the size every input must have)",
            path.display(),
            first.display()
        );
        let (more, more_float) = read_sized(path, &what, size, mode)?;
        decoding.check_kind(path, "photograph", more_float.is_some())?;
        decoding.record(path, more_float);
        each.push(one_of_several(&more, &mut decoding)?);
        image = image.zip_map(&more, |a, b| a + b);
    }
    let corrected = correct(
        image,
        setup.images.len(),
        setup,
        size,
        &mut decoding,
        camera,
    )?;
    let ambient_clamped = match setup.ambient {
        Some(_) => corrected.clamped as f64 / corrected.image.len().max(1) as f64,
        None => 0.0,
    };
    let image = resize(&corrected.image);
    let lost = corrected
        .lost
        .map(|l| resize(&l).map(|&v| if v >= 0.999 { 1.0 } else { 0.0 }));
    let clipped = if several {
        Some(Grid::from_fn(w, h, |c, r| {
            each.iter().any(|one: &Each| *one.clipped.at(c, r))
        }))
    } else if is_float {
        Some(Grid::filled(w, h, false))
    } else {
        taken_clipped
    };
    Ok(Photo {
        image,
        lost,
        srgb: (srgb, why),
        ambient_clamped,
        clipped,
        each,
        float: is_float,
        negatives: decoding.negatives,
    })
}
