//! Reading and writing the files sfs-studio works with: grey images, masks,
//! `.npy` arrays, PLY meshes, the camera/scene JSON file, and an
//! [`OutputStage`] that makes a run's outputs appear all at once or not at all.
//!
//! Every error names the file (or folder) it concerns.

use std::fs;
use std::io::{BufWriter, Cursor, Write};
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageBuffer, ImageError, ImageFormat, ImageReader, Luma};
use npyz::{DType, NpyFile, NpyHeader, Order, TypeChar, WriteOptions, WriterBuilder};
use serde::{Deserialize, Serialize};

use crate::camera::Intrinsics;
use crate::depth_mesh::DepthMesh;
use crate::grid::Grid;
use crate::model::LevelGeometry;

/// Rec. 709 luminance weights for linear red, green and blue.
const LUMA_709: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// An input/output failure; its message always names the file concerned.
///
/// The cause is part of the message (`Display`), so the variants do not
/// expose it again as an error `source`.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// A file could not be opened or read.
    #[error("cannot read {}: {cause}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// An image file could not be opened or read (missing, a folder,
    /// unreadable, truncated, too large for the decoder's limits).
    #[error("cannot read image {}: {cause}", path.display())]
    ReadImage {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        cause: ImageError,
    },
    /// The file was read but is not an image in a supported format
    /// (PNG, TIFF, JPEG).
    #[error("{} is not an image ({cause})", path.display())]
    NotAnImage {
        /// The file.
        path: PathBuf,
        /// The decoder's complaint.
        cause: ImageError,
    },
    /// The image decoded but its content cannot be used (empty, NaN values).
    #[error("{} is not a usable image: {reason}", path.display())]
    BadImage {
        /// The image file.
        path: PathBuf,
        /// Why it cannot be used.
        reason: String,
    },
    /// An image-like input does not have the size it must have.
    #[error(
        "{} is {}x{} but the image is {}x{}",
        path.display(), found.0, found.1, expected.0, expected.1
    )]
    SizeMismatch {
        /// The file whose size is wrong.
        path: PathBuf,
        /// Its `(width, height)`.
        found: (usize, usize),
        /// The `(width, height)` it must have.
        expected: (usize, usize),
    },
    /// A `.npy` file is malformed or does not hold a 2-D numeric array.
    #[error("{} is not a usable .npy array: {reason}", path.display())]
    Npy {
        /// The `.npy` file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The camera/scene file is malformed, has missing or unknown keys, or
    /// holds invalid values.
    #[error("camera file {}: {reason}", path.display())]
    Camera {
        /// The camera file.
        path: PathBuf,
        /// What is wrong with it (names the key concerned).
        reason: String,
    },
    /// A file could not be written.
    #[error("cannot write {}: {cause}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        cause: Box<dyn std::error::Error + Send + Sync>,
    },
    /// An output folder could not be created.
    #[error("cannot create folder {}: {cause}", path.display())]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// A staged output could not be moved to its final name.
    #[error("cannot move {} to {}: {cause}", from.display(), to.display())]
    Rename {
        /// The temporary file.
        from: PathBuf,
        /// The final name.
        to: PathBuf,
        /// What went wrong.
        cause: std::io::Error,
    },
    /// Another run holds the output folder's lock.
    #[error(
        "{} is being written by another sfs-studio run; wait for it to finish or choose another output folder",
        path.display()
    )]
    Busy {
        /// The output folder.
        path: PathBuf,
    },
}

fn write_error(path: &Path, cause: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        cause: cause.into(),
    }
}

// ---------------------------------------------------------------------------
// Images
// ---------------------------------------------------------------------------

/// The sRGB electro-optical transfer function: encoded value in [0, 1] to
/// linear value in [0, 1].
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn decode_image(path: &Path) -> Result<DynamicImage, IoError> {
    let read_error = |cause: std::io::Error| IoError::ReadImage {
        path: path.to_path_buf(),
        cause: ImageError::IoError(cause),
    };
    let meta = fs::metadata(path).map_err(read_error)?;
    if meta.is_dir() {
        return Err(read_error(std::io::Error::other("it is a folder")));
    }
    let reader = ImageReader::open(path)
        .map_err(read_error)?
        .with_guessed_format()
        .map_err(read_error)?;
    let is_tiff = reader.format() == Some(ImageFormat::Tiff);
    reader.decode().or_else(|cause| match cause {
        // Grey float32/float64 and 32-bit integer TIFFs, which `image` does
        // not decode.
        ImageError::Unsupported(_) if is_tiff => {
            decode_tiff_samples(path).map_err(|reason| IoError::BadImage {
                path: path.to_path_buf(),
                reason,
            })
        }
        cause => Err(cause_to_error(path, cause)),
    })
}

/// An image's `(width, height)` from its header, without decoding it
/// (TIFFs that `image` does not decode through the `tiff` crate).
pub fn image_size(path: &Path) -> Result<(usize, usize), IoError> {
    match image::image_dimensions(path) {
        Ok((w, h)) => Ok((w as usize, h as usize)),
        Err(ImageError::Unsupported(cause)) => {
            let tiff_size = fs::File::open(path)
                .ok()
                .and_then(|f| tiff::decoder::Decoder::new(std::io::BufReader::new(f)).ok())
                .and_then(|mut d| d.dimensions().ok());
            match tiff_size {
                Some((w, h)) => Ok((w as usize, h as usize)),
                None => Err(cause_to_error(path, ImageError::Unsupported(cause))),
            }
        }
        Err(cause) => Err(cause_to_error(path, cause)),
    }
}

/// A decoder error as the error naming `path`.
fn cause_to_error(path: &Path, cause: ImageError) -> IoError {
    match cause {
        ImageError::IoError(_) | ImageError::Limits(_) => IoError::ReadImage {
            path: path.to_path_buf(),
            cause,
        },
        _ => IoError::NotAnImage {
            path: path.to_path_buf(),
            cause,
        },
    }
}

