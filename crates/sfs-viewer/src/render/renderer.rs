//! Long-lived GPU state: pipelines, mesh buffers and the offscreen target.

use super::mesh::{SurfaceMesh, SurfaceVertex};
use super::settings::{ColourMode, RenderError, ViewSettings};
use glam::Vec3;
use std::num::NonZeroU64;

/// Depth format of the offscreen target.
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Uniform block of surface.wgsl. Keep in sync with `SurfaceUniforms` there.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct SurfaceUniforms {
    clip_from_world: [[f32; 4]; 4],
    /// Unit vector from the surface towards the light, world space.
    light_dir_world: [f32; 3],
    ambient: f32,
    value_min: f32,
    value_max: f32,
    /// 0 shaded, 1 depth, 2 error, 3 photo.
    colour_mode: u32,
    /// 1 when the target format is sRGB (the shader then outputs linear values).
    output_linear: u32,
}

const _: () = assert!(std::mem::size_of::<SurfaceUniforms>() == 96);

impl SurfaceUniforms {
    fn new(settings: &ViewSettings, aspect: f32, output_linear: bool) -> Self {
        let camera = &settings.camera;
        let (sin_yaw, cos_yaw) = settings.light_yaw_rad.sin_cos();
        let (sin_pitch, cos_pitch) = settings.light_pitch_rad.sin_cos();
        let light_dir_view = Vec3::new(sin_yaw * cos_pitch, sin_pitch, cos_yaw * cos_pitch);
        let light_dir_world = camera
            .world_from_view()
            .transform_vector3(light_dir_view)
            .try_normalize()
            .unwrap_or(Vec3::Z);
        Self {
            clip_from_world: camera.clip_from_world(aspect).to_cols_array_2d(),
            light_dir_world: light_dir_world.to_array(),
            ambient: settings.ambient.clamp(0.0, 1.0),
            value_min: settings.value_range[0],
            value_max: settings.value_range[1],
            colour_mode: match settings.colour_mode {
                ColourMode::Shaded => 0,
                ColourMode::Depth => 1,
                ColourMode::Error => 2,
                ColourMode::Photo => 3,
            },
            output_linear: u32::from(output_linear),
        }
    }
}

/// A GPU buffer reused while the data fits, re-created (with headroom) when not.
struct GrowableBuffer {
    buffer: wgpu::Buffer,
    capacity_bytes: u64,
    len_bytes: u64,
}

/// Writes `data` into `slot`, growing it when needed (`data` must fit the
/// device's `max_buffer_size`); never reads back.
fn write_growable(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    slot: &mut Option<GrowableBuffer>,
    data: &[u8],
    usage: wgpu::BufferUsages,
    label: &str,
) {
    let len_bytes = data.len() as u64;
    match slot {
        Some(existing) if existing.capacity_bytes >= len_bytes => existing.len_bytes = len_bytes,
        _ => {
            let align = wgpu::COPY_BUFFER_ALIGNMENT;
            let max_bytes = device.limits().max_buffer_size.max(align);
            let wanted = (len_bytes + len_bytes / 4).clamp(align, max_bytes);
            let capacity_bytes = wanted.div_ceil(align) * align;
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: capacity_bytes,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            *slot = Some(GrowableBuffer {
                buffer,
                capacity_bytes,
                len_bytes,
            });
        }
    }
    if let Some(target) = slot
        && len_bytes > 0
    {
        queue.write_buffer(&target.buffer, 0, data);
    }
}

/// The offscreen colour + depth target and the blit bind group reading it.
struct Target {
    size_px: [u32; 2],
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    blit_bind_group: wgpu::BindGroup,
}

/// The 3-D surface view's GPU state: create once (e.g. into egui-wgpu's
/// `callback_resources`), [`upload`](Self::upload) each new mesh,
/// [`render`](Self::render) each frame, then [`paint`](Self::paint).
///
/// One renderer serves one view per frame (the uniforms are written by
/// `render`).
pub struct SurfaceRenderer {
    colour_format: wgpu::TextureFormat,
    surface_pipeline: wgpu::RenderPipeline,
    wireframe_pipeline: wgpu::RenderPipeline,
    blit_pipeline: wgpu::RenderPipeline,
    uniform_buffer: wgpu::Buffer,
    uniform_bind_group: wgpu::BindGroup,
    blit_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    vertices: Option<GrowableBuffer>,
    triangle_indices: Option<GrowableBuffer>,
    line_indices: Option<GrowableBuffer>,
    target: Option<Target>,
}

