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
pub mod fits;
pub mod holes;
pub(crate) mod light_frame;
pub mod material_fit;
pub(crate) mod memo;
pub mod method;
pub mod multigrid;
pub mod photometric;
pub(crate) mod plane_start;
pub mod prepare;
pub mod preview;
pub mod problem;
pub mod pyramid;
pub(crate) mod shadow_bound;
pub mod shadows;
pub mod sor;
pub mod system;
pub(crate) mod unused;
pub(crate) mod working;

pub use driver::solve_with_model;
pub use explicit::{ExplicitParams, solve_explicit};
pub use fast_marching::{FastMarchingParams, solve_fast_marching};
pub use method::{Method, solve, solve_method};
pub use prepare::{WALK_ABOVE_SIDE, WALK_SIDE, initial_depth_from_image};
pub use problem::{
    IterationReport, LevelReport, LevelResult, NoiseReading, PhaseTimes, Problem, Solution,
    SolveError, SolveMemo, SolveObserver,
};
