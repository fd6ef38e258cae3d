//! The one table of solver parameters: name, label, help, kind and range,
//! and how to read and write each in [`SolverParams`]. The command line
//! (`cli::params`), the viewer's sliders and tooltips, the viewer's stored
//! settings, the solve report and [`SolverParams::validate`] all read it, so
//! a parameter is added in one place.

use super::settings::{
    Alpha, DomainMode, LinearSolver, ReflectanceChoice, SolverParams, StartDenoise, StepControl,
    Units,
};
use crate::model::Derivatives;

/// What values a parameter takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamKind {
    /// A real number in `[min, max]`; `log`: shown on a logarithmic slider;
    /// `auto`: the word `auto` is accepted too.
    Real {
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
        /// Logarithmic slider.
        log: bool,
        /// Accepts `auto`.
        auto: bool,
    },
    /// A whole number in `[min, max]`.
    Count {
        /// Smallest accepted value.
        min: usize,
        /// Largest accepted value.
        max: usize,
    },
    /// One of these words.
    Choice(&'static [&'static str]),
}

/// A parameter's value, as the table reads and writes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamValue {
    /// A real number.
    Real(f64),
    /// A whole number.
    Count(usize),
    /// One of the parameter's words.
    Choice(&'static str),
    /// Chosen by the solver.
    Auto,
}

impl std::fmt::Display for ParamValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // Very large or small numbers in scientific notation.
            ParamValue::Real(v) if *v != 0.0 && !(1e-4..1e6).contains(&v.abs()) => {
                write!(f, "{v:e}")
            }
            ParamValue::Real(v) => write!(f, "{v}"),
            ParamValue::Count(v) => write!(f, "{v}"),
            ParamValue::Choice(w) => write!(f, "{w}"),
            ParamValue::Auto => write!(f, "auto"),
        }
    }
}

impl ParamValue {
    /// The value as JSON (numbers as numbers, words as strings).
    pub fn to_json(self) -> serde_json::Value {
        match self {
            ParamValue::Real(v) => serde_json::json!(v),
            ParamValue::Count(v) => serde_json::json!(v),
            ParamValue::Choice(w) => serde_json::json!(w),
            ParamValue::Auto => serde_json::json!("auto"),
        }
    }
}

/// One parameter.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// Name on the command line (`--NAME`), in reports and stored settings.
    pub name: &'static str,
    /// Short label in the viewer.
    pub label: &'static str,
    /// What it does, its unit, its default and the paper's value.
    pub help: &'static str,
    /// Values and range (why the bounds: in `help`).
    pub kind: ParamKind,
    /// How the viewer shows it: a number's slider range (relative units);
    /// for a choice any `Some` shows a selector; `None`: not in the viewer.
    pub slider: Option<(f64, f64)>,
    /// Reads the value.
    pub get: fn(&SolverParams) -> ParamValue,
    /// Writes a value already checked against `kind`.
    pub set: fn(&mut SolverParams, ParamValue),
}

/// A value that does not fit a parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid parameter {name} = {value}: {reason}")]
pub struct ParamError {
    /// The parameter's name as the command line spells it.
    pub name: &'static str,
    /// The rejected value.
    pub value: String,
    /// What a valid value is.
    pub reason: String,
}

impl ParamSpec {
    /// What the kind accepts, in words.
    pub fn accepted(&self) -> String {
        match self.kind {
            ParamKind::Real { min, max, auto, .. } => format!(
                "must be {}a finite number in [{min:e}, {max:e}]",
                if auto { "'auto' or " } else { "" }
            ),
            ParamKind::Count { min, max } => format!("must be a whole number in [{min}, {max}]"),
            ParamKind::Choice(words) => format!("must be one of {}", words.join(", ")),
        }
    }

    fn error(&self, value: impl ToString) -> ParamError {
        ParamError {
            name: self.name,
            value: value.to_string(),
            reason: self.accepted(),
        }
    }

    /// Checks a value against the kind and range.
    pub fn check(&self, value: ParamValue) -> Result<(), ParamError> {
        let ok = match (self.kind, value) {
            (ParamKind::Real { auto, .. }, ParamValue::Auto) => auto,
            (ParamKind::Real { min, max, .. }, ParamValue::Real(v)) => {
                v.is_finite() && (min..=max).contains(&v)
            }
            (ParamKind::Count { min, max }, ParamValue::Count(v)) => (min..=max).contains(&v),
            (ParamKind::Choice(words), ParamValue::Choice(w)) => words.contains(&w),
            _ => false,
        };
        if ok { Ok(()) } else { Err(self.error(value)) }
    }

