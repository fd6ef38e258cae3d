//! `sfs-studio synth`: render a scene with ground truth into a folder.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

use sfs_core::camera_file::CameraFile;
use sfs_core::camera_file::LightEntry;
use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::light::PointLight;
use sfs_core::scene::shading::Shading;
use sfs_core::scene::{self, Scene, mesh, sombrero};

/// Arguments of `synth`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct SynthArgs {
    /// `sombrero` (analytic, METHOD.md section 7) or the path of an OBJ mesh.
    pub scene: String,
    /// Image size WIDTHxHEIGHT in pixels.
    #[arg(long, default_value = "256x256", value_parser = super::parse::parse_size)]
    pub size: (usize, usize),
    /// Gaussian noise standard deviation on the 0..255 scale; writes noisy8.png.
    #[arg(long, value_name = "SIGMA")]
    pub noise: Option<f64>,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Inpainting disc CX,CY,R (fractions of width, height and the smaller
    /// side) where confidence is 0; writes confidence.png (255 = trusted).
    #[arg(long, value_name = "CX,CY,R", value_parser = super::parse::parse_floats::<3>)]
    pub inpaint_disc: Option<[f64; 3]>,
    /// Mesh rotation X,Y,Z in degrees (applied about X, then Y, then Z).
    #[arg(long, value_name = "X,Y,Z", default_value = "180,0,0", value_parser = super::parse::parse_floats::<3>)]
    pub rotation: [f64; 3],
    /// Mesh distance from the camera, in units of the mesh's largest side.
    #[arg(long, default_value_t = 2.0)]
    pub distance: f64,
    /// Trace cast shadows: each light is hidden where the surface lies
    /// between it and the point (a ray march through the depth map); writes
    /// shadow.png (255 where no light reaches the object).
    #[arg(long)]
    pub shadows: bool,
    /// Lights (camera frame, in units of depth: the Sombrero's, or the
    /// mesh's largest side = 1) [default: one at the optical centre].
    #[command(flatten)]
    pub lights: super::lights::LightArgs,
    /// The surface's material [default: lambert]; recorded in scene.json.
    #[command(flatten)]
    pub material: super::lights::MaterialArgs,
    /// How the image is shaded: `mesh` (the renderer's own normals: a
    /// mesh's interpolated normals, the Sombrero's exact gradient) or
    /// `depth-map` (the ground-truth depth map through the solver's model
    /// with its upwind derivatives, object neighbours only: the true depth
    /// explains the image exactly, the paper's Table 1 convention).
    #[arg(long, value_name = "KIND", default_value = "mesh", value_parser = parse_shading)]
    pub shading: Shading,
    /// Output folder (created if needed).
    #[arg(long, value_parser = super::parse::parse_path)]
    pub out: PathBuf,
    /// A photometric-stereo set instead of one image: N photographs
    /// (led01.png, ...), each lit by one LED alone, on a ring 10 to 45
    /// degrees off the line to the object, at 0.75 of its distance, mu = 1,
    /// aimed at it; cast shadows traced. scene.json names each image's
    /// light; normals_gt.npy and albedo_gt.npy hold the truth. With
    /// --noise the ledNN.png are the noisy 8-bit photographs (the clean
    /// ones are clean_ledNN.png).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..=64))]
    pub ps_leds: Option<u32>,
    /// With --ps-leds: the albedo painted on the surface (image plane):
    /// `patches` (a few albedos in cells), `lines` (thin dark strokes),
    /// `smooth` (a slow gradient) or `uniform`.
    #[arg(
        long,
        value_name = "KIND",
        default_value = "patches",
        requires = "ps_leds"
    )]
    pub albedo_pattern: String,
}

/// Renders a scene lit by the lights given.
type Renderer = dyn Fn(&[PointLight]) -> Result<Scene>;

/// Renders the scene named by the arguments; with `--shadows`, also the
/// pixels no light reaches (cast or attached shadow).
pub fn render_scene(args: &SynthArgs) -> Result<(Scene, Option<Grid<bool>>)> {
    let (width, height) = args.size;
    if !args.lights.indices.is_empty() {
        anyhow::bail!("--light-index picks lights of a camera file; synth takes --light X,Y,Z");
    }
    let lights = args.lights.lights()?.unwrap_or_default();
    let material = args.material.material()?.unwrap_or_default();
    let shading = args.shading;
    let render: Box<Renderer> = if args.scene == "sombrero" {
        Box::new(move |lights: &[PointLight]| {
            Ok(shading.apply(sombrero::sombrero_shaded(width, height, lights, material)))
        })
    } else {
        let path = Path::new(&args.scene);
        let mesh = mesh::load_obj(path)?;
        let placement = mesh::Placement {
            rotation_deg: args.rotation,
            distance: args.distance,
            ..Default::default()
        };
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "mesh".into());
        Box::new(move |lights: &[PointLight]| {
            Ok(shading.apply(mesh::render_shaded(
                &mesh, width, height, &placement, lights, material, &name,
            )?))
        })
    };
    if args.shadows {
        let (scene, shadow) = scene::shadow::with_cast_shadows(render, &lights)?;
        Ok((scene, Some(shadow)))
    } else {
        Ok((render(&lights)?, None))
    }
}

