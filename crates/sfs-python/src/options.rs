//! The keyword options of the Python functions, as the command line's
//! options in snake case (`max_side=324` is `--max-side 324`), turned into
//! the core's inputs: the photo pipeline's [`PhotoInput`], the solver's
//! parameters (through the core's parameter table, by name) and the
//! distances given. The messages name the option as the command line does.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;
use sfs_core::io::SrgbMode;
use sfs_core::light::PointLight;
use sfs_core::params::{AlbedoChoice, InitialDepth, PARAMS, ParamSpec, SolverParams};
use sfs_core::photo::{CameraSpec, LightSpec, PhotoInput, ScaleSpec, Vignetting};
use sfs_core::photograph_solve::KnownDistance;
use sfs_core::solver;

/// The default working size (longest side, pixels), as the command line's
/// `--max-side`.
pub const DEFAULT_MAX_SIDE: usize = 2000;

/// Why options are refused: a message in the command line's words.
#[derive(Debug)]
pub struct OptionError(pub String);

impl<E: std::fmt::Display> From<E> for OptionError {
    fn from(e: E) -> Self {
        Self(e.to_string())
    }
}

/// The options left to take, by snake-case name.
pub struct Options {
    left: BTreeMap<String, Value>,
}

/// `--name` as the command line spells a snake-case option.
pub fn flag(key: &str) -> String {
    format!("--{}", key.replace('_', "-"))
}

/// A JSON value as the text the command line would have been given.
fn text_of(value: &Value) -> String {
    match value {
        Value::String(s) => s.clone(),
        Value::Bool(b) => b.to_string(),
        other => other.to_string(),
    }
}

impl Options {
    /// Options from a JSON object (what the Python layer sends); `None`
    /// values are dropped (not given).
    pub fn from_json(text: &str) -> Result<Self, OptionError> {
        let value: Value = serde_json::from_str(text)?;
        let Value::Object(map) = value else {
            return Err(OptionError("options must be keyword arguments".into()));
        };
        Ok(Self {
            left: map.into_iter().filter(|(_, v)| !v.is_null()).collect(),
        })
    }

    /// Whether `key` was given.
    pub fn has(&self, key: &str) -> bool {
        self.left.contains_key(key)
    }

    /// Takes `key` as text (numbers as written).
    pub fn text(&mut self, key: &str) -> Option<String> {
        self.left.remove(key).map(|v| text_of(&v))
    }

    /// Takes `key` as a number.
    pub fn number(&mut self, key: &str) -> Result<Option<f64>, OptionError> {
        match self.left.remove(key) {
            None => Ok(None),
            Some(Value::Number(n)) => Ok(n.as_f64()),
            Some(other) => {
                let text = text_of(&other);
                text.parse()
                    .map(Some)
                    .map_err(|_| OptionError(format!("{} {text}: not a number", flag(key))))
            }
        }
    }

    /// Takes `key` as a count.
    pub fn count(&mut self, key: &str) -> Result<Option<usize>, OptionError> {
        match self.left.remove(key) {
            None => Ok(None),
            Some(value) => {
                let text = text_of(&value);
                text.parse().map(Some).map_err(|_| {
                    OptionError(format!(
                        "{} {text}: not a whole number at least 0",
                        flag(key)
                    ))
                })
            }
        }
    }

    /// Takes `key` as a switch.
    pub fn switch(&mut self, key: &str) -> Result<bool, OptionError> {
        match self.left.remove(key) {
            None => Ok(false),
            Some(Value::Bool(b)) => Ok(b),
            Some(other) => Err(OptionError(format!(
                "{} {}: expected True or False",
                flag(key),
                text_of(&other)
            ))),
        }
    }

    /// Takes `key` as a list of `N` numbers each (one or several: `(x, y,
    /// z)` or `[(x, y, z), ...]`).
    pub fn tuples<const N: usize>(&mut self, key: &str) -> Result<Vec<[f64; N]>, OptionError> {
        let Some(value) = self.left.remove(key) else {
            return Ok(Vec::new());
        };
        let bad = || {
            OptionError(format!(
                "{}: expected {N} numbers, or a list of them",
                flag(key)
            ))
        };
        let one = |v: &Value| -> Option<[f64; N]> {
            let items = v.as_array()?;
            if items.len() != N {
                return None;
            }
            let mut out = [0.0; N];
            for (slot, item) in out.iter_mut().zip(items) {
                *slot = item.as_f64()?;
            }
            Some(out)
        };
        let Value::Array(items) = &value else {
            return Err(bad());
        };
        if let Some(single) = one(&value)
            && items.iter().all(Value::is_number)
        {
            return Ok(vec![single]);
        }
        items.iter().map(|v| one(v).ok_or_else(bad)).collect()
    }

