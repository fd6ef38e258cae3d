//! sfs-studio: perspective shape from shading with a point light at the
//! optical centre (Maurer, Ju, Breuss, Bruhn, GCPR 2015).
//!
//! Layers (see ARCHITECTURE.md): [`grid`], [`camera`], [`params`] are core
//! types; [`model`] and [`metrics`] the image formation and error measures;
//! [`solver`] the linearised coarse-to-fine Gauss-Newton scheme; [`scene`] and
//! [`io`] synthetic scenes and files; [`cli`] the command line.
#![deny(missing_docs)]

pub mod camera;
pub mod cli;
pub mod grid;
pub mod io;
pub mod metrics;
pub mod model;
pub mod params;
pub mod scene;
pub mod solver;
