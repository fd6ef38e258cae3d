//! A photometric-stereo set as the solver takes it and what it returns:
//! [`PhotometricProblem`] (its [`SetPhoto`]s), [`PhotometricParams`],
//! [`PhotometricSolution`] (a [`PhotoResult`] per photograph). Plain data
//! below the solve and its children; re-exported from the folder's module.
//! Uses `camera`, `grid`, `light`, `model`, `params` (the set's rules).

use crate::camera::Intrinsics;
use crate::grid::Grid;
use crate::light::PointLight;
use crate::model::Energy;
use crate::params::ParamError;
use crate::params::photometric::{PS_ROBUST_SCALE, PS_SMOOTHNESS};
use crate::solver::problem::LevelReport;

/// One photograph of a set, lit by its own light.
#[derive(Clone, Debug)]
pub struct SetPhoto {
    /// Its name (the file), for messages and reports.
    pub name: String,
    /// Linear values (ambient frame, vignetting subtracted or divided out).
    pub image: Grid<f64>,
    /// Its light, camera frame, units of depth; the intensity is relative.
    pub light: PointLight,
    /// Where it was saturated (left out).
    pub saturated: Option<Grid<bool>>,
    /// Its own confidence in [0, 1] (a per-photograph mask), combined with
    /// the set's.
    pub confidence: Option<Grid<f64>>,
}

impl SetPhoto {
    /// Whether this photograph's pixel `q` (row-major) may be used: not
    /// saturated, and of positive confidence of its own.
    pub fn trusts(&self, q: usize) -> bool {
        !self.saturated.as_ref().is_some_and(|s| s.as_slice()[q])
            && self
                .confidence
                .as_ref()
                .is_none_or(|c| c.as_slice()[q] > 0.0)
    }
}

/// A photometric-stereo problem.
#[derive(Clone, Debug)]
pub struct PhotometricProblem {
    /// The photographs, all of one size.
    pub photos: Vec<SetPhoto>,
    /// Intrinsics at the photographs' size.
    pub camera: Intrinsics,
    /// Pixels that see the object (`None`: every pixel).
    pub object_mask: Option<Grid<bool>>,
    /// Confidence for every photograph, in [0, 1].
    pub confidence: Option<Grid<f64>>,
    /// Whether the lights' intensities were measured; if not, each
    /// photograph's intensity is estimated (semi-calibrated).
    pub intensities_known: bool,
    /// The intensity scale `s`, when known: the albedo is then absolute;
    /// otherwise it is `s rho` (relative).
    pub intensity_scale: Option<f64>,
}

/// The scheme's settings; the defaults are what a user gets.
#[derive(Clone, Debug, PartialEq)]
pub struct PhotometricParams {
    /// Smoothness weight (relative: the second derivatives of the log-depth
    /// times `f^2`); `None`: automatic from the photographs' noise.
    pub alpha: Option<f64>,
    /// Charbonnier `lambda` of the smoothness, in the same units.
    pub lambda: f64,
    /// The Cauchy scale of the residuals relative to the brightness;
    /// `None`: automatic (from the residuals' median).
    pub robust_scale: Option<f64>,
    /// Leave out observations in the current surface's cast shadows.
    pub cast_shadows: bool,
    /// Most linearisations per level.
    pub iterations: usize,
    /// Distance of the object along the optical axis to start from;
    /// `None`: searched.
    pub initial_depth: Option<f64>,
    /// Smallest side of the coarsest level, pixels.
    pub min_side: usize,
}

impl Default for PhotometricParams {
    fn default() -> Self {
        Self {
            alpha: None,
            lambda: 10.0,
            robust_scale: None,
            cast_shadows: true,
            iterations: 30,
            initial_depth: None,
            min_side: 16,
        }
    }
}

impl PhotometricParams {
    /// Checks the values a user sets against their entries of the
    /// photometric-stereo table ([`crate::params::PS_PARAMS`]: the rules
    /// the command line and the viewer apply too); the error names the
    /// parameter.
    pub fn validate(&self) -> Result<(), ParamError> {
        PS_SMOOTHNESS.check(self.alpha)?;
        PS_ROBUST_SCALE.check(self.robust_scale)
    }
}

