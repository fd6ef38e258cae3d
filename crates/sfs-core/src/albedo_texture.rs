//! Fine texture read as albedo: hair (a beard, stubble, brows) is a dense
//! texture of dark strands, a pixel or two wide, that darkens a region
//! gradually, without the sharp step the L0 edge prior of `albedo` finds.
//! Shading from a smooth surface has no such texture, so where the log
//! brightness is rough at the pixel scale the surface is darker than its
//! shape explains.
//!
//! The texture is the local root mean square of the log brightness minus
//! its blur over [`DETAIL_SIGMA_PX`] pixels, pooled over
//! [`POOL_SIGMA_PX`] pixels, with what the image's noise puts there taken
//! out (the noise of a log is `sigma / I`, so a dark, noisy render is not
//! textured), less the object's median [`BASE_PERCENTILE`] (the untextured
//! material's own grain: skin has pores; at most half the object is hair). How
//! much darker a unit of texture makes the albedo is measured in the image
//! itself: the log brightness left once the edge estimate is divided out
//! is regressed on the texture between two blurs of 1/324 and 1/81 of the
//! object's side (larger than the texture, smaller than the shading of a
//! face's features). The slope is used only when it is negative and the
//! two agree at a correlation of at least [`MIN_CORRELATION`] in
//! magnitude; otherwise the texture says nothing (a render's patches,
//! lines or noise). Measured on the shared face (LED 4, 648 px, the nose's
//! distance given): the texture alone correlates -0.80 with the log of the
//! seven photographs' albedo, the edge estimate 0.51 (docs/albedo.md,
//! step 6).
//! Pure functions over `grid` and `resample`, polling a `Cancel`.

use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::grid::for_rows;
use crate::resample::{gaussian_kernel, resize_area};

/// The blur (standard deviation, pixels of the image) whose residual is the
/// texture's detail: the scale of a strand of hair.
pub const DETAIL_SIGMA_PX: f64 = 1.0;
/// The blur (pixels of the image) over which the detail's power is pooled.
pub const POOL_SIGMA_PX: f64 = 4.0;
/// The object's percentile of texture taken as the untextured material's
/// own (at most half the object is hair). Measured on the face's seven LEDs
/// alone at 648 px: the 10th percentile darkened 55 % of the face and made
/// four of the six other LEDs 1.5-2.2 degrees worse (mean 28.9 against the
/// edges' 28.8); the median, mean 28.3.
pub const BASE_PERCENTILE: f64 = 0.5;
/// The least magnitude of correlation between texture and the brightness
/// left by the edges for the slope to be used: the 32 local albedo renders'
/// fine geometry (the Dragon's scales, Suzanne's facets) reached 0.30; the
/// face 0.41-0.63 (432-1296 px).
pub const MIN_CORRELATION: f64 = 0.4;
/// Longest side of the copy the texture is measured on: the same albedo
/// whatever the photograph's size (a strand's pixel at this size).
pub const TEXTURE_SIDE: usize = 648;
/// The two blurs of the regression's band, as fractions of that side.
const BAND: (f64, f64) = (1.0 / 324.0, 1.0 / 81.0);
/// The least share of the blurred mask for a pixel to enter the regression
/// (away from the object's border).
const INTERIOR: f64 = 0.9;

/// What the texture said, in numbers (the solve report's
/// `albedo_fit.texture`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TextureSummary {
    /// The slope: change of log albedo per unit of texture (negative:
    /// textured is darker); NaN when it could not be measured.
    pub log_slope: f64,
    /// The band-passed correlation of texture and brightness it rests on.
    pub correlation: f64,
    /// Whether the slope is used.
    pub used: bool,
    /// Share of the trusted object darkened by more than 10 %.
    pub darkened_share: f64,
}

impl TextureSummary {
    /// Nothing measured, nothing used.
    pub const UNMEASURED: Self = Self {
        log_slope: f64::NAN,
        correlation: f64::NAN,
        used: false,
        darkened_share: 0.0,
    };
}

/// What the texture says about the albedo.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureAlbedo {
    /// Per pixel of the copy of at most [`TEXTURE_SIDE`] pixels, the factor
    /// the texture multiplies the albedo by (1 where it is not used or not
    /// textured).
    pub factor: Grid<f64>,
    /// The copy's trusted pixels (where `factor` was measured).
    pub inside: Grid<bool>,
    /// The slope, its correlation and what it did.
    pub summary: TextureSummary,
}

