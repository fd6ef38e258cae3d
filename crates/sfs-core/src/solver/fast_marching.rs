//! Baseline: fast marching for perspective shape from shading with a point
//! light at the optical centre and 1/r^2 fall-off (the Lambertian model of
//! Prados and Faugeras, solved by fast marching as Vogel et al. do).
//!
//! ## Formulation
//!
//! References: E. Prados, O. Faugeras, "Shape from shading: a well-posed
//! problem?", CVPR 2005 (the model and its Hamilton-Jacobi equation);
//! O. Vogel, M. Breuss, J. Weickert, "Perspective shape from shading with
//! non-Lambertian reflectance", DAGM 2008, and O. Vogel, M. Breuss,
//! T. Leichtweis, J. Weickert, "Fast shape from shading for Phong-type
//! surfaces", SSVM 2009 (upwind discretisation and fast marching); J. A.
//! Sethian, "Level set methods and fast marching methods", 1999.
//!
//! With the conventions of METHOD.md, `I = s Q^3 / (z W)`,
//! `W = sqrt(f^2 |grad z|^2 + (grad z . x + z)^2)`. Prados and Faugeras
//! parametrise the surface by its distance from the light along each ray,
//! `r = z / Q`, and write `r = e^v`. With `grad ln z = grad v - x / (|x|^2 +
//! f^2)` the cross terms cancel and the model becomes the Hamilton-Jacobi
//! equation
//!
//! ```text
//! H(x, v, p) = I(x) e^{2v} sqrt(f^2 |p|^2 + (p . x)^2 + Q(x)^2) - s Q(x) = 0,  p = grad v.
//! ```
//!
//! The square root is smallest, `Q`, at `p = 0`, where the surface faces the
//! light, so every solution satisfies `v <= v_f = ln sqrt(s / I)` (the
//! distance at which a light-facing patch has brightness `I`), with equality
//! at the singular points (local minima of the distance). Parametrised by
//! `ln z` instead, the root gains a term linear in `p`, the equation becomes
//! strongly anisotropic and fast marching's neighbour ordering no longer
//! follows its characteristics (a tilted plane came out 1% wrong at any
//! resolution). The depth is `z = Q e^v`.
//!
//! ## Discretisation and ordering
//!
//! `p` is replaced by the upwind differences of the paper (Eqs. 9-11) taken
//! towards the smaller neighbour along each axis, as in fast marching for the
//! eikonal equation: a pixel's value depends only on neighbours with smaller
//! values. Fast marching then accepts pixels in increasing order of `v`.
//! Every object pixel starts as a trial pixel with its
//! frontal value `v_f` (the state constraint above; these are read in order
//! from a `FrontalQueue`, and a binary heap holds only the propagated
//! values); so the singular points,
//! whose frontal value no propagated value undercuts, are accepted first
//! and the front marches outwards from them. When a pixel is accepted, each
//! not yet accepted object neighbour gets the local solution of the
//! discrete equation from its accepted neighbours (one axis with the
//! smaller neighbour first; both axes if the one-axis value exceeds the other
//! neighbour), found by Newton's method on the logarithm of the equation,
//! safeguarded by bisection in a bracket above the neighbours; where even a
//! zero slope predicts a darker pixel than observed, the neighbour's value is
//! kept.
//!
//! It relies entirely on the data: noise creates false brightest points
//! (trial values that are accepted too early) and kinks propagate along the
//! characteristics; it has no confidence mechanism (`c` is ignored) and no
//! smoothness. Only object pixels are solved.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::time::Instant;

use rayon::prelude::*;

use crate::camera::Intrinsics;
use crate::cancel::{Cancel, Cancelled, Uncancelled};
use crate::grid::Grid;
use crate::material::Material;
use crate::model::{self, LevelGeometry};
use crate::params::DomainMode;

use super::problem::{
    IterationReport, LevelReport, LevelResult, PhaseTimes, Problem, Solution, SolveError,
    SolveObserver, masked,
};

/// Settings of the fast marching baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct FastMarchingParams {
    /// Image values below this fraction of the brightest object pixel are
    /// raised to it (a black pixel has no finite solution); default 1e-3.
    pub min_relative_intensity: f64,
    /// The surface's material: Lambert (default) or any whose brightness
    /// under a centred light grows with `N . L` ([`Material::centred_is_monotone`]:
    /// Blinn-Phong, Oren-Nayar up to about 0.61 rad), the Phong-type
    /// marching of Vogel, Breuss, Leichtweis and Weickert.
    pub material: Material,
}