impl SurfaceRenderer {
    /// Builds the pipelines for an offscreen target of `colour_format` (use the
    /// format of the pass [`paint`](Self::paint) will draw into, e.g. egui's
    /// target format; that pass must be single-sampled with no depth attachment).
    pub fn new(
        device: &wgpu::Device,
        colour_format: wgpu::TextureFormat,
    ) -> Result<Self, RenderError> {
        let features = colour_format.guaranteed_format_features(device.features());
        let needed = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        if colour_format.has_depth_aspect()
            || !features.allowed_usages.contains(needed)
            || !features
                .flags
                .contains(wgpu::TextureFormatFeatureFlags::FILTERABLE)
        {
            return Err(RenderError::UnsupportedFormat(colour_format));
        }

        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("surface uniforms"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: NonZeroU64::new(size_of::<SurfaceUniforms>() as u64),
                },
                count: None,
            }],
        });
        let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("surface uniforms"),
            size: size_of::<SurfaceUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let uniform_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surface uniforms"),
            layout: &uniform_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform_buffer.as_entire_binding(),
            }],
        });
        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("surface blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("surface blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });

        let surface_shader = device.create_shader_module(wgpu::include_wgsl!("surface.wgsl"));
        let surface_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("surface"),
            bind_group_layouts: &[Some(&uniform_layout)],
            immediate_size: 0,
        });
        let vertex_attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32, 3 => Float32];
        let vertex_layout = wgpu::VertexBufferLayout {
            array_stride: size_of::<SurfaceVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &vertex_attributes,
        };
        let colour_target = [Some(wgpu::ColorTargetState {
            format: colour_format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })];
        let blit_shader = device.create_shader_module(wgpu::include_wgsl!("blit.wgsl"));
        let blit_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("surface blit"),
            bind_group_layouts: &[Some(&blit_layout)],
            immediate_size: 0,
        });
        let depth_test = wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        };
        let surface = (&surface_layout, &surface_shader, "vs_surface", "fs_surface");
        let blit = (&blit_pipeline_layout, &blit_shader, "vs_blit", "fs_blit");
        let vertex_buffers = [Some(vertex_layout)];
        let pipeline =
            |label, (layout, module, vertex, fragment), topology, depth_stencil: Option<_>| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(layout),
                    vertex: wgpu::VertexState {
                        module,
                        entry_point: Some(vertex),
                        compilation_options: Default::default(),
                        buffers: if depth_stencil.is_some() {
                            &vertex_buffers
                        } else {
                            &[]
                        },
                    },
                    // No culling: the surface can be seen from behind.
                    primitive: wgpu::PrimitiveState {
                        topology,
                        front_face: wgpu::FrontFace::Ccw,
                        ..Default::default()
                    },
                    depth_stencil,
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module,
                        entry_point: Some(fragment),
                        compilation_options: Default::default(),
                        targets: &colour_target,
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
        use wgpu::PrimitiveTopology::{LineList, TriangleList};
        let surface_pipeline = pipeline("surface", surface, TriangleList, Some(depth_test.clone()));
        let wireframe_pipeline = pipeline("surface wireframe", surface, LineList, Some(depth_test));
        let blit_pipeline = pipeline("surface blit", blit, TriangleList, None);

        Ok(Self {
            colour_format,
            surface_pipeline,
            wireframe_pipeline,
            blit_pipeline,
            uniform_buffer,
            uniform_bind_group,
            blit_layout,
            sampler,
            vertices: None,
            triangle_indices: None,
            line_indices: None,
            target: None,
        })
    }

    /// The offscreen colour format (also the blit's target format).
    pub fn colour_format(&self) -> wgpu::TextureFormat {
        self.colour_format
    }

    /// Replaces the drawn mesh: writes into the existing buffers when it fits,
    /// else re-creates them with 25 % headroom. No read-back, no wait. A mesh
    /// too large for the device is refused whole (the old one stays).
    pub fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        mesh: &SurfaceMesh,
    ) -> Result<(), RenderError> {
        let vertices: &[u8] = bytemuck::cast_slice(mesh.vertices());
        let triangles: &[u8] = bytemuck::cast_slice(mesh.triangle_indices());
        let lines: &[u8] = bytemuck::cast_slice(mesh.line_indices());
        let max_bytes = device.limits().max_buffer_size;
        let bytes = [vertices, triangles, lines].map(|data| data.len() as u64);
        if let Some(&bytes) = bytes.iter().find(|&&b| b > max_bytes) {
            return Err(RenderError::MeshTooLarge { bytes, max_bytes });
        }
        use wgpu::BufferUsages as Usage;
        let slots = [
            (
                &mut self.vertices,
                vertices,
                Usage::VERTEX,
                "surface vertices",
            ),
            (
                &mut self.triangle_indices,
                triangles,
                Usage::INDEX,
                "surface triangles",
            ),
            (&mut self.line_indices, lines, Usage::INDEX, "surface edges"),
        ];
        for (slot, data, usage, label) in slots {
            write_growable(device, queue, slot, data, usage, label);
        }
        Ok(())
    }

    /// Records the surface into the offscreen target of `size_px` (created or
    /// resized as needed): clear to the background, depth-tested draw.
    /// Writes the uniforms through `queue`; call before [`paint`](Self::paint).
    pub fn render(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        size_px: [u32; 2],
        settings: &ViewSettings,
    ) -> Result<(), RenderError> {
        self.record(device, queue, encoder, size_px, settings)
            .map(|_| ())
    }

    /// [`render`](Self::render), returning the target it drew into.
    fn record(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        size_px: [u32; 2],
        settings: &ViewSettings,
    ) -> Result<&Target, RenderError> {
        let max_px = device.limits().max_texture_dimension_2d;
        if size_px.iter().any(|&s| s == 0 || s > max_px) {
            return Err(RenderError::InvalidSize {
                width_px: size_px[0],
                height_px: size_px[1],
                max_px,
            });
        }
        let target = match self.target.take() {
            Some(target) if target.size_px == size_px => target,
            _ => self.create_target(device, size_px),
        };
        let target = &*self.target.insert(target);
        let output_linear = self.colour_format.is_srgb();
        let aspect = size_px[0] as f32 / size_px[1] as f32;
        let uniforms = SurfaceUniforms::new(settings, aspect, output_linear);
        queue.write_buffer(&self.uniform_buffer, 0, bytemuck::bytes_of(&uniforms));
        let [r, g, b] = settings.background_rgb.map(|c| {
            let c = f64::from(c.clamp(0.0, 1.0));
            match (output_linear, c <= 0.04045) {
                (false, _) => c,
                (true, true) => c / 12.92,
                (true, false) => ((c + 0.055) / 1.055).powf(2.4),
            }
        });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("surface"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target.colour_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        let (pipeline, indices) = if settings.wireframe {
            (&self.wireframe_pipeline, &self.line_indices)
        } else {
            (&self.surface_pipeline, &self.triangle_indices)
        };
        if let (Some(vertices), Some(indices)) = (&self.vertices, indices)
            && vertices.len_bytes > 0
            && indices.len_bytes > 0
        {
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.uniform_bind_group, &[]);
            pass.set_vertex_buffer(0, vertices.buffer.slice(..vertices.len_bytes));
            pass.set_index_buffer(
                indices.buffer.slice(..indices.len_bytes),
                wgpu::IndexFormat::Uint32,
            );
            let index_count = (indices.len_bytes / 4) as u32;
            pass.draw_indexed(0..index_count, 0, 0..1);
        }
        drop(pass);
        Ok(target)
    }

    fn create_target(&self, device: &wgpu::Device, size_px: [u32; 2]) -> Target {
        let size = wgpu::Extent3d {
            width: size_px[0],
            height: size_px[1],
            depth_or_array_layers: 1,
        };
        let readable = self
            .colour_format
            .guaranteed_format_features(device.features())
            .allowed_usages
            & wgpu::TextureUsages::COPY_SRC;
        let texture = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | usage,
                view_formats: &[],
            })
        };
        let usage = wgpu::TextureUsages::TEXTURE_BINDING | readable;
        let colour = texture("surface colour", self.colour_format, usage);
        let depth = texture("surface depth", DEPTH_FORMAT, wgpu::TextureUsages::empty());
        let colour_view = colour.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let blit_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surface blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&colour_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        Target {
            size_px,
            colour,
            colour_view,
            depth_view,
            blit_bind_group,
        }
    }

    /// Draws the last [`render`](Self::render)ed image over the pass's
    /// viewport (a full-screen triangle sampling the offscreen target).
    /// Does nothing before the first `render`.
    pub fn paint(&self, render_pass: &mut wgpu::RenderPass<'static>) {
        if let Some(target) = &self.target {
            render_pass.set_pipeline(&self.blit_pipeline);
            render_pass.set_bind_group(0, &target.blit_bind_group, &[]);
            render_pass.draw(0..3, 0..1);
        }
    }

    /// Renders one frame and reads it back as tightly packed RGBA8 rows, top
    /// row first (for tests and headless screenshots). Blocks until the GPU
    /// is done. Needs an 8-bit RGBA or BGRA colour format.
    pub fn render_to_rgba(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        size_px: [u32; 2],
        settings: &ViewSettings,
    ) -> Result<Vec<u8>, RenderError> {
        use wgpu::TextureFormat as F;
        let swap_red_blue = match self.colour_format {
            F::Rgba8Unorm | F::Rgba8UnormSrgb => false,
            F::Bgra8Unorm | F::Bgra8UnormSrgb => true,
            other => return Err(RenderError::UnsupportedReadback(other)),
        };
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("surface read-back"),
        });
        let target = self.record(device, queue, &mut encoder, size_px, settings)?;
        let colour = target.colour.clone();
        read_texture_rgba(device, queue, encoder, &colour, size_px, swap_red_blue)
    }
}

