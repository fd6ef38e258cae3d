//! Albedo from one photograph (Retinex with an L0 edge prior): the
//! reflectance of a matte surface is taken as piecewise constant with
//! sparse, sharp changes, the shading as varying smoothly. Between two
//! 4-neighbouring trusted object pixels, a step of the log brightness larger
//! than the edge step `tau` (and than five times its noise) is an albedo
//! edge; any smaller step is shading. The log albedo is the least-squares
//! integral of the edges (a screened Poisson equation over the object,
//! conjugate gradients preconditioned by a multigrid V-cycle), normalised
//! so that the object's 90th percentile
//! is 1 (the brightest common material carries the intensity scale, as
//! `albedo 1` does) and clamped to `[ALBEDO_FLOOR, 1]`.
//!
//! Minimising `(g - a)^2 + tau^2 [a != 0]` per difference gives exactly
//! this rule (`a = g` where `|g| > tau`), so `tau` is the weight of the L0
//! prior on the log albedo's gradient. An occluding contour is a brightness
//! step too; whether the estimate explains a photograph better than albedo
//! 1 is decided with the shape (`solver::albedo_fit`), not here.
//! With [`EdgeRule::Chains`], only the steps that their chain confirms
//! (`crate::albedo_chain`) are edges and the others are cut out of the
//! integration (their link kept at a weight of [`CUT_WEIGHT`]: neither
//! albedo nor shading, only the level of a region no edge fixes).
//! Given an albedo found on a smaller copy (where an edge blurred over
//! several pixels is a step), [`estimate`] adds the edges left in the
//! image once it is divided out. Pure functions over `grid`, polling a `Cancel` between
//! iterations.

use std::borrow::Borrow;

use rayon::prelude::*;

use crate::albedo_chain::{EdgePair, confirmed_by_chain};
use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::linalg::cg;
use crate::linalg::multigrid::{self, Coarsen, Hierarchy, Level as _, Sweeps};

/// The default edge step `tau`: the smallest change of log brightness
/// between neighbours taken as an albedo edge (0.2: a ratio of 1.22).
pub const DEFAULT_EDGE_LOG_STEP: f64 = 0.2;
/// Elements per partial sum of the integration's dot products.
const DOT_CHUNK: usize = 8192;
/// The lowest albedo an estimate holds (relative to the common material).
pub const ALBEDO_FLOOR: f64 = 0.05;
/// The object's albedo percentile that is set to 1.
const NORMALISE_PERCENTILE: f64 = 0.9;
/// A neighbouring difference of the same sign and at least this share of
/// an edge's peak belongs to the edge (a blurred edge).
const EDGE_SHOULDER: f64 = 0.3;
/// An edge must also exceed this many standard deviations of its own noise.
const NOISE_SIGMAS: f64 = 5.0;
/// The screening weight of the Poisson equation (per pixel, against unit
/// weights per difference): it fixes the constant of each region that no
/// edge joins to another, and is too small to bend a region.
const SCREENING: f64 = 1e-6;
/// The weight of a cut link (a step its chain does not confirm), against 1
/// for the others: weak, so that a region whose every link is cut keeps
/// its surroundings' level (removed, such a region took the screening's
/// level, log albedo 0, once the integration converged), and too weak to
/// pull a region that an edge fixes. Measured on the bench's renders: at
/// 1e-2 no row moves by more than 0.0022 of RSE; at 1e-4 the beside Bunny
/// with patches goes from 0.042 to 0.086, as with the link removed.
const CUT_WEIGHT: f64 = 1e-3;

/// Which steps of log brightness become albedo edges (named in the
/// report's `albedo_fit`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeRule {
    /// Every step above the edge step and its noise; every other
    /// difference is shading.
    Steps,
    /// Only the steps their chain confirms (`crate::albedo_chain`: the
    /// same ratio along the edge, as between two materials); a step the
    /// chain does not confirm (an occluding contour, a shadow's edge) is
    /// cut out of the integration, neither albedo nor shading.
    Chains,
}

/// The prior on the log albedo's gradient: the edge step `tau` (the L0
/// weight) and which steps become edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgePrior {
    /// The smallest step of log brightness taken as an edge.
    pub log_step: f64,
    /// Every such step, or only those their chain confirms.
    pub rule: EdgeRule,
}

/// An albedo estimated from one image.
#[derive(Clone, Debug, PartialEq)]
pub struct AlbedoEstimate {
    /// Relative albedo per pixel in `[ALBEDO_FLOOR, 1]` (1 off the object).
    pub albedo: Grid<f64>,
    /// Differences between object pixels taken as albedo edges.
    pub edge_pairs: usize,
    /// Differences left out of the integration: steps that their chain
    /// does not confirm (`crate::albedo_chain`), neither albedo nor shading.
    pub cut_pairs: usize,
    /// Share of the object's pixels beside an albedo edge.
    pub edge_share: f64,
    /// Share of the variance of the object's log brightness that the log
    /// albedo explains (0: none; 1: the image is all albedo).
    pub explained_share: f64,
    /// Conjugate-gradient iterations of the integration.
    pub iterations: usize,
}

