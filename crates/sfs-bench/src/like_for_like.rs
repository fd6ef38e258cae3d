//! The paper's Table 1 like for like (`--part table1`, and a section of the
//! paper part's report): every Table 1 scene at the paper's size, rendered
//! both ways (METHOD.md section 12: `mesh`, shaded with the renderer's own
//! normals, and `depth-map`, the true depth through the solver's model),
//! clean and with Gaussian noise sigma 20 on the 0..255 scale, solved at the
//! defaults (no alpha given), beside the paper's RSE.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use serde::Serialize;

use sfs_core::params::SolverParams;
use sfs_core::scene::shading::Shading;

use super::markdown::{SceneReport, markdown_head, skipped_meshes};
use super::paper_table::paper_rse;
use super::scenes::{noisy, problem, render_or_skip, timed_solve};
use super::shared::{BenchArgs, NOISE_SIGMA, wanted_renders};

/// One scene, shading and noise level at the defaults.
#[derive(Clone, Debug, Serialize)]
pub struct LikeRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// `mesh` or `depth-map`.
    pub shading: String,
    /// Noise sigma on the 0..255 scale (0: clean).
    pub noise: f64,
    /// RSE at the defaults.
    pub rse: f64,
    /// RIE against the clean image.
    pub rie: f64,
    /// The alpha the defaults chose (relative units).
    pub chosen_alpha: f64,
    /// Whether the fast-marching start marched a denoised image.
    pub start_denoised: Option<bool>,
    /// The paper's RSE for the scene at this noise (Table 1; NaN: none).
    pub paper_rse: f64,
    /// Wall time of the solve.
    pub seconds: f64,
}