/// Submits `encoder` plus a copy of `texture` (8-bit, 4 channels) and reads it
/// back as tight rows, top first; swaps channels 0 and 2 if asked.
fn read_texture_rgba(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    mut encoder: wgpu::CommandEncoder,
    texture: &wgpu::Texture,
    size_px: [u32; 2],
    swap_red_blue: bool,
) -> Result<Vec<u8>, RenderError> {
    let [width, height] = size_px;
    let unpadded_row_bytes = 4 * width;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let padded_row_bytes = unpadded_row_bytes.div_ceil(align) * align;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("surface read-back"),
        size: u64::from(padded_row_bytes) * u64::from(height),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row_bytes),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
    queue.submit([encoder.finish()]);
    let (sender, receiver) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |result| {
        // The receiver only goes away if we already returned an error.
        let _ = sender.send(result);
    });
    device.poll(wgpu::PollType::wait_indefinitely())?;
    receiver
        .try_recv()
        .map_err(|_| RenderError::MapCallbackLost)??;
    let mut rgba = Vec::with_capacity(unpadded_row_bytes as usize * height as usize);
    {
        let mapped = buffer.get_mapped_range(..)?;
        for row in mapped.chunks_exact(padded_row_bytes as usize) {
            rgba.extend_from_slice(&row[..unpadded_row_bytes as usize]);
        }
    }
    buffer.unmap();
    if swap_red_blue {
        for pixel in rgba.chunks_exact_mut(4) {
            pixel.swap(0, 2);
        }
    }
    Ok(rgba)
}