    /// Parses and checks a value written as text (the command line's form).
    pub fn parse(&self, text: &str) -> Result<ParamValue, ParamError> {
        let text = text.trim();
        let value = match self.kind {
            ParamKind::Real { auto, .. } if auto && text.eq_ignore_ascii_case("auto") => {
                ParamValue::Auto
            }
            ParamKind::Real { .. } => ParamValue::Real(text.parse().map_err(|_| self.error(text))?),
            ParamKind::Count { .. } => {
                ParamValue::Count(text.parse().map_err(|_| self.error(text))?)
            }
            ParamKind::Choice(words) => ParamValue::Choice(
                words
                    .iter()
                    .find(|w| w.eq_ignore_ascii_case(text))
                    .ok_or_else(|| self.error(text))?,
            ),
        };
        self.check(value)?;
        Ok(value)
    }

    /// Reads a value from JSON (stored settings); `None` if it does not fit.
    pub fn from_json(&self, json: &serde_json::Value) -> Option<ParamValue> {
        let text = match json {
            serde_json::Value::String(s) => s.clone(),
            serde_json::Value::Number(n) => n.to_string(),
            _ => return None,
        };
        self.parse(&text).ok()
    }
}

fn real(value: ParamValue) -> f64 {
    match value {
        ParamValue::Real(v) => v,
        ParamValue::Count(v) => v as f64,
        _ => f64::NAN,
    }
}

fn count(value: ParamValue) -> usize {
    match value {
        ParamValue::Count(v) => v,
        _ => 0,
    }
}

fn word(value: ParamValue) -> &'static str {
    match value {
        ParamValue::Choice(w) => w,
        _ => "",
    }
}

/// A number field of [`SolverParams`] as the table reads and writes it.
trait Field {
    /// The field's value.
    fn value(self) -> ParamValue;
    /// A checked value as the field's type.
    fn read(value: ParamValue) -> Self;
}

impl Field for f64 {
    fn value(self) -> ParamValue {
        ParamValue::Real(self)
    }
    fn read(value: ParamValue) -> f64 {
        real(value)
    }
}

impl Field for usize {
    fn value(self) -> ParamValue {
        ParamValue::Count(self)
    }
    fn read(value: ParamValue) -> usize {
        count(value)
    }
}

/// A real number in `[min, max]` on a linear slider, without `auto`.
const fn linear((min, max): (f64, f64)) -> ParamKind {
    ParamKind::Real {
        min,
        max,
        log: false,
        auto: false,
    }
}

/// A real number in `[min, max]` on a logarithmic slider, without `auto`.
const fn logarithmic((min, max): (f64, f64)) -> ParamKind {
    ParamKind::Real {
        min,
        max,
        log: true,
        auto: false,
    }
}

/// A whole number in `[min, max]`.
const fn whole((min, max): (usize, usize)) -> ParamKind {
    ParamKind::Count { min, max }
}

// The table's common kinds, one field of [`SolverParams`] each:
// `field_param!` a real or whole number (the field's type, through
// [`Field`], says which; the kind from [`linear`], [`logarithmic`] or
// [`whole`]) and `choice_param!` an enum of words (word => variant, the
// first variant standing for a value that is not one of the words). Each
// expands to a `ParamSpec` literal whose `get` and `set` read and write the
// field.
macro_rules! field_param {
    (
        $name:literal, $label:literal,
        $field:ident, $kind:expr, slider = $slider:expr,
        $help:literal $(,)?
    ) => {
        field_param!(@spec $name, $label, $help, $kind, $slider,
            |p| Field::value(p.$field),
            |p, v| p.$field = Field::read(v))
    };
    (@spec $name:literal, $label:literal, $help:literal, $kind:expr, $slider:expr,
        $get:expr, $set:expr) => {
        ParamSpec {
            name: $name,
            label: $label,
            help: $help,
            kind: $kind,
            slider: $slider,
            get: $get,
            set: $set,
        }
    };
}

