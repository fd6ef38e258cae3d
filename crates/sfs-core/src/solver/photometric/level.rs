//! One pyramid level of a photometric-stereo solve: its photographs and
//! weights, and the passes over its pixels (lights at the current surface,
//! the albedo eliminated per pixel, robust weights, the data part of the
//! system, the energy, the distance search along the rays, the
//! photographs' intensities).

use glam::DVec3;
use rayon::prelude::*;

use super::linear::{GradientForm, gradient, second_derivatives, valid_pairs};
use crate::camera::Intrinsics;
use crate::light::PointLight;
use crate::model::{charbonnier, charbonnier_derivative};

/// A value below this share of the brightest of its pixel is dark.
const DARK_SHARE: f64 = 0.1;

/// The most photographs a pixel's pass keeps on the stack.
pub(super) const MAX_PHOTOS: usize = 64;

/// A level's photographs and what is trusted of them.
pub(super) struct Level {
    pub width: usize,
    pub height: usize,
    /// Intrinsics at this level's size.
    pub camera: Intrinsics,
    /// Pixels whose depth is solved.
    pub domain: Vec<bool>,
    /// Each photograph's linear values.
    pub images: Vec<Vec<f64>>,
    /// Each photograph's weight per pixel: confidence, its own mask, 0
    /// where saturated.
    pub weights: Vec<Vec<f64>>,
}

/// The scales a solve's passes share: the Cauchy scale of the residuals
/// and the dark level (image units), the reference brightness the data term
/// is divided by, the smoothness weight `alpha` (relative) and Charbonnier
/// `lambda`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Scales {
    pub robust_scale: f64,
    /// Values at or below this are dark (a shadow can explain them).
    pub dark_level: f64,
    pub brightness: f64,
    pub alpha: f64,
    pub lambda: f64,
}

/// What the passes read besides the depth: the lights, each photograph's
/// intensity (relative; the lights' own when given), the cast shadow per
/// photograph and pixel (empty: none computed) and the scales.
#[derive(Clone)]
pub(super) struct Shared<'a> {
    pub lights: &'a [PointLight],
    pub intensities: &'a [f64],
    pub cast: &'a [Vec<bool>],
    pub robust_scale: f64,
    pub dark_level: f64,
    pub brightness: f64,
    pub alpha: f64,
    pub lambda: f64,
}

impl<'a> Shared<'a> {
    /// The passes' view of a state.
    pub fn new(
        lights: &'a [PointLight],
        intensities: &'a [f64],
        cast: &'a [Vec<bool>],
        scales: Scales,
    ) -> Self {
        Self {
            lights,
            intensities,
            cast,
            robust_scale: scales.robust_scale,
            dark_level: scales.dark_level,
            brightness: scales.brightness,
            alpha: scales.alpha,
            lambda: scales.lambda,
        }
    }
}

/// One observation at a pixel: its gradient coefficients, `L_z`, the
/// predicted shading `u` (`I = m u`), the observed value and its weight.
#[derive(Clone, Copy, Default)]
pub(super) struct Observation {
    pub a: [f64; 2],
    /// `du / dzeta` at the pixel (the lights seen from a point moved along
    /// its ray).
    pub du: f64,
    pub u: f64,
    pub value: f64,
    pub weight: f64,
}

/// What [`Level::observe`] found at a pixel besides its observations.
#[derive(Clone, Copy)]
pub(super) struct Observed {
    /// The number of observations.
    pub n: usize,
    /// The gradient chosen (the pairs' weighted mean).
    pub g: [f64; 2],
    /// The weights of the valid difference pairs (summing to 1).
    pub pair_weights: [f64; 4],
}

/// What a pixel's observations say.
#[derive(Clone, Copy, Default)]
pub(super) struct PixelFit {
    /// `rho / |n|` (the albedo over the normal's length in log-depth terms).
    pub m: f64,
    /// `sum w r^2` with Cauchy weights (IRLS), image units squared.
    pub data: f64,
    /// The robust data energy `sum base * s^2 log(1 + r^2 / s^2)`.
    pub robust: f64,
}

/// The smoothness at a surface: its lagged weights and its energy (not
/// yet times alpha).
pub(super) struct SmoothnessAt {
    pub weights: super::linear::Smoothness,
    pub energy: f64,
}

