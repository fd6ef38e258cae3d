//! The camera/scene file: intrinsics (with the image size they were
//! calibrated for, scaled to the image actually solved), the intensity scale
//! and the lights. Reads the project's own `scene.json` and near_ps-style
//! `calibration.json` files (`position_mm`, `direction`, `mu`,
//! `rgb_intensity`, `led`) alike.

use std::fs;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::camera::Intrinsics;
use crate::io::IoError;
use crate::light::PointLight;

/// Largest relative difference between the horizontal and vertical scale
/// factors for which a calibration is scaled to an image (beyond it the
/// image was cropped, not resized, and the intrinsics cannot follow).
pub const MAX_ASPECT_MISMATCH: f64 = 0.01;
/// Largest relative difference between a `K`'s fx and fy the model takes
/// (square pixels; their mean is used).
pub const MAX_FOCAL_MISMATCH: f64 = 0.01;

/// The names `units` may take: lengths at the scale of a camera set-up
/// (any case).
pub const LENGTH_UNITS: [&str; 16] = [
    "nm",
    "um",
    "µm",
    "micron",
    "mm",
    "millimetre",
    "millimeter",
    "cm",
    "centimetre",
    "centimeter",
    "m",
    "metre",
    "meter",
    "in",
    "inch",
    "ft",
];

/// One light as a camera file stores it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightEntry {
    /// Position in the camera frame (x right, y down, z forward), units of
    /// depth (`position_mm` in near_ps files).
    #[serde(alias = "position_mm")]
    pub position: [f64; 3],
    /// Principal direction (any length; normalised).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f64; 3]>,
    /// Anisotropy `mu >= 0` (0 isotropic).
    #[serde(default)]
    pub mu: f64,
    /// Relative intensity; `rgb_intensity` (its Rec. 709 luminance) is used
    /// when this is absent; 1 when both are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity: Option<f64>,
    /// Per-channel intensity of near_ps calibrations.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rgb_intensity: Option<[f64; 3]>,
    /// The LED's number, for `--light-index`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub led: Option<u32>,
    /// The image taken with this light alone (file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
}

impl LightEntry {
    /// The entry's relative intensity: `intensity`, else the luminance of
    /// `rgb_intensity`, else 1.
    pub fn relative_intensity(&self) -> f64 {
        match (self.intensity, self.rgb_intensity) {
            (Some(phi), _) => phi,
            (None, Some([r, g, b])) => 0.2126 * r + 0.7152 * g + 0.0722 * b,
            (None, None) => 1.0,
        }
    }

    /// The entry of `light` (its intensity taken as measured), numbered
    /// `led` and taking `image` (a file name), as `synth` writes them.
    pub fn of_light(light: &PointLight, led: Option<u32>, image: Option<String>) -> Self {
        Self {
            position: light.position,
            direction: light.direction,
            mu: light.mu,
            intensity: Some(light.intensity),
            rgb_intensity: None,
            led,
            image,
        }
    }

    /// The light of this entry (intensity as stored; not yet validated).
    pub fn light(&self) -> PointLight {
        PointLight {
            position: self.position,
            direction: self.direction,
            mu: self.mu,
            intensity: self.relative_intensity(),
        }
    }
}

/// The camera/scene file (`scene.json`, or a near_ps `calibration.json`).
///
/// Intrinsics are `focal`, `cx`, `cy` (pixels) or a 3x3 `K`, for an image of
/// `width` x `height` (alias `calibration_width` / `calibration_height`);
/// they are scaled to the image solved ([`CameraFile::intrinsics_for`]).
/// Unknown keys are rejected so that typos are caught.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Optional scene name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Width of the image the intrinsics are for, pixels.
    #[serde(alias = "calibration_width")]
    pub width: usize,
    /// Height of the image the intrinsics are for, pixels.
    #[serde(alias = "calibration_height")]
    pub height: usize,
    /// Focal length in pixels (or give `K`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focal: Option<f64>,
    /// Principal point column in pixels (0-based pixel centres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f64>,
    /// Principal point row in pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f64>,
    /// The intrinsic matrix `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]` instead
    /// of `focal`, `cx`, `cy` (`f = (fx + fy) / 2`).
    #[serde(rename = "K", default, skip_serializing_if = "Option::is_none")]
    pub k: Option<[[f64; 3]; 3]>,
    /// Intensity scale `s` (albedo times light power times camera gain);
    /// absent: estimated (`--intensity-scale auto`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity_scale: Option<f64>,
    /// Whether `intensity_scale` was measured (a render's truth, a
    /// radiometric calibration). With lights off the optical centre `s`
    /// decides the depth unit, and an unmeasured one (a placeholder 1.0) is
    /// treated as unknown; default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub intensity_scale_measured: bool,
    /// The surface's material, where known (a render's truth, written by
    /// `synth` for any but Lambert); `eval` measures with it. `solve` does
    /// not read it: the material to solve with is a parameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<crate::material::Material>,
    /// The unit of depth and of light positions (e.g. `mm`), for reports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<String>,
    /// The lights (empty: one light at the optical centre).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<LightEntry>,
    /// Provenance of a calibration (kept, not interpreted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration_source: Option<serde_json::Value>,
    /// Provenance of the data (kept, not interpreted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<serde_json::Value>,
}

