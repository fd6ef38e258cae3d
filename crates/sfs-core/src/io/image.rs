//! Grey images and masks: PNG, TIFF (8/16/32-bit and float) and JPEG read as
//! linear luminance (sRGB decoded on request or as the file says; integer
//! samples on [0, 1], float samples on their own scale, see
//! [`FloatSamples`]), 16- and 8-bit PNG writers marking linear data (gAMA
//! 1.0), mask PNGs, and the 16-bit depth picture for viewing.

use std::fs;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, ImageError, ImageFormat, ImageReader, Luma};
use serde::{Deserialize, Serialize};

use super::error::{IoError, write_error};
use crate::grid::Grid;

/// Rec. 709 luminance weights for linear red, green and blue.
const LUMA_709: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The sRGB electro-optical transfer function: encoded value in [0, 1] to
/// linear value in [0, 1].
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes `path`; the flag says whether its samples are floats (a float
/// TIFF: no fixed white), as opposed to integers (divided by their type's
/// maximum, on [0, 1]).
fn decode_image(path: &Path) -> Result<(DynamicImage, bool), IoError> {
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
    match reader.decode() {
        Ok(image) => {
            let float = matches!(
                image,
                DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
            );
            Ok((image, float))
        }
        // Grey float32/float64 and 32-bit integer TIFFs, which `image` does
        // not decode.
        Err(ImageError::Unsupported(_)) if is_tiff => {
            decode_tiff_samples(path).map_err(|reason| IoError::BadImage {
                path: path.to_path_buf(),
                reason,
            })
        }
        Err(cause) => Err(cause_to_error(path, cause)),
    }
}

/// The EXIF orientation of a photograph when it is not the identity
/// (`None` without EXIF, or for an upright image).
pub fn exif_orientation(path: &Path) -> Option<image::metadata::Orientation> {
    use image::ImageDecoder as _;
    let mut decoder = ImageReader::open(path)
        .ok()?
        .with_guessed_format()
        .ok()?
        .into_decoder()
        .ok()?;
    decoder
        .orientation()
        .ok()
        .filter(|o| *o != image::metadata::Orientation::NoTransforms)
}

/// Whether `orientation` turns the image by a quarter turn (width and
/// height swap).
fn swaps_sides(orientation: image::metadata::Orientation) -> bool {
    use image::metadata::Orientation as O;
    matches!(
        orientation,
        O::Rotate90 | O::Rotate270 | O::Rotate90FlipH | O::Rotate270FlipH
    )
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

/// A photograph's `(width, height)` upright (after its EXIF orientation, as
/// [`read_photo`] returns it), from its header.
pub fn photo_size(path: &Path) -> Result<(usize, usize), IoError> {
    let (w, h) = image_size(path)?;
    Ok(match exif_orientation(path) {
        Some(orientation) if swaps_sides(orientation) => (h, w),
        _ => (w, h),
    })
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
/// float RGB (integers divided by their type's maximum), with whether the
/// samples were floats. The error says what the file holds.
fn decode_tiff_samples(path: &Path) -> Result<(DynamicImage, bool), String> {
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
    let (values, float): (Vec<f32>, bool) =
        match decoder.read_image().map_err(|e| format!("bad TIFF: {e}"))? {
            DecodingResult::U8(v) => (v.iter().map(|&s| f32::from(s) / 255.0).collect(), false),
            DecodingResult::U16(v) => (v.iter().map(|&s| f32::from(s) / 65535.0).collect(), false),
            DecodingResult::U32(v) => (
                v.iter()
                    .map(|&s| (f64::from(s) / f64::from(u32::MAX)) as f32)
                    .collect(),
                false,
            ),
            DecodingResult::F32(v) => (v, true),
            DecodingResult::F64(v) => (v.iter().map(|&s| s as f32).collect(), true),
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
        .map(|image| (DynamicImage::ImageRgb32F(image), float))
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

/// What a float image's samples held (see [`read_photo`]): a float image
/// has no fixed white, so its values are read on their own scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatSamples {
    /// Pixels with a negative sample (noise below a dark frame's level),
    /// read as 0.
    pub negative_pixels: usize,
    /// Their share of the image's pixels.
    pub negative_share: f64,
}

/// An image's linear grey values: integer samples on [0, 1], float samples
/// (`float`) on their own scale with [`FloatSamples`].
fn image_to_grey(
    path: &Path,
    image: DynamicImage,
    float: bool,
    srgb: bool,
) -> Result<(Grid<f64>, Option<FloatSamples>), IoError> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!("it is empty ({w}x{h})"),
        });
    }
    // Integer samples on [0, 1]: divided by their type's maximum.
    let bytes = |raw: &[u8], channels: usize, colour: bool| {
        samples_to_grey(path, (w, h, channels), raw, colour, 255.0, srgb)
    };
    let words = |raw: &[u16], channels: usize, colour: bool| {
        samples_to_grey(path, (w, h, channels), raw, colour, 65535.0, srgb)
    };
    let grid = match image {
        DynamicImage::ImageLuma8(b) => bytes(b.as_raw(), 1, false)?,
        DynamicImage::ImageLumaA8(b) => bytes(b.as_raw(), 2, false)?,
        DynamicImage::ImageRgb8(b) => bytes(b.as_raw(), 3, true)?,
        DynamicImage::ImageRgba8(b) => bytes(b.as_raw(), 4, true)?,
        DynamicImage::ImageLuma16(b) => words(b.as_raw(), 1, false)?,
        DynamicImage::ImageLumaA16(b) => words(b.as_raw(), 2, false)?,
        DynamicImage::ImageRgb16(b) => words(b.as_raw(), 3, true)?,
        DynamicImage::ImageRgba16(b) => words(b.as_raw(), 4, true)?,
        DynamicImage::ImageRgb32F(b) if float => {
            return own_scale_to_grey(path, (w, h, 3), b.as_raw(), srgb);
        }
        DynamicImage::ImageRgba32F(b) if float => {
            return own_scale_to_grey(path, (w, h, 4), b.as_raw(), srgb);
        }
        // Integer TIFF samples the `tiff` crate decoded, divided by their
        // type's maximum.
        DynamicImage::ImageRgb32F(b) => unit_float_to_grey(path, w, h, b.as_raw(), 3, srgb)?,
        DynamicImage::ImageRgba32F(b) => unit_float_to_grey(path, w, h, b.as_raw(), 4, srgb)?,
        other => {
            // Layouts added to `image` later: go through normalised float RGB.
            let rgb = other.to_rgb32f();
            unit_float_to_grey(path, w, h, rgb.as_raw(), 3, srgb)?
        }
    };
    Ok((grid, None))
}

