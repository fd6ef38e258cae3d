//! The masks on disk: a layer saved to or loaded from a PNG, the crash-safe
//! autosave of both layers and its restore, and the autosave folder of an
//! image (named by a fixed hash of its path). Mask files are read and
//! size-checked by the core's one mask reader, `sfs_core::photo::read_mask_at`.

use std::fs;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};
use sfs_core::io::{self, IoError};

use super::masks::Masks;
use super::rect::whole;
use super::types::{Layer, MaskError};
use super::undo::{Change, region_edit};

/// File names inside an autosave folder.
const AUTOSAVE_JSON: &str = "autosave.json";
const AUTOSAVE_CONFIDENCE: &str = "confidence.png";
const AUTOSAVE_OBJECT: &str = "object.png";
const AUTOSAVE_FORMAT: u32 = 1;

/// Contents of `autosave.json`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AutosaveInfo {
    format: u32,
    image: String,
    width: usize,
    height: usize,
    saved_unix_s: u64,
}

impl Masks {
    /// Saves `layer` as an 8-bit grey PNG (confidence `round(255 c)`, object
    /// 255 / background 0), written to a temporary file then renamed.
    pub fn save_png(&self, layer: Layer, path: &Path) -> Result<(), MaskError> {
        match layer {
            Layer::Confidence => {
                let values = self.confidence.map(|&v| f64::from(v));
                write_atomic(path, |p| io::write_png8(p, &values))
            }
            Layer::Object => write_atomic(path, |p| io::write_mask_png(p, &self.object)),
        }
    }

    /// Loads `layer` from an image read by `sfs_core::io::read_mask`
    /// (PNG/TIFF/JPEG, 8- or 16-bit, colour as Rec. 709 luminance, alpha
    /// ignored): confidence takes the value in [0, 1], object is
    /// `value >= 0.5`. The image is of the masks' size, or of the
    /// photograph's own size `photo_size` (area-averaged to the masks'
    /// size), read by the photo pipeline's one mask reader; another size is
    /// an error naming the file and the sizes; any error leaves the masks
    /// unchanged. A load that changes something is one undo step; returns
    /// whether it did.
    pub fn load_png(
        &mut self,
        layer: Layer,
        path: &Path,
        photo_size: (usize, usize),
    ) -> Result<bool, MaskError> {
        let what = match layer {
            Layer::Confidence => "confidence",
            Layer::Object => "mask",
        };
        let values = sfs_core::photo::read_mask_at(path, what, photo_size, self.size())?;
        self.end_stroke();
        let rect = whole(&values);
        let change = match layer {
            Layer::Confidence => region_edit(&mut self.confidence, rect, |c, r, _| {
                *values.at(c, r) as f32
            })
            .map(Change::Confidence),
            Layer::Object => region_edit(&mut self.object, rect, |c, r, _| *values.at(c, r) >= 0.5)
                .map(Change::Object),
        };
        Ok(self.record(change))
    }

