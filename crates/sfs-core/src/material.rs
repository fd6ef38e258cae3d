//! How the surface reflects (METHOD.md section 10): Lambert, the qualitative
//! Oren-Nayar model for rough surfaces and Blinn-Phong for glossy ones, as
//! functions of the unit normal `N`, the unit direction `L` to the light and
//! the unit direction `V` to the camera. The light's fall-off, emission and
//! intensity are `light`'s; this module gives the factor that replaces
//! Lambert's `N . L`:
//!
//! - Lambert: `N . L`;
//! - Oren-Nayar, roughness `sigma` (radians):
//!   `(N . L) (A + B max(0, cos(phi_i - phi_r)) sin(alpha) tan(beta))`,
//!   `A = 1 - 0.5 sigma^2 / (sigma^2 + 0.33)`, `B = 0.45 sigma^2 / (sigma^2 + 0.09)`,
//!   `alpha`/`beta` the larger/smaller of the angles of `L` and `V` to `N`,
//!   `phi_i - phi_r` the azimuth between `L` and `V` around `N`;
//! - Blinn-Phong, specular weight `k_s` and shininess `n`:
//!   `(N . L) + k_s max(0, N . H)^n`, `H = (L + V) / |L + V|`, the diffuse
//!   weight 1 (both only where `N . L > 0`).
//!
//! With the light at the camera (`L = V`) each is a function of `c = N . L`
//! alone, [`Material::centred`]: `c`, `A c + B (1 - c^2)` and `c + k_s c^n`.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// A reflectance model and its parameters (all dimensionless: they mean the
/// same at every image size, exposure and unit of depth).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum Material {
    /// Lambert's matte surface (the paper's).
    #[default]
    Lambert,
    /// The qualitative Oren-Nayar model of a rough surface.
    OrenNayar {
        /// Roughness `sigma`: the standard deviation of the facets' slope
        /// angle, radians.
        roughness_rad: f64,
    },
    /// Blinn-Phong: Lambert plus a specular lobe around the half vector.
    BlinnPhong {
        /// Specular weight `k_s` (the diffuse weight is 1).
        specular: f64,
        /// Shininess exponent `n` (larger: a smaller, sharper highlight).
        shininess: f64,
    },
}

/// Largest accepted roughness, radians (about 57 degrees of facet slope;
/// the qualitative model is fitted to measurements below it).
pub const MAX_ROUGHNESS_RAD: f64 = 1.0;
/// Largest accepted specular weight `k_s`.
pub const MAX_SPECULAR: f64 = 10.0;
/// Accepted shininess exponents `n`.
pub const SHININESS_RANGE: (f64, f64) = (1.0, 1000.0);

/// Which reflectance model the solver uses (the parameter table's
/// `reflectance`): one of [`MODELS`] (by [`Model::choice`]) or `auto`. Its
/// words, parsing and parameters all come from [`MODELS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ReflectanceChoice {
    /// Lambert (the paper's; default).
    #[default]
    Lambert,
    /// Oren-Nayar with `roughness_rad`.
    OrenNayar,
    /// Blinn-Phong with `specular` and `shininess`.
    BlinnPhong,
    /// Fitted to the image on a coarse working copy before the solve
    /// (`solver::material_fit`).
    Auto,
}

/// The word of [`ReflectanceChoice::Auto`].
pub const AUTO: &str = "auto";

impl ReflectanceChoice {
    /// The model chosen; `None` for [`ReflectanceChoice::Auto`].
    pub fn model(self) -> Option<&'static Model> {
        MODELS.iter().find(|m| m.choice == self)
    }

    /// The command-line word: the model's name, or `auto`.
    pub fn name(self) -> &'static str {
        self.model().map_or(AUTO, |m| m.name)
    }

    /// The choice called `word` (any case); `None` for an unknown word.
    pub fn from_name(word: &str) -> Option<Self> {
        if word.eq_ignore_ascii_case(AUTO) {
            return Some(ReflectanceChoice::Auto);
        }
        MODELS
            .iter()
            .find(|m| m.name.eq_ignore_ascii_case(word))
            .map(|m| m.choice)
    }
}