/// Decodes a TIFF with the `tiff` crate directly: grey, grey+alpha, RGB or
/// RGBA with unsigned 8/16/32-bit or float 32/64-bit samples, returned as
/// float RGB (integers divided by their type's maximum). The error says what
/// the file holds.
fn decode_tiff_samples(path: &Path) -> Result<DynamicImage, String> {
    use tiff::ColorType;
    use tiff::decoder::{Decoder, DecodingResult};
    let file = fs::File::open(path).map_err(|e| e.to_string())?;
    let mut decoder =
        Decoder::new(std::io::BufReader::new(file)).map_err(|e| format!("bad TIFF: {e}"))?;
    let (w, h) = decoder.dimensions().map_err(|e| format!("bad TIFF: {e}"))?;
    let colour = decoder.colortype().map_err(|e| format!("bad TIFF: {e}"))?;
    let (channels, rgb) = match colour {
        ColorType::Gray(_) => (1, false),
        ColorType::GrayA(_) => (2, false),
        ColorType::RGB(_) => (3, true),
        ColorType::RGBA(_) => (4, true),
        other => return Err(format!("TIFF colour type {other:?} is not supported")),
    };
    let values: Vec<f32> = match decoder.read_image().map_err(|e| format!("bad TIFF: {e}"))? {
        DecodingResult::U8(v) => v.iter().map(|&s| f32::from(s) / 255.0).collect(),
        DecodingResult::U16(v) => v.iter().map(|&s| f32::from(s) / 65535.0).collect(),
        DecodingResult::U32(v) => v
            .iter()
            .map(|&s| (f64::from(s) / f64::from(u32::MAX)) as f32)
            .collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.iter().map(|&s| s as f32).collect(),
        _ => {
            return Err(
                "TIFF samples are signed, 64-bit integer or half float; unsigned 8/16/32-bit \
                 and float 32/64-bit are supported"
                    .into(),
            );
        }
    };
    let pixels = (w as usize) * (h as usize);
    if values.len() != pixels * channels {
        return Err(format!(
            "the TIFF decoder gave {} samples for {w}x{h} pixels of {channels} channel(s)",
            values.len()
        ));
    }
    let rgb_values: Vec<f32> = values
        .chunks_exact(channels)
        .flat_map(|px| {
            if rgb {
                [px[0], px[1], px[2]]
            } else {
                [px[0]; 3]
            }
        })
        .collect();
    image::Rgb32FImage::from_raw(w, h, rgb_values)
        .map(DynamicImage::ImageRgb32F)
        .ok_or_else(|| format!("the TIFF's {w}x{h} pixels do not match its samples"))
}

/// Converts interleaved samples (`channels` per pixel, the first one grey or
/// the first three red/green/blue) to linear grey in [0, 1].
fn samples_to_grey<T: Copy + Into<f64>>(
    path: &Path,
    (width, height, channels): (usize, usize, usize),
    raw: &[T],
    colour: bool,
    max: f64,
    srgb: bool,
) -> Result<Grid<f64>, IoError> {
    let lin = |s: T| {
        let v = (s.into() / max).clamp(0.0, 1.0);
        if srgb { srgb_to_linear(v) } else { v }
    };
    let data = raw
        .chunks_exact(channels)
        .map(|px| {
            if colour {
                LUMA_709[0] * lin(px[0]) + LUMA_709[1] * lin(px[1]) + LUMA_709[2] * lin(px[2])
            } else {
                lin(px[0])
            }
        })
        .collect();
    Grid::from_vec(width, height, data).ok_or_else(|| IoError::BadImage {
        path: path.to_path_buf(),
        reason: format!(
            "the decoder gave {} samples for {width}x{height} pixels of {channels} channel(s)",
            raw.len()
        ),
    })
}

fn image_to_grey(path: &Path, image: DynamicImage, srgb: bool) -> Result<Grid<f64>, IoError> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!("it is empty ({w}x{h})"),
        });
    }
    let grid = match image {
        DynamicImage::ImageLuma8(b) => {
            samples_to_grey(path, (w, h, 1), b.as_raw(), false, 255.0, srgb)?
        }
        DynamicImage::ImageLumaA8(b) => {
            samples_to_grey(path, (w, h, 2), b.as_raw(), false, 255.0, srgb)?
        }
        DynamicImage::ImageRgb8(b) => {
            samples_to_grey(path, (w, h, 3), b.as_raw(), true, 255.0, srgb)?
        }
        DynamicImage::ImageRgba8(b) => {
            samples_to_grey(path, (w, h, 4), b.as_raw(), true, 255.0, srgb)?
        }
        DynamicImage::ImageLuma16(b) => {
            samples_to_grey(path, (w, h, 1), b.as_raw(), false, 65535.0, srgb)?
        }
        DynamicImage::ImageLumaA16(b) => {
            samples_to_grey(path, (w, h, 2), b.as_raw(), false, 65535.0, srgb)?
        }
        DynamicImage::ImageRgb16(b) => {
            samples_to_grey(path, (w, h, 3), b.as_raw(), true, 65535.0, srgb)?
        }
        DynamicImage::ImageRgba16(b) => {
            samples_to_grey(path, (w, h, 4), b.as_raw(), true, 65535.0, srgb)?
        }
        DynamicImage::ImageRgb32F(b) => float_to_grey(path, w, h, b.as_raw(), 3, srgb)?,
        DynamicImage::ImageRgba32F(b) => float_to_grey(path, w, h, b.as_raw(), 4, srgb)?,
        other => {
            // Layouts added to `image` later: go through normalised float RGB.
            let rgb = other.to_rgb32f();
            float_to_grey(path, w, h, rgb.as_raw(), 3, srgb)?
        }
    };
    Ok(grid)
}

fn float_to_grey(
    path: &Path,
    width: usize,
    height: usize,
    raw: &[f32],
    channels: usize,
    srgb: bool,
) -> Result<Grid<f64>, IoError> {
    let has_nan = raw
        .chunks_exact(channels)
        .any(|px| px[..3].iter().any(|v| v.is_nan()));
    if has_nan {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: "it contains NaN values".into(),
        });
    }
    samples_to_grey(path, (width, height, channels), raw, true, 1.0, srgb)
}

