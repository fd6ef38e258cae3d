//! The schedule for holes, scored as a decision over randomized renders
//! (issue 51, part 3).
//!
//! `cargo run -p sfs-bench --release --example holes_schedule -- [CASES] [SEED]`
//!
//! Where the image has holes (object pixels of confidence 0), the defaults
//! refine the start with the schedule for holes (`--linear-solver auto`:
//! multigrid, `--kappa-holes` 10 iterations) instead of the schedule
//! without holes (SOR sweeps, `--kappa` 5). This draws CASES renders (default
//! 100): the Sombrero, the Bunny, the Dragon or Suzanne, shaded from the mesh
//! or through the depth map, 128-256 px, light at the optical centre, noise
//! 0-10 of 255, with one hole (a disc, seeded blobs or a band) of confidence
//! 0, and solves each at the defaults both ways. It prints one line per case
//! (RSE of each schedule, and of the harmonic fill of the true depth across
//! the hole: what a smooth continuation of the truth costs) and the counts:
//! how often each schedule is better by more than 5 %, and the geometric
//! means. The meshes are read from `../shared/meshes` or `$SFS_MESHES`.

use std::collections::HashMap;

use anyhow::Result;

mod common;
use rand::{Rng, SeedableRng};

use sfs_core::grid::Grid;
use sfs_core::metrics::rse;
use sfs_core::params::{LinearSolver, SolverParams};
use sfs_core::scene::{self, Scene, shading::Shading};
use sfs_core::solver::solve;

/// A relative RSE difference below this is a tie.
const TIE: f64 = 0.05;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let cases: usize = args.first().map_or(Ok(100), |v| v.parse())?;
    let seed: u64 = args.get(1).map_or(Ok(0), |v| v.parse())?;
    let meshes = common::meshes_folder();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut rendered: HashMap<(String, usize, bool), Scene> = HashMap::new();
    let (mut holes_better, mut sor_better, mut ties) = (0, 0, 0);
    let (mut log_holes, mut log_sor) = (0.0, 0.0);
    let mut by_group: HashMap<String, (usize, usize, usize)> = HashMap::new();
    for case in 0..cases {
        let name = ["sombrero", "bunny", "dragon", "suzanne"][rng.random_range(0..4)];
        let depth_map = rng.random_bool(0.5);
        let side = [128, 192, 256][rng.random_range(0..3)];
        // The paper's aspect: Suzanne 2:1, the others square.
        let (paper_w, paper_h) = common::paper_size(name);
        let (w, h) = (side, side * paper_h / paper_w);
        let noise = [0.0, 0.0, 2.0, 5.0, 10.0][rng.random_range(0..5)];
        let key = (name.to_string(), side, depth_map);
        if !rendered.contains_key(&key) {
            let scene = common::render(name, w, h, &meshes)?;
            let scene = if depth_map {
                Shading::DepthMap.apply(scene)
            } else {
                scene
            };
            rendered.insert(key.clone(), scene);
        }
        let truth = &rendered[&key];
        let object = &truth.object_mask;
        let (hole, confidence) = match rng.random_range(0..3) {
            0 => {
                // A disc centred on an object pixel.
                let on: Vec<(usize, usize)> = (0..h)
                    .flat_map(|r| (0..w).map(move |c| (c, r)))
                    .filter(|&(c, r)| *object.at(c, r))
                    .collect();
                let (c, r) = on[rng.random_range(0..on.len())];
                let radius = rng.random_range(0.06..0.2);
                (
                    format!("disc r {radius:.2}"),
                    scene::disc_confidence(
                        w,
                        h,
                        (c as f64 + 0.5) / w as f64,
                        (r as f64 + 0.5) / h as f64,
                        radius,
                    ),
                )
            }
            1 => {
                let share = rng.random_range(0.1..0.3);
                (
                    format!("blobs {:.0} %", 100.0 * share),
                    scene::blob_confidence(object, share, rng.random()),
                )
            }
            _ => {
                let height = rng.random_range(0.05..0.12);
                (
                    format!("band {:.2}", height),
                    scene::band_confidence(w, h, rng.random_range(0.25..0.75), height),
                )
            }
        };
        let image = if noise > 0.0 {
            scene::add_noise(&truth.image, noise, rng.random())
        } else {
            truth.image.clone()
        };
        let problem = common::problem(truth, image, Some(confidence.clone()));
        let defaults = SolverParams::default();
        let without = SolverParams {
            linear_solver: LinearSolver::Sor,
            kappa_holes: defaults.kappa,
            ..defaults.clone()
        };
        let with_holes = rse(&solve(&problem, &defaults, &mut ())?.depth, &truth.depth_gt)?;
        let with_sor = rse(&solve(&problem, &without, &mut ())?.depth, &truth.depth_gt)?;
        let hidden = Grid::from_fn(w, h, |c, r| *object.at(c, r) && *confidence.at(c, r) == 0.0);
        let known = hidden.map(|&x| !x);
        let fill = rse(
            &scene::harmonic_fill(&truth.depth_gt, &known),
            &truth.depth_gt,
        )?;
        let group = format!(
            "{} {}",
            if depth_map { "depth-map" } else { "mesh" },
            if noise > 0.0 { "noisy" } else { "clean" }
        );
        let entry = by_group.entry(group).or_default();
        let verdict = if with_holes < (1.0 - TIE) * with_sor {
            holes_better += 1;
            entry.0 += 1;
            "holes schedule"
        } else if with_sor < (1.0 - TIE) * with_holes {
            sor_better += 1;
            entry.1 += 1;
            "schedule without holes"
        } else {
            ties += 1;
            entry.2 += 1;
            "tie"
        };
        log_holes += with_holes.ln();
        log_sor += with_sor.ln();
        println!(
            "{case:3} {name} {} {w}x{h} noise {noise} {hole}: holes schedule {with_holes:.5}, \
             without {with_sor:.5}, fill of the truth {fill:.5}: {verdict}",
            if depth_map { "depth-map" } else { "mesh" },
        );
    }
    println!(
        "better by > {:.0} %: holes schedule {holes_better}, schedule without holes {sor_better}, \
         ties {ties} of {cases}; geometric mean RSE {:.5} vs {:.5}",
        100.0 * TIE,
        (log_holes / cases as f64).exp(),
        (log_sor / cases as f64).exp()
    );
    let mut groups: Vec<_> = by_group.into_iter().collect();
    groups.sort();
    for (group, (a, b, t)) in groups {
        println!("  {group}: holes schedule {a}, without {b}, ties {t}");
    }
    Ok(())
}
