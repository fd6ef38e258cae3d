//! The options of one photograph's solve as a user gives them (the command
//! line's `solve`, Python's keywords), turned into the photo pipeline's
//! input, the solver's parameters and a checked [`PhotographSolve`] once
//! for every front. Each refusal names the option in the command line's
//! words (`--albedo 0: is neither one of its words nor an existing file`).
//! The fronts only read their own syntax into a [`SolveOptions`].
//!
//! Uses: `photo` (the pipeline's input), `params` (the table and its
//! checks), `light`, `io` (the initial depth map), `solver` (the method and
//! the pyramid's size), the parent module.

use std::path::{Path, PathBuf};

use super::{KnownDistance, PhotographSolve, shown};
use crate::io::{self, SrgbMode};
use crate::light::PointLight;
use crate::params::given::params_from_given;
use crate::params::photometric::{PS_ROBUST_SCALE, PS_SMOOTHNESS};
use crate::params::{AlbedoChoice, InitialDepth, ParamError, ParamSpec, SolverParams};
use crate::photo::{CameraSpec, LightSpec, PhotoInput, PreparedPhoto, ScaleSpec, Vignetting};
use crate::solver::photometric::PhotometricParams;
use crate::solver::{self, Method};

/// The default working size of a solve (longest side, pixels): 1920x1080
/// solves at full size, an 18 MP photograph at 2000x1333.
pub const DEFAULT_MAX_SIDE: usize = 2000;

/// Why options are refused: a message naming the option as the command
/// line spells it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct OptionError(pub String);

impl From<ParamError> for OptionError {
    fn from(e: ParamError) -> Self {
        Self(e.to_string())
    }
}

impl From<String> for OptionError {
    fn from(e: String) -> Self {
        Self(e)
    }
}

