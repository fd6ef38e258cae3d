//! Which of the parameters a user set (away from the table's defaults) the
//! path a linearised solve took left without effect, each with why: the
//! pyramid's parameters when a full-resolution start is refined on the
//! full image alone, the multigrid's under SOR and SOR's under multigrid,
//! the hole refinement's without holes to refine, the domain without an
//! object mask; and the thresholds whose decisions came out the same as the
//! defaults' at every point they were taken (a stopping test that never
//! stopped the solve earlier or later than the default would have, a crop
//! whose steps never raised the energy, so backtracking would have halved
//! none). Each is then reported as an unused option (`--NAME VALUE: why`)
//! instead of being silently accepted. Used by the driver; reads only the
//! parameter table and the resolved schedule.

use crate::params::{LinearSolver, PARAMS, SolverParams, StepControl};

/// What the parameters' decisions did during a solve, against what the
/// defaults' decisions would have done at the same points.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Effects {
    /// A level's stopping test (`kappa`, `level-tolerance`) stopped at an
    /// iteration where the defaults' would not have, or the reverse.
    pub level_stop_differed: bool,
    /// The inner iterations' early stop (`inner-tolerance`) came out
    /// differently from the default's at some inner iteration.
    pub inner_stop_differed: bool,
    /// With `step-control crop`: a step raised the energy (backtracking
    /// would have halved it).
    pub energy_rose: bool,
    /// Some outer iteration's inner iterations ended at another count than
    /// the default `inner-iters` would have ended them.
    pub inner_count_differed: bool,
    /// Some level's outer iterations were ended by `kappa-max` where the
    /// default cap would not have ended them (or ran past the default cap).
    pub kappa_max_bound: bool,
}

impl Effects {
    /// The effects of two parts of one solve (a walked start and its
    /// refinement): a decision differed where it differed in either.
    pub(crate) fn merge(&mut self, other: Effects) {
        self.level_stop_differed |= other.level_stop_differed;
        self.inner_stop_differed |= other.inner_stop_differed;
        self.energy_rose |= other.energy_rose;
        self.inner_count_differed |= other.inner_count_differed;
        self.kappa_max_bound |= other.kappa_max_bound;
    }
}

/// How the solve ran, resolved for its problem.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Path {
    /// A full-resolution start refined on the full image alone (no pyramid).
    pub refines_warm_start: bool,
    /// That start was walked up the pyramid on a working copy (the
    /// pyramid's parameters apply there).
    pub walked_start: bool,
    /// That start refined across holes (`kappa-holes` applies).
    pub refines_holes: bool,
    /// The linear solver each level ran.
    pub linear_solver: LinearSolver,
    /// The most outer iterations of the resolved schedule, and the fewest
    /// before the stopping test runs.
    pub kappa: usize,
    pub kappa_max: usize,
    /// The problem has an object mask.
    pub has_object_mask: bool,
    /// Whether the fast-marching start marched a denoised image (`None`:
    /// no such start), and whether the automatic decision would have.
    pub start_denoised: Option<bool>,
    pub auto_start_denoised: bool,
    /// The pixels the shadow bound moved; `None` when it did not run (no
    /// shadow: the light at the optical centre, reported before the solve).
    pub shadow_bound_moved: Option<usize>,
}

/// The table's parameters that `params` sets away from the defaults of its
/// units, as `--NAME VALUE`.
fn given(params: &SolverParams) -> Vec<(&'static str, String)> {
    let defaults = SolverParams::for_units(params.units);
    PARAMS
        .iter()
        .filter(|spec| (spec.get)(params) != (spec.get)(&defaults))
        .map(|spec| (spec.name, format!("--{} {}", spec.name, (spec.get)(params))))
        .collect()
}