/// One parameter of a reflectance model: its entry in the parameter table
/// (`params::PARAMS`, where the solver's value lives) and how a
/// [`Material`] holds it.
#[derive(Clone, Copy, Debug)]
pub struct ModelParam {
    /// The parameter table's name (the command line's `--NAME`).
    pub name: &'static str,
    /// Accepted values, `[min, max]` (the table's range).
    pub range: (f64, f64),
    /// The solver's default.
    pub default: f64,
    /// Reads it from a material of its model.
    pub get: fn(&Material) -> f64,
    /// Writes it into a material of its model (other models: unchanged).
    pub set: fn(&mut Material, f64),
}

/// One reflectance model: a row of [`MODELS`]. Everything that lists the
/// models (the parameter table's `reflectance` words and which parameters
/// belong to which model, `reflectance auto`'s candidates, fast marching's
/// bound, the command line's accepted names) reads these rows.
#[derive(Clone, Copy, Debug)]
pub struct Model {
    /// Its name on the command line, in reports and stored settings.
    pub name: &'static str,
    /// Its value of the parameter table's `reflectance`.
    pub choice: ReflectanceChoice,
    /// What it models, one line (for help texts and the viewer).
    pub summary: &'static str,
    /// Its parameters, in the order [`Model::fit_grid`] lists them.
    pub params: &'static [ModelParam],
    /// The material with every parameter at its default.
    pub base: Material,
    /// The values `reflectance auto` tries, one list per parameter (every
    /// combination, the first parameter outermost); `None`: not tried.
    pub fit_grid: Option<&'static [&'static [f64]]>,
    /// Fast marching's bound by `g` alone holds: `ln m(c)` falls at least
    /// as fast as `ln c` towards the rim.
    pub bound_by_g: bool,
}

impl Model {
    /// The material of this model with `value(param)` for each parameter.
    pub fn material(&self, value: impl Fn(&ModelParam) -> f64) -> Material {
        let mut material = self.base;
        for param in self.params {
            (param.set)(&mut material, value(param));
        }
        material
    }

    /// The materials `reflectance auto` tries of this model: every
    /// combination of [`Model::fit_grid`] (the first parameter outermost);
    /// none when it is not tried.
    pub fn fit_candidates(&self) -> Vec<Material> {
        let Some(grid) = self.fit_grid else {
            return Vec::new();
        };
        let mut out = vec![self.base];
        for (param, values) in self.params.iter().zip(grid.iter()) {
            out = out
                .iter()
                .flat_map(|&material| {
                    values.iter().map(move |&v| {
                        let mut m = material;
                        (param.set)(&mut m, v);
                        m
                    })
                })
                .collect();
        }
        out
    }
}

// A `ModelParam` held in the field `$field` of the variant `$variant`:
// `get` is NaN and `set` does nothing on any other material.
macro_rules! variant_param {
    ($name:literal, $range:expr, $default:expr, $variant:ident, $field:ident) => {
        ModelParam {
            name: $name,
            range: $range,
            default: $default,
            get: |m| match *m {
                Material::$variant { $field, .. } => $field,
                _ => f64::NAN,
            },
            set: |m, v| {
                if let Material::$variant { $field, .. } = m {
                    *$field = v;
                }
            },
        }
    };
}

/// Oren-Nayar's roughness `sigma`, radians.
pub const ROUGHNESS: ModelParam = variant_param!(
    "roughness",
    (0.0, MAX_ROUGHNESS_RAD),
    0.3,
    OrenNayar,
    roughness_rad
);

/// Blinn-Phong's specular weight `k_s`.
pub const SPECULAR: ModelParam =
    variant_param!("specular", (0.0, MAX_SPECULAR), 0.3, BlinnPhong, specular);

/// Blinn-Phong's shininess exponent `n`.
pub const SHININESS: ModelParam =
    variant_param!("shininess", SHININESS_RANGE, 20.0, BlinnPhong, shininess);