/// One photograph's solve as the user asked for it, each field an option
/// of `sfs-studio solve` (`--max-side` is `max_side`), as typed where the
/// core reads words or files.
#[derive(Clone, Debug)]
pub struct SolveOptions {
    /// `--camera`: a camera file (scene.json or a near_ps calibration).
    pub camera_file: Option<PathBuf>,
    /// `--focal`: the focal length in pixels of the photograph as given.
    pub focal_px: Option<f64>,
    /// `--cx`: the principal point's column, pixels.
    pub cx_px: Option<f64>,
    /// `--cy`: the principal point's row, pixels.
    pub cy_px: Option<f64>,
    /// `--intensity-scale`: a number or `auto`; `None`: the camera file's.
    pub intensity_scale: Option<String>,
    /// `--known-depth X,Y,Z`: pixels of the photograph as given and their
    /// distances.
    pub known_depth: Vec<[f64; 3]>,
    /// `--distance`: the object's median depth.
    pub distance: Option<f64>,
    /// `--light` and its companions, built by
    /// [`crate::light::lights_from_options`]; `None`: the camera file's.
    pub lights: Option<Vec<PointLight>>,
    /// `--light-index`: the camera file's lights that are on.
    pub light_index: Vec<u32>,
    /// `--mask`: the object mask.
    pub mask: Option<PathBuf>,
    /// `--confidence`: a confidence image in [0, 1].
    pub confidence: Option<PathBuf>,
    /// `--auto-confidence`.
    pub auto_confidence: bool,
    /// `--srgb`.
    pub srgb: SrgbMode,
    /// `--ambient`: a frame with every light off.
    pub ambient: Option<PathBuf>,
    /// `--vignetting`: `cos4`, `none` or a flat-field image.
    pub vignetting: Option<String>,
    /// `--albedo`: `auto`, `1` or a file.
    pub albedo: String,
    /// `--max-side`: the working size's longest side; 0: the full size.
    pub max_side: usize,
    /// `--init-depth`: a method, a number or a `.npy` of the working size.
    pub init_depth: Option<String>,
    /// `--method`.
    pub method: Method,
    /// The parameter table's options given, as typed.
    pub table: Vec<(&'static ParamSpec, String)>,
}

impl Default for SolveOptions {
    /// `sfs-studio solve` with no option.
    fn default() -> Self {
        Self {
            camera_file: None,
            focal_px: None,
            cx_px: None,
            cy_px: None,
            intensity_scale: None,
            known_depth: Vec::new(),
            distance: None,
            lights: None,
            light_index: Vec::new(),
            mask: None,
            confidence: None,
            auto_confidence: false,
            srgb: SrgbMode::Auto,
            ambient: None,
            vignetting: None,
            albedo: "auto".into(),
            max_side: DEFAULT_MAX_SIDE,
            init_depth: None,
            method: Method::Linearised,
            table: Vec::new(),
        }
    }
}

/// `--srgb WORD`: `on`, `off` or `auto` (also `true`/`false`).
pub fn srgb_mode(text: &str) -> Result<SrgbMode, OptionError> {
    match text.to_ascii_lowercase().as_str() {
        "auto" => Ok(SrgbMode::Auto),
        "on" | "true" => Ok(SrgbMode::On),
        "off" | "false" => Ok(SrgbMode::Off),
        other => Err(OptionError(format!(
            "--srgb {other}: expected on, off or auto"
        ))),
    }
}

/// `--method WORD`: `linearised`, `explicit` or `fast-marching`.
pub fn method(text: &str) -> Result<Method, OptionError> {
    match text.replace('_', "-").as_str() {
        "linearised" => Ok(Method::Linearised),
        "explicit" => Ok(Method::Explicit(solver::ExplicitParams::default())),
        "fast-marching" => Ok(Method::FastMarching(solver::FastMarchingParams::default())),
        other => Err(OptionError(format!(
            "--method {other}: expected linearised, explicit or fast-marching"
        ))),
    }
}

/// A photometric-stereo set's settings from `--ps-smoothness` and
/// `--ps-robust-scale` (each `auto` or a number under the table's rule,
/// [`crate::params::PS_PARAMS`]) and `--ps-no-cast-shadows`.
pub fn photometric_params(
    smoothness: &str,
    robust_scale: &str,
    no_cast_shadows: bool,
) -> Result<PhotometricParams, OptionError> {
    Ok(PhotometricParams {
        alpha: PS_SMOOTHNESS.read_option(smoothness)?,
        robust_scale: PS_ROBUST_SCALE.read_option(robust_scale)?,
        cast_shadows: !no_cast_shadows,
        ..PhotometricParams::default()
    })
}

/// `--NAME TEXT`: `file` must exist, else the error lists what is
/// `accepted`.
fn check_word_or_file(
    name: &str,
    text: &str,
    file: &Path,
    accepted: &str,
) -> Result<(), OptionError> {
    if file.is_file() {
        return Ok(());
    }
    let what = if file.exists() {
        "is not a file"
    } else {
        "is neither one of its words nor an existing file"
    };
    Err(OptionError(format!(
        "--{name} {text}: {what}; accepted: {accepted}"
    )))
}

impl SolveOptions {
    /// The parameter table's options given, checked (before the working
    /// size is known; the initial depth at its default).
    pub fn table_params(&self) -> Result<SolverParams, OptionError> {
        Ok(params_from_given(&self.table)?)
    }

    /// `--albedo FILE`: the map the pipeline divides out (`None` for
    /// `auto` and `1`).
    pub fn albedo_file(&self) -> Option<PathBuf> {
        let text = self.albedo.trim();
        (!(text.eq_ignore_ascii_case("auto") || text == "1")).then(|| PathBuf::from(text))
    }

    /// How the solver takes the albedo: estimated for `auto`, else 1 (a
    /// given map is already divided out).
    pub fn albedo_choice(&self) -> AlbedoChoice {
        if self.albedo.trim().eq_ignore_ascii_case("auto") {
            AlbedoChoice::Auto
        } else {
            AlbedoChoice::One
        }
    }

