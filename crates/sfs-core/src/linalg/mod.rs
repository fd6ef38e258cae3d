//! Numerical building blocks shared by the solvers, with no knowledge of
//! images or of the solver: [`cg`], the one preconditioned
//! conjugate-gradient routine, and [`multigrid`], the one multigrid
//! hierarchy (its coarsening loop and V-cycle, generic over the levels).

pub(crate) mod cg;
pub(crate) mod multigrid;
