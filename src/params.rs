//! Solver parameters with their documented defaults and validation.
//!
//! Defaults are the paper's (Maurer et al. 2015, Section 4) where it gives one.
//! [`SolverParams::validate`] rejects bad values with an error naming the
//! parameter; nothing is clamped silently.

use serde::{Deserialize, Serialize};

use crate::model::Derivatives;

/// How the domain of the unknown depth is chosen (see README, "Object mask
/// versus confidence").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DomainMode {
    /// Only object pixels carry depth: upwind differences and smoothness
    /// stencils at the silhouette use object pixels only. Fits the image
    /// better (lower RIE) and is faster, but its RSE on the mesh scenes was
    /// higher and sensitive to tiny input changes at the default alpha.
    Object,
    /// The paper's set-up (default): every pixel carries depth, the background
    /// only has confidence 0 and is filled in by the smoothness term. Lowest
    /// and most stable RSE on all mesh scenes at the default alpha (README).
    #[default]
    Paper,
}

/// What alpha and lambda are measured in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SmoothnessUnits {
    /// The paper's: second derivatives per full-resolution pixel squared.
    #[default]
    Pixel,
    /// Resolution independent: alpha and lambda refer to a camera with a
    /// 256 px focal length; at focal length `f` the solver uses
    /// `alpha_px = alpha (f/256)^4` and `lambda_px = lambda (256/f)^2`, so the
    /// same values give the same shape at any image size.
    Normalized,
}

/// How each Gauss-Newton update is controlled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StepControl {
    /// The paper's: crop `|dz| <= dz_limit` per pixel and apply.
    Crop,
    /// Crop, then halve the whole step (at most 4 times) until the level's
    /// energy does not increase; the last halving is applied regardless.
    #[default]
    Backtracking,
}

/// Reference focal length (pixels) of [`SmoothnessUnits::Normalized`].
pub const NORMALIZED_FOCAL_PX: f64 = 256.0;

/// Initial depth `z^0`.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum InitialDepth {
    /// Constant depth from the image (default): at the brightest trusted
    /// object pixel `b` of the coarsest level, assume the surface faces the
    /// light, `z0 = Q_b sqrt(s / I_b)`.
    #[default]
    FromImage,
    /// A constant depth (depth units, > 0).
    Constant(f64),
    /// Warm start from a full-resolution depth map (NaN where unknown): the
    /// coarse levels are skipped and the map is refined at full resolution.
    Map(crate::grid::Grid<f64>),
}

/// Every parameter of the linearised coarse-to-fine solver.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverParams {
    /// Smoothness weight `alpha` (paper: 0.003 to 3 per image, Table 1, in
    /// its own units). Default 100: with coordinates in full-resolution pixels
    /// second derivatives are small (about 1e-4 on the Sombrero), and alpha
    /// 30 to 300 gave the lowest errors on every clean test scene, 2000 on
    /// noisy ones (see README).
    pub alpha: f64,
    /// Charbonnier contrast `lambda`; paper 1e-3.
    pub lambda: f64,
    /// Units of alpha and lambda; default [`SmoothnessUnits::Pixel`].
    pub smoothness_units: SmoothnessUnits,
    /// Downsampling factor `eta` in (0, 1) between pyramid levels; paper 0.9.
    pub eta: f64,
    /// Outer (Gauss-Newton) iterations `kappa` per level; paper 5.
    pub kappa: usize,
    /// Inner fixed-point iterations `l_max` on Psi'; paper 9.
    pub inner_iterations: usize,
    /// SOR sweeps per inner iteration; paper 10.
    pub sor_iterations: usize,
    /// SOR relaxation `omega` in (0, 2); the paper does not state it; default 1.5.
    pub omega: f64,
    /// Per-pixel crop `|dz| <= dz_limit` of each update (depth units); paper 0.01.
    pub dz_limit: f64,
    /// How `dD/dz` is computed; default exact (agrees with the paper's numeric
    /// `h_z = 1e-12` to about 1e-4 and is faster).
    pub derivatives: Derivatives,
    /// Smallest side (pixels) of the coarsest pyramid level; default 16.
    pub min_level_side: usize,
    /// Domain handling; default [`DomainMode::Paper`].
    pub domain: DomainMode,
    /// Initial depth; default [`InitialDepth::FromImage`].
    pub initial_depth: InitialDepth,
    /// Update control; default [`StepControl::Backtracking`] (lower energy
    /// and RIE on every test scene; see README).
    pub step_control: StepControl,
    /// Anti-aliasing of the pyramid: Gaussian `sigma = anti_alias_sigma *
    /// sqrt(1/eta^2 - 1)` finer pixels before each downsampling (IPOL's
    /// `sigma_0`, usually 0.6). Default 0: every level is point-sampled
    /// (bilinear) from the full image, which keeps bright peaks: area
    /// averaging darkened the Sombrero's dome on coarse levels and left it too
    /// far away (RSE 0.048 against 0.018).
    pub anti_alias_sigma: f64,
}