/// The reflectance models, in the order the command line lists them and
/// `reflectance auto` tries them. Adding a model: its [`Material`] variant
/// (with its arms in this file), its [`ReflectanceChoice`], its row here and
/// its parameters' entries in the parameter table (ARCHITECTURE.md, "Adding
/// a reflectance model").
pub const MODELS: &[Model] = &[
    Model {
        name: "lambert",
        choice: ReflectanceChoice::Lambert,
        summary: "the paper's matte surface",
        params: &[],
        base: Material::Lambert,
        fit_grid: Some(&[]),
        bound_by_g: true,
    },
    Model {
        name: "oren-nayar",
        choice: ReflectanceChoice::OrenNayar,
        summary: "rough: plaster, clay, stone, cloth",
        params: &[ROUGHNESS],
        base: Material::OrenNayar {
            roughness_rad: ROUGHNESS.default,
        },
        fit_grid: Some(&[&[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8]]),
        bound_by_g: false,
    },
    Model {
        name: "blinn-phong",
        choice: ReflectanceChoice::BlinnPhong,
        summary: "glossy: skin, plastic",
        params: &[SPECULAR, SHININESS],
        base: Material::BlinnPhong {
            specular: SPECULAR.default,
            shininess: SHININESS.default,
        },
        fit_grid: Some(&[&[0.1, 0.3, 0.6, 1.0], &[5.0, 10.0, 20.0, 40.0, 80.0]]),
        bound_by_g: true,
    },
];

/// Every model's name: the words a material option accepts.
pub const MODEL_NAMES: &[&str] = &{
    let mut names = [""; MODELS.len()];
    let mut i = 0;
    while i < MODELS.len() {
        names[i] = MODELS[i].name;
        i += 1;
    }
    names
};

/// The words of the parameter table's `reflectance`: every model's name,
/// then `auto`.
pub const REFLECTANCE_WORDS: &[&str] = &{
    let mut words = [AUTO; MODELS.len() + 1];
    let mut i = 0;
    while i < MODELS.len() {
        words[i] = MODELS[i].name;
        i += 1;
    }
    words
};

/// The model whose parameter the parameter table's `name` is; `None` for a
/// parameter of every model.
pub fn model_of_param(name: &str) -> Option<&'static Model> {
    MODELS
        .iter()
        .find(|m| m.params.iter().any(|p| p.name == name))
}

impl Material {
    /// Its model's choice (the one `match` naming each model's variant).
    pub fn choice(&self) -> ReflectanceChoice {
        match self {
            Material::Lambert => ReflectanceChoice::Lambert,
            Material::OrenNayar { .. } => ReflectanceChoice::OrenNayar,
            Material::BlinnPhong { .. } => ReflectanceChoice::BlinnPhong,
        }
    }