/// Opens a device for off-screen rendering (tests, headless screenshots):
/// the first adapter of the backends chosen by `WGPU_BACKEND` (`gl`,
/// `vulkan`, ...; all when unset or empty; a software rasteriser such as
/// llvmpipe or lavapipe is fine),
/// with that adapter's limits. Block on it with e.g. `pollster::block_on`.
pub async fn request_headless_device()
-> Result<(wgpu::Device, wgpu::Queue, wgpu::AdapterInfo), RenderError> {
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if descriptor.backends.is_empty() {
        // `WGPU_BACKEND=` (set but empty) would enable nothing.
        descriptor.backends = wgpu::Backends::all();
    }
    let instance = wgpu::Instance::new(descriptor);
    let adapter = instance
        .request_adapter(&wgpu::RequestAdapterOptions::default())
        .await?;
    let (device, queue) = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("sfs-studio headless"),
            required_limits: adapter.limits(),
            ..Default::default()
        })
        .await?;
    Ok((device, queue, adapter.get_info()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::OrbitCamera;
    use sfs_core::camera::Intrinsics;
    use sfs_core::grid::Grid;
    use wgpu::TextureFormat::{Bgra8Unorm, Rgba8Unorm, Rgba8UnormSrgb, Rgba16Float};

    const SIZE_PX: [u32; 2] = [128, 128];

    /// A device from whatever wgpu finds (`WGPU_BACKEND` picks); no device
    /// fails the test rather than skipping it.
    fn device() -> (wgpu::Device, wgpu::Queue) {
        match pollster::block_on(request_headless_device()) {
            Ok((device, queue, info)) => {
                eprintln!("wgpu adapter: {} ({:?})", info.name, info.backend);
                (device, queue)
            }
            Err(error) => panic!(
                "no wgpu device for the GPU tests: {error}. Needs Mesa's llvmpipe \
                 (WGPU_BACKEND=gl) or lavapipe (apt mesa-vulkan-drivers libvulkan1)"
            ),
        }
    }

    /// Front cap of a sphere (radius 3, centre 10 in front of a 64x64 camera,
    /// f = 64 px); NaN where the ray misses.
    fn sphere_mesh() -> SurfaceMesh {
        let camera = Intrinsics::centred(64.0, 64, 64);
        let depth = Grid::from_fn(64, 64, |c, r| {
            let (x, y) = camera.image_xy(c as f64, r as f64);
            // |t (x/f, y/f, 1) - (0, 0, 10)|^2 = 9, nearer root; depth = t.
            let a = 1.0 + (x * x + y * y) / (64.0 * 64.0);
            let discriminant = 400.0 - 4.0 * a * 91.0;
            (20.0 - discriminant.sqrt()) / (2.0 * a) // NaN when negative
        });
        SurfaceMesh::from_depth(&depth, &camera, None)
    }

    fn render_with(
        (device, queue): &(wgpu::Device, wgpu::Queue),
        format: wgpu::TextureFormat,
        mesh: Option<&SurfaceMesh>,
        settings: &ViewSettings,
    ) -> Vec<u8> {
        let mut renderer = SurfaceRenderer::new(device, format).expect("renderer");
        if let Some(mesh) = mesh {
            renderer.upload(device, queue, mesh).expect("upload");
        }
        renderer
            .render_to_rgba(device, queue, SIZE_PX, settings)
            .expect("render")
    }

    fn pixel(rgba: &[u8], column: u32, row: u32) -> [u8; 4] {
        let i = 4 * (row * SIZE_PX[0] + column) as usize;
        [rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3]]
    }

    fn brightness(p: [u8; 4]) -> u32 {
        p[..3].iter().map(|&c| u32::from(c)).sum()
    }

    #[test]
    fn renders_a_lit_sphere_and_its_wireframe() {
        let gpu = device();
        let mesh = sphere_mesh();
        let settings = ViewSettings {
            camera: OrbitCamera::framing(&mesh.bounds(), 1.0),
            ..Default::default()
        };
        let draw = |settings: ViewSettings| render_with(&gpu, Rgba8Unorm, Some(&mesh), &settings);

        let empty = render_with(&gpu, Rgba8Unorm, None, &settings);
        let clear = pixel(&empty, 0, 0);
        let expected = settings.background_rgb.map(|c| c * 255.0);
        assert!(
            (0..3).all(|i| (f32::from(clear[i]) - expected[i]).abs() <= 1.0),
            "{clear:?}"
        );
        assert!(empty.chunks_exact(4).all(|p| p == clear));

        let filled = draw(settings);
        for (column, row) in [(0, 0), (127, 0), (0, 127), (127, 127)] {
            assert_eq!(
                pixel(&filled, column, row),
                clear,
                "corner ({column}, {row})"
            );
        }
        let centre = pixel(&filled, 64, 64);
        assert_ne!(centre, clear);
        // Headlight: the rim (first surface pixels of the middle row) is darker.
        let first = (0..64)
            .find(|&c| pixel(&filled, c, 64) != clear)
            .expect("a rim");
        let rim = pixel(&filled, first + 1, 64);
        assert!(
            brightness(centre) > brightness(rim) + 60,
            "{centre:?} vs rim {rim:?}"
        );
        // Light from the left (negative view-space yaw) lights the left half.
        let side_lit = draw(ViewSettings {
            light_yaw_rad: -1.0,
            ..settings
        });
        assert!(brightness(pixel(&side_lit, 44, 64)) > brightness(pixel(&side_lit, 84, 64)));

        let wireframe = draw(ViewSettings {
            wireframe: true,
            ..settings
        });
        let differing = filled
            .chunks(4)
            .zip(wireframe.chunks(4))
            .filter(|(a, b)| a != b);
        assert!(differing.count() > 100);
        assert_eq!(pixel(&wireframe, 0, 0), clear);

        // The nearest point (depth 7) in the middle of the range: green.
        let range = ViewSettings {
            value_range: [6.0, 8.0],
            ..settings
        };
        for colour_mode in [ColourMode::Depth, ColourMode::Error] {
            let c = pixel(
                &draw(ViewSettings {
                    colour_mode,
                    ..range
                }),
                64,
                64,
            );
            assert!(c[1] > 200 && c[1] > c[0] && c[1] > c[2], "{c:?}");
        }
        // Other 8-bit formats show the same picture; others cannot be read.
        for format in [Rgba8UnormSrgb, Bgra8Unorm] {
            let other = render_with(&gpu, format, Some(&mesh), &range);
            let worst = other.iter().zip(&filled).map(|(a, b)| a.abs_diff(*b)).max();
            assert!(
                worst.is_some_and(|w| w <= 3),
                "{format:?} differs by {worst:?}"
            );
        }
        let mut float = SurfaceRenderer::new(&gpu.0, Rgba16Float).expect("renderer");
        let result = float.render_to_rgba(&gpu.0, &gpu.1, SIZE_PX, &settings);
        assert!(matches!(result, Err(RenderError::UnsupportedReadback(_))));
    }

    #[test]
    fn renderer_can_live_in_egui_callback_resources() {
        fn send_sync_static<T: Send + Sync + 'static>() {}
        send_sync_static::<SurfaceRenderer>();
    }

    #[test]
    fn reuses_buffers_resizes_the_target_and_rejects_bad_sizes() {
        let (device, queue) = device();
        let mut renderer = SurfaceRenderer::new(&device, Rgba8Unorm).expect("renderer");
        let settings = ViewSettings::default();
        let small = SurfaceMesh::from_depth(
            &Grid::filled(8, 8, 1.0),
            &Intrinsics::centred(8.0, 8, 8),
            None,
        );
        for mesh in [sphere_mesh(), small, SurfaceMesh::default()] {
            renderer.upload(&device, &queue, &mesh).expect("upload");
            let rgba = renderer.render_to_rgba(&device, &queue, [40, 30], &settings);
            assert_eq!(rgba.expect("render").len(), 4 * 40 * 30);
        }
        let rgba = renderer.render_to_rgba(&device, &queue, [0, 30], &settings);
        assert!(matches!(rgba, Err(RenderError::InvalidSize { .. })));
    }

    #[test]
    fn paint_blits_into_a_foreign_pass() {
        let (device, queue) = device();
        let mut renderer = SurfaceRenderer::new(&device, Rgba8Unorm).expect("renderer");
        let red = ViewSettings {
            background_rgb: [1.0, 0.0, 0.0],
            ..Default::default()
        };
        let foreign = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("foreign"),
            size: wgpu::Extent3d {
                width: 16,
                height: 16,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: Rgba8Unorm,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        renderer
            .render(&device, &queue, &mut encoder, [8, 8], &red)
            .expect("render");
        {
            // Like egui's: a pass without depth, the viewport set to the callback rect.
            let view = foreign.create_view(&Default::default());
            let mut pass = encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::GREEN),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    ..Default::default()
                })
                .forget_lifetime();
            pass.set_viewport(4.0, 4.0, 8.0, 8.0, 0.0, 1.0);
            renderer.paint(&mut pass);
        }
        let rgba = read_texture_rgba(&device, &queue, encoder, &foreign, [16, 16], false);
        let rgba = rgba.expect("read-back");
        let at = |c: usize, r: usize| &rgba[4 * (r * 16 + c)..][..4];
        for (c, r) in [(0, 0), (15, 15), (12, 11), (3, 4)] {
            assert_eq!(at(c, r), [0, 255, 0, 255], "outside at ({c}, {r})");
        }
        for (c, r) in [(4, 4), (11, 11), (7, 8)] {
            assert_eq!(at(c, r), [255, 0, 0, 255], "inside at ({c}, {r})");
        }
    }
}