/// Estimates the albedo of `image` (linear, >= 0) over `object` pixels,
/// with edges only between pixels of confidence at least 0.5 (`trusted`),
/// at edge step `edge_log_step` and the image's noise `noise_sigma` (its
/// standard deviation, image units).
///
/// With `known`, an albedo (any scale, positive) estimated on a smaller
/// copy of `image` and brought to its size, the edges are those of `image`
/// divided by it (the steps the copy blurred or could not see, as thin
/// lines), integrated and added to it before the normalisation; the noise
/// threshold is still `image`'s own and the counts are those edges'.
///
/// # Errors
/// `Cancelled` when `cancel` says so between iterations.
pub fn estimate(
    image: &Grid<f64>,
    known: Option<&Grid<f64>>,
    object: &Grid<bool>,
    trusted: &Grid<bool>,
    prior: EdgePrior,
    noise_sigma: f64,
    cancel: Cancel<'_>,
) -> Result<AlbedoEstimate, Cancelled> {
    let (w, h) = image.size();
    let log = image.map(|&v| v.max(noise_floor(noise_sigma)).ln());
    let log_known = known.map(|k| {
        k.map(|&a| {
            if a > 0.0 && a.is_finite() {
                a.ln()
            } else {
                0.0
            }
        })
    });
    let residual = match &log_known {
        Some(k) => log.zip_map(k, |l, a| l - a),
        None => log.clone(),
    };
    let mut edges = integrated_edges(
        image,
        &residual,
        object,
        trusted,
        prior,
        noise_sigma,
        cancel,
    )?;
    if let Some(k) = &log_known {
        for (f, c) in edges.log_albedo.iter_mut().zip(k.as_slice()) {
            *f += c;
        }
    }
    let albedo = normalise(&edges.log_albedo, object, w, h);
    Ok(edges.estimate(albedo, &log, object))
}

/// The darkest value whose logarithm is taken: twice the noise.
fn noise_floor(noise_sigma: f64) -> f64 {
    (2.0 * noise_sigma).max(1e-4)
}

/// The edges of `log` (the log brightness, or what is left of it) and
/// their least-squares integral, before normalisation.
struct IntegratedEdges {
    log_albedo: Vec<f64>,
    edge_pairs: usize,
    cut_pairs: usize,
    beside_edge: usize,
    objects: usize,
    iterations: usize,
}

impl IntegratedEdges {
    /// The estimate with `albedo`, its variance share measured on `log`.
    fn estimate(&self, albedo: Grid<f64>, log: &Grid<f64>, object: &Grid<bool>) -> AlbedoEstimate {
        let explained_share = explained(log, &albedo, object);
        AlbedoEstimate {
            albedo,
            edge_pairs: self.edge_pairs,
            cut_pairs: self.cut_pairs,
            edge_share: self.beside_edge as f64 / self.objects.max(1) as f64,
            explained_share,
            iterations: self.iterations,
        }
    }
}

