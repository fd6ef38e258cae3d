//! Point lights anywhere in the camera frame (METHOD.md section 9): the
//! general near-light Lambertian model with anisotropic LEDs, its exact
//! partial derivatives, and the lights' description shared by the camera
//! file, the CLI, `synth` and the viewer.
//!
//! `I = s sum_k phi_k a_k(P) max(0, N . (S_k - P)) / |S_k - P|^3`, with
//! `P = z (x/f, y/f, 1)`, `N = n / |n|`, `n = (f z_x, f z_y, -(z + x z_x + y z_y))`
//! and `a_k = (D_k . (P - S_k) / |P - S_k|)^mu_k`. One isotropic light at the
//! optical centre gives back the paper's `s Q^3 / (z W)` exactly.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::material::Material;
use crate::model::{Lambertian, PixelRay, Reflectance};

/// One point light in the camera frame (x right, y down, z along the optical
/// axis), in the units of depth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointLight {
    /// Position `S` in the camera frame, units of depth.
    pub position: [f64; 3],
    /// Unit principal direction `D` of an anisotropic emitter (normalised on
    /// validation); `None`: isotropic.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f64; 3]>,
    /// Anisotropy `mu >= 0` (radiance falls off as `cos^mu` of the angle to
    /// `direction`; 0: isotropic, 1: Lambertian emitter). Ignored without a
    /// direction.
    #[serde(default)]
    pub mu: f64,
    /// Relative intensity `phi > 0` (1 for one light).
    #[serde(default = "one")]
    pub intensity: f64,
}

fn one() -> f64 {
    1.0
}

/// Largest accepted anisotropy: LED datasheets stay below ~10; beyond 100 a
/// light is a laser pointer and `cos^mu` underflows.
pub const MAX_MU: f64 = 100.0;

impl PointLight {
    /// The paper's light: isotropic, intensity 1, at the optical centre.
    pub const CENTRED: PointLight = PointLight {
        position: [0.0; 3],
        direction: None,
        mu: 0.0,
        intensity: 1.0,
    };

    /// True when this light is the paper's (up to its intensity): at the
    /// optical centre and isotropic.
    pub fn is_centred(&self) -> bool {
        self.position == [0.0; 3] && (self.direction.is_none() || self.mu == 0.0)
    }

    /// The position to one decimal, `(x, y, z)`, for summaries.
    pub fn position_text(&self) -> String {
        let [x, y, z] = self.position;
        format!("({x:.1}, {y:.1}, {z:.1})")
    }

    /// `, mu MU` for an aimed anisotropic light, else nothing, for summaries.
    pub fn aim_text(&self) -> String {
        if self.direction.is_some() && self.mu > 0.0 {
            format!(", mu {}", self.mu)
        } else {
            String::new()
        }
    }

    /// Checks every field and normalises the direction; the error says which
    /// field of light `index` (from 1) is wrong and why.
    pub fn validated(mut self, index: usize) -> Result<Self, String> {
        let name = format!("light {index}");
        if self
            .position
            .iter()
            .any(|v| !v.is_finite() || v.abs() > 1e12)
        {
            return Err(format!(
                "{name}: position {:?} must be finite (|value| <= 1e12)",
                self.position
            ));
        }
        if !(self.mu.is_finite() && (0.0..=MAX_MU).contains(&self.mu)) {
            return Err(format!("{name}: mu {} must lie in [0, {MAX_MU}]", self.mu));
        }
        if !(self.intensity.is_finite() && self.intensity > 0.0 && self.intensity < 1e30) {
            return Err(format!(
                "{name}: intensity {} must be positive and finite",
                self.intensity
            ));
        }
        if let Some(d) = self.direction {
            let v = DVec3::from_array(d);
            let length = v.length();
            if !(length.is_finite() && length > 1e-12) {
                return Err(format!("{name}: direction {d:?} must be a non-zero vector"));
            }
            // Divided by the length, not multiplied by its reciprocal as
            // `normalize` does: the rounding the saved results were made with.
            self.direction = Some((v / length).to_array());
        }
        Ok(self)
    }

    /// Distance of the light from the optical axis, units of depth.
    pub fn off_axis(&self) -> f64 {
        self.position[0].hypot(self.position[1])
    }
}