/// The light vector `L = phi a(P) (S - P) / |S - P|^3` of a light at a
/// point `P`, and its derivative along the ray, `dL / dzeta` for `P =
/// e^zeta ray` (so `dP / dzeta = P`).
#[inline]
pub(super) fn light_vector(light: &PointLight, intensity: f64, point: DVec3) -> (DVec3, DVec3) {
    let d = DVec3::from_array(light.position) - point;
    let r2 = d.length_squared();
    if r2.is_nan() || r2 <= 0.0 {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    let r = r2.sqrt();
    let r3 = r2 * r;
    let dp = d.dot(point);
    // d(d / r^3) / dzeta = -P / r^3 + 3 d (d . P) / r^5.
    let d_shape = -point / r3 + d * (3.0 * dp / (r3 * r2));
    let (anisotropy, d_anisotropy) = match light.direction {
        Some(dir) if light.mu > 0.0 => {
            let dir = DVec3::from_array(dir);
            let t = -dir.dot(d) / r;
            if t > 0.0 {
                // dt / dzeta = (D . P) / r - (D . d)(d . P) / r^3.
                let dt = dir.dot(point) / r - dir.dot(d) * dp / r3;
                let a = if light.mu == 1.0 { t } else { t.powf(light.mu) };
                (a, light.mu * a / t * dt)
            } else {
                (0.0, 0.0)
            }
        }
        _ => (1.0, 0.0),
    };
    let l = d / r3;
    (
        l * (intensity * anisotropy),
        (l * d_anisotropy + d_shape * anisotropy) * intensity,
    )
}

/// The Cauchy weight `1 / (1 + r^2 / s^2)`.
#[inline]
fn cauchy_weight(r: f64, scale: f64) -> f64 {
    1.0 / (1.0 + (r / scale) * (r / scale))
}

impl Level {
    /// Number of photographs.
    pub fn photos(&self) -> usize {
        self.images.len()
    }

    /// Image-plane coordinates of pixel `p`.
    #[inline]
    fn xy(&self, p: usize) -> (f64, f64) {
        self.camera
            .image_xy((p % self.width) as f64, (p / self.width) as f64)
    }

    /// The observations at pixel `p` for log-depth `zeta[p] + shift`: the
    /// lights at the surface point, and the gradient chosen among the
    /// pixel's forward/backward difference pairs (each weighted by how well
    /// it explains the photographs, so that a pair reaching across a depth
    /// jump counts for little), with the shading `u` and weights for it (0
    /// in attached or cast shadow where dark, saturated or untrusted).
    #[inline]
    pub fn observe(
        &self,
        shared: &Shared<'_>,
        zeta: &[f64],
        p: usize,
        shift: f64,
        out: &mut [Observation; MAX_PHOTOS],
    ) -> Observed {
        let (x, y) = self.xy(p);
        let f = self.camera.focal_px;
        let z = (zeta[p] + shift).exp();
        let point = DVec3::new(z * x / f, z * y / f, z);
        let n = self.photos().min(MAX_PHOTOS);
        let mut lz = [0.0; MAX_PHOTOS];
        let mut da = [[0.0; 3]; MAX_PHOTOS];
        for j in 0..n {
            let (l, dl) = light_vector(&shared.lights[j], shared.intensities[j], point);
            lz[j] = l.z;
            da[j] = [f * dl.x - x * dl.z, f * dl.y - y * dl.z, dl.z];
            out[j] = Observation {
                a: [f * l.x - x * l.z, f * l.y - y * l.z],
                du: 0.0,
                u: 0.0,
                value: self.images[j][p],
                weight: self.weights[j][p],
            };
        }
        let brightest = out[..n]
            .iter()
            .filter(|o| o.weight > 0.0)
            .map(|o| o.value)
            .fold(0.0, f64::max);
        let dark = shared.dark_level.max(DARK_SHARE * brightest);
        let (pairs, count) = valid_pairs(&self.domain, self.width, p);
        let mut pair_weights = [0.0; 4];
        let g = if count == 0 {
            gradient(zeta, &self.domain, self.width, p)
        } else {
            let w = self.width as isize;
            let mut gradients = [[0.0; 2]; 4];
            let mut errors = [0.0; 4];
            for (k, &(sx, sy)) in pairs[..count].iter().enumerate() {
                let a = (p as isize + sx) as usize;
                let b = (p as isize + sy * w) as usize;
                let g = [
                    sx as f64 * (zeta[a] - zeta[p]),
                    sy as f64 * (zeta[b] - zeta[p]),
                ];
                gradients[k] = g;
                let (mut num, mut den, mut weight, mut ii) = (0.0, 0.0, 0.0, 0.0);
                for j in 0..n {
                    let o = &out[j];
                    let u = o.a[0] * g[0] + o.a[1] * g[1] - lz[j];
                    let wt = if o.value <= dark && self.in_shadow(shared, j, p, u) {
                        0.0
                    } else {
                        o.weight
                    };
                    num += wt * u * o.value;
                    den += wt * u * u;
                    weight += wt;
                    ii += wt * o.value * o.value;
                }
                // The least-squares residual with m fitted: sum w I^2 -
                // (sum w u I)^2 / sum w u^2, per unit weight.
                let explained = if den > 0.0 { num * num / den } else { 0.0 };
                errors[k] = (ii - explained).max(0.0) / weight.max(1e-300);
            }
            let b2 = shared.brightness * shared.brightness;
            let tau2 = (shared.robust_scale * shared.robust_scale / b2).max(1e-12);
            let least = errors[..count]
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            let mut total = 0.0;
            for k in 0..count {
                pair_weights[k] = 1.0 / (1.0 + (errors[k] - least) / (b2 * tau2));
                total += pair_weights[k];
            }
            let mut g = [0.0; 2];
            for k in 0..count {
                pair_weights[k] /= total;
                g[0] += pair_weights[k] * gradients[k][0];
                g[1] += pair_weights[k] * gradients[k][1];
            }
            g
        };
        for j in 0..n {
            let o = &mut out[j];
            o.u = o.a[0] * g[0] + o.a[1] * g[1] - lz[j];
            o.du = da[j][0] * g[0] + da[j][1] * g[1] - da[j][2];
            if o.value <= dark && self.in_shadow(shared, j, p, o.u) {
                o.weight = 0.0;
            }
        }
        Observed { n, g, pair_weights }
    }

    /// Whether the surface puts pixel `p` in the shadow of light `j`: it
    /// turns away from it (`u <= 0`) or the surface hides it.
    #[inline]
    pub fn in_shadow(&self, shared: &Shared<'_>, j: usize, p: usize, u: f64) -> bool {
        u <= 0.0 || shared.cast.get(j).is_some_and(|c| c[p])
    }

    /// The albedo factor `m` by weighted least squares over the pixel's
    /// observations, refined by two Cauchy reweightings; the weights left
    /// in `obs` are the robust ones.
    #[inline]
    pub fn fit_pixel(shared: &Shared<'_>, obs: &mut [Observation], previous_m: f64) -> PixelFit {
        let solve = |obs: &[Observation]| {
            let (num, den) = obs.iter().fold((0.0, 0.0), |(n, d), o| {
                (n + o.weight * o.u * o.value, d + o.weight * o.u * o.u)
            });
            if den > 0.0 {
                (num / den).max(0.0)
            } else {
                previous_m
            }
        };
        let base: [f64; MAX_PHOTOS] = std::array::from_fn(|j| obs.get(j).map_or(0.0, |o| o.weight));
        let mut m = solve(obs);
        let scale = shared.robust_scale;
        for _ in 0..2 {
            for (o, &b) in obs.iter_mut().zip(&base) {
                o.weight = b * cauchy_weight(m * o.u - o.value, scale);
            }
            m = solve(obs);
        }
        let mut fit = PixelFit {
            m,
            ..PixelFit::default()
        };
        for (o, &b) in obs.iter_mut().zip(&base) {
            let r = m * o.u - o.value;
            o.weight = b * cauchy_weight(r, scale);
            fit.data += o.weight * r * r;
            fit.robust += b * scale * scale * (1.0 + (r / scale) * (r / scale)).ln();
        }
        fit
    }

    /// One linearisation: at every domain pixel the albedo factor
    /// (eliminated), the robust weights and the quadratic form of the data
    /// term in the gradient, divided by the brightness squared. Returns the
    /// forms, the albedo factors and the robust data energy.
    pub fn linearise(
        &self,
        shared: &Shared<'_>,
        zeta: &[f64],
        m_previous: &[f64],
    ) -> (Vec<GradientForm>, Vec<f64>, f64) {
        let b2 = shared.brightness * shared.brightness;
        // Unzipped as they are made: no third copy of the forms.
        let (forms, fits): (Vec<GradientForm>, Vec<(f64, f64)>) = (0..zeta.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|p| {
                if !self.domain[p] {
                    return (GradientForm::default(), (0.0, 0.0));
                }
                let mut obs = [Observation::default(); MAX_PHOTOS];
                let seen = self.observe(shared, zeta, p, 0.0, &mut obs);
                let (n, g) = (seen.n, seen.g);
                let fit = Self::fit_pixel(shared, &mut obs[..n], m_previous[p]);
                let m = fit.m;
                // The Jacobian of m u_j in (zeta_x, zeta_y, zeta), with m's
                // own dependence projected out (variable projection: m is
                // the weighted least-squares albedo factor of every step).
                let (mut uu, mut proj) = (0.0, [0.0; 3]);
                for o in &obs[..n] {
                    let column = [m * o.a[0], m * o.a[1], m * o.du];
                    uu += o.weight * o.u * o.u;
                    for (s, c) in proj.iter_mut().zip(column) {
                        *s += o.weight * o.u * c;
                    }
                }
                if uu > 0.0 {
                    for s in &mut proj {
                        *s /= uu;
                    }
                }
                let v0 = [g[0], g[1], zeta[p]];
                let mut form = GradientForm {
                    pair_weights: seen.pair_weights,
                    ..GradientForm::default()
                };
                for o in &obs[..n] {
                    if o.weight <= 0.0 {
                        continue;
                    }
                    let column = [
                        m * o.a[0] - o.u * proj[0],
                        m * o.a[1] - o.u * proj[1],
                        m * o.du - o.u * proj[2],
                    ];
                    let r0 = m * o.u - o.value;
                    let at_v0 = column[0] * v0[0] + column[1] * v0[1] + column[2] * v0[2];
                    form.add(column, o.weight / b2, at_v0 - r0);
                }
                (form, (m, fit.robust / b2))
            })
            .unzip();
        let mut ms = Vec::with_capacity(fits.len());
        let mut data = 0.0;
        for (m, e) in fits {
            ms.push(m);
            data += e;
        }
        (forms, ms, data)
    }

    /// The lagged Charbonnier weights of the smoothness at `zeta`, times
    /// `alpha f^4`, per second difference that fits the domain.
    pub fn smoothness_weights(&self, shared: &Shared<'_>, zeta: &[f64]) -> SmoothnessAt {
        let w = self.width;
        let f4 = self.camera.focal_px.powi(4);
        let per_pixel: Vec<([f64; 3], f64)> = (0..zeta.len())
            .into_par_iter()
            .with_min_len(1024)
            .map(|p| {
                if !self.domain[p] {
                    return ([0.0; 3], 0.0);
                }
                let (vxx, vxy, vyy) = super::linear::second_valid(&self.domain, w, p);
                let [xx, xy, yy] = second_derivatives(zeta, &self.domain, w, p);
                let s2 = f4 * (xx * xx + 2.0 * xy * xy + yy * yy);
                let k = shared.alpha * f4 * charbonnier_derivative(s2, shared.lambda);
                (
                    [
                        if vxx { k } else { 0.0 },
                        if vxy { k } else { 0.0 },
                        if vyy { k } else { 0.0 },
                    ],
                    charbonnier(s2, shared.lambda),
                )
            })
            .collect();
        SmoothnessAt {
            weights: super::linear::Smoothness {
                kxx: per_pixel.iter().map(|v| v.0[0]).collect(),
                kxy: per_pixel.iter().map(|v| v.0[1]).collect(),
                kyy: per_pixel.iter().map(|v| v.0[2]).collect(),
            },
            energy: per_pixel.iter().map(|v| v.1).sum(),
        }
    }

    /// The weighted least-squares data energy of `zeta + shift` with the
    /// gradient as it is and the albedo eliminated per pixel, over every
    /// `stride`-th domain pixel: what the distance along the rays is
    /// chosen by.
    pub fn shifted_data(
        &self,
        shared: &Shared<'_>,
        zeta: &[f64],
        shift: f64,
        stride: usize,
    ) -> f64 {
        // Collected, then summed in order: the same bits on every run.
        let values: Vec<f64> = (0..zeta.len())
            .into_par_iter()
            .step_by(stride.max(1))
            .with_min_len(256)
            .map(|p| {
                if !self.domain[p] {
                    return 0.0;
                }
                let mut obs = [Observation::default(); MAX_PHOTOS];
                let n = self.observe(shared, zeta, p, shift, &mut obs).n;
                Self::fit_pixel(shared, &mut obs[..n], 0.0).robust
            })
            .collect();
        values.iter().sum()
    }

    /// Each photograph's residuals `m u - I` (0 off the domain), whether it
    /// was used (trusted, lit, robust weight at least a half), and the
    /// prediction `max(0, m u)`.
    pub fn residuals(
        &self,
        shared: &Shared<'_>,
        zeta: &[f64],
        m_previous: &[f64],
    ) -> Vec<Vec<(f64, f64, u8)>> {
        let per_pixel: Vec<Vec<(f64, f64, u8)>> = (0..zeta.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|p| {
                let j_count = self.photos();
                if !self.domain[p] {
                    return vec![(0.0, 0.0, LEFT_OUT_OFF); j_count];
                }
                let mut obs = [Observation::default(); MAX_PHOTOS];
                let n = self.observe(shared, zeta, p, 0.0, &mut obs).n;
                let base: Vec<f64> = obs[..n].iter().map(|o| o.weight).collect();
                let fit = Self::fit_pixel(shared, &mut obs[..n], m_previous[p]);
                (0..n)
                    .map(|j| {
                        let o = obs[j];
                        let predicted = (fit.m * o.u).max(0.0);
                        let why = if self.weights[j][p] <= 0.0 {
                            LEFT_OUT_UNTRUSTED
                        } else if base[j] <= 0.0 {
                            LEFT_OUT_SHADOW
                        } else if base[j] > 0.0 && o.weight < 0.5 * base[j] {
                            LEFT_OUT_ROBUST
                        } else {
                            USED
                        };
                        (predicted - o.value, predicted, why)
                    })
                    .collect()
            })
            .collect();
        per_pixel
    }

    /// Each photograph's intensity refitted to the current surface (least
    /// squares of its observations against the prediction), normalised to a
    /// geometric mean of 1.
    pub fn refit_intensities(&self, shared: &Shared<'_>, zeta: &[f64], m: &[f64]) -> Vec<f64> {
        let j_count = self.photos();
        // Per row, then summed in order: the same bits on every run.
        let rows: Vec<Vec<(f64, f64)>> = (0..self.height)
            .into_par_iter()
            .map(|r| {
                let mut acc = vec![(0.0, 0.0); j_count];
                let first = r * self.width;
                for (p, &m_p) in m.iter().enumerate().skip(first).take(self.width) {
                    if self.domain[p] && m_p > 0.0 {
                        let mut obs = [Observation::default(); MAX_PHOTOS];
                        let n = self.observe(shared, zeta, p, 0.0, &mut obs).n;
                        let _ = Self::fit_pixel(shared, &mut obs[..n], m_p);
                        for (j, o) in obs[..n].iter().enumerate() {
                            let predicted = m_p * o.u;
                            acc[j].0 += o.weight * predicted * o.value;
                            acc[j].1 += o.weight * predicted * predicted;
                        }
                    }
                }
                acc
            })
            .collect();
        let mut sums = vec![(0.0, 0.0); j_count];
        for row in rows {
            for (total, part) in sums.iter_mut().zip(row) {
                total.0 += part.0;
                total.1 += part.1;
            }
        }
        let mut next: Vec<f64> = shared
            .intensities
            .iter()
            .zip(&sums)
            .map(|(&phi, &(num, den))| {
                if den > 0.0 && num > 0.0 {
                    phi * num / den
                } else {
                    phi
                }
            })
            .collect();
        let log_mean = next.iter().map(|v| v.ln()).sum::<f64>() / next.len().max(1) as f64;
        let k = (-log_mean).exp();
        for v in &mut next {
            *v *= k;
        }
        next
    }
}

/// Why an observation was used or left out (the residuals' flag).
pub const USED: u8 = 0;
/// Left out: untrusted (confidence 0, its own mask, saturated).
pub const LEFT_OUT_UNTRUSTED: u8 = 1;
/// Left out: in attached or cast shadow of the current surface.
pub const LEFT_OUT_SHADOW: u8 = 2;
/// Kept with less than half its weight by the robust estimator.
pub const LEFT_OUT_ROBUST: u8 = 3;
/// Off the domain.
pub const LEFT_OUT_OFF: u8 = 4;
