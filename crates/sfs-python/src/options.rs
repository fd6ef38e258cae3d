//! The keyword options of the Python functions, as the command line's
//! options in snake case (`max_side=324` is `--max-side 324`), turned into
//! the core's inputs: the photo pipeline's [`PhotoInput`], the solver's
//! parameters (through the core's parameter table, by name) and the
//! distances given. The messages name the option as the command line does.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde_json::Value;
use sfs_core::io::SrgbMode;
use sfs_core::light::PointLight;
use sfs_core::params::{PARAMS, ParamSpec};
use sfs_core::photograph_solve::options::{self as solve_options};
pub use sfs_core::photograph_solve::options::{DEFAULT_MAX_SIDE, OptionError, SolveOptions};

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
        let value: Value = serde_json::from_str(text).map_err(|e| OptionError(e.to_string()))?;
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

/// One photograph's solve as the options describe it: the core's
/// [`SolveOptions`] (which checks them and builds the solve) and the
/// ground-truth folder.
pub struct TakenSolve {
    /// The options as the core reads them.
    pub options: SolveOptions,
    /// `gt`: a ground-truth folder written by `synth`.
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

impl TakenSolve {
    /// The options of one photograph's solve (a camera file `camera`, else
    /// `focal`/`cx`/`cy`, else the photograph's EXIF), as `sfs-studio
    /// solve` reads its command line (the core checks them when it builds the
    /// pipeline's input).
    pub fn take(options: &mut Options, camera: Option<PathBuf>) -> Result<Self, OptionError> {
        let light_index = options
            .numbers("light_index")?
            .into_iter()
            .map(|k| k as u32)
            .collect();
        let solve = SolveOptions {
            camera_file: camera,
            focal_px: options.number("focal")?,
            cx_px: options.number("cx")?,
            cy_px: options.number("cy")?,
            intensity_scale: options.text("intensity_scale"),
            known_depth: options.tuples::<3>("known_depth")?,
            distance: options.number("distance")?,
            lights: given_lights(options)?,
            light_index,
            mask: options.text("mask").map(PathBuf::from),
            confidence: options.text("confidence").map(PathBuf::from),
            auto_confidence: options.switch("auto_confidence")?,
            srgb: match options.text("srgb") {
                Some(text) => solve_options::srgb_mode(&text)?,
                None => SrgbMode::Auto,
            },
            ambient: options.text("ambient").map(PathBuf::from),
            vignetting: options.text("vignetting"),
            albedo: options.text("albedo").unwrap_or_else(|| "auto".into()),
            max_side: options.count("max_side")?.unwrap_or(DEFAULT_MAX_SIDE),
            init_depth: options.text("init_depth"),
            method: match options.text("method") {
                Some(text) => solve_options::method(&text)?,
                None => sfs_core::solver::Method::Linearised,
            },
            table: options.table(),
        };
        Ok(Self {
            options: solve,
            gt: options.text("gt").map(PathBuf::from),
        })
    }
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
        let params = sfs_core::params::given::params_from_given(&table).expect("params");
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
        let err = sfs_core::params::given::params_from_given(&options.table())
            .expect_err("no oren-nayar");
        let err = OptionError::from(err);
        assert!(
            err.0
                .contains("--roughness belongs to --reflectance oren-nayar"),
            "{}",
            err.0
        );
    }
}
