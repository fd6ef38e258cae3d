//! The figures of report.md, from what the paper part's solves gave: RSE
//! over time per scene and Figs. 2-4 (the panels, their titles and shading);
//! `figures` draws them.

use anyhow::Result;

use super::figures::{self, Figure, LogLogPlot, Panel, Series, Shade};
use sfs_core::grid::Grid;
use sfs_core::scene::Scene;

/// Grey values of an image, 0 black to 1 white.
const IMAGE: Shade = Shade::Grey([0.0, 1.0]);

/// RSE over time of `scene`'s clean image: linearised blue, explicit red.
pub(super) fn rse_time(scene: &str, lin: &[(f64, f64)], exp: &[(f64, f64)]) -> Result<Figure> {
    let all = || lin.iter().chain(exp);
    LogLogPlot {
        title: &format!("RSE over time: {scene}, clean image"),
        x_name: "seconds",
        y_name: "RSE",
        x_range: figures::decades(all().map(|p| p.0)),
        y_range: figures::decades(all().map(|p| p.1)),
        series: &[
            Series {
                colour: [31, 90, 200],
                label: "linearised",
                points: lin,
            },
            Series {
                colour: [210, 40, 40],
                label: "explicit",
                points: exp,
            },
        ],
    }
    .draw()
}

/// Fig. 2: the input `image`, then its reprojection for each `(alpha,
/// reprojection)`.
pub(super) fn fig2(image: &Grid<f64>, reprojections: &[(f64, Grid<f64>)]) -> Result<Figure> {
    let titles: Vec<String> = reprojections
        .iter()
        .map(|(alpha, _)| format!("α = {}", figures::tick_label(*alpha)))
        .collect();
    let mut row = vec![Panel::new(image, IMAGE, "input")];
    row.extend(
        reprojections
            .iter()
            .zip(&titles)
            .map(|((_, reprojection), title)| Panel::new(reprojection, IMAGE, title)),
    );
    figures::panel_grid(&[row], 1)
}

/// Fig. 3: the input `image` with the region where `confidence` is 0 removed
/// (drawn light grey), the reprojection of the inpainted solve (`masked`)
/// and of the solve without the region (`full`).
pub(super) fn fig3(
    image: &Grid<f64>,
    confidence: &Grid<f64>,
    masked: &Grid<f64>,
    full: &Grid<f64>,
) -> Result<Figure> {
    let degraded = Grid::from_fn(image.width(), image.height(), |c, r| {
        if *confidence.at(c, r) == 0.0 {
            f64::NAN
        } else {
            *image.at(c, r)
        }
    });
    figures::panel_grid(
        &[vec![
            Panel::new(&degraded, IMAGE, "input, region removed"),
            Panel::new(masked, IMAGE, "inpainted"),
            Panel::new(full, IMAGE, "without the region"),
        ]],
        1,
    )
}

/// Fig. 4: reprojection and depth of the high-resolution scene: ground truth,
/// linearised and its difference, fast marching and its difference. `lin`
/// and `fmm` are each method's `[depth, reprojection]`.
pub(super) fn fig4(scene: &Scene, lin: [&Grid<f64>; 2], fmm: [&Grid<f64>; 2]) -> Result<Figure> {
    let diff = |a: &Grid<f64>, b: &Grid<f64>| {
        Grid::from_fn(a.width(), a.height(), |c, r| {
            (a.at(c, r) - b.at(c, r)).abs()
        })
    };
    let gt_depth = &scene.depth_gt;
    let depth_range = figures::range_of([gt_depth]);
    let (dl, df) = (diff(lin[0], gt_depth), diff(fmm[0], gt_depth));
    let (il, ifm) = (diff(lin[1], &scene.image), diff(fmm[1], &scene.image));
    let depth_err = [
        0.0,
        0.05 * (depth_range[1] - depth_range[0]).max(1e-9) * 4.0,
    ];
    let image_err = [0.0, 0.1];
    let step = (scene.image.width() / 270).max(1);
    figures::panel_grid(
        &[
            vec![
                Panel::new(&scene.image, IMAGE, "image (truth)"),
                Panel::new(lin[1], IMAGE, "linearised"),
                Panel::new(&il, Shade::Colour(image_err), "|difference| 0-0.1"),
                Panel::new(fmm[1], IMAGE, "fast marching"),
                Panel::new(&ifm, Shade::Colour(image_err), "|difference| 0-0.1"),
            ],
            vec![
                Panel::new(gt_depth, Shade::Colour(depth_range), "depth (truth)"),
                Panel::new(lin[0], Shade::Colour(depth_range), "linearised"),
                Panel::new(&dl, Shade::Colour(depth_err), "|difference| 0-20%"),
                Panel::new(fmm[0], Shade::Colour(depth_range), "fast marching"),
                Panel::new(&df, Shade::Colour(depth_err), "|difference| 0-20%"),
            ],
        ],
        step,
    )
}