/// True when `lights` is the paper's set-up: no light given, or one light at
/// the optical centre (its intensity only scales `s`).
pub fn is_centred(lights: &[PointLight]) -> bool {
    lights.is_empty() || lights.iter().all(PointLight::is_centred)
}

/// The summed intensity of `lights` (1 for none: the paper's light), which
/// the closed forms of centred lights fold into `s`.
fn summed_intensity(lights: &[PointLight]) -> f64 {
    if lights.is_empty() {
        1.0
    } else {
        lights.iter().map(|l| l.intensity).sum()
    }
}

/// The vectors of a surface point seen along `ray` at `depth` with depth
/// gradient `(dz_dx, dz_dy)`, lit by `light`: the view ray `v = (x/f, y/f,
/// 1)` (the point is `P = z v`), `L = S - P` and the unnormalised normal
/// `n = (f z_x, f z_y, -(z + x z_x + y z_y))`.
#[inline]
fn surface_vectors(
    light: &PointLight,
    ray: &PixelRay,
    depth: f64,
    dz_dx: f64,
    dz_dy: f64,
) -> (DVec3, DVec3, DVec3) {
    let f = ray.focal_px;
    let (x, y) = (ray.x_px, ray.y_px);
    let v = DVec3::new(x / f, y / f, 1.0);
    let l = DVec3::from_array(light.position) - depth * v;
    let n = DVec3::new(f * dz_dx, f * dz_dy, -(depth + x * dz_dx + y * dz_dy));
    (v, l, n)
}

/// Lambertian surface lit by point lights anywhere, `1/r^2` fall-off, LED
/// anisotropy: the general model of METHOD.md section 9.
#[derive(Clone, Debug, PartialEq)]
pub struct NearLights {
    /// Intensity scale `s` (albedo times the camera's gain).
    pub intensity_scale: f64,
    /// The lights switched on (summed). Validated (unit directions).
    pub lights: Vec<PointLight>,
}

/// An LED's emission towards a point at `l = S - P` (`d = |l|`):
/// `(a, e, mu)` with `a = (e / d)^mu`, `e = D . (P - S)` and `mu` the
/// effective exponent (0 and `a = 1` for an isotropic light); `None` behind
/// the emitter.
#[inline]
fn emission(light: &PointLight, l: DVec3, d: f64) -> Option<(f64, f64, f64)> {
    match light.direction {
        Some(dir) if light.mu > 0.0 => {
            let e = -DVec3::from_array(dir).dot(l);
            // `x^1 = x` exactly: the common LED (mu 1) skips `pow`, a
            // tenth of a photograph's solve.
            let ratio = e / d;
            let aniso = if light.mu == 1.0 {
                ratio
            } else {
                ratio.powf(light.mu)
            };
            (e > 0.0).then_some((aniso, e, light.mu))
        }
        _ => Some((1.0, 1.0, 0.0)),
    }
}

/// One light's irradiance at a surface point and the partial derivatives of
/// its logarithm with respect to `(z, z_x, z_y)`; `None` where the light
/// does not reach the surface (behind it, or outside the emitter's cone).
#[inline]
fn light_term(
    light: &PointLight,
    ray: &PixelRay,
    depth: f64,
    dz_dx: f64,
    dz_dy: f64,
) -> Option<(f64, [f64; 3])> {
    let f = ray.focal_px;
    let (x, y) = (ray.x_px, ray.y_px);
    let (v, l, n) = surface_vectors(light, ray, depth, dz_dx, dz_dy);
    let g = n.dot(l);
    let w2 = n.length_squared();
    let d2 = l.length_squared();
    if !(g > 0.0 && w2 > 0.0 && d2 > 0.0) {
        return None;
    }
    let d = d2.sqrt();
    let (aniso, e, mu) = emission(light, l, d)?;
    // d log a / dz = mu (de/dz) / e with e = -D . L, de/dz = D . v.
    let dlog_aniso_dz = match light.direction {
        Some(dir) if mu > 0.0 => mu * DVec3::from_array(dir).dot(v) / e,
        _ => 0.0,
    };
    let value = light.intensity * aniso * g / (w2.sqrt() * d2 * d);
    // d log I / d theta = mu e'/e - (mu + 3) d'/d + g'/g - W'/W.
    let l_dot_v = l.dot(v);
    let dz = dlog_aniso_dz + (mu + 3.0) * l_dot_v / d2 + (-l.z - n.dot(v)) / g + n.z / w2;
    let dzx = (f * l.x - x * l.z) / g - (f * n.x - x * n.z) / w2;
    let dzy = (f * l.y - y * l.z) / g - (f * n.y - y * n.z) / w2;
    Some((value, [dz, dzx, dzy]))
}

