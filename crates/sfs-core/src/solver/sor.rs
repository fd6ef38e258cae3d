//! Successive over-relaxation on the 17-point system of
//! [`super::system::LinearSystem`].
//!
//! The fast solver sweeps in *band red-black order*: the rows are cut into
//! bands of at least [`BAND_ROWS`] rows; all even bands are swept (each
//! lexicographically, in parallel), then all odd bands. The stencil reaches two
//! rows, so bands of one colour never touch each other's unknowns and the
//! result does not depend on the number of threads. [`reference_sweep`] is a
//! plain sequential SOR over an explicit row list in the same order; a test
//! checks the two agree.

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};

use super::system::{HALO, LinearSystem, PLANE_INVERSE_DIAGONAL, PLANE_RHS, PLANES};

/// Rows per band (at least 2, the stencil's reach).
pub const BAND_ROWS: usize = 8;

/// Levels with fewer pixels are swept on one thread (same order).
const PARALLEL_MIN_PIXELS: usize = 16 * 1024;

/// Number of bands of a `height`-row level.
pub fn band_count(height: usize) -> usize {
    (height / BAND_ROWS).max(1)
}

/// Rows of band `band`: `BAND_ROWS` rows each, the remainder joined to the
/// last band so that no band is shorter than the stencil's reach.
pub fn band_rows(height: usize, band: usize) -> std::ops::Range<usize> {
    let start = band * BAND_ROWS;
    let end = if band + 1 == band_count(height) {
        height
    } else {
        start + BAND_ROWS
    };
    start..end
}

/// Row ranges of all bands of a `height`-row level.
pub fn bands(height: usize) -> Vec<std::ops::Range<usize>> {
    (0..band_count(height))
        .map(|b| band_rows(height, b))
        .collect()
}

/// The row order of one band red-black sweep: even bands, then odd bands.
pub fn sweep_order(height: usize) -> Vec<usize> {
    let bands = bands(height);
    let even = bands.iter().step_by(2);
    let odd = bands.iter().skip(1).step_by(2);
    even.chain(odd).flat_map(|b| b.clone()).collect()
}

/// Raw pointer to the unknowns, shared by the band tasks of one colour.
#[derive(Clone, Copy)]
struct SharedUnknowns(*mut f32);
// SAFETY: see `sweep_band`; tasks of one colour write disjoint rows and read
// only rows that no task of that colour writes.
unsafe impl Send for SharedUnknowns {}
unsafe impl Sync for SharedUnknowns {}

/// One SOR sweep in band red-black order.
///
/// Each row is updated in two passes: a vectorisable pass computes, for every
/// pixel, everything that does not depend on the row's own new values (the
/// rows above are final, the row itself and the rows below still hold their
/// old values, exactly what lexicographic SOR reads), then a short sequential
/// pass applies the two couplings to the left neighbours just updated. On
/// x86-64 with AVX2 and FMA (detected at run time) the kernel is compiled for
/// those; the FMA path rounds differently in the last bit, so results are
/// deterministic per machine, not across machines.
///
/// Polls `cancel` before each band and skips the rest of the sweep once it
/// says yes (`Err`: the unknowns are then half-swept).
pub fn sweep(system: &mut LinearSystem, omega: f64, cancel: Cancel<'_>) -> Result<(), Cancelled> {
    let height = system.height;
    let pw = system.padded_width();
    let count_all = band_count(height);
    let len = system.dz_padded.len();
    let unknowns = SharedUnknowns(system.dz_padded.as_mut_ptr());
    let parallel = system.width * system.height >= PARALLEL_MIN_PIXELS;
    let kernel = RowKernel::detect();
    let coefficients = &system.coefficients[..];
    // Three rows of work per band, sized here so the system needs no
    // knowledge of the sweep's band layout.
    let needed = band_count(height) * 3 * pw;
    if system.sweep_scratch.len() < needed {
        // Zeroed by the allocator (fresh pages from the kernel at large
        // sizes): each band's rows are first touched by the task that sweeps
        // it, between polls, not in one pass of tens of megabytes here.
        system.sweep_scratch = vec![0.0; needed];
    }
    let scratch = &mut system.sweep_scratch[..];
    let shape = Shape {
        width: system.width,
        height,
        len,
    };
    let omega = omega as f32;
    for colour in 0..2 {
        let run = |(b, work): (usize, &mut [f32])| {
            if b % 2 != colour || cancel.is_cancelled() {
                return;
            }
            // SAFETY: `unknowns` points to `len` f32s owned by `system`, which is
            // not otherwise accessed during the sweep. Band `b` writes only its
            // own rows; bands of the same colour are separated by a band of the
            // other colour of at least BAND_ROWS >= 2 rows (the stencil's
            // reach), so no row written by one task is read or written by
            // another running task.
            unsafe {
                sweep_band(
                    shape,
                    coefficients,
                    unknowns,
                    band_rows(height, b),
                    omega,
                    kernel,
                    work,
                )
            }
        };
        // Scratch rows are per band, so no allocation in the sweep.
        if parallel {
            scratch
                .par_chunks_mut(3 * pw)
                .take(count_all)
                .enumerate()
                .for_each(run);
        } else {
            scratch
                .chunks_mut(3 * pw)
                .take(count_all)
                .enumerate()
                .for_each(run);
        }
    }
    cancel.check()
}

