//! Property tests of the solver on random small problems: it never panics,
//! never returns NaN where it must return depth, and only fails with an input
//! or parameter error.

use std::cell::Cell;

use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::model::Derivatives;
use sfs_core::params::{Alpha, DomainMode, InitialDepth, SolverParams, StepControl, Units};
use sfs_core::solver::{Problem, SolveError, solve};

/// A random problem with its parameters.
#[derive(Clone, Debug)]
struct Case {
    width: usize,
    height: usize,
    image: Vec<f64>,
    mask: Option<Vec<bool>>,
    confidence: Option<Vec<f64>>,
    focal: f64,
    intensity_scale: f64,
    params: SolverParams,
}

impl Case {
    fn problem(&self) -> Problem {
        let (w, h) = (self.width, self.height);
        Problem {
            image: Grid::from_vec(w, h, self.image.clone()).unwrap(),
            camera: Intrinsics::centred(self.focal, w, h),
            intensity_scale: self.intensity_scale,
            object_mask: self
                .mask
                .as_ref()
                .map(|m| Grid::from_vec(w, h, m.clone()).unwrap()),
            confidence: self
                .confidence
                .as_ref()
                .map(|c| Grid::from_vec(w, h, c.clone()).unwrap()),
            lights: Vec::new(),
        }
    }
}

/// Values in [0, 1], exact 0 and 1 included often.
fn unit_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => Just(0.0),
        1 => Just(1.0),
        4 => 0.0..=1.0f64,
    ]
}

fn params() -> impl Strategy<Value = SolverParams> {
    (
        (0.0..=2.0f64, 1e-4..=1.0f64, 0.3..=0.95f64),
        (1..=3usize, 1..=3usize, 1..=4usize),
        (0.2..=1.95f64, 1e-3..=0.5f64, 3..=8usize),
        (any::<bool>(), any::<bool>(), any::<bool>(), any::<bool>()),
        (any::<bool>(), any::<bool>(), any::<bool>()),
    )
        .prop_map(
            |(
                (alpha, lambda, eta),
                (kappa, inner_iterations, sor_iterations),
                (omega, dz_limit, min_level_side),
                (paper, crop, anti_alias, numeric),
                (relative, auto, fast_marching),
            )| SolverParams {
                // Relative units: alpha scaled into their useful range.
                alpha: match (auto, relative) {
                    (true, _) => Alpha::Auto,
                    (false, true) => Alpha::Value(alpha * 1e-5),
                    (false, false) => Alpha::Value(alpha),
                },
                units: if relative {
                    Units::Relative
                } else {
                    Units::Paper
                },
                initial_depth: if fast_marching {
                    InitialDepth::FastMarching
                } else {
                    InitialDepth::FromImage
                },
                lambda,
                eta,
                kappa,
                inner_iterations,
                sor_iterations,
                omega,
                dz_limit,
                min_level_side,
                domain: if paper {
                    DomainMode::Paper
                } else {
                    DomainMode::Object
                },
                step_control: if crop {
                    StepControl::Crop
                } else {
                    StepControl::Backtracking
                },
                anti_alias_sigma: if anti_alias { 0.6 } else { 0.0 },
                derivatives: if numeric {
                    Derivatives::Numeric { h_z: 1e-6 }
                } else {
                    Derivatives::Exact
                },
                ..SolverParams::default()
            },
        )
}

fn case() -> impl Strategy<Value = Case> {
    (3..=12usize, 3..=12usize)
        .prop_flat_map(|(width, height)| {
            let n = width * height;
            (
                Just((width, height)),
                prop::collection::vec(unit_value(), n),
                prop::option::of(prop::collection::vec(any::<bool>(), n)),
                prop::option::of(prop::collection::vec(unit_value(), n)),
                1.0..=50.0f64,
                0.1..=5.0f64,
                params(),
            )
        })
        .prop_map(
            |((width, height), image, mask, confidence, focal, intensity_scale, params)| Case {
                width,
                height,
                image,
                mask,
                confidence,
                focal,
                intensity_scale,
                params,
            },
        )
}

/// Checks one case; returns whether the solve succeeded.
fn check(case: &Case) -> Result<bool, TestCaseError> {
    let problem = case.problem();
    match solve(&problem, &case.params, &mut ()) {
        Ok(solution) => {
            let size = (case.width, case.height);
            prop_assert_eq!(solution.depth.size(), size);
            prop_assert_eq!(solution.reprojection.size(), size);
            for r in 0..case.height {
                for c in 0..case.width {
                    let z = *solution.depth.at(c, r);
                    let on_object = problem.object_mask.as_ref().is_none_or(|m| *m.at(c, r));
                    if on_object {
                        prop_assert!(
                            z.is_finite() && z > 0.0,
                            "depth at ({}, {}) on the object is {}",
                            c,
                            r,
                            z
                        );
                    } else {
                        prop_assert!(
                            z.is_nan(),
                            "depth at ({}, {}) off the object is {}",
                            c,
                            r,
                            z
                        );
                    }
                    let v = *solution.reprojection.at(c, r);
                    prop_assert!(v.is_finite(), "reprojection at ({}, {}) is {}", c, r, v);
                }
            }
            Ok(true)
        }
        Err(SolveError::Input(message)) => {
            prop_assert!(!message.is_empty());
            Ok(false)
        }
        Err(SolveError::Param(e)) => {
            prop_assert!(!e.to_string().is_empty());
            Ok(false)
        }
        // In-range parameters on a valid image must not diverge.
        Err(e @ (SolveError::Cancelled | SolveError::Diverged(_))) => {
            Err(TestCaseError::fail(format!("unexpected {e:?}")))
        }
    }
}

#[test]
fn solver_never_panics_nor_returns_nan() {
    let config = Config {
        cases: 48,
        failure_persistence: None,
        ..Config::default()
    };
    let mut runner = TestRunner::new(config);
    let solved = Cell::new(0usize);
    let result = runner.run(&case(), |case| {
        if check(&case)? {
            solved.set(solved.get() + 1);
        }
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    // Most random problems are solvable; the property must not hold vacuously.
    assert!(
        solved.get() >= 12,
        "only {} of 48 random problems were solved",
        solved.get()
    );
}

fn uniform(width: usize, height: usize, value: f64) -> Problem {
    Problem {
        image: Grid::filled(width, height, value),
        camera: Intrinsics::centred(10.0, width, height),
        intensity_scale: 1.0,
        object_mask: None,
        confidence: None,
        lights: Vec::new(),
    }
}

#[test]
fn black_and_tiny_images_are_input_errors() {
    let params = SolverParams::default();
    match solve(&uniform(6, 5, 0.0), &params, &mut ()) {
        Err(SolveError::Input(message)) => assert!(message.contains("black"), "{message}"),
        other => panic!("an all-zero image gave {other:?}"),
    }
    for side in [1, 2] {
        match solve(&uniform(side, side, 0.5), &params, &mut ()) {
            Err(SolveError::Input(message)) => assert!(message.contains("3x3"), "{message}"),
            other => panic!("a {side}x{side} image gave {other:?}"),
        }
    }
}