/// The albedo edges of `log` between trusted object pixels (their noise
/// threshold from `image`, whose pixels below the noise floor have no
/// difference) and their integral over the object.
fn integrated_edges(
    image: &Grid<f64>,
    log: &Grid<f64>,
    object: &Grid<bool>,
    trusted: &Grid<bool>,
    prior: EdgePrior,
    noise_sigma: f64,
    cancel: Cancel<'_>,
) -> Result<IntegratedEdges, Cancelled> {
    let (w, h) = image.size();
    let floor = noise_floor(noise_sigma);
    let usable = |q: usize| trusted.as_slice()[q] && image.as_slice()[q] > floor;
    // Each pixel's edge target to its right and below neighbour (0 where
    // the difference is shading), and whether that difference exists.
    let mut stencil = Stencil {
        width: w,
        height: h,
        right: vec![0.0; w * h],
        down: vec![0.0; w * h],
        screen: object
            .as_slice()
            .iter()
            .map(|&o| if o { SCREENING } else { 0.0 })
            .collect(),
        rhs: vec![0.0; w * h],
    };
    // The links of the integration: every pair of 4-neighbouring object
    // pixels.
    for r in 0..h {
        for c in 0..w {
            let p = r * w + c;
            if !object.as_slice()[p] {
                continue;
            }
            if c + 1 < w && object.as_slice()[p + 1] {
                stencil.right[p] = 1.0;
            }
            if r + 1 < h && object.as_slice()[p + w] {
                stencil.down[p] = 1.0;
            }
        }
    }
    // The edges: along every row and column, the steps of `edge_steps`,
    // kept where their chain confirms them (`crate::albedo_chain`).
    let lines = (0..h)
        .map(|r| (0..w).map(|c| r * w + c).collect::<Vec<_>>())
        .chain((0..w).map(|c| (0..h).map(|r| r * w + c).collect::<Vec<_>>()));
    let mut found = Vec::new();
    for line in lines {
        found.extend(edge_steps(&line, log, &usable, |p, q| {
            let (a, b) = (image.as_slice()[p], image.as_slice()[q]);
            let noise = noise_sigma * (1.0 / (a * a) + 1.0 / (b * b)).sqrt();
            (prior.log_step.max(NOISE_SIGMAS * noise), noise)
        }));
    }
    let confirmed = match prior.rule {
        EdgeRule::Steps => vec![true; found.len()],
        EdgeRule::Chains => confirmed_by_chain(&found, w, h),
    };
    let (mut edge_pairs, mut cut_pairs) = (0, 0);
    let mut beside_edge = vec![false; w * h];
    for (edge, &kept) in found.iter().zip(&confirmed) {
        if kept {
            // The link's target: (x_q - x_p - step)^2.
            stencil.rhs[edge.p] -= edge.step;
            stencil.rhs[edge.q] += edge.step;
            edge_pairs += 1;
            beside_edge[edge.p] = true;
            beside_edge[edge.q] = true;
        } else if edge.q == edge.p + 1 {
            stencil.right[edge.p] = CUT_WEIGHT;
            cut_pairs += 1;
        } else {
            stencil.down[edge.p] = CUT_WEIGHT;
            cut_pairs += 1;
        }
    }
    let objects = object.as_slice().iter().filter(|&&o| o).count();
    let mut solution = vec![0.0; w * h];
    let mut iterations = 0;
    if edge_pairs > 0 {
        iterations = integrate(&stencil, &mut solution, cancel)?;
    }
    Ok(IntegratedEdges {
        log_albedo: solution,
        edge_pairs,
        cut_pairs,
        beside_edge: beside_edge.iter().filter(|&&b| b).count(),
        objects,
        iterations,
    })
}

/// The albedo edges along one line of pixels (`line`: their indices in
/// order) as `(p, q, log I_q - log I_p)` of neighbouring pairs. An edge is
/// a step, not a slope: a peak of the differences (above half the edge
/// step, at least its same-signed neighbours), with the neighbour on each
/// side of the same sign and at least [`EDGE_SHOULDER`] of the peak joined to
/// it (an edge blurred over up to three pairs), where the next difference
/// beyond a joined one is not such a shoulder too (that is a slope of
/// shading, whose single differences pass the edge step at a low
/// resolution), and whose sum exceeds `threshold(first pixel, last pixel)`.
/// A thin dark line is two peaks of opposite sign. Pairs with a pixel that
/// is not `usable` have no difference.
fn edge_steps(
    line: &[usize],
    log: &Grid<f64>,
    usable: &impl Fn(usize) -> bool,
    threshold: impl Fn(usize, usize) -> (f64, f64),
) -> Vec<EdgePair> {
    let pairs: Vec<(usize, usize, f64)> = line
        .windows(2)
        .map(|pair| {
            let (p, q) = (pair[0], pair[1]);
            let step = if usable(p) && usable(q) {
                log.as_slice()[q] - log.as_slice()[p]
            } else {
                f64::NAN
            };
            (p, q, step)
        })
        .collect();
    let at = |k: isize| -> f64 {
        if k < 0 {
            f64::NAN
        } else {
            pairs.get(k as usize).map_or(f64::NAN, |(_, _, g)| *g)
        }
    };
    let mut edges = Vec::new();
    for (k, &(p, q, g)) in pairs.iter().enumerate() {
        let k = k as isize;
        if g.is_nan() || g.abs() <= 0.5 * threshold(p, q).0 {
            continue;
        }
        let same = |x: f64| x.is_finite() && x.signum() == g.signum();
        let (before, after) = (at(k - 1), at(k + 1));
        // A peak: no same-signed neighbour larger (the first of equals).
        if (same(before) && before.abs() >= g.abs()) || (same(after) && after.abs() > g.abs()) {
            continue;
        }
        let shoulder = |x: f64| same(x) && x.abs() >= EDGE_SHOULDER * g.abs();
        let (join_before, join_after) = (shoulder(before), shoulder(after));
        if (join_before && shoulder(at(k - 2))) || (join_after && shoulder(at(k + 2))) {
            continue;
        }
        let first = if join_before { k - 1 } else { k } as usize;
        let last = if join_after { k + 1 } else { k } as usize;
        let total: f64 = pairs[first..=last].iter().map(|(_, _, g)| g).sum();
        let (least, noise) = threshold(pairs[first].0, pairs[last].1);
        if total.abs() > least {
            edges.extend(pairs[first..=last].iter().map(|&(p, q, step)| EdgePair {
                p,
                q,
                step,
                total,
                noise,
            }));
        }
    }
    edges
}

