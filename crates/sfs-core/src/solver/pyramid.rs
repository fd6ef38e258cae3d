//! The coarse-to-fine pyramid: level sizes, anti-aliased downsampling of the
//! image and masks (normalised convolution over the domain), and resampling of
//! depth from one level to the next finer one.

use std::borrow::Cow;

use crate::cancel::{Cancel, Uncancelled};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::LevelGeometry;

/// The data of one pyramid level.
#[derive(Clone, Debug)]
pub struct PyramidLevel<'a> {
    /// Size, spacing and camera.
    pub geometry: LevelGeometry,
    /// Linear image values: the problem's own image on the finest level
    /// (borrowed, not copied: 8 bytes per pixel), a downsampled one below.
    pub image: Cow<'a, Grid<f64>>,
    /// Confidence `c` in [0, 1] (0 outside the object), one byte per pixel
    /// where it is 0 or 1 everywhere.
    pub confidence: Confidence,
    /// Pixels that carry an unknown depth.
    pub domain: Grid<bool>,
}

/// The most pyramid levels a solve builds: eta near its bound of 0.99 on a
/// large image asks for hundreds of levels whose total size is up to 50
/// times the image (an hour's work for no gain); the solve is refused
/// instead, naming eta.
pub const MAX_LEVELS: usize = 400;

/// Total pixels of all `level_sizes` over the finest level's pixels.
pub fn pyramid_factor(width: usize, height: usize, eta: f64, min_side: usize) -> f64 {
    let finest = (width * height).max(1) as f64;
    level_sizes(width, height, eta, min_side)
        .iter()
        .map(|&(w, h)| (w * h) as f64)
        .sum::<f64>()
        / finest
}

/// Level sizes from finest (the full image) to coarsest: `round(side *
/// eta^l)` while both sides stay at least `min_side`, strictly decreasing.
pub fn level_sizes(width: usize, height: usize, eta: f64, min_side: usize) -> Vec<(usize, usize)> {
    let mut sizes = vec![(width, height)];
    let mut factor = 1.0;
    loop {
        factor *= eta;
        let w = (width as f64 * factor).round() as usize;
        let h = (height as f64 * factor).round() as usize;
        if w < min_side || h < min_side || factor < 1e-6 {
            break;
        }
        let &(lw, lh) = sizes.last().unwrap_or(&(width, height));
        if w < lw || h < lh {
            sizes.push((w, h));
        }
    }
    sizes
}

/// Separable Gaussian blur with standard deviation `sigma_px` (Neumann border).
pub fn gaussian_blur(grid: &Grid<f64>, sigma_px: f64) -> Grid<f64> {
    if sigma_px <= 1e-3 {
        return grid.clone();
    }
    let kernel = crate::resample::gaussian_kernel(sigma_px);
    let radius = (kernel.len() / 2) as isize;
    let (w, h) = grid.size();
    let horizontal = Grid::from_fn(w, h, |c, r| {
        kernel
            .iter()
            .enumerate()
            .map(|(k, wgt)| wgt * grid.at_clamped(c as isize + k as isize - radius, r as isize))
            .sum::<f64>()
    });
    Grid::from_fn(w, h, |c, r| {
        kernel
            .iter()
            .enumerate()
            .map(|(k, wgt)| {
                wgt * horizontal.at_clamped(c as isize, r as isize + k as isize - radius)
            })
            .sum::<f64>()
    })
}

/// Bilinear interpolation at fractional `(column, row)`, clamped to the grid.
pub fn bilinear(grid: &Grid<f64>, column: f64, row: f64) -> f64 {
    bilinear_taps(grid.size(), column, row)
        .iter()
        .map(|&(q, weight)| weight * grid.as_slice()[q])
        .sum()
}

