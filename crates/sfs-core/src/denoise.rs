//! Image noise and its removal: Immerkaer's noise estimate (whole image, or
//! robust over trusted pixels), TV (ROF) denoising by primal-dual, and the
//! filling of untrusted pixels by diffusion. Pure functions over [`Grid`];
//! used by the solver (the fast-marching start, the automatic alpha) and by
//! the benchmark's pre-processing.

use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;

/// Noise standard deviation of an image (same units as its values), by
/// Immerkaer's estimator ("Fast noise variance estimation", CVIU 1996): the
/// mean absolute response to the Laplacian difference mask
/// `[1 -2 1; -2 4 -2; 1 -2 1]`, which cancels smooth content, times
/// `sqrt(pi/2) / 6`.
pub fn estimate_noise_sigma(image: &Grid<f64>) -> f64 {
    let (w, h) = image.size();
    if w < 3 || h < 3 {
        return 0.0;
    }
    let z = |c: usize, r: usize| *image.at(c, r);
    let mut sum = 0.0;
    for r in 1..h - 1 {
        for c in 1..w - 1 {
            let v = z(c - 1, r - 1) - 2.0 * z(c, r - 1) + z(c + 1, r - 1) - 2.0 * z(c - 1, r)
                + 4.0 * z(c, r)
                - 2.0 * z(c + 1, r)
                + z(c - 1, r + 1)
                - 2.0 * z(c, r + 1)
                + z(c + 1, r + 1);
            sum += v.abs();
        }
    }
    (std::f64::consts::PI / 2.0).sqrt() * sum / (6.0 * ((w - 2) * (h - 2)) as f64)
}

/// TV (ROF) denoising: the minimiser of
/// `1/2 sum (u - f)^2 + weight sum |grad u|` (isotropic TV, forward
/// differences, Neumann boundary), by the accelerated primal-dual algorithm of
/// Chambolle and Pock (2011, Algorithm 2, the data term being 1-strongly
/// convex). `weight <= 0` returns the image unchanged. Polls `cancel`
/// every few iterations.
pub fn tv_denoise(
    image: &Grid<f64>,
    weight: f64,
    iterations: usize,
    cancel: Cancel<'_>,
) -> Result<Grid<f64>, Cancelled> {
    let (w, h) = image.size();
    if !(weight > 0.0 && weight.is_finite()) || w == 0 || h == 0 {
        return Ok(image.clone());
    }
    let f = image.as_slice();
    let n = w * h;
    let mut u = f.to_vec();
    let mut u_bar = u.clone();
    let (mut px, mut py) = (vec![0.0; n], vec![0.0; n]);
    // ||grad||^2 <= 8.
    let (mut tau, mut sigma) = (0.25f64, 0.5f64);
    for iteration in 0..iterations {
        if iteration % 4 == 0 {
            cancel.check()?;
        }
        // Dual ascent and projection onto |p| <= weight.
        for r in 0..h {
            for c in 0..w {
                let q = r * w + c;
                let gx = if c + 1 < w {
                    u_bar[q + 1] - u_bar[q]
                } else {
                    0.0
                };
                let gy = if r + 1 < h {
                    u_bar[q + w] - u_bar[q]
                } else {
                    0.0
                };
                let (nx, ny) = (px[q] + sigma * gx, py[q] + sigma * gy);
                let scale = ((nx * nx + ny * ny).sqrt() / weight).max(1.0);
                px[q] = nx / scale;
                py[q] = ny / scale;
            }
        }
        // Primal descent: u = (u + tau div p + tau f) / (1 + tau).
        let theta = 1.0 / (1.0 + 2.0 * tau).sqrt();
        for r in 0..h {
            for c in 0..w {
                let q = r * w + c;
                let dx = if c + 1 < w { px[q] } else { 0.0 } - if c > 0 { px[q - 1] } else { 0.0 };
                let dy = if r + 1 < h { py[q] } else { 0.0 } - if r > 0 { py[q - w] } else { 0.0 };
                let new = (u[q] + tau * (dx + dy) + tau * f[q]) / (1.0 + tau);
                u_bar[q] = new + theta * (new - u[q]);
                u[q] = new;
            }
        }
        tau *= theta;
        sigma /= theta;
    }
    Ok(Grid::from_vec(w, h, u).unwrap_or_else(|| image.clone()))
}

/// The default TV weight for an image: its estimated noise level
/// ([`estimate_noise_sigma`]).
pub fn default_tv_weight(image: &Grid<f64>) -> f64 {
    estimate_noise_sigma(image)
}