/// Sizes [`sweep_band`] needs.
#[derive(Clone, Copy)]
struct Shape {
    width: usize,
    height: usize,
    /// Length of the padded unknowns.
    len: usize,
}

/// Which compiled variant of the row kernel runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RowKernel {
    /// Baseline x86-64 / any target.
    Portable,
    /// AVX2 + FMA, chosen at run time when the CPU has both.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
}

impl RowKernel {
    fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return RowKernel::Avx2Fma;
        }
        RowKernel::Portable
    }
}

/// Sweeps rows `rows` lexicographically.
///
/// # Safety
/// `unknowns` must point to `shape.len` valid f32s laid out as
/// `LinearSystem::dz_padded`, and no other thread may access rows within two
/// of `rows` while it runs, nor write any row this task reads.
unsafe fn sweep_band(
    shape: Shape,
    coefficients: &[f32],
    unknowns: SharedUnknowns,
    rows: std::ops::Range<usize>,
    omega: f32,
    kernel: RowKernel,
    work: &mut [f32],
) {
    let w = shape.width;
    let pw = w + 2 * HALO;
    assert!(shape.len >= (shape.height + 2 * HALO) * pw && work.len() >= 3 * pw);
    assert!(coefficients.len() >= shape.len * PLANES);
    for r in rows {
        // Padded row index of image row r.
        let pr = r + HALO;
        // SAFETY: rows pr-2 ..= pr+2 exist thanks to the halo (asserted
        // above); by the caller's contract no other thread writes them now and
        // only row pr is written here, through `mid` alone.
        let (up2, up1, mid, down1, down2) = unsafe {
            let line = |k: usize| unknowns.0.add(k * pw);
            (
                std::slice::from_raw_parts(line(pr - 2), pw),
                std::slice::from_raw_parts(line(pr - 1), pw),
                std::slice::from_raw_parts_mut(line(pr), pw),
                std::slice::from_raw_parts(line(pr + 1), pw),
                std::slice::from_raw_parts(line(pr + 2), pw),
            )
        };
        let block = |k: usize| &coefficients[k * PLANES * pw..(k + 1) * PLANES * pw];
        let rows = RowSlices {
            up2,
            up1,
            down1,
            down2,
            here: block(pr),
            above1: block(pr - 1),
            above2: block(pr - 2),
        };
        match kernel {
            RowKernel::Portable => update_row_portable(&rows, mid, omega, work),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `detect` saw AVX2 and FMA on this CPU.
            RowKernel::Avx2Fma => unsafe { update_row_avx2_fma(&rows, mid, omega, work) },
        }
    }
}

/// What one row update reads besides the row itself.
struct RowSlices<'a> {
    up2: &'a [f32],
    up1: &'a [f32],
    down1: &'a [f32],
    down2: &'a [f32],
    /// Coefficient block of this row and of the two rows above.
    here: &'a [f32],
    above1: &'a [f32],
    above2: &'a [f32],
}