macro_rules! choice_param {
    (
        $name:literal, $label:literal,
        $field:ident,
        [$first:literal => $first_variant:path $(, $word:literal => $variant:path)* $(,)?],
        $help:literal $(,)?
    ) => {
        field_param!(@spec $name, $label, $help, ParamKind::Choice(&[$first $(, $word)*]), None,
            |p| ParamValue::Choice(match p.$field {
                $first_variant => $first,
                $($variant => $word,)*
            }),
            |p, v| p.$field = match word(v) {
                $($word => $variant,)*
                _ => $first_variant,
            })
    };
}

/// Every parameter of [`SolverParams`] but the initial depth (a map or a
/// method, given separately). Bounds keep every solve finite and its size
/// sane: no parameter accepted here can make the solver hang, overflow or
/// allocate without bound.
pub const PARAMS: &[ParamSpec] = &[
    ParamSpec {
        name: "alpha",
        label: "alpha",
        help: "Smoothness weight, in --units, or 'auto' (default): chosen from the image's \
               estimated noise, see docs/units-and-alpha.md. Larger = smoother. In relative \
               units 1e-8 to 1e-5 suit most images; the paper used 0.003 to 3 in its own units.",
        kind: ParamKind::Real {
            min: 0.0,
            max: 1e15,
            log: true,
            auto: true,
        },
        slider: Some((1e-10, 1e-3)),
        get: |p| match p.alpha {
            Alpha::Auto => ParamValue::Auto,
            Alpha::Value(v) => ParamValue::Real(v),
        },
        set: |p, v| {
            p.alpha = match v {
                ParamValue::Auto => Alpha::Auto,
                v => Alpha::Value(real(v)),
            }
        },
    },
    field_param! {
        "lambda", "lambda",
        lambda, logarithmic((1e-12, 1e12)), slider = Some((0.1, 1e4)),
        "Charbonnier contrast of the smoothness term, in --units: below it smoothing is \
         quadratic, above it creases are kept. Default 30 relative (the paper's 1e-3 \
         pixel units on its Sombrero)."
    },
    choice_param! {
        "units", "units",
        units, ["relative" => Units::Relative, "paper" => Units::Paper],
        "Units of alpha, lambda, dz-limit and h-z: 'relative' (default; dimensionless, \
         the same values give the same result at any image size, exposure and unit of \
         depth) or 'paper' (per full-resolution pixel and depth units, as in the paper)."
    },
    field_param! {
        "eta", "eta",
        eta, linear((0.1, 0.99)), slider = Some((0.5, 0.98)),
        "Pyramid factor between levels (paper 0.9). Bounded by 0.99: the number of \
         levels grows as 1/(1 - eta)."
    },
    field_param! {
        "kappa", "kappa",
        kappa, whole((1, 1000)), slider = Some((1.0, 20.0)),
        "Outer (Gauss-Newton) iterations per level, at least (paper 5); refining a start \
         across holes, kappa-holes."
    },
    field_param! {
        "kappa-max", "kappa max",
        kappa_max, whole((1, 1000)), slider = None,
        "Outer iterations per level at most: after kappa a level goes on while its \
         energy falls by more than level-tolerance per iteration. Default 5 (= kappa, \
         the paper's fixed count: converging every coarse level was measured worse)."
    },
    field_param! {
        "kappa-holes", "kappa (holes)",
        kappa_holes, whole((1, 1000)), slider = None,
        "Outer iterations refining a full-resolution start across holes (object pixels \
         of confidence below 0.5), at least; kappa-max rises to it. Default 10: the fill \
         travels farther than a start without holes, and every step is cropped."
    },
    ParamSpec {
        name: "shadow-bound",
        label: "shadow bound",
        help: "With lights off the optical centre: 'on' holds the full-resolution surface \
               behind what its shadow says (a shadow pixel the surface would light goes back \
               onto the ray from the light that grazes its occluder); 'off' (default: measured \
               no better on the shadows bench).",
        kind: ParamKind::Choice(&["off", "on"]),
        slider: None,
        get: |p| ParamValue::Choice(if p.shadow_bound { "on" } else { "off" }),
        set: |p, v| p.shadow_bound = word(v) == "on",
    },
    field_param! {
        "level-tolerance", "level tolerance",
        level_tolerance, linear((0.0, 1.0)), slider = None,
        "Relative energy decrease per outer iteration below which a level stops \
         (after kappa iterations). Default 1e-3."
    },
    field_param! {
        "inner-iters", "inner iterations",
        inner_iterations, whole((1, 1000)), slider = Some((1.0, 30.0)),
        "Fixed-point iterations l_max on the Charbonnier weights Psi' (paper 9)."
    },
    field_param! {
        "sor-iters", "SOR sweeps",
        sor_iterations, whole((1, 1000)), slider = Some((1.0, 50.0)),
        "SOR sweeps per inner iteration, at most with a linear tolerance (paper 10; \
         linear solver 'sor')."
    },
    choice_param! {
        "linear-solver", "linear solver",
        linear_solver, [
            "auto" => LinearSolver::Auto,
            "multigrid" => LinearSolver::Multigrid,
            "sor" => LinearSolver::Sor,
        ],
        "'auto' (default): multigrid where a full-resolution start is refined across \
         holes (object pixels of confidence below 0.5), SOR elsewhere; 'multigrid': \
         V-cycles with Galerkin coarse levels and SOR smoothing; 'sor': the paper's SOR \
         sweeps."
    },
    choice_param! {
        "start-denoise", "start denoising",
        start_denoise, [
            "auto" => StartDenoise::Auto,
            "on" => StartDenoise::On,
            "off" => StartDenoise::Off,
        ],
        "Whether the fast-marching start marches a TV-denoised image. 'auto' (default): \
         when the image reads noisy (noise above 1 % of the brightness scale over the \
         object and over its brightest quarter, where the surface's own detail shows \
         least); 'on': always; 'off': never (a clean image of a finely detailed surface). \
         The refinement always fits the image as given."
    },
    field_param! {
        "cycles", "V-cycles",
        cycles, whole((1, 1000)), slider = None,
        "Multigrid V-cycles per inner iteration, at most (default 4)."
    },
    field_param! {
        "smoothing-sweeps", "smoothing sweeps",
        smoothing_sweeps, whole((1, 100)), slider = None,
        "SOR sweeps before and after each coarse correction of a V-cycle (default 2)."
    },
    field_param! {
        "linear-tolerance", "linear tolerance",
        linear_tolerance, linear((0.0, 1.0)), slider = None,
        "Inexact Newton: each linear solve stops once its residual fell by this factor \
         (default 0: the fixed sweep or cycle count, the paper's)."
    },
    field_param! {
        "step-tolerance", "step tolerance",
        step_tolerance, linear((0.0, 1.0)), slider = None,
        "Refining a full-resolution start (not across holes), a level stops once an outer \
         iteration moved the depth by less than this share of itself on average, before \
         kappa iterations if need be. Default 0 (kappa and the level tolerance alone, \
         the paper's); 1e-4 (a hundredth of a percent) about halves the refinement's time \
         on clean images at the same RSE, with a worse image fit (RIE)."
    },
    field_param! {
        "inner-tolerance", "inner tolerance",
        inner_tolerance, linear((0.0, 1.0)), slider = None,
        "Refining a full-resolution start, the inner iterations stop when the \
         Charbonnier weights Psi' moved by less than this (relative) since the last \
         linear solve and the later ones would only polish the step (default 0.05); 0 \
         runs all of them (the paper's)."
    },
    field_param! {
        "omega", "omega",
        omega, linear((0.01, 1.99)), slider = Some((0.1, 1.95)),
        "SOR over-relaxation, in (0, 2) (not given in the paper; default 1.5)."
    },
    field_param! {
        "dz-limit", "dz limit",
        dz_limit, logarithmic((1e-9, 1e9)), slider = Some((1e-4, 0.1)),
        "Largest depth change per pixel and outer iteration: a fraction of the pixel's \
         depth in relative units (default 0.005), depth units in paper units (paper \
         0.01)."
    },
    ParamSpec {
        name: "derivatives",
        label: "derivatives",
        help: "Derivatives of the residual: 'exact' (default) or 'numeric' (central \
               differences with h-z, the paper's; both agree to about 1e-4).",
        kind: ParamKind::Choice(&["exact", "numeric"]),
        slider: None,
        get: |p| {
            ParamValue::Choice(match p.derivatives {
                Derivatives::Exact => "exact",
                Derivatives::Numeric { .. } => "numeric",
            })
        },
        set: |p, v| {
            p.derivatives = match (word(v), p.derivatives) {
                ("numeric", Derivatives::Numeric { h_z }) => Derivatives::Numeric { h_z },
                ("numeric", Derivatives::Exact) => Derivatives::Numeric { h_z: 1e-12 },
                _ => Derivatives::Exact,
            }
        },
    },
    ParamSpec {
        name: "h-z",
        label: "h_z",
        help: "Perturbation of numeric derivatives (with derivatives = numeric): a fraction \
               of the depth scale in relative units, depth units in paper units (paper \
               1e-12).",
        kind: ParamKind::Real {
            min: 1e-15,
            max: 1.0,
            log: true,
            auto: false,
        },
        slider: None,
        get: |p| match p.derivatives {
            Derivatives::Numeric { h_z } => ParamValue::Real(h_z),
            Derivatives::Exact => ParamValue::Real(1e-12),
        },
        set: |p, v| {
            if let Derivatives::Numeric { h_z } = &mut p.derivatives {
                *h_z = real(v);
            }
        },
    },
    field_param! {
        "min-level-side", "coarsest side",
        min_level_side, whole((3, 1 << 20)), slider = None,
        "Smallest side of the coarsest pyramid level, pixels (default 16)."
    },
    choice_param! {
        "domain", "domain",
        domain, ["paper" => DomainMode::Paper, "object" => DomainMode::Object],
        "'paper' (default): every pixel carries depth, the background only has \
         confidence 0; 'object': only object-mask pixels do (docs/mask-and-confidence.md)."
    },
    choice_param! {
        "step-control", "step control",
        step_control, ["backtracking" => StepControl::Backtracking, "crop" => StepControl::Crop],
        "'backtracking' (default): crop, then halve the step until the energy does not \
         rise; 'crop': the paper's per-pixel crop alone."
    },
    field_param! {
        "anti-alias", "anti-alias",
        anti_alias_sigma, linear((0.0, 10.0)), slider = None,
        "Pyramid anti-aliasing sigma_0 (0, the default: point-sample every level from \
         the full image, keeping bright peaks). Bounded by 10: the blur's kernel grows \
         with it."
    },
    ParamSpec {
        name: "reflectance",
        label: "reflectance",
        help: "Reflectance model (METHOD.md section 10): 'lambert' (default, the paper's matte \
               surface), 'oren-nayar' (rough: plaster, clay, stone, cloth; --roughness), \
               'blinn-phong' (glossy: skin, plastic; --specular, --shininess), or 'auto': \
               fitted to the image on a coarse copy, reported with how well the image \
               determined it.",
        kind: ParamKind::Choice(crate::material::REFLECTANCE_WORDS),
        slider: Some((0.0, 0.0)),
        get: |p| ParamValue::Choice(p.reflectance.name()),
        set: |p, v| p.reflectance = ReflectanceChoice::from_name(word(v)).unwrap_or_default(),
    },
    field_param! {
        "roughness", "roughness (rad)",
        roughness_rad, linear(crate::material::ROUGHNESS.range), slider = Some((0.0, 1.0)),
        "Oren-Nayar roughness sigma: the spread of the surface's facet slopes, radians \
         (default 0.3; 0 is Lambert; at most 1). Rough surfaces stay lit towards the rim \
         and look flatter facing the light. Fast marching needs it below about 0.61."
    },
    field_param! {
        "specular", "specular k_s",
        specular, linear(crate::material::SPECULAR.range), slider = Some((0.0, 2.0)),
        "Blinn-Phong specular weight k_s against a diffuse weight of 1 (default 0.3; 0 \
         is Lambert; at most 10)."
    },
    field_param! {
        "shininess", "shininess n",
        shininess, logarithmic(crate::material::SHININESS.range), slider = Some((1.0, 200.0)),
        "Blinn-Phong shininess exponent n (default 20): larger gives a smaller, sharper \
         highlight (10: a broad sheen, 30: skin or plastic, 100: polished). In [1, 1000]."
    },
    field_param! {
        "albedo-edge", "albedo edge (log step)",
        albedo_edge, logarithmic((0.02, 2.0)), slider = Some((0.05, 1.0)),
        "The albedo prior's weight, used by --albedo auto: the smallest step of log \
         brightness between neighbouring pixels taken as a change of albedo rather than \
         of shading (an L0 penalty tau^2 on the log albedo's gradient; default 0.2, a \
         ratio of 1.22; a step must also exceed five times its noise). Lower finds \
         fainter marks and takes more shading for albedo. In [0.02, 2]."
    },
];