/// Runs `synth`.
pub fn run(args: &SynthArgs) -> Result<()> {
    refuse_unused(args)?;
    if args.ps_leds.is_some() {
        return run_set(args);
    }
    if let Some(sigma) = args.noise
        && !(sigma.is_finite() && sigma >= 0.0)
    {
        anyhow::bail!("invalid parameter noise = {sigma}: must be finite and >= 0");
    }
    if let Some([cx, cy, r]) = args.inpaint_disc
        && !((0.0..=1.0).contains(&cx) && (0.0..=1.0).contains(&cy) && r > 0.0 && r <= 1.0)
    {
        anyhow::bail!(
            "invalid parameter inpaint-disc = {cx},{cy},{r}: centre in [0,1], radius in (0,1]"
        );
    }
    let (width, height) = args.size;
    sfs_core::memory::check(
        &format!("rendering {width}x{height} pixels"),
        sfs_core::memory::synth_estimate(args.size),
        "choose a smaller --size",
    )?;
    // The destination is locked and checked writable before any work.
    let mut stage = super::outputs::stage(&args.out)?;
    let (scene, shadow) = render_scene(args)?;
    let (w, h) = scene.image.size();
    // A scene the solver could not take is refused, not written: lights
    // that reach no object pixel (inside or behind the object, an LED
    // pointing away), or a scale outside the accepted range.
    let lit = scene
        .image
        .as_slice()
        .iter()
        .zip(scene.object_mask.as_slice())
        .filter(|(v, on)| **on && **v > 0.0)
        .count();
    if lit == 0 {
        anyhow::bail!(
            "the lights reach no pixel of the object (a light inside or beyond it, or an LED \
             pointing away): the image would be black; check --light, --light-dir and --light-mu"
        );
    }
    let (s_min, s_max) = sfs_core::params::INTENSITY_SCALE_RANGE;
    if !(s_min..=s_max).contains(&scene.intensity_scale) {
        anyhow::bail!(
            "the lights give an intensity scale of {:e} (outside [{s_min:e}, {s_max:e}], which \
             solve accepts): a light barely reaches the object (an LED with a high --light-mu \
             aimed away?); check --light, --light-dir and --light-mu",
            scene.intensity_scale
        );
    }
    io::write_png16(&stage.path("image16.png"), &scene.image)?;
    io::write_png8(&stage.path("image8.png"), &scene.image)?;
    if let Some(sigma) = args.noise {
        let noisy = scene::add_noise(&scene.image, sigma, args.seed);
        io::write_png8(&stage.path("noisy8.png"), &noisy)?;
    }
    if let Some([cx, cy, r]) = args.inpaint_disc {
        let confidence = scene::disc_confidence(w, h, cx, cy, r);
        io::write_png8(&stage.path("confidence.png"), &confidence)?;
    }
    io::write_mask_png(&stage.path("mask.png"), &scene.object_mask)?;
    if let Some(shadow) = &shadow {
        io::write_mask_png(&stage.path("shadow.png"), shadow)?;
    }
    io::write_npy_f64(&stage.path("depth_gt.npy"), &scene.depth_gt)?;
    let camera = CameraFile {
        name: Some(scene.name.clone()),
        intensity_scale: Some(scene.intensity_scale),
        intensity_scale_measured: true,
        material: (!scene.material.is_lambert()).then_some(scene.material),
        lights: scene
            .lights
            .iter()
            .map(|l| LightEntry::of_light(l, None, None))
            .collect(),
        ..CameraFile::new(scene.camera, w, h)
    };
    finish(stage, &camera, &args.out)?;
    eprintln!(
        "wrote {} ({w}x{h}, f = {:.1} px, s = {:.4}, {} shading) to {}",
        scene.name,
        scene.camera.focal_px,
        scene.intensity_scale,
        args.shading.name(),
        args.out.display()
    );
    Ok(())
}

/// Writes `camera` as the staged folder's scene.json and moves the staged
/// files into `out`.
fn finish(mut stage: crate::output::OutputStage, camera: &CameraFile, out: &Path) -> Result<()> {
    sfs_core::camera_file::write_camera(&stage.path("scene.json"), camera)?;
    stage
        .commit()
        .with_context(|| format!("cannot finish writing {}", out.display()))?;
    Ok(())
}