/// `albedo` times `factor` (both positive), normalised again as
/// [`estimate`] normalises: the object's 90th percentile 1, clamped.
pub fn renormalised(albedo: &Grid<f64>, factor: &Grid<f64>, object: &Grid<bool>) -> Grid<f64> {
    let (w, h) = albedo.size();
    let log: Vec<f64> = albedo
        .as_slice()
        .iter()
        .zip(factor.as_slice())
        .map(|(a, f)| (a * f).max(1e-12).ln())
        .collect();
    normalise(&log, object, w, h)
}

/// `exp` of the log albedo, its object's 90th percentile set to 1, clamped.
fn normalise(log_albedo: &[f64], object: &Grid<bool>, w: usize, h: usize) -> Grid<f64> {
    let mut values: Vec<f64> = log_albedo
        .iter()
        .zip(object.as_slice())
        .filter(|(_, o)| **o)
        .map(|(l, _)| *l)
        .collect();
    let top = if values.is_empty() {
        0.0
    } else {
        let k = ((values.len() - 1) as f64 * NORMALISE_PERCENTILE).round() as usize;
        *values.select_nth_unstable_by(k, f64::total_cmp).1
    };
    Grid::from_fn(w, h, |c, r| {
        let q = r * w + c;
        if object.as_slice()[q] {
            (log_albedo[q] - top).exp().clamp(ALBEDO_FLOOR, 1.0)
        } else {
            1.0
        }
    })
}

/// Share of the variance of the object's log brightness explained by the
/// log albedo: `1 - var(log I - log rho) / var(log I)`, at least 0.
fn explained(log: &Grid<f64>, albedo: &Grid<f64>, object: &Grid<bool>) -> f64 {
    let (mut n, mut s1, mut s2, mut t1, mut t2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for ((l, a), o) in log
        .as_slice()
        .iter()
        .zip(albedo.as_slice())
        .zip(object.as_slice())
    {
        if *o {
            let shading = l - a.ln();
            n += 1.0;
            s1 += l;
            s2 += l * l;
            t1 += shading;
            t2 += shading * shading;
        }
    }
    if n < 2.0 {
        return 0.0;
    }
    let var_image = s2 / n - (s1 / n).powi(2);
    let var_shading = t2 / n - (t1 / n).powi(2);
    if var_image <= 0.0 {
        0.0
    } else {
        (1.0 - var_shading / var_image).max(0.0)
    }
}

/// The screened Poisson system of the integration as a weighted 5-point
/// graph: `A x = b` with `A = diag(screen) + sum over links w (e_q - e_p)
/// (e_q - e_p)^T`.
struct Stencil {
    width: usize,
    height: usize,
    /// Weight of the link from each pixel to its right neighbour (0: none).
    right: Vec<f64>,
    /// Weight of the link from each pixel to the one below (0: none).
    down: Vec<f64>,
    /// The screening per pixel (0 off the object).
    screen: Vec<f64>,
    /// The right-hand side.
    rhs: Vec<f64>,
}

impl Stencil {
    /// `(A v)_p` at pixel `p` of row `r`, column `c`: the pixel gathering
    /// its own links.
    #[inline(always)]
    fn row_times(&self, v: &[f64], p: usize, r: usize, c: usize) -> f64 {
        let w = self.width;
        let mut sum = self.screen[p] * v[p];
        if self.right[p] > 0.0 {
            sum += self.right[p] * (v[p] - v[p + 1]);
        }
        if c > 0 && self.right[p - 1] > 0.0 {
            sum += self.right[p - 1] * (v[p] - v[p - 1]);
        }
        if self.down[p] > 0.0 {
            sum += self.down[p] * (v[p] - v[p + w]);
        }
        if r > 0 && self.down[p - w] > 0.0 {
            sum += self.down[p - w] * (v[p] - v[p - w]);
        }
        sum
    }

    /// `A v` (rows in parallel).
    fn apply(&self, v: &[f64], out: &mut [f64]) {
        let w = self.width;
        out.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            for (c, o) in row.iter_mut().enumerate() {
                *o = self.row_times(v, r * w + c, r, c);
            }
        });
    }

    /// One damped Jacobi sweep for `A x = b` into `next` (`x` unread where
    /// `x_is_zero`: `A 0 = 0`), in one pass over the rows (in parallel).
    fn jacobi_sweep(
        &self,
        (x, x_is_zero): (&[f64], bool),
        b: &[f64],
        diagonal: &[f64],
        next: &mut [f64],
    ) {
        let w = self.width;
        next.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
            for (c, z) in row.iter_mut().enumerate() {
                let p = r * w + c;
                let (old, az) = if x_is_zero {
                    (0.0, 0.0)
                } else {
                    (x[p], self.row_times(x, p, r, c))
                };
                let d = diagonal[p];
                *z = if d > 0.0 {
                    old + JACOBI_DAMPING * (b[p] - az) / d
                } else {
                    old
                };
            }
        });
    }

    /// The residual `b - A x` summed over the 2x2 blocks (coarse rows in
    /// parallel; each block's four pixels added in row order).
    fn restricted_residual(&self, x: &[f64], b: &[f64]) -> Vec<f64> {
        let (w, h) = (self.width, self.height);
        let cw = w.div_ceil(2);
        let mut coarse = vec![0.0; cw * h.div_ceil(2)];
        coarse
            .par_chunks_mut(cw)
            .enumerate()
            .for_each(|(coarse_row, line)| {
                for r in 2 * coarse_row..(2 * coarse_row + 2).min(h) {
                    for c in 0..w {
                        let p = r * w + c;
                        line[c / 2] += b[p] - self.row_times(x, p, r, c);
                    }
                }
            });
        coarse
    }

    /// The diagonal of `A`.
    fn diagonal(&self) -> Vec<f64> {
        let w = self.width;
        let mut d = self.screen.clone();
        for p in 0..d.len() {
            if self.right[p] > 0.0 {
                d[p] += self.right[p];
                d[p + 1] += self.right[p];
            }
            if self.down[p] > 0.0 {
                d[p] += self.down[p];
                d[p + w] += self.down[p];
            }
        }
        d
    }

    /// The Galerkin coarse system of 2x2 blocks with a piecewise-constant
    /// prolongation (`P^T A P`, `P^T b`): links inside a block vanish, the
    /// ones between blocks add up.
    fn coarsen(&self) -> Stencil {
        let (w, h) = (self.width, self.height);
        let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
        let mut coarse = Stencil {
            width: cw,
            height: ch,
            right: vec![0.0; cw * ch],
            down: vec![0.0; cw * ch],
            screen: self.restrict(&self.screen),
            rhs: self.restrict(&self.rhs),
        };
        for r in 0..h {
            for c in 0..w {
                let p = r * w + c;
                let q = (r / 2) * cw + c / 2;
                if self.right[p] > 0.0 && c % 2 == 1 {
                    coarse.right[q] += self.right[p];
                }
                if self.down[p] > 0.0 && r % 2 == 1 {
                    coarse.down[q] += self.down[p];
                }
            }
        }
        coarse
    }

    /// `P^T v`: the sums of `v` (on this grid) over its 2x2 blocks, on the
    /// coarse grid of [`Stencil::coarsen`].
    fn restrict(&self, v: &[f64]) -> Vec<f64> {
        let (w, cw) = (self.width, self.width.div_ceil(2));
        let mut coarse = vec![0.0; cw * self.height.div_ceil(2)];
        for (r, line) in v.chunks(w).enumerate() {
            for (c, value) in line.iter().enumerate() {
                coarse[(r / 2) * cw + c / 2] += value;
            }
        }
        coarse
    }

    /// `v += weight P y`: each 2x2 block of `v` (on this grid) raised by its
    /// coarse value in `y`.
    fn prolong_add(&self, y: &[f64], weight: f64, v: &mut [f64]) {
        let cw = self.width.div_ceil(2);
        v.par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(r, line)| {
                for (c, value) in line.iter_mut().enumerate() {
                    *value += weight * y[(r / 2) * cw + c / 2];
                }
            });
    }
}