    /// Takes `key` as numbers (one or a list).
    pub fn numbers(&mut self, key: &str) -> Result<Vec<f64>, OptionError> {
        match self.left.remove(key) {
            None => Ok(Vec::new()),
            Some(Value::Array(items)) => items
                .iter()
                .map(|v| {
                    v.as_f64()
                        .ok_or_else(|| OptionError(format!("{}: expected numbers", flag(key))))
                })
                .collect(),
            Some(v) => v
                .as_f64()
                .map(|x| vec![x])
                .ok_or_else(|| OptionError(format!("{}: expected a number", flag(key)))),
        }
    }

    /// Takes the parameter table's entries given (`kappa_max` for
    /// `--kappa-max`), as the command line's text, in the table's order.
    pub fn table(&mut self) -> Vec<(&'static ParamSpec, String)> {
        PARAMS
            .iter()
            .filter_map(|spec| {
                self.text(&spec.name.replace('-', "_"))
                    .map(|text| (spec, text))
            })
            .collect()
    }

    /// Refuses what is left: options no function takes, listed with what
    /// is accepted.
    pub fn finish(self, accepted: &[&str]) -> Result<(), OptionError> {
        if let Some(key) = self.left.keys().next() {
            let mut names: Vec<String> = accepted.iter().map(|s| (*s).to_owned()).collect();
            names.extend(PARAMS.iter().map(|s| s.name.replace('-', "_")));
            return Err(OptionError(format!(
                "unknown option {key} ({}); accepted: {}",
                flag(key),
                names.join(", ")
            )));
        }
        Ok(())
    }
}

/// The options of one photograph's solve besides the parameter table's.
pub const SOLVE_OPTIONS: &[&str] = &[
    "focal",
    "cx",
    "cy",
    "intensity_scale",
    "known_depth",
    "distance",
    "light",
    "light_dir",
    "light_mu",
    "light_intensity",
    "light_index",
    "mask",
    "confidence",
    "auto_confidence",
    "srgb",
    "ambient",
    "vignetting",
    "albedo",
    "max_side",
    "init_depth",
    "method",
    "gt",
];

