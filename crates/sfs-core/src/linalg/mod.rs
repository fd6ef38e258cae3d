//! Numerical building blocks shared by the solvers, with no knowledge of
//! images or of the solver: [`cg`], the one preconditioned
//! conjugate-gradient routine.

pub(crate) mod cg;
