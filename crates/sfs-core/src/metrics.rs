//! Error measures of METHOD.md section 5: relative surface error (RSE) and
//! relative image error (RIE) over the ground-truth mask.

use serde::Serialize;

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Uncancelled};
use crate::grid::Grid;
use crate::model::{self, Lambertian, LevelGeometry, Reflectance};

/// RSE and RIE of a result.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Errors {
    /// `||z - z_gt|| / ||z_gt||` over the mask.
    pub rse: f64,
    /// `||I_reproj - I|| / ||I||` over the mask.
    pub rie: f64,
}

/// Why errors cannot be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// Grids of different sizes.
    #[error("size mismatch: {what} is {got:?} but the ground truth is {expected:?}")]
    Size {
        /// Which input.
        what: &'static str,
        /// Its size.
        got: (usize, usize),
        /// The ground truth's size.
        expected: (usize, usize),
    },
    /// Nothing to measure.
    #[error("the ground-truth mask is empty")]
    EmptyMask,
    /// The result has no depth at some ground-truth pixel.
    #[error("the depth is missing (NaN) at {0} ground-truth pixels")]
    MissingDepth(usize),
    /// The result is infinite at some ground-truth pixel.
    #[error("the depth is infinite at {0} ground-truth pixels")]
    InfiniteDepth(usize),
}

/// Relative L2 error of `depth` against `depth_gt` over pixels where the
/// ground truth is finite.
pub fn rse(depth: &Grid<f64>, depth_gt: &Grid<f64>) -> Result<f64, MetricsError> {
    check_size("depth", depth.size(), depth_gt.size())?;
    let (mut num, mut den, mut count, mut missing) = (0.0, 0.0, 0usize, 0usize);
    let mut infinite = 0usize;
    for (z, g) in depth.as_slice().iter().zip(depth_gt.as_slice()) {
        if !g.is_finite() {
            continue;
        }
        if z.is_infinite() {
            infinite += 1;
            continue;
        }
        if z.is_nan() {
            missing += 1;
            continue;
        }
        num += (z - g) * (z - g);
        den += g * g;
        count += 1;
    }
    if infinite > 0 {
        return Err(MetricsError::InfiniteDepth(infinite));
    }
    if missing > 0 {
        return Err(MetricsError::MissingDepth(missing));
    }
    if count == 0 || den == 0.0 {
        return Err(MetricsError::EmptyMask);
    }
    Ok((num / den).sqrt())
}

/// RSE and RIE of `depth` against the ground-truth depth (NaN = background)
/// and the noise-free image, reprojecting with the solver's upwind scheme over
/// the ground-truth mask.
pub fn errors(
    depth: &Grid<f64>,
    depth_gt: &Grid<f64>,
    image: &Grid<f64>,
    camera: Intrinsics,
    intensity_scale: f64,
) -> Result<Errors, MetricsError> {
    let model = Lambertian { intensity_scale };
    errors_with_model(depth, depth_gt, image, camera, &model)
}

/// [`errors`] for any reflectance model (e.g. lights off the optical centre).
pub fn errors_with_model<M: Reflectance + ?Sized>(
    depth: &Grid<f64>,
    depth_gt: &Grid<f64>,
    image: &Grid<f64>,
    camera: Intrinsics,
    model: &M,
) -> Result<Errors, MetricsError> {
    check_size("image", image.size(), depth_gt.size())?;
    let rse = rse(depth, depth_gt)?;
    let (w, h) = depth_gt.size();
    let mask = depth_gt.map(|g| g.is_finite());
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let reprojection =
        model::reproject(model, &geometry, &mask, depth, Cancel::NEVER).uncancelled();
    let (mut num, mut den) = (0.0, 0.0);
    for q in 0..w * h {
        if mask.as_slice()[q] {
            let (r, i) = (reprojection.as_slice()[q], image.as_slice()[q]);
            num += (r - i) * (r - i);
            den += i * i;
        }
    }
    if den == 0.0 {
        return Err(MetricsError::EmptyMask);
    }
    Ok(Errors {
        rse,
        rie: (num / den).sqrt(),
    })
}

fn check_size(
    what: &'static str,
    got: (usize, usize),
    expected: (usize, usize),
) -> Result<(), MetricsError> {
    if got == expected {
        Ok(())
    } else {
        Err(MetricsError::Size {
            what,
            got,
            expected,
        })
    }
}