    /// The known distances as the solve takes them.
    pub fn known_distances(&self) -> Vec<KnownDistance> {
        self.known_depth
            .iter()
            .map(|&[column_px, row_px, depth]| KnownDistance {
                column_px,
                row_px,
                depth,
            })
            .collect()
    }

    /// Refuses what the options say together, before any pixel is read:
    /// the camera given twice, lights given and picked, a light picked
    /// twice, words that are neither a word nor a file, `--albedo-edge`
    /// without `--albedo auto`, a distance that is not one, and two ways
    /// to set the depth unit.
    pub fn check(&self) -> Result<(), OptionError> {
        if self.camera_file.is_some() && self.focal_px.is_some() {
            return Err(OptionError(
                "--camera and --focal both give the intrinsics: give one".into(),
            ));
        }
        if self.lights.is_some() && !self.light_index.is_empty() {
            return Err(OptionError(
                "give either --light X,Y,Z or --light-index K (a camera file's lights)".into(),
            ));
        }
        let picks = &self.light_index;
        if let Some(twice) = picks
            .iter()
            .enumerate()
            .find_map(|(k, i)| picks[..k].contains(i).then_some(*i))
        {
            return Err(OptionError(format!(
                "--light-index {twice} is given twice: each LED is on once (give each number \
                 once)"
            )));
        }
        if let Some(file) = self.albedo_file() {
            check_word_or_file(
                "albedo",
                &self.albedo,
                &file,
                "`auto`, `1` or FILE (an image, or a .npy such as the albedo.npy a solve writes)",
            )?;
        }
        if let Some(text) = &self.vignetting
            && !matches!(text.as_str(), "none" | "cos4")
        {
            check_word_or_file(
                "vignetting",
                text,
                Path::new(text),
                "`cos4`, `none` or FILE (a flat-field image)",
            )?;
        }
        if self.albedo_choice() != AlbedoChoice::Auto
            && self
                .table
                .iter()
                .any(|(spec, _)| spec.name == "albedo-edge")
        {
            return Err(OptionError(format!(
                "--albedo-edge belongs to --albedo auto (the estimated albedo's prior); with \
                 --albedo {} no albedo is estimated, so it would change nothing",
                self.albedo
            )));
        }
        Ok(())
    }

    /// Refuses a distance that is not one, and a distance with a given
    /// intensity scale (both set the depth unit).
    fn check_distances(&self) -> Result<(), OptionError> {
        if let Some(distance) = self.distance
            && !(distance.is_finite() && distance > 0.0)
        {
            return Err(OptionError(format!(
                "--distance {distance}: must be a positive distance (the camera file's unit)"
            )));
        }
        if (!self.known_depth.is_empty() || self.distance.is_some())
            && let Some(given) = &self.intensity_scale
            && given != "auto"
        {
            return Err(OptionError(format!(
                "--{} and --intensity-scale {given} both set the depth unit: give one (a \
                 distance searches the intensity scale)",
                if self.known_depth.is_empty() {
                    "distance"
                } else {
                    "known-depth"
                }
            )));
        }
        Ok(())
    }

