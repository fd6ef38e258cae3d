//! What the renderer is told and what it can fail with: the view
//! settings, the colour mode, the errors.

use super::orbit::OrbitCamera;

/// Errors of the renderer. None of them is a panic: GPU-dependent failures
/// are reported here and the caller decides (log, skip the frame, fall back).
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter (GPU or software rasteriser) could be found.
    #[error("no wgpu adapter available (try WGPU_BACKEND=gl or vulkan): {0}")]
    NoAdapter(#[from] wgpu::RequestAdapterError),
    /// The adapter refused to open a device.
    #[error("could not open the wgpu device: {0}")]
    Device(#[from] wgpu::RequestDeviceError),
    /// The colour format cannot be both rendered to and sampled with filtering.
    #[error("texture format {0:?} cannot be used as a filterable render target")]
    UnsupportedFormat(wgpu::TextureFormat),
    /// The requested view size is zero or larger than the device allows.
    #[error("view size {width_px}x{height_px} px is outside 1..={max_px} px")]
    InvalidSize {
        /// Requested width in pixels.
        width_px: u32,
        /// Requested height in pixels.
        height_px: u32,
        /// The device's `max_texture_dimension_2d`.
        max_px: u32,
    },
    /// A mesh buffer would exceed the device's `max_buffer_size`.
    #[error("mesh needs a {bytes}-byte buffer but the device allows {max_bytes}")]
    MeshTooLarge {
        /// Size of the buffer that would be needed.
        bytes: u64,
        /// The device's `max_buffer_size`.
        max_bytes: u64,
    },
    /// Reading back is only implemented for 8-bit RGBA/BGRA targets.
    #[error("reading back texture format {0:?} is not supported (8-bit RGBA/BGRA only)")]
    UnsupportedReadback(wgpu::TextureFormat),
    /// Waiting for the GPU failed.
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// Mapping the read-back buffer failed.
    #[error("mapping the read-back buffer failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    /// The mapped range of the read-back buffer could not be accessed.
    #[error("reading the mapped buffer failed: {0}")]
    MapRange(#[from] wgpu::MapRangeError),
    /// The map callback was dropped without being called.
    #[error("the read-back buffer was never mapped")]
    MapCallbackLost,
}

/// How the surface is coloured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ColourMode {
    /// Grey Lambertian shading plus ambient light.
    #[default]
    Shaded,
    /// [`colour_map`] of the depth (`-z_world`) over [`ViewSettings::value_range`],
    /// lightly shaded.
    Depth,
    /// [`colour_map`] of the vertex value (e.g. reprojection error) over
    /// [`ViewSettings::value_range`], lightly shaded. Vertices without a value
    /// ([`NO_VALUE`]) are grey.
    Error,
    /// The photograph on the surface: each vertex's
    /// [`SurfaceVertex::photo`] grey with the 2-D panels' display gamma
    /// (2.2), barely shaded (the photograph has its own shading); vertices
    /// without one are dark.
    Photo,
}

/// Everything that changes how one frame looks (small, `Copy`, per frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSettings {
    /// The orbit camera.
    pub camera: OrbitCamera,
    /// Direction *towards* the light in **view space**, as yaw about the view's
    /// up axis (positive: light from the right). `0, 0` is a headlight: light
    /// from the viewer, as in the shape-from-shading model (light at the
    /// optical centre). The light moves with the camera.
    pub light_yaw_rad: f32,
    /// Direction towards the light in view space: pitch above the view
    /// direction (positive: light from above).
    pub light_pitch_rad: f32,
    /// Ambient light fraction in 0..1 (shade = ambient + (1 - ambient) Lambert).
    pub ambient: f32,
    /// How the surface is coloured.
    pub colour_mode: ColourMode,
    /// `[low, high]` mapped to the ends of the colour map (depth units for
    /// [`ColourMode::Depth`], value units for [`ColourMode::Error`]).
    pub value_range: [f32; 2],
    /// Draw the triangle edges (a line list, works without `POLYGON_MODE_LINE`)
    /// instead of the filled surface.
    pub wireframe: bool,
    /// Background colour, display (sRGB-encoded) RGB in 0..1.
    pub background_rgb: [f32; 3],
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self {
            camera: OrbitCamera::default(),
            light_yaw_rad: 0.0,
            light_pitch_rad: 0.0,
            ambient: 0.15,
            colour_mode: ColourMode::Shaded,
            value_range: [0.0, 1.0],
            wireframe: false,
            background_rgb: [0.1, 0.1, 0.12],
        }
    }
}
