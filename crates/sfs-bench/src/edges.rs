//! `sfs-bench --part edges`: what the energy prefers at occlusion edges. For
//! each scene (Sombrero, Bunny, Dragon, Suzanne) at the robustness table's
//! sizes (64 and 256 pixels, Suzanne twice as wide; the Dragon also at
//! 1080x1920), clean and at noise sigma 20, it measures the default solve,
//! the same refinement started from the true depth and fast marching alone;
//! the data energy `sum (I - R)^2` per object pixel of the true depth
//! against the default answer (the solver's own upwind differences, the
//! image solved); where the truth's misfit lies (the share of its data
//! energy on pixels beside a true depth jump, its median residual relative
//! to the brightness); the same energy ratio with differences that do not
//! cross a jump and with each pixel's best one-sided pair (what the energy
//! would prefer with those differences); and the share of object pixels beside a true depth
//! jump against the share detected as occluding contours in the default
//! answer (`model_fit::occlusion_edges`), with that detection's precision
//! and recall. Quick: 32 and 64 pixels, no 1080x1920 Dragon. Writes
//! `edges.md` and `edges.json`.

use std::fmt::Write as _;

use anyhow::{Context, Result};
use serde::Serialize;

use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::model::{self, LevelGeometry, Reflectance};
use sfs_core::model_fit;
use sfs_core::params::{InitialDepth, SolverParams};
use sfs_core::scene::Scene;
use sfs_core::solver::{FastMarchingParams, Problem, solve, solve_fast_marching};

use super::markdown::{SceneReport, markdown_head, skipped_meshes, table};
use super::scenes::{noisy, problem, render_or_skip, timed_solve};
use super::shared::{BenchArgs, wanted_renders};

/// A depth jump between neighbours: steeper than this tangent (about 87
/// degrees) in the true depth, `|dz| / z * f / h`.
const JUMP_TANGENT: f64 = 20.0;

/// A one-sided difference steeper than this tangent (about 84 degrees),
/// `|dz| / z * f / h`, and four times the other side's, crosses a jump.
const CROSSING_TANGENT: f64 = 10.0;

/// The paper's noisy RSE (sigma 20) per scene (Table 1's text).
fn paper_noisy(scene: &str) -> Option<f64> {
    match scene {
        "sombrero" => Some(0.01542),
        "bunny" => Some(0.01359),
        "dragon" => Some(0.03391),
        "suzanne" => Some(0.00826),
        _ => None,
    }
}

/// One scene at one size and noise level.
#[derive(Clone, Debug, Serialize)]
pub struct EdgeRow {
    /// Scene name.
    pub scene: String,
    /// `WxH`.
    pub size: String,
    /// Noise sigma on the 0..255 scale.
    pub noise: f64,
    /// RSE at the defaults.
    pub default_rse: f64,
    /// RSE of the default refinement started from the true depth.
    pub truth_start_rse: f64,
    /// RSE of fast marching alone (the default's start).
    pub fast_marching_rse: f64,
    /// The paper's RSE on its own noisy render (sigma 20 rows only).
    pub paper_rse: Option<f64>,
    /// `sum (I - R)^2` per object pixel of the true depth (the image solved).
    pub truth_data_energy: f64,
    /// The same of the default answer.
    pub default_data_energy: f64,
    /// `truth_data_energy / default_data_energy` with differences that do
    /// not cross a jump: a neighbour is dropped where its one-sided slope
    /// is steeper than [`CROSSING_TANGENT`] and four times the other side's.
    pub non_crossing_ratio: f64,
    /// The same ratio with each pixel's best of its four one-sided
    /// difference pairs (the one closest to its brightness).
    pub best_pair_ratio: f64,
    /// Share of the truth's data energy on object pixels beside a true
    /// depth jump.
    pub truth_energy_share_at_jumps: f64,
    /// Median `|I - R|` of the true depth over object pixels, relative to the
    /// 99th percentile of the object's brightness (how well the render's
    /// depth and shading agree).
    pub truth_median_residual: f64,
    /// Share of object pixels beside a true depth jump.
    pub jump_share: f64,
    /// Share of object pixels detected as occluding contours in the default
    /// answer.
    pub detected_share: f64,
    /// Share of detected pixels within one pixel of a true jump.
    pub detected_precision: f64,
    /// Share of pixels beside a true jump within one pixel of a detected one.
    pub detected_recall: f64,
    /// Wall time of the default solve.
    pub seconds: f64,
}

