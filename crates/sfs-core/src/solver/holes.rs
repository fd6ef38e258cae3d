//! What the image cannot tell, filled in depth: the thin-plate fill of a
//! depth map across its untrusted pixels, the minimiser of the model's own
//! second-order smoothness `sum z_xx^2 + 2 z_xy^2 + z_yy^2` (the same central
//! stencils, natural boundary conditions at the object's edge) with the
//! trusted pixels fixed. The smoothness term is what decides the depth where
//! the data term has no weight, so a start filled this way is already what
//! the refinement converges to there, instead of a surface marched on an
//! image diffused into the hole. Solved coarse to fine (block means of the
//! trusted depth, the hole filled on the coarsest level, then conjugate
//! gradients on each finer one from the level below), so wide holes fill
//! in a few hundred steps at any size.
//! Depends on the grid and the cancellation only.

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::linalg::cg;

/// Pixels below this confidence count as a hole: their data term weighs less
/// than the smoothness that continues their neighbours.
pub const HOLE_CONFIDENCE: f64 = 0.5;

/// Fills `depth` at the pixels of `domain` that are not `known` with the
/// thin-plate continuation of the known ones; returns how many were filled.
/// Pixels off `domain` are neither read nor written. A component of unknown
/// pixels that touches no known pixel keeps its values. Polls `cancel`
/// every few steps.
pub fn thin_plate_fill(
    depth: &mut Grid<f64>,
    domain: &Grid<bool>,
    known: &Grid<bool>,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    let unknown = unknown_pixels(domain, known);
    if unknown.is_empty() {
        return Ok(0);
    }
    // A useful start for the coarsest level: the mean of the known depth.
    let (sum, count) = depth
        .as_slice()
        .iter()
        .zip(domain.as_slice().iter().zip(known.as_slice()))
        .filter(|(z, (d, k))| **d && **k && z.is_finite())
        .fold((0.0, 0usize), |(s, n), (z, _)| (s + z, n + 1));
    if count == 0 {
        return Ok(0);
    }
    let mean = sum / count as f64;
    for &q in &unknown {
        if !depth.as_slice()[q].is_finite() {
            depth.as_mut_slice()[q] = mean;
        }
    }
    fill_level(depth, domain, known, &unknown, mean.abs(), cancel)?;
    Ok(unknown.len())
}

/// A connected region of trusted pixels smaller than this share of all of
/// them is not trusted to carry a marched depth of its own: a sliver cut
/// off by a hole has no point that faces the light, and fast marching puts
/// it where a facing patch would be as dark (far behind the object).
pub const MIN_REGION_SHARE: f64 = 0.02;

/// Clears from `trusted` every 4-connected region holding less than
/// `min_share` of its pixels; returns how many pixels were cleared.
pub fn drop_small_regions(trusted: &mut Grid<bool>, min_share: f64) -> usize {
    let (w, h) = trusted.size();
    let total = trusted.as_slice().iter().filter(|&&t| t).count();
    let min_pixels = (min_share * total as f64).ceil() as usize;
    let mut label = vec![u32::MAX; w * h];
    let mut stack = Vec::new();
    let mut region = Vec::new();
    let mut cleared = 0;
    let mut next = 0u32;
    for seed in 0..w * h {
        if !trusted.as_slice()[seed] || label[seed] != u32::MAX {
            continue;
        }
        region.clear();
        label[seed] = next;
        stack.push(seed);
        while let Some(q) = stack.pop() {
            region.push(q);
            let (c, r) = (q % w, q / w);
            let mut visit = |n: usize| {
                if trusted.as_slice()[n] && label[n] == u32::MAX {
                    label[n] = next;
                    stack.push(n);
                }
            };
            if c > 0 {
                visit(q - 1);
            }
            if c + 1 < w {
                visit(q + 1);
            }
            if r > 0 {
                visit(q - w);
            }
            if r + 1 < h {
                visit(q + w);
            }
        }
        next = next.wrapping_add(1);
        if region.len() < min_pixels {
            for &q in &region {
                trusted.as_mut_slice()[q] = false;
            }
            cleared += region.len();
        }
    }
    cleared
}