/// The four cells (row-major indices) and weights of bilinear interpolation
/// at fractional `(column, row)` in a grid of `size`, clamped to the grid.
pub fn bilinear_taps((w, h): (usize, usize), column: f64, row: f64) -> [(usize, f64); 4] {
    let u = column.clamp(0.0, (w - 1) as f64);
    let v = row.clamp(0.0, (h - 1) as f64);
    let c0 = (u.floor() as usize).min(w.saturating_sub(2));
    let r0 = (v.floor() as usize).min(h.saturating_sub(2));
    let c1 = (c0 + 1).min(w - 1);
    let r1 = (r0 + 1).min(h - 1);
    let fu = u - c0 as f64;
    let fv = v - r0 as f64;
    [
        (r0 * w + c0, (1.0 - fu) * (1.0 - fv)),
        (r0 * w + c1, fu * (1.0 - fv)),
        (r1 * w + c0, (1.0 - fu) * fv),
        (r1 * w + c1, fu * fv),
    ]
}

/// Position in a `from`-sized grid of the centre of cell `index` of a
/// `to`-sized grid covering the same extent.
#[inline]
pub fn map_coordinate(index: usize, to: usize, from: usize) -> f64 {
    (index as f64 + 0.5) * (from as f64 / to as f64) - 0.5
}

/// Downsamples a level to `width` x `height`: Gaussian anti-aliasing with
/// `sigma = sigma_scale * sqrt(1/ratio^2 - 1)` (finer pixels, IPOL style) as a
/// normalised convolution over the finer domain, then bilinear sampling. A
/// coarse pixel is in the domain when at least half of its neighbourhood is.
pub fn downsample(
    finer: &PyramidLevel<'_>,
    geometry: LevelGeometry,
    sigma_scale: f64,
) -> PyramidLevel<'static> {
    let (fw, fh) = finer.image.size();
    let (w, h) = (geometry.width, geometry.height);
    let ratio = (w as f64 / fw as f64).min(h as f64 / fh as f64);
    let sigma = sigma_scale * (1.0 / (ratio * ratio) - 1.0).max(0.0).sqrt();
    // Normalised convolution over the finer domain: blurred sums of the
    // domain weight, of weight x image and of weight x confidence. Without
    // blur they are sampled straight from the finer level (no copies).
    let blurred = (sigma > 1e-3).then(|| {
        let weight = finer.domain.map(|&d| if d { 1.0 } else { 0.0 });
        let weighted_image = Grid::from_fn(fw, fh, |c, r| weight.at(c, r) * finer.image.at(c, r));
        let weighted_conf =
            Grid::from_fn(fw, fh, |c, r| weight.at(c, r) * finer.confidence.at(c, r));
        [
            gaussian_blur(&weight, sigma),
            gaussian_blur(&weighted_image, sigma),
            gaussian_blur(&weighted_conf, sigma),
        ]
    });
    let sample = |u: f64, v: f64| -> [f64; 3] {
        match &blurred {
            Some([coverage, image_sum, conf_sum]) => [
                bilinear(coverage, u, v),
                bilinear(image_sum, u, v),
                bilinear(conf_sum, u, v),
            ],
            None => bilinear_taps((fw, fh), u, v)
                .iter()
                .filter(|&&(q, _)| finer.domain.as_slice()[q])
                .fold([0.0; 3], |[cov, img, conf], &(q, wgt)| {
                    [
                        cov + wgt,
                        img + wgt * finer.image.as_slice()[q],
                        conf + wgt * finer.confidence.weight(q),
                    ]
                }),
        }
    };
    let mut image = Grid::filled(w, h, 0.0);
    let mut confidence = Grid::filled(w, h, 0.0);
    let mut domain = Grid::filled(w, h, false);
    for r in 0..h {
        let v = map_coordinate(r, h, fh);
        for c in 0..w {
            let u = map_coordinate(c, w, fw);
            let [cov, image_sum, conf_sum] = sample(u, v);
            if cov >= 0.5 {
                *domain.at_mut(c, r) = true;
                *image.at_mut(c, r) = image_sum / cov;
                *confidence.at_mut(c, r) = (conf_sum / cov).clamp(0.0, 1.0);
            }
        }
    }
    PyramidLevel {
        geometry,
        image: Cow::Owned(image),
        confidence: Confidence::from_grid(confidence, Cancel::NEVER).uncancelled(),
        domain,
    }
}

