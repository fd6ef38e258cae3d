//! The automatic smoothness weight (`alpha = auto`).
//!
//! A maximum-a-posteriori reading of the energy: with Gaussian image noise of
//! standard deviation `sigma` and a Gaussian prior of spread `tau` on the
//! relative second derivatives, `E / (2 sigma^2)` is the negative log
//! posterior when `alpha = sigma^2 / tau^2` (in relative units, the data term
//! divided by `I_ref^2`). The image's own noise is not the only error the data
//! term sees: the discrete model (first-order upwind differences, pixel
//! sampling) misfits a noise-free image by a floor `sigma_model`, so
//! `alpha = (sigma_model^2 + sigma^2) / tau^2`. `sigma` is estimated from the
//! image (robust Immerkaer estimator on trusted object pixels, relative to
//! `I_ref`), `sigma_model` and `tau` are constants of the method, measured
//! once over the test scenes (docs/units-and-alpha.md).

use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::params::ProblemScales;

use super::pyramid::PyramidLevel;

/// Relative misfit of the discrete model on a noise-free image.
pub const SIGMA_MODEL: f64 = 0.023;
/// Prior spread of the relative second derivatives `S_rel`.
pub const TAU: f64 = 75.0;

/// The relative noise level `sigma / I_ref` of the problem's finest level,
/// polling `cancel` per row.
pub fn relative_noise(
    finest: &PyramidLevel,
    scales: &ProblemScales,
    cancel: Cancel<'_>,
) -> Result<f64, Cancelled> {
    crate::denoise::robust_noise_sigma(&finest.image, &trusted(finest), cancel)
        .map(|sigma| sigma / scales.intensity)
}

/// The relative noise level of the problem's finest level read where the
/// surface faces the light ([`crate::denoise::facing_noise_sigma`] over its
/// trusted pixels, relative to `I_ref`), polling `cancel` per row.
pub fn relative_facing_noise(
    finest: &PyramidLevel,
    scales: &ProblemScales,
    cancel: Cancel<'_>,
) -> Result<f64, Cancelled> {
    crate::denoise::facing_noise_sigma(&finest.image, &trusted(finest), cancel)
        .map(|sigma| sigma / scales.intensity)
}

/// The level's pixels the noise is read on: in its domain, confidence above 0.
fn trusted(finest: &PyramidLevel) -> Grid<bool> {
    Grid::from_fn(finest.image.width(), finest.image.height(), |c, r| {
        *finest.domain.at(c, r) && finest.confidence.at(c, r) > 0.0
    })
}

/// The automatic alpha in relative units for an image whose relative noise
/// level is `relative_noise` (see the module doc).
pub fn choose(relative_noise: f64) -> f64 {
    (SIGMA_MODEL * SIGMA_MODEL + relative_noise * relative_noise) / (TAU * TAU)
}