/// Indices of the pixels of `domain` not `known`, in raster order.
fn unknown_pixels(domain: &Grid<bool>, known: &Grid<bool>) -> Vec<usize> {
    domain
        .as_slice()
        .iter()
        .zip(known.as_slice())
        .enumerate()
        .filter(|(_, (d, k))| **d && !**k)
        .map(|(q, _)| q)
        .collect()
}

/// Below this side (or with this few unknown pixels) a level is solved
/// directly, without a coarser level.
const COARSEST_SIDE: usize = 24;
/// Conjugate-gradient steps on the coarsest level, and on every finer one.
const COARSEST_STEPS: usize = 2000;
const FINER_STEPS: usize = 500;
/// The steps stop once the energy's gradient at every pixel is below this
/// share of the depth.
const RELATIVE_TOLERANCE: f64 = 1e-10;

fn fill_level(
    depth: &mut Grid<f64>,
    domain: &Grid<bool>,
    known: &Grid<bool>,
    unknown: &[usize],
    scale: f64,
    cancel: Cancel<'_>,
) -> Result<(), Cancelled> {
    let (w, h) = depth.size();
    let steps = if w.min(h) <= COARSEST_SIDE || unknown.len() <= COARSEST_SIDE * COARSEST_SIDE {
        COARSEST_STEPS
    } else {
        let (coarse_depth, coarse_domain, coarse_known) = restrict(depth, domain, known);
        let coarse_unknown = unknown_pixels(&coarse_domain, &coarse_known);
        let mut coarse_depth = coarse_depth;
        if !coarse_unknown.is_empty() {
            fill_level(
                &mut coarse_depth,
                &coarse_domain,
                &coarse_known,
                &coarse_unknown,
                scale,
                cancel,
            )?;
        }
        // Each unknown pixel starts from its coarse cell's filled depth.
        let cw = coarse_depth.size().0;
        for &q in unknown {
            let (c, r) = (q % w, q / w);
            let z = coarse_depth.as_slice()[(r / 2) * cw + c / 2];
            if z.is_finite() {
                depth.as_mut_slice()[q] = z;
            }
        }
        FINER_STEPS
    };
    conjugate_gradients(depth, domain, unknown, steps, scale, cancel)
}

/// The next coarser level: 2x2 blocks; a block is on the domain where any of
/// its pixels is, known where all its domain pixels are known (its depth
/// their mean), so a coarse hole covers the fine one.
fn restrict(
    depth: &Grid<f64>,
    domain: &Grid<bool>,
    known: &Grid<bool>,
) -> (Grid<f64>, Grid<bool>, Grid<bool>) {
    let (w, h) = depth.size();
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut coarse_depth = Grid::filled(cw, ch, f64::NAN);
    let mut coarse_domain = Grid::filled(cw, ch, false);
    let mut coarse_known = Grid::filled(cw, ch, false);
    for r in 0..ch {
        for c in 0..cw {
            let (mut sum, mut on, mut all_known) = (0.0, 0usize, true);
            for (fc, fr) in [
                (2 * c, 2 * r),
                (2 * c + 1, 2 * r),
                (2 * c, 2 * r + 1),
                (2 * c + 1, 2 * r + 1),
            ] {
                if fc < w && fr < h && *domain.at(fc, fr) {
                    on += 1;
                    all_known &= *known.at(fc, fr);
                    sum += *depth.at(fc, fr);
                }
            }
            if on > 0 {
                *coarse_domain.at_mut(c, r) = true;
                *coarse_known.at_mut(c, r) = all_known;
                *coarse_depth.at_mut(c, r) = sum / on as f64;
            }
        }
    }
    (coarse_depth, coarse_domain, coarse_known)
}

