//! Inpainting on the paper's terms (issue 51, part 3): a depth-map render
//! of a Table 1 scene with holes of confidence 0, solved at the defaults.
//!
//! `cargo run -p sfs-bench --release --example inpaint_probe -- SCENE NOISE`
//! prints, per hole, the share of the object hidden, the RSE of the
//! harmonic fill of the TRUE depth across it (what a smooth continuation
//! of the truth costs: the paper's inpainting row is 0.00793 against
//! 0.00696 without the hole, so its region cost at most about 0.004), and
//! the RSE at the defaults with `--albedo 1` and `--albedo auto`.

use anyhow::{Context, Result};

mod common;

use sfs_core::grid::Grid;
use sfs_core::metrics::rse;
use sfs_core::params::{AlbedoChoice, LinearSolver, SolverParams};
use sfs_core::scene::{self, shading::Shading};
use sfs_core::solver::solve;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |k: usize, default: &'static str| args.get(k).map_or(default, String::as_str);
    let name = arg(0, "suzanne");
    let noise: f64 = arg(1, "0").parse().context("NOISE: a number")?;
    // SCHEDULE `sor`: the schedule without holes (SOR, kappa 5) across holes too.
    let schedule = arg(2, "defaults");
    let (w, h) = common::paper_size(name);
    let truth = Shading::DepthMap.apply(common::render(name, w, h, &common::meshes_folder())?);
    let image = if noise > 0.0 {
        scene::add_noise(&truth.image, noise, 1)
    } else {
        truth.image.clone()
    };
    let problem =
        |confidence: Option<Grid<f64>>| common::problem(&truth, image.clone(), confidence);
    let solved = |confidence: Option<Grid<f64>>, albedo: AlbedoChoice| -> Result<f64> {
        let mut params = SolverParams {
            albedo,
            ..SolverParams::default()
        };
        if schedule == "sor" {
            params.linear_solver = LinearSolver::Sor;
            params.kappa_holes = params.kappa;
        }
        let solution = solve(&problem(confidence), &params, &mut ())?;
        Ok(rse(&solution.depth, &truth.depth_gt)?)
    };
    println!(
        "{name} depth-map {w}x{h} noise {noise}: no hole RSE {:.5} (albedo 1) {:.5} (auto)",
        solved(None, AlbedoChoice::One)?,
        solved(None, AlbedoChoice::Auto)?
    );
    let mut holes: Vec<(String, Grid<f64>)> = Vec::new();
    for (x, y, r) in [
        (0.5, 0.45, 0.14),
        (0.5, 0.45, 0.28),
        (0.45, 0.3, 0.14),
        (0.55, 0.7, 0.14),
        (0.35, 0.55, 0.14),
        (0.3, 0.45, 0.1),
    ] {
        holes.push((
            format!("disc {x},{y},{r}"),
            scene::disc_confidence(w, h, x, y, r),
        ));
    }
    for seed in 1..=6 {
        holes.push((
            format!("blobs 20 % seed {seed}"),
            scene::blob_confidence(&truth.object_mask, 0.2, seed),
        ));
    }
    let object = &truth.object_mask;
    let object_pixels = object.as_slice().iter().filter(|&&o| o).count();
    for (what, confidence) in holes {
        let hidden = Grid::from_fn(w, h, |c, r| *object.at(c, r) && *confidence.at(c, r) == 0.0);
        let share = hidden.as_slice().iter().filter(|&&o| o).count() as f64 / object_pixels as f64;
        let known = hidden.map(|&x| !x);
        let fill = scene::harmonic_fill(&truth.depth_gt, &known);
        println!(
            "{what}: hidden {:.1} %, fill of the truth RSE {:.5}, defaults RSE {:.5} (albedo 1) {:.5} (auto)",
            100.0 * share,
            rse(&fill, &truth.depth_gt)?,
            solved(Some(confidence.clone()), AlbedoChoice::One)?,
            solved(Some(confidence), AlbedoChoice::Auto)?,
        );
    }
    Ok(())
}
