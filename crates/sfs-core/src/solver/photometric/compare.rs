//! A single-photograph depth against a set's (`compare_single`), and what
//! the reports read of any depth: its quantiles, its range and its normals.

use glam::DVec3;

use super::linear::gradient;
use crate::camera::Intrinsics;
use crate::grid::Grid;

/// How far a single-photograph shape is from the set's: the single-image
/// method measured on a real photograph against what the set says.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SingleComparison {
    /// RSE of the single-image depth against the set's over the pixels
    /// both solved.
    pub rse_to_set: f64,
    /// The same after the single depth is scaled by the one factor that
    /// best matches the set's (a single photograph's depth unit may be
    /// unknown).
    pub rse_to_set_scaled: f64,
    /// That factor.
    pub scale_to_set: f64,
    /// The mean angle between the two surfaces' normals, degrees.
    pub mean_normal_angle_deg: f64,
    /// The median of the same.
    pub median_normal_angle_deg: f64,
    /// The set's depth range (2nd to 98th percentile), units of depth.
    pub set_depth_range: f64,
    /// The single photograph's depth range, the same way.
    pub single_depth_range: f64,
    /// The pixels compared.
    pub pixels: usize,
}

/// Compares a single-photograph depth with the set's (both at the set's
/// working size, NaN off the object; `camera`: its intrinsics).
pub fn compare_single(
    set_depth: &Grid<f64>,
    single_depth: &Grid<f64>,
    camera: Intrinsics,
) -> Option<SingleComparison> {
    if set_depth.size() != single_depth.size() {
        return None;
    }
    let both = set_depth.zip_map(single_depth, |a, b| {
        a.is_finite() && b.is_finite() && *a > 0.0 && *b > 0.0
    });
    let pairs: Vec<(f64, f64)> = set_depth
        .as_slice()
        .iter()
        .zip(single_depth.as_slice())
        .zip(both.as_slice())
        .filter(|(_, b)| **b)
        .map(|((a, b), _)| (*a, *b))
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let norm = pairs.iter().map(|(a, _)| a * a).sum::<f64>().sqrt();
    let rse = |k: f64| {
        pairs
            .iter()
            .map(|(a, b)| (k * b - a).powi(2))
            .sum::<f64>()
            .sqrt()
            / norm
    };
    let k = pairs.iter().map(|(a, b)| a * b).sum::<f64>()
        / pairs.iter().map(|(_, b)| b * b).sum::<f64>().max(1e-300);
    let normals_set = depth_normals(set_depth, camera);
    let normals_single = depth_normals(single_depth, camera);
    let mut angles: Vec<f64> = normals_set
        .as_slice()
        .iter()
        .zip(normals_single.as_slice())
        .zip(both.as_slice())
        .filter(|(_, b)| **b)
        .filter_map(|((a, b), _)| {
            let (u, v) = (DVec3::from_array(*a), DVec3::from_array(*b));
            (u.is_finite() && v.is_finite()).then(|| u.angle_between(v).to_degrees())
        })
        .collect();
    let mean_angle = angles.iter().sum::<f64>() / angles.len().max(1) as f64;
    let median_angle = if angles.is_empty() {
        f64::NAN
    } else {
        let k = angles.len() / 2;
        *angles.select_nth_unstable_by(k, f64::total_cmp).1
    };
    let range = |depth: &Grid<f64>| {
        let masked = depth.zip_map(&both, |z, &b| if b { *z } else { f64::NAN });
        depth_range(&masked).map_or(f64::NAN, |[near, far]| far - near)
    };
    Some(SingleComparison {
        rse_to_set: rse(1.0),
        rse_to_set_scaled: rse(k),
        scale_to_set: k,
        mean_normal_angle_deg: mean_angle,
        median_normal_angle_deg: median_angle,
        set_depth_range: range(set_depth),
        single_depth_range: range(single_depth),
        pixels: pairs.len(),
    })
}

/// The `q` quantile (0..1, nearest rank) of the finite positive values of
/// `grid` (a depth, an albedo); `None` when there is none.
pub fn positive_quantile(grid: &Grid<f64>, q: f64) -> Option<f64> {
    let mut values = grid.finite_positive_values();
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(*values.select_nth_unstable_by(k, f64::total_cmp).1)
}

/// The 2nd to 98th percentile of a depth (`[near, far]`), the range the
/// reports quote; `None` without a depth.
pub fn depth_range(depth: &Grid<f64>) -> Option<[f64; 2]> {
    Some([
        positive_quantile(depth, 0.02)?,
        positive_quantile(depth, 0.98)?,
    ])
}

/// Unit normals of a depth map (camera frame, towards the camera) from
/// central differences of the log-depth where both neighbours are on the
/// surface (one-sided otherwise); NaN off it.
pub fn depth_normals(depth: &Grid<f64>, camera: Intrinsics) -> Grid<[f64; 3]> {
    let (w, h) = depth.size();
    let domain: Vec<bool> = depth
        .as_slice()
        .iter()
        .map(|z| z.is_finite() && *z > 0.0)
        .collect();
    let zeta: Vec<f64> = depth
        .as_slice()
        .iter()
        .map(|z| {
            if z.is_finite() && *z > 0.0 {
                z.ln()
            } else {
                0.0
            }
        })
        .collect();
    let f = camera.focal_px;
    Grid::from_fn(w, h, |c, r| {
        let p = r * w + c;
        if !domain[p] {
            return [f64::NAN; 3];
        }
        let g = gradient(&zeta, &domain, w, p);
        let (x, y) = camera.image_xy(c as f64, r as f64);
        let n = DVec3::new(f * g[0], f * g[1], -(1.0 + x * g[0] + y * g[1]));
        (n / n.length()).to_array()
    })
}