/// Float samples already on [0, 1] (integers divided by their type's
/// maximum): clamped to it, NaN refused.
fn unit_float_to_grey(
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

/// A float image's samples (`channels` per pixel, the first three red,
/// green and blue; a grey image's three equal) as linear grey on their own
/// scale: no fixed white, so nothing is clamped at the top; a negative
/// sample is read as 0 and counted; NaN and infinite samples are refused,
/// naming the file and the first such pixel.
fn own_scale_to_grey(
    path: &Path,
    (width, height, channels): (usize, usize, usize),
    raw: &[f32],
    srgb: bool,
) -> Result<(Grid<f64>, Option<FloatSamples>), IoError> {
    let pixels = || raw.chunks_exact(channels).map(|px| &px[..3]);
    let not_finite = pixels()
        .filter(|px| px.iter().any(|v| !v.is_finite()))
        .count();
    if let Some(first) = pixels().position(|px| px.iter().any(|v| !v.is_finite())) {
        let column = first % width.max(1);
        let row = first / width.max(1);
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: format!(
                "{not_finite} of its pixels hold NaN or infinite values (the first at column \
                 {column}, row {row}): a photograph's values must be finite; mask them out and \
                 write them as 0"
            ),
        });
    }
    let mut negative_pixels = 0usize;
    let data = pixels()
        .map(|px| {
            negative_pixels += usize::from(px.iter().any(|&v| v < 0.0));
            let lin = |v: f32| {
                let v = f64::from(v).max(0.0);
                if srgb { srgb_to_linear(v) } else { v }
            };
            if px[0] == px[1] && px[1] == px[2] {
                // Grey: its own value, exactly.
                lin(px[0])
            } else {
                LUMA_709[0] * lin(px[0]) + LUMA_709[1] * lin(px[1]) + LUMA_709[2] * lin(px[2])
            }
        })
        .collect();
    let grid = Grid::from_vec(width, height, data).ok_or_else(|| IoError::BadImage {
        path: path.to_path_buf(),
        reason: format!(
            "the decoder gave {} samples for {width}x{height} pixels of {channels} channel(s)",
            raw.len()
        ),
    })?;
    let float = FloatSamples {
        negative_pixels,
        negative_share: negative_pixels as f64 / grid.len().max(1) as f64,
    };
    Ok((grid, Some(float)))
}

