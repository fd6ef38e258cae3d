//! The schemes behind one interface ([`Method`], [`solve_method`]): the
//! estimators that run before a solve (`--albedo auto`: [`albedo_fit`],
//! `--reflectance auto`: [`material_fit`]) and then the chosen scheme, the
//! linearised one ([`driver`]), the explicit one ([`explicit`](super::explicit)) or fast
//! marching ([`fast_marching`](super::fast_marching)). Above the solver core and the
//! estimators, so that neither imports the other through it; re-exported
//! as `solver::{Method, solve_method, solve}`.

use super::albedo_fit;
use super::driver;
use super::explicit::{ExplicitParams, solve_explicit};
use super::fast_marching::{FastMarchingParams, solve_fast_marching};
use super::material_fit;
use super::problem::{Problem, Solution, SolveError, SolveObserver};

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
    let (divided, mut albedo) = albedo_fit::apply(problem, params, observer)?;
    // A rejected estimate is not read again: not held through the solve.
    if let Some(fit) = &mut albedo {
        fit.forget_rejected();
    }
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
    match method {
        Method::FastMarching(_) => {
            solution.unused_parameters = super::unused::unused_by_fast_marching(params);
        }
        Method::Explicit(_) => {
            solution.unused_parameters = super::unused::unused_by_explicit(params);
        }
        Method::Linearised => {}
    }
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