/// The thin-plate energy's gradient at one unknown pixel `q` (half of it:
/// `sum_t w_t a_t r_t` over the terms `t` containing the pixel, `a_t` its
/// coefficient, `r_t` the term's value) and the matching diagonal entry
/// `sum_t w_t a_t^2`. Terms are the central differences of
/// `z_xx^2 + 2 z_xy^2 + z_yy^2`, each only where its stencil lies in
/// `domain` (`z_xy`'s stencil spans 2h both ways: weight 2 / 16).
fn gradient_at(depth: &Grid<f64>, domain: &Grid<bool>, q: usize) -> (f64, f64) {
    let (w, h) = depth.size();
    let inside = |c: isize, r: isize| {
        c >= 0
            && r >= 0
            && (c as usize) < w
            && (r as usize) < h
            && domain.as_slice()[r as usize * w + c as usize]
    };
    let z = |c: isize, r: isize| depth.as_slice()[r as usize * w + c as usize];
    let (c, r) = ((q % w) as isize, (q / w) as isize);
    let (mut gradient, mut diagonal) = (0.0, 0.0);
    // z_xx and z_yy centred on this pixel and on its neighbours.
    for (dc, dr) in [(1isize, 0isize), (0, 1)] {
        for (offset, a) in [(-1isize, 1.0), (0, -2.0), (1, 1.0)] {
            let (cc, cr) = (c + offset * dc, r + offset * dr);
            if inside(cc, cr) && inside(cc - dc, cr - dr) && inside(cc + dc, cr + dr) {
                let term = z(cc - dc, cr - dr) - 2.0 * z(cc, cr) + z(cc + dc, cr + dr);
                gradient += a * term;
                diagonal += a * a;
            }
        }
    }
    // z_xy centred on the four diagonal neighbours; this pixel is one corner
    // of each stencil (+ on the diagonal, - on the anti-diagonal).
    const XY_WEIGHT: f64 = 2.0 / 16.0;
    for (dc, dr) in [(-1isize, -1isize), (1, -1), (-1, 1), (1, 1)] {
        let (cc, cr) = (c + dc, r + dr);
        let corners = [
            (cc + 1, cr + 1),
            (cc + 1, cr - 1),
            (cc - 1, cr + 1),
            (cc - 1, cr - 1),
        ];
        if corners.iter().all(|&(a, b)| inside(a, b)) {
            let term =
                z(cc + 1, cr + 1) - z(cc + 1, cr - 1) - z(cc - 1, cr + 1) + z(cc - 1, cr - 1);
            let a = if dc == dr { 1.0 } else { -1.0 };
            gradient += XY_WEIGHT * a * term;
            diagonal += XY_WEIGHT;
        }
    }
    (gradient, diagonal)
}

