//! Resampling an image to a working size by area averaging, and the
//! intrinsics that follow it; pure functions over `grid` and `camera`.

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Grid, for_rows};

/// The working size for `max_side`: the image's own when it fits, else
/// scaled down keeping the aspect ratio (each side at least 1).
pub fn working_size(width: usize, height: usize, max_side: Option<usize>) -> (usize, usize) {
    let Some(max_side) = max_side else {
        return (width, height);
    };
    let longest = width.max(height);
    if longest <= max_side || max_side == 0 {
        return (width, height);
    }
    let k = max_side as f64 / longest as f64;
    let side = |v: usize| ((v as f64 * k).round() as usize).clamp(1, max_side);
    (side(width), side(height))
}

/// Resamples `grid` to `width` x `height` by area averaging: every output
/// pixel is the mean of the input area it covers (fractional overlaps
/// weighted). Upsampling repeats values. Rows in parallel, polling `cancel`
/// per row.
pub fn resize_area(
    grid: &Grid<f64>,
    width: usize,
    height: usize,
    cancel: Cancel<'_>,
) -> Result<Grid<f64>, Cancelled> {
    let (w, h) = grid.size();
    if (w, h) == (width, height) {
        return Ok(grid.clone());
    }
    let columns = weights(w, width);
    let rows = weights(h, height);
    // Horizontal pass (w -> width) per input row, then vertical.
    let mut across = Grid::filled(width, h, 0.0);
    for_rows(across.as_mut_slice(), width, cancel, |r, out| {
        for (c, taps) in columns.iter().enumerate() {
            out[c] = taps.iter().map(|&(i, wt)| wt * grid.at(i, r)).sum();
        }
    })?;
    let mut out = Grid::filled(width, height, 0.0);
    for_rows(out.as_mut_slice(), width, cancel, |r, out| {
        for (c, value) in out.iter_mut().enumerate() {
            *value = rows[r].iter().map(|&(i, wt)| wt * across.at(c, i)).sum();
        }
    })?;
    Ok(out)
}

/// The sampled Gaussian of standard deviation `sigma_px` (> 0) over
/// `-ceil(3 sigma) ..= ceil(3 sigma)`, normalised to sum 1: the one kernel
/// of the pyramid's blur and the albedo texture's.
pub fn gaussian_kernel(sigma_px: f64) -> Vec<f64> {
    let radius = (3.0 * sigma_px).ceil() as isize;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma_px * sigma_px)).exp())
        .collect();
    let norm: f64 = kernel.iter().sum();
    kernel.iter().map(|k| k / norm).collect()
}

/// Per output index, the input indices it covers and their weights (sum 1).
fn weights(input: usize, output: usize) -> Vec<Vec<(usize, f64)>> {
    let k = input as f64 / output as f64;
    (0..output)
        .map(|o| {
            let (a, b) = (o as f64 * k, (o + 1) as f64 * k);
            let first = a.floor() as usize;
            let last = (b.ceil() as usize).min(input).max(first + 1);
            let taps: Vec<(usize, f64)> = (first..last)
                .map(|i| {
                    let overlap = (b.min(i as f64 + 1.0) - a.max(i as f64)).max(0.0);
                    (i.min(input - 1), overlap)
                })
                .filter(|&(_, wt)| wt > 0.0)
                .collect();
            let total: f64 = taps.iter().map(|t| t.1).sum();
            if total > 0.0 {
                taps.into_iter().map(|(i, wt)| (i, wt / total)).collect()
            } else {
                vec![(first.min(input - 1), 1.0)]
            }
        })
        .collect()
}

/// The intrinsics of an image of `from` pixels resampled to `to` pixels
/// (pixel-centre convention: `c' = (c + 1/2) k - 1/2`, `f' = f k`).
pub fn scale_intrinsics(
    camera: Intrinsics,
    from: (usize, usize),
    to: (usize, usize),
) -> Intrinsics {
    let kx = to.0 as f64 / from.0 as f64;
    let ky = to.1 as f64 / from.1 as f64;
    Intrinsics {
        focal_px: camera.focal_px * 0.5 * (kx + ky),
        principal_x_px: (camera.principal_x_px + 0.5) * kx - 0.5,
        principal_y_px: (camera.principal_y_px + 0.5) * ky - 0.5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::Uncancelled;

    #[test]
    fn working_size_keeps_the_aspect() {
        assert_eq!(working_size(5184, 3456, Some(1500)), (1500, 1000));
        assert_eq!(working_size(3456, 5184, Some(1500)), (1000, 1500));
        assert_eq!(working_size(640, 480, Some(1500)), (640, 480));
        assert_eq!(working_size(640, 480, None), (640, 480));
    }

    #[test]
    fn area_averaging_keeps_the_mean_and_averages_blocks() {
        let g = Grid::from_fn(6, 4, |c, r| (c + 10 * r) as f64);
        let half = resize_area(&g, 3, 2, Cancel::NEVER).uncancelled();
        assert_eq!(*half.at(0, 0), (0.0 + 1.0 + 10.0 + 11.0) / 4.0);
        assert_eq!(*half.at(2, 1), (24.0 + 25.0 + 34.0 + 35.0) / 4.0);
        let odd = resize_area(&g, 4, 3, Cancel::NEVER).uncancelled();
        let mean = |g: &Grid<f64>| g.as_slice().iter().sum::<f64>() / g.len() as f64;
        assert!((mean(&odd) - mean(&g)).abs() < 1e-12);
    }

    #[test]
    fn intrinsics_follow_the_resampling() {
        let camera = Intrinsics {
            focal_px: 1000.0,
            principal_x_px: 99.5,
            principal_y_px: 49.5,
        };
        let half = scale_intrinsics(camera, (200, 100), (100, 50));
        assert_eq!(half.focal_px, 500.0);
        assert_eq!((half.principal_x_px, half.principal_y_px), (49.5, 24.5));
    }
}
