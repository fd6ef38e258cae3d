//! The start's denoising decision over a randomized corpus (a section of
//! `sfs-bench --part corpus`): whether the fast-marching start marches a
//! TV-denoised image (`--start-denoise auto`). Each render (the Sombrero,
//! the meshes and the face's shape; the renderer's own shading or the depth
//! map's; lit from the optical centre or by a flash beside the lens, with
//! and without cast shadows; noise 0-10 of 255; the corpus's sizes) is
//! solved with the start denoised and not, and the decision is wrong where
//! the other start ends more than [`WORSE`] better in RSE. The rule before
//! this one (the noise over all trusted pixels alone) is scored beside it
//! from the noise the solve read.

use std::fmt::Write as _;

use anyhow::Result;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use sfs_core::light::PointLight;
use sfs_core::metrics::rse;
use sfs_core::params::{FAST_MARCHING_DENOISE_ABOVE, SolverParams, StartDenoise};
use sfs_core::scene::{self, Scene, shading::Shading};
use sfs_core::solver::calibrate::median_depth;
use sfs_core::solver::{Problem, solve};

use super::shared::BenchArgs;

/// Renders scene `name` at `side` px under the lights given (none: the
/// light at the optical centre).
pub type Render<'a> = dyn Fn(&str, usize, &[PointLight]) -> Result<Scene> + 'a;

/// Renders drawn (and with `--quick`).
const CASES: usize = 120;
const QUICK_CASES: usize = 30;
/// A decision is wrong where the other start's RSE is lower by more than
/// this share.
pub const WORSE: f64 = 0.05;

/// One render: the noise the solve read, both decisions, both outcomes.
#[derive(Clone, Debug, Serialize)]
pub struct DenoiseRow {
    /// Case number (its seed, offset from the albedo corpus's).
    pub case: usize,
    /// Scene name.
    pub scene: String,
    /// `mesh` (the renderer's normals) or `depth-map`.
    pub shading: String,
    /// Image size.
    pub size: String,
    /// `centred` or `flash`.
    pub light: String,
    /// Cast shadows rendered.
    pub shadows: bool,
    /// Noise sigma on the 8-bit scale.
    pub noise: f64,
    /// The noise the solve read over all trusted pixels and over the
    /// brightest quarter (NaN where not read), relative to the brightness
    /// scale.
    pub relative_noise: f64,
    pub relative_facing_noise: f64,
    /// What `auto` decided, and what the rule before it (all pixels alone)
    /// would have.
    pub denoised: bool,
    pub denoised_before: bool,
    /// RSE with the start denoised and not.
    pub rse_on: f64,
    pub rse_off: f64,
}

impl DenoiseRow {
    /// `decision` was wrong: the other start ended more than [`WORSE`]
    /// better.
    fn wrong(&self, decision: bool) -> bool {
        let (chosen, other) = match decision {
            true => (self.rse_on, self.rse_off),
            false => (self.rse_off, self.rse_on),
        };
        other < chosen * (1.0 - WORSE)
    }
}

/// Draws and solves the corpus (renders that fail are listed in `skipped`).
pub fn run(
    args: &BenchArgs,
    render: &Render<'_>,
    scenes: &[&str],
    skipped: &mut Vec<String>,
) -> Vec<DenoiseRow> {
    let cases = if args.quick { QUICK_CASES } else { CASES };
    let draw = args.seed.unwrap_or(0);
    let mut rows = Vec::new();
    for case in 0..cases {
        // Its own stream: the albedo corpus's draws are unchanged.
        let seed = draw
            .wrapping_mul(1_000_003)
            .wrapping_add(case as u64)
            .wrapping_add(0x5eed_0000);
        let mut rng = StdRng::seed_from_u64(seed);
        let name = scenes[rng.random_range(0..scenes.len())];
        let side = args.corpus_sides[rng.random_range(0..args.corpus_sides.len())];
        match one_case(render, case, name, side, seed, &mut rng) {
            Ok(row) => {
                eprintln!(
                    "  denoise {case} {} {} {} {} shadows {} noise {}: read {:.4} / {:.4}, \
                     denoised {} (before {}), RSE on {:.4} off {:.4}",
                    row.scene,
                    row.shading,
                    row.size,
                    row.light,
                    row.shadows,
                    row.noise,
                    row.relative_noise,
                    row.relative_facing_noise,
                    row.denoised,
                    row.denoised_before,
                    row.rse_on,
                    row.rse_off
                );
                rows.push(row);
            }
            Err(e) => {
                let why = format!("denoise case {case} ({name}): {e:#}");
                eprintln!("  skipped {why}");
                skipped.push(why);
            }
        }
    }
    rows
}