/// Minimises the thin-plate energy over the `unknown` pixels of `depth` by
/// conjugate gradients preconditioned with the diagonal, from the current
/// values, for at most `iterations` steps or until the residual is below
/// [`RELATIVE_TOLERANCE`] of `scale` (polls `cancel` every few steps). The
/// routine is [`crate::linalg::cg`]'s, on the unknown pixels gathered into
/// one vector (dot products summed serially, in order).
fn conjugate_gradients(
    depth: &mut Grid<f64>,
    domain: &Grid<bool>,
    unknown: &[usize],
    iterations: usize,
    scale: f64,
    cancel: Cancel<'_>,
) -> Result<(), Cancelled> {
    let n = unknown.len();
    let (w, h) = depth.size();
    let mut diagonal = vec![0.0; n];
    let mut residual = vec![0.0; n];
    for (k, &q) in unknown.iter().enumerate() {
        let (gradient, d) = gradient_at(depth, domain, q);
        residual[k] = -gradient;
        diagonal[k] = d;
    }
    let precondition = |r: &[f64], z: &mut [f64]| {
        for ((z, r), d) in z.iter_mut().zip(r).zip(&diagonal) {
            *z = if *d > 0.0 { r / d } else { 0.0 };
        }
    };
    // The direction on the full grid (zero on known pixels and off the
    // domain), so that the operator is the gradient's own stencil.
    let mut spread = Grid::filled(w, h, 0.0);
    let apply = |direction: &[f64], product: &mut [f64]| {
        for (k, &q) in unknown.iter().enumerate() {
            spread.as_mut_slice()[q] = direction[k];
        }
        // The operator, in parallel: a pass over the hole per step.
        product
            .par_iter_mut()
            .zip(unknown.par_iter())
            .with_min_len(4096)
            .for_each(|(p, &q)| *p = gradient_at(&spread, domain, q).0);
    };
    let settings = cg::Settings {
        max_iterations: iterations,
        summation: cg::Summation::Serial,
        stop: cg::Stop::BeforeStep {
            norm: cg::Norm::Max,
            tolerance: RELATIVE_TOLERANCE * scale.max(f64::MIN_POSITIVE),
        },
        cancel_poll: cg::CancelPoll {
            every: 16,
            before_test: true,
        },
        rz_guard: cg::RzGuard::BeforeStep,
        beta: cg::Beta::FletcherReeves,
    };
    let mut x: Vec<f64> = unknown.iter().map(|&q| depth.as_slice()[q]).collect();
    let result = cg::solve(&mut x, residual, apply, precondition, &settings, cancel);
    // The steps taken stand even when cancelled, as they did in place.
    for (&q, z) in unknown.iter().zip(&x) {
        depth.as_mut_slice()[q] = *z;
    }
    result.map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc_hole(n: usize, radius: f64) -> (Grid<bool>, Grid<bool>) {
        let domain = Grid::filled(n, n, true);
        let centre = (n as f64 - 1.0) / 2.0;
        let known = Grid::from_fn(n, n, |c, r| {
            (c as f64 - centre).hypot(r as f64 - centre) > radius
        });
        (domain, known)
    }

    #[test]
    fn a_plane_and_a_paraboloid_are_filled_exactly() {
        // The thin-plate energy's minimiser reproduces any surface whose
        // fourth derivatives vanish (a plane, a paraboloid) from its rim.
        for surface in [
            (|x: f64, y: f64| 100.0 + 0.3 * x - 0.2 * y) as fn(f64, f64) -> f64,
            |x: f64, y: f64| 50.0 + 0.01 * (x * x + y * y) - 0.005 * x * y,
        ] {
            let n = 96;
            let truth = Grid::from_fn(n, n, |c, r| surface(c as f64, r as f64));
            let (domain, known) = disc_hole(n, 30.0);
            let mut depth = Grid::from_fn(n, n, |c, r| {
                if *known.at(c, r) {
                    *truth.at(c, r)
                } else {
                    f64::NAN
                }
            });
            let filled =
                thin_plate_fill(&mut depth, &domain, &known, Cancel::NEVER).expect("not cancelled");
            assert!(filled > 2000);
            let worst = depth.max_abs_difference(&truth);
            // Exact to 1e-5 of the depth (the steps stop short of exact).
            assert!(worst < 1e-5 * 50.0, "worst error {worst}");
        }
    }

    #[test]
    fn small_regions_are_dropped_and_large_ones_kept() {
        // A 10x10 block, a 2x3 sliver and a single pixel.
        let mut trusted = Grid::from_fn(20, 20, |c, r| {
            (c < 10 && r < 10)
                || ((15..17).contains(&c) && (12..15).contains(&r))
                || (c == 19 && r == 19)
        });
        let cleared = drop_small_regions(&mut trusted, 0.1);
        assert_eq!(cleared, 7);
        assert!(*trusted.at(0, 0) && *trusted.at(9, 9));
        assert!(!*trusted.at(15, 12) && !*trusted.at(19, 19));
    }

    #[test]
    fn nothing_to_fill_changes_nothing() {
        let n = 16;
        let mut depth = Grid::from_fn(n, n, |c, r| (c * r) as f64);
        let before = depth.clone();
        let domain = Grid::filled(n, n, true);
        let filled =
            thin_plate_fill(&mut depth, &domain, &domain, Cancel::NEVER).expect("not cancelled");
        assert_eq!(filled, 0);
        assert_eq!(depth, before);
    }
}