/// Reads a PNG, TIFF or JPEG (8-bit, 16-bit or float) as linear grey values
/// in [0, 1].
///
/// Integer samples are divided by the maximum of their type (8-bit by 255,
/// 16-bit by 65535); float samples are clamped to [0, 1] and NaN is rejected.
/// When `srgb` is true every channel (grey included) is first linearised with
/// the sRGB transfer function. Colour is converted to luminance with the
/// Rec. 709 weights (0.2126, 0.7152, 0.0722) on the linear channel values.
/// Alpha is ignored. The format is recognised from the content, falling back
/// to the extension. Empty images are an error.
pub fn read_image(path: &Path, srgb: bool) -> Result<Grid<f64>, IoError> {
    let image = decode_image(path)?;
    image_to_grey(path, image, srgb)
}

/// How a photograph's values are decoded to linear light (`--srgb`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SrgbMode {
    /// Always apply the sRGB transfer function.
    On,
    /// Never: the values are linear.
    Off,
    /// On for JPEG and 8-bit images, off for 16-bit and float images and for
    /// PNGs marked linear (gAMA 1.0, as everything this tool writes).
    #[default]
    Auto,
}

/// What [`SrgbMode::Auto`] decides for `path`, and why (for reports and the
/// viewer). `None` when the file cannot be decoded.
pub fn srgb_decision(path: &Path, mode: SrgbMode) -> Result<(bool, String), IoError> {
    let image = decode_image(path)?;
    Ok(decide_srgb(path, &image, mode))
}

fn decide_srgb(path: &Path, image: &DynamicImage, mode: SrgbMode) -> (bool, String) {
    match mode {
        SrgbMode::On => return (true, "sRGB decoding on (--srgb on)".into()),
        SrgbMode::Off => return (false, "values read as linear (--srgb off)".into()),
        SrgbMode::Auto => {}
    }
    let is_jpeg = matches!(ImageFormat::from_path(path), Ok(ImageFormat::Jpeg))
        || fs::read(path)
            .map(|b| b.starts_with(&[0xFF, 0xD8, 0xFF]))
            .unwrap_or(false);
    if is_jpeg {
        return (true, "a JPEG: sRGB-decoded (auto)".into());
    }
    if png_marked_linear(path) {
        return (
            false,
            "a PNG marked linear (gAMA 1.0): read as linear (auto)".into(),
        );
    }
    let eight_bit = matches!(
        image,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_)
    );
    if eight_bit {
        (true, "an 8-bit photograph: sRGB-decoded (auto)".into())
    } else {
        (
            false,
            "a 16-bit or float image: read as linear (auto)".into(),
        )
    }
}

/// True when `path` is a PNG whose gAMA chunk says gamma 1 (linear values).
fn png_marked_linear(path: &Path) -> bool {
    let Ok(file) = fs::File::open(path) else {
        return false;
    };
    let decoder = png::Decoder::new(std::io::BufReader::new(file));
    let Ok(reader) = decoder.read_info() else {
        return false;
    };
    let info = reader.info();
    if info.srgb.is_some() {
        return false;
    }
    // The gAMA chunk itself: png 0.18 leaves `source_gamma` unset when it
    // reads one (8-bit PNGs this tool wrote were sRGB-decoded).
    match info.gama_chunk.or(info.source_gamma) {
        // gAMA stores 1/gamma; 1.0 means linear.
        Some(g) => (g.into_value() - 1.0).abs() < 0.01,
        None => false,
    }
}

/// Reads a photograph as linear grey values, deciding the sRGB decoding by
/// `mode`; returns the image and whether sRGB decoding was applied, with the
/// reason.
pub fn read_photo(path: &Path, mode: SrgbMode) -> Result<(Grid<f64>, bool, String), IoError> {
    let image = decode_image(path)?;
    let (srgb, why) = decide_srgb(path, &image, mode);
    Ok((image_to_grey(path, image, srgb)?, srgb, why))
}

/// Reads a mask/confidence image as values in [0, 1]: grey value divided by
/// the maximum of its type, luminance (Rec. 709) for colour, never
/// sRGB-decoded; alpha is ignored.
pub fn read_mask(path: &Path) -> Result<Grid<f64>, IoError> {
    read_image(path, false)
}

fn image_dims(path: &Path, width: usize, height: usize) -> Result<(u32, u32), IoError> {
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(write_error(
            path,
            format!("{width}x{height} is too large for an image"),
        )),
    }
}

/// A grey image buffer holding `data` (row-major).
fn grey_buffer<P: image::Primitive>(
    path: &Path,
    width: usize,
    height: usize,
    data: Vec<P>,
) -> Result<ImageBuffer<Luma<P>, Vec<P>>, IoError> {
    let (w, h) = image_dims(path, width, height)?;
    ImageBuffer::from_raw(w, h, data)
        .ok_or_else(|| write_error(path, "internal error: pixel count does not match the size"))
}

fn save_png(path: &Path, image: DynamicImage) -> Result<(), IoError> {
    // The format is explicit: staged outputs end in `.partial`.
    image
        .save_with_format(path, ImageFormat::Png)
        .map_err(|e| write_error(path, e))
}

/// Quantises a value to `0..=max`: clamped to [0, 1], NaN as 0, rounded.
fn quantise(v: f64, max: f64) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        (v.clamp(0.0, 1.0) * max).round()
    }
}

/// Writes a 16-bit linear grey PNG: values clamped to [0, 1], NaN as 0,
/// scaled by 65535 and rounded; marked linear (gAMA 1.0).
pub fn write_png16(path: &Path, image: &Grid<f64>) -> Result<(), IoError> {
    let data: Vec<u16> = image
        .as_slice()
        .iter()
        .map(|&v| quantise(v, 65535.0) as u16)
        .collect();
    let bytes: Vec<u8> = data.iter().flat_map(|v: &u16| v.to_be_bytes()).collect();
    save_linear_png(
        path,
        image.width(),
        image.height(),
        png::BitDepth::Sixteen,
        &bytes,
    )
}

