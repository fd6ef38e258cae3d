//! The output folders' names and staging, from the core (one list for the
//! command line and the Python package: [`sfs_core::output::names`]).

pub use sfs_core::output::{ground_truth_files, stage};
