//! The linear system of one photometric-stereo step in the log-depth
//! `zeta`: the data part as a symmetric 9-point stencil assembled from each
//! pixel's quadratic form in the gradient (averaged over the four
//! forward/backward difference pairs, so no checkerboard escapes it), the
//! second-order smoothness applied without a matrix (its lagged Charbonnier
//! weights per pixel), a small proximal term that makes it definite, its
//! rows as 5x5 stencils, and conjugate gradients over the domain
//! preconditioned by a multigrid V-cycle of those rows
//! (`solver::multigrid::RowsCycle`).

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};
use crate::linalg::cg;
use crate::solver::multigrid::RowsCycle;

/// One pixel's quadratic form in `v = (zeta_x, zeta_y, zeta)`:
/// `v^T T v - 2 v^T h` (the linearised data term).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct GradientForm {
    /// `T` (symmetric): `[xx, xy, xz, yy, yz, zz]`.
    pub t: [f64; 6],
    /// `h`.
    pub h: [f64; 3],
    /// The weight of each valid difference pair (in [`valid_pairs`]'s
    /// order, summing to 1; all 0: equal weights).
    pub pair_weights: [f64; 4],
}

impl GradientForm {
    /// `T[i][k]`.
    #[inline]
    pub fn at(&self, i: usize, k: usize) -> f64 {
        const INDEX: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
        self.t[INDEX[i][k]]
    }

    /// Adds `weight c c^T` to `T` and `weight c target` to `h`.
    #[inline]
    pub fn add(&mut self, c: [f64; 3], weight: f64, target: f64) {
        self.t[0] += weight * c[0] * c[0];
        self.t[1] += weight * c[0] * c[1];
        self.t[2] += weight * c[0] * c[2];
        self.t[3] += weight * c[1] * c[1];
        self.t[4] += weight * c[1] * c[2];
        self.t[5] += weight * c[2] * c[2];
        for (h, c) in self.h.iter_mut().zip(c) {
            *h += weight * c * target;
        }
    }
}

/// The symmetric 9-point data stencil: per pixel its diagonal and its
/// couplings to the east, south, south-east and south-west neighbours.
pub(super) struct Stencil {
    width: usize,
    centre: Vec<f64>,
    east: Vec<f64>,
    south: Vec<f64>,
    south_east: Vec<f64>,
    south_west: Vec<f64>,
    /// The right-hand side.
    pub rhs: Vec<f64>,
}

/// The difference pairs `(sx, sy)` valid at pixel `p` of a `width` x
/// `height` domain: each neighbour inside the image and the domain.
#[inline]
pub(super) fn valid_pairs(domain: &[bool], width: usize, p: usize) -> ([(isize, isize); 4], usize) {
    let (c, r) = (p % width, p / width);
    let height = domain.len() / width;
    let xs = [
        (c + 1 < width && domain[p + 1]).then_some(1isize),
        (c > 0 && domain[p - 1]).then_some(-1isize),
    ];
    let ys = [
        (r + 1 < height && domain[p + width]).then_some(1isize),
        (r > 0 && domain[p - width]).then_some(-1isize),
    ];
    let mut out = [(0, 0); 4];
    let mut n = 0;
    for sx in xs.into_iter().flatten() {
        for sy in ys.into_iter().flatten() {
            out[n] = (sx, sy);
            n += 1;
        }
    }
    (out, n)
}

/// The gradient of `zeta` at `p` averaged over its valid difference pairs
/// (a central difference where both neighbours are in the domain, one-sided
/// where only one is, 0 where none is).
#[inline]
pub(super) fn gradient(zeta: &[f64], domain: &[bool], width: usize, p: usize) -> [f64; 2] {
    let (c, r) = (p % width, p / width);
    let height = domain.len() / width;
    let one_axis = |plus: bool, minus: bool, step: usize| match (plus, minus) {
        (true, true) => 0.5 * (zeta[p + step] - zeta[p - step]),
        (true, false) => zeta[p + step] - zeta[p],
        (false, true) => zeta[p] - zeta[p - step],
        (false, false) => 0.0,
    };
    [
        one_axis(c + 1 < width && domain[p + 1], c > 0 && domain[p - 1], 1),
        one_axis(
            r + 1 < height && domain[p + width],
            r > 0 && domain[p - width],
            width,
        ),
    ]
}