/// Writes an 8-bit grey PNG of linear values: clamped to [0, 1], NaN as 0,
/// scaled by 255 and rounded; marked linear (gAMA 1.0), so that
/// `--srgb auto` does not decode it again.
pub fn write_png8(path: &Path, image: &Grid<f64>) -> Result<(), IoError> {
    let data: Vec<u8> = image
        .as_slice()
        .iter()
        .map(|&v| quantise(v, 255.0) as u8)
        .collect();
    save_linear_png(
        path,
        image.width(),
        image.height(),
        png::BitDepth::Eight,
        &data,
    )
}

/// Writes grey samples (big-endian for 16 bits) as a PNG whose gAMA chunk
/// says the values are linear (gamma 1.0).
fn save_linear_png(
    path: &Path,
    width: usize,
    height: usize,
    depth: png::BitDepth,
    samples: &[u8],
) -> Result<(), IoError> {
    let (w, h) = image_dims(path, width, height)?;
    let file = fs::File::create(path).map_err(|e| write_error(path, e))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(depth);
    encoder.set_source_gamma(png::ScaledFloat::new(1.0));
    let mut writer = encoder.write_header().map_err(|e| write_error(path, e))?;
    writer
        .write_image_data(samples)
        .map_err(|e| write_error(path, e))?;
    writer.finish().map_err(|e| write_error(path, e))
}

/// Writes a binary mask as an 8-bit grey PNG, 255 for true and 0 for false.
pub fn write_mask_png(path: &Path, mask: &Grid<bool>) -> Result<(), IoError> {
    let data = mask
        .as_slice()
        .iter()
        .map(|&b| if b { 255u8 } else { 0 })
        .collect();
    let buffer = grey_buffer(path, mask.width(), mask.height(), data)?;
    save_png(path, DynamicImage::ImageLuma8(buffer))
}

// ---------------------------------------------------------------------------
// .npy
// ---------------------------------------------------------------------------

fn write_npy<T>(path: &Path, grid: &Grid<f64>, convert: impl Fn(f64) -> T) -> Result<(), IoError>
where
    T: npyz::AutoSerialize,
{
    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    let shape = [grid.height() as u64, grid.width() as u64];
    let mut writer = WriteOptions::<T>::new()
        .default_dtype()
        .shape(&shape)
        .writer(&mut out)
        .begin_nd()
        .map_err(err)?;
    writer
        .extend(grid.as_slice().iter().map(|&v| convert(v)))
        .map_err(err)?;
    writer.finish().map_err(err)?;
    out.flush().map_err(err)
}

/// Writes `grid` as an H x W (rows x columns) C-order `.npy` of little-endian
/// float32. NaN (no value) is written as NaN; a value that is infinite, or
/// too large for float32, is an error and nothing is written.
pub fn write_npy_f32(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    refuse_infinite(path, grid, f64::from(f32::MAX))?;
    write_npy(path, grid, |v| v as f32)
}

/// Writes `grid` as an H x W (rows x columns) C-order `.npy` of little-endian
/// float64. NaN is written as NaN; an infinite value is an error.
pub fn write_npy_f64(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    refuse_infinite(path, grid, f64::MAX)?;
    write_npy(path, grid, |v| v)
}

/// An error naming `path` when a value of `grid` is beyond `±limit`.
fn refuse_infinite(path: &Path, grid: &Grid<f64>, limit: f64) -> Result<(), IoError> {
    match grid.as_slice().iter().find(|v| v.abs() > limit) {
        Some(v) => Err(write_error(
            path,
            format!("the array holds {v:e}, which the file's number type cannot hold"),
        )),
        None => Ok(()),
    }
}

/// Reads all elements of `file` (whose data is known to be complete) as f64.
fn npy_values<T, R>(file: NpyFile<R>, to_f64: impl Fn(T) -> f64) -> std::io::Result<Vec<f64>>
where
    T: npyz::Deserialize,
    R: std::io::Read,
{
    let reader = file
        .data::<T>()
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string()))?;
    reader.map(|v| v.map(&to_f64)).collect()
}

