//! The 3-D view of a recovered depth map: wgpu only (no egui, no solver).
//!
//! - [`SurfaceMesh`] turns a depth [`Grid`](sfs_core::grid::Grid) into a
//!   triangle mesh on the CPU.
//! - [`OrbitCamera`] is a glam orbit camera around that mesh.
//! - [`SurfaceRenderer`] owns the long-lived GPU state: it renders into its own
//!   colour + depth target ([`SurfaceRenderer::render`], e.g. in egui-wgpu's
//!   `CallbackTrait::prepare`) and blits that target into a render pass opened
//!   by someone else ([`SurfaceRenderer::paint`], e.g. in `CallbackTrait::paint`,
//!   whose pass has no depth attachment).
//!
//! # Coordinate spaces
//!
//! - *camera*: the photo's camera, as in `sfs_core::camera`: x right, y down,
//!   z forward (depth), origin at the optical centre.
//! - *world*: right-handed, y up, used for viewing:
//!   `world = (x_camera, -y_camera, -z_camera)` (a half turn about x). The
//!   photo's camera sits at the world origin looking down `-z`, so a point's
//!   depth is `-z_world`.
//! - *view*: glam's right-handed y-up view space of the [`OrbitCamera`]
//!   (looking down `-z_view`); *clip*: WebGPU clip space (depth 0..1).

mod mesh;
mod orbit;
mod renderer;
mod settings;

pub use mesh::{Bounds, NO_VALUE, SurfaceMesh, SurfaceVertex};
pub use orbit::OrbitCamera;
pub use renderer::{SurfaceRenderer, request_headless_device};
pub use settings::{ColourMode, RenderError, ViewSettings};

pub use sfs_core::colour::colour_map;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_map_runs_dark_blue_to_green_to_dark_red() {
        let low = colour_map(0.0);
        let mid = colour_map(0.5);
        let high = colour_map(1.0);
        let blue = colour_map(0.15);
        assert!(
            low.iter().map(|&c| u32::from(c)).sum::<u32>() < 120,
            "{low:?}"
        );
        assert!(blue[2] > blue[0] && blue[2] > blue[1], "{blue:?}");
        assert!(mid[1] > 200, "{mid:?}");
        assert!(high[0] > high[1] && high[0] > high[2], "{high:?}");
        assert_eq!(colour_map(-3.0), low);
        assert_eq!(colour_map(f32::NAN), low);
        assert_eq!(colour_map(7.0), high);
    }
}
