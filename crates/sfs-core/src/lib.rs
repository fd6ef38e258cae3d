//! sfs-core: perspective shape from shading with a point light near the
//! optical centre (Maurer, Ju, Breuss, Bruhn, GCPR 2015), without any GUI or
//! command-line dependency.
//!
//! Layers (see ARCHITECTURE.md): [`grid`], [`camera`], [`params`] are core
//! types; [`model`] and [`metrics`] the image formation and error measures,
//! [`denoise`] image noise and its removal;
//! [`depth_mesh`] the one triangulation of a depth map (view and exports);
//! [`solver`] the linearised coarse-to-fine Gauss-Newton scheme; [`scene`] and
//! [`io`] synthetic scenes and files; [`photo`] a photograph as the solver
//! needs it.
#![deny(missing_docs)]

pub mod albedo;
pub mod albedo_chain;
pub mod albedo_texture;
pub mod camera;
pub mod camera_file;
pub mod cancel;
pub mod colour;
pub mod denoise;
pub mod depth_mesh;
pub mod grid;
pub mod io;
pub mod light;
pub(crate) mod linalg;
pub mod material;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod model_fit;
pub mod occlusion;
pub mod output;
pub mod params;
pub mod photo;
pub mod photograph_solve;
pub mod resample;
pub mod scene;
pub mod selection;
pub mod solver;