impl Reflectance for NearLights {
    #[inline]
    fn radiance(&self, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64 {
        let sum: f64 = self
            .lights
            .iter()
            .filter_map(|light| light_term(light, ray, depth, dz_dx, dz_dy))
            .map(|(value, _)| value)
            .sum();
        self.intensity_scale * sum
    }

    #[inline]
    fn radiance_with_partials(
        &self,
        ray: &PixelRay,
        depth: f64,
        dz_dx: f64,
        dz_dy: f64,
    ) -> Option<[f64; 4]> {
        let mut out = [0.0; 4];
        for light in &self.lights {
            if let Some((value, dlog)) = light_term(light, ray, depth, dz_dx, dz_dy) {
                out[0] += value;
                out[1] += value * dlog[0];
                out[2] += value * dlog[1];
                out[3] += value * dlog[2];
            }
        }
        Some(out.map(|v| self.intensity_scale * v))
    }
}

/// A surface of any [`Material`] under point lights anywhere (METHOD.md
/// section 10): `I = s sum_k phi_k a_k(P) m(N, L_k, V) / |S_k - P|^2`, with
/// `m` the material's factor. With every light at the optical centre the
/// factor is a function of `c = N . L = z Q / W` alone and the derivatives
/// are exact; otherwise they are central differences in `(z, z_x, z_y)`
/// (the paper's numeric derivatives).
#[derive(Clone, Debug, PartialEq)]
pub struct ShadedLights {
    /// Intensity scale `s` (albedo times the camera's gain).
    pub intensity_scale: f64,
    /// The lights switched on (summed); empty: one at the optical centre.
    pub lights: Vec<PointLight>,
    /// The material (any; Lambert gives back [`NearLights`]' values).
    pub material: Material,
    /// Every light at the optical centre: their summed intensity, folded
    /// into the closed form; `None`: the general model.
    centred_intensity: Option<f64>,
}

impl ShadedLights {
    /// The model of `material` lit by `lights` (empty: the paper's light).
    pub fn new(intensity_scale: f64, lights: &[PointLight], material: Material) -> Self {
        let centred_intensity = is_centred(lights).then(|| summed_intensity(lights));
        ShadedLights {
            intensity_scale,
            lights: lights.to_vec(),
            material,
            centred_intensity,
        }
    }