/// The table entry called `name`.
pub fn spec(name: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|s| s.name == name)
}

/// Parameters from checked values over the defaults of the units among them
/// (the defaults of lambda and dz-limit depend on the units), the initial
/// depth at its default.
pub fn params_from<'a>(
    values: impl IntoIterator<Item = (&'a ParamSpec, ParamValue)>,
) -> SolverParams {
    let values: Vec<_> = values.into_iter().collect();
    let units = match values.iter().find(|(spec, _)| spec.name == "units") {
        Some((_, ParamValue::Choice("paper"))) => Units::Paper,
        _ => Units::Relative,
    };
    let mut params = SolverParams::for_units(units);
    for (spec, value) in values {
        (spec.set)(&mut params, value);
    }
    params
}

/// Every parameter's value as a JSON object (the report's `parameters`).
pub fn to_json(params: &SolverParams) -> serde_json::Value {
    serde_json::Value::Object(
        PARAMS
            .iter()
            .map(|s| (s.name.to_string(), (s.get)(params).to_json()))
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_default_passes_its_own_check_and_round_trips_as_text() {
        for params in [SolverParams::default(), SolverParams::paper(100.0)] {
            for s in PARAMS {
                let value = (s.get)(&params);
                s.check(value).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(s.parse(&value.to_string()), Ok(value), "{}", s.name);
                let mut copy = params.clone();
                (s.set)(&mut copy, value);
                assert_eq!(copy, params, "{}", s.name);
            }
        }
    }

    #[test]
    fn names_are_unique_and_bad_text_is_named() {
        for (i, a) in PARAMS.iter().enumerate() {
            assert!(
                PARAMS[i + 1..].iter().all(|b| b.name != a.name),
                "{}",
                a.name
            );
        }
        let alpha = spec("alpha").expect("alpha");
        assert_eq!(alpha.parse("auto"), Ok(ParamValue::Auto));
        assert_eq!(alpha.parse("-1").map_err(|e| e.name), Err("alpha"));
        assert_eq!(alpha.parse("abc").map_err(|e| e.name), Err("alpha"));
        let eta = spec("eta").expect("eta");
        assert!(eta.parse("0.999999999999").is_err());
        assert!(
            spec("anti-alias")
                .expect("anti-alias")
                .parse("1e20")
                .is_err()
        );
        assert!(spec("lambda").expect("lambda").parse("1e300").is_err());
        assert!(spec("domain").expect("domain").parse("OBJECT").is_ok());
    }

    /// Every number a help text calls the default ("default 0.1", "Default
    /// 5") is the default (`--linear-tolerance` said 0.1 where it is 0).
    #[test]
    fn the_defaults_the_help_states_are_the_defaults() {
        let defaults = SolverParams::default();
        for s in PARAMS {
            let lower = s.help.to_ascii_lowercase();
            for (at, _) in lower.match_indices("default ") {
                let rest = &lower[at + "default ".len()..];
                let number: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | 'e' | '-'))
                    .collect();
                let Ok(stated) = number.trim_end_matches('.').parse::<f64>() else {
                    continue;
                };
                let actual = match (s.get)(&defaults) {
                    ParamValue::Real(v) => v,
                    ParamValue::Count(v) => v as f64,
                    other => panic!("{}: help states default {stated}, is {other}", s.name),
                };
                assert_eq!(stated, actual, "{}: help says default {stated}", s.name);
            }
        }
    }

    /// The albedo-edge help states the noise factor `crate::albedo` uses
    /// (it said three times where the code uses five).
    #[test]
    fn albedo_edge_help_states_the_codes_noise_factor() {
        let source = include_str!("../albedo.rs");
        let key = "const NOISE_SIGMAS: f64 = ";
        let at = source.find(key).expect("albedo.rs defines NOISE_SIGMAS") + key.len();
        let sigmas: f64 = source[at..]
            .split(';')
            .next()
            .and_then(|v| v.trim().parse().ok())
            .expect("NOISE_SIGMAS is a number");
        let words = [
            "zero", "one", "two", "three", "four", "five", "six", "seven", "eight",
        ];
        let word = words[sigmas as usize];
        let help = spec("albedo-edge").expect("albedo-edge").help;
        assert!(
            help.contains(&format!("{word} times its noise")),
            "albedo-edge help does not say {word} times the noise: {help}"
        );
    }
}