impl Default for FastMarchingParams {
    fn default() -> Self {
        Self {
            min_relative_intensity: 1e-3,
            material: Material::Lambert,
        }
    }
}

impl FastMarchingParams {
    /// The default settings for `material`.
    pub fn for_material(material: Material) -> Self {
        Self {
            material,
            ..Self::default()
        }
    }
}

/// A heap entry: smallest `v` first.
#[derive(Clone, Copy, PartialEq, bytemuck::Zeroable)]
struct Trial {
    value: f64,
    index: usize,
}

impl Eq for Trial {}

impl Ord for Trial {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .value
            .total_cmp(&self.value)
            .then_with(|| other.index.cmp(&self.index))
    }
}

impl PartialOrd for Trial {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The data of one pixel's local equation.
#[derive(Clone, Copy)]
struct Pixel {
    /// Image-plane coordinates, pixels.
    x: f64,
    y: f64,
    /// `Q^2`.
    q2: f64,
    /// `ln(s Q / I)` (with `I` clamped from below).
    log_target: f64,
}

/// One upwind axis of a local update: the smaller accepted neighbour's value
/// and the sign of the difference (`+1`: the neighbour is at `x - h`).
#[derive(Clone, Copy)]
struct Axis {
    value: f64,
    sign: f64,
}

/// The local equation in logarithms, `H(v) = 2 v + ln sqrt(g(v)) - ln(s Q / I)`
/// with `g(v) = f^2 (a^2 + b^2) + (a x + b y)^2 + Q^2`: zero exactly where
/// `F(v) = I e^{2v} sqrt(g) - s Q` is, with the same sign elsewhere, and no
/// exponential.
struct LocalEquation<'a, const LAMBERT: bool> {
    pixel: &'a Pixel,
    f2: f64,
    ax: Option<Axis>,
    ay: Option<Axis>,
    /// Unless `LAMBERT`: `H` gains `-ln(m(c) / c)`, `c = Q / sqrt(g)` (see
    /// [`LocalEquation::eval`]). `LAMBERT` compiles the paper's equation
    /// alone (a branch in this inner loop slowed a 1024 px start).
    material: Material,
}

impl<const LAMBERT: bool> LocalEquation<'_, LAMBERT> {
    /// `g(v)` and `dg/dv`.
    fn root_term(&self, v: f64) -> (f64, f64) {
        let p = self.pixel;
        let (a, sa) = self
            .ax
            .map_or((0.0, 0.0), |n| (n.sign * (v - n.value), n.sign));
        let (b, sb) = self
            .ay
            .map_or((0.0, 0.0), |n| (n.sign * (v - n.value), n.sign));
        let t = a * p.x + b * p.y;
        let g = self.f2 * (a * a + b * b) + t * t + p.q2;
        let dg = 2.0 * self.f2 * (a * sa + b * sb) + 2.0 * t * (sa * p.x + sb * p.y);
        (g, dg)
    }

    /// `H(v)` and `dH/dv`. For a material with factor `m(c)` under the
    /// centred light, `I e^{2v} = s m(c)` with `c = Q / sqrt(g)`:
    /// `H = 2 v + ln sqrt(g) - ln(s Q / I) - ln(m(c) / c)`, and
    /// `dH/dv = 2 + (c m'(c) / m(c)) dg / (2 g)` (Lambert: `m = c`).
    fn eval(&self, v: f64) -> (f64, f64) {
        let (g, dg) = self.root_term(v);
        let lambert = (
            2.0 * v + 0.5 * g.ln() - self.pixel.log_target,
            2.0 + 0.5 * dg / g,
        );
        if LAMBERT {
            return lambert;
        }
        let c = (self.pixel.q2 / g).sqrt().min(1.0);
        let (m, dm) = self.material.centred(c);
        (lambert.0 - (m / c).ln(), 2.0 + 0.5 * (c * dm / m) * dg / g)
    }

    /// `d^2 g / dv^2` (constant: `g` is quadratic in `v`).
    fn curvature(&self) -> f64 {
        let p = self.pixel;
        let sa = self.ax.map_or(0.0, |n| n.sign);
        let sb = self.ay.map_or(0.0, |n| n.sign);
        let lin = sa * p.x + sb * p.y;
        2.0 * (self.f2 * (sa * sa + sb * sb) + lin * lin)
    }

    /// The value `v >= lower` where `g` is smallest (the slope that faces
    /// the light most).
    fn facing_value(&self, lower: f64) -> f64 {
        let (_, dg) = self.root_term(lower);
        let curvature = self.curvature();
        if curvature > 0.0 && dg < 0.0 {
            lower - dg / curvature
        } else {
            lower
        }
    }
}