impl Stencil {
    /// Assembles the data part from each domain pixel's form: the form
    /// averaged over the pixel's valid difference pairs. Sequential (a
    /// scatter), about 20 ns a pixel.
    pub fn assemble(forms: &[GradientForm], domain: &[bool], width: usize) -> Self {
        let n = forms.len();
        let mut s = Stencil {
            width,
            centre: vec![0.0; n],
            east: vec![0.0; n],
            south: vec![0.0; n],
            south_east: vec![0.0; n],
            south_west: vec![0.0; n],
            rhs: vec![0.0; n],
        };
        let w = width as isize;
        for (x, form) in forms.iter().enumerate() {
            if !domain[x] {
                continue;
            }
            let (pairs, count) = valid_pairs(domain, width, x);
            if count == 0 {
                continue;
            }
            let equal = form.pair_weights[..count].iter().all(|&w| w == 0.0);
            for (index, &(sx, sy)) in pairs[..count].iter().enumerate() {
                let k = if equal {
                    1.0 / count as f64
                } else {
                    form.pair_weights[index]
                };
                let a = (x as isize + sx) as usize;
                let b = (x as isize + sy * w) as usize;
                let (fx, fy) = (sx as f64, sy as f64);
                // The functionals zeta_x, zeta_y, zeta over (x, a, b).
                let e = [[-fx, fx, 0.0], [-fy, 0.0, fy], [1.0, 0.0, 0.0]];
                let mut local = [[0.0; 3]; 3];
                let mut rhs = [0.0; 3];
                for i in 0..3 {
                    for kk in 0..3 {
                        let t = form.at(i, kk);
                        if t == 0.0 {
                            continue;
                        }
                        for (row, &ei) in local.iter_mut().zip(&e[i]) {
                            for (cell, &ek) in row.iter_mut().zip(&e[kk]) {
                                *cell += t * ei * ek;
                            }
                        }
                    }
                    for (r, &ei) in rhs.iter_mut().zip(&e[i]) {
                        *r += form.h[i] * ei;
                    }
                }
                s.centre[x] += k * local[0][0];
                s.centre[a] += k * local[1][1];
                s.centre[b] += k * local[2][2];
                s.add_horizontal(x, a, k * local[0][1]);
                s.add_vertical(x, b, k * local[0][2]);
                s.add_diagonal(a, b, k * local[1][2]);
                s.rhs[x] += k * rhs[0];
                s.rhs[a] += k * rhs[1];
                s.rhs[b] += k * rhs[2];
            }
        }
        s
    }

    fn add_horizontal(&mut self, p: usize, q: usize, value: f64) {
        self.east[p.min(q)] += value;
    }

    fn add_vertical(&mut self, p: usize, q: usize, value: f64) {
        self.south[p.min(q)] += value;
    }

    fn add_diagonal(&mut self, p: usize, q: usize, value: f64) {
        let (lo, hi) = (p.min(q), p.max(q));
        if hi == lo + self.width + 1 {
            self.south_east[lo] += value;
        } else {
            self.south_west[lo] += value;
        }
    }

