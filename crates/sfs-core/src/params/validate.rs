//! The validation of the parameters against the table's ranges and each
//! other ([`SolverParams::validate`]), and of a constant start against the
//! problem's depth scale. Above the parameters (`settings`) and their table
//! (`table`). Uses nothing else.

use super::settings::{DEPTH_RANGE, INIT_DEPTH_RELATIVE_RANGE, InitialDepth, SolverParams};
use super::table::{PARAMS, ParamError, ParamValue};

/// Refuses a constant initial depth `z0` outside
/// [`INIT_DEPTH_RELATIVE_RANGE`] times the problem's depth scale
/// `depth_scale`, naming `init-depth` and the range in depth units.
pub fn check_constant_initial_depth(z0: f64, depth_scale: f64) -> Result<(), ParamError> {
    let (low, high) = INIT_DEPTH_RELATIVE_RANGE;
    let (z_min, z_max) = (low * depth_scale, high * depth_scale);
    if !(depth_scale.is_finite() && depth_scale > 0.0) || (z_min..=z_max).contains(&z0) {
        return Ok(());
    }
    Err(ParamError {
        name: "init-depth",
        value: ParamValue::Real(z0).to_string(),
        reason: format!(
            "a constant start must lie within [{low:e}, {high:e}] times the depth the image's \
             brightness implies ({depth_scale:.4e}), i.e. in [{z_min:.4e}, {z_max:.4e}] depth \
             units: the solve cannot move a start that far (give a depth in that range, or \
             leave --init-depth at fast-marching)"
        ),
    })
}

impl SolverParams {
    /// Checks every parameter against its range in [`PARAMS`] and the
    /// combinations (kappa-max >= kappa, a usable initial depth); the first
    /// bad one is named in the error. Nothing is clamped.
    pub fn validate(&self) -> Result<(), ParamError> {
        for spec in PARAMS {
            spec.check((spec.get)(self))?;
        }
        let error = |name: &'static str, value: String, reason: &str| ParamError {
            name,
            value,
            reason: reason.to_string(),
        };
        if self.kappa_max < self.kappa {
            return Err(error(
                "kappa-max",
                self.kappa_max.to_string(),
                &format!(
                    "is below kappa = {}: kappa-max must be at least kappa (raise kappa-max \
                     or lower kappa)",
                    self.kappa
                ),
            ));
        }
        let (z_min, z_max) = DEPTH_RANGE;
        let in_range = |z: f64| z.is_finite() && (z_min..=z_max).contains(&z);
        match &self.initial_depth {
            InitialDepth::Constant(z) if !in_range(*z) => Err(error(
                "init-depth",
                ParamValue::Real(*z).to_string(),
                &format!("must be a depth in [{z_min:e}, {z_max:e}]"),
            )),
            InitialDepth::Map(map)
                if map
                    .as_slice()
                    .iter()
                    .any(|&z| z.is_finite() && z > 0.0 && !in_range(z)) =>
            {
                Err(error(
                    "init-depth",
                    "depth map".into(),
                    &format!("has a depth outside [{z_min:e}, {z_max:e}]"),
                ))
            }
            InitialDepth::Map(map) if !map.as_slice().iter().any(|z| z.is_finite() && *z > 0.0) => {
                Err(error(
                    "init-depth",
                    "depth map".into(),
                    "has no finite positive depth",
                ))
            }
            _ => Ok(()),
        }
    }
}