    /// One light's term `phi a m(N, L, V) / d^2` at `P = z v`.
    #[inline]
    fn term(&self, light: &PointLight, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64 {
        let (v, l, n) = surface_vectors(light, ray, depth, dz_dx, dz_dy);
        let (w2, d2) = (n.length_squared(), l.length_squared());
        if !(n.dot(l) > 0.0 && w2 > 0.0 && d2 > 0.0) {
            return 0.0;
        }
        let d = d2.sqrt();
        let Some((aniso, _, _)) = emission(light, l, d) else {
            return 0.0;
        };
        let to_camera = -v / v.length();
        let factor = self.material.factor(n / w2.sqrt(), l / d, to_camera);
        light.intensity * aniso * factor / d2
    }

    /// Closed form with the lights at the centre: `[R, dR/dz, dR/dzx, dR/dzy]`.
    #[inline]
    fn centred(&self, phi: f64, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> [f64; 4] {
        // c = z Q / W, r^2 = z^2 / Q^2, R = s phi m(c) Q^2 / z^2.
        let f2 = ray.focal_px * ray.focal_px;
        let t = depth + dz_dx * ray.x_px + dz_dy * ray.y_px;
        let w2 = f2 * (dz_dx * dz_dx + dz_dy * dz_dy) + t * t;
        let w = w2.sqrt();
        let q = ray.q();
        let c = (depth * q / w).min(1.0);
        let (m, dm) = self.material.centred(c);
        let k = self.intensity_scale * phi * q * q / (depth * depth);
        let r = k * m;
        // dc/dz = (Q/W)(1 - z t / W^2); dc/dz_x = -(z Q / W^3)(f^2 z_x + t x).
        let dc_dz = q / w * (1.0 - depth * t / w2);
        let common = -depth * q / (w2 * w);
        let dc_dzx = common * (f2 * dz_dx + t * ray.x_px);
        let dc_dzy = common * (f2 * dz_dy + t * ray.y_px);
        [
            r,
            k * dm * dc_dz - 2.0 * r / depth,
            k * dm * dc_dzx,
            k * dm * dc_dzy,
        ]
    }
}

impl Reflectance for ShadedLights {
    #[inline]
    fn radiance(&self, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64 {
        if let Some(phi) = self.centred_intensity {
            return self.centred(phi, ray, depth, dz_dx, dz_dy)[0];
        }
        let sum: f64 = self
            .lights
            .iter()
            .map(|light| self.term(light, ray, depth, dz_dx, dz_dy))
            .sum();
        self.intensity_scale * sum
    }

    #[inline]
    fn radiance_with_partials(
        &self,
        ray: &PixelRay,
        depth: f64,
        dz_dx: f64,
        dz_dy: f64,
    ) -> Option<[f64; 4]> {
        if let Some(phi) = self.centred_intensity {
            return Some(self.centred(phi, ray, depth, dz_dx, dz_dy));
        }
        // Central differences, each step relative to its variable's scale:
        // the depth, and the slope of 45 degrees (z / f) for the gradient.
        let r = self.radiance(ray, depth, dz_dx, dz_dy);
        let h_z = NUMERIC_STEP * depth.abs();
        let slope = depth.abs() / ray.focal_px;
        let h_x = NUMERIC_STEP * dz_dx.abs().max(slope);
        let h_y = NUMERIC_STEP * dz_dy.abs().max(slope);
        let d_z = (self.radiance(ray, depth + h_z, dz_dx, dz_dy)
            - self.radiance(ray, depth - h_z, dz_dx, dz_dy))
            / (2.0 * h_z);
        let d_x = (self.radiance(ray, depth, dz_dx + h_x, dz_dy)
            - self.radiance(ray, depth, dz_dx - h_x, dz_dy))
            / (2.0 * h_x);
        let d_y = (self.radiance(ray, depth, dz_dx, dz_dy + h_y)
            - self.radiance(ray, depth, dz_dx, dz_dy - h_y))
            / (2.0 * h_y);
        Some([r, d_z, d_x, d_y])
    }
}

/// Relative step of [`ShadedLights`]' central differences: truncation
/// `~1e-12`, rounding `~1e-10` of the radiance.
const NUMERIC_STEP: f64 = 1e-6;

/// The reflectance a problem is solved with: the paper's closed form when
/// every light sits at the optical centre (their intensities fold into `s`),
/// the general model otherwise; any material but Lambert through
/// [`ShadedLights`].
#[derive(Clone, Debug, PartialEq)]
pub enum LightModel {
    /// Lights at the optical centre: `s sum(phi) Q^3 / (z W)`.
    Centred(Lambertian),
    /// Lights anywhere.
    Near(NearLights),
    /// A material other than Lambert, lights anywhere.
    Shaded(ShadedLights),
}

impl LightModel {
    /// The model for intensity scale `intensity_scale` and `lights` (empty:
    /// the paper's single light at the optical centre).
    pub fn new(intensity_scale: f64, lights: &[PointLight]) -> Self {
        if is_centred(lights) {
            LightModel::Centred(Lambertian {
                intensity_scale: intensity_scale * summed_intensity(lights),
            })
        } else {
            LightModel::Near(NearLights {
                intensity_scale,
                lights: lights.to_vec(),
            })
        }
    }

    /// The model of `material` for intensity scale `intensity_scale` and
    /// `lights`: [`LightModel::new`]'s for Lambert (the same closed forms and
    /// exact derivatives), [`ShadedLights`] otherwise.
    pub fn with_material(intensity_scale: f64, lights: &[PointLight], material: Material) -> Self {
        if material.is_lambert() {
            Self::new(intensity_scale, lights)
        } else {
            LightModel::Shaded(ShadedLights::new(intensity_scale, lights, material))
        }
    }

    /// The intensity scale `s` this model multiplies by (with centred
    /// Lambertian lights, their summed intensity folded in).
    pub fn intensity_scale(&self) -> f64 {
        match self {
            LightModel::Centred(m) => m.intensity_scale,
            LightModel::Near(m) => m.intensity_scale,
            LightModel::Shaded(m) => m.intensity_scale,
        }
    }
}

impl Reflectance for LightModel {
    #[inline]
    fn radiance(&self, ray: &PixelRay, depth: f64, dz_dx: f64, dz_dy: f64) -> f64 {
        match self {
            LightModel::Centred(m) => m.radiance(ray, depth, dz_dx, dz_dy),
            LightModel::Near(m) => m.radiance(ray, depth, dz_dx, dz_dy),
            LightModel::Shaded(m) => m.radiance(ray, depth, dz_dx, dz_dy),
        }
    }

    #[inline]
    fn radiance_with_partials(
        &self,
        ray: &PixelRay,
        depth: f64,
        dz_dx: f64,
        dz_dy: f64,
    ) -> Option<[f64; 4]> {
        match self {
            LightModel::Centred(m) => m.radiance_with_partials(ray, depth, dz_dx, dz_dy),
            LightModel::Near(m) => m.radiance_with_partials(ray, depth, dz_dx, dz_dy),
            LightModel::Shaded(m) => m.radiance_with_partials(ray, depth, dz_dx, dz_dy),
        }
    }
}

/// Irradiance factor `sum_k phi_k a_k (N . L_k)^+ / |L_k|^3` at camera-space
/// point `point` with unit normal `normal` facing the camera (for renderers
/// that know the true normal).
pub fn irradiance(lights: &[PointLight], point: [f64; 3], normal: [f64; 3]) -> f64 {
    irradiance_with_material(lights, Material::Lambert, point, normal)
}

/// [`irradiance`] of a surface of `material`: `sum_k phi_k a_k m(N, L_k, V)
/// / |L_k|^2` at `point` with unit `normal` facing the camera, `V` the
/// direction from the point to the camera (Lambert: `m = N . L`, computed
/// as `N . (S_k - P) / |L_k|^3`).
pub fn irradiance_with_material(
    lights: &[PointLight],
    material: Material,
    point: [f64; 3],
    normal: [f64; 3],
) -> f64 {
    let (point, normal) = (DVec3::from_array(point), DVec3::from_array(normal));
    let to_camera = -point.normalize_or_zero();
    let centred = [PointLight::CENTRED];
    let lights = if lights.is_empty() {
        &centred[..]
    } else {
        lights
    };
    lights
        .iter()
        .map(|light| {
            let l = DVec3::from_array(light.position) - point;
            let d2 = l.length_squared();
            let cos_n = normal.dot(l);
            if !(cos_n > 0.0 && d2 > 0.0) {
                return 0.0;
            }
            let d = d2.sqrt();
            let Some((aniso, _, _)) = emission(light, l, d) else {
                return 0.0;
            };
            if material.is_lambert() {
                light.intensity * aniso * cos_n / (d2 * d)
            } else {
                light.intensity * aniso * material.factor(normal, l / d, to_camera) / d2
            }
        })
        .sum()
}

/// Warnings for lights that cannot light the object as a solve placed it
/// (`depth`, NaN off the object, through `camera`): a light behind the
/// camera's plane; a light that lights less than half of the object's
/// points, with each point's normal taken as facing the camera (a light
/// beyond the object, or an LED pointing away). Empty when every light can.
pub fn lights_that_miss(
    lights: &[PointLight],
    depth: &crate::grid::Grid<f64>,
    camera: &crate::camera::Intrinsics,
) -> Vec<String> {
    let (w, h) = depth.size();
    // At most about 4096 points of the surface.
    let step = ((w * h) as f64 / 4096.0).sqrt().ceil().max(1.0) as usize;
    let points: Vec<DVec3> = (0..h)
        .step_by(step)
        .flat_map(|r| (0..w).step_by(step).map(move |c| (c, r)))
        .filter_map(|(c, r)| {
            let z = *depth.at(c, r);
            (z.is_finite() && z > 0.0).then(|| {
                let (x, y) = camera.image_xy(c as f64, r as f64);
                DVec3::from_array(camera.back_project(x, y, z))
            })
        })
        .collect();
    if points.is_empty() {
        return Vec::new();
    }
    let mut warnings = Vec::new();
    for (k, light) in lights.iter().enumerate() {
        let s = DVec3::from_array(light.position);
        if light.is_centred() {
            continue;
        }
        if s.z < 0.0 {
            warnings.push(format!(
                "light {} at ({:.3}, {:.3}, {:.3}) is behind the camera (z < 0): check the \
                 sign of its position",
                k + 1,
                s.x,
                s.y,
                s.z
            ));
        }
        let lit = points
            .iter()
            .filter(|&&p| {
                let facing = -p.normalize_or_zero();
                let towards = s - p;
                let aimed = match light.direction {
                    Some(d) if light.mu > 0.0 => DVec3::from_array(d).dot(p - s) > 0.0,
                    _ => true,
                };
                facing.dot(towards) > 0.0 && aimed
            })
            .count();
        if 2 * lit < points.len() {
            let median = {
                let mut z: Vec<f64> = points.iter().map(|p| p.z).collect();
                let middle = z.len() / 2;
                *z.select_nth_unstable_by(middle, f64::total_cmp).1
            };
            warnings.push(format!(
                "light {} at ({:.3}, {:.3}, {:.3}) cannot light most of the object as solved \
                 (median depth {median:.3}): it lights {:.0} % of the surface facing the camera \
                 ({}); check its position{}",
                k + 1,
                s.x,
                s.y,
                s.z,
                100.0 * lit as f64 / points.len() as f64,
                if s.z >= median {
                    "it is beyond the object"
                } else {
                    "it points away or sits behind the surface"
                },
                if light.mu > 0.0 { " and direction" } else { "" }
            ));
        }
    }
    warnings
}

/// The lights of the `--light X,Y,Z` options with their companions
/// (`--light-dir`, `--light-mu`, `--light-intensity`: each given once for
/// all lights or once per light), validated; `None` without a position.
/// Every front (the command line, Python) builds its lights here.
///
/// # Errors
/// A companion without a position, a companion given neither once nor once
/// per light, `mu` without a direction, or an invalid light.
pub fn lights_from_options(
    positions: &[[f64; 3]],
    directions: &[[f64; 3]],
    mus: &[f64],
    intensities: &[f64],
) -> Result<Option<Vec<PointLight>>, String> {
    if positions.is_empty() {
        if !(directions.is_empty() && mus.is_empty() && intensities.is_empty()) {
            return Err("--light-dir, --light-mu and --light-intensity need --light X,Y,Z".into());
        }
        return Ok(None);
    }
    let n = positions.len();
    fn per<T: Copy>(values: &[T], n: usize, name: &str) -> Result<Vec<Option<T>>, String> {
        match values.len() {
            0 => Ok(vec![None; n]),
            1 => Ok(vec![Some(values[0]); n]),
            k if k == n => Ok(values.iter().map(|&v| Some(v)).collect()),
            k => Err(format!(
                "--{name} is given {k} times for {n} --light: give it once or once per light"
            )),
        }
    }
    let directions = per(directions, n, "light-dir")?;
    let mus = per(mus, n, "light-mu")?;
    let intensities = per(intensities, n, "light-intensity")?;
    let mut lights = Vec::with_capacity(n);
    for k in 0..n {
        let light = PointLight {
            position: positions[k],
            direction: directions[k],
            mu: mus[k].unwrap_or(0.0),
            intensity: intensities[k].unwrap_or(1.0),
        };
        if light.mu > 0.0 && light.direction.is_none() {
            return Err(format!(
                "--light-mu {} for light {} needs --light-dir",
                light.mu,
                k + 1
            ));
        }
        lights.push(
            light
                .validated(k + 1)
                .map_err(|e| format!("--light: {e}"))?,
        );
    }
    Ok(Some(lights))
}

#[cfg(test)]
mod tests {
    use super::*;

    const NON_LAMBERT: [Material; 3] = [
        Material::OrenNayar { roughness_rad: 0.4 },
        Material::BlinnPhong {
            specular: 0.3,
            shininess: 30.0,
        },
        Material::BlinnPhong {
            specular: 1.0,
            shininess: 5.0,
        },
    ];

    #[test]
    fn shaded_lambert_is_the_lambertian_model_centred_and_off_centre() {
        let off = [aimed_led()];
        for lights in [&[][..], &off[..]] {
            let shaded = ShadedLights::new(2.0, lights, Material::Lambert);
            let lambert = LightModel::new(2.0, lights);
            for (z, zx, zy) in [(4.0, 0.01, -0.02), (2.5, -0.003, 0.0)] {
                let a = shaded.radiance_with_partials(&ray(), z, zx, zy).unwrap();
                let b = lambert.radiance_with_partials(&ray(), z, zx, zy).unwrap();
                for k in 0..4 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-7 * b[0].abs() * (1.0 + b[k].abs() / b[0]),
                        "{lights:?} slot {k}: {a:?} {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn centred_material_partials_are_exact_and_agree_with_numeric_ones() {
        // The centred closed form against central differences of the
        // general (per light) model with the light at the optical centre.
        for material in NON_LAMBERT {
            let exact = ShadedLights::new(1.7, &[], material);
            let general = ShadedLights {
                centred_intensity: None,
                lights: vec![PointLight::CENTRED],
                ..exact.clone()
            };
            for (z, zx, zy) in [(4.0, 0.004, -0.006), (2.5, -0.01, 0.002), (6.0, 0.0, 0.0)] {
                let a = exact.radiance_with_partials(&ray(), z, zx, zy).unwrap();
                let b = general.radiance_with_partials(&ray(), z, zx, zy).unwrap();
                for k in 0..4 {
                    let scale = if k == 0 { a[0] } else { a[0] / z * 300.0 };
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-6 * scale,
                        "{material:?} slot {k}: exact {a:?} numeric {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn numeric_partials_off_centre_match_differences_of_the_radiance() {
        let lights = [
            aimed_led(),
            PointLight {
                position: [-0.2, 0.1, 0.0],
                direction: None,
                mu: 0.0,
                intensity: 0.7,
            },
        ];
        for material in NON_LAMBERT {
            let model = ShadedLights::new(3.0, &lights, material);
            for (z, zx, zy) in [(4.0, 0.004, -0.006), (2.5, -0.01, 0.002)] {
                let p = model.radiance_with_partials(&ray(), z, zx, zy).unwrap();
                assert!(p.iter().all(|v| v.is_finite()));
                // A coarser difference (1e-4 of the scale) agrees to its
                // own truncation error.
                let r =
                    |dz: f64, dx: f64, dy: f64| model.radiance(&ray(), z + dz, zx + dx, zy + dy);
                let hz = 1e-4 * z;
                let hg = 1e-4 * z / 300.0;
                let coarse = [
                    (r(hz, 0.0, 0.0) - r(-hz, 0.0, 0.0)) / (2.0 * hz),
                    (r(0.0, hg, 0.0) - r(0.0, -hg, 0.0)) / (2.0 * hg),
                    (r(0.0, 0.0, hg) - r(0.0, 0.0, -hg)) / (2.0 * hg),
                ];
                for k in 0..3 {
                    let scale = p[0] / z * if k == 0 { 1.0 } else { 300.0 };
                    assert!(
                        (p[k + 1] - coarse[k]).abs() <= 1e-5 * scale,
                        "{material:?} slot {k}: {p:?} {coarse:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn renderer_irradiance_agrees_with_the_model() {
        // The renderer's value from the true normal against the model's
        // from the depth gradient, for a tilted plane point.
        let lights = [PointLight {
            position: [0.3, -0.1, 0.0],
            direction: None,
            mu: 0.0,
            intensity: 1.0,
        }];
        let r = ray();
        let (z, zx, zy) = (3.0, 0.003, -0.002);
        let f = r.focal_px;
        let point = [z * r.x_px / f, z * r.y_px / f, z];
        let n = DVec3::new(f * zx, f * zy, -(z + r.x_px * zx + r.y_px * zy)).normalize();
        for material in NON_LAMBERT.into_iter().chain([Material::Lambert]) {
            for set in [&[][..], &lights[..]] {
                let model = LightModel::with_material(1.0, set, material);
                let a = model.radiance(&r, z, zx, zy);
                let b = irradiance_with_material(set, material, point, n.to_array());
                assert!((a - b).abs() <= 1e-12 * b, "{material:?} {set:?}: {a} {b}");
            }
        }
    }

    /// An LED off the axis aimed across the field (validated), intensity 1.
    fn aimed_led() -> PointLight {
        PointLight {
            position: [0.8, -0.5, 0.3],
            direction: Some([-0.3, 0.4, 0.87]),
            mu: 1.5,
            ..PointLight::CENTRED
        }
        .validated(1)
        .unwrap()
    }

    fn ray() -> PixelRay {
        PixelRay {
            x_px: 37.0,
            y_px: -21.0,
            focal_px: 300.0,
        }
    }

    #[test]
    fn centred_light_is_the_papers_model() {
        let near = NearLights {
            intensity_scale: 2.5,
            lights: vec![PointLight::CENTRED],
        };
        let paper = Lambertian {
            intensity_scale: 2.5,
        };
        for (z, zx, zy) in [(4.0, 0.01, -0.02), (1.5, -0.003, 0.0), (10.0, 0.05, 0.04)] {
            let a = near.radiance_with_partials(&ray(), z, zx, zy).unwrap();
            let b = paper.radiance_with_partials(&ray(), z, zx, zy).unwrap();
            for k in 0..4 {
                assert!(
                    (a[k] - b[k]).abs() <= 1e-12 * b[k].abs().max(1e-9),
                    "{k}: {a:?} {b:?}"
                );
            }
        }
    }

    #[test]
    fn exact_partials_match_differences_off_centre() {
        let lights = vec![
            aimed_led(),
            PointLight {
                position: [-0.6, 0.2, -0.1],
                direction: None,
                mu: 0.0,
                intensity: 0.7,
            },
        ];
        let model = NearLights {
            intensity_scale: 3.0,
            lights,
        };
        for (z, zx, zy) in [(4.0, 0.004, -0.006), (2.5, -0.01, 0.002), (6.0, 0.0, 0.0)] {
            let exact = model.radiance_with_partials(&ray(), z, zx, zy).unwrap();
            assert!((exact[0] - model.radiance(&ray(), z, zx, zy)).abs() < 1e-15);
            let h = [1e-6 * z, 1e-8, 1e-8];
            let args = [z, zx, zy];
            for k in 0..3 {
                let at = |delta: f64| {
                    let mut a = args;
                    a[k] += delta;
                    model.radiance(&ray(), a[0], a[1], a[2])
                };
                let numeric = (at(h[k]) - at(-h[k])) / (2.0 * h[k]);
                let scale = exact[k + 1].abs().max(1e-6 * exact[0] / z);
                assert!(
                    (numeric - exact[k + 1]).abs() < 1e-5 * scale,
                    "partial {k} at {args:?}: numeric {numeric} exact {}",
                    exact[k + 1]
                );
            }
        }
    }

    #[test]
    fn light_behind_the_surface_gives_no_light() {
        // A plane facing +x (steep) lit from the -x side.
        let model = NearLights {
            intensity_scale: 1.0,
            lights: vec![PointLight {
                position: [-100.0, 0.0, 0.0],
                ..PointLight::CENTRED
            }],
        };
        let r = PixelRay {
            x_px: 0.0,
            y_px: 0.0,
            focal_px: 100.0,
        };
        // z_x < 0 strongly: the normal turns towards -x... and +x for z_x > 0.
        assert!(model.radiance(&r, 5.0, -1.0, 0.0) > 0.0);
        assert_eq!(model.radiance(&r, 5.0, 1.0, 0.0), 0.0);
    }

    #[test]
    fn irradiance_matches_the_model_on_a_plane() {
        let lights = vec![PointLight {
            position: [0.4, 0.1, 0.2],
            direction: Some([0.0, 0.0, 1.0]),
            mu: 1.0,
            intensity: 2.0,
        }];
        let model = NearLights {
            intensity_scale: 1.0,
            lights: lights.clone(),
        };
        // Fronto-parallel plane at z = 3: N = (0, 0, -1).
        let r = ray();
        let point = [3.0 * r.x_px / r.focal_px, 3.0 * r.y_px / r.focal_px, 3.0];
        let a = irradiance(&lights, point, [0.0, 0.0, -1.0]);
        let b = model.radiance(&r, 3.0, 0.0, 0.0);
        assert!((a - b).abs() < 1e-12 * b, "{a} {b}");
    }

    #[test]
    fn validation_names_the_field() {
        let bad = PointLight {
            mu: -1.0,
            ..PointLight::CENTRED
        };
        assert!(bad.validated(2).unwrap_err().contains("light 2: mu"));
        let bad = PointLight {
            direction: Some([0.0; 3]),
            mu: 1.0,
            ..PointLight::CENTRED
        };
        assert!(bad.validated(1).unwrap_err().contains("direction"));
    }
}