fn one_case(
    render: &Render<'_>,
    case: usize,
    name: &str,
    side: usize,
    seed: u64,
    rng: &mut StdRng,
) -> Result<DenoiseRow> {
    let probe = render(name, side, &[])?;
    let distance = median_depth(&probe.depth_gt);
    let flash = rng.random_bool(0.5);
    let lights = match flash {
        true => {
            // Beside the lens: 3-20 % of the distance off the axis.
            let off = distance * rng.random_range(0.03..0.2);
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            vec![PointLight {
                position: [off * angle.cos(), off * angle.sin(), 0.0],
                ..PointLight::CENTRED
            }]
        }
        false => Vec::new(),
    };
    // The face's shape is a depth map already (shaded through the model).
    let shading = match name {
        "face" => Shading::DepthMap,
        _ if rng.random_bool(0.5) => Shading::DepthMap,
        _ => Shading::Mesh,
    };
    let shadows = flash && rng.random_bool(0.5);
    let noise = [0.0, 0.0, 1.0, 2.0, 3.0, 5.0, 10.0][rng.random_range(0..7)];
    let shaded = |l: &[PointLight]| -> Result<Scene> {
        let scene = render(name, side, l)?;
        Ok(match (name, shading) {
            ("face", _) => scene,
            (_, kind) => kind.apply(scene),
        })
    };
    let rendered = match shadows {
        true => scene::shadow::with_cast_shadows(shaded, &lights)?.0,
        false => shaded(&lights)?,
    };
    let image = match noise > 0.0 {
        true => scene::add_noise(&rendered.image, noise, seed),
        false => rendered.image.clone(),
    };
    let problem = Problem {
        image,
        camera: rendered.camera,
        intensity_scale: rendered.intensity_scale,
        object_mask: Some(rendered.object_mask.clone()),
        confidence: None,
        lights: rendered.lights.clone(),
    };
    let solved = |start_denoise| {
        let params = SolverParams {
            start_denoise,
            ..SolverParams::default()
        };
        solve(&problem, &params, &mut ())
    };
    let auto = solved(StartDenoise::Auto)?;
    let denoised = auto
        .start_denoised
        .ok_or_else(|| anyhow::anyhow!("no fast-marching start was marched"))?;
    let other = solved(if denoised {
        StartDenoise::Off
    } else {
        StartDenoise::On
    })?;
    let (on, off) = match denoised {
        true => (&auto, &other),
        false => (&other, &auto),
    };
    let noise_read = auto
        .noise
        .ok_or_else(|| anyhow::anyhow!("the solve read no noise"))?;
    let (w, h) = rendered.image.size();
    Ok(DenoiseRow {
        case,
        scene: name.into(),
        shading: shading.name().into(),
        size: format!("{w}x{h}"),
        light: if flash { "flash" } else { "centred" }.into(),
        shadows,
        noise,
        relative_noise: noise_read.relative,
        relative_facing_noise: noise_read.relative_facing,
        denoised,
        denoised_before: noise_read.relative > FAST_MARCHING_DENOISE_ABOVE,
        rse_on: rse(&on.depth, &rendered.depth_gt)?,
        rse_off: rse(&off.depth, &rendered.depth_gt)?,
    })
}

/// The section of corpus.md: the rates by shading and noise, then every case.
pub fn markdown(rows: &[DenoiseRow], md: &mut String) {
    let _ = writeln!(
        md,
        "\n## The start's denoising (`--start-denoise auto`)\n\n{} renders (scenes, shading \
         `mesh` or `depth-map`, a centred light or a flash beside the lens, cast shadows, noise \
         0-10 of 255), each solved with the fast-marching start denoised and not. A decision is \
         wrong where the other start ends more than {:.0} % lower in RSE. \"before\": the rule \
         that read the noise over all trusted pixels alone.\n",
        rows.len(),
        100.0 * WORSE
    );
    let _ = writeln!(
        md,
        "| renders | count | wrong now | wrong before | denoised now | denoised before | mean \
         RSE now | mean RSE before |\n| --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    type Filter = fn(&DenoiseRow) -> bool;
    let groups: [(&str, Filter); 5] = [
        ("all", |_| true),
        ("mesh shading, clean", |r| {
            r.shading == "mesh" && r.noise == 0.0
        }),
        ("mesh shading, noisy", |r| {
            r.shading == "mesh" && r.noise > 0.0
        }),
        ("depth-map shading, clean", |r| {
            r.shading == "depth-map" && r.noise == 0.0
        }),
        ("depth-map shading, noisy", |r| {
            r.shading == "depth-map" && r.noise > 0.0
        }),
    ];
    let chosen = |r: &DenoiseRow, d: bool| if d { r.rse_on } else { r.rse_off };
    for (label, filter) in groups {
        let group: Vec<&DenoiseRow> = rows.iter().filter(|r| filter(r)).collect();
        let n = group.len().max(1) as f64;
        let count = |f: &dyn Fn(&DenoiseRow) -> bool| group.iter().filter(|r| f(r)).count();
        let _ = writeln!(
            md,
            "| {label} | {} | {} | {} | {} | {} | {:.4} | {:.4} |",
            group.len(),
            count(&|r| r.wrong(r.denoised)),
            count(&|r| r.wrong(r.denoised_before)),
            count(&|r| r.denoised),
            count(&|r| r.denoised_before),
            group.iter().map(|r| chosen(r, r.denoised)).sum::<f64>() / n,
            group
                .iter()
                .map(|r| chosen(r, r.denoised_before))
                .sum::<f64>()
                / n,
        );
    }
    let _ = writeln!(
        md,
        "\n| case | scene | shading | size | light | shadows | noise | read (all) | read \
         (brightest quarter) | denoised | before | RSE denoised | RSE not |\n| --- | --- | --- | \
         --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {} | {} | {:.4} | {:.4} |",
            r.case,
            r.scene,
            r.shading,
            r.size,
            r.light,
            if r.shadows { "yes" } else { "no" },
            r.noise,
            r.relative_noise,
            r.relative_facing_noise,
            if r.denoised { "yes" } else { "no" },
            if r.denoised_before { "yes" } else { "no" },
            r.rse_on,
            r.rse_off
        );
    }
}