/// `synth --ps-leds N`: a photometric-stereo set with its truth.
fn run_set(args: &SynthArgs) -> Result<()> {
    let count = args.ps_leds.unwrap_or(2) as usize;
    if !args.lights.positions.is_empty() || !args.lights.indices.is_empty() {
        anyhow::bail!("--ps-leds places its own LEDs: leave out --light and --light-index");
    }
    if args.shading != Shading::Mesh {
        anyhow::bail!(
            "--shading {} renders through the one-photograph solver's model; a --ps-leds set is \
             shaded with its normals (leave out --shading)",
            args.shading.name()
        );
    }
    if args.shadows || args.inpaint_disc.is_some() {
        anyhow::bail!(
            "--ps-leds always traces cast shadows and writes no confidence: leave out --shadows \
             and --inpaint-disc"
        );
    }
    if let Some(sigma) = args.noise
        && !(sigma.is_finite() && sigma >= 0.0)
    {
        anyhow::bail!("invalid parameter noise = {sigma}: must be finite and >= 0");
    }
    if !["patches", "lines", "smooth", "uniform"].contains(&args.albedo_pattern.as_str()) {
        anyhow::bail!(
            "--albedo-pattern {}: expected patches, lines, smooth or uniform",
            args.albedo_pattern
        );
    }
    let (width, height) = args.size;
    sfs_core::memory::check(
        &format!("rendering {count} photographs of {width}x{height} pixels"),
        sfs_core::memory::synth_estimate(args.size).saturating_mul(count as u64 + 2),
        "choose a smaller --size or fewer --ps-leds",
    )?;
    let mut stage = super::outputs::stage(&args.out)?;
    // The object's centre: the Sombrero's rim depth, a mesh's distance.
    let target = if args.scene == "sombrero" {
        [0.0, 0.0, 2.0]
    } else {
        [0.0, 0.0, args.distance]
    };
    let leds = scene::photometric::standard_leds(count, target);
    let albedo = if args.albedo_pattern == "uniform" {
        Grid::filled(width, height, 1.0)
    } else {
        scene::photometric::albedo_pattern(width, height, &args.albedo_pattern)
    };
    let render = |lights: &[PointLight]| -> Result<Scene> {
        let mut one = args.clone_for_render();
        one.lights.positions = lights.iter().map(|l| l.position).collect();
        one.lights.directions = lights.iter().filter_map(|l| l.direction).collect();
        one.lights.mus = lights.iter().map(|l| l.mu).collect();
        Ok(render_scene(&one)?.0)
    };
    let set = scene::photometric::render_set(render, &leds, &albedo, true)?;
    let mut entries = Vec::new();
    for (k, (image, light)) in set.images.iter().zip(&set.lights).enumerate() {
        let name = format!("led{:02}.png", k + 1);
        match args.noise {
            Some(sigma) => {
                io::write_png16(&stage.path(&format!("clean_{name}")), image)?;
                let noisy = scene::add_noise(image, sigma, args.seed + k as u64);
                io::write_png8(&stage.path(&name), &noisy)?;
            }
            None => io::write_png16(&stage.path(&name), image)?,
        }
        entries.push(LightEntry::of_light(light, Some(k as u32 + 1), Some(name)));
    }
    io::write_mask_png(&stage.path("mask.png"), &set.object_mask)?;
    io::write_npy_f64(&stage.path("depth_gt.npy"), &set.depth_gt)?;
    io::write_npy_f32_vec3(&stage.path("normals_gt.npy"), &set.normals_gt)?;
    io::write_npy_f64(&stage.path("albedo_gt.npy"), &set.albedo_gt)?;
    let camera = CameraFile {
        name: Some(set.name.clone()),
        intensity_scale: Some(set.intensity_scale),
        intensity_scale_measured: true,
        lights: entries,
        ..CameraFile::new(set.camera, width, height)
    };
    finish(stage, &camera, &args.out)?;
    eprintln!(
        "wrote a set of {count} photographs of {} ({width}x{height}, f = {:.1} px, {} albedo) \
         to {}",
        set.name,
        set.camera.focal_px,
        args.albedo_pattern,
        args.out.display()
    );
    Ok(())
}

/// Refuses options this scene leaves without effect (a value away from its
/// default: `--rotation` or `--distance` with the analytic Sombrero, which
/// place a mesh; `--seed` without `--noise`, which it seeds).
fn refuse_unused(args: &SynthArgs) -> Result<()> {
    if args.scene == "sombrero" && args.rotation != [180.0, 0.0, 0.0] {
        anyhow::bail!(
            "--rotation turns a mesh; the Sombrero is analytic and has none (give an OBJ mesh)"
        );
    }
    if args.scene == "sombrero" && args.distance != 2.0 {
        anyhow::bail!(
            "--distance places a mesh; the Sombrero is analytic, at its own distance (give an OBJ mesh)"
        );
    }
    if args.noise.is_none() && args.seed != 1 {
        anyhow::bail!("--seed seeds the noise and no --noise was given");
    }
    Ok(())
}

/// The `--shading` named `text`.
fn parse_shading(text: &str) -> Result<Shading, String> {
    Shading::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = Shading::NAMES.iter().map(|(n, _)| *n).collect();
        format!("unknown shading {text:?}: expected {}", names.join(" or "))
    })
}

impl SynthArgs {
    /// A copy for rendering one light of a set.
    fn clone_for_render(&self) -> SynthArgs {
        SynthArgs {
            scene: self.scene.clone(),
            size: self.size,
            noise: None,
            seed: self.seed,
            inpaint_disc: None,
            rotation: self.rotation,
            distance: self.distance,
            shadows: false,
            lights: super::lights::LightArgs::default(),
            material: self.material.clone(),
            shading: self.shading,
            out: self.out.clone(),
            ps_leds: None,
            albedo_pattern: self.albedo_pattern.clone(),
        }
    }
}