/// The root of the local equation `F(v) = I e^{2v} sqrt(g(v)) - s Q = 0`
/// above the neighbours (`v >= lower`) where `F` crosses zero upwards.
///
/// The perspective term makes `F` dip below its value at `lower` before it
/// grows (the slope first turns the surface towards the light), so there can
/// be two roots: the larger one, past the dip, is taken, where `F` grows
/// with `v` as a monotone scheme needs; it is the one that reproduces the
/// surface near the singular points. Without any root (the pixel is brighter
/// than any slope explains) the most light-facing value is returned.
///
/// The root is found on [`LocalEquation`]'s `H` by Newton's method,
/// safeguarded by bisection, from an upper bound in closed form: past the
/// facing value both `2 v` and `g` grow, so the root lies below where either
/// alone would close the gap `-H(facing)`; below about 45 degrees of slope
/// `H` is convex there and the iterates fall monotonically onto the root.
fn local_root<const LAMBERT: bool>(
    p: &Pixel,
    f2: f64,
    material: Material,
    lower: f64,
    ax: Option<Axis>,
    ay: Option<Axis>,
) -> f64 {
    let equation = LocalEquation::<LAMBERT> {
        pixel: p,
        f2,
        ax,
        ay,
        material,
    };
    // The bound by g alone needs `ln m(c)` to fall at least as fast as
    // `ln c` (Lambert, Blinn-Phong); Oren-Nayar's falls slower. The models'
    // table says which.
    let bound_by_g = material.bound_by_g();
    let facing = equation.facing_value(lower);
    let (h_facing, _) = equation.eval(facing);
    if !h_facing.is_finite() {
        return facing;
    }
    let (mut lo, mut hi) = if h_facing < 0.0 {
        // 2 v alone closes the gap at `facing - H / 2`; g alone where it
        // reaches g(facing) e^{-2 H} (the larger root of a quadratic, in a
        // form without cancellation).
        let (g, dg) = equation.root_term(facing);
        let gap = g * (-2.0 * h_facing).exp_m1();
        let half_curvature = 0.5 * equation.curvature();
        let by_g = 2.0 * gap / (dg + (dg * dg + 4.0 * half_curvature * gap).sqrt());
        let by_v = -0.5 * h_facing;
        let bound = if bound_by_g && by_g.is_finite() {
            by_g.min(by_v)
        } else {
            by_v
        };
        (facing, facing + bound)
    } else if equation.eval(lower).0 < 0.0 {
        (lower, facing)
    } else {
        return facing;
    };
    let mut v = hi;
    for _ in 0..100 {
        let (hv, dv) = equation.eval(v);
        if hv == 0.0 {
            return v;
        }
        if hv < 0.0 {
            lo = v;
        } else {
            hi = v;
        }
        let step = hv / dv;
        let tolerance = 1e-13 * (1.0 + v.abs());
        if step.abs() <= tolerance || hi - lo <= tolerance {
            return (v - step).clamp(lo, hi);
        }
        let newton = v - step;
        v = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    v
}

/// The fast-marching depth of `image` seen by `camera` on `domain` (a
/// problem validated by the caller, intensity scale `s`): a value at every pixel, the mean reached
/// depth off the domain and where the front did not arrive; and that mean.
/// Polls `cancel` every [`CANCEL_POLL`] heap operations.
///
/// Every domain pixel starts with its frontal value; those are read in
/// order from a [`FrontalQueue`] beside a binary heap that holds only the
/// propagated values (the front, not the whole image), so a pop costs a
/// comparison of the two heads and a heap operation on the front's size.
pub(crate) fn march(
    image: &Grid<f64>,
    camera: Intrinsics,
    domain: &Grid<bool>,
    s: f64,
    settings: &FastMarchingParams,
    cancel: Cancel<'_>,
) -> Result<(Grid<f64>, f64), SolveError> {
    if settings.material.is_lambert() {
        march_with::<true>(image, camera, domain, s, settings, cancel)
    } else {
        march_with::<false>(image, camera, domain, s, settings, cancel)
    }
}

/// [`march`] for Lambert (`LAMBERT`) or any other material.
fn march_with<const LAMBERT: bool>(
    image: &Grid<f64>,
    camera: Intrinsics,
    domain: &Grid<bool>,
    s: f64,
    settings: &FastMarchingParams,
    cancel: Cancel<'_>,
) -> Result<(Grid<f64>, f64), SolveError> {
    let (w, h) = image.size();
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let f2 = camera.focal_px * camera.focal_px;
    let inside = domain.as_slice();
    let image = image.as_slice();
    // By rows, polled (one pass over 18 MP is tens of milliseconds).
    let brightest = inside
        .par_chunks(w.max(1))
        .zip(image.par_chunks(w.max(1)))
        .map(|(inside, image)| {
            if cancel.is_cancelled() {
                return 0.0;
            }
            inside
                .iter()
                .zip(image)
                .filter(|(inside, _)| **inside)
                .fold(0.0, |brightest: f64, (_, &v)| brightest.max(v))
        })
        .reduce(|| 0.0, f64::max);
    cancel.check()?;
    let floor = settings.min_relative_intensity * brightest;
    let material = settings.material;
    // A light-facing patch (c = 1) is m(1) times Lambert's brightness.
    let facing_s = s * settings.material.facing_gain();
    let pixel = |q: usize, log_target: f64| {
        let ray = geometry.ray(q % w, q / w);
        let qv = ray.q();
        Pixel {
            x: ray.x_px,
            y: ray.y_px,
            q2: qv * qv,
            log_target,
        }
    };
    let mut log_target = vec![0.0; w * h];
    fill_rows(&mut log_target, w, cancel, |q| {
        (s * geometry.ray(q % w, q / w).q() / image[q].max(floor)).ln()
    })?;
    // Frontal values: a light-facing patch at distance e^v has I = s e^{-2v}.
    // Zeroed by the allocator (untouched pages), every value set by the
    // polled rows: one sequential fill of 8 bytes per pixel would be tens to
    // hundreds of milliseconds without a poll at 18 MP.
    let mut value = vec![0.0; w * h];
    fill_rows(&mut value, w, cancel, |q| {
        if inside[q] {
            0.5 * (facing_s / image[q].max(floor)).ln()
        } else {
            f64::INFINITY
        }
    })?;
    let mut accepted = vec![false; w * h];
    let mut frontal = FrontalQueue::new(&value, inside, w, cancel)?;
    let mut heap: BinaryHeap<Trial> = BinaryHeap::new();
    let axis = |value: &[f64], accepted: &[bool], minus: Option<usize>, plus: Option<usize>| {
        let m = minus.filter(|&n| accepted[n]).map(|n| value[n]);
        let p = plus.filter(|&n| accepted[n]).map(|n| value[n]);
        match (m, p) {
            (Some(a), Some(b)) if b < a => Some(Axis {
                value: b,
                sign: -1.0,
            }),
            (Some(a), _) => Some(Axis {
                value: a,
                sign: 1.0,
            }),
            (None, Some(b)) => Some(Axis {
                value: b,
                sign: -1.0,
            }),
            (None, None) => None,
        }
    };
    let mut popped = 0usize;
    loop {
        // The smaller head of the two queues (the greater in `Trial`'s order).
        let from_heap = match (heap.peek(), frontal.peek()) {
            (Some(a), Some(b)) => a > b,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        let Some(Trial { value: v, index }) = (if from_heap {
            heap.pop()
        } else {
            frontal.next()
        }) else {
            break;
        };
        // Polled per pop, not per accepted pixel: stale entries can run for
        // a long time at 18 megapixels.
        popped += 1;
        if popped.is_multiple_of(CANCEL_POLL) {
            cancel.check()?;
        }
        if accepted[index] || v > value[index] {
            continue;
        }
        accepted[index] = true;
        let (c, r) = (index % w, index / w);
        let mut neighbours = [None; 4];
        if c > 0 {
            neighbours[0] = Some(index - 1);
        }
        if c + 1 < w {
            neighbours[1] = Some(index + 1);
        }
        if r > 0 {
            neighbours[2] = Some(index - w);
        }
        if r + 1 < h {
            neighbours[3] = Some(index + w);
        }
        for q in neighbours.into_iter().flatten() {
            if accepted[q] || !inside[q] {
                continue;
            }
            let (qc, qr) = (q % w, q / w);
            let within = |n: usize| inside[n];
            let left = (qc > 0).then(|| q - 1).filter(|&n| within(n));
            let right = (qc + 1 < w).then(|| q + 1).filter(|&n| within(n));
            let up = (qr > 0).then(|| q - w).filter(|&n| within(n));
            let down = (qr + 1 < h).then(|| q + w).filter(|&n| within(n));
            let ax = axis(&value, &accepted, left, right);
            let ay = axis(&value, &accepted, up, down);
            let p = pixel(q, log_target[q]);
            let candidate = match (ax, ay) {
                (Some(x), Some(y)) => {
                    let (first, second, first_is_x) = if x.value <= y.value {
                        (x, y, true)
                    } else {
                        (y, x, false)
                    };
                    let one = if first_is_x {
                        local_root::<LAMBERT>(&p, f2, material, first.value, Some(first), None)
                    } else {
                        local_root::<LAMBERT>(&p, f2, material, first.value, None, Some(first))
                    };
                    if one <= second.value {
                        one
                    } else {
                        local_root::<LAMBERT>(&p, f2, material, second.value, Some(x), Some(y))
                    }
                }
                (Some(x), None) => local_root::<LAMBERT>(&p, f2, material, x.value, Some(x), None),
                (None, Some(y)) => local_root::<LAMBERT>(&p, f2, material, y.value, None, Some(y)),
                (None, None) => continue,
            };
            if candidate.is_finite() && candidate < value[q] {
                value[q] = candidate;
                heap.push(Trial {
                    value: candidate,
                    index: q,
                });
            }
        }
    }
    // Freeing these pages takes tens of milliseconds at 18 MP: on the pool.
    rayon::spawn(move || drop((heap, frontal, accepted, log_target)));

    let depth_at = |q: usize| geometry.ray(q % w, q / w).q() * value[q].exp();
    let reached = |q: usize| inside[q] && value[q].is_finite();
    // Row sums in parallel, added in row order (deterministic).
    let row_sums: Vec<(f64, usize)> = (0..h)
        .into_par_iter()
        .map(|r| {
            (r * w..(r + 1) * w)
                .filter(|&q| reached(q))
                .fold((0.0, 0), |(sum, count), q| (sum + depth_at(q), count + 1))
        })
        .collect();
    cancel.check()?;
    let (sum, count) = row_sums
        .iter()
        .fold((0.0, 0usize), |a, b| (a.0 + b.0, a.1 + b.1));
    let mean = sum / count.max(1) as f64;
    let mut solved = vec![0.0; w * h];
    fill_rows(&mut solved, w, cancel, |q| {
        if reached(q) { depth_at(q) } else { mean }
    })?;
    let solved = Grid::from_vec(w, h, solved)
        .ok_or_else(|| SolveError::Input("fast marching: the depth has the image's size".into()))?;
    Ok((solved, mean))
}

/// Sets `out[q] = value(q)` for every pixel of a `w`-wide image, rows in
/// parallel, polling `cancel` per row.
fn fill_rows<T: Send>(
    out: &mut [T],
    w: usize,
    cancel: Cancel<'_>,
    value: impl Fn(usize) -> T + Sync,
) -> Result<(), Cancelled> {
    crate::grid::for_rows(out, w, cancel, |r, row| {
        for (c, v) in row.iter_mut().enumerate() {
            *v = value(r * w + c);
        }
    })
}

/// The frontal values of the domain pixels in increasing order (ties by
/// index: the heap's order), without sorting them all up front: they are
/// counted into buckets of equal width in value (a monotone map, so the
/// buckets are in order), and each bucket is sorted when the queue reaches
/// it, inside the march (which polls cancellation), not in one long pass.
struct FrontalQueue {
    /// The trials, bucket after bucket.
    trials: Vec<Trial>,
    /// Where each bucket starts in `trials` (and the end, last).
    starts: Vec<usize>,
    /// The next trial to give.
    next: usize,
    /// `trials[..sorted_until]` is sorted; the current bucket ends there.
    sorted_until: usize,
    /// The bucket after the sorted ones.
    bucket: usize,
}

impl FrontalQueue {
    /// Trials per bucket on average.
    const PER_BUCKET: usize = 64;

    /// The queue of `value[q]` over the pixels `inside`, in rows of `w`.
    fn new(
        value: &[f64],
        inside: &[bool],
        w: usize,
        cancel: Cancel<'_>,
    ) -> Result<Self, Cancelled> {
        // By rows, polled (one pass over 18 MP is tens of milliseconds).
        let (low, high, count) = value
            .par_chunks(w.max(1))
            .zip(inside.par_chunks(w.max(1)))
            .map(|(value, inside)| {
                let mut range = (f64::INFINITY, f64::NEG_INFINITY, 0usize);
                if cancel.is_cancelled() {
                    return range;
                }
                for (&v, _) in value.iter().zip(inside).filter(|(_, inside)| **inside) {
                    range = (range.0.min(v), range.1.max(v), range.2 + 1);
                }
                range
            })
            .reduce(
                || (f64::INFINITY, f64::NEG_INFINITY, 0),
                |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2),
            );
        cancel.check()?;
        let buckets = (count / Self::PER_BUCKET).max(1);
        let scale = if high > low {
            (buckets - 1) as f64 / (high - low)
        } else {
            0.0
        };
        let bucket_of = |v: f64| (((v - low) * scale) as usize).min(buckets - 1);
        let rows = inside.chunks(w.max(1)).zip(value.chunks(w.max(1)));
        let mut starts = vec![0usize; buckets + 1];
        for (r, (inside, value)) in rows.clone().enumerate() {
            if r % 64 == 0 {
                cancel.check()?;
            }
            for (&inside, &v) in inside.iter().zip(value) {
                if inside {
                    starts[bucket_of(v) + 1] += 1;
                }
            }
        }
        for b in 0..buckets {
            starts[b + 1] += starts[b];
        }
        let mut fill = starts.clone();
        // Zeroed by the allocator, its pages first touched by the polled
        // rows below (a sequential fill would not poll).
        let mut trials: Vec<Trial> = bytemuck::zeroed_vec(count);
        for (r, (inside, value)) in rows.enumerate() {
            cancel.check()?;
            for (c, (&inside, &v)) in inside.iter().zip(value).enumerate() {
                if inside {
                    let slot = &mut fill[bucket_of(v)];
                    trials[*slot] = Trial {
                        value: v,
                        index: r * w + c,
                    };
                    *slot += 1;
                }
            }
        }
        Ok(Self {
            trials,
            starts,
            next: 0,
            sorted_until: 0,
            bucket: 0,
        })
    }

    /// Sorts the next non-empty bucket once the sorted ones are used up.
    fn sort_ahead(&mut self) {
        while self.next == self.sorted_until && self.bucket + 1 < self.starts.len() {
            let (start, end) = (self.starts[self.bucket], self.starts[self.bucket + 1]);
            // `Trial`'s order is reversed (the heap's greatest is the
            // smallest value): descending order gives the smallest first.
            self.trials[start..end].sort_unstable_by(|a, b| b.cmp(a));
            self.sorted_until = end;
            self.bucket += 1;
        }
    }

    /// The smallest trial left.
    fn peek(&mut self) -> Option<&Trial> {
        self.sort_ahead();
        self.trials.get(self.next)
    }

    /// Takes the smallest trial left.
    fn next(&mut self) -> Option<Trial> {
        self.sort_ahead();
        let trial = self.trials.get(self.next).copied();
        self.next += usize::from(trial.is_some());
        trial
    }
}

/// Heap operations between two polls of `cancel` (a few milliseconds).
const CANCEL_POLL: usize = 4096;

/// Solves `problem` by fast marching on its object pixels. The confidence is
/// ignored (the method has no use for it).
pub fn solve_fast_marching(
    problem: &Problem,
    settings: &FastMarchingParams,
    observer: &mut dyn SolveObserver,
) -> Result<Solution, SolveError> {
    let start = Instant::now();
    crate::memory::return_large_frees_to_the_system();
    if !(settings.min_relative_intensity > 0.0 && settings.min_relative_intensity < 1.0) {
        return Err(SolveError::Input(
            "fast marching: min_relative_intensity must lie in (0, 1)".into(),
        ));
    }
    let (domain, confidence) = problem.validate(DomainMode::Object, None, Cancel::NEVER)?;
    let scales = problem.scales(&confidence, Cancel::NEVER).uncancelled();
    let (w, h) = problem.image.size();
    let geometry = LevelGeometry::new(w, h, w, h, problem.camera);
    if !problem.light_is_centred() {
        return Err(SolveError::Input(
            "fast marching models lights at the optical centre only (the paper's set-up); \
             these lights are off the centre: use the linearised or the explicit method"
                .into(),
        ));
    }
    if !settings.material.centred_is_monotone() {
        return Err(SolveError::Input(format!(
            "fast marching needs a brightness that grows as the surface turns to the light; \
             {} does not (Oren-Nayar roughness above about 0.61 rad): use the linearised \
             or the explicit method",
            settings.material.describe()
        )));
    }
    let model = problem.model(settings.material);
    let s = problem.centred_scale();
    let (solved, mean) = march(
        &problem.image,
        problem.camera,
        &domain,
        s,
        settings,
        Cancel::new(&|| observer.is_cancelled()),
    )?;
    let reprojection =
        model::reproject(&model, &geometry, &domain, &solved, Cancel::NEVER).uncancelled();
    let ones = Grid::filled(w, h, 1.0);
    let energy = model::energy(
        &model,
        &geometry,
        &problem.image,
        problem.confidence.as_ref().unwrap_or(&ones),
        &domain,
        &solved,
        0.0,
        1e-3,
        Cancel::NEVER,
    )
    .uncancelled();
    let depth = masked(&solved, &domain, Cancel::NEVER).uncancelled();
    let elapsed = start.elapsed();
    observer.on_iteration(&IterationReport {
        level: 0,
        levels: 1,
        width: w,
        height: h,
        iteration: 0,
        energy,
        max_step: 0.0,
        elapsed,
    });
    observer.on_level(&LevelResult {
        level: 0,
        levels: 1,
        depth: std::sync::Arc::new(depth.clone()),
        reprojection: std::sync::Arc::new(reprojection.clone()),
        geometry,
        domain_pixels: domain.as_slice().iter().filter(|&&d| d).count(),
        energy,
        elapsed,
    });
    Solution {
        depth,
        reprojection,
        initial_energy: energy,
        final_energy: energy,
        levels: vec![LevelReport {
            width: w,
            height: h,
            energies: vec![energy.total],
            seconds: elapsed.as_secs_f64(),
        }],
        phases: PhaseTimes::default(),
        initial_depth: mean,
        seconds: start.elapsed().as_secs_f64(),
        iterations: 1,
        budget_exhausted: false,
        shadow: None,
        alpha: f64::NAN,
        alpha_px: f64::NAN,
        lambda_px: f64::NAN,
        scales,
        material: settings.material,
        material_fit: None,
        albedo_fit: None,
        start_denoised: None,
        noise: None,
        unused_parameters: Vec::new(),
    }
    .checked()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;

    /// An exact image of the surface `depth` (NaN off the object) with unit
    /// normals `normal(P)` facing the camera: `I = s (N . L) / |P|^2`.
    fn render(
        w: usize,
        h: usize,
        camera: Intrinsics,
        depth: impl Fn(f64, f64) -> Option<f64>,
        normal: impl Fn([f64; 3]) -> [f64; 3],
    ) -> (Problem, Grid<f64>) {
        let mut image = Grid::filled(w, h, 0.0);
        let mut truth = Grid::filled(w, h, f64::NAN);
        let mut mask = Grid::filled(w, h, false);
        for r in 0..h {
            for c in 0..w {
                let (x, y) = camera.image_xy(c as f64, r as f64);
                if let Some(z) = depth(x, y) {
                    let p = camera.back_project(x, y, z);
                    let n = normal(p);
                    let d2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
                    let l = p.map(|v| -v / d2.sqrt());
                    let cos = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
                    *image.at_mut(c, r) = cos.max(0.0) / d2;
                    *truth.at_mut(c, r) = z;
                    *mask.at_mut(c, r) = true;
                }
            }
        }
        let problem = Problem {
            image,
            camera,
            intensity_scale: 1.0,
            object_mask: Some(mask),
            confidence: None,
            lights: Vec::new(),
        };
        (problem, truth)
    }

    fn rse(problem: &Problem, truth: &Grid<f64>) -> f64 {
        let solution = solve_fast_marching(problem, &FastMarchingParams::default(), &mut ())
            .expect("fast marching solves an exact image");
        assert!(
            solution
                .depth
                .as_slice()
                .iter()
                .zip(truth.as_slice())
                .all(|(z, t)| t.is_nan() || z.is_finite()),
            "every object pixel gets a finite depth"
        );
        crate::metrics::rse(&solution.depth, truth).expect("sizes match")
    }

    #[test]
    fn recovers_a_tilted_plane() {
        // Plane n . P = d, its foot point (singular) inside the image.
        let (w, h) = (128, 96);
        let camera = Intrinsics::centred(120.0, w, h);
        let n = {
            let v = [0.15, -0.1, -1.0];
            let len: f64 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
            v.map(|x: f64| x / len.sqrt())
        };
        let d = -1.5; // n . P = d with n_z < 0: the plane faces the camera
        let f = camera.focal_px;
        let (problem, truth) = render(
            w,
            h,
            camera,
            |x, y| Some(d / (n[0] * x / f + n[1] * y / f + n[2])),
            |_| n,
        );
        let error = rse(&problem, &truth);
        eprintln!("plane RSE {error}");
        assert!(error < 2e-3, "plane RSE {error}");
    }

    /// RSE of fast marching on a sphere cap seen at `n` x `n` pixels (90
    /// degrees field of view).
    fn sphere_cap_rse(n: usize) -> f64 {
        let camera = Intrinsics::centred(n as f64, n, n);
        let (centre_z, radius) = (3.0, 1.0);
        let f = camera.focal_px;
        let hit = move |x: f64, y: f64| {
            // Ray direction u = (x, y, f)/|.|; nearest intersection with the sphere.
            let len = (x * x + y * y + f * f).sqrt();
            let uz = f / len;
            let b = uz * centre_z;
            let disc = b * b - centre_z * centre_z + radius * radius;
            // Keep a margin from the silhouette, where the cap turns away.
            (disc > 0.2 * radius * radius).then(|| (b - disc.sqrt()) * uz)
        };
        let (problem, truth) = render(n, n, camera, hit, |p| {
            [p[0] / radius, p[1] / radius, (p[2] - centre_z) / radius]
        });
        rse(&problem, &truth)
    }

    #[test]
    fn recovers_a_sphere_cap_to_first_order() {
        // Upwind differences are first order: the error of the curved cap
        // halves with the pixel size.
        let (coarse, fine) = (sphere_cap_rse(64), sphere_cap_rse(128));
        eprintln!("sphere cap RSE {coarse} at 64 px, {fine} at 128 px");
        assert!(fine < 4e-3, "sphere cap RSE {fine} at 128 px");
        assert!(
            fine < 0.6 * coarse,
            "RSE {coarse} at 64 px, {fine} at 128 px"
        );
    }

    #[test]
    fn noise_makes_false_singular_points() {
        // The method's known weakness: on a noisy plane the error grows by
        // orders of magnitude.
        let (w, h) = (64, 48);
        let camera = Intrinsics::centred(60.0, w, h);
        let f = camera.focal_px;
        let (clean, truth) = render(
            w,
            h,
            camera,
            |x, _| Some(1.5 / (1.0 - 0.1 * x / f)),
            |_| {
                let len = (1.0f64 + 0.01).sqrt();
                [0.1 / len, 0.0, -1.0 / len]
            },
        );
        let noisy = Problem {
            image: crate::scene::add_noise(&clean.image, 20.0, 3),
            ..clean.clone()
        };
        let (a, b) = (rse(&clean, &truth), rse(&noisy, &truth));
        eprintln!("noisy plane RSE {b}, clean {a}");
        assert!(b > 5.0 * a, "clean {a} noisy {b}");
    }
}
