//! sfs-viewer: the interactive viewer of sfs-studio over [`sfs_core`].
//!
//! [`worker`] is the viewer's solver thread and [`mask_edit`] its mask
//! editing model (both without egui); [`render`] the wgpu surface renderer
//! and [`app`] the egui viewer. See ARCHITECTURE.md.
#![deny(missing_docs)]

pub mod app;
pub mod mask_edit;
pub mod render;
pub mod worker;

#[cfg(test)]
mod test_sets;