/// The texture's albedo factor for `image` (linear, >= 0; its noise
/// `noise_sigma` in image units) over `trusted` pixels, given the edge
/// estimate `albedo` at the same size.
///
/// # Errors
/// `Cancelled` when `cancel` says so.
pub fn texture_albedo(
    image: &Grid<f64>,
    albedo: &Grid<f64>,
    trusted: &Grid<bool>,
    noise_sigma: f64,
    cancel: Cancel<'_>,
) -> Result<TextureAlbedo, Cancelled> {
    // The copy: area averages of the image and of the edges' log albedo
    // over trusted pixels, its noise that of a k x k average.
    let (fw, fh) = image.size();
    let (w, h) = crate::resample::working_size(fw, fh, Some(TEXTURE_SIDE));
    let k = fw.max(fh) as f64 / w.max(h) as f64;
    let noise_sigma = noise_sigma / k;
    let mass = resize_area(&trusted.map(|&t| f64::from(u8::from(t))), w, h, cancel)?;
    let average = |values: Grid<f64>| -> Result<Vec<f64>, Cancelled> {
        let weighted = values.zip_map(trusted, |v, &t| if t { *v } else { 0.0 });
        let sum = resize_area(&weighted, w, h, cancel)?;
        Ok(sum
            .as_slice()
            .iter()
            .zip(mass.as_slice())
            .map(|(s, m)| if *m > 0.0 { s / m } else { 0.0 })
            .collect())
    };
    let small_image = average(image.clone())?;
    let small_log_albedo = average(albedo.map(|a| a.max(1e-12).ln()))?;
    let floor = (2.0 * noise_sigma).max(1e-4);
    let weight: Vec<f64> = mass
        .as_slice()
        .iter()
        .zip(&small_image)
        .map(|(&m, &v)| if m >= 0.5 && v > floor { 1.0 } else { 0.0 })
        .collect();
    let log: Vec<f64> = small_image.iter().map(|&v| v.max(floor).ln()).collect();
    // The detail and its pooled power, with the noise's share taken out.
    let smooth_log = masked_blur(&log, &weight, w, h, DETAIL_SIGMA_PX, cancel)?;
    let detail_power: Vec<f64> = log
        .iter()
        .zip(&smooth_log)
        .map(|(l, s)| (l - s).powi(2))
        .collect();
    let power = masked_blur(&detail_power, &weight, w, h, POOL_SIGMA_PX, cancel)?;
    let brightness = masked_blur(&small_image, &weight, w, h, POOL_SIGMA_PX, cancel)?;
    let gain = detail_noise_gain(DETAIL_SIGMA_PX);
    let texture: Vec<f64> = (0..w * h)
        .map(|q| {
            if weight[q] == 0.0 {
                return 0.0;
            }
            let noise = gain * (noise_sigma / brightness[q].max(floor)).powi(2);
            (power[q] - noise).max(0.0).sqrt()
        })
        .collect();
    let mut values: Vec<f64> = (0..w * h)
        .filter(|&q| weight[q] > 0.0)
        .map(|q| texture[q])
        .collect();
    let inside = Grid::from_vec(w, h, weight.iter().map(|&v| v > 0.0).collect())
        .unwrap_or_else(|| Grid::filled(w, h, false));
    let unused = |log_slope: f64, correlation: f64| TextureAlbedo {
        factor: Grid::filled(w, h, 1.0),
        inside: inside.clone(),
        summary: TextureSummary {
            log_slope,
            correlation,
            ..TextureSummary::UNMEASURED
        },
    };
    if values.len() < 16 {
        return Ok(unused(f64::NAN, f64::NAN));
    }
    let rank = ((values.len() - 1) as f64 * BASE_PERCENTILE).round() as usize;
    let base = *values.select_nth_unstable_by(rank, f64::total_cmp).1;
    let excess: Vec<f64> = texture.iter().map(|t| (t - base).max(0.0)).collect();
    // What the edges leave of the log brightness.
    let left: Vec<f64> = log
        .iter()
        .zip(&small_log_albedo)
        .map(|(l, a)| l - a)
        .collect();
    let (log_slope, correlation) = band_regression(&excess, &left, &weight, w, h, cancel)?;
    if !(log_slope < 0.0 && correlation <= -MIN_CORRELATION) {
        return Ok(unused(log_slope, correlation));
    }
    let factor: Vec<f64> = excess.iter().map(|e| (log_slope * e).exp()).collect();
    let trusted_count = weight.iter().filter(|&&v| v > 0.0).count();
    let darkened = (0..w * h)
        .filter(|&q| weight[q] > 0.0 && factor[q] < 0.9)
        .count();
    Ok(TextureAlbedo {
        factor: Grid::from_vec(w, h, factor).unwrap_or_else(|| Grid::filled(w, h, 1.0)),
        inside,
        summary: TextureSummary {
            log_slope,
            correlation,
            used: true,
            darkened_share: darkened as f64 / trusted_count.max(1) as f64,
        },
    })
}