/// Reads a 2-D `.npy` array as a grid with rows along the first axis.
///
/// Accepted element types, in either byte order and in C or Fortran order:
/// float32, float64, signed and unsigned integers of 1 to 8 bytes and bool
/// (converted to f64; integers beyond 2^53 lose precision, bool is 0 or 1).
/// Anything else (other dimensions, strings, records, complex, float16), a
/// truncated file or an array with no elements is an error naming the file
/// and what was found.
pub fn read_npy(path: &Path) -> Result<Grid<f64>, IoError> {
    let bad = |reason: String| IoError::Npy {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = fs::read(path).map_err(|cause| IoError::Read {
        path: path.to_path_buf(),
        cause,
    })?;
    let mut cursor = Cursor::new(bytes.as_slice());
    let header =
        NpyHeader::from_reader(&mut cursor).map_err(|e| bad(format!("bad header: {e}")))?;
    let shape = header.shape().to_vec();
    if shape.len() != 2 {
        return Err(bad(format!(
            "expected a 2-D array, found {}-D with shape {:?}",
            shape.len(),
            shape
        )));
    }
    let (rows, cols) = match (usize::try_from(shape[0]), usize::try_from(shape[1])) {
        (Ok(r), Ok(c)) => (r, c),
        _ => return Err(bad(format!("shape {shape:?} is too large"))),
    };
    let count = rows
        .checked_mul(cols)
        .ok_or_else(|| bad(format!("shape {shape:?} is too large")))?;
    if count == 0 {
        return Err(bad(format!("the array is empty (shape {shape:?})")));
    }
    let dtype = header.dtype();
    let type_str = match &dtype {
        DType::Plain(t) => t.clone(),
        other => return Err(bad(format!("unsupported element type {}", other.descr()))),
    };
    let item_size = dtype
        .num_bytes()
        .ok_or_else(|| bad(format!("unsupported element type {type_str}")))?;
    let available = bytes.len() as u64 - cursor.position();
    let needed = (count as u64).checked_mul(item_size as u64);
    if needed.is_none_or(|n| n > available) {
        return Err(bad(format!(
            "the file is truncated: shape {shape:?} of {type_str} needs {} bytes of data, found {available}",
            needed.map_or_else(|| "too many".to_string(), |n| n.to_string())
        )));
    }
    let order = header.order();
    let file = NpyFile::with_header(header, cursor);
    let values = match (type_str.type_char(), item_size) {
        (TypeChar::Float, 8) => npy_values(file, |v: f64| v),
        (TypeChar::Float, 4) => npy_values(file, |v: f32| f64::from(v)),
        (TypeChar::Int, 1) => npy_values(file, |v: i8| f64::from(v)),
        (TypeChar::Int, 2) => npy_values(file, |v: i16| f64::from(v)),
        (TypeChar::Int, 4) => npy_values(file, |v: i32| f64::from(v)),
        (TypeChar::Int, 8) => npy_values(file, |v: i64| v as f64),
        (TypeChar::Uint, 1) => npy_values(file, |v: u8| f64::from(v)),
        (TypeChar::Uint, 2) => npy_values(file, |v: u16| f64::from(v)),
        (TypeChar::Uint, 4) => npy_values(file, |v: u32| f64::from(v)),
        (TypeChar::Uint, 8) => npy_values(file, |v: u64| v as f64),
        (TypeChar::Bool, 1) => npy_values(file, |v: bool| if v { 1.0 } else { 0.0 }),
        _ => {
            return Err(bad(format!(
                "unsupported element type {type_str} (expected float32, float64, an integer or bool)"
            )));
        }
    }
    .map_err(|e| bad(format!("bad data: {e}")))?;
    if values.len() != count {
        return Err(bad(format!(
            "expected {count} values, read {}",
            values.len()
        )));
    }
    let grid = match order {
        Order::C => Grid::from_vec(cols, rows, values),
        // Fortran order: the first axis (rows) varies fastest.
        Order::Fortran => Some(Grid::from_fn(cols, rows, |c, r| values[c * rows + r])),
    };
    grid.ok_or_else(|| bad("internal error: value count does not match the shape".into()))
}

// ---------------------------------------------------------------------------
// PLY mesh
// ---------------------------------------------------------------------------

/// Writes a triangle mesh of a depth map as a binary little-endian PLY.
///
/// The mesh is [`DepthMesh::new`]'s, the one the 3-D view draws: every
/// pixel with finite depth `z > 0` becomes the vertex
/// `((i - cx) z / f, (j - cy) z / f, z)` (column `i`, row `j`); triangles
/// join neighbouring pixels but never cross a missing pixel or a depth jump
/// (see [`crate::depth_mesh`]). Triangles wind counter-clockwise as seen
/// from the camera, so their normals `(v1 - v0) x (v2 - v0)` point towards it
/// (negative z for a fronto-parallel plane). With `shade` (same size as
/// `depth`, values in [0, 1], NaN as 0) each vertex gets grey
/// `red`/`green`/`blue` uchar properties.
pub fn write_depth_ply(
    path: &Path,
    depth: &Grid<f64>,
    camera: &Intrinsics,
    shade: Option<&Grid<f64>>,
) -> Result<(), IoError> {
    let (w, h) = depth.size();
    if let Some(s) = shade
        && s.size() != depth.size()
    {
        return Err(write_error(
            path,
            format!(
                "the shading is {}x{} but the depth map is {w}x{h}",
                s.width(),
                s.height()
            ),
        ));
    }
    let mesh = full_resolution_mesh(path, depth, camera)?;

    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment sfs-studio depth mesh\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        mesh.vertex_count()
    );
    if shade.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.triangles().len()
    ));
    out.write_all(header.as_bytes()).map_err(err)?;
    for (&(i, j), position) in mesh.vertex_pixels().iter().zip(mesh.positions_camera()) {
        for &v in position {
            out.write_all(&(v as f32).to_le_bytes()).map_err(err)?;
        }
        if let Some(s) = shade {
            let g = quantise(*s.at(i, j), 255.0) as u8;
            out.write_all(&[g, g, g]).map_err(err)?;
        }
    }
    for triangle in mesh.triangles() {
        out.write_all(&[3u8]).map_err(err)?;
        for &v in triangle {
            // Fits: the mesh has at most `depth_mesh::MAX_VERTICES` = i32::MAX.
            out.write_all(&(v as i32).to_le_bytes()).map_err(err)?;
        }
    }
    out.flush().map_err(err)
}

/// The mesh of a full-resolution depth map seen through `camera`.
fn full_resolution_mesh(
    path: &Path,
    depth: &Grid<f64>,
    camera: &Intrinsics,
) -> Result<DepthMesh, IoError> {
    let (w, h) = depth.size();
    let geometry = LevelGeometry::new(w, h, w, h, *camera);
    DepthMesh::new(depth, &geometry).map_err(|e| write_error(path, e))
}

/// Writes the depth map as a Wavefront OBJ triangle mesh (camera
/// coordinates: x right, y down, z forward, in depth units), the same mesh
/// as [`write_depth_ply`].
pub fn write_depth_obj(path: &Path, depth: &Grid<f64>, camera: &Intrinsics) -> Result<(), IoError> {
    let mesh = full_resolution_mesh(path, depth, camera)?;
    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    writeln!(
        out,
        "# sfs-studio depth mesh, camera coordinates (x right, y down, z forward)"
    )
    .map_err(err)?;
    for [px, py, pz] in mesh.positions_camera() {
        writeln!(out, "v {px} {py} {pz}").map_err(err)?;
    }
    for [a, b, c] in mesh.triangles() {
        writeln!(out, "f {} {} {}", a + 1, b + 1, c + 1).map_err(err)?;
    }
    out.flush().map_err(err)
}

// ---------------------------------------------------------------------------
// Camera / scene file and JSON
// ---------------------------------------------------------------------------

/// Writes depth as a 16-bit PNG for viewing: 1 (white) at the nearest depth,
/// 0 at the farthest and off the object. Returns `(near, far)` or `None`
/// when no depth is finite.
pub fn write_depth_png16(path: &Path, depth: &Grid<f64>) -> Result<Option<(f64, f64)>, IoError> {
    let mut range: Option<(f64, f64)> = None;
    for &z in depth.as_slice() {
        if z.is_finite() {
            range = Some(range.map_or((z, z), |(lo, hi)| (lo.min(z), hi.max(z))));
        }
    }
    let (near, far) = range.unwrap_or((0.0, 1.0));
    let span = (far - near).max(f64::MIN_POSITIVE);
    let view = depth.map(|&z| {
        if z.is_finite() {
            1.0 - (z - near) / span
        } else {
            0.0
        }
    });
    write_png16(path, &view)?;
    Ok(range)
}