/// `--NAME VALUE: why` for every parameter set away from its default that
/// the solve's path or its decisions left without effect.
pub(crate) fn unused_parameters(
    params: &SolverParams,
    path: Path,
    effects: Effects,
) -> Vec<String> {
    let why = |name: &str| -> Option<&'static str> {
        match name {
            "eta" | "min-level-side" | "anti-alias"
                if path.refines_warm_start && !path.walked_start =>
            {
                Some(
                    "the solve refines a full-resolution start (--init-depth fast-marching) on \
                     the full image alone, without a pyramid (--init-depth constant walks one)",
                )
            }
            "start-denoise" if path.start_denoised.is_none() => Some(
                "this solve marched no fast-marching start (--init-depth from-image, a \
                 constant or a map, a light far off the lens, or a material fast marching \
                 cannot solve)",
            ),
            "start-denoise" if path.start_denoised == Some(path.auto_start_denoised) => {
                Some(match path.auto_start_denoised {
                    true => {
                        "the image reads noisy, so the automatic decision denoised the start too"
                    }
                    false => {
                        "the image does not read noisy, so the automatic decision left the \
                         start's image as given too"
                    }
                })
            }
            "kappa-holes" if !path.refines_holes => Some(
                "no full-resolution start was refined across holes (wide regions of confidence \
                 below 0.5 in a clean image)",
            ),
            "cycles" | "smoothing-sweeps" | "linear-tolerance"
                if path.linear_solver != LinearSolver::Multigrid =>
            {
                Some("the linear solver was SOR (--linear-solver multigrid uses it)")
            }
            "sor-iters" | "omega" if path.linear_solver == LinearSolver::Multigrid => Some(
                "the linear solver was multigrid, whose smoother is Gauss-Seidel with a fixed \
                 count (--linear-solver sor uses it)",
            ),
            "level-tolerance" if path.kappa >= path.kappa_max => Some(
                "every level ran kappa-max outer iterations (kappa is not below it), so the \
                 convergence test never ran; set --kappa below --kappa-max",
            ),
            "step-tolerance" if !path.refines_warm_start || path.refines_holes => Some(
                "it stops the outer iterations refining a full-resolution start without holes, \
                 and this solve refined none (a pyramid, or a start across holes)",
            ),
            "kappa" | "level-tolerance" | "step-tolerance" if !effects.level_stop_differed => Some(
                "no level stopped at another iteration than with the default (neither the \
                 energy within --level-tolerance nor the depth within --step-tolerance settled \
                 otherwise before kappa-max iterations)",
            ),
            "kappa-max" if !effects.kappa_max_bound => Some(
                "every level stopped (by --level-tolerance, or at kappa) within the default \
                 kappa-max's iterations, so the cap never bound",
            ),
            "inner-iters" if !effects.inner_count_differed => Some(
                "every outer iteration's inner iterations ended where they would have with the \
                 default count (stopped early by --inner-tolerance)",
            ),
            "inner-tolerance" if !path.refines_warm_start || params.inner_iterations < 2 => Some(
                "it stops the inner iterations of a full-resolution start's refinement early, \
                 and this solve ran none to stop (one inner iteration, or a pyramid)",
            ),
            "inner-tolerance" if !effects.inner_stop_differed => Some(
                "no inner iteration stopped at another point than with the default (the steps \
                 were large against the crop)",
            ),
            "shadow-bound" if path.shadow_bound_moved == Some(0) => Some(
                "the bound moved no pixel: no shadow pixel lay where the solved surface lets \
                 the light reach it",
            ),
            "domain" if !path.has_object_mask => {
                Some("there is no object mask: the object is the whole image")
            }
            "step-control" if params.step_control == StepControl::Crop && !effects.energy_rose => {
                Some("no step raised the energy, so backtracking would have halved none")
            }
            _ => None,
        }
    };
    given(params)
        .into_iter()
        .filter_map(|(name, option)| why(name).map(|w| format!("{option}: {w}")))
        .collect()
}

/// `--NAME VALUE: why` for every parameter of the energy set away from its
/// default, for a method that solves no energy (fast marching): everything
/// but the reflectance model's (`--units paper` included).
pub(crate) fn unused_by_fast_marching(params: &SolverParams) -> Vec<String> {
    given(params)
        .into_iter()
        .chain(
            (params.units != crate::params::Units::Relative)
                .then(|| ("units", "--units paper".to_owned())),
        )
        .filter(|(name, _)| {
            crate::material::model_of_param(name).is_none() && *name != "reflectance"
        })
        .map(|(_, option)| {
            format!("{option}: fast marching solves no energy and has no such parameter")
        })
        .collect()
}

/// The linearised scheme's own parameters (its outer and inner iterations,
/// linear solver and step control), which the explicit scheme does not
/// have.
const LINEARISED_ONLY: [&str; 13] = [
    "kappa",
    "kappa-max",
    "kappa-holes",
    "level-tolerance",
    "inner-iters",
    "sor-iters",
    "omega",
    "linear-solver",
    "cycles",
    "smoothing-sweeps",
    "linear-tolerance",
    "inner-tolerance",
    "step-control",
];