/// Reads a PNG, TIFF or JPEG (8-bit, 16-bit or float) as linear grey values.
///
/// Integer samples are divided by the maximum of their type (8-bit by 255,
/// 16-bit by 65535), so lie in [0, 1]. Float samples have no fixed white:
/// they are read on their own scale (nothing clamped at the top), a
/// negative sample as 0 ([`read_photo`] says how many), and NaN or infinite
/// samples are refused. When `srgb` is true every channel (grey included)
/// is first linearised with the sRGB transfer function. Colour is converted
/// to luminance with the Rec. 709 weights (0.2126, 0.7152, 0.0722) on the
/// linear channel values. Alpha is ignored. The format is recognised from
/// the content, falling back to the extension. Empty images are an error.
pub fn read_image(path: &Path, srgb: bool) -> Result<Grid<f64>, IoError> {
    let (image, float) = decode_image(path)?;
    Ok(image_to_grey(path, image, float, srgb)?.0)
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
    let (image, _) = decode_image(path)?;
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

/// A photograph as [`read_photo`] reads it.
#[derive(Clone, Debug)]
pub struct DecodedPhoto {
    /// Linear grey values: an integer image's on [0, 1] (value / its type's
    /// maximum), a float image's on its own scale (see [`read_image`]).
    pub image: Grid<f64>,
    /// Whether sRGB decoding was applied.
    pub srgb: bool,
    /// Why.
    pub srgb_reason: String,
    /// For a float image, what its samples held; `None` for integer
    /// samples.
    pub float: Option<FloatSamples>,
}

/// Reads a photograph as linear grey values (as [`read_image`]), upright
/// (its EXIF orientation applied), deciding the sRGB decoding by `mode`.
pub fn read_photo(path: &Path, mode: SrgbMode) -> Result<DecodedPhoto, IoError> {
    let (mut image, float) = decode_image(path)?;
    // Upright, as photo viewers show it (and as masks are drawn on it).
    if let Some(orientation) = exif_orientation(path) {
        image.apply_orientation(orientation);
    }
    let (srgb, srgb_reason) = decide_srgb(path, &image, mode);
    let (image, float) = image_to_grey(path, image, float, srgb)?;
    Ok(DecodedPhoto {
        image,
        srgb,
        srgb_reason,
        float,
    })
}

/// Reads a mask/confidence image as values in [0, 1]: grey value divided by
/// the maximum of its type, luminance (Rec. 709) for colour, never
/// sRGB-decoded; alpha is ignored. A float image's values are clamped to
/// [0, 1].
///
/// # Errors
/// Besides the reading errors, a mask with transparent pixels is refused:
/// its grey values are the mask, and a transparent pixel's grey says
/// nothing (a cut-out's alpha would be silently ignored).
pub fn read_mask(path: &Path) -> Result<Grid<f64>, IoError> {
    let (image, float) = decode_image(path)?;
    if image.color().has_alpha() && image.to_luma_alpha16().pixels().any(|p| p.0[1] < u16::MAX) {
        return Err(IoError::BadImage {
            path: path.to_path_buf(),
            reason: "it has transparent pixels, but a mask is read from its grey values (white = \
                     object, black = background): save the alpha as a grey image, or flatten it"
                .into(),
        });
    }
    let (grid, samples) = image_to_grey(path, image, float, false)?;
    Ok(match samples {
        Some(_) => grid.map(|v| v.clamp(0.0, 1.0)),
        None => grid,
    })
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
pub(super) fn quantise(v: f64, max: f64) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        (v.clamp(0.0, 1.0) * max).round()
    }
}

/// Writes a 16-bit linear grey PNG: values clamped to [0, 1], NaN as 0,
/// scaled by 65535 and rounded; marked linear (gAMA 1.0).
pub fn write_png16(path: &Path, image: &Grid<f64>) -> Result<(), IoError> {
    write_quantised_png(path, image, png::BitDepth::Sixteen)
}