    /// `y[p] = (A v)[p]` for the data part at one pixel.
    #[inline]
    fn apply_at(&self, v: &[f64], p: usize) -> f64 {
        let w = self.width;
        let n = v.len();
        let mut y = self.centre[p] * v[p];
        if p + 1 < n {
            y += self.east[p] * v[p + 1];
        }
        if p >= 1 {
            y += self.east[p - 1] * v[p - 1];
        }
        if p + w < n {
            y += self.south[p] * v[p + w];
        }
        if p >= w {
            y += self.south[p - w] * v[p - w];
        }
        if p + w + 1 < n {
            y += self.south_east[p] * v[p + w + 1];
        }
        if p > w {
            y += self.south_east[p - w - 1] * v[p - w - 1];
        }
        if p + w >= 1 && p + w - 1 < n {
            y += self.south_west[p] * v[p + w - 1];
        }
        if p + 1 >= w && p + 1 - w < n {
            y += self.south_west[p + 1 - w] * v[p + 1 - w];
        }
        y
    }
}

/// The second-order smoothness `alpha sum_x k(x) (zeta_xx^2 + 2 zeta_xy^2 +
/// zeta_yy^2)` with a weight per pixel (`alpha f^4` times the lagged
/// Charbonnier derivative; 0 where no second difference fits the domain).
pub(super) struct Smoothness {
    /// Weight of `zeta_xx^2` per pixel (0 where `x - 1` or `x + 1` is out).
    pub kxx: Vec<f64>,
    /// Weight of `2 zeta_xy^2` per pixel (0 where a diagonal is out).
    pub kxy: Vec<f64>,
    /// Weight of `zeta_yy^2` per pixel.
    pub kyy: Vec<f64>,
}

/// Which second differences fit the domain at `p`: `(xx, xy, yy)`.
#[inline]
pub(super) fn second_valid(domain: &[bool], width: usize, p: usize) -> (bool, bool, bool) {
    let (c, r) = (p % width, p / width);
    let height = domain.len() / width;
    let inside_x = c >= 1 && c + 1 < width;
    let inside_y = r >= 1 && r + 1 < height;
    let xx = inside_x && domain[p - 1] && domain[p + 1];
    let yy = inside_y && domain[p - width] && domain[p + width];
    let xy = inside_x
        && inside_y
        && domain[p - width - 1]
        && domain[p - width + 1]
        && domain[p + width - 1]
        && domain[p + width + 1];
    (xx, xy, yy)
}

/// `(zeta_xx, zeta_xy, zeta_yy)` at `p` (0 where not valid).
#[inline]
pub(super) fn second_derivatives(
    zeta: &[f64],
    domain: &[bool],
    width: usize,
    p: usize,
) -> [f64; 3] {
    if !domain[p] {
        return [0.0; 3];
    }
    let (xx, xy, yy) = second_valid(domain, width, p);
    let w = width;
    [
        if xx {
            zeta[p - 1] - 2.0 * zeta[p] + zeta[p + 1]
        } else {
            0.0
        },
        if xy {
            0.25 * (zeta[p + w + 1] - zeta[p + w - 1] - zeta[p - w + 1] + zeta[p - w - 1])
        } else {
            0.0
        },
        if yy {
            zeta[p - w] - 2.0 * zeta[p] + zeta[p + w]
        } else {
            0.0
        },
    ]
}

/// The whole operator: data stencil, smoothness and the proximal weight
/// `tau` (times the identity) on the domain.
pub(super) struct Operator<'a> {
    pub stencil: &'a Stencil,
    pub smoothness: &'a Smoothness,
    pub tau: f64,
    pub domain: &'a [bool],
    pub width: usize,
}