fn update_row_portable(rows: &RowSlices<'_>, mid: &mut [f32], omega: f32, work: &mut [f32]) {
    update_row::<false>(rows, mid, omega, work);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn update_row_avx2_fma(rows: &RowSlices<'_>, mid: &mut [f32], omega: f32, work: &mut [f32]) {
    update_row::<true>(rows, mid, omega, work);
}

/// `a * b + c`, fused where the caller was compiled with FMA.
#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

/// One row of lexicographic SOR (see [`sweep`]).
#[inline(always)]
fn update_row<const FMA: bool>(
    rows: &RowSlices<'_>,
    mid: &mut [f32],
    omega: f32,
    work: &mut [f32],
) {
    let pw = mid.len();
    let n = pw - 2 * HALO;
    fn plane(block: &[f32], pw: usize, n: usize, k: usize, dx: isize) -> &[f32] {
        let start = (k * pw + HALO).wrapping_add_signed(dx);
        &block[start..start + n]
    }
    fn line(values: &[f32], n: usize, dx: isize) -> &[f32] {
        let start = HALO.wrapping_add_signed(dx);
        &values[start..start + n]
    }
    let plane = |block, k, dx| plane(block, pw, n, k, dx);
    let line = |values, dx| line(values, n, dx);
    let (base, rest) = work.split_at_mut(pw);
    let (g1, g2) = rest.split_at_mut(pw);
    let (base, g1, g2) = (&mut base[..n], &mut g1[..n], &mut g2[..n]);
    {
        let old: &[f32] = mid;
        let (x_p1, x_p2) = (line(old, 1), line(old, 2));
        let x_0 = line(old, 0);
        let (d1_m1, d1_0, d1_p1) = (
            line(rows.down1, -1),
            line(rows.down1, 0),
            line(rows.down1, 1),
        );
        let (d2_m2, d2_0, d2_p2) = (
            line(rows.down2, -2),
            line(rows.down2, 0),
            line(rows.down2, 2),
        );
        let (u1_m1, u1_0, u1_p1) = (line(rows.up1, -1), line(rows.up1, 0), line(rows.up1, 1));
        let (u2_m2, u2_0, u2_p2) = (line(rows.up2, -2), line(rows.up2, 0), line(rows.up2, 2));
        let f: [&[f32]; 8] = std::array::from_fn(|k| plane(rows.here, k, 0));
        // Backward couplings: offset -o of this pixel is forward entry o of
        // the pixel at -o (FORWARD order: (-1,1), (0,1), (1,1), (-2,2), (0,2), (2,2)).
        let b2 = plane(rows.above1, 2, 1);
        let b3 = plane(rows.above1, 3, 0);
        let b4 = plane(rows.above1, 4, -1);
        let b5 = plane(rows.above2, 5, 2);
        let b6 = plane(rows.above2, 6, 0);
        let b7 = plane(rows.above2, 7, -2);
        let left1 = plane(rows.here, 0, -1);
        let left2 = plane(rows.here, 1, -2);
        let inverse = plane(rows.here, PLANE_INVERSE_DIAGONAL, 0);
        let rhs = plane(rows.here, PLANE_RHS, 0);
        for c in 0..n {
            let forward_same = madd::<FMA>(f[0][c], x_p1[c], f[1][c] * x_p2[c]);
            let forward_below = madd::<FMA>(
                f[2][c],
                d1_m1[c],
                madd::<FMA>(f[3][c], d1_0[c], f[4][c] * d1_p1[c]),
            );
            let forward_below2 = madd::<FMA>(
                f[5][c],
                d2_m2[c],
                madd::<FMA>(f[6][c], d2_0[c], f[7][c] * d2_p2[c]),
            );
            let backward_above = madd::<FMA>(
                b2[c],
                u1_p1[c],
                madd::<FMA>(b3[c], u1_0[c], b4[c] * u1_m1[c]),
            );
            let backward_above2 = madd::<FMA>(
                b5[c],
                u2_p2[c],
                madd::<FMA>(b6[c], u2_0[c], b7[c] * u2_m2[c]),
            );
            let independent = (forward_same + forward_below)
                + (forward_below2 + backward_above)
                + backward_above2;
            let relaxed_inverse = omega * inverse[c];
            // x_new = (1 - omega) x + omega (b - sum) / a_qq; an unsolved
            // pixel (inverse 0) keeps its value.
            base[c] = if inverse[c] == 0.0 {
                x_0[c]
            } else {
                madd::<FMA>(
                    relaxed_inverse,
                    rhs[c] - independent,
                    (1.0 - omega) * x_0[c],
                )
            };
            g1[c] = relaxed_inverse * left1[c];
            g2[c] = relaxed_inverse * left2[c];
        }
    }
    // Sequential part: the couplings to the two left neighbours, just updated.
    let row = &mut mid[HALO - 2..HALO + n];
    let (mut left2_value, mut left1_value) = (row[0], row[1]);
    for c in 0..n {
        let partial = madd::<FMA>(-g2[c], left2_value, base[c]);
        let new = madd::<FMA>(-g1[c], left1_value, partial);
        row[c + 2] = new;
        left2_value = left1_value;
        left1_value = new;
    }
}

/// Plain sequential SOR sweep over an explicit sparse matrix, visiting rows in
/// `order`: the reference the fast sweep is tested against.
///
/// `rows[i]` lists `(column, value)` of row `i` including the diagonal.
pub fn reference_sweep(
    rows: &[Vec<(usize, f64)>],
    rhs: &[f64],
    x: &mut [f64],
    order: &[usize],
    omega: f64,
) {
    for &i in order {
        let mut diag = 0.0;
        let mut sum = 0.0;
        for &(j, a) in &rows[i] {
            if j == i {
                diag = a;
            } else {
                sum += a * x[j];
            }
        }
        if diag > 0.0 {
            x[i] += omega * ((rhs[i] - sum) / diag - x[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::Uncancelled;
    use crate::solver::system::test_system;

    /// A level of `w x h` with a smooth depth and an object mask with holes.
    fn system(w: usize, h: usize) -> LinearSystem {
        test_system(w, h, |c, r| !(c * 13 + r * 7).is_multiple_of(29), 0.3, 0.05)
    }

    #[test]
    fn fast_sweep_matches_reference_sor_in_the_same_order() {
        // 160 x 120 = 19200 pixels: the parallel path, 15 bands.
        for (w, h) in [(23, 11), (160, 120)] {
            let mut fast = system(w, h);
            let rows = fast.explicit_rows();
            let rhs: Vec<f64> = (0..w * h)
                .map(|q| f64::from(fast.row(q % w, q / w).rhs))
                .collect();
            let order: Vec<usize> = sweep_order(h)
                .into_iter()
                .flat_map(|r| r * w..(r + 1) * w)
                .collect();
            let mut x = vec![0.0; w * h];
            for _ in 0..5 {
                sweep(&mut fast, 1.4, Cancel::NEVER).uncancelled();
                reference_sweep(&rows, &rhs, &mut x, &order, 1.4);
            }
            let got = fast.dz_grid();
            let scale = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(scale > 0.0);
            for (q, (fast, reference)) in got.as_slice().iter().zip(&x).enumerate() {
                // The fast sweep computes in f32 (the reference in f64): a
                // wrong order or coupling differs by ~1e-2 of the scale.
                assert!(
                    (fast - reference).abs() <= 1e-5 * scale,
                    "{w}x{h} pixel {q}: fast {fast} reference {reference}"
                );
            }
        }
    }

    #[test]
    fn sweeps_converge_to_the_solution() {
        let (w, h) = (40, 30);
        let mut s = system(w, h);
        let rows = s.explicit_rows();
        let rhs: Vec<f64> = (0..w * h)
            .map(|q| f64::from(s.row(q % w, q / w).rhs))
            .collect();
        for _ in 0..3000 {
            sweep(&mut s, 1.5, Cancel::NEVER).uncancelled();
        }
        let x = s.dz_grid();
        let residual: f64 = rows
            .iter()
            .enumerate()
            .filter(|(_, row)| !row.is_empty())
            .map(|(i, row)| {
                let ax: f64 = row.iter().map(|&(j, a)| a * x.as_slice()[j]).sum();
                (ax - rhs[i]).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        let norm: f64 = rhs.iter().map(|b| b * b).sum::<f64>().sqrt();
        // f32 unknowns bound the attainable relative residual near 1e-6
        // (measured 1.1e-6); a sweep that does not converge stays near 1.
        assert!(residual < 1e-5 * norm, "residual {residual} vs rhs {norm}");
    }

    #[test]
    fn bands_cover_every_row_once() {
        for h in [1, 2, 7, 8, 15, 16, 17, 33, 250] {
            let mut order = sweep_order(h);
            assert!(bands(h).iter().all(|b| b.len() >= BAND_ROWS.min(h)));
            order.sort();
            assert_eq!(order, (0..h).collect::<Vec<_>>());
        }
    }
}