/// Solves the integration's system from zero by conjugate gradients
/// preconditioned with a multigrid V-cycle over its 2x2-block Galerkin
/// levels ([`JacobiLevel`] in the crate's one [`Hierarchy`]), to a relative
/// residual of 1e-6; returns the
/// iterations. The estimate is the system's solution, not where a solver
/// stops: the cascadic Jacobi-preconditioned CG before ran into its 400
/// iterations at every level above 256 px, and the chains' estimate on the
/// beside Bunny with patches rested on that (RSE 0.042 there, 0.086
/// converged without [`CUT_WEIGHT`]). The bench's render rows are the same
/// to four digits at 1e-6 and 1e-9 (at most 136 iterations at 1e-8).
fn integrate(stencil: &Stencil, x: &mut [f64], cancel: Cancel<'_>) -> Result<usize, Cancelled> {
    let mut fine = JacobiLevel::new(stencil);
    let mut hierarchy = Hierarchy::build(&fine);
    x.iter_mut().for_each(|v| *v = 0.0);
    // One V-cycle from zero for `A z = r` (the same smoothing before and
    // after, the coarse correction weighted by [`COARSE_CORRECTION`]):
    // symmetric, and positive on every system measured, so a
    // preconditioner of conjugate gradients (which stops should `r . z`
    // ever turn non-positive).
    let precondition = |r: &[f64], z: &mut [f64]| {
        fine.b.copy_from_slice(r);
        fine.zero_unknowns();
        hierarchy.cycle(&mut fine, SWEEPS);
        z.copy_from_slice(&fine.x);
    };
    conjugate_gradients(stencil, x, precondition, cancel)
}