impl Operator<'_> {
    /// `y = A v` on the domain (0 elsewhere); rows in parallel.
    fn apply(&self, v: &[f64], scratch: &mut [[f64; 3]], y: &mut [f64]) {
        let w = self.width;
        let domain = self.domain;
        let s = self.smoothness;
        // Weighted second differences of v.
        let rows = (4096 / w).max(1);
        scratch
            .par_chunks_mut(w)
            .with_min_len(rows)
            .enumerate()
            .for_each(|(r, row)| {
                for (c, out) in row.iter_mut().enumerate() {
                    let p = r * w + c;
                    // A weight is 0 exactly where its difference does not
                    // fit the domain (or alpha is 0): no neighbour is read
                    // there, and every neighbour exists where it fits.
                    let (kxx, kxy, kyy) = (s.kxx[p], s.kxy[p], s.kyy[p]);
                    *out = [
                        if kxx == 0.0 {
                            0.0
                        } else {
                            kxx * (v[p - 1] - 2.0 * v[p] + v[p + 1])
                        },
                        if kxy == 0.0 {
                            0.0
                        } else {
                            2.0 * kxy
                                * (0.25
                                    * (v[p + w + 1] - v[p + w - 1] - v[p - w + 1] + v[p - w - 1]))
                        },
                        if kyy == 0.0 {
                            0.0
                        } else {
                            kyy * (v[p - w] - 2.0 * v[p] + v[p + w])
                        },
                    ];
                }
            });
        let scratch = &*scratch;
        let n = v.len();
        y.par_chunks_mut(w)
            .with_min_len(rows)
            .enumerate()
            .for_each(|(r, row)| {
                for (c, out) in row.iter_mut().enumerate() {
                    let p = r * w + c;
                    if !domain[p] {
                        *out = 0.0;
                        continue;
                    }
                    let mut value = self.stencil.apply_at(v, p) + self.tau * v[p];
                    // Transposes of the second differences: away from the
                    // first and last rows every neighbour is in the image.
                    if p > w && p + w + 1 < n {
                        let t = |q: usize, k: usize| scratch[q][k];
                        value += t(p - 1, 0) - 2.0 * t(p, 0) + t(p + 1, 0);
                        value += t(p - w, 2) - 2.0 * t(p, 2) + t(p + w, 2);
                        value += 0.25
                            * (t(p - w - 1, 1) - t(p - w + 1, 1) - t(p + w - 1, 1)
                                + t(p + w + 1, 1));
                        *out = value;
                        continue;
                    }
                    let get = |q: Option<usize>, k: usize| {
                        q.filter(|&q| q < n).map_or(0.0, |q| scratch[q][k])
                    };
                    value += get(p.checked_sub(1), 0) - 2.0 * scratch[p][0] + get(Some(p + 1), 0);
                    value += get(p.checked_sub(w), 2) - 2.0 * scratch[p][2] + get(Some(p + w), 2);
                    let up = p.checked_sub(w);
                    value += 0.25
                        * (get(up.and_then(|u| u.checked_sub(1)), 1)
                            - get(up.map(|u| u + 1), 1)
                            - get(Some(p + w - 1).filter(|_| p + w >= 1), 1)
                            + get(Some(p + w + 1), 1));
                    *out = value;
                }
            });
    }

    /// The row of pixel `(column, row)` as a 5x5 stencil (row-major,
    /// centre 12; f32, for the preconditioner), `None` outside the domain:
    /// the data stencil, `tau` and each second difference's `D^T k D` that
    /// reaches the pixel.
    fn row(&self, column: usize, row: usize) -> Option<[f32; 25]> {
        /// A tap `(dx, dy, coefficient)` of a second difference.
        type Tap = (isize, isize, f64);
        /// The taps of the three second differences.
        const XX: [Tap; 3] = [(-1, 0, 1.0), (0, 0, -2.0), (1, 0, 1.0)];
        const YY: [Tap; 3] = [(0, -1, 1.0), (0, 0, -2.0), (0, 1, 1.0)];
        const XY: [Tap; 4] = [(1, 1, 0.25), (-1, 1, -0.25), (1, -1, -0.25), (-1, -1, 0.25)];
        let w = self.width;
        let h = self.domain.len() / w;
        let p = row * w + column;
        if !self.domain[p] {
            return None;
        }
        let mut a = [0.0f64; 25];
        let at = |dx: isize, dy: isize| (12 + 5 * dy + dx) as usize;
        let s = self.stencil;
        a[12] = s.centre[p] + self.tau;
        if column + 1 < w {
            a[at(1, 0)] += s.east[p];
        }
        if column >= 1 {
            a[at(-1, 0)] += s.east[p - 1];
        }
        if row + 1 < h {
            a[at(0, 1)] += s.south[p];
            if column + 1 < w {
                a[at(1, 1)] += s.south_east[p];
            }
            if column >= 1 {
                a[at(-1, 1)] += s.south_west[p];
            }
        }
        if row >= 1 {
            a[at(0, -1)] += s.south[p - w];
            if column >= 1 {
                a[at(-1, -1)] += s.south_east[p - w - 1];
            }
            if column + 1 < w {
                a[at(1, -1)] += s.south_west[p + 1 - w];
            }
        }
        // The second differences centred on the neighbours q = p + (ox, oy)
        // whose taps hold p: each adds k_q d_q(p) d_q(j) at j - p.
        let k = self.smoothness;
        for oy in -1isize..=1 {
            for ox in -1isize..=1 {
                let (qc, qr) = (column as isize + ox, row as isize + oy);
                if qc < 0 || qr < 0 || qc >= w as isize || qr >= h as isize {
                    continue;
                }
                let q = qr as usize * w + qc as usize;
                let terms: [(&[Tap], f64); 3] =
                    [(&XX, k.kxx[q]), (&YY, k.kyy[q]), (&XY, 2.0 * k.kxy[q])];
                for (taps, weight) in terms {
                    if weight == 0.0 {
                        continue;
                    }
                    // p's own tap in q's difference: at offset (-ox, -oy).
                    let Some(&(_, _, own)) = taps.iter().find(|t| t.0 == -ox && t.1 == -oy) else {
                        continue;
                    };
                    for &(tx, ty, coefficient) in taps {
                        a[at(ox + tx, oy + ty)] += weight * own * coefficient;
                    }
                }
            }
        }
        let mut out = [0.0f32; 25];
        for (o, v) in out.iter_mut().zip(a) {
            *o = v as f32;
        }
        Some(out)
    }
}