/// Noise standard deviation of the trusted pixels of `image` (image units):
/// the lower quartile of the absolute responses to Immerkaer's mask
/// `[1 -2 1; -2 4 -2; 1 -2 1]` (standard deviation `6 sigma` on pure noise)
/// over pixels whose 3x3 neighbourhood is trusted, divided by the lower
/// quartile of `|N(0, 36)|`. A low quantile keeps silhouettes, creases and
/// fine detail (large responses on part of the image) from counting as
/// noise: on a clean 128x64 Suzanne the median read 5.2/255, the quartile
/// 1.8/255. 0 when no such pixel exists. Rows in parallel, polling `cancel`
/// per row.
pub fn robust_noise_sigma(
    image: &Grid<f64>,
    trusted: &Grid<bool>,
    cancel: Cancel<'_>,
) -> Result<f64, Cancelled> {
    let (w, h) = image.size();
    if w < 3 || h < 3 {
        return Ok(0.0);
    }
    const MASK: [[f64; 3]; 3] = [[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]];
    let responses = |row: usize, out: &mut Vec<f64>| {
        let r = row + 1;
        'pixel: for c in 1..w - 1 {
            let mut sum = 0.0;
            for (dr, mask_row) in MASK.iter().enumerate() {
                for (dc, weight) in mask_row.iter().enumerate() {
                    let (cc, rr) = (c + dc - 1, r + dr - 1);
                    if !trusted.at(cc, rr) {
                        continue 'pixel;
                    }
                    sum += weight * image.at(cc, rr);
                }
            }
            out.push(sum.abs());
        }
    };
    let quartile = crate::selection::kth_smallest(h - 2, responses, |n| n / 4, cancel)?;
    Ok(quartile.map_or(0.0, |q| q / (6.0 * ABS_NORMAL_LOWER_QUARTILE)))
}

/// [`robust_noise_sigma`] over the brightest quarter of the trusted pixels
/// alone (pixels whose 3x3 neighbourhood lies in that quarter). Shading
/// changes least with the surface's tilt where the surface faces the light
/// (`d cos(theta) / d theta = 0` at `theta = 0`), so surface detail (fine
/// relief, facets, a rendered depth map's pixel-scale steps) shows least
/// there, while the camera's noise is as large or larger (shot noise grows
/// with brightness). 0 when no such pixel exists. Polls `cancel` per row.
pub fn facing_noise_sigma(
    image: &Grid<f64>,
    trusted: &Grid<bool>,
    cancel: Cancel<'_>,
) -> Result<f64, Cancelled> {
    let (w, h) = image.size();
    let values = |r: usize, out: &mut Vec<f64>| {
        out.extend(
            (0..w)
                .filter(|&c| *trusted.at(c, r) && image.at(c, r).is_finite())
                .map(|c| image.at(c, r).max(0.0)),
        );
    };
    // The brightest quarter: at least the value of rank 3n/4.
    let Some(cut) = crate::selection::kth_smallest(h, values, |n| n * 3 / 4, cancel)? else {
        return Ok(0.0);
    };
    let bright = Grid::from_fn(w, h, |c, r| *trusted.at(c, r) && *image.at(c, r) >= cut);
    robust_noise_sigma(image, &bright, cancel)
}

/// The lower quartile of `|N(0, 1)|`: the normal quantile at 0.625.
const ABS_NORMAL_LOWER_QUARTILE: f64 = 0.318_639_363_964_375;