/// Resamples a depth map onto a finer level: bilinear interpolation that
/// uses only coarse domain pixels; finer domain pixels with no coarse domain
/// pixel among their four neighbours take the nearest coarse domain depth
/// along their row or the coarse mean.
pub fn upsample_depth(
    coarse_depth: &Grid<f64>,
    coarse_domain: &Grid<bool>,
    finer_domain: &Grid<bool>,
) -> Grid<f64> {
    let (cw, ch) = coarse_depth.size();
    let (fw, fh) = finer_domain.size();
    let (sum, count) = coarse_depth
        .as_slice()
        .iter()
        .zip(coarse_domain.as_slice())
        .filter(|(_, d)| **d)
        .fold((0.0, 0usize), |(s, n), (z, _)| (s + z, n + 1));
    let mean = if count > 0 { sum / count as f64 } else { 1.0 };
    Grid::from_fn(fw, fh, |c, r| {
        if !finer_domain.at(c, r) {
            return mean;
        }
        let u = map_coordinate(c, fw, cw).clamp(0.0, (cw - 1) as f64);
        let v = map_coordinate(r, fh, ch).clamp(0.0, (ch - 1) as f64);
        let c0 = u.floor() as usize;
        let r0 = v.floor() as usize;
        let (fu, fv) = (u - c0 as f64, v - r0 as f64);
        let mut acc = 0.0;
        let mut wsum = 0.0;
        for (dc, wc) in [(0, 1.0 - fu), (1, fu)] {
            for (dr, wr) in [(0, 1.0 - fv), (1, fv)] {
                let (cc, rr) = ((c0 + dc).min(cw - 1), (r0 + dr).min(ch - 1));
                let wgt = wc * wr;
                if *coarse_domain.at(cc, rr) && wgt > 0.0 {
                    acc += wgt * coarse_depth.at(cc, rr);
                    wsum += wgt;
                }
            }
        }
        if wsum > 1e-12 {
            return acc / wsum;
        }
        // Nearest coarse domain pixel (rare: thin structures).
        let (cu, cv) = (u.round() as usize, v.round() as usize);
        let mut best = (f64::MAX, mean);
        for rr in cv.saturating_sub(3)..(cv + 4).min(ch) {
            for cc in cu.saturating_sub(3)..(cu + 4).min(cw) {
                if *coarse_domain.at(cc, rr) {
                    let d2 = (cc as f64 - u).powi(2) + (rr as f64 - v).powi(2);
                    if d2 < best.0 {
                        best = (d2, *coarse_depth.at(cc, rr));
                    }
                }
            }
        }
        best.1
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_decrease_to_the_smallest_side() {
        let s = level_sizes(256, 128, 0.5, 16);
        assert_eq!(s, vec![(256, 128), (128, 64), (64, 32), (32, 16)]);
        let s = level_sizes(20, 20, 0.9, 16);
        assert_eq!(s, vec![(20, 20), (18, 18), (16, 16)]);
        assert_eq!(level_sizes(8, 8, 0.9, 16), vec![(8, 8)]);
    }

    #[test]
    fn constant_image_stays_constant() {
        let g = Grid::filled(9, 7, 0.25);
        let b = gaussian_blur(&g, 1.3);
        assert!(b.as_slice().iter().all(|v| (v - 0.25).abs() < 1e-12));
        let z = upsample_depth(
            &Grid::filled(4, 4, 2.0),
            &Grid::filled(4, 4, true),
            &Grid::filled(9, 9, true),
        );
        assert!(z.as_slice().iter().all(|v| (v - 2.0).abs() < 1e-12));
    }
}