/// Dot products summed in fixed chunks in a fixed order: the same bits on
/// every run, whatever the threads do.
const SUMMATION: cg::Summation = cg::Summation::Chunked(8192);

/// Gauss-Seidel sweeps before and after each coarse correction of the
/// preconditioner's cycle: on the face's seven photographs at 1296 px, 1
/// sweep needs 20-26 iterations to 1e-3, 2 sweeps 11-14 (the least time),
/// 3-4 sweeps 7-11 at no less time.
const CYCLE_SWEEPS: usize = 2;

/// Solves `A x = b` by conjugate gradients preconditioned with one
/// multigrid V-cycle of `A`'s rows ([`RowsCycle`]), from `x` (warm start)
/// until the residual falls below `tolerance` times the initial one or
/// `max_iterations` pass; polls `cancel` every iteration. Returns the
/// iterations run. The routine is [`crate::linalg::cg`]'s in its flexible
/// form (the cycle's Gauss-Seidel is not exactly symmetric). With Jacobi,
/// before, the smooth error of a 1296 px face took hundreds of iterations:
/// capped at 60 (and even at 300) the face's depth stood 6-9 mm from the
/// converged one.
pub(super) fn conjugate_gradients(
    operator: &Operator<'_>,
    b: &[f64],
    x: &mut [f64],
    tolerance: f64,
    max_iterations: usize,
    cancel: Cancel<'_>,
) -> Result<usize, Cancelled> {
    let n = x.len();
    let domain = operator.domain;
    let mut scratch = vec![[0.0; 3]; n];
    let mut ax = vec![0.0; n];
    operator.apply(x, &mut scratch, &mut ax);
    let r: Vec<f64> = (0..n)
        .map(|p| if domain[p] { b[p] - ax[p] } else { 0.0 })
        .collect();
    let height = n / operator.width.max(1);
    let mut cycle = RowsCycle::build(
        operator.width,
        height,
        |c, r| operator.row(c, r),
        CYCLE_SWEEPS,
    );
    let settings = cg::Settings {
        max_iterations,
        summation: SUMMATION,
        stop: cg::Stop::AfterStepRelative {
            norm: cg::Norm::Euclidean,
            tolerance,
        },
        cancel_poll: cg::CancelPoll {
            every: 1,
            before_test: true,
        },
        rz_guard: cg::RzGuard::None,
        beta: cg::Beta::PolakRibiere,
    };
    cg::solve(
        x,
        r,
        |v, out| operator.apply(v, &mut scratch, out),
        |r, z| cycle.apply(r, z),
        &settings,
        cancel,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small domain with a hole, random forms and weights.
    fn setup() -> (usize, Vec<bool>, Vec<GradientForm>, Smoothness) {
        let (w, h) = (7, 6);
        let domain: Vec<bool> = (0..w * h).map(|p| p != 17 && p % w != 0).collect();
        let mut seed = 1u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let forms = (0..w * h)
            .map(|_| {
                let (a, b, c) = (next() + 0.5, next() - 0.5, next() + 0.5);
                let mut form = GradientForm::default();
                form.add([a, b, 0.1 * c], 1.0, next() - 0.5);
                form.add([b, c, 0.2 * a], 0.5, next() - 0.5);
                form.add([0.3, -0.2, 0.5 * b], next(), next() - 0.5);
                form
            })
            .collect();
        // Weights only where the second difference fits, as the solver's.
        let mut weights = |which: usize| -> Vec<f64> {
            (0..w * h)
                .map(|p| {
                    let v = next();
                    let (xx, xy, yy) = second_valid(&domain, w, p);
                    let valid = [xx, xy, yy][which];
                    if domain[p] && valid { v } else { 0.0 }
                })
                .collect()
        };
        let (kxx, kxy, kyy) = (weights(0), weights(1), weights(2));
        let smoothness = Smoothness { kxx, kxy, kyy };
        (w, domain, forms, smoothness)
    }

    /// The energy the operator is the Hessian of (halved): data forms over
    /// the valid pairs, smoothness, proximal term.
    fn energy(
        zeta: &[f64],
        w: usize,
        domain: &[bool],
        forms: &[GradientForm],
        smoothness: &Smoothness,
        tau: f64,
    ) -> f64 {
        let mut e = 0.0;
        for p in 0..zeta.len() {
            if !domain[p] {
                continue;
            }
            let (pairs, count) = valid_pairs(domain, w, p);
            for &(sx, sy) in &pairs[..count] {
                let gx = sx as f64 * (zeta[(p as isize + sx) as usize] - zeta[p]);
                let gy = sy as f64 * (zeta[(p as isize + sy * w as isize) as usize] - zeta[p]);
                let f = forms[p];
                let v = [gx, gy, zeta[p]];
                let mut q = 0.0;
                for i in 0..3 {
                    for k in 0..3 {
                        q += f.at(i, k) * v[i] * v[k];
                    }
                    q -= 2.0 * f.h[i] * v[i];
                }
                e += q / count as f64;
            }
            let [xx, xy, yy] = second_derivatives(zeta, domain, w, p);
            e += smoothness.kxx[p] * xx * xx
                + 2.0 * smoothness.kxy[p] * xy * xy
                + smoothness.kyy[p] * yy * yy;
            e += tau * zeta[p] * zeta[p];
        }
        e
    }

    #[test]
    fn the_operator_is_the_energys_hessian_and_cg_finds_its_minimum() {
        let (w, domain, forms, smoothness) = setup();
        let n = domain.len();
        let stencil = Stencil::assemble(&forms, &domain, w);
        let tau = 1e-3;
        let op = Operator {
            stencil: &stencil,
            smoothness: &smoothness,
            tau,
            domain: &domain,
            width: w,
        };
        // Column by column: A e_q against the energy's second differences.
        let zero = vec![0.0; n];
        let e0 = energy(&zero, w, &domain, &forms, &smoothness, tau);
        let mut scratch = vec![[0.0; 3]; n];
        for q in (0..n).filter(|&q| domain[q]) {
            let mut unit = vec![0.0; n];
            unit[q] = 1.0;
            let mut column = vec![0.0; n];
            op.apply(&unit, &mut scratch, &mut column);
            for p in (0..n).filter(|&p| domain[p]) {
                let mut both = unit.clone();
                both[p] += 1.0;
                let mut only_p = vec![0.0; n];
                only_p[p] = 1.0;
                // E(e_p + e_q) - E(e_p) - E(e_q) + E(0) = 2 A_pq (quadratic part).
                let mixed = energy(&both, w, &domain, &forms, &smoothness, tau)
                    - energy(&only_p, w, &domain, &forms, &smoothness, tau)
                    - energy(&unit, w, &domain, &forms, &smoothness, tau)
                    + e0;
                assert!(
                    (mixed - 2.0 * column[p]).abs() < 1e-9,
                    "A[{p}][{q}]: {} against {}",
                    column[p],
                    0.5 * mixed
                );
            }
        }

        // The right-hand side is minus half the energy's gradient at 0.
        for p in (0..n).filter(|&p| domain[p]) {
            let mut e = vec![0.0; n];
            e[p] = 1e-3;
            let plus = energy(&e, w, &domain, &forms, &smoothness, tau);
            e[p] = -1e-3;
            let minus = energy(&e, w, &domain, &forms, &smoothness, tau);
            let slope = (plus - minus) / 2e-3;
            assert!((slope + 2.0 * stencil.rhs[p]).abs() < 1e-6, "rhs {p}");
        }
        // CG reaches the minimum: the energy's gradient vanishes there.
        let mut x = vec![0.0; n];
        conjugate_gradients(&op, &stencil.rhs, &mut x, 1e-12, 500, Cancel::NEVER).unwrap();
        let mut ax = vec![0.0; n];
        op.apply(&x, &mut scratch, &mut ax);
        for p in (0..n).filter(|&p| domain[p]) {
            assert!((ax[p] - stencil.rhs[p]).abs() < 1e-8, "residual at {p}");
        }
    }

    #[test]
    fn each_row_is_the_operators_row() {
        let (w, domain, forms, smoothness) = setup();
        let n = domain.len();
        let stencil = Stencil::assemble(&forms, &domain, w);
        let op = Operator {
            stencil: &stencil,
            smoothness: &smoothness,
            tau: 1e-3,
            domain: &domain,
            width: w,
        };
        let mut scratch = vec![[0.0; 3]; n];
        for q in 0..n {
            let mut unit = vec![0.0; n];
            unit[q] = 1.0;
            let mut column = vec![0.0; n];
            op.apply(&unit, &mut scratch, &mut column);
            // A is symmetric: column q read along the rows of every p.
            for (p, &operator) in column.iter().enumerate() {
                let (dx, dy) = (
                    (q % w) as isize - (p % w) as isize,
                    (q / w) as isize - (p / w) as isize,
                );
                let seen = match op.row(p % w, p / w) {
                    None => 0.0,
                    Some(_) if dx.abs() > 2 || dy.abs() > 2 => 0.0,
                    Some(row) => f64::from(row[(12 + 5 * dy + dx) as usize]),
                };
                let expected = if domain[q] { operator } else { 0.0 };
                assert!(
                    (seen - expected).abs() <= 1e-5 * (1.0 + expected.abs()),
                    "A[{p}][{q}]: row {seen}, operator {expected}"
                );
            }
        }
    }
}