/// The Table 1 scenes and their sizes (Suzanne twice as wide as high, as
/// in the paper); quick: a quarter of the size per side.
fn sizes(quick: bool) -> [(&'static str, (usize, usize)); 4] {
    let d = if quick { 4 } else { 1 };
    [
        ("sombrero", (256 / d, 256 / d)),
        ("bunny", (256 / d, 256 / d)),
        ("dragon", (256 / d, 256 / d)),
        ("suzanne", (512 / d, 256 / d)),
    ]
}

/// Solves every scene of `wanted` in both shadings, clean and noisy, at the
/// defaults; mesh scenes whose file is missing go to `skipped`.
pub fn run(
    wanted: &[&str],
    meshes: &Path,
    quick: bool,
    skipped: &mut Vec<String>,
) -> Result<Vec<LikeRow>> {
    let mut rows = Vec::new();
    for (name, (w, h)) in sizes(quick) {
        if !wanted.contains(&name) {
            continue;
        }
        let Some(mesh_shaded) = render_or_skip(name, meshes, w, h, skipped)? else {
            continue;
        };
        for shading in [Shading::Mesh, Shading::DepthMap] {
            let scene = shading.apply(mesh_shaded.clone());
            for noise in [0.0, NOISE_SIGMA] {
                eprintln!(
                    "  table 1 like for like: {name} {w}x{h} {} noise {noise}",
                    shading.name()
                );
                let what = format!("{name} ({} shading, noise {noise})", shading.name());
                let problem = problem(&scene, noisy(&scene.image, noise));
                let (solution, seconds) = timed_solve(&problem, &SolverParams::default(), &what)?;
                let errors = scene.centred_errors(&solution.depth)?;
                rows.push(LikeRow {
                    scene: name.into(),
                    size: format!("{w}x{h}"),
                    shading: shading.name().into(),
                    noise,
                    rse: errors.rse,
                    rie: errors.rie,
                    chosen_alpha: solution.alpha,
                    start_denoised: solution.start_denoised,
                    paper_rse: paper_rse(name, noise > 0.0).unwrap_or(f64::NAN),
                    seconds,
                });
            }
        }
    }
    Ok(rows)
}

/// `--part table1`: [`run`] on the scenes `--scenes` asks for, written as
/// `table1.md` and `table1.json` into `--out`.
pub fn run_part(args: &BenchArgs) -> Result<()> {
    let names: Vec<&str> = wanted_renders(args).collect();
    let mut skipped = Vec::new();
    let rows = run(&names, &args.meshes, args.quick, &mut skipped)?;
    SceneReport::write(&args.out, "table1", rows, skipped, |report| {
        let mut md = markdown_head("The paper's Table 1 like for like", &report.command);
        md.push_str(&markdown(&report.rows));
        skipped_meshes(&mut md, &report.skipped);
        md
    })?;
    Ok(())
}

/// The RSE of `shading` on `scene` at `noise` among `rows` (NaN: not run).
fn rse_of(rows: &[LikeRow], scene: &str, shading: Shading, noise: f64) -> f64 {
    rows.iter()
        .find(|r| r.scene == scene && r.shading == shading.name() && r.noise == noise)
        .map_or(f64::NAN, |r| r.rse)
}

/// A number to five decimals; a dash for NaN.
fn fmt(v: f64) -> String {
    if v.is_nan() {
        "–".into()
    } else {
        format!("{v:.5}")
    }
}

/// The report's section: one line a scene and noise level, both shadings
/// beside the paper's RSE (empty when the part was not run).
pub fn markdown(rows: &[LikeRow]) -> String {
    let mut md = String::new();
    if rows.is_empty() {
        return md;
    }
    let _ = writeln!(
        md,
        "\n## Table 1 like for like: mesh and depth-map renders at the defaults\n"
    );
    let _ = writeln!(
        md,
        "Each scene rendered at the paper's size and shaded two ways (METHOD.md section 12): \
         `mesh` (the renderer's own normals: the mesh's interpolated normals, the Sombrero's \
         exact gradient) and `depth-map` (the true depth through the solver's model with its \
         upwind derivatives, object neighbours only: the true depth explains the image \
         exactly, the convention under which the paper's figures are reproduced). Solved at \
         the defaults (alpha auto, relative units, fast-marching start); noise Gaussian sigma \
         {NOISE_SIGMA} of 255, seed {}, quantised to 8 bits. \"at or below\": depth-map RSE \
         at or below the paper's. \"start denoised\": whether the fast-marching start \
         marched a TV-denoised image (`--start-denoise auto`: the image reads noisy over \
         all its pixels and over the brightest quarter).\n",
        super::scenes::SEED
    );
    super::markdown::table_head(
        &mut md,
        "| scene | noise | mesh RSE | depth-map RSE | paper RSE | depth-map / paper | at or below | alpha chosen (mesh, depth-map) | start denoised (mesh, depth-map) |",
    );
    let mut seen: Vec<(&str, f64)> = Vec::new();
    for row in rows {
        let key = (row.scene.as_str(), row.noise);
        if seen.contains(&key) {
            continue;
        }
        seen.push(key);
        let mesh = rse_of(rows, &row.scene, Shading::Mesh, row.noise);
        let depth_map = rse_of(rows, &row.scene, Shading::DepthMap, row.noise);
        let of = |shading: Shading| {
            rows.iter().find(|r| {
                r.scene == row.scene && r.noise == row.noise && r.shading == shading.name()
            })
        };
        let alpha = |shading: Shading| {
            of(shading).map_or("–".into(), |r| format!("{:.2e}", r.chosen_alpha))
        };
        let denoised = |shading: Shading| match of(shading).and_then(|r| r.start_denoised) {
            Some(true) => "yes",
            Some(false) => "no",
            None => "–",
        };
        let _ = writeln!(
            md,
            "| {} {} | {} | {} | {} | {} | {:.2} | {} | {}, {} | {}, {} |",
            row.scene,
            row.size,
            row.noise,
            fmt(mesh),
            fmt(depth_map),
            fmt(row.paper_rse),
            depth_map / row.paper_rse,
            if depth_map <= row.paper_rse {
                "yes"
            } else {
                "no"
            },
            alpha(Shading::Mesh),
            alpha(Shading::DepthMap),
            denoised(Shading::Mesh),
            denoised(Shading::DepthMap),
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scene: &str, shading: Shading, noise: f64, rse: f64) -> LikeRow {
        LikeRow {
            scene: scene.into(),
            size: "64x64".into(),
            shading: shading.name().into(),
            noise,
            rse,
            rie: rse / 2.0,
            chosen_alpha: 1e-7,
            start_denoised: Some(noise > 0.0),
            paper_rse: paper_rse(scene, noise > 0.0).unwrap_or(f64::NAN),
            seconds: 1.0,
        }
    }

    #[test]
    fn the_table_sets_both_shadings_beside_the_papers_rse() {
        let rows = vec![
            row("sombrero", Shading::Mesh, 0.0, 0.02),
            row("sombrero", Shading::DepthMap, 0.0, 0.005),
            row("sombrero", Shading::Mesh, NOISE_SIGMA, 0.03),
            row("sombrero", Shading::DepthMap, NOISE_SIGMA, 0.02),
        ];
        let md = markdown(&rows);
        for line in [
            "| sombrero 64x64 | 0 | 0.02000 | 0.00500 | 0.00768 | 0.65 | yes | 1.00e-7, 1.00e-7 | no, no |",
            "| sombrero 64x64 | 20 | 0.03000 | 0.02000 | 0.01542 | 1.30 | no | 1.00e-7, 1.00e-7 | yes, yes |",
        ] {
            assert!(md.contains(line), "no {line:?} in\n{md}");
        }
        assert_eq!(
            md.matches("| sombrero").count(),
            2,
            "one line a noise level"
        );
        assert!(markdown(&[]).is_empty());
    }
}
