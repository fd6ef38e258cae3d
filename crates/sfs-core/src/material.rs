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

impl Material {
    /// The command-line name: `lambert`, `oren-nayar` or `blinn-phong`.
    pub fn name(&self) -> &'static str {
        match self {
            Material::Lambert => "lambert",
            Material::OrenNayar { .. } => "oren-nayar",
            Material::BlinnPhong { .. } => "blinn-phong",
        }
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
