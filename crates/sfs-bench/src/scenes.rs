//! The rendered scenes the parts share: each scene by name (the Sombrero or
//! a mesh of `--meshes`), rendered or skipped, its problem, its noisy image
//! and the timed solve of it.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};

use sfs_core::grid::Grid;
use sfs_core::params::SolverParams;
use sfs_core::scene::{self, Scene, mesh, sombrero::sombrero};
use sfs_core::solver::{Problem, Solution, solve};

/// Seed of the noise added to a rendered image.
pub(super) const SEED: u64 = 1;

/// The scene `name` rendered at `width` x `height`.
pub(super) fn render(name: &str, meshes: &Path, width: usize, height: usize) -> Result<Scene> {
    let Some(file) = mesh_file(name)? else {
        return Ok(sombrero(width, height));
    };
    let path = meshes.join(file);
    mesh::load_obj(&path)
        .and_then(|m| mesh::render(&m, width, height, &mesh::Placement::default(), name))
        .with_context(|| format!("{name}: {}", path.display()))
}

/// [`render`], or `None` with the scene's name added to `skipped` (and
/// said) where a mesh scene cannot be rendered (its file is missing or
/// broken); the analytic Sombrero's failure is an error.
pub(super) fn render_or_skip(
    name: &str,
    meshes: &Path,
    width: usize,
    height: usize,
    skipped: &mut Vec<String>,
) -> Result<Option<Scene>> {
    or_skip(name, render(name, meshes, width, height), skipped)
}

/// `result` of scene `name`, or `None` with the name added to `skipped`
/// (and said) where it is an error of a mesh scene (its file is missing or
/// broken); an error of the analytic Sombrero stays an error.
pub(super) fn or_skip<T>(
    name: &str,
    result: Result<T>,
    skipped: &mut Vec<String>,
) -> Result<Option<T>> {
    match result {
        Ok(value) => Ok(Some(value)),
        Err(e) if name != "sombrero" => {
            eprintln!("  skipped {name}: {e:#}");
            skipped.push(name.to_string());
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// The mesh file of the bench's scene `name` in the meshes folder (`None`
/// for the analytic Sombrero).
pub(super) fn mesh_file(name: &str) -> Result<Option<&'static str>> {
    Ok(Some(match name {
        "sombrero" => return Ok(None),
        "bunny" => "stanford-bunny.obj",
        "dragon" => "dragon.obj",
        "suzanne" => "suzanne.obj",
        other => anyhow::bail!("no scene called {other}"),
    }))
}

/// The problem of `scene` solved on `image` (its light at the optical
/// centre, every pixel trusted).
pub(super) fn problem(scene: &Scene, image: Grid<f64>) -> Problem {
    Problem {
        image,
        camera: scene.camera,
        intensity_scale: scene.intensity_scale,
        object_mask: Some(scene.object_mask.clone()),
        confidence: None,
        lights: Vec::new(),
    }
}

/// `image` with noise of `sigma` on the 0..255 scale (seed [`SEED`]);
/// `sigma` 0: `image` itself.
pub(super) fn noisy(image: &Grid<f64>, sigma: f64) -> Grid<f64> {
    if sigma > 0.0 {
        scene::add_noise(image, sigma, SEED)
    } else {
        image.clone()
    }
}

/// Solves `problem` with `params`: the solution and the solve's wall time in
/// seconds; `what` names the solve in an error.
pub(super) fn timed_solve(
    problem: &Problem,
    params: &SolverParams,
    what: &str,
) -> Result<(Solution, f64)> {
    let start = Instant::now();
    let solution =
        solve(problem, params, &mut ()).with_context(|| format!("solve of {what} failed"))?;
    Ok((solution, start.elapsed().as_secs_f64()))
}