impl CameraFile {
    /// A file for intrinsics `camera` of a `width` x `height` image.
    pub fn new(camera: Intrinsics, width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            focal: Some(camera.focal_px),
            cx: Some(camera.principal_x_px),
            cy: Some(camera.principal_y_px),
            ..Self::default()
        }
    }

    /// The intrinsics at the calibration's own size, `None` when neither
    /// `focal`/`cx`/`cy` nor `K` is complete.
    pub fn intrinsics(&self) -> Option<Intrinsics> {
        if let (Some(f), Some(cx), Some(cy)) = (self.focal, self.cx, self.cy) {
            return Some(Intrinsics {
                focal_px: f,
                principal_x_px: cx,
                principal_y_px: cy,
            });
        }
        self.k.map(|k| Intrinsics {
            focal_px: 0.5 * (k[0][0] + k[1][1]),
            principal_x_px: k[0][2],
            principal_y_px: k[1][2],
        })
    }

    /// The intrinsics for an image of `image_size` pixels: the calibration's
    /// own when the sizes agree, else scaled (`f` by the size ratio, the
    /// principal point as pixel-centre coordinates, `(c + 1/2) k - 1/2`).
    ///
    /// # Errors
    /// When the aspect ratios differ by more than [`MAX_ASPECT_MISMATCH`]
    /// (a crop, not a resize); the message names `path` and both sizes.
    pub fn intrinsics_for(
        &self,
        path: &Path,
        image_size: (usize, usize),
    ) -> Result<Intrinsics, IoError> {
        let bad = |reason: String| IoError::Camera {
            path: path.to_path_buf(),
            reason,
        };
        let own = self
            .intrinsics()
            .ok_or_else(|| bad("needs `focal`, `cx` and `cy`, or `K`".into()))?;
        if (self.width, self.height) == image_size {
            return Ok(own);
        }
        let kx = image_size.0 as f64 / self.width as f64;
        let ky = image_size.1 as f64 / self.height as f64;
        if ((kx - ky) / kx).abs() > MAX_ASPECT_MISMATCH {
            return Err(bad(format!(
                "is calibrated for {}x{} images; the image is {}x{}, a different aspect \
                 ratio (cropped?), so the intrinsics cannot be scaled to it",
                self.width, self.height, image_size.0, image_size.1
            )));
        }
        let k = 0.5 * (kx + ky);
        Ok(Intrinsics {
            focal_px: own.focal_px * k,
            principal_x_px: (own.principal_x_px + 0.5) * kx - 0.5,
            principal_y_px: (own.principal_y_px + 0.5) * ky - 0.5,
        })
    }

    /// Checks every value (a `K` the pinhole model cannot represent, a focal
    /// length below [`crate::camera::MIN_FOCAL_PER_SIDE`] of the longest side, duplicate
    /// LED numbers or image names); the error names the key and `path`.
    pub fn validate(&self, path: &Path) -> Result<(), IoError> {
        let bad = |reason: String| {
            Err(IoError::Camera {
                path: path.to_path_buf(),
                reason,
            })
        };
        if let Some(units) = &self.units
            && !LENGTH_UNITS.contains(&units.trim().to_lowercase().as_str())
        {
            return bad(format!(
                "`units` {units:?} is not a unit of length of a camera set-up: give one of {} (the \
                 unit of depth and of the lights' positions), or leave it out",
                LENGTH_UNITS.join(", ")
            ));
        }
        let has_focal = self.focal.is_some() || self.cx.is_some() || self.cy.is_some();
        if let Some(k) = self.k {
            // K is [[fx, skew, cx], [0, fy, cy], [0, 0, 1]]; the model is a
            // pinhole with square pixels and no skew.
            if has_focal {
                return bad(
                    "gives both `K` and `focal`/`cx`/`cy`: give one of them (they may disagree)"
                        .into(),
                );
            }
            if k.iter().flatten().any(|v| !v.is_finite()) {
                return bad("`K` must hold finite numbers".into());
            }
            let (fx, fy) = (k[0][0], k[1][1]);
            if !(fx > 0.0 && fy > 0.0) {
                return bad(format!(
                    "`K`: fx = K[0][0] and fy = K[1][1] must be positive, got {fx} and {fy}"
                ));
            }
            if (fx - fy).abs() > MAX_FOCAL_MISMATCH * fx.max(fy) {
                return bad(format!(
                    "`K`: fx = {fx} and fy = {fy} differ by more than {} %: the model has \
                     square pixels (resample the image to square pixels first)",
                    100.0 * MAX_FOCAL_MISMATCH
                ));
            }
            if k[0][1].abs() > 1e-9 * fx || k[1][0] != 0.0 || k[2][0] != 0.0 || k[2][1] != 0.0 {
                return bad(format!(
                    "`K`: skew K[0][1] = {} and the lower off-diagonal entries must be 0: the \
                     model has no skew",
                    k[0][1]
                ));
            }
            if (k[2][2] - 1.0).abs() > 1e-9 {
                return bad(format!(
                    "`K`: K[2][2] must be 1 (a normalised intrinsic matrix), got {}",
                    k[2][2]
                ));
            }
        }
        let Some(camera) = self.intrinsics() else {
            return bad("needs `focal`, `cx` and `cy`, or `K`".into());
        };
        let focal_key = if self.k.is_some() {
            "`K`'s fx, fy"
        } else {
            "`focal`"
        };
        if !(camera.focal_px.is_finite() && camera.focal_px > 0.0 && camera.focal_px < 1e9) {
            return bad(format!(
                "{focal_key} must be a positive number below 1e9 pixels, got {:?}",
                camera.focal_px
            ));
        }
        let smallest = crate::camera::MIN_FOCAL_PER_SIDE * self.width.max(self.height) as f64;
        if camera.focal_px < smallest {
            return bad(format!(
                "{focal_key} {:?} px is below {smallest} px ({} of the longest side of the \
                 {}x{} calibration): a field of view near 180 degrees the model cannot represent",
                camera.focal_px,
                crate::camera::MIN_FOCAL_PER_SIDE,
                self.width,
                self.height
            ));
        }
        // The principal point (and the focal length's upper bound) against
        // the calibration's size, as every solve checks them.
        if let Err(reason) = camera.check_for(self.width, self.height) {
            return bad(format!(
                "{reason}: the size of the file's `width` and `height`"
            ));
        }
        // Each LED number and image name once: a duplicate would silently
        // resolve to the first.
        for (a, first) in self.lights.iter().enumerate() {
            for (b, second) in self.lights.iter().enumerate().skip(a + 1) {
                if first.led.is_some() && first.led == second.led {
                    return bad(format!(
                        "`lights`: entries {} and {} both have `led` {}",
                        a + 1,
                        b + 1,
                        first.led.unwrap_or_default()
                    ));
                }
                if first.image.is_some() && first.image == second.image {
                    return bad(format!(
                        "`lights`: entries {} and {} both have `image` {:?}",
                        a + 1,
                        b + 1,
                        first.image.as_deref().unwrap_or_default()
                    ));
                }
            }
        }
        if let Some(s) = self.intensity_scale
            && !(s.is_finite()
                && (crate::params::INTENSITY_SCALE_RANGE.0
                    ..=crate::params::INTENSITY_SCALE_RANGE.1)
                    .contains(&s))
        {
            let (s_min, s_max) = crate::params::INTENSITY_SCALE_RANGE;
            return bad(format!(
                "`intensity_scale` must be a number in [{s_min:e}, {s_max:e}], got {s:e}"
            ));
        }
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 {
                return bad(format!("`{key}` must be at least 1, got 0"));
            }
        }
        for (k, entry) in self.lights.iter().enumerate() {
            if let Err(reason) = entry.light().validated(k + 1) {
                return bad(format!("`lights`: {reason}"));
            }
        }
        Ok(())
    }

    /// The lights switched on for an image: those whose `led` number is in
    /// `picks` (summed), else, with no picks, the one whose `image` is
    /// `image_name`, else every light when the file has one or its lights
    /// name no images (they are on together). Relative
    /// intensities are divided by their mean over the chosen lights, so one
    /// light has intensity 1 and `s` keeps its meaning. Returns the lights
    /// and a sentence saying which were chosen.
    ///
    /// # Errors
    /// A pick that matches no light, or several lights and no way to choose.
    pub fn lights_for(
        &self,
        path: &Path,
        picks: &[u32],
        image_name: Option<&str>,
    ) -> Result<(Vec<PointLight>, String), IoError> {
        let bad = |reason: String| IoError::Camera {
            path: path.to_path_buf(),
            reason,
        };
        let numbers = || {
            self.lights
                .iter()
                .enumerate()
                .map(|(k, e)| e.led.unwrap_or(k as u32 + 1).to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let chosen: Vec<(usize, &LightEntry)> = if !picks.is_empty() {
            let mut chosen = Vec::new();
            for &pick in picks {
                let found = self
                    .lights
                    .iter()
                    .enumerate()
                    .find(|(k, e)| e.led.unwrap_or(*k as u32 + 1) == pick)
                    .ok_or_else(|| {
                        bad(format!(
                            "no light numbered {pick} (the file has: {})",
                            numbers()
                        ))
                    })?;
                chosen.push(found);
            }
            chosen
        } else if let Some(found) = image_name.and_then(|name| {
            self.lights
                .iter()
                .enumerate()
                .find(|(_, e)| e.image.as_deref() == Some(name))
        }) {
            vec![found]
        } else if self.lights.len() <= 1 || self.lights.iter().all(|e| e.image.is_none()) {
            // One light, or lights not tied to images (a synthetic set-up):
            // all of them are on.
            self.lights.iter().enumerate().collect()
        } else {
            return Err(bad(format!(
                "has {} lights and none is marked as taking {}: pick with --light-index K \
                 (repeatable; lights on together are summed): {}",
                self.lights.len(),
                image_name.unwrap_or("this image"),
                numbers()
            )));
        };
        let mean = chosen
            .iter()
            .map(|(_, e)| e.relative_intensity())
            .sum::<f64>()
            / chosen.len().max(1) as f64;
        let mut lights = Vec::with_capacity(chosen.len());
        for (k, entry) in &chosen {
            let mut light = entry.light();
            if mean > 0.0 && mean.is_finite() {
                light.intensity /= mean;
            }
            lights.push(
                light
                    .validated(k + 1)
                    .map_err(|r| bad(format!("`lights`: {r}")))?,
            );
        }
        let units = self.units.as_deref().unwrap_or("depth units");
        let said = match chosen.as_slice() {
            [] => "one light at the optical centre".to_owned(),
            list => list
                .iter()
                .zip(&lights)
                .map(|((k, e), l)| {
                    let led = e.led.unwrap_or(*k as u32 + 1);
                    let (position, aim) = (l.position_text(), l.aim_text());
                    format!("light {led} at {position} {units}{aim}")
                })
                .collect::<Vec<_>>()
                .join("; "),
        };
        Ok((lights, said))
    }
}

/// Reads and validates ([`CameraFile::validate`]) a camera/scene file.
///
/// Missing keys, unknown keys and values of the wrong type are errors naming
/// the key and the file.
pub fn read_camera(path: &Path) -> Result<CameraFile, IoError> {
    let text = fs::read_to_string(path).map_err(|cause| IoError::Read {
        path: path.to_path_buf(),
        cause,
    })?;
    let camera: CameraFile = serde_json::from_str(&text).map_err(|e| IoError::Camera {
        path: path.to_path_buf(),
        reason: json_error_words(&text, &e),
    })?;
    camera.validate(path)?;
    Ok(camera)
}

/// Keys that are one key spelt two ways (serde aliases): serde calls both
/// given "duplicate field `width`", a field the file holds once.
const ALIASES: [(&str, &str); 3] = [
    ("width", "calibration_width"),
    ("height", "calibration_height"),
    ("position", "position_mm"),
];

/// A camera file's parse error in the user's terms: a file that is not a
/// JSON object ("expected a string" for a top-level array), and a key
/// given under both its spellings, are said as such; other errors are
/// serde's (which name the key).
fn json_error_words(text: &str, error: &serde_json::Error) -> String {
    let Ok(value) = serde_json::from_str::<serde_json::Value>(text) else {
        return error.to_string();
    };
    let kind = match &value {
        serde_json::Value::Object(_) => None,
        serde_json::Value::Array(_) => Some("an array"),
        serde_json::Value::String(_) => Some("a string"),
        serde_json::Value::Number(_) => Some("a number"),
        serde_json::Value::Bool(_) => Some("a boolean"),
        serde_json::Value::Null => Some("null"),
    };
    if let Some(kind) = kind {
        return format!(
            "a camera file is a JSON object ({{\"width\": ..., \"height\": ..., \"focal\": \
             ...}}), this one holds {kind}"
        );
    }
    let both = |object: &serde_json::Map<String, serde_json::Value>| {
        ALIASES
            .iter()
            .find(|(a, b)| object.contains_key(*a) && object.contains_key(*b))
    };
    let lights = value
        .get("lights")
        .and_then(serde_json::Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(serde_json::Value::as_object);
    let found = value
        .as_object()
        .and_then(both)
        .map(|pair| (pair, String::new()))
        .or_else(|| {
            lights
                .enumerate()
                .find_map(|(k, light)| both(light).map(|pair| (pair, format!("light {}: ", k + 1))))
        });
    match found {
        Some(((a, b), light)) => format!(
            "{light}`{a}` and `{b}` are the same key (two spellings of one value): give one"
        ),
        None => error.to_string(),
    }
}

/// Writes a camera/scene file as pretty JSON.
pub fn write_camera(path: &Path, camera: &CameraFile) -> Result<(), IoError> {
    crate::io::write_json(path, camera)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tempfile::tempdir;
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
    fn units_that_are_not_a_length_are_refused_naming_the_accepted_ones() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("scene.json");
        for (units, accepted) in [
            ("mm", true),
            ("Metre", true),
            ("parsecs", false),
            ("", false),
        ] {
            let file = CameraFile {
                units: Some(units.into()),
                ..camera()
            };
            write_camera(&p, &file).unwrap();
            match read_camera(&p) {
                Ok(read) => assert!(accepted, "{units:?} was taken: {read:?}"),
                Err(e) => {
                    let e = e.to_string();
                    assert!(!accepted, "{units:?} refused: {e}");
                    assert!(e.contains("`units`") && e.contains("mm, millimetre"), "{e}");
                }
            }
        }
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

    fn file(json: &str) -> CameraFile {
        let camera: CameraFile = serde_json::from_str(json).unwrap();
        camera.validate(Path::new("c.json")).unwrap();
        camera
    }

    #[test]
    fn intrinsics_scale_to_the_image_size() {
        let c = file(r#"{"width": 1296, "height": 864, "focal": 2000, "cx": 619, "cy": 449.5}"#);
        let same = c.intrinsics_for(Path::new("c.json"), (1296, 864)).unwrap();
        assert_eq!(same.focal_px, 2000.0);
        let half = c.intrinsics_for(Path::new("c.json"), (648, 432)).unwrap();
        assert!((half.focal_px - 1000.0).abs() < 1e-9);
        // Pixel-centre mapping: a 2x2 block's centre.
        assert!((half.principal_x_px - 309.25).abs() < 1e-9, "{half:?}");
        assert!((half.principal_y_px - 224.5).abs() < 1e-9, "{half:?}");
        let double = c.intrinsics_for(Path::new("c.json"), (2592, 1728)).unwrap();
        assert!((double.focal_px - 4000.0).abs() < 1e-9);
        let cropped = c.intrinsics_for(Path::new("c.json"), (1296, 700));
        let message = cropped.unwrap_err().to_string();
        assert!(
            message.contains("c.json") && message.contains("aspect"),
            "{message}"
        );
    }

    #[test]
    fn k_matrix_and_calibration_size_aliases() {
        // fx and fy within 1 % are averaged (square pixels).
        let c = file(
            r#"{"calibration_width": 100, "calibration_height": 50,
                "K": [[200.5, 0, 49.5], [0, 199.5, 24.5], [0, 0, 1]]}"#,
        );
        let k = c.intrinsics_for(Path::new("c.json"), (200, 100)).unwrap();
        assert!((k.focal_px - 400.0).abs() < 1e-9);
        assert!((k.principal_x_px - 99.5).abs() < 1e-9);
        // 10 % apart is refused, with the numbers.
        let apart: CameraFile = serde_json::from_str(
            r#"{"calibration_width": 100, "calibration_height": 50,
                "K": [[210, 0, 49.5], [0, 190, 24.5], [0, 0, 1]]}"#,
        )
        .unwrap();
        let e = apart.validate(Path::new("c.json")).unwrap_err().to_string();
        assert!(e.contains("fx = 210") && e.contains("fy = 190"), "{e}");
    }

    #[test]
    fn near_ps_lights_are_picked_by_number_or_image() {
        let c = file(
            r#"{"width": 10, "height": 10, "focal": 20, "cx": 4.5, "cy": 4.5, "units": "mm",
                "lights": [
                  {"led": 1, "image": "led1.png", "position_mm": [-200, 0, 500],
                   "direction": [1, 0, 0.2], "mu": 1.0, "rgb_intensity": [1, 2, 1]},
                  {"led": 4, "image": "led4.png", "position_mm": [20, -160, 390],
                   "direction": [0, 1, 1], "mu": 1.0, "rgb_intensity": [2, 4, 2]}
                ],
                "calibration_source": {"anything": 1}, "source": "x"}"#,
        );
        let p = Path::new("c.json");
        let (one, said) = c.lights_for(p, &[4], None).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].intensity, 1.0);
        assert_eq!(one[0].position, [20.0, -160.0, 390.0]);
        let d = one[0].direction.unwrap();
        assert!((d[1] - 0.5f64.sqrt()).abs() < 1e-12);
        assert!(said.contains("light 4"), "{said}");
        let (by_image, _) = c.lights_for(p, &[], Some("led1.png")).unwrap();
        assert_eq!(by_image[0].position[0], -200.0);
        let (both, _) = c.lights_for(p, &[1, 4], None).unwrap();
        // Relative intensities 1.8 and 3.6 (luminance), mean 1 after scaling.
        assert!((both[0].intensity - 2.0 / 3.0).abs() < 1e-9, "{both:?}");
        assert!((both[1].intensity - 4.0 / 3.0).abs() < 1e-9);
        let none = c
            .lights_for(p, &[], Some("other.png"))
            .unwrap_err()
            .to_string();
        assert!(
            none.contains("--light-index") && none.contains("1, 4"),
            "{none}"
        );
        let missing = c.lights_for(p, &[5], None).unwrap_err().to_string();
        assert!(missing.contains("no light numbered 5"), "{missing}");
    }

    /// Both spellings of one key said "duplicate field `width`"; a
    /// top-level array said "expected a string".
    #[test]
    fn aliases_given_twice_and_non_objects_are_said_plainly() {
        let dir = tempdir().unwrap();
        let read = |name: &str, text: &str| {
            let path = dir.path().join(name);
            fs::write(&path, text).unwrap();
            read_camera(&path).unwrap_err().to_string()
        };
        let both = read(
            "both.json",
            r#"{"width": 64, "calibration_width": 64, "height": 48, "focal": 80}"#,
        );
        assert!(
            both.contains("`width` and `calibration_width` are the same key")
                && both.contains("give one"),
            "{both}"
        );
        let light = read(
            "light.json",
            r#"{"width": 64, "height": 48, "focal": 80,
                "lights": [{"position": [0, 0, 0], "position_mm": [0, 0, 0]}]}"#,
        );
        assert!(
            light.contains("light 1: `position` and `position_mm`"),
            "{light}"
        );
        let array = read("array.json", r#"[{"width": 64}]"#);
        assert!(
            array.contains("a camera file is a JSON object") && array.contains("an array"),
            "{array}"
        );
        let typo = read(
            "typo.json",
            r#"{"width": 1, "height": 1, "focal": 1, "foacl": 2}"#,
        );
        assert!(typo.contains("foacl"), "{typo}");
    }

    #[test]
    fn bad_lights_and_typos_are_named() {
        let typo: Result<CameraFile, _> = serde_json::from_str(
            r#"{"width": 1, "height": 1, "focal": 1, "cx": 0, "cy": 0, "foacl": 2}"#,
        );
        assert!(typo.unwrap_err().to_string().contains("foacl"));
        let c: CameraFile = serde_json::from_str(
            r#"{"width": 1, "height": 1, "focal": 1, "cx": 0, "cy": 0,
                "lights": [{"position": [0, 0, 0], "mu": -2}]}"#,
        )
        .unwrap();
        let e = c.validate(Path::new("c.json")).unwrap_err().to_string();
        assert!(e.contains("mu"), "{e}");
    }
}