/// One photograph's solve as the options describe it.
pub struct SolveOptions {
    /// The photo pipeline's input.
    pub input: PhotoInput,
    /// The table's options given, as text.
    pub table: Vec<(&'static ParamSpec, String)>,
    /// `init_depth` as given.
    pub init_depth: Option<String>,
    /// `albedo` as given (`auto`, `1` or a file).
    pub albedo: String,
    /// The scheme.
    pub method: solver::Method,
    /// Known distances.
    pub known_distances: Vec<KnownDistance>,
    /// The object's distance.
    pub distance: Option<f64>,
    /// `intensity_scale` as given.
    pub intensity_scale: Option<String>,
    /// Ground-truth folder.
    pub gt: Option<PathBuf>,
}

/// The lights given (`light`, `light_dir`, `light_mu`, `light_intensity`),
/// as the command line's `--light` options.
fn given_lights(options: &mut Options) -> Result<Option<Vec<PointLight>>, OptionError> {
    let positions = options.tuples::<3>("light")?;
    let directions = options.tuples::<3>("light_dir")?;
    let mus = options.numbers("light_mu")?;
    let intensities = options.numbers("light_intensity")?;
    sfs_core::light::lights_from_options(&positions, &directions, &mus, &intensities)
        .map_err(OptionError)
}

/// `srgb`: `on`, `off`, `auto`, or True/False.
fn srgb_mode(text: Option<String>) -> Result<SrgbMode, OptionError> {
    match text.as_deref().map(str::to_ascii_lowercase).as_deref() {
        None | Some("auto") => Ok(SrgbMode::Auto),
        Some("on" | "true") => Ok(SrgbMode::On),
        Some("off" | "false") => Ok(SrgbMode::Off),
        Some(other) => Err(OptionError(format!(
            "--srgb {other}: expected on, off or auto"
        ))),
    }
}

/// `method`: `linearised`, `explicit` or `fast-marching`.
fn method(text: Option<String>) -> Result<solver::Method, OptionError> {
    match text.as_deref().map(|t| t.replace('_', "-")).as_deref() {
        None | Some("linearised") => Ok(solver::Method::Linearised),
        Some("explicit") => Ok(solver::Method::Explicit(solver::ExplicitParams::default())),
        Some("fast-marching") => Ok(solver::Method::FastMarching(
            solver::FastMarchingParams::default(),
        )),
        Some(other) => Err(OptionError(format!(
            "--method {other}: expected linearised, explicit or fast-marching"
        ))),
    }
}

/// `--NAME TEXT`: `file` must exist, else the error lists what is
/// accepted (as the command line's).
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
    /// The options of one photograph's solve of `images` (a camera file
    /// `camera`, else `focal`/`cx`/`cy`, else the photograph's EXIF), as
    /// `sfs-studio solve` reads its command line.
    pub fn take(
        options: &mut Options,
        images: Vec<PathBuf>,
        camera: Option<PathBuf>,
    ) -> Result<Self, OptionError> {
        let focal = options.number("focal")?;
        let cx = options.number("cx")?;
        let cy = options.number("cy")?;
        let camera = match (camera, focal) {
            (Some(_), Some(_)) => {
                return Err(OptionError(
                    "camera and focal both give the intrinsics: give one".into(),
                ));
            }
            (Some(path), None) => CameraSpec::File(path),
            (None, Some(focal_px)) => CameraSpec::Focal {
                focal_px,
                cx_px: cx,
                cy_px: cy,
            },
            (None, None) => CameraSpec::Exif { guess: false },
        };
        let picks: Vec<u32> = options
            .numbers("light_index")?
            .into_iter()
            .map(|k| k as u32)
            .collect();
        let lights = match given_lights(options)? {
            Some(lights) => {
                if !picks.is_empty() {
                    return Err(OptionError(
                        "give either --light X,Y,Z or --light-index K (a camera file's lights)"
                            .into(),
                    ));
                }
                LightSpec::Given(lights)
            }
            None => {
                if let Some(twice) = picks
                    .iter()
                    .enumerate()
                    .find_map(|(k, i)| picks[..k].contains(i).then_some(*i))
                {
                    return Err(OptionError(format!(
                        "--light-index {twice} is given twice: each LED is on once (give each \
                         number once)"
                    )));
                }
                LightSpec::CameraFile { picks }
            }
        };
        let intensity_scale_text = options.text("intensity_scale");
        let intensity_scale = match intensity_scale_text.as_deref() {
            None => ScaleSpec::FromCamera,
            Some(text) if text.eq_ignore_ascii_case("auto") => ScaleSpec::Auto,
            Some(text) => ScaleSpec::Given(text.parse().map_err(|_| {
                OptionError(format!("--intensity-scale {text}: not a number or `auto`"))
            })?),
        };
        let albedo = options.text("albedo").unwrap_or_else(|| "auto".into());
        let albedo_file = {
            let text = albedo.trim();
            (!(text.eq_ignore_ascii_case("auto") || text == "1")).then(|| PathBuf::from(text))
        };
        if let Some(file) = &albedo_file {
            check_word_or_file(
                "albedo",
                &albedo,
                file,
                "`auto`, `1` or FILE (an image, or a .npy such as the albedo.npy a solve writes)",
            )?;
        }
        let vignetting_text = options.text("vignetting");
        if let Some(text) = &vignetting_text
            && !matches!(text.as_str(), "none" | "cos4")
        {
            check_word_or_file(
                "vignetting",
                text,
                Path::new(text),
                "`cos4`, `none` or FILE (a flat-field image)",
            )?;
        }
        let table = options.table();
        let table_params = table_params(&table)?;
        if !albedo.trim().eq_ignore_ascii_case("auto")
            && table.iter().any(|(spec, _)| spec.name == "albedo-edge")
        {
            return Err(OptionError(format!(
                "--albedo-edge belongs to --albedo auto (the estimated albedo's prior); with \
                 --albedo {albedo} no albedo is estimated, so it would change nothing"
            )));
        }
        let max_side = options.count("max_side")?.unwrap_or(DEFAULT_MAX_SIDE);
        let max_side = (max_side > 0).then_some(max_side);
        let full = images
            .first()
            .and_then(|p| sfs_core::io::photo_size(p).ok());
        let pyramid_factor = full.map_or(sfs_core::memory::DEFAULT_PYRAMID_FACTOR, |(w, h)| {
            let (w, h) = sfs_core::resample::working_size(w, h, max_side);
            solver::pyramid::pyramid_factor(w, h, table_params.eta, table_params.min_level_side)
        });
        let input = PhotoInput {
            images,
            srgb: srgb_mode(options.text("srgb"))?,
            camera,
            lights,
            intensity_scale,
            object_mask: options.text("mask").map(PathBuf::from),
            confidence: options.text("confidence").map(PathBuf::from),
            auto_confidence: options.switch("auto_confidence")?,
            ambient: options.text("ambient").map(PathBuf::from),
            vignetting: Vignetting::from_option(vignetting_text.as_deref()),
            albedo: albedo_file,
            max_side,
            pyramid_factor,
            max_side_setting: "--max-side".into(),
            photometric_stereo: false,
            given_intensities: false,
            photo_confidence: Vec::new(),
        };
        let known_distances = options
            .tuples::<3>("known_depth")?
            .into_iter()
            .map(|[column_px, row_px, depth]| KnownDistance {
                column_px,
                row_px,
                depth,
            })
            .collect();
        Ok(Self {
            input,
            table,
            init_depth: options.text("init_depth"),
            albedo,
            method: method(options.text("method"))?,
            known_distances,
            distance: options.number("distance")?,
            intensity_scale: intensity_scale_text,
            gt: options.text("gt").map(PathBuf::from),
        })
    }