    /// Writes both layers (confidence as 16-bit grey for near-exact restore,
    /// object as 8-bit) and `autosave.json` (image path, size, Unix time)
    /// into `dir`, creating it; each file is written to a temporary file in
    /// `dir` and renamed, so a crash never leaves a half-written file.
    pub fn autosave(&self, dir: &Path, image_path: &Path) -> Result<(), MaskError> {
        let create_error = |cause| IoError::CreateDir {
            path: dir.to_path_buf(),
            cause,
        };
        fs::create_dir_all(dir).map_err(create_error)?;
        let confidence = self.confidence.map(|&v| f64::from(v));
        write_atomic(&dir.join(AUTOSAVE_CONFIDENCE), |p| {
            io::write_png16(p, &confidence)
        })?;
        write_atomic(&dir.join(AUTOSAVE_OBJECT), |p| {
            io::write_mask_png(p, &self.object)
        })?;
        let ((width, height), now) = (self.size(), SystemTime::now());
        let info = AutosaveInfo {
            format: AUTOSAVE_FORMAT,
            image: image_path.display().to_string(),
            width,
            height,
            saved_unix_s: now.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs()),
        };
        write_atomic(&dir.join(AUTOSAVE_JSON), |p| io::write_json(p, &info))
    }

    /// Restores masks autosaved in `dir` for an image of `expected_size`,
    /// with an empty history. `Ok(None)` when `dir` holds no autosave; an
    /// error when its files are corrupt, missing or of another size.
    pub fn restore(dir: &Path, expected_size: (usize, usize)) -> Result<Option<Self>, MaskError> {
        let json = dir.join(AUTOSAVE_JSON);
        let text = match fs::read_to_string(&json) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(cause) => return Err(IoError::Read { path: json, cause }.into()),
        };
        let corrupt = |reason: String| MaskError::Autosave {
            path: json.clone(),
            reason,
        };
        let info: AutosaveInfo = serde_json::from_str(&text).map_err(|e| corrupt(e.to_string()))?;
        if info.format != AUTOSAVE_FORMAT {
            return Err(corrupt(format!("unknown format {}", info.format)));
        }
        let ((w, h), saved) = (expected_size, (info.width, info.height));
        if saved != expected_size {
            let reason = format!(
                "saved for a {}x{} image but the image is {w}x{h}",
                saved.0, saved.1
            );
            return Err(corrupt(reason));
        }
        let read = |name: &str| {
            sfs_core::photo::read_mask_at(&dir.join(name), "autosave", expected_size, expected_size)
        };
        let confidence = read(AUTOSAVE_CONFIDENCE)?;
        let object = read(AUTOSAVE_OBJECT)?;
        Self::from_layers(confidence.map(|&v| v as f32), object.map(|&v| v >= 0.5)).map(Some)
    }
}

/// [`io::write_atomic`], its failure as a mask error.
fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), IoError>,
) -> Result<(), MaskError> {
    Ok(io::write_atomic(path, write)?)
}

/// 64-bit FNV-1a: a fixed hash, stable across Rust versions and platforms.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    hash
}