pub use crate::calibration::{CameraFile, read_camera, write_camera};

/// Writes any serde value as pretty JSON, with a final newline.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), IoError> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| write_error(path, e))?;
    text.push('\n');
    fs::write(path, text).map_err(|e| write_error(path, e))
}

// ---------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    #[test]
    fn an_8_bit_png_this_tool_wrote_is_read_as_linear() {
        // synth's noisy8.png: gAMA 1.0 says linear; sRGB-decoding it
        // darkened the mid-tones and the noisy Sombrero came back with RSE
        // 0.42 instead of 0.015.
        let dir = tempdir().unwrap();
        let path = dir.path().join("noisy8.png");
        let image = Grid::from_fn(8, 6, |c, r| (c + r) as f64 / 20.0);
        write_png8(&path, &image).unwrap();
        let (read, srgb, why) = read_photo(&path, SrgbMode::Auto).unwrap();
        assert!(!srgb, "{why}");
        for (a, b) in read.as_slice().iter().zip(image.as_slice()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-12, "{a} vs {b}");
        }
    }
    use super::*;
    use tempfile::tempdir;

    fn ramp(w: usize, h: usize) -> Grid<f64> {
        Grid::from_fn(w, h, |i, j| (i + w * j) as f64 / (w * h - 1) as f64)
    }

    #[test]
    fn png16_round_trip_is_exact_to_one_step() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("a.png");
        let mut g = ramp(7, 5);
        *g.at_mut(0, 0) = f64::NAN;
        *g.at_mut(1, 0) = 1.5;
        *g.at_mut(2, 0) = -0.5;
        write_png16(&p, &g).unwrap();
        let back = read_image(&p, false).unwrap();
        assert_eq!(back.size(), (7, 5));
        assert_eq!(*back.at(0, 0), 0.0);
        assert_eq!(*back.at(1, 0), 1.0);
        assert_eq!(*back.at(2, 0), 0.0);
        for (k, (a, b)) in g.as_slice().iter().zip(back.as_slice()).enumerate().skip(3) {
            assert!(
                (a - b).abs() <= 0.5 / 65535.0 + 1e-12,
                "pixel {k}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn png8_round_trip() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("a.png");
        let g = ramp(4, 3);
        write_png8(&p, &g).unwrap();
        let back = read_image(&p, false).unwrap();
        for (a, b) in g.as_slice().iter().zip(back.as_slice()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-12);
        }
    }

    #[test]
    fn mask_round_trip() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("m.png");
        let m = Grid::from_fn(5, 4, |i, j| (i + j) % 2 == 0);
        write_mask_png(&p, &m).unwrap();
        let back = read_mask(&p).unwrap();
        assert_eq!(back.size(), (5, 4));
        for (a, b) in m.as_slice().iter().zip(back.as_slice()) {
            assert_eq!(*b, if *a { 1.0 } else { 0.0 });
        }
    }

    #[test]
    fn rgb_reads_as_linear_luminance_and_srgb_decodes() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("rgb.png");
        let img = image::RgbImage::from_fn(2, 1, |x, _| {
            if x == 0 {
                image::Rgb([0, 255, 0])
            } else {
                image::Rgb([128, 128, 128])
            }
        });
        img.save(&p).unwrap();
        let lin = read_image(&p, false).unwrap();
        assert!((lin.at(0, 0) - 0.7152).abs() < 1e-12);
        assert!((lin.at(1, 0) - 128.0 / 255.0).abs() < 1e-12);
        let dec = read_image(&p, true).unwrap();
        assert!((dec.at(0, 0) - 0.7152).abs() < 1e-12);
        assert!((dec.at(1, 0) - 0.2158).abs() < 1e-3, "{}", dec.at(1, 0));
        // Grey images are sRGB-decoded too; masks never are.
        let q = dir.path().join("grey.png");
        image::GrayImage::from_pixel(1, 1, Luma([128]))
            .save(&q)
            .unwrap();
        assert!((read_image(&q, true).unwrap().at(0, 0) - 0.2158).abs() < 1e-3);
        assert!((read_mask(&q).unwrap().at(0, 0) - 128.0 / 255.0).abs() < 1e-12);
    }

    #[test]
    fn one_pixel_image_reads() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("one.tif");
        image::ImageBuffer::<Luma<u16>, _>::from_pixel(1, 1, Luma([65535u16]))
            .save(&p)
            .unwrap();
        let g = read_image(&p, false).unwrap();
        assert_eq!(g.size(), (1, 1));
        assert_eq!(*g.at(0, 0), 1.0);
    }

    #[test]
    fn bad_image_files_name_the_path() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("x.png");
        fs::write(&p, "this is text").unwrap();
        let e = read_image(&p, false).unwrap_err().to_string();
        assert!(e.contains(&p.display().to_string()), "{e}");
        assert!(e.contains("is not an image"), "{e}");

        let missing = dir.path().join("missing.png");
        let e = read_image(&missing, false).unwrap_err().to_string();
        assert!(e.contains(&missing.display().to_string()), "{e}");
        assert!(e.starts_with("cannot read image"), "{e}");

        let e = read_image(dir.path(), false).unwrap_err().to_string();
        assert!(e.contains(&dir.path().display().to_string()), "{e}");
    }

    #[test]
    fn npy_round_trips_keep_nan() {
        let dir = tempdir().unwrap();
        let mut g = ramp(4, 3);
        *g.at_mut(1, 2) = f64::NAN;
        *g.at_mut(3, 0) = -2.5e10;
        for (name, f32_file) in [("a32.npy", true), ("a64.npy", false)] {
            let p = dir.path().join(name);
            if f32_file {
                write_npy_f32(&p, &g).unwrap();
            } else {
                write_npy_f64(&p, &g).unwrap();
            }
            let back = read_npy(&p).unwrap();
            assert_eq!(back.size(), (4, 3));
            for (a, b) in g.as_slice().iter().zip(back.as_slice()) {
                if a.is_nan() {
                    assert!(b.is_nan());
                } else if f32_file {
                    assert_eq!(*b, *a as f32 as f64);
                } else {
                    assert_eq!(a, b);
                }
            }
        }
    }

    /// A hand-made `.npy` (version 1.0) with the given header dict and data.
    fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
        let mut text = dict.to_string();
        while !(10 + text.len() + 1).is_multiple_of(64) {
            text.push(' ');
        }
        text.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((text.len() as u16).to_le_bytes());
        out.extend(text.as_bytes());
        out.extend(data);
        out
    }

    #[test]
    fn reads_fortran_order_big_endian_npy() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("f.npy");
        // 2 rows x 3 columns, value 10 r + c, stored column by column.
        let mut data = Vec::new();
        for c in 0..3 {
            for r in 0..2 {
                data.extend((10.0 * r as f64 + c as f64).to_be_bytes());
            }
        }
        let dict = "{'descr': '>f8', 'fortran_order': True, 'shape': (2, 3), }";
        fs::write(&p, npy_bytes(dict, &data)).unwrap();
        let g = read_npy(&p).unwrap();
        assert_eq!(g.size(), (3, 2));
        assert_eq!(g.as_slice(), &[0.0, 1.0, 2.0, 10.0, 11.0, 12.0]);

        // Fortran order written by npyz, float32.
        let q = dir.path().join("f32.npy");
        let mut out = BufWriter::new(fs::File::create(&q).unwrap());
        let mut w = WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[2, 3])
            .order(Order::Fortran)
            .writer(&mut out)
            .begin_nd()
            .unwrap();
        w.extend([0.0, 10.0, 1.0, 11.0, 2.0, 12.0]).unwrap();
        w.finish().unwrap();
        out.flush().unwrap();
        drop(out);
        assert_eq!(read_npy(&q).unwrap(), g);
    }

    #[test]
    fn npy_errors_name_the_file_and_what_was_found() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("v.npy");
        let data: Vec<u8> = [1.0f64, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        fs::write(
            &p,
            npy_bytes(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }",
                &data,
            ),
        )
        .unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(
            e.contains(&p.display().to_string()) && e.contains("1-D"),
            "{e}"
        );

        // Truncated: the header promises far more than the file holds.
        fs::write(
            &p,
            npy_bytes(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }",
                &data,
            ),
        )
        .unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");

        // Integers convert; strings do not.
        let ints: Vec<u8> = [1i32, -2, 3, 4]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        fs::write(
            &p,
            npy_bytes(
                "{'descr': '<i4', 'fortran_order': False, 'shape': (2, 2), }",
                &ints,
            ),
        )
        .unwrap();
        assert_eq!(read_npy(&p).unwrap().as_slice(), &[1.0, -2.0, 3.0, 4.0]);
        fs::write(
            &p,
            npy_bytes(
                "{'descr': '|S4', 'fortran_order': False, 'shape': (2, 2), }",
                &ints,
            ),
        )
        .unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("unsupported element type"), "{e}");

        fs::write(&p, "not npy").unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains(&p.display().to_string()), "{e}");
        let e = read_npy(&dir.path().join("none.npy"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.npy"), "{e}");
    }

    fn camera() -> CameraFile {
        CameraFile {
            name: Some("vase".into()),
            width: 64,
            height: 48,
            focal: Some(80.0),
            cx: Some(31.5),
            cy: Some(23.5),
            intensity_scale: Some(1.0),
            ..CameraFile::default()
        }
    }

    #[test]
    fn camera_file_round_trip() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("scene.json");
        write_camera(&p, &camera()).unwrap();
        assert_eq!(read_camera(&p).unwrap(), camera());
        let unnamed = CameraFile {
            name: None,
            ..camera()
        };
        write_camera(&p, &unnamed).unwrap();
        assert!(!fs::read_to_string(&p).unwrap().contains("name"));
        assert_eq!(read_camera(&p).unwrap(), unnamed);
        let k = camera().intrinsics().unwrap();
        assert_eq!(
            (k.focal_px, k.principal_x_px, k.principal_y_px),
            (80.0, 31.5, 23.5)
        );
    }

    #[test]
    fn camera_file_errors_name_key_and_path() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("cam.json");
        fs::write(
            &p,
            r#"{"width": 4, "height": 4, "cx": 1.5, "cy": 1.5, "intensity_scale": 1}"#,
        )
        .unwrap();
        let e = read_camera(&p).unwrap_err().to_string();
        assert!(
            e.contains("focal") && e.contains(&p.display().to_string()),
            "{e}"
        );

        fs::write(
            &p,
            r#"{"width": 4, "height": 4, "focal": 5, "cx": 1.5, "cy": 1.5,
                "intensity_scale": 1, "focla": 3}"#,
        )
        .unwrap();
        let e = read_camera(&p).unwrap_err().to_string();
        assert!(e.contains("focla") && e.contains("unknown field"), "{e}");

        let bad = CameraFile {
            focal: Some(0.0),
            ..camera()
        };
        let e = bad.validate(&p).unwrap_err().to_string();
        assert!(
            e.contains("`focal`") && e.contains(&p.display().to_string()),
            "{e}"
        );
        write_camera(&p, &bad).unwrap();
        assert!(read_camera(&p).unwrap_err().to_string().contains("`focal`"));
        let bad = CameraFile {
            width: 0,
            ..camera()
        };
        assert!(
            bad.validate(&p)
                .unwrap_err()
                .to_string()
                .contains("`width`")
        );
    }

    /// Parses the PLY written by `write_depth_ply`: header lines, vertices
    /// (x, y, z) and faces.
    fn parse_ply(bytes: &[u8], colour: bool) -> (Vec<String>, Vec<[f32; 3]>, Vec<[i32; 3]>) {
        let end = b"end_header\n";
        let pos = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let header: Vec<String> = std::str::from_utf8(&bytes[..pos])
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        let count = |prefix: &str| -> usize {
            header
                .iter()
                .find_map(|l| l.strip_prefix(prefix))
                .unwrap()
                .parse()
                .unwrap()
        };
        let (nv, nf) = (count("element vertex "), count("element face "));
        let stride = if colour { 15 } else { 12 };
        let mut k = pos;
        let f32_at = |k: usize| f32::from_le_bytes(bytes[k..k + 4].try_into().unwrap());
        let mut vertices = Vec::new();
        for _ in 0..nv {
            vertices.push([f32_at(k), f32_at(k + 4), f32_at(k + 8)]);
            k += stride;
        }
        let mut faces = Vec::new();
        for _ in 0..nf {
            assert_eq!(bytes[k], 3);
            let i = |o: usize| i32::from_le_bytes(bytes[k + o..k + o + 4].try_into().unwrap());
            faces.push([i(1), i(5), i(9)]);
            k += 13;
        }
        assert_eq!(k, bytes.len());
        (header, vertices, faces)
    }

    #[test]
    fn ply_of_a_plane_faces_the_camera() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("plane.ply");
        let depth = Grid::filled(3, 3, 2.0);
        let cam = Intrinsics::centred(10.0, 3, 3);
        write_depth_ply(&p, &depth, &cam, Some(&Grid::filled(3, 3, 0.5))).unwrap();
        let (header, v, f) = parse_ply(&fs::read(&p).unwrap(), true);
        assert_eq!(header[0], "ply");
        assert_eq!(header[1], "format binary_little_endian 1.0");
        assert!(header.contains(&"element vertex 9".to_string()));
        assert!(header.contains(&"element face 8".to_string()));
        assert!(header.contains(&"property uchar red".to_string()));
        assert!(header.contains(&"property list uchar int vertex_indices".to_string()));
        assert_eq!(header.last().unwrap(), "end_header");
        assert_eq!((v.len(), f.len()), (9, 8));
        // Pixel (0, 0) is at x = (0 - 1) * 2 / 10.
        assert_eq!(v[0], [-0.2, -0.2, 2.0]);
        for face in &f {
            let [a, b, c] = face.map(|i| v[i as usize]);
            let e1 = [b[0] - a[0], b[1] - a[1]];
            let e2 = [c[0] - a[0], c[1] - a[1]];
            let nz = e1[0] * e2[1] - e1[1] * e2[0];
            assert!(nz < 0.0, "face {face:?} has normal z {nz}");
        }
    }

    #[test]
    fn ply_skips_missing_pixels() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("hole.ply");
        let mut depth = Grid::filled(3, 3, 2.0);
        *depth.at_mut(0, 0) = f64::NAN;
        let cam = Intrinsics::centred(10.0, 3, 3);
        write_depth_ply(&p, &depth, &cam, None).unwrap();
        let (header, v, f) = parse_ply(&fs::read(&p).unwrap(), false);
        assert!(!header.iter().any(|l| l.contains("red")));
        assert_eq!((v.len(), f.len()), (8, 7));
        // With the centre missing too, the top-left block has two valid
        // pixels (no face) and the other three blocks three (one face each).
        *depth.at_mut(1, 1) = 0.0;
        write_depth_ply(&p, &depth, &cam, None).unwrap();
        let (_, v, f) = parse_ply(&fs::read(&p).unwrap(), false);
        assert_eq!((v.len(), f.len()), (7, 3));
        let e = write_depth_ply(&p, &depth, &cam, Some(&Grid::filled(2, 2, 0.0)));
        assert!(e.unwrap_err().to_string().contains("hole.ply"));
    }

    #[test]
    fn grey_float_and_uint32_tiffs_are_read() {
        use tiff::encoder::{TiffEncoder, colortype};
        let dir = tempdir().unwrap();
        let (w, h) = (4u32, 3u32);
        let float_path = dir.path().join("grey32f.tif");
        let values: Vec<f32> = (0..w * h).map(|k| k as f32 / 11.0).collect();
        let mut encoder = TiffEncoder::new(fs::File::create(&float_path).unwrap()).unwrap();
        encoder
            .write_image::<colortype::Gray32Float>(w, h, &values)
            .unwrap();
        let grid = read_image(&float_path, false).unwrap();
        assert_eq!(grid.size(), (4, 3));
        assert_eq!(image_size(&float_path).unwrap(), (4, 3));
        for (k, v) in grid.as_slice().iter().enumerate() {
            assert!((v - k as f64 / 11.0).abs() < 1e-6, "{k}: {v}");
        }
        // Read as linear by the automatic sRGB decision.
        assert!(!read_photo(&float_path, SrgbMode::Auto).unwrap().1);

        let uint_path = dir.path().join("grey32u.tif");
        let values: Vec<u32> = (0..w * h).map(|k| k * (u32::MAX / 11)).collect();
        let mut encoder = TiffEncoder::new(fs::File::create(&uint_path).unwrap()).unwrap();
        encoder
            .write_image::<colortype::Gray32>(w, h, &values)
            .unwrap();
        let grid = read_image(&uint_path, false).unwrap();
        for (k, v) in grid.as_slice().iter().enumerate() {
            assert!((v - k as f64 / 11.0).abs() < 1e-6, "{k}: {v}");
        }

        // Signed samples are refused with a reason naming the file.
        let signed_path = dir.path().join("grey16i.tif");
        let values: Vec<i16> = vec![5; (w * h) as usize];
        let mut encoder = TiffEncoder::new(fs::File::create(&signed_path).unwrap()).unwrap();
        encoder
            .write_image::<colortype::GrayI16>(w, h, &values)
            .unwrap();
        let e = read_image(&signed_path, false).unwrap_err().to_string();
        assert!(e.contains("grey16i.tif") && e.contains("signed"), "{e}");
    }

    #[test]
    fn a_wrong_sample_count_is_an_error_not_a_black_image() {
        let path = Path::new("odd.png");
        let e = samples_to_grey(path, (3, 3, 1), &[0u8; 8], false, 255.0, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("odd.png") && e.contains("8 samples"), "{e}");
    }
}