/// The slope and correlation of `y` on `x` between the two blurs of
/// [`BAND`] over the interior pixels of `weight`.
fn band_regression(
    x: &[f64],
    y: &[f64],
    weight: &[f64],
    w: usize,
    h: usize,
    cancel: Cancel<'_>,
) -> Result<(f64, f64), Cancelled> {
    let side = w.max(h) as f64;
    let band = |v: &[f64]| -> Result<Vec<f64>, Cancelled> {
        let fine = masked_blur(v, weight, w, h, side * BAND.0, cancel)?;
        let coarse = masked_blur(v, weight, w, h, side * BAND.1, cancel)?;
        Ok(fine.iter().zip(&coarse).map(|(a, b)| a - b).collect())
    };
    let (xb, yb) = (band(x)?, band(y)?);
    let interior = blur(weight, w, h, side * BAND.1, cancel)?;
    let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for q in 0..w * h {
        if weight[q] > 0.0 && interior[q] >= INTERIOR {
            let (a, b) = (xb[q], yb[q]);
            n += 1.0;
            sx += a;
            sy += b;
            sxx += a * a;
            syy += b * b;
            sxy += a * b;
        }
    }
    if n < 16.0 {
        return Ok((f64::NAN, f64::NAN));
    }
    let vx = sxx - sx * sx / n;
    let vy = syy - sy * sy / n;
    let cxy = sxy - sx * sy / n;
    if !(vx > 0.0 && vy > 0.0) {
        return Ok((f64::NAN, f64::NAN));
    }
    Ok((cxy / vx, cxy / (vx * vy).sqrt()))
}

/// The variance a unit of white noise leaves in `x - G * x` for a Gaussian
/// `G` of `sigma_px` (as [`blur`] samples it): `sum (delta - g)^2`.
fn detail_noise_gain(sigma_px: f64) -> f64 {
    let kernel = gaussian_kernel(sigma_px);
    let radius = kernel.len() / 2;
    let mut gain = 0.0;
    for (i, a) in kernel.iter().enumerate() {
        for (j, b) in kernel.iter().enumerate() {
            let delta = if i == radius && j == radius { 1.0 } else { 0.0 };
            gain += (delta - a * b).powi(2);
        }
    }
    gain
}

/// The mean of `values` over pixels of `weight` near each pixel: the blur
/// of `values * weight` over the blur of `weight` (0 where that is 0).
fn masked_blur(
    values: &[f64],
    weight: &[f64],
    w: usize,
    h: usize,
    sigma_px: f64,
    cancel: Cancel<'_>,
) -> Result<Vec<f64>, Cancelled> {
    let weighted: Vec<f64> = values.iter().zip(weight).map(|(v, m)| v * m).collect();
    let top = blur(&weighted, w, h, sigma_px, cancel)?;
    let bottom = blur(weight, w, h, sigma_px, cancel)?;
    Ok(top
        .iter()
        .zip(&bottom)
        .map(|(t, b)| if *b > 1e-9 { t / b } else { 0.0 })
        .collect())
}