/// `--NAME VALUE: why` for the linearised scheme's own parameters set away
/// from their defaults, for the explicit scheme (gradient descent with its
/// own budget).
pub(crate) fn unused_by_explicit(params: &SolverParams) -> Vec<String> {
    given(params)
        .into_iter()
        .filter(|(name, _)| LINEARISED_ONLY.contains(name))
        .map(|(_, option)| {
            format!(
                "{option}: the explicit scheme descends the energy's gradient with its own \
                 budget; it has no Gauss-Newton iterations, linear solver or step control"
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::table::spec;

    fn path() -> Path {
        Path {
            refines_warm_start: true,
            walked_start: false,
            refines_holes: false,
            linear_solver: LinearSolver::Sor,
            kappa: 5,
            kappa_max: 5,
            has_object_mask: false,
            shadow_bound_moved: Some(0),
            start_denoised: Some(false),
            auto_start_denoised: false,
        }
    }

    fn set(name: &str, value: &str) -> SolverParams {
        let mut params = SolverParams::default();
        let s = spec(name).expect("in the table");
        (s.set)(&mut params, s.parse(value).expect("valid"));
        params
    }

    #[test]
    fn the_explicit_scheme_reports_the_linearised_schemes_own_parameters() {
        let unused = unused_by_explicit(&set("sor-iters", "3"));
        assert_eq!(unused.len(), 1, "{unused:?}");
        assert!(unused[0].starts_with("--sor-iters 3: the explicit scheme"));
        assert!(unused_by_explicit(&set("alpha", "0.01")).is_empty());
    }

    #[test]
    fn defaults_are_never_reported() {
        let unused = unused_parameters(&SolverParams::default(), path(), Effects::default());
        assert!(unused.is_empty(), "{unused:?}");
    }

    #[test]
    fn a_path_that_skips_a_parameter_reports_it_with_why() {
        for (name, value, words) in [
            ("eta", "0.5", "without a pyramid"),
            ("kappa-holes", "40", "across holes"),
            ("cycles", "16", "SOR"),
            ("level-tolerance", "0.5", "never ran"),
            ("domain", "object", "no object mask"),
            ("step-control", "crop", "halved none"),
            ("shadow-bound", "on", "moved no pixel"),
            ("kappa-max", "20", "never bound"),
            (
                "start-denoise",
                "off",
                "left the start's image as given too",
            ),
        ] {
            let unused = unused_parameters(&set(name, value), path(), Effects::default());
            assert_eq!(unused.len(), 1, "{name}: {unused:?}");
            assert!(unused[0].starts_with(&format!("--{name} ")), "{unused:?}");
            assert!(unused[0].contains(words), "{unused:?}");
        }
    }

    #[test]
    fn a_parameter_whose_decision_differed_is_not_reported() {
        let acted = Effects {
            level_stop_differed: true,
            inner_stop_differed: true,
            energy_rose: true,
            inner_count_differed: true,
            kappa_max_bound: true,
        };
        let pyramid = Path {
            refines_warm_start: false,
            kappa: 1,
            ..path()
        };
        for (name, value) in [
            ("kappa", "1"),
            ("step-control", "crop"),
            ("eta", "0.5"),
            ("inner-iters", "3"),
            ("kappa-max", "20"),
        ] {
            let unused = unused_parameters(&set(name, value), pyramid, acted);
            assert!(unused.is_empty(), "{name}: {unused:?}");
        }
    }

    #[test]
    fn the_start_denoising_is_used_only_where_it_overrode_the_automatic_decision() {
        let marched = |denoised: bool, auto: bool| Path {
            start_denoised: Some(denoised),
            auto_start_denoised: auto,
            ..path()
        };
        let on = set("start-denoise", "on");
        let off = set("start-denoise", "off");
        assert!(unused_parameters(&on, marched(true, false), Effects::default()).is_empty());
        assert!(unused_parameters(&off, marched(false, true), Effects::default()).is_empty());
        let same = unused_parameters(&on, marched(true, true), Effects::default());
        assert!(
            same.len() == 1 && same[0].contains("reads noisy"),
            "{same:?}"
        );
        let none = Path {
            start_denoised: None,
            ..path()
        };
        let unused = unused_parameters(&off, none, Effects::default());
        assert!(
            unused.len() == 1 && unused[0].contains("marched no fast-marching start"),
            "{unused:?}"
        );
    }

    #[test]
    fn a_walked_start_uses_the_pyramids_parameters() {
        let walked = Path {
            walked_start: true,
            ..path()
        };
        for (name, value) in [("eta", "0.5"), ("min-level-side", "8")] {
            assert_eq!(
                unused_parameters(&set(name, value), path(), Effects::default()).len(),
                1,
                "{name} without a pyramid"
            );
            let unused = unused_parameters(&set(name, value), walked, Effects::default());
            assert!(unused.is_empty(), "{name}: {unused:?}");
        }
    }

    #[test]
    fn merged_effects_keep_every_part_that_differed() {
        let mut effects = Effects::default();
        effects.merge(Effects {
            inner_stop_differed: true,
            ..Effects::default()
        });
        effects.merge(Effects::default());
        assert!(effects.inner_stop_differed && !effects.level_stop_differed);
    }
}