    /// The photo pipeline's input for `images` (the photographs given, or
    /// those of a folder), checked ([`Self::check`]).
    pub fn photo_input(&self, images: &[PathBuf]) -> Result<PhotoInput, OptionError> {
        self.check()?;
        let camera = match (&self.camera_file, self.focal_px) {
            (Some(path), _) => CameraSpec::File(path.clone()),
            (None, Some(focal_px)) => CameraSpec::Focal {
                focal_px,
                cx_px: self.cx_px,
                cy_px: self.cy_px,
            },
            (None, None) => CameraSpec::Exif { guess: false },
        };
        let lights = match &self.lights {
            Some(lights) => LightSpec::Given(lights.clone()),
            None => LightSpec::CameraFile {
                picks: self.light_index.clone(),
            },
        };
        let intensity_scale = match self.intensity_scale.as_deref() {
            None => ScaleSpec::FromCamera,
            Some(text) if text.eq_ignore_ascii_case("auto") => ScaleSpec::Auto,
            Some(text) => ScaleSpec::Given(text.parse().map_err(|_| {
                OptionError(format!("--intensity-scale {text}: not a number or `auto`"))
            })?),
        };
        // The table's parameters (eta, min-level-side) size the pyramid.
        let table_params = self.table_params()?;
        let max_side = (self.max_side > 0).then_some(self.max_side);
        let full = images.first().and_then(|p| io::photo_size(p).ok());
        let pyramid_factor = full.map_or(crate::memory::DEFAULT_PYRAMID_FACTOR, |(w, h)| {
            let (w, h) = crate::resample::working_size(w, h, max_side);
            solver::pyramid::pyramid_factor(w, h, table_params.eta, table_params.min_level_side)
        });
        Ok(PhotoInput {
            images: images.to_vec(),
            srgb: self.srgb,
            camera,
            lights,
            intensity_scale,
            object_mask: self.mask.clone(),
            confidence: self.confidence.clone(),
            auto_confidence: self.auto_confidence,
            ambient: self.ambient.clone(),
            vignetting: Vignetting::from_option(self.vignetting.as_deref()),
            albedo: self.albedo_file(),
            max_side,
            pyramid_factor,
            max_side_setting: "--max-side".into(),
            photometric_stereo: false,
            given_intensities: false,
            photo_confidence: Vec::new(),
        })
    }

    /// The solver's parameters for the working size `image_size` (the
    /// initial depth map, if one is given, must have that size).
    pub fn params(&self, image_size: (usize, usize)) -> Result<SolverParams, OptionError> {
        let mut params = self.table_params()?;
        params.initial_depth = initial_depth(self.init_depth.as_deref(), image_size)?;
        params.albedo = self.albedo_choice();
        Ok(params)
    }