/// Separable Gaussian blur of a `w` x `h` image, zero outside it; rows in
/// parallel, polling `cancel` per row.
fn blur(
    values: &[f64],
    w: usize,
    h: usize,
    sigma_px: f64,
    cancel: Cancel<'_>,
) -> Result<Vec<f64>, Cancelled> {
    let kernel = gaussian_kernel(sigma_px.max(0.3));
    let radius = (kernel.len() / 2) as isize;
    let kernel = kernel.as_slice();
    // The taps of position `i` that fall inside `0..n`, with their offsets.
    let taps = move |i: usize, n: usize| {
        kernel.iter().enumerate().filter_map(move |(k, g)| {
            let j = i as isize + k as isize - radius;
            (j >= 0 && (j as usize) < n).then_some((j as usize, *g))
        })
    };
    let mut across = vec![0.0; w * h];
    for_rows(&mut across, w, cancel, |r, out| {
        let row = &values[r * w..(r + 1) * w];
        for (c, value) in out.iter_mut().enumerate() {
            *value = taps(c, w).map(|(j, g)| g * row[j]).sum();
        }
    })?;
    let mut out = vec![0.0; w * h];
    for_rows(&mut out, w, cancel, |r, out| {
        for (j, g) in taps(r, h) {
            for (value, s) in out.iter_mut().zip(&across[j * w..(j + 1) * w]) {
                *value += g * s;
            }
        }
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::Uncancelled;

    const SIDE: usize = 648;

    /// A smooth shading (a broad bump from 0.25 to 0.75).
    fn shading() -> Grid<f64> {
        Grid::from_fn(SIDE, SIDE, |c, r| {
            let (x, y) = (c as f64 / SIDE as f64 - 0.5, r as f64 / SIDE as f64 - 0.5);
            0.25 + 0.5 * (-(x * x + y * y) / 0.08).exp()
        })
    }

    /// A deterministic pseudo-random number in [0, 1) per pixel.
    fn hash(c: usize, r: usize, seed: u64) -> f64 {
        let mut v = ((c as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
            ^ ((r as u64 + 7).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
            ^ seed;
        v ^= v >> 29;
        v = v.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        v ^= v >> 32;
        (v % 1_000_003) as f64 / 1_000_003.0
    }

    /// Hair in the dark squares of a 32 px checkerboard: 40 % of their
    /// pixels are strands of albedo 0.3.
    fn hairy(c: usize, r: usize) -> bool {
        (c / 32 + r / 32).is_multiple_of(2)
    }

    fn hair_image() -> Grid<f64> {
        let base = shading();
        Grid::from_fn(SIDE, SIDE, |c, r| {
            let strand = hairy(c, r) && hash(c, r, 1) < 0.4;
            base.at(c, r) * if strand { 0.3 } else { 1.0 }
        })
    }

    fn run(image: &Grid<f64>, noise_sigma: f64) -> TextureAlbedo {
        let ones = Grid::filled(SIDE, SIDE, 1.0);
        let trusted = Grid::filled(SIDE, SIDE, true);
        texture_albedo(image, &ones, &trusted, noise_sigma, Cancel::NEVER).uncancelled()
    }

    #[test]
    fn hair_darkens_its_region_and_leaves_the_rest() {
        let found = run(&hair_image(), 1e-3);
        assert!(found.summary.used, "{found:?}");
        assert!(found.summary.log_slope < 0.0 && found.summary.correlation <= -MIN_CORRELATION);
        let (mut hair, mut clean) = (Vec::new(), Vec::new());
        // Away from the squares' borders, where the pooling mixes both.
        for r in 0..SIDE {
            for c in 0..SIDE {
                let (u, v) = (c % 32, r % 32);
                if (10..22).contains(&u) && (10..22).contains(&v) {
                    let f = *found.factor.at(c, r);
                    if hairy(c, r) {
                        hair.push(f)
                    } else {
                        clean.push(f)
                    }
                }
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!(mean(&hair) < 0.85, "hair {}", mean(&hair));
        assert!(mean(&clean) > 0.95, "clean {}", mean(&clean));
    }

    #[test]
    fn noise_is_not_texture() {
        // sigma 20 of 255 on a shading as dark as 0.25: the log's noise is
        // three times larger in the dark than in the bright, as hair's is.
        let sigma = 20.0 / 255.0;
        let base = shading();
        let noisy = Grid::from_fn(SIDE, SIDE, |c, r| {
            // The sum of four uniforms: mean 2, variance 1/3.
            let u: f64 = (0..4).map(|k| hash(c, r, 10 + k)).sum::<f64>() - 2.0;
            (base.at(c, r) + sigma * u * 3f64.sqrt()).max(0.0)
        });
        let found = run(&noisy, sigma);
        assert!(!found.summary.used, "{found:?}");
        assert!(found.factor.as_slice().iter().all(|&f| f == 1.0));
    }

    #[test]
    fn the_factor_is_invariant_to_exposure() {
        let image = hair_image();
        let bright = run(&image, 1e-3);
        let dark = run(&image.map(|v| v * 0.25), 0.25e-3);
        assert!(bright.summary.used && dark.summary.used);
        let worst = bright
            .factor
            .as_slice()
            .iter()
            .zip(dark.factor.as_slice())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{worst}");
    }
}