/// The part's report.
pub type EdgesReport = SceneReport<EdgeRow>;

/// The object pixels of `depth` (finite) beside a neighbour more than
/// [`JUMP_TANGENT`] away in relative depth (both pixels of the pair).
fn jump_pixels(depth: &Grid<f64>, focal_px: f64) -> Grid<bool> {
    let (w, h) = depth.size();
    let jump = |a: f64, b: f64| {
        a.is_finite() && b.is_finite() && (a - b).abs() / a.min(b) * focal_px > JUMP_TANGENT
    };
    Grid::from_fn(w, h, |c, r| {
        let z = *depth.at(c, r);
        (c > 0 && jump(z, *depth.at(c - 1, r)))
            || (c + 1 < w && jump(z, *depth.at(c + 1, r)))
            || (r > 0 && jump(z, *depth.at(c, r - 1)))
            || (r + 1 < h && jump(z, *depth.at(c, r + 1)))
    })
}

/// Whether `mask` holds a pixel within one pixel (8-neighbourhood) of
/// `(c, r)`.
fn near(mask: &Grid<bool>, c: usize, r: usize) -> bool {
    let (w, h) = mask.size();
    (r.saturating_sub(1)..=(r + 1).min(h - 1))
        .any(|rr| (c.saturating_sub(1)..=(c + 1).min(w - 1)).any(|cc| *mask.at(cc, rr)))
}

/// `I - R` of `depth` on its finite pixels (NaN elsewhere), the solver's
/// upwind differences.
fn residual(problem: &Problem, depth: &Grid<f64>) -> Grid<f64> {
    let (w, h) = depth.size();
    let geometry = LevelGeometry::new(w, h, w, h, problem.camera);
    let domain = depth.map(|z| z.is_finite());
    let model = problem.model(sfs_core::material::Material::Lambert);
    let shown = model::reproject(&model, &geometry, &domain, depth, Cancel::NEVER).uncancelled();
    Grid::from_fn(w, h, |c, r| {
        if *domain.at(c, r) {
            problem.image.at(c, r) - shown.at(c, r)
        } else {
            f64::NAN
        }
    })
}

/// How a pixel's gradient is taken for [`data_energy`].
#[derive(Clone, Copy)]
enum Differences {
    /// Upwind, a neighbour across a jump dropped (the inner one-sided
    /// difference then, as beside the silhouette).
    NonCrossing,
    /// The best of the four one-sided pairs.
    BestPair,
}

/// `sum (I - R)^2` over the finite pixels of `depth` with the gradient taken
/// as `how` says.
fn data_energy(problem: &Problem, depth: &Grid<f64>, how: Differences) -> f64 {
    let (w, h) = depth.size();
    let geometry = LevelGeometry::new(w, h, w, h, problem.camera);
    let domain = depth.map(|z| z.is_finite());
    let model = problem.model(sfs_core::material::Material::Lambert);
    let f = problem.camera.focal_px;
    let mut total = 0.0;
    for r in 0..h {
        for c in 0..w {
            if !*domain.at(c, r) {
                continue;
            }
            let nb = model::neighbourhood(depth, &domain, c, r);
            let z = nb.centre;
            let ray = geometry.ray(c, r);
            let image = *problem.image.at(c, r);
            let slope = |n: Option<f64>| n.map(|v| (v - z).abs() / z * f);
            // One axis: drop a neighbour whose difference crosses a jump.
            let keep = |minus: Option<f64>, plus: Option<f64>| {
                let (sm, sp) = (slope(minus), slope(plus));
                let crosses = |a: Option<f64>, b: Option<f64>| match (a, b) {
                    (Some(a), Some(b)) => a > CROSSING_TANGENT && a > 4.0 * b,
                    _ => false,
                };
                (
                    minus.filter(|_| !crosses(sm, sp)),
                    plus.filter(|_| !crosses(sp, sm)),
                )
            };
            let residual = match how {
                Differences::NonCrossing => {
                    let (left, right) = keep(nb.left, nb.right);
                    let (up, down) = keep(nb.up, nb.down);
                    let (_, gx) = model::upwind(left, z, right, geometry.spacing.x);
                    let (_, gy) = model::upwind(up, z, down, geometry.spacing.y);
                    image - model.radiance(&ray, z, gx, gy)
                }
                Differences::BestPair => {
                    let one_sided = |minus: Option<f64>, plus: Option<f64>, spacing: f64| {
                        [
                            minus.map(|m| (z - m) / spacing),
                            plus.map(|p| (p - z) / spacing),
                        ]
                    };
                    let xs = one_sided(nb.left, nb.right, geometry.spacing.x);
                    let ys = one_sided(nb.up, nb.down, geometry.spacing.y);
                    let mut best = f64::INFINITY;
                    for gx in xs
                        .iter()
                        .flatten()
                        .copied()
                        .chain(xs.iter().all(Option::is_none).then_some(0.0))
                    {
                        for gy in ys
                            .iter()
                            .flatten()
                            .copied()
                            .chain(ys.iter().all(Option::is_none).then_some(0.0))
                        {
                            let d = image - model.radiance(&ray, z, gx, gy);
                            if d.abs() < best.abs() {
                                best = d;
                            }
                        }
                    }
                    best
                }
            };
            if residual.is_finite() {
                total += residual * residual;
            }
        }
    }
    total
}