    /// The solve of `prepared` (taken: its image moves into the job) these
    /// options ask for, refused where it cannot run: a photograph too dark
    /// to solve (`cannot solve FILE: why`), a known distance off the
    /// photograph or the object, a distance that is not one, two ways to
    /// set the depth unit.
    pub fn job(&self, prepared: PreparedPhoto) -> Result<PhotographSolve, OptionError> {
        let params = self.params(prepared.size())?;
        let mut job = PhotographSolve::from_prepared(prepared, params, self.method.clone());
        job.initial_depth_given = Some(
            self.init_depth
                .clone()
                .unwrap_or_else(|| "fast-marching".into()),
        );
        job.known_distances = self.known_distances();
        job.distance = self.distance;
        if let Some(reason) = job.refusal() {
            let first = job
                .photo
                .images
                .first()
                .map_or_else(String::new, |p| p.display().to_string());
            return Err(OptionError(format!("cannot solve {first}: {reason}")));
        }
        // The distances given, checked where the user gave them (the pixel
        // of the photograph as given).
        for point in &job.known_distances {
            if let Err(e) = job.known_depth(point) {
                return Err(OptionError(format!(
                    "--known-depth {},{},{}: {e}",
                    point.column_px,
                    point.row_px,
                    shown(point.depth)
                )));
            }
        }
        self.check_distances()?;
        Ok(job)
    }
}

/// `--init-depth`: a method, a number or a `.npy` file of the working
/// size; `None`: fast marching.
pub fn initial_depth(
    text: Option<&str>,
    image_size: (usize, usize),
) -> Result<InitialDepth, OptionError> {
    let Some(text) = text else {
        return Ok(InitialDepth::FastMarching);
    };
    if text.eq_ignore_ascii_case("fast-marching") {
        return Ok(InitialDepth::FastMarching);
    }
    if text.eq_ignore_ascii_case("from-image") {
        return Ok(InitialDepth::FromImage);
    }
    if let Ok(z) = text.parse::<f64>() {
        return Ok(InitialDepth::Constant(z));
    }
    let map = io::read_npy(Path::new(text)).map_err(|e| {
        OptionError(format!(
            "--init-depth {text}: not a method, a number or a readable .npy: {e}"
        ))
    })?;
    if map.size() != image_size {
        return Err(OptionError(format!(
            "--init-depth {text} is {}x{} but the image is {}x{}",
            map.width(),
            map.height(),
            image_size.0,
            image_size.1
        )));
    }
    Ok(InitialDepth::Map(map))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The message `options` are refused with by `check`.
    fn refused(options: SolveOptions) -> String {
        options.check().expect_err("refused").0
    }

    /// The options' own contradictions are refused by name before any
    /// file is read.
    #[test]
    fn contradictions_are_refused_by_name() {
        let both = refused(SolveOptions {
            camera_file: Some("scene.json".into()),
            focal_px: Some(500.0),
            ..SolveOptions::default()
        });
        assert!(both.contains("--camera and --focal"), "{both}");
        let twice = refused(SolveOptions {
            light_index: vec![2, 3, 2],
            ..SolveOptions::default()
        });
        assert!(twice.contains("--light-index 2 is given twice"), "{twice}");
        let word = refused(SolveOptions {
            albedo: "0".into(),
            ..SolveOptions::default()
        });
        assert!(
            word.contains("--albedo 0: is neither one of its words nor an existing file"),
            "{word}"
        );
        let edge = refused(SolveOptions {
            albedo: "1".into(),
            table: vec![(
                crate::params::table::spec("albedo-edge").expect("entry"),
                "0.3".into(),
            )],
            ..SolveOptions::default()
        });
        assert!(edge.contains("--albedo-edge belongs"), "{edge}");
        let unit = SolveOptions {
            distance: Some(600.0),
            intensity_scale: Some("2".into()),
            ..SolveOptions::default()
        };
        let unit = unit.check_distances().expect_err("two units").0;
        assert!(
            unit.contains("--distance and --intensity-scale 2 both set the depth unit"),
            "{unit}"
        );
    }

    /// The words of `--srgb` and `--method`, and what is refused.
    #[test]
    fn words_are_read_and_others_listed() {
        assert_eq!(srgb_mode("ON"), Ok(SrgbMode::On));
        assert!(
            srgb_mode("maybe")
                .expect_err("bad")
                .0
                .contains("expected on, off or auto")
        );
        assert!(matches!(
            method("fast_marching"),
            Ok(Method::FastMarching(_))
        ));
        assert!(
            method("newton")
                .expect_err("bad")
                .0
                .contains("expected linearised")
        );
    }

    /// A set's settings under the table's one rule each (`-1` was "must be
    /// non-negative", then 0 "must be positive", for one option).
    #[test]
    fn set_settings_follow_the_tables_rules() {
        let p = photometric_params("auto", "0.2", true).expect("settings");
        assert_eq!(
            (p.alpha, p.robust_scale, p.cast_shadows),
            (None, Some(0.2), false)
        );
        let zero = photometric_params("auto", "0", false).expect_err("scale 0");
        assert!(zero.0.starts_with("--ps-robust-scale 0:"), "{zero}");
        let negative = photometric_params("-1", "auto", false).expect_err("alpha -1");
        assert!(negative.0.starts_with("--ps-smoothness -1:"), "{negative}");
        for text in ["-1", "0", "abc", "inf"] {
            assert_eq!(
                photometric_params("auto", text, false).expect_err(text).0,
                format!("--ps-robust-scale {text}: must be `auto` or a positive number (above 0)")
            );
        }
        assert_eq!(
            photometric_params("0", "AUTO", false).map(|p| p.alpha),
            Ok(Some(0.0))
        );
        // The solver's own validation refuses what the option refuses.
        let core = PhotometricParams {
            robust_scale: Some(0.0),
            ..PhotometricParams::default()
        };
        assert_eq!(
            core.validate().expect_err("refused").name,
            "ps-robust-scale"
        );
    }
}