/// One photograph's fit.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PhotoResult {
    /// The photograph.
    pub name: String,
    /// Its light as given (the report lists the lights with the input).
    #[serde(skip)]
    pub light: PointLight,
    /// Its intensity (given, or estimated and normalised to a geometric
    /// mean of 1 over the set).
    pub intensity: f64,
    /// Relative residual `||prediction - I|| / ||I||` over its used
    /// observations.
    pub relative_residual: f64,
    /// Relative residual `||prediction - I|| / ||I||` over every trusted
    /// observation its light reaches on the solved surface, those the
    /// robust estimator weighted down included. NaN when there is none.
    pub fit_residual: f64,
    /// The smooth part of that misfit, relative to the photograph's
    /// brightness: the prediction scaled by the best factor `a + b u + c v`
    /// across the image (`u`, `v` from -1 to 1), minus the prediction. A
    /// light whose intensity or position is not what the camera file says
    /// leaves such a misfit; noise and local model errors do not. NaN when
    /// there is no observation.
    pub systematic_misfit: f64,
    /// [`systematic_misfit`](Self::systematic_misfit) over the median of
    /// the other photographs' (NaN when either is not a positive number);
    /// judged by [`super::misfit_warning`].
    pub misfit_ratio: f64,
    /// The photograph over what the other photographs predict of it under
    /// its light as given (the set solved again without it, at a coarse
    /// level): the least-squares `scale` of `I = scale P`. Near 1 when its
    /// intensity and exposure agree with the others'; NaN when not
    /// measured (fewer than five photographs). Judged by
    /// [`super::held_out_warning`].
    pub held_out_scale: f64,
    /// The photograph's mean difference from that prediction (`I = P +
    /// offset`) over its brightness (its 99th percentile there): an
    /// ambient light or black level the other photographs lack. NaN when
    /// not measured.
    pub held_out_offset: f64,
    /// Whether [`held_out_offset`](Self::held_out_offset) explains the
    /// photograph better than [`held_out_scale`](Self::held_out_scale)
    /// (the smaller residual).
    pub held_out_offset_better: bool,
    /// How well the other photographs fit each other without this one
    /// (their relative residual over their used observations in that
    /// solve): the photograph at fault is the one without which the others
    /// fit best. NaN when not measured.
    pub held_out_rest: f64,
    /// Share of the object's observations used.
    pub used_share: f64,
    /// Share left out as attached or cast shadow.
    pub shadow_share: f64,
    /// Share left out as untrusted (confidence 0, its own mask, saturated).
    pub untrusted_share: f64,
    /// Share the robust estimator gave less than half their weight.
    pub robust_share: f64,
    /// `I - prediction` per pixel (as a single solve's residual); NaN off
    /// the object.
    #[serde(skip)]
    pub residual: Grid<f64>,
    /// Why each observation was left out ([`USED`](super::level::USED),
    /// [`LEFT_OUT_SHADOW`](super::level::LEFT_OUT_SHADOW), ...).
    #[serde(skip)]
    pub left_out: Grid<u8>,
}

/// The conjugate-gradient solves of the levels' linearisations: how many,
/// their iterations in all, and how many stopped at their iteration cap
/// rather than at their tolerance (0: every step converged).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinearSolves {
    /// Solves.
    pub solves: usize,
    /// Iterations over all solves.
    pub iterations: usize,
    /// Solves that ran their most iterations.
    pub capped: usize,
}

impl LinearSolves {
    /// Adds one solve of `iterations` whose cap was `cap`.
    pub fn add(&mut self, iterations: usize, cap: usize) {
        self.solves += 1;
        self.iterations += iterations;
        if iterations >= cap {
            self.capped += 1;
        }
    }

    /// The two runs' solves together.
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        Self {
            solves: self.solves + other.solves,
            iterations: self.iterations + other.iterations,
            capped: self.capped + other.capped,
        }
    }
}

/// The result of a photometric-stereo solve.
#[derive(Clone, Debug)]
pub struct PhotometricSolution {
    /// Depth along the optical axis, units of the lights; NaN off the object.
    pub depth: Grid<f64>,
    /// Unit normals of the solved surface (camera frame, towards the
    /// camera); NaN off the object.
    pub normals: Grid<[f64; 3]>,
    /// Albedo per pixel: absolute with a known intensity scale, else
    /// `s rho`; NaN off the object or where no photograph says anything.
    pub albedo: Grid<f64>,
    /// Whether the albedo is relative (`s rho`, the scale unknown).
    pub albedo_relative: bool,
    /// Each photograph's fit.
    pub photos: Vec<PhotoResult>,
    /// The lights that cannot light the object as solved (behind the
    /// camera, beyond the object, pointing away: the single-image path's
    /// rule, [`crate::light::lights_that_miss`]), each message led by the
    /// photograph's name.
    pub light_warnings: Vec<String>,
    /// Whether the intensities were estimated (semi-calibrated).
    pub intensities_estimated: bool,
    /// The smoothness weight used.
    pub alpha: f64,
    /// The Cauchy scale used at the end, relative to the brightness.
    pub robust_scale: f64,
    /// The reference brightness (median of the trusted object values).
    pub brightness: f64,
    /// The distance the solve started from, and every distance tried at
    /// the coarsest level with its energy per pixel.
    pub initial_depth: f64,
    /// The distances tried `(distance, energy per pixel)`.
    pub distances_tried: Vec<(f64, f64)>,
    /// Final energy (data over the brightness squared; smoothness; total).
    pub energy: Energy,
    /// Levels, coarsest first.
    pub levels: Vec<LevelReport>,
    /// Linearisations over all levels.
    pub iterations: usize,
    /// The levels' linear solves (the start's trials and the held-out check
    /// not counted).
    pub linear: LinearSolves,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Of which the held-out check (each photograph predicted from the
    /// others), seconds.
    pub held_out_seconds: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One value out of range is refused by the core with the rule the
    /// command line and the viewer apply (their tests), naming it.
    #[test]
    fn validate_refuses_a_value_outside_its_rule_and_names_it() {
        assert!(PhotometricParams::default().validate().is_ok());
        let bad = PhotometricParams {
            robust_scale: Some(0.0),
            ..PhotometricParams::default()
        };
        let e = bad.validate().expect_err("0 divides");
        assert_eq!(e.name, "ps-robust-scale");
        assert_eq!(e.reason, PS_ROBUST_SCALE.accepted());
        assert!(PS_ROBUST_SCALE.parse("0").is_err());
        let bad = PhotometricParams {
            alpha: Some(-1.0),
            ..PhotometricParams::default()
        };
        assert_eq!(bad.validate().expect_err("negative").name, "ps-smoothness");
        let fine = PhotometricParams {
            alpha: Some(0.0),
            robust_scale: Some(0.5),
            ..PhotometricParams::default()
        };
        assert!(fine.validate().is_ok());
    }
}
