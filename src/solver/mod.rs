//! The linearised coarse-to-fine Gauss-Newton solver (paper Section 3):
//! pyramid, per-level linear systems, SOR and the driver. It reports through
//! [`SolveObserver`] and knows nothing of threads, files or windows.

pub mod driver;
pub mod pyramid;
pub mod sor;
pub mod system;

pub use driver::{
    IterationReport, LevelReport, LevelResult, PhaseTimes, Problem, Solution, SolveError,
    SolveObserver, initial_depth_from_image, solve, solve_with_model,
};