/// One row.
fn row(name: &str, scene: &Scene, noise: f64) -> Result<EdgeRow> {
    let (w, h) = scene.image.size();
    eprintln!("  edges {name} {w}x{h} noise {noise}");
    let problem = problem(scene, noisy(&scene.image, noise));
    let defaults = SolverParams::default();
    let (answer, seconds) = timed_solve(&problem, &defaults, name)?;
    let truth_start = solve(
        &problem,
        &SolverParams {
            initial_depth: InitialDepth::Map(scene.depth_gt.clone()),
            ..defaults
        },
        &mut (),
    )
    .with_context(|| format!("truth start of {name} failed"))?;
    let fast = solve_fast_marching(&problem, &FastMarchingParams::default(), &mut ())
        .with_context(|| format!("fast marching on {name} failed"))?;

    let truth = scene
        .depth_gt
        .zip_map(&scene.object_mask, |z, on| if *on { *z } else { f64::NAN });
    let jumps = jump_pixels(&truth, scene.camera.focal_px);
    let truth_residual = residual(&problem, &truth);
    let answer_residual = residual(&problem, &answer.depth);
    let object: Vec<(usize, usize)> = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .filter(|&(c, r)| *scene.object_mask.at(c, r))
        .collect();
    let count = object.len().max(1) as f64;
    let energy = |res: &Grid<f64>| {
        object
            .iter()
            .map(|&(c, r)| res.at(c, r).powi(2))
            .filter(|v| v.is_finite())
            .sum::<f64>()
    };
    let truth_energy = energy(&truth_residual);
    // `+ 0.0`: an empty sum is -0.
    let at_jumps: f64 = object
        .iter()
        .filter(|&&(c, r)| *jumps.at(c, r))
        .map(|&(c, r)| truth_residual.at(c, r).powi(2))
        .filter(|v| v.is_finite())
        .sum::<f64>()
        + 0.0;
    let mut brightness: Vec<f64> = object
        .iter()
        .map(|&(c, r)| *problem.image.at(c, r))
        .collect();
    brightness.sort_by(f64::total_cmp);
    let bright = brightness
        .get(((brightness.len() as f64 * 0.99) as usize).min(brightness.len().saturating_sub(1)))
        .copied()
        .unwrap_or(1.0)
        .max(f64::MIN_POSITIVE);
    let mut misfit: Vec<f64> = object
        .iter()
        .map(|&(c, r)| truth_residual.at(c, r).abs())
        .filter(|v| v.is_finite())
        .collect();
    misfit.sort_by(f64::total_cmp);
    let median = misfit.get(misfit.len() / 2).copied().unwrap_or(f64::NAN) / bright;

    let ratio_of = |how: Differences| {
        data_energy(&problem, &truth, how) / data_energy(&problem, &answer.depth, how)
    };
    let non_crossing_ratio = ratio_of(Differences::NonCrossing);
    let best_pair_ratio = ratio_of(Differences::BestPair);
    let detected = model_fit::occlusion_edges(&problem.image, &answer.depth, scene.camera);
    let on = |mask: &Grid<bool>| object.iter().filter(|&&(c, r)| *mask.at(c, r)).count();
    let (n_jumps, n_detected) = (on(&jumps), on(&detected));
    let hits = object
        .iter()
        .filter(|&&(c, r)| *detected.at(c, r) && near(&jumps, c, r))
        .count();
    let found = object
        .iter()
        .filter(|&&(c, r)| *jumps.at(c, r) && near(&detected, c, r))
        .count();
    let ratio = |a: usize, b: usize| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    Ok(EdgeRow {
        scene: name.into(),
        size: format!("{w}x{h}"),
        noise,
        default_rse: metrics::rse(&answer.depth, &scene.depth_gt)?,
        truth_start_rse: metrics::rse(&truth_start.depth, &scene.depth_gt)?,
        fast_marching_rse: metrics::rse(&fast.depth, &scene.depth_gt)?,
        paper_rse: (noise > 0.0).then(|| paper_noisy(name)).flatten(),
        truth_data_energy: truth_energy / count,
        default_data_energy: energy(&answer_residual) / count,
        non_crossing_ratio,
        best_pair_ratio,
        truth_energy_share_at_jumps: if truth_energy > 0.0 {
            at_jumps / truth_energy
        } else {
            0.0
        },
        truth_median_residual: median,
        jump_share: n_jumps as f64 / count,
        detected_share: n_detected as f64 / count,
        detected_precision: ratio(hits, n_detected),
        detected_recall: ratio(found, n_jumps),
        seconds,
    })
}