/// Writes an 8-bit grey PNG of linear values: clamped to [0, 1], NaN as 0,
/// scaled by 255 and rounded; marked linear (gAMA 1.0), so that
/// `--srgb auto` does not decode it again.
pub fn write_png8(path: &Path, image: &Grid<f64>) -> Result<(), IoError> {
    write_quantised_png(path, image, png::BitDepth::Eight)
}

/// Writes `image` as a linear grey PNG of `depth` (8 or 16 bits), each
/// value quantised to the depth's maximum ([`quantise`]).
fn write_quantised_png(
    path: &Path,
    image: &Grid<f64>,
    depth: png::BitDepth,
) -> Result<(), IoError> {
    let values = image.as_slice().iter();
    let bytes: Vec<u8> = if depth == png::BitDepth::Sixteen {
        values
            .flat_map(|&v| (quantise(v, 65535.0) as u16).to_be_bytes())
            .collect()
    } else {
        values.map(|&v| quantise(v, 255.0) as u8).collect()
    };
    save_linear_png(path, image.width(), image.height(), depth, &bytes)
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

/// Writes an 8-bit RGB PNG of display colours (each channel in [0, 1],
/// clamped, NaN as 0; written as sRGB-encoded display values, e.g. a
/// normal map).
pub fn write_rgb_png8(path: &Path, image: &Grid<[f64; 3]>) -> Result<(), IoError> {
    let (w, h) = image_dims(path, image.width(), image.height())?;
    let data: Vec<u8> = image
        .as_slice()
        .iter()
        .flat_map(|rgb| rgb.map(|v| quantise(v, 255.0) as u8))
        .collect();
    let buffer = ImageBuffer::<image::Rgb<u8>, Vec<u8>>::from_raw(w, h, data)
        .ok_or_else(|| write_error(path, "internal error: pixel count does not match the size"))?;
    save_png(path, DynamicImage::ImageRgb8(buffer))
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

/// The nearest and farthest finite depth, as `depth16.png` maps them to
/// white and black (`None`: no finite depth).
pub fn depth_range(depth: &Grid<f64>) -> Option<(f64, f64)> {
    let mut range: Option<(f64, f64)> = None;
    for &z in depth.as_slice() {
        if z.is_finite() {
            range = Some(range.map_or((z, z), |(lo, hi)| (lo.min(z), hi.max(z))));
        }
    }
    range
}

/// Writes depth as a 16-bit PNG for viewing: 1 (white) at the nearest depth,
/// 0 at the farthest and off the object. Returns `(near, far)` or `None`
/// when no depth is finite.
pub fn write_depth_png16(path: &Path, depth: &Grid<f64>) -> Result<Option<(f64, f64)>, IoError> {
    let range = depth_range(depth);
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

#[cfg(test)]
mod tests {
    #[test]
    fn a_mask_with_transparent_pixels_is_refused_and_an_opaque_one_read() {
        let dir = tempdir().unwrap();
        let path = dir.path().join("mask.png");
        let mut rgba = image::RgbaImage::from_pixel(4, 3, image::Rgba([255, 255, 255, 255]));
        rgba.save(&path).unwrap();
        assert!(
            read_mask(&path)
                .unwrap()
                .as_slice()
                .iter()
                .all(|&v| v > 0.99)
        );
        rgba.put_pixel(1, 1, image::Rgba([255, 255, 255, 0]));
        rgba.save(&path).unwrap();
        let e = read_mask(&path).unwrap_err().to_string();
        assert!(e.contains("mask.png") && e.contains("transparent"), "{e}");
    }

    #[test]
    fn an_8_bit_png_this_tool_wrote_is_read_as_linear() {
        // synth's noisy8.png: gAMA 1.0 says linear; sRGB-decoding it
        // darkened the mid-tones and the noisy Sombrero came back with RSE
        // 0.42 instead of 0.015.
        let dir = tempdir().unwrap();
        let path = dir.path().join("noisy8.png");
        let image = Grid::from_fn(8, 6, |c, r| (c + r) as f64 / 20.0);
        write_png8(&path, &image).unwrap();
        let photo = read_photo(&path, SrgbMode::Auto).unwrap();
        assert!(!photo.srgb, "{}", photo.srgb_reason);
        for (a, b) in photo.image.as_slice().iter().zip(image.as_slice()) {
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
        assert!(!read_photo(&float_path, SrgbMode::Auto).unwrap().srgb);

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

    /// A float TIFF is read on its own scale (issue 48 item 11): nothing
    /// clamped at 1, a negative value read as 0 and counted, NaN and
    /// infinity refused naming the file; a float mask still reads on
    /// [0, 1].
    #[test]
    fn h5_float_tiffs_keep_their_scale_and_refuse_non_finite_values() {
        use tiff::encoder::{TiffEncoder, colortype};
        let dir = tempdir().unwrap();
        let write = |name: &str, values: &[f32]| {
            let path = dir.path().join(name);
            let mut encoder = TiffEncoder::new(fs::File::create(&path).unwrap()).unwrap();
            encoder
                .write_image::<colortype::Gray32Float>(2, 2, values)
                .unwrap();
            path
        };
        let path = write("hdr.tif", &[3.0, 0.001, -0.5, 1024.0]);
        let photo = read_photo(&path, SrgbMode::Auto).unwrap();
        assert_eq!(
            photo.image.as_slice(),
            &[3.0, f64::from(0.001f32), 0.0, 1024.0]
        );
        let float = photo.float.unwrap();
        assert_eq!((float.negative_pixels, float.negative_share), (1, 0.25));
        assert_eq!(
            read_mask(&path).unwrap().as_slice(),
            &[1.0, f64::from(0.001f32), 0.0, 1.0]
        );
        // Integer samples are not float ones.
        let png = dir.path().join("a.png");
        write_png16(&png, &ramp(2, 2)).unwrap();
        assert_eq!(read_photo(&png, SrgbMode::Auto).unwrap().float, None);

        for (name, bad) in [("inf.tif", f32::INFINITY), ("nan.tif", f32::NAN)] {
            let path = write(name, &[0.5, 0.5, 0.5, bad]);
            let e = read_photo(&path, SrgbMode::Auto).unwrap_err().to_string();
            assert!(
                e.contains(name) && e.contains("NaN or infinite") && e.contains("column 1, row 1"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_wrong_sample_count_is_an_error_not_a_black_image() {
        let path = Path::new("odd.png");
        let e = samples_to_grey(path, (3, 3, 1), &[0u8; 8], false, 255.0, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("odd.png") && e.contains("8 samples"), "{e}");
    }

    /// A photograph tagged "rotate 90 clockwise" (EXIF orientation 6) is read
    /// upright, as photo viewers show it, and its size is the upright one.
    #[test]
    fn an_exif_orientation_is_honoured() {
        let dir = std::env::temp_dir().join(format!("sfs-exif-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let path = dir.join("turned.png");
        // 3 wide, 2 high as stored: values 10..15 row by row.
        let stored: Vec<u8> = (10..16).collect();
        {
            let file = fs::File::create(&path).unwrap();
            let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), 3, 2);
            encoder.set_color(png::ColorType::Grayscale);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header().unwrap();
            // A big-endian TIFF header and one IFD entry: Orientation
            // (0x0112), SHORT, count 1, value 6.
            let exif: Vec<u8> = vec![
                b'M', b'M', 0, 42, 0, 0, 0, 8, 0, 1, 0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0, 0,
                0, 0, 0,
            ];
            writer
                .write_chunk(png::chunk::ChunkType(*b"eXIf"), &exif)
                .unwrap();
            writer.write_image_data(&stored).unwrap();
        }
        assert_eq!(
            exif_orientation(&path),
            Some(image::metadata::Orientation::Rotate90)
        );
        assert_eq!(image_size(&path).unwrap(), (3, 2));
        assert_eq!(photo_size(&path).unwrap(), (2, 3));
        let grid = read_photo(&path, SrgbMode::Off).unwrap().image;
        assert_eq!(grid.size(), (2, 3));
        // Turned a quarter clockwise: the stored bottom-left pixel (13) is
        // the top-left, the stored top-left (10) the top-right.
        let value = |c: usize, r: usize| (grid.at(c, r) * 255.0).round() as u8;
        assert_eq!((value(0, 0), value(1, 0)), (13, 10));
        assert_eq!((value(0, 2), value(1, 2)), (15, 12));
        let _ = fs::remove_dir_all(&dir);
    }
}
