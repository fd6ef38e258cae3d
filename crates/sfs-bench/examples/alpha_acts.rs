//! Does the smoothness weight act at the defaults? (issue 51, part 2)
//!
//! `cargo run -p sfs-bench --release --example alpha_acts -- SCENE SHADING
//! NOISE START [FACTORS] [SETTINGS]`: SCENE `sombrero`, `bunny`, `dragon` or
//! `suzanne` (the meshes read from `../shared/meshes`, or `$SFS_MESHES`) at
//! the paper's size; SHADING `mesh` or `depth-map`; NOISE sigma on the
//! 0..255 scale; START `fm` (the defaults' fast-marching start), `img` (the
//! paper's constant start through the whole pyramid) or `truth`; FACTORS
//! (comma separated, default 1,10,100,1000,10000) multiply the automatic
//! alpha; SETTINGS (comma separated `name=value`: `kappa`, `kappa_max`,
//! `sor`, `inner`, `inner_tol`, `dz`, `object=1`) change the defaults.
//! Prints fast marching's RSE alone, then per alpha the RSE, the depth's
//! roughness (RMS of `S = sqrt(z_xx^2 + 2 z_xy^2 + z_yy^2)`, pixel units,
//! over object pixels whose 3x3 neighbourhood is on the object), how far
//! the depth moved from the automatic alpha's (RSE between them), the
//! iterations run and the energy's two parts.

use anyhow::{Context, Result, bail};

mod common;

use sfs_core::grid::Grid;
use sfs_core::metrics::rse;
use sfs_core::model::{Spacing, smoothness_squared};
use sfs_core::params::{Alpha, DomainMode, InitialDepth, SolverParams};
use sfs_core::scene::{self, shading::Shading};
use sfs_core::solver::{solve, solve_fast_marching};

/// RMS of the second-derivative magnitude over the object's inner pixels.
fn roughness(depth: &Grid<f64>, mask: &Grid<bool>) -> f64 {
    let (w, h) = depth.size();
    let on = Grid::from_fn(w, h, |c, r| *mask.at(c, r) && depth.at(c, r).is_finite());
    let (mut sum, mut count) = (0.0, 0usize);
    for r in 1..h.saturating_sub(1) {
        for c in 1..w.saturating_sub(1) {
            if (r - 1..=r + 1).all(|rr| (c - 1..=c + 1).all(|cc| *on.at(cc, rr))) {
                sum += smoothness_squared(depth, &on, c, r, Spacing { x: 1.0, y: 1.0 });
                count += 1;
            }
        }
    }
    (sum / count.max(1) as f64).sqrt()
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |k: usize, default: &'static str| args.get(k).map_or(default, String::as_str);
    let name = arg(0, "bunny");
    let shading = Shading::from_name(arg(1, "depth-map")).context("SHADING: mesh or depth-map")?;
    let noise: f64 = arg(2, "0").parse().context("NOISE: a number")?;
    let start = arg(3, "fm");
    let factors = arg(4, "1,10,100,1000,10000")
        .split(',')
        .map(|v| v.parse::<f64>().with_context(|| format!("FACTORS: {v}")))
        .collect::<Result<Vec<_>>>()?;
    let (w, h) = common::paper_size(name);
    let truth = shading.apply(common::render(name, w, h, &common::meshes_folder())?);
    let image = if noise > 0.0 {
        scene::add_noise(&truth.image, noise, 1)
    } else {
        truth.image.clone()
    };
    let problem = common::problem(&truth, image, None);
    let initial_depth = match start {
        "fm" => InitialDepth::FastMarching,
        "img" => InitialDepth::FromImage,
        "truth" => InitialDepth::Map(truth.depth_gt.clone()),
        other => bail!("START: fm, img or truth, not {other}"),
    };
    let mut base = SolverParams {
        initial_depth,
        ..SolverParams::default()
    };
    for setting in arg(5, "").split(',').filter(|s| !s.is_empty()) {
        let (key, value) = setting.split_once('=').context("SETTINGS: name=value")?;
        let number = || {
            value
                .parse::<usize>()
                .with_context(|| format!("{key}={value}"))
        };
        let real = || {
            value
                .parse::<f64>()
                .with_context(|| format!("{key}={value}"))
        };
        match key {
            "kappa" => {
                base.kappa = number()?;
                base.kappa_max = base.kappa_max.max(base.kappa);
            }
            "kappa_max" => base.kappa_max = number()?,
            "sor" => base.sor_iterations = number()?,
            "inner" => base.inner_iterations = number()?,
            "inner_tol" => base.inner_tolerance = real()?,
            "dz" => base.dz_limit = real()?,
            "object" => base.domain = DomainMode::Object,
            other => bail!("SETTINGS: no setting {other}"),
        }
    }
    let alone = solve_fast_marching(&problem, &Default::default(), &mut ())?;
    println!(
        "{name} {} noise {noise}: fast marching alone RSE {:.5}; truth roughness {:.3e}",
        shading.name(),
        rse(&alone.depth, &truth.depth_gt)?,
        roughness(&truth.depth_gt, &truth.object_mask)
    );
    let auto = solve(&problem, &base, &mut ())?;
    for factor in factors {
        let params = SolverParams {
            alpha: Alpha::Value(auto.alpha * factor),
            ..base.clone()
        };
        let solved = solve(&problem, &params, &mut ())?;
        println!(
            "start {start} alpha {:.3e} (auto x {factor:e}): RSE {:.5} roughness {:.3e} moved {:.2e} \
             outer {} inner {} sweeps {} energy data {:.3e} smoothness {:.3e}",
            auto.alpha * factor,
            rse(&solved.depth, &truth.depth_gt)?,
            roughness(&solved.depth, &truth.object_mask),
            rse(&solved.depth, &auto.depth)?,
            solved.iterations,
            solved.phases.inner_iterations,
            solved.phases.linear_iterations,
            solved.final_energy.data,
            solved.final_energy.smoothness,
        );
    }
    Ok(())
}
