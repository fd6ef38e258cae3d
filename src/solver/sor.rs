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

use super::system::{FORWARD, HALO, LinearSystem};

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
struct SharedUnknowns(*mut f64);
// SAFETY: see `sweep_band`; tasks of one colour write disjoint rows and read
// only rows that no task of that colour writes.
unsafe impl Send for SharedUnknowns {}
unsafe impl Sync for SharedUnknowns {}

/// One SOR sweep in band red-black order.
pub fn sweep(system: &mut LinearSystem, omega: f64) {
    let height = system.height;
    let count_all = band_count(height);
    let len = system.dz_padded.len();
    let unknowns = SharedUnknowns(system.dz_padded.as_mut_ptr());
    let sys = &*system;
    let parallel = sys.width * sys.height >= PARALLEL_MIN_PIXELS;
    for colour in 0..2 {
        let run = |b: usize| {
            // SAFETY: `unknowns` points to `len` f64s owned by `system`, which is
            // not otherwise accessed during the sweep. Band `b` writes only its
            // own rows; bands of the same colour are separated by a band of the
            // other colour of at least BAND_ROWS >= 2 rows (the stencil's
            // reach), so no row written by one task is read or written by
            // another running task.
            unsafe { sweep_band(sys, unknowns, len, band_rows(height, b), omega) }
        };
        // Bands colour, colour + 2, ...: no allocation in the sweep.
        let count = (count_all + 1 - colour) / 2;
        if parallel {
            (0..count).into_par_iter().for_each(|k| run(colour + 2 * k));
        } else {
            (0..count).for_each(|k| run(colour + 2 * k));
        }
    }
}