/// One level of the integration's multigrid: a [`Stencil`] (borrowed for
/// the finest, owned below) with its diagonal and vectors, smoothed by
/// damped Jacobi, its coarser level the 2x2-block Galerkin system of
/// [`Stencil::coarsen`].
struct JacobiLevel<S> {
    /// The level's system.
    stencil: S,
    /// The diagonal of its matrix.
    diagonal: Vec<f64>,
    /// The unknowns.
    x: Vec<f64>,
    /// The right-hand side (the finest level's: the residual to
    /// precondition).
    b: Vec<f64>,
    /// The next sweep's unknowns.
    scratch: Vec<f64>,
    /// `x` is all zero (set by `zero_unknowns`; a sweep then skips `A x`).
    x_is_zero: bool,
}

/// The coarsest level's longest side, pixels.
const COARSEST_SIDE: usize = 4;
/// Damped Jacobi sweeps before and after each coarse correction, and on
/// the coarsest level.
const SWEEPS: Sweeps = Sweeps {
    smoothing: 2,
    coarsest: 20,
};
/// The coarse correction's weight: a piecewise-constant prolongation
/// undercorrects smooth errors; measured on a 1920x1080 render's two
/// estimates, 1.5 needed 11-29 iterations to 1e-4 against 22-41 with 1.
const COARSE_CORRECTION: f64 = 1.5;
/// Damping of the Jacobi sweeps (below 1: a convergent smoother for a
/// graph Laplacian, whose Jacobi-scaled spectrum lies in (0, 2]).
const JACOBI_DAMPING: f64 = 0.8;

impl<S: Borrow<Stencil>> JacobiLevel<S> {
    /// The level of `stencil`, its vectors zero.
    fn new(stencil: S) -> Self {
        let system: &Stencil = stencil.borrow();
        let diagonal = system.diagonal();
        let n = system.width * system.height;
        Self {
            stencil,
            diagonal,
            x: vec![0.0; n],
            b: vec![0.0; n],
            scratch: vec![0.0; n],
            x_is_zero: true,
        }
    }
}

impl<S: Borrow<Stencil>> Coarsen for JacobiLevel<S> {
    type Coarse = JacobiLevel<Stencil>;

    /// The 2x2-block Galerkin level, down to a longest side of at most
    /// [`COARSEST_SIDE`].
    fn coarsen(&self) -> Option<JacobiLevel<Stencil>> {
        let stencil: &Stencil = self.stencil.borrow();
        (stencil.width.max(stencil.height) > COARSEST_SIDE)
            .then(|| JacobiLevel::new(stencil.coarsen()))
    }
}

impl<S: Borrow<Stencil>> multigrid::Level for JacobiLevel<S> {
    type Coarse = JacobiLevel<Stencil>;

    /// `x` += damped Jacobi sweeps for `A x = b`.
    fn smooth(&mut self, sweeps: usize) {
        let stencil: &Stencil = self.stencil.borrow();
        for _ in 0..sweeps {
            stencil.jacobi_sweep(
                (&self.x, self.x_is_zero),
                &self.b,
                &self.diagonal,
                &mut self.scratch,
            );
            std::mem::swap(&mut self.x, &mut self.scratch);
            self.x_is_zero = false;
        }
    }

    /// The residual `b - A x` summed over the 2x2 blocks.
    fn restrict_residual(&mut self, coarse: &mut JacobiLevel<Stencil>) {
        let stencil: &Stencil = self.stencil.borrow();
        coarse.b = stencil.restricted_residual(&self.x, &self.b);
    }

    /// Each 2x2 block of `x` raised by [`COARSE_CORRECTION`] times its
    /// coarse value.
    fn prolong_add(&mut self, coarse: &JacobiLevel<Stencil>) {
        let stencil: &Stencil = self.stencil.borrow();
        stencil.prolong_add(&coarse.x, COARSE_CORRECTION, &mut self.x);
        self.x_is_zero = false;
    }

    fn zero_unknowns(&mut self) {
        self.x.iter_mut().for_each(|v| *v = 0.0);
        self.x_is_zero = true;
    }
}