impl Default for SolverParams {
    fn default() -> Self {
        Self {
            alpha: 100.0,
            lambda: 1e-3,
            smoothness_units: SmoothnessUnits::Pixel,
            eta: 0.9,
            kappa: 5,
            inner_iterations: 9,
            sor_iterations: 10,
            omega: 1.5,
            dz_limit: 0.01,
            derivatives: Derivatives::Exact,
            min_level_side: 16,
            domain: DomainMode::Paper,
            initial_depth: InitialDepth::FromImage,
            step_control: StepControl::Backtracking,
            anti_alias_sigma: 0.0,
        }
    }
}

/// A parameter value that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid parameter {name} = {value}: {reason}")]
pub struct ParamError {
    /// The parameter's name as the command line spells it.
    pub name: &'static str,
    /// The rejected value.
    pub value: String,
    /// What a valid value is.
    pub reason: &'static str,
}

fn check(
    ok: bool,
    name: &'static str,
    value: impl ToString,
    reason: &'static str,
) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError {
            name,
            value: value.to_string(),
            reason,
        })
    }
}

impl SolverParams {
    /// Checks every parameter; the first bad one is named in the error.
    pub fn validate(&self) -> Result<(), ParamError> {
        check(
            self.alpha.is_finite() && self.alpha >= 0.0,
            "alpha",
            self.alpha,
            "must be finite and >= 0",
        )?;
        check(
            self.lambda.is_finite() && self.lambda > 0.0,
            "lambda",
            self.lambda,
            "must be finite and > 0",
        )?;
        check(
            self.eta > 0.0 && self.eta < 1.0,
            "eta",
            self.eta,
            "must lie in (0, 1)",
        )?;
        check(self.kappa >= 1, "kappa", self.kappa, "must be at least 1")?;
        check(
            self.inner_iterations >= 1,
            "inner-iters",
            self.inner_iterations,
            "must be at least 1",
        )?;
        check(
            self.sor_iterations >= 1,
            "sor-iters",
            self.sor_iterations,
            "must be at least 1",
        )?;
        check(
            self.omega > 0.0 && self.omega < 2.0,
            "omega",
            self.omega,
            "must lie in (0, 2)",
        )?;
        check(
            self.dz_limit.is_finite() && self.dz_limit > 0.0,
            "dz-limit",
            self.dz_limit,
            "must be finite and > 0",
        )?;
        if let Derivatives::Numeric { h_z } = self.derivatives {
            check(
                h_z.is_finite() && h_z > 0.0,
                "h-z",
                h_z,
                "must be finite and > 0",
            )?;
        }
        check(
            self.anti_alias_sigma.is_finite() && self.anti_alias_sigma >= 0.0,
            "anti-alias",
            self.anti_alias_sigma,
            "must be finite and >= 0",
        )?;
        check(
            self.min_level_side >= 3,
            "min-level-side",
            self.min_level_side,
            "must be at least 3",
        )?;
        match &self.initial_depth {
            InitialDepth::Constant(z) => check(
                z.is_finite() && *z > 0.0,
                "init-depth",
                z,
                "must be finite and > 0",
            )?,
            InitialDepth::Map(map) => check(
                map.as_slice().iter().any(|z| z.is_finite() && *z > 0.0),
                "init-depth",
                "depth map",
                "has no finite positive depth",
            )?,
            InitialDepth::FromImage => {}
        }
        Ok(())
    }

    /// `(alpha, lambda)` in per-pixel units for a camera with focal length
    /// `focal_px`.
    pub fn pixel_smoothness(&self, focal_px: f64) -> (f64, f64) {
        match self.smoothness_units {
            SmoothnessUnits::Pixel => (self.alpha, self.lambda),
            SmoothnessUnits::Normalized => {
                let ratio = focal_px / NORMALIZED_FOCAL_PX;
                (self.alpha * ratio.powi(4), self.lambda / (ratio * ratio))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        assert!(SolverParams::default().validate().is_ok());
        let bad = |f: fn(&mut SolverParams)| {
            let mut p = SolverParams::default();
            f(&mut p);
            p.validate().expect_err("must be rejected").name
        };
        assert_eq!(bad(|p| p.alpha = -1.0), "alpha");
        assert_eq!(bad(|p| p.alpha = f64::NAN), "alpha");
        assert_eq!(bad(|p| p.eta = 1.0), "eta");
        assert_eq!(bad(|p| p.eta = 0.0), "eta");
        assert_eq!(bad(|p| p.kappa = 0), "kappa");
        assert_eq!(bad(|p| p.omega = 2.0), "omega");
        assert_eq!(bad(|p| p.dz_limit = 0.0), "dz-limit");
        assert_eq!(bad(|p| p.lambda = 0.0), "lambda");
        assert_eq!(
            bad(|p| p.initial_depth = InitialDepth::Constant(-1.0)),
            "init-depth"
        );
    }

    #[test]
    fn normalized_units_match_pixel_units_at_reference_focal() {
        let p = SolverParams {
            smoothness_units: SmoothnessUnits::Normalized,
            alpha: 0.5,
            lambda: 2e-3,
            ..Default::default()
        };
        assert_eq!(p.pixel_smoothness(256.0), (0.5, 2e-3));
        let (a, l) = p.pixel_smoothness(512.0);
        assert!((a - 8.0).abs() < 1e-12 && (l - 5e-4).abs() < 1e-15);
    }
}