/// Runs the part and writes `edges.md` and `edges.json` into `args.out`.
pub fn run(args: &BenchArgs) -> Result<EdgesReport> {
    let sides: &[usize] = if args.quick { &[32, 64] } else { &[64, 256] };
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for name in wanted_renders(args) {
        let aspect = if name == "suzanne" { 2 } else { 1 };
        let mut sizes: Vec<(usize, usize)> = sides.iter().map(|&s| (s * aspect, s)).collect();
        if name == "dragon" && !args.quick {
            sizes.push((1080, 1920));
        }
        for (w, h) in sizes {
            let Some(scene) = render_or_skip(name, &args.meshes, w, h, &mut skipped)? else {
                break;
            };
            for noise in [0.0, 20.0] {
                rows.push(row(name, &scene, noise)?);
            }
        }
    }
    SceneReport::write(&args.out, "edges", rows, skipped, markdown)
}

/// The report as markdown: a table.
fn markdown(report: &EdgesReport) -> String {
    let mut md = markdown_head("Occlusion edges: what the energy prefers", &report.command);
    let _ = writeln!(
        md,
        "Data energy: `sum (I - R)^2` per object pixel with the solver's upwind differences, \
         on the image solved. Jumps: neighbours more than {JUMP_TANGENT} apart in `|dz| / z * f` \
         (steeper than about 87 degrees) in the true depth. Non-crossing / best pair: the truth's \
         data energy over the answer's with differences that do not cross a jump (a neighbour \
         dropped where its one-sided slope is steeper than about 84 degrees and four times the \
         other side's) and with each pixel's best one-sided pair. Detected: occluding contours found \
         in the default answer (`model_fit::occlusion_edges`); precision and recall within one \
         pixel.\n"
    );
    table(
        &mut md,
        "| scene | size | noise | default RSE | truth start | fast marching | paper | data energy truth / default | non-crossing / best pair | truth's energy at jumps | truth's median residual | jump pixels | detected | precision / recall | seconds |",
        &report.rows,
        |r| {
            format!(
                "| {} | {} | {} | {:.4} | {:.4} | {:.4} | {} | {:.2e} / {:.2e} ({:.2}) | {:.2} / {:.2} | {:.0} % | {:.2} % | {:.2} % | {:.2} % | {} / {} | {:.2} |",
                r.scene,
                r.size,
                r.noise,
                r.default_rse,
                r.truth_start_rse,
                r.fast_marching_rse,
                r.paper_rse.map_or("-".to_string(), |p| format!("{p:.4}")),
                r.truth_data_energy,
                r.default_data_energy,
                r.truth_data_energy / r.default_data_energy,
                r.non_crossing_ratio,
                r.best_pair_ratio,
                100.0 * r.truth_energy_share_at_jumps,
                100.0 * r.truth_median_residual,
                100.0 * r.jump_share,
                100.0 * r.detected_share,
                percent(r.detected_precision),
                percent(r.detected_recall),
                r.seconds
            )
        },
    );
    skipped_meshes(&mut md, &report.skipped);
    md
}

/// A share as a whole percentage, `-` when undefined.
fn percent(share: f64) -> String {
    if share.is_finite() {
        format!("{:.0} %", 100.0 * share)
    } else {
        "-".into()
    }
}