    /// The solver's parameters for a working size `image_size`.
    pub fn params(&self, image_size: (usize, usize)) -> Result<SolverParams, OptionError> {
        let mut params = table_params(&self.table)?;
        params.initial_depth = initial_depth(self.init_depth.as_deref(), image_size)?;
        params.albedo = if self.albedo.trim().eq_ignore_ascii_case("auto") {
            AlbedoChoice::Auto
        } else {
            AlbedoChoice::One
        };
        Ok(params)
    }
}

/// Parameters from the table's options given, as the command line's
/// (a model's parameter without its model, `kappa` above `kappa-max`, are
/// refused by name).
pub fn table_params(given: &[(&'static ParamSpec, String)]) -> Result<SolverParams, OptionError> {
    let mut values = Vec::with_capacity(given.len());
    for (spec, text) in given {
        values.push((*spec, spec.parse(text)?));
    }
    let params = sfs_core::params::table::params_from(values);
    if let Some((spec, _)) = given.iter().find(|(spec, _)| !params.applies(spec.name)) {
        return Err(OptionError(format!(
            "--{} belongs to --reflectance {} (the chosen reflectance does not use it)",
            spec.name,
            sfs_core::material::model_of_param(spec.name).map_or("", |m| m.name)
        )));
    }
    Ok(params)
}

/// `init_depth`: a method, a number or a `.npy` file of the working size.
fn initial_depth(
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
    let map = sfs_core::io::read_npy(Path::new(text)).map_err(|e| {
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

    /// One point or a list of points, as Python writes them.
    #[test]
    fn tuples_take_one_or_a_list() {
        let mut options =
            Options::from_json(r#"{"known_depth": [1, 2, 3], "light": [[0, 0, 0], [1, 0, 0]]}"#)
                .expect("json");
        assert_eq!(
            options.tuples::<3>("known_depth").expect("one"),
            [[1.0, 2.0, 3.0]]
        );
        assert_eq!(options.tuples::<3>("light").expect("list").len(), 2);
        let mut bad = Options::from_json(r#"{"light": [1, 2]}"#).expect("json");
        let err = bad.tuples::<3>("light").expect_err("two numbers");
        assert!(err.0.contains("--light: expected 3 numbers"), "{}", err.0);
    }

    /// The table's options by their snake-case names; anything else is
    /// refused with the accepted names.
    #[test]
    fn table_options_are_taken_by_name_and_the_rest_refused() {
        let mut options =
            Options::from_json(r#"{"kappa_max": 8, "alpha": "auto", "colour": "red"}"#)
                .expect("json");
        let table = options.table();
        let names: Vec<&str> = table.iter().map(|(spec, _)| spec.name).collect();
        assert!(
            names.contains(&"kappa-max") && names.contains(&"alpha"),
            "{names:?}"
        );
        let params = table_params(&table).expect("params");
        assert_eq!(params.kappa_max, 8);
        let err = options.finish(SOLVE_OPTIONS).expect_err("colour");
        assert!(
            err.0.starts_with("unknown option colour (--colour)"),
            "{}",
            err.0
        );
        assert!(
            err.0.contains("max_side") && err.0.contains("kappa_max"),
            "{}",
            err.0
        );
    }

    /// A model's parameter without its model is refused by name, as on the
    /// command line.
    #[test]
    fn a_models_parameter_without_its_model_is_refused() {
        let mut options = Options::from_json(r#"{"roughness": 0.3}"#).expect("json");
        let err = table_params(&options.table()).expect_err("no oren-nayar");
        assert!(
            err.0
                .contains("--roughness belongs to --reflectance oren-nayar"),
            "{}",
            err.0
        );
    }
}