/// The autosave folder of `image_path`:
/// `DATA_DIR/autosave/STEM-HASH`, where HASH is the 64-bit FNV-1a (hex) of
/// the image's canonical absolute path (its absolute path when it cannot be
/// canonicalised, e.g. because it no longer exists) and STEM the file stem
/// reduced to at most 32 ASCII letters, digits, `-` and `_` (`image` if
/// none is left). Remove the folder to discard an autosave.
pub fn autosave_dir(image_path: &Path, data_dir: &Path) -> PathBuf {
    let absolute = fs::canonicalize(image_path)
        .or_else(|_| std::path::absolute(image_path))
        .unwrap_or_else(|_| image_path.to_path_buf());
    let hash = fnv1a64(absolute.as_os_str().as_encoded_bytes());
    let stem = absolute.file_stem().unwrap_or_default().to_string_lossy();
    let allowed = |c: &char| c.is_ascii_alphanumeric() || *c == '-' || *c == '_';
    let mut stem: String = stem.chars().filter(allowed).take(32).collect();
    if stem.is_empty() {
        stem = "image".into();
    }
    data_dir
        .join("autosave")
        .join(format!("{stem}-{hash:016x}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask_edit::Mode;
    use crate::mask_edit::test_support::*;
    use tempfile::tempdir;

    /// 20x12 masks with one confidence stroke across them.
    fn confidence_stroked() -> Masks {
        let mut m = Masks::new(20, 12);
        stroke(
            &mut m,
            Layer::Confidence,
            brush(5.0, 0.3, Mode::Paint),
            &[[4.0, 4.0], [15.0, 8.0]],
        );
        m
    }

    /// Asserts that the confidence of `a` and of `b` differ by at most
    /// `tolerance` at every pixel (what a file's quantisation allows).
    fn assert_confidence_within(a: &Masks, b: &Masks, tolerance: f32) {
        for (a, b) in a
            .confidence()
            .as_slice()
            .iter()
            .zip(b.confidence().as_slice())
        {
            assert!((a - b).abs() <= tolerance, "{a} {b}");
        }
    }

    #[test]
    fn png_round_trip_and_wrong_size_load() {
        let dir = tempdir().unwrap();
        let (cp, op) = (dir.path().join("conf.png"), dir.path().join("obj.png"));
        let mut m = confidence_stroked();
        stroke(
            &mut m,
            Layer::Object,
            brush(3.0, 1.0, Mode::Paint),
            &[[10.0, 2.0], [10.0, 10.0]],
        );
        m.save_png(Layer::Confidence, &cp).unwrap();
        m.save_png(Layer::Object, &op).unwrap();
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);

        let mut n = Masks::new(20, 12);
        assert!(n.load_png(Layer::Confidence, &cp, n.size()).unwrap());
        assert!(n.load_png(Layer::Object, &op, n.size()).unwrap());
        assert_eq!(n.object(), m.object());
        assert_confidence_within(&n, &m, 0.5 / 255.0 + 1e-6);
        assert!(n.undo() && n.undo());
        assert_eq!(state(&n), state(&Masks::new(20, 12)));

        let mut wrong = Masks::new(21, 12);
        wrong.fill_rect(Layer::Object, Mode::Paint, [0.0, 0.0], [3.0, 3.0]);
        let (before, revision) = (state(&wrong), wrong.revision());
        let e = wrong
            .load_png(Layer::Object, &op, wrong.size())
            .unwrap_err()
            .to_string();
        let op_name = op.display().to_string();
        assert!(
            e.contains(&op_name) && e.contains("20x12") && e.contains("21x12"),
            "{e}"
        );
        assert_eq!((state(&wrong), wrong.revision()), (before, revision));
        assert!(wrong.undo() && !wrong.undo());
        let e = n
            .load_png(Layer::Object, &dir.path().join("missing.png"), n.size())
            .unwrap_err();
        assert!(e.to_string().contains("missing.png"), "{e}");
    }

    #[test]
    fn autosave_round_trip_missing_and_corrupt() {
        let data = tempdir().unwrap();
        let image = data.path().join("vase.png");
        fs::write(&image, "x").unwrap();
        let dir = autosave_dir(&image, data.path());
        assert!(Masks::restore(&dir, (20, 12)).unwrap().is_none());

        let mut m = confidence_stroked();
        m.fill_rect(Layer::Object, Mode::Paint, [0.0, 0.0], [6.0, 12.0]);
        m.autosave(&dir, &image).unwrap();
        m.autosave(&dir, &image).unwrap();
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 3);
        let json = fs::read_to_string(dir.join(AUTOSAVE_JSON)).unwrap();
        assert!(
            json.contains("vase.png") && json.contains("\"width\": 20"),
            "{json}"
        );

        let r = Masks::restore(&dir, (20, 12)).unwrap().unwrap();
        assert_eq!(r.object(), m.object());
        assert_confidence_within(&r, &m, 1.0 / 65535.0);
        assert!(!r.can_undo());

        let e = Masks::restore(&dir, (21, 12)).unwrap_err().to_string();
        assert!(e.contains("20x12") && e.contains("21x12"), "{e}");
        fs::write(dir.join(AUTOSAVE_OBJECT), "garbage").unwrap();
        let e = Masks::restore(&dir, (20, 12)).unwrap_err().to_string();
        assert!(e.contains(AUTOSAVE_OBJECT), "{e}");
        fs::write(dir.join(AUTOSAVE_JSON), "{\"format\": 1").unwrap();
        let e = Masks::restore(&dir, (20, 12)).unwrap_err().to_string();
        assert!(e.contains(AUTOSAVE_JSON), "{e}");
    }

    #[test]
    fn autosave_dir_is_stable_and_distinct() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
        let data = tempdir().unwrap();
        let (a, b) = (data.path().join("a b.png"), data.path().join("b.png"));
        fs::write(&a, "x").unwrap();
        fs::write(&b, "x").unwrap();
        let dir = autosave_dir(&a, data.path());
        assert_eq!(
            dir,
            autosave_dir(&data.path().join(".").join("a b.png"), data.path())
        );
        assert_ne!(dir, autosave_dir(&b, data.path()));
        assert!(dir.starts_with(data.path().join("autosave")));
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("ab-") && name.len() == 3 + 16, "{name}");
    }
}