/// Sweeps rows `rows` lexicographically.
///
/// # Safety
/// `unknowns` must point to `len` valid f64s laid out as `system.dz_padded`,
/// and no other thread may write rows within two of `rows` while it runs.
unsafe fn sweep_band(
    system: &LinearSystem,
    unknowns: SharedUnknowns,
    len: usize,
    rows: std::ops::Range<usize>,
    omega: f64,
) {
    let w = system.width;
    let pw = w + 2 * HALO;
    let one_minus_omega = 1.0 - omega;
    let records = &system.rows;
    debug_assert!(len == records.len() && len >= (system.height + 2 * HALO) * pw);
    for r in rows {
        let i0 = (r + HALO) * pw + HALO;
        // SAFETY: rows r-2 ..= r+2 of the padded buffer exist thanks to the
        // halo; column offsets below stay within -2 ..= w+1.
        let (up2, up1, mid, down1, down2) = unsafe {
            let base = unknowns.0.add(i0);
            (
                base.sub(2 * pw),
                base.sub(pw),
                base,
                base.add(pw),
                base.add(2 * pw),
            )
        };
        // The value left of the current pixel, as last written, and its
        // forward (1, 0) coefficient: kept in registers so the sequential
        // dependency is one multiply-subtract.
        // SAFETY: column -1 is inside the halo.
        let mut left = unsafe { *mid.sub(1) };
        let mut left_coupling = records[i0 - 1].forward[0] as f64;
        for c in 0..w {
            let i = i0 + c;
            // SAFETY: i indexes column c of row r of the padded buffer, and
            // `records` has the padded size (checked above in debug builds).
            let row = unsafe { records.get_unchecked(i) };
            if row.inverse_diagonal == 0.0 {
                // Not solved for: its unknown keeps its value (0).
                // SAFETY: column c of this row is inside the buffer.
                left = unsafe { *mid.add(c) };
                left_coupling = row.forward[0] as f64;
                continue;
            }
            let a = &row.forward;
            // Backward couplings, stored with the earlier neighbours.
            // SAFETY: the neighbours are within two rows and columns of i,
            // inside the padded buffer thanks to the halo.
            let back = |dx: isize, dy: isize, k: usize| unsafe {
                records
                    .get_unchecked((i as isize + dx + dy * pw as isize) as usize)
                    .forward[k] as f64
            };
            // SAFETY: every read is at column c-2 ..= c+2 of rows r-2 ..= r+2,
            // inside the padded buffer; only column c of row r is written, by
            // this task alone.
            unsafe {
                let at = |line: *mut f64, dx: isize| *line.offset(c as isize + dx);
                // Forward half, in FORWARD order.
                let f0 = a[0] as f64 * at(mid, 1) + a[1] as f64 * at(mid, 2);
                let f1 = a[2] as f64 * at(down1, -1)
                    + a[3] as f64 * at(down1, 0)
                    + a[4] as f64 * at(down1, 1);
                let f2 = a[5] as f64 * at(down2, -2)
                    + a[6] as f64 * at(down2, 0)
                    + a[7] as f64 * at(down2, 2);
                // Backward half: the coupling to q + o is forward entry -o of q + o.
                let b0 = back(-2, 0, 1) * at(mid, -2);
                let b1 = back(-1, -1, 4) * at(up1, -1)
                    + back(0, -1, 3) * at(up1, 0)
                    + back(1, -1, 2) * at(up1, 1);
                let b2 = back(-2, -2, 7) * at(up2, -2)
                    + back(0, -2, 6) * at(up2, 0)
                    + back(2, -2, 5) * at(up2, 2);
                let independent = (f0 + f1) + (f2 + b0) + (b1 + b2);
                let relaxed_inverse = omega * f64::from(row.inverse_diagonal);
                let old = at(mid, 0);
                // x_new = (1 - omega) x + omega (b - sum) / a_qq
                let base =
                    one_minus_omega * old + relaxed_inverse * (f64::from(row.rhs) - independent);
                let new = base - (relaxed_inverse * left_coupling) * left;
                *mid.add(c) = new;
                left = new;
            }
            left_coupling = a[0] as f64;
        }
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

/// The system as explicit sparse rows over unpadded indices (for tests and
/// debugging). Rows of pixels that are not solved for are empty.
pub fn explicit_rows(system: &LinearSystem) -> Vec<Vec<(usize, f64)>> {
    let (w, h) = (system.width, system.height);
    let record = |c: isize, r: isize| &system.rows[system.padded_index(c as usize, r as usize)];
    let solved = |c: isize, r: isize| {
        c >= 0
            && r >= 0
            && (c as usize) < w
            && (r as usize) < h
            && record(c, r).inverse_diagonal != 0.0
    };
    (0..w * h)
        .map(|q| {
            let (c, r) = ((q % w) as isize, (q / w) as isize);
            if !solved(c, r) {
                return Vec::new();
            }
            let mut row = vec![(q, 1.0 / f64::from(record(c, r).inverse_diagonal))];
            for (k, &(dx, dy)) in FORWARD.iter().enumerate() {
                // Forward coupling stored here, backward one stored there.
                for (cc, rr, a) in [
                    (c + dx, r + dy, record(c, r).forward[k]),
                    (
                        c - dx,
                        r - dy,
                        if solved(c - dx, r - dy) {
                            record(c - dx, r - dy).forward[k]
                        } else {
                            0.0
                        },
                    ),
                ] {
                    if a != 0.0 && solved(cc, rr) {
                        row.push((rr as usize * w + cc as usize, a as f64));
                    }
                }
            }
            row
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::grid::Grid;
    use crate::model::{Derivatives, Lambertian, LevelGeometry};
    use crate::solver::pyramid::PyramidLevel;

    /// A level of `w x h` with a smooth depth and an object mask with holes.
    fn system(w: usize, h: usize) -> LinearSystem {
        let camera = Intrinsics::centred(w as f64, w, h);
        let level = PyramidLevel {
            geometry: LevelGeometry::new(w, h, w, h, camera),
            image: Grid::from_fn(w, h, |c, r| {
                0.3 + 0.05 * ((c * 3 + r * 7) as f64 * 0.1).sin()
            }),
            confidence: Grid::filled(w, h, 1.0),
            domain: Grid::from_fn(w, h, |c, r| (c * 13 + r * 7) % 29 != 0),
        };
        let depth = Grid::from_fn(w, h, |c, r| 2.0 + 0.02 * ((c + 2 * r) as f64 * 0.3).sin());
        let mut system = LinearSystem::new(&level);
        assert!(system.linearise_data(
            &Lambertian {
                intensity_scale: 1.0
            },
            &level,
            &depth,
            Derivatives::Exact
        ));
        system.add_smoothness(&level, 0.05, 1e-3);
        system
    }

    #[test]
    fn fast_sweep_matches_reference_sor_in_the_same_order() {
        // 160 x 120 = 19200 pixels: the parallel path, 15 bands.
        for (w, h) in [(23, 11), (160, 120)] {
            let mut fast = system(w, h);
            let rows = explicit_rows(&fast);
            let rhs: Vec<f64> = (0..w * h)
                .map(|q| f64::from(fast.rows[fast.padded_index(q % w, q / w)].rhs))
                .collect();
            let order: Vec<usize> = sweep_order(h)
                .into_iter()
                .flat_map(|r| r * w..(r + 1) * w)
                .collect();
            let mut x = vec![0.0; w * h];
            for _ in 0..5 {
                sweep(&mut fast, 1.4);
                reference_sweep(&rows, &rhs, &mut x, &order, 1.4);
            }
            let got = fast.dz_grid();
            let scale = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(scale > 0.0);
            for (q, (fast, reference)) in got.as_slice().iter().zip(&x).enumerate() {
                assert!(
                    (fast - reference).abs() <= 1e-9 * scale,
                    "{w}x{h} pixel {q}: fast {fast} reference {reference}"
                );
            }
        }
    }

    #[test]
    fn sweeps_converge_to_the_solution() {
        let (w, h) = (40, 30);
        let mut s = system(w, h);
        let rows = explicit_rows(&s);
        let rhs: Vec<f64> = (0..w * h)
            .map(|q| f64::from(s.rows[s.padded_index(q % w, q / w)].rhs))
            .collect();
        for _ in 0..3000 {
            sweep(&mut s, 1.5);
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
        assert!(residual < 1e-6 * norm, "residual {residual} vs rhs {norm}");
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
