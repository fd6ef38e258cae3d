//! sfs-studio: perspective shape from shading with a point light at the
//! optical centre (Maurer, Ju, Breuss, Bruhn, GCPR 2015).
//!
//! Layers (see ARCHITECTURE.md): [`grid`], [`camera`], [`params`] are core
//! types; [`model`] and [`metrics`] the image formation and error measures,
//! [`denoise`] image noise and its removal;
//! [`depth_mesh`] the one triangulation of a depth map (view and exports);
//! [`solver`] the linearised coarse-to-fine Gauss-Newton scheme; [`scene`] and
//! [`io`] synthetic scenes and files; [`worker`] the viewer's solver thread
//! and [`mask_edit`] its mask editing model (both without egui); `render`
//! the wgpu surface renderer and `app` the egui viewer (feature `gui`);
//! [`cli`] the command line.
#![deny(missing_docs)]

#[cfg(feature = "gui")]
pub mod app;
pub mod calibration;
pub mod camera;
pub mod cli;
pub mod colour;
pub mod denoise;
pub mod depth_mesh;
pub mod filters;
pub mod fit;
pub mod grid;
pub mod io;
pub mod light;
pub mod mask_edit;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod order;
pub mod output;
pub mod params;
pub mod photo;
#[cfg(feature = "gui")]
pub mod render;
pub mod resample;
pub mod scene;
pub mod solver;
pub mod worker;
