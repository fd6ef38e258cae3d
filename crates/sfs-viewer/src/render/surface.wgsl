// The depth-map surface: filled triangles or a line list, one uniform block.

// Keep in sync with `SurfaceUniforms` in renderer.rs.
struct SurfaceUniforms {
    clip_from_world: mat4x4<f32>,
    // Unit vector from the surface towards the light, world space.
    light_dir_world: vec3<f32>,
    ambient: f32,
    value_min: f32,
    value_max: f32,
    // 0 shaded, 1 depth, 2 error, 3 photo (`ColourMode`).
    colour_mode: u32,
    // 1 when the target stores linear values (an sRGB format).
    output_linear: u32,
}

@group(0) @binding(0) var<uniform> uniforms: SurfaceUniforms;

// Keep in sync with `SurfaceVertex` in mesh.rs.
struct VertexIn {
    @location(0) position_world: vec3<f32>,
    @location(1) normal_world: vec3<f32>,
    @location(2) value: f32,
    @location(3) photo: f32,
}

struct VertexOut {
    @builtin(position) position_clip: vec4<f32>,
    @location(0) normal_world: vec3<f32>,
    @location(1) depth: f32,
    @location(2) value: f32,
    @location(3) photo: f32,
}

@vertex
fn vs_surface(in: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.position_clip = uniforms.clip_from_world * vec4<f32>(in.position_world, 1.0);
    out.normal_world = in.normal_world;
    out.depth = -in.position_world.z;
    out.value = in.value;
    out.photo = in.photo;
    return out;
}

// Turbo colour map, degree-5 polynomial (keep in sync with `TURBO` in mod.rs).
const TURBO_C0 = vec3<f32>(0.13572138, 0.09140261, 0.1066733);
const TURBO_C1 = vec3<f32>(4.6153926, 2.1941884, 12.641946);
const TURBO_C2 = vec3<f32>(-42.660324, 4.8429666, -60.582047);
const TURBO_C3 = vec3<f32>(132.13108, -14.185033, 110.36277);
const TURBO_C4 = vec3<f32>(-152.9424, 4.2772985, -89.90311);
const TURBO_C5 = vec3<f32>(59.28638, 2.829566, 27.34825);

fn colour_map(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0);
    let c = TURBO_C0 + x * (TURBO_C1 + x * (TURBO_C2 + x * (TURBO_C3 + x * (TURBO_C4 + x * TURBO_C5))));
    return clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
}

fn linear_from_srgb(c: vec3<f32>) -> vec3<f32> {
    let low = c / 12.92;
    let high = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(high, low, c <= vec3<f32>(0.04045));
}

@fragment
fn fs_surface(in: VertexOut, @builtin(front_facing) front_facing: bool) -> @location(0) vec4<f32> {
    // Two-sided lighting: seen from behind, the surface faces the other way.
    var normal = normalize(in.normal_world);
    if !front_facing {
        normal = -normal;
    }
    let lambert = max(dot(normal, uniforms.light_dir_world), 0.0);
    let shade = uniforms.ambient + (1.0 - uniforms.ambient) * lambert;
    var colour = vec3<f32>(0.85 * shade);
    if uniforms.colour_mode == 3u {
        // The photograph, display gamma as in the 2-D panels; NO_VALUE dark.
        if in.photo > 1.0e30 {
            colour = vec3<f32>(0.2 * shade);
        } else {
            colour = vec3<f32>(pow(clamp(in.photo, 0.0, 1.0), 1.0 / 2.2)) * (0.8 + 0.2 * shade);
        }
    } else if uniforms.colour_mode != 0u {
        let v = select(in.value, in.depth, uniforms.colour_mode == 1u);
        if v > 1.0e30 {
            colour = vec3<f32>(0.5 * shade);
        } else {
            let t = (v - uniforms.value_min) / max(uniforms.value_max - uniforms.value_min, 1.0e-20);
            colour = colour_map(t) * (0.5 + 0.5 * shade);
        }
    }
    if uniforms.output_linear != 0u {
        colour = linear_from_srgb(colour);
    }
    return vec4<f32>(colour, 1.0);
}