/// Conjugate gradients on `stencil` from `x`, preconditioned by
/// `precondition` (symmetric, positive), to a residual of
/// `RELATIVE_TOLERANCE` times the right-hand side's (dot products summed in
/// fixed chunks, [`DOT_CHUNK`]; at most 400 steps); returns the iterations
/// used. The routine is [`crate::linalg::cg`]'s.
fn conjugate_gradients(
    stencil: &Stencil,
    x: &mut [f64],
    precondition: impl FnMut(&[f64], &mut [f64]),
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    const MAX_ITERATIONS: usize = 400;
    const RELATIVE_TOLERANCE: f64 = 1e-6;
    let summation = cg::Summation::Chunked(DOT_CHUNK);
    let mut ax = vec![0.0; x.len()];
    stencil.apply(x, &mut ax);
    let r: Vec<f64> = stencil.rhs.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let target = RELATIVE_TOLERANCE * summation.dot(&stencil.rhs, &stencil.rhs).sqrt();
    let settings = cg::Settings {
        max_iterations: MAX_ITERATIONS,
        summation,
        stop: cg::Stop::BeforeStep {
            norm: cg::Norm::Euclidean,
            tolerance: target,
        },
        cancel_poll: cg::CancelPoll {
            every: 1,
            before_test: false,
        },
        rz_guard: cg::RzGuard::AfterPreconditioning,
        beta: cg::Beta::FletcherReeves,
    };
    cg::solve(
        x,
        r,
        |v, out| stencil.apply(v, out),
        precondition,
        &settings,
        cancel,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every step an edge, at the default edge step.
    const STEPS: EdgePrior = EdgePrior {
        log_step: DEFAULT_EDGE_LOG_STEP,
        rule: EdgeRule::Steps,
    };

    /// A smooth shading times a two-patch albedo (left 1, right `dark`).
    fn patched(dark: f64) -> (Grid<f64>, Grid<f64>) {
        let shading = Grid::from_fn(40, 30, |c, r| {
            0.6 + 0.3 * ((c as f64) / 13.0).sin() * ((r as f64) / 11.0).cos()
        });
        let albedo = Grid::from_fn(40, 30, |c, _| if c < 25 { 1.0 } else { dark });
        (shading.zip_map(&albedo, |s, a| s * a), albedo)
    }

    /// [`estimate`] over every pixel of `image` at the default edge step,
    /// without noise, every step an edge.
    fn clean_estimate(image: &Grid<f64>) -> AlbedoEstimate {
        clean_estimate_by(image, EdgeRule::Steps)
    }

    /// [`clean_estimate`] with `rule`.
    fn clean_estimate_by(image: &Grid<f64>, rule: EdgeRule) -> AlbedoEstimate {
        let (w, h) = image.size();
        let all = Grid::filled(w, h, true);
        estimate(
            image,
            None,
            &all,
            &all,
            EdgePrior {
                log_step: DEFAULT_EDGE_LOG_STEP,
                rule,
            },
            0.0,
            Cancel::NEVER,
        )
        .expect("not cancelled")
    }

    #[test]
    fn a_chain_confirms_a_constant_ratio_and_cuts_a_changing_one() {
        // Two materials: the same estimate under either rule.
        let (image, truth) = patched(0.5);
        let found = clean_estimate_by(&image, EdgeRule::Chains);
        for (a, t) in found.albedo.as_slice().iter().zip(truth.as_slice()) {
            assert!((a - t).abs() < 0.01, "albedo {a} against {t}");
        }
        assert_eq!((found.edge_pairs, found.cut_pairs), (30, 0));
        // A step that changes along its edge (the right side a sawtooth
        // of 1, 0.85 and 0.72 down the rows, steps of 0.16-0.33 inside it:
        // shading at an edge step of 0.5) is not two materials: cut, and
        // the albedo stays 1 on both sides, where every step as an edge
        // darkens the right side.
        let (shading, _) = patched(1.0);
        let turning = shading.zip_map(
            &Grid::from_fn(40, 30, |c, r| {
                if c < 25 {
                    1.0
                } else {
                    0.5 * [1.0, 0.85, 0.72][r % 3]
                }
            }),
            |s, f| s * f,
        );
        let all = Grid::filled(40, 30, true);
        let by = |rule| {
            let prior = EdgePrior {
                log_step: 0.5,
                rule,
            };
            estimate(&turning, None, &all, &all, prior, 0.0, Cancel::NEVER).expect("not cancelled")
        };
        let chains = by(EdgeRule::Chains);
        assert_eq!(chains.edge_pairs, 0);
        assert_eq!(chains.cut_pairs, 30);
        assert!(
            chains
                .albedo
                .as_slice()
                .iter()
                .all(|&a| (a - 1.0).abs() < 0.01)
        );
        let steps = by(EdgeRule::Steps);
        assert!(
            *steps.albedo.at(35, 10) < 0.8,
            "{}",
            steps.albedo.at(35, 10)
        );
    }

    #[test]
    fn a_patch_is_found_and_shading_is_left_alone() {
        let (image, truth) = patched(0.5);
        let found = clean_estimate(&image);
        for (a, t) in found.albedo.as_slice().iter().zip(truth.as_slice()) {
            assert!((a - t).abs() < 0.01, "albedo {a} against {t}");
        }
        assert_eq!(found.edge_pairs, 30);
        assert!(found.explained_share > 0.3, "{}", found.explained_share);
        // Smooth shading alone has no edge: the albedo stays 1.
        let (shading, _) = patched(1.0);
        let none = clean_estimate(&shading);
        assert_eq!(none.edge_pairs, 0);
        assert!(none.albedo.as_slice().iter().all(|&a| a == 1.0));
    }

    #[test]
    fn a_known_coarse_albedo_leaves_only_what_it_misses() {
        let (image, truth) = patched(0.5);
        let (w, h) = image.size();
        let all = Grid::filled(w, h, true);
        let refine_with = |coarse: &Grid<f64>| {
            estimate(&image, Some(coarse), &all, &all, STEPS, 0.0, Cancel::NEVER)
                .expect("not cancelled")
        };
        // Nothing known yet: the estimate itself.
        assert_eq!(
            refine_with(&Grid::filled(w, h, 1.0)),
            clean_estimate(&image)
        );
        // The albedo known (at another scale): no edge is left to add.
        let known = refine_with(&truth.map(|a| 0.8 * a));
        assert_eq!(known.edge_pairs, 0);
        for (a, t) in known.albedo.as_slice().iter().zip(truth.as_slice()) {
            assert!((a - t).abs() < 1e-12, "albedo {a} against {t}");
        }
    }

    #[test]
    fn the_integration_reaches_the_least_squares_solution() {
        // A 23x17 graph with links of weight 1, CUT_WEIGHT or none and a
        // pseudo-random right-hand side (a linear congruential sequence),
        // solved densely by Cholesky: the multigrid-preconditioned CG
        // lands on the same solution, whatever its levels.
        let (w, h) = (23, 17);
        let n = w * h;
        let mut seed: u64 = 12_345;
        let mut next = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut weight = |last: bool| {
            let u = next();
            if last || u < 0.1 {
                0.0
            } else if u < 0.3 {
                CUT_WEIGHT
            } else {
                1.0
            }
        };
        let right: Vec<f64> = (0..n).map(|p| weight(p % w == w - 1)).collect();
        let down: Vec<f64> = (0..n).map(|p| weight(p / w == h - 1)).collect();
        // Edge targets as the estimate makes them: a step on some of the
        // links, -step at one end and +step at the other.
        let mut rhs = vec![0.0; n];
        for p in 0..n {
            for (q, weight) in [(p + 1, right[p]), (p + w, down[p])] {
                let u = next();
                if weight > 0.0 && u < 0.2 {
                    let step = 5.0 * u - 0.5;
                    rhs[p] -= step;
                    rhs[q] += step;
                }
            }
        }
        let stencil = Stencil {
            width: w,
            height: h,
            right,
            down,
            screen: vec![SCREENING; n],
            rhs,
        };
        let mut found = vec![0.0; n];
        let iterations = integrate(&stencil, &mut found, Cancel::NEVER).expect("not cancelled");
        assert!(iterations < 400, "{iterations} iterations");
        // The dense matrix from `apply` on the unit vectors, then Cholesky.
        let mut a = vec![0.0; n * n];
        let mut unit = vec![0.0; n];
        let mut column = vec![0.0; n];
        for j in 0..n {
            unit[j] = 1.0;
            stencil.apply(&unit, &mut column);
            unit[j] = 0.0;
            for i in 0..n {
                a[i * n + j] = column[i];
            }
        }
        for j in 0..n {
            let pivot = (a[j * n + j] - (0..j).map(|k| a[j * n + k].powi(2)).sum::<f64>()).sqrt();
            a[j * n + j] = pivot;
            for i in j + 1..n {
                let dot: f64 = (0..j).map(|k| a[i * n + k] * a[j * n + k]).sum();
                a[i * n + j] = (a[i * n + j] - dot) / pivot;
            }
        }
        let mut exact = stencil.rhs.clone();
        for i in 0..n {
            let dot: f64 = (0..i).map(|k| a[i * n + k] * exact[k]).sum();
            exact[i] = (exact[i] - dot) / a[i * n + i];
        }
        for i in (0..n).rev() {
            let dot: f64 = (i + 1..n).map(|k| a[k * n + i] * exact[k]).sum();
            exact[i] = (exact[i] - dot) / a[i * n + i];
        }
        let scale = exact.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for (f, e) in found.iter().zip(&exact) {
            assert!(
                (f - e).abs() <= 1e-4 * scale,
                "{f} against {e} (scale {scale})"
            );
        }
    }

    #[test]
    fn the_estimate_is_invariant_to_exposure() {
        let (image, _) = patched(0.6);
        let at = |k: f64| clean_estimate(&image.map(|v| v * k)).albedo;
        let (a, b) = (at(1.0), at(0.25));
        for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
            assert!((x - y).abs() < 1e-9, "{x} {y}");
        }
    }

    #[test]
    fn noise_below_its_own_threshold_makes_no_edge() {
        // A flat grey at 0.1 with +-0.03 checkerboard "noise" (log steps
        // 0.6): at its noise sigma no step is an edge; at sigma 0 they are.
        let image = Grid::from_fn(20, 20, |c, r| if (c + r) % 2 == 0 { 0.13 } else { 0.07 });
        let all = Grid::filled(20, 20, true);
        let quiet = estimate(&image, None, &all, &all, STEPS, 0.03, Cancel::NEVER).expect("ok");
        assert_eq!(quiet.edge_pairs, 0);
        let loud = estimate(&image, None, &all, &all, STEPS, 0.0, Cancel::NEVER).expect("ok");
        assert!(loud.edge_pairs > 0);
    }
}
