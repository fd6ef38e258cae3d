//! Solver parameters with their documented defaults and validation.
//!
//! Defaults are the paper's (Maurer et al. 2015, Section 4) where it gives one.
//! [`SolverParams::validate`] rejects bad values with an error naming the
//! parameter; nothing is clamped silently.
pub mod given;
pub mod photometric;
mod reflectance;
mod settings;
pub mod table;
mod validate;

pub use photometric::{PS_PARAMS, PsParamSpec, PsRule, ps_spec};
pub use settings::*;
pub use table::{PARAMS, ParamError, ParamKind, ParamSpec, ParamValue};
pub use validate::check_constant_initial_depth;

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
        assert_eq!(bad(|p| p.alpha = Alpha::Value(-1.0)), "alpha");
        assert_eq!(bad(|p| p.alpha = Alpha::Value(f64::NAN)), "alpha");
        assert_eq!(bad(|p| p.eta = 1.0), "eta");
        assert_eq!(bad(|p| p.kappa_max = 2), "kappa-max");
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

    /// `--init-depth 1e-15` ran to a constant depth with an astronomical
    /// RIE, `1e25` to a constant depth too: both are refused by name.
    #[test]
    fn a_constant_start_far_from_the_images_depth_is_refused() {
        assert!(check_constant_initial_depth(2.0, 2.0).is_ok());
        assert!(check_constant_initial_depth(0.01, 2.0).is_ok());
        for z0 in [1e-15, 1e25, 1e-4, 1e4] {
            let err = check_constant_initial_depth(z0, 2.0).expect_err("refused");
            assert_eq!(err.name, "init-depth");
            let text = err.to_string();
            assert!(text.contains("[2.0000e-3, 2.0000e3]"), "{text}");
        }
    }

    #[test]
    fn relative_smoothness_converts_to_pixels_and_back() {
        let scales = ProblemScales {
            depth: 2.0,
            intensity: 0.5,
            focal_px: 256.0,
        };
        let px = scales.alpha_px(3e-7);
        assert!((scales.alpha_relative(px) - 3e-7).abs() < 1e-20);
        // Twice the focal length: second derivatives per pixel shrink 4x,
        // so alpha_px grows 16x and lambda_px shrinks 4x.
        let wide = ProblemScales {
            focal_px: 512.0,
            ..scales
        };
        assert!((wide.alpha_px(3e-7) / px - 16.0).abs() < 1e-9);
        assert!((scales.lambda_px(30.0) / wide.lambda_px(30.0) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn alpha_parses_auto_and_numbers() {
        assert_eq!("auto".parse::<Alpha>(), Ok(Alpha::Auto));
        assert_eq!("AUTO".parse::<Alpha>(), Ok(Alpha::Auto));
        assert_eq!("2.5".parse::<Alpha>(), Ok(Alpha::Value(2.5)));
        assert!("abc".parse::<Alpha>().is_err());
        assert_eq!(Alpha::Value(2.5).to_string(), "2.5");
    }
}
