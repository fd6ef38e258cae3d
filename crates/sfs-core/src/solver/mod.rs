//! The linearised coarse-to-fine Gauss-Newton solver (paper Section 3):
//! pyramid, per-level linear systems, SOR and the driver; and, behind the
//! same interface ([`Method`], [`solve_method`]), the two baselines the paper
//! compares against: the explicit variational scheme of Ju et al.
//! ([`explicit`]) and fast marching for the Prados-Faugeras model
//! ([`fast_marching`]). It reports through [`SolveObserver`] and knows
//! nothing of threads, files or windows.

pub mod albedo_fit;
pub mod auto_alpha;
pub mod calibrate;
pub(crate) mod coarse_to_fine;
pub mod depth_unit;
pub mod driver;
pub mod explicit;
pub mod fast_marching;
pub mod holes;
pub(crate) mod light_frame;
pub mod material_fit;
pub mod multigrid;
pub mod photometric;
pub mod prepare;
pub mod preview;
pub mod problem;
pub mod pyramid;
pub(crate) mod shadow_bound;
pub mod shadows;
pub mod sor;
pub mod system;
pub(crate) mod working;

pub use driver::solve_with_model;
pub use explicit::{ExplicitParams, solve_explicit};
pub use fast_marching::{FastMarchingParams, solve_fast_marching};
pub use prepare::initial_depth_from_image;
pub use problem::{
    IterationReport, LevelReport, LevelResult, PhaseTimes, Problem, Solution, SolveError,
    SolveObserver,
};

/// A shape-from-shading scheme: the paper's method or a baseline.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// The linearised coarse-to-fine Gauss-Newton scheme (the paper's).
    Linearised,
    /// Gradient descent on the same energy (Ju et al.), with its budget.
    Explicit(ExplicitParams),
    /// Fast marching for the Hamilton-Jacobi equation (Vogel et al.).
    FastMarching(FastMarchingParams),
}

impl Method {
    /// The name used in reports and on the command line: `linearised`,
    /// `explicit` or `fast_marching`.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Linearised => "linearised",
            Method::Explicit(_) => "explicit",
            Method::FastMarching(_) => "fast_marching",
        }
    }
}

/// Solves `problem` with `method`. The variational schemes use every
/// parameter of `params`; fast marching has no parameters of the energy and
/// ignores them. With `--albedo auto` the albedo is estimated and compared
/// first ([`albedo_fit`]) and the fit is kept in the solution.
pub fn solve_method(
    problem: &Problem,
    params: &crate::params::SolverParams,
    method: &Method,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let (divided, albedo) = albedo_fit::apply(problem, params, observer)?;
    let problem = divided.as_ref().unwrap_or(problem);
    let (mut params, fit) = material_fit::resolve(problem, params, observer)?;
    params.albedo = crate::params::AlbedoChoice::One;
    let params = &params;
    let mut solution = match method {
        Method::Linearised => driver::solve(problem, params, observer),
        Method::Explicit(explicit) => solve_explicit(problem, params, explicit, observer),
        Method::FastMarching(settings) => solve_fast_marching(
            problem,
            &FastMarchingParams {
                material: params.material(),
                ..settings.clone()
            },
            observer,
        ),
    }?;
    solution.material_fit = fit;
    if let Some(albedo) = albedo {
        albedo.restore(&mut solution);
    }
    Ok(solution)
}

/// Solves `problem` with the linearised scheme (the paper's) at `params`:
/// with `--reflectance auto` the materials are compared first
/// ([`material_fit`]) and the fit is kept in the solution.
///
/// # Errors
/// As the scheme, and the fit.
pub fn solve(
    problem: &Problem,
    params: &crate::params::SolverParams,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    solve_method(problem, params, &Method::Linearised, observer)
}