    /// Its row of [`MODELS`].
    pub fn model(&self) -> &'static Model {
        let choice = self.choice();
        MODELS
            .iter()
            .find(|m| m.choice == choice)
            .unwrap_or(&MODELS[0])
    }

    /// The command-line name: its model's (`lambert`, `oren-nayar`, ...).
    pub fn name(&self) -> &'static str {
        self.model().name
    }

    /// Fast marching's bound by `g` alone holds for it ([`Model::bound_by_g`]).
    pub fn bound_by_g(&self) -> bool {
        self.model().bound_by_g
    }

    /// True for Lambert (the closed forms of the paper apply).
    pub fn is_lambert(&self) -> bool {
        matches!(self, Material::Lambert)
    }

    /// The model in words with its parameters, e.g. `oren-nayar (roughness 0.4 rad)`.
    pub fn describe(&self) -> String {
        match *self {
            Material::Lambert => "lambert".into(),
            Material::OrenNayar { roughness_rad } => {
                format!("oren-nayar (roughness {roughness_rad:.3} rad)")
            }
            Material::BlinnPhong {
                specular,
                shininess,
            } => format!("blinn-phong (specular {specular:.3}, shininess {shininess:.1})"),
        }
    }

    /// The model in a few characters (a narrow table's cell), e.g.
    /// `oren-nayar σ 0.40`, `blinn-phong k_s 0.60 n 5`.
    pub fn short(&self) -> String {
        match *self {
            Material::Lambert => "lambert".into(),
            Material::OrenNayar { roughness_rad } => format!("oren-nayar σ {roughness_rad:.2}"),
            Material::BlinnPhong {
                specular,
                shininess,
            } => format!("blinn-phong k_s {specular:.2} n {shininess:.0}"),
        }
    }

    /// Checks the parameters; the error names the one out of range.
    pub fn validated(self) -> Result<Self, String> {
        match self {
            Material::Lambert => {}
            Material::OrenNayar { roughness_rad } => {
                if !(roughness_rad.is_finite()
                    && (0.0..=MAX_ROUGHNESS_RAD).contains(&roughness_rad))
                {
                    return Err(format!(
                        "roughness {roughness_rad} must lie in [0, {MAX_ROUGHNESS_RAD}] radians"
                    ));
                }
            }
            Material::BlinnPhong {
                specular,
                shininess,
            } => {
                if !(specular.is_finite() && (0.0..=MAX_SPECULAR).contains(&specular)) {
                    return Err(format!(
                        "specular weight {specular} must lie in [0, {MAX_SPECULAR}]"
                    ));
                }
                let (low, high) = SHININESS_RANGE;
                if !(shininess.is_finite() && (low..=high).contains(&shininess)) {
                    return Err(format!("shininess {shininess} must lie in [{low}, {high}]"));
                }
            }
        }
        Ok(self)
    }

    /// Oren-Nayar's `(A, B)` for roughness `sigma` (radians).
    pub fn oren_nayar_ab(roughness_rad: f64) -> (f64, f64) {
        let s2 = roughness_rad * roughness_rad;
        (1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09))
    }

    /// The factor that replaces Lambert's `N . L` for unit vectors `n`
    /// (normal), `l` (to the light) and `v` (to the camera); 0 where
    /// `N . L <= 0`.
    #[inline]
    pub fn factor(&self, n: DVec3, l: DVec3, v: DVec3) -> f64 {
        let cos_i = n.dot(l);
        if cos_i <= 0.0 {
            return 0.0;
        }
        match *self {
            Material::Lambert => cos_i,
            Material::OrenNayar { roughness_rad } => {
                let (a, b) = Self::oren_nayar_ab(roughness_rad);
                // A surface seen edge-on or from behind: clamp the view
                // angle just inside 90 degrees (tan stays finite).
                let cos_r = n.dot(v).clamp(1e-6, 1.0);
                let cos_i = cos_i.min(1.0);
                // sin(alpha) tan(beta): alpha the larger angle (smaller cosine).
                let (small, large) = if cos_i < cos_r {
                    (cos_i, cos_r)
                } else {
                    (cos_r, cos_i)
                };
                let sin_alpha = (1.0 - small * small).max(0.0).sqrt();
                let tan_beta = (1.0 - large * large).max(0.0).sqrt() / large;
                // cos(phi_i - phi_r): L and V projected on the tangent plane.
                let lp = l - cos_i * n;
                let vp = v - n.dot(v) * n;
                let norms = (lp.length_squared() * vp.length_squared()).sqrt();
                let cos_azimuth = if norms > 1e-24 {
                    (lp.dot(vp) / norms).max(0.0)
                } else {
                    0.0
                };
                cos_i * (a + b * cos_azimuth * sin_alpha * tan_beta)
            }
            Material::BlinnPhong {
                specular,
                shininess,
            } => {
                let half = l + v;
                let length = half.length();
                let cos_h = if length > 1e-12 {
                    (n.dot(half) / length).max(0.0)
                } else {
                    0.0
                };
                cos_i + specular * cos_h.powf(shininess)
            }
        }
    }

    /// With the light at the camera: the factor as a function of
    /// `c = N . L = N . V` in `(0, 1]`, and its derivative `d/dc`.
    #[inline]
    pub fn centred(&self, c: f64) -> (f64, f64) {
        match *self {
            Material::Lambert => (c, 1.0),
            Material::OrenNayar { roughness_rad } => {
                let (a, b) = Self::oren_nayar_ab(roughness_rad);
                (a * c + b * (1.0 - c * c), a - 2.0 * b * c)
            }
            Material::BlinnPhong {
                specular,
                shininess,
            } => {
                let cn1 = c.powf(shininess - 1.0);
                (c + specular * cn1 * c, 1.0 + specular * shininess * cn1)
            }
        }
    }

    /// True when the centred factor grows with `c` over `(0, 1]` (every
    /// brightness is one slope): what fast marching needs. Oren-Nayar loses
    /// it beyond about 0.61 rad of roughness (`A < 2 B`).
    pub fn centred_is_monotone(&self) -> bool {
        match *self {
            Material::OrenNayar { roughness_rad } => {
                let (a, b) = Self::oren_nayar_ab(roughness_rad);
                a - 2.0 * b > 0.0
            }
            _ => true,
        }
    }

    /// The brightest a light-facing patch gets relative to Lambert's:
    /// the centred factor at `c = 1` (`A`, `1 + k_s`).
    pub fn facing_gain(&self) -> f64 {
        self.centred(1.0).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z).normalize()
    }

    #[test]
    fn general_factor_reduces_to_the_centred_one_when_the_light_is_at_the_camera() {
        let materials = [
            Material::Lambert,
            Material::OrenNayar { roughness_rad: 0.4 },
            Material::BlinnPhong {
                specular: 0.3,
                shininess: 30.0,
            },
        ];
        for m in materials {
            for n in [
                unit(0.0, 0.0, -1.0),
                unit(0.3, -0.2, -1.0),
                unit(1.0, 0.5, -0.4),
            ] {
                let v = unit(0.1, 0.05, -1.0);
                let c = n.dot(v);
                let general = m.factor(n, v, v);
                let centred = m.centred(c).0;
                assert!(
                    (general - centred).abs() < 1e-9 * (1.0 + centred),
                    "{m:?}: {general} vs {centred}"
                );
            }
        }
    }

    #[test]
    fn centred_derivative_matches_a_difference() {
        for m in [
            Material::OrenNayar { roughness_rad: 0.7 },
            Material::BlinnPhong {
                specular: 0.5,
                shininess: 10.0,
            },
        ] {
            for c in [0.1, 0.5, 0.9] {
                let h = 1e-6;
                let numeric = (m.centred(c + h).0 - m.centred(c - h).0) / (2.0 * h);
                assert!((numeric - m.centred(c).1).abs() < 1e-6, "{m:?} at {c}");
            }
        }
    }

    #[test]
    fn oren_nayar_brightens_the_rim_and_blinn_phong_the_facing_patch() {
        let on = Material::OrenNayar { roughness_rad: 0.4 };
        // At grazing angles a rough surface stays lit (B), at normal
        // incidence it is darker than Lambert (A < 1).
        assert!(on.centred(0.05).0 > 0.05 + 0.2);
        assert!(on.facing_gain() < 0.9);
        let bp = Material::BlinnPhong {
            specular: 0.3,
            shininess: 30.0,
        };
        assert!((bp.facing_gain() - 1.3).abs() < 1e-12);
        // Ten degrees off the light the lobe has mostly gone.
        let c = 10f64.to_radians().cos();
        assert!(bp.centred(c).0 - c < 0.3 * 0.7);
    }

    #[test]
    fn monotone_limit_of_oren_nayar() {
        assert!(Material::OrenNayar { roughness_rad: 0.6 }.centred_is_monotone());
        assert!(!Material::OrenNayar { roughness_rad: 0.7 }.centred_is_monotone());
    }

    #[test]
    fn validation_names_the_parameter() {
        let e = Material::OrenNayar { roughness_rad: 2.0 }
            .validated()
            .unwrap_err();
        assert!(e.contains("roughness"), "{e}");
        let e = Material::BlinnPhong {
            specular: 0.3,
            shininess: 0.5,
        }
        .validated()
        .unwrap_err();
        assert!(e.contains("shininess"), "{e}");
    }
}
