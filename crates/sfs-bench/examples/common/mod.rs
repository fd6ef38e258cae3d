//! What the measuring examples share: the Table 1 scenes rendered at any
//! size, and the problem a rendered scene poses.

use anyhow::{Context, Result, bail};

use sfs_core::grid::Grid;
use sfs_core::scene::{Scene, mesh, sombrero::sombrero};
use sfs_core::solver::Problem;

/// The folder of the meshes: `$SFS_MESHES`, else `../shared/meshes`.
pub fn meshes_folder() -> String {
    std::env::var("SFS_MESHES").unwrap_or_else(|_| "../shared/meshes".into())
}

/// The paper's size of a Table 1 scene: Suzanne 512x256, the others
/// 256x256.
pub fn paper_size(name: &str) -> (usize, usize) {
    if name == "suzanne" {
        (512, 256)
    } else {
        (256, 256)
    }
}

/// `sombrero`, `bunny`, `dragon` or `suzanne` rendered at `w` x `h` (the
/// meshes from `meshes`, default placement), shaded from the mesh.
pub fn render(name: &str, w: usize, h: usize, meshes: &str) -> Result<Scene> {
    if name == "sombrero" {
        return Ok(sombrero(w, h));
    }
    let file = match name {
        "bunny" => "stanford-bunny.obj",
        "dragon" => "dragon.obj",
        "suzanne" => "suzanne.obj",
        other => bail!("SCENE: no scene {other}"),
    };
    let path = std::path::Path::new(meshes).join(file);
    let loaded = mesh::load_obj(&path).with_context(|| format!("{}", path.display()))?;
    Ok(mesh::render(
        &loaded,
        w,
        h,
        &mesh::Placement::default(),
        name,
    )?)
}

/// The problem `truth` poses with `image` (the render, or a noisy copy) and
/// `confidence`: its camera, intensity scale and object mask, the light at
/// the optical centre.
pub fn problem(truth: &Scene, image: Grid<f64>, confidence: Option<Grid<f64>>) -> Problem {
    Problem {
        image,
        camera: truth.camera,
        intensity_scale: truth.intensity_scale,
        object_mask: Some(truth.object_mask.clone()),
        confidence,
        lights: Vec::new(),
    }
}