/// Fills the pixels where `known` is false by diffusion from the known ones
/// (Jacobi iterations of Laplace's equation on a coarse-to-fine schedule, so
/// large holes fill in `O(log)` passes); known pixels keep their values.
/// With no known pixel the image is returned unchanged. Polls `cancel`
/// between sweeps.
pub fn fill_unknown(
    image: &Grid<f64>,
    known: &Grid<bool>,
    cancel: Cancel<'_>,
) -> Result<Grid<f64>, Cancelled> {
    let (w, h) = image.size();
    let count = known.as_slice().iter().filter(|&&k| k).count();
    if count == 0 || count == w * h {
        return Ok(image.clone());
    }
    let mean = image
        .as_slice()
        .iter()
        .zip(known.as_slice())
        .filter(|(_, k)| **k)
        .map(|(v, _)| v)
        .sum::<f64>()
        / count as f64;
    let mut u = Grid::from_fn(w, h, |c, r| {
        if *known.at(c, r) {
            *image.at(c, r)
        } else {
            mean
        }
    });
    // Jacobi sweeps with strides from coarse to fine: each stride spreads
    // values that far per sweep.
    let mut previous = u.clone();
    let mut stride = w.max(h).next_power_of_two() / 2;
    while stride >= 1 {
        for _ in 0..8 {
            cancel.check()?;
            previous.as_mut_slice().copy_from_slice(u.as_slice());
            for r in 0..h {
                for c in 0..w {
                    if *known.at(c, r) {
                        continue;
                    }
                    let mut sum = 0.0;
                    let mut n = 0.0;
                    if c >= stride {
                        sum += previous.at(c - stride, r);
                        n += 1.0;
                    }
                    if c + stride < w {
                        sum += previous.at(c + stride, r);
                        n += 1.0;
                    }
                    if r >= stride {
                        sum += previous.at(c, r - stride);
                        n += 1.0;
                    }
                    if r + stride < h {
                        sum += previous.at(c, r + stride);
                        n += 1.0;
                    }
                    if n > 0.0 {
                        *u.at_mut(c, r) = sum / n;
                    }
                }
            }
        }
        stride /= 2;
    }
    Ok(u)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::Uncancelled;
    use crate::scene::{add_noise, sombrero::sombrero};

    #[test]
    fn noise_estimate_finds_the_added_noise() {
        let scene = sombrero(128, 128);
        let noisy = add_noise(&scene.image, 20.0, 5);
        let sigma = estimate_noise_sigma(&noisy) * 255.0;
        assert!((sigma - 20.0).abs() < 2.0, "estimated {sigma}");
        assert!(estimate_noise_sigma(&scene.image) * 255.0 < 1.0);
    }

    #[test]
    fn tv_denoising_brings_a_noisy_image_closer_to_the_clean_one() {
        let scene = sombrero(96, 96);
        let noisy = add_noise(&scene.image, 20.0, 9);
        let error = |g: &Grid<f64>| {
            g.as_slice()
                .iter()
                .zip(scene.image.as_slice())
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let denoised =
            tv_denoise(&noisy, default_tv_weight(&noisy), 200, Cancel::NEVER).uncancelled();
        assert!(
            error(&denoised) < 0.5 * error(&noisy),
            "{} -> {}",
            error(&noisy),
            error(&denoised)
        );
        assert_eq!(
            tv_denoise(&noisy, 0.0, 10, Cancel::NEVER),
            Ok(noisy.clone())
        );
    }

    #[test]
    fn the_facing_estimate_reads_noise_everywhere_but_detail_only_where_it_is() {
        // A ramp of brightness 0.1..0.9; detail (a pixel checkerboard of 5 %)
        // on its darker four fifths only, or noise everywhere.
        let (w, h) = (128, 128);
        let ramp = |c: usize| 0.1 + 0.8 * c as f64 / (w - 1) as f64;
        let detailed = Grid::from_fn(w, h, |c, r| {
            let checker = if (c + r) % 2 == 0 { 0.05 } else { -0.05 };
            ramp(c) + if c < 4 * w / 5 { checker } else { 0.0 }
        });
        let all = Grid::filled(w, h, true);
        let read = |image: &Grid<f64>| {
            (
                robust_noise_sigma(image, &all, Cancel::NEVER).uncancelled() * 255.0,
                facing_noise_sigma(image, &all, Cancel::NEVER).uncancelled() * 255.0,
            )
        };
        let (everywhere, facing) = read(&detailed);
        assert!(everywhere > 5.0 && facing < 0.5, "{everywhere} {facing}");
        let noisy = add_noise(&Grid::from_fn(w, h, |c, _| ramp(c)), 10.0, 4);
        let (everywhere, facing) = read(&noisy);
        assert!((everywhere - 10.0).abs() < 1.5, "{everywhere}");
        assert!((facing - 10.0).abs() < 2.0, "{facing}");
        // No trusted pixel: nothing read.
        let none = Grid::filled(w, h, false);
        assert_eq!(facing_noise_sigma(&noisy, &none, Cancel::NEVER), Ok(0.0));
    }

    #[test]
    fn robust_estimate_ignores_shading_and_finds_added_noise() {
        let scene = sombrero(128, 128);
        let all = Grid::filled(128, 128, true);
        let clean = robust_noise_sigma(&scene.image, &all, Cancel::NEVER).uncancelled() * 255.0;
        let noisy = robust_noise_sigma(&add_noise(&scene.image, 20.0, 3), &all, Cancel::NEVER)
            .uncancelled()
            * 255.0;
        assert!(clean < 0.5, "clean {clean}");
        assert!((noisy - 20.0).abs() < 2.0, "noisy {noisy}");
        // Only trusted pixels count: noise outside them is not seen.
        let half = Grid::from_fn(128, 128, |c, _| c < 64);
        let mixed = Grid::from_fn(128, 128, |c, r| {
            if c < 64 {
                *scene.image.at(c, r)
            } else {
                0.5 + if (c + r) % 2 == 0 { 0.3 } else { -0.3 }
            }
        });
        assert!(robust_noise_sigma(&mixed, &half, Cancel::NEVER).uncancelled() * 255.0 < 0.5);
    }

    #[test]
    fn filling_keeps_known_pixels_and_interpolates_a_ramp() {
        let ramp = Grid::from_fn(40, 30, |c, _| c as f64 / 39.0);
        let known = Grid::from_fn(40, 30, |c, r| {
            !(10..30).contains(&c) || !(5..25).contains(&r)
        });
        let holed = Grid::from_fn(
            40,
            30,
            |c, r| if *known.at(c, r) { *ramp.at(c, r) } else { 7.0 },
        );
        let filled = fill_unknown(&holed, &known, Cancel::NEVER).uncancelled();
        for r in 0..30 {
            for c in 0..40 {
                let error = (filled.at(c, r) - ramp.at(c, r)).abs();
                assert!(error < 0.02, "({c}, {r}): {error}");
            }
        }
    }
}
