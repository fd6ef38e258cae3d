//! One Gauss-Newton step's sparse symmetric linear system
//! `(J^T C J + alpha A(Psi')) dz = -J^T C D - alpha A(Psi') z` on one level,
//! stored as a 17-point stencil per pixel (METHOD.md section 4).
//!
//! The data part `J^T C J`, `-J^T C D` is built once per outer iteration
//! (lagged upwind branches); the smoothness part is added for every inner
//! iteration with the current `Psi'`. Both are assembled by gathering, so rows
//! are built in parallel without write conflicts.

use rayon::prelude::*;

use crate::grid::Grid;
use crate::model::{self, Derivatives, Reflectance};

use super::pyramid::PyramidLevel;

/// Offsets `(dx, dy)` of the 17-point stencil; entry 0 is the pixel itself,
/// entry 1 its left neighbour (the one SOR has just updated), the rest grouped
/// by row so the sweep can address each row with one pointer.
pub const STENCIL: [(isize, isize); 17] = [
    (0, 0),
    (-1, 0),
    (-2, -2),
    (0, -2),
    (2, -2),
    (-1, -1),
    (0, -1),
    (1, -1),
    (-2, 0),
    (1, 0),
    (2, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
    (-2, 2),
    (0, 2),
    (2, 2),
];

/// Position of offset `(dx, dy)` (each in -2..=2) in [`STENCIL`], or `usize::MAX`.
const fn build_lookup() -> [usize; 25] {
    let mut table = [usize::MAX; 25];
    let mut k = 0;
    while k < 17 {
        let (dx, dy) = STENCIL[k];
        table[((dy + 2) * 5 + (dx + 2)) as usize] = k;
        k += 1;
    }
    table
}
const LOOKUP: [usize; 25] = build_lookup();

#[inline]
const fn stencil_index(dx: isize, dy: isize) -> usize {
    LOOKUP[((dy + 2) * 5 + (dx + 2)) as usize]
}

/// Offsets of the 5-point slots `[centre, left, right, up, down]`.
const SLOT_OFFSET: [(isize, isize); 5] = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)];

/// Halo (rows/columns) around the padded vectors so that stencil reads never
/// leave them.
pub const HALO: usize = 2;

/// Bits of the smoothness flags: which second-derivative stencils centred at
/// a pixel lie in the domain.
const HAS_XX: u8 = 1;
const HAS_YY: u8 = 2;
const HAS_XY: u8 = 4;

/// Offsets of the 8 *forward* stencil entries (after the pixel in row-major
/// order). The matrix is symmetric: the coefficient of a backward offset `-o`
/// in row `q` is the forward coefficient `o` stored with the pixel `q - o`.
pub const FORWARD: [(isize, isize); 8] = [
    (1, 0),
    (2, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
    (-2, 2),
    (0, 2),
    (2, 2),
];

/// One row of the full system as the SOR sweep reads it (40 bytes): the
/// diagonal, the right-hand side and the forward half of the off-diagonals.
/// Stored in f32 to halve the memory traffic of the sweeps (memory-bound at
/// 1920x1080); the arithmetic is f64, and the stored rounding changes an
/// update by about 1e-7 relative, far below what a few sweeps resolve.
#[derive(Clone, Copy, Debug, Default)]
pub struct SystemRow {
    /// Forward off-diagonal coefficients: `forward[k]` couples this pixel with
    /// the one at offset `FORWARD[k]`.
    pub forward: [f32; 8],
    /// `1 / diagonal`, or 0 for a pixel that is not solved for (its unknown
    /// stays 0).
    pub inverse_diagonal: f32,
    /// Right-hand side.
    pub rhs: f32,
}

/// The data part of a row, fixed for one outer iteration.
#[derive(Clone, Copy, Debug, Default)]
struct DataRow {
    forward: [f32; 8],
    diagonal: f64,
    rhs: f64,
}

/// The linear system of one level with its work buffers.
pub struct LinearSystem {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Full system rows, padded like `dz_padded` (zero rows in the halo).
    pub rows: Vec<SystemRow>,
    /// Unknowns `dz` with a [`HALO`]-wide border of zeros, row-major with
    /// width `width + 2 HALO`.
    pub dz_padded: Vec<f64>,
    /// Data part (per outer iteration).
    data: Vec<DataRow>,
    /// Residual `D` per pixel at the linearisation point.
    residual: Vec<f64>,
    /// `dD_p/dz_q` for the 5 slots of each pixel.
    jacobian: Vec<[f64; 5]>,
    /// Smoothness stencil flags per pixel (unpadded).
    smooth_flags: Vec<u8>,
    /// `Psi'_p k^2` for the xx, yy and (doubled) xy stencils, one padded
    /// plane each (laid out like `dz_padded`, 0 in the halo and where the
    /// stencil leaves the domain).
    psi_weights: [Vec<f64>; 3],
    /// The linearisation point `z^k`, padded like `dz_padded`.
    z_padded: Vec<f64>,
}

impl LinearSystem {
    /// Allocates the system for a level.
    pub fn new(level: &PyramidLevel) -> Self {
        let (w, h) = level.domain.size();
        let n = w * h;
        let domain = &level.domain;
        let inside = |c: usize, r: usize, dc: isize, dr: isize| {
            let (cc, rr) = (c as isize + dc, r as isize + dr);
            cc >= 0
                && rr >= 0
                && (cc as usize) < w
                && (rr as usize) < h
                && *domain.at(cc as usize, rr as usize)
        };
        let smooth_flags = (0..n)
            .map(|q| {
                let (c, r) = (q % w, q / w);
                let at = |dc, dr| inside(c, r, dc, dr);
                if !at(0, 0) {
                    return 0;
                }
                let mut f = 0;
                if at(-1, 0) && at(1, 0) {
                    f |= HAS_XX;
                }
                if at(0, -1) && at(0, 1) {
                    f |= HAS_YY;
                }
                if at(-1, -1) && at(1, -1) && at(-1, 1) && at(1, 1) {
                    f |= HAS_XY;
                }
                f
            })
            .collect();
        let padded = (w + 2 * HALO) * (h + 2 * HALO);
        Self {
            width: w,
            height: h,
            rows: vec![SystemRow::default(); padded],
            dz_padded: vec![0.0; padded],
            data: vec![DataRow::default(); n],
            residual: vec![0.0; n],
            jacobian: vec![[0.0; 5]; n],
            smooth_flags,
            psi_weights: std::array::from_fn(|_| vec![0.0; padded]),
            z_padded: vec![0.0; padded],
        }
    }

    /// Bytes held by the system's buffers (all proportional to the pixel count).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.rows.capacity() * size_of::<SystemRow>()
            + self.dz_padded.capacity() * size_of::<f64>()
            + self.data.capacity() * size_of::<DataRow>()
            + self.residual.capacity() * size_of::<f64>()
            + self.jacobian.capacity() * size_of::<[f64; 5]>()
            + self.smooth_flags.capacity()
            + self
                .psi_weights
                .iter()
                .map(|p| p.capacity() * size_of::<f64>())
                .sum::<usize>()
            + self.z_padded.capacity() * size_of::<f64>()
    }

    /// Padded row width.
    #[inline]
    pub fn padded_width(&self) -> usize {
        self.width + 2 * HALO
    }

    /// Index of `(column, row)` in [`Self::dz_padded`].
    #[inline]
    pub fn padded_index(&self, column: usize, row: usize) -> usize {
        (row + HALO) * self.padded_width() + column + HALO
    }

    /// Sets every unknown to 0.
    pub fn clear_dz(&mut self) {
        self.dz_padded.iter_mut().for_each(|v| *v = 0.0);
    }

    /// Copies the unknowns into a `width x height` grid.
    pub fn dz_grid(&self) -> Grid<f64> {
        Grid::from_fn(self.width, self.height, |c, r| {
            self.dz_padded[self.padded_index(c, r)]
        })
    }

    /// Linearises the data term at `depth` (branches frozen there) and builds
    /// `J^T C J` and `-J^T C D`. Returns false when the reflectance model
    /// cannot give the requested derivatives.
    pub fn linearise_data<M: Reflectance + ?Sized>(
        &mut self,
        model: &M,
        level: &PyramidLevel,
        depth: &Grid<f64>,
        derivatives: Derivatives,
    ) -> bool {
        let w = self.width;
        let pw = self.padded_width();
        let min_rows = rows_per_task(w);
        for r in 0..self.height {
            let start = (r + HALO) * pw + HALO;
            self.z_padded[start..start + w].copy_from_slice(&depth.as_slice()[r * w..(r + 1) * w]);
        }
        let geometry = level.geometry;
        let h = geometry.spacing;
        let ok = self
            .residual
            .par_chunks_mut(w)
            .zip(self.jacobian.par_chunks_mut(w))
            .with_min_len(min_rows)
            .enumerate()
            .map(|(r, (res_row, jac_row))| {
                let mut ok = true;
                for c in 0..w {
                    res_row[c] = 0.0;
                    jac_row[c] = [0.0; 5];
                    if !level.domain.at(c, r) {
                        continue;
                    }
                    let nb = model::neighbourhood(depth, &level.domain, c, r);
                    let (branches, _, _) = nb.upwind(h);
                    let values = nb.values();
                    let ray = geometry.ray(c, r);
                    match model::residual_and_jacobian(
                        model,
                        &ray,
                        *level.image.at(c, r),
                        &values,
                        branches,
                        h,
                        derivatives,
                    ) {
                        Some((d, jac)) if d.is_finite() && jac.iter().all(|v| v.is_finite()) => {
                            res_row[c] = d;
                            jac_row[c] = jac;
                        }
                        Some(_) => {}
                        None => ok = false,
                    }
                }
                ok
            })
            .reduce(|| true, |a, b| a && b);
        if !ok {
            return false;
        }
        let height = self.height;
        let residual = &self.residual;
        let jacobian = &self.jacobian;
        let confidence = level.confidence.as_slice();
        let domain = &level.domain;
        self.data
            .par_chunks_mut(w)
            .with_min_len(min_rows)
            .enumerate()
            .for_each(|(r, data_row)| {
                for (c, out) in data_row.iter_mut().enumerate() {
                    let mut stencil = [0.0f64; 17];
                    let mut rhs = 0.0;
                    if *domain.at(c, r) {
                        for (s, &(sx, sy)) in SLOT_OFFSET.iter().enumerate() {
                            // p is the pixel whose slot s is q = (c, r).
                            let (pc, pr) = (c as isize - sx, r as isize - sy);
                            if pc < 0 || pr < 0 || pc as usize >= w || pr as usize >= height {
                                continue;
                            }
                            let p = pr as usize * w + pc as usize;
                            let j_pq = jacobian[p][s];
                            if j_pq == 0.0 {
                                continue;
                            }
                            let weight = confidence[p] * j_pq;
                            rhs -= weight * residual[p];
                            for (t, &(tx, ty)) in SLOT_OFFSET.iter().enumerate() {
                                let j_pt = jacobian[p][t];
                                if j_pt != 0.0 {
                                    stencil[stencil_index(tx - sx, ty - sy)] += weight * j_pt;
                                }
                            }
                        }
                    }
                    *out = DataRow {
                        forward: std::array::from_fn(|k| {
                            stencil[stencil_index(FORWARD[k].0, FORWARD[k].1)] as f32
                        }),
                        diagonal: stencil[0],
                        rhs,
                    };
                }
            });
        true
    }

    /// Adds the smoothness part with `Psi'` evaluated at `z^k + dz` (the
    /// linearisation point of [`Self::linearise_data`] plus the current
    /// unknowns) and sets the full rows for the current inner iteration.
    /// Pixels with a non-positive diagonal are not solved for (their `dz`
    /// stays 0).
    pub fn add_smoothness(&mut self, level: &PyramidLevel, alpha: f64, lambda: f64) {
        let w = self.width;
        let pw = self.padded_width();
        let h = level.geometry.spacing;
        let min_rows = rows_per_task(w);
        let kxx = 1.0 / (h.x * h.x);
        let kyy = 1.0 / (h.y * h.y);
        let kxy = 1.0 / (4.0 * h.x * h.y);
        let flags = &self.smooth_flags;
        let z = &self.z_padded;
        let dz = &self.dz_padded;
        let [wxx, wyy, wxy] = &mut self.psi_weights;
        wxx.par_chunks_mut(pw)
            .zip(wyy.par_chunks_mut(pw))
            .zip(wxy.par_chunks_mut(pw))
            .skip(HALO)
            .take(self.height)
            .with_min_len(min_rows)
            .enumerate()
            .for_each(|(r, ((row_xx, row_yy), row_xy))| {
                let trial = |i: usize| z[i] + dz[i];
                for c in 0..w {
                    let f = flags[r * w + c];
                    let out = c + HALO;
                    if f == 0 {
                        (row_xx[out], row_yy[out], row_xy[out]) = (0.0, 0.0, 0.0);
                        continue;
                    }
                    let i = (r + HALO) * pw + c + HALO;
                    let centre = trial(i);
                    let mut s2 = 0.0;
                    if f & HAS_XX != 0 {
                        let zxx = (trial(i - 1) - 2.0 * centre + trial(i + 1)) * kxx;
                        s2 += zxx * zxx;
                    }
                    if f & HAS_YY != 0 {
                        let zyy = (trial(i - pw) - 2.0 * centre + trial(i + pw)) * kyy;
                        s2 += zyy * zyy;
                    }
                    if f & HAS_XY != 0 {
                        let zxy = (trial(i + pw + 1) - trial(i - pw + 1) - trial(i + pw - 1)
                            + trial(i - pw - 1))
                            * kxy;
                        s2 += 2.0 * zxy * zxy;
                    }
                    let psi = model::charbonnier_derivative(s2, lambda);
                    let on = |bit: u8| if f & bit != 0 { psi } else { 0.0 };
                    row_xx[out] = on(HAS_XX) * kxx * kxx;
                    row_yy[out] = on(HAS_YY) * kyy * kyy;
                    // the mixed term enters S^2 twice
                    row_xy[out] = 2.0 * on(HAS_XY) * kxy * kxy;
                }
            });
        let weights = &self.psi_weights;
        let data = &self.data;
        let domain = level.domain.as_slice();
        self.rows
            .par_chunks_mut(pw)
            .skip(HALO)
            .take(self.height)
            .with_min_len(min_rows)
            .enumerate()
            .for_each(|(r, out)| {
                assemble_row(
                    RowInputs {
                        row: r,
                        padded_width: pw,
                        alpha,
                        data: &data[r * w..(r + 1) * w],
                        domain: &domain[r * w..(r + 1) * w],
                        weights,
                        z,
                    },
                    &mut out[HALO..HALO + w],
                )
            });
    }
}

/// What [`assemble_row`] reads.
struct RowInputs<'a> {
    row: usize,
    padded_width: usize,
    alpha: f64,
    data: &'a [DataRow],
    domain: &'a [bool],
    weights: &'a [Vec<f64>; 3],
    z: &'a [f64],
}

/// Full rows of one image row: data part plus `alpha` times the smoothness
/// operator `A(Psi') = K^T Psi' K`, right-hand side `-J^T C D - alpha A z`.
///
/// The smoothness rows come in closed form from the per-pixel weights
/// `[w_xx, w_yy, w_xy]` (`Psi'_p k^2`, mixed weight doubled): a z_xx stencil
/// `(1, -2, 1)` centred at `p` contributes `w_p k_pq k_pr` to row `q`; summing
/// over the three stencils that contain `q` gives the entries below, likewise
/// for z_yy; a mixed stencil at the diagonal neighbour `p = q - (a, b)`
/// contributes `+w` at `q`, `-w` at `q + (-2a, 0)` and at `q + (0, -2b)`, and
/// `+w` at `q + (-2a, -2b)`.
fn assemble_row(inputs: RowInputs<'_>, out: &mut [SystemRow]) {
    let RowInputs {
        row,
        padded_width: pw,
        alpha,
        data,
        domain,
        weights,
        z,
    } = inputs;
    let base = (row + HALO) * pw + HALO;
    for (c, out) in out.iter_mut().enumerate() {
        if !domain[c] {
            *out = SystemRow::default();
            continue;
        }
        let i = base + c;
        let [wxx, wyy, wxy] = weights;
        let (left, here, right) = (wxx[i - 1], wxx[i], wxx[i + 1]);
        let (up, here_y, down) = (wyy[i - pw], wyy[i], wyy[i + pw]);
        // Mixed stencils at p = q - (a, b): names give (a, b) as m/p signs.
        let mm = wxy[i + pw + 1];
        let pm = wxy[i + pw - 1];
        let mp = wxy[i - pw + 1];
        let pp = wxy[i - pw - 1];
        // Entries in STENCIL order.
        let s: [f64; 17] = [
            left + 4.0 * here + right + up + 4.0 * here_y + down + mm + pm + mp + pp, // (0, 0)
            -2.0 * (left + here),                                                     // (-1, 0)
            pp,                                                                       // (-2, -2)
            up - mp - pp,                                                             // (0, -2)
            mp,                                                                       // (2, -2)
            0.0,                                                                      // (-1, -1)
            -2.0 * (up + here_y),                                                     // (0, -1)
            0.0,                                                                      // (1, -1)
            left - pm - pp,                                                           // (-2, 0)
            -2.0 * (here + right),                                                    // (1, 0)
            right - mm - mp,                                                          // (2, 0)
            0.0,                                                                      // (-1, 1)
            -2.0 * (here_y + down),                                                   // (0, 1)
            0.0,                                                                      // (1, 1)
            pm,                                                                       // (-2, 2)
            down - mm - pm,                                                           // (0, 2)
            mm,                                                                       // (2, 2)
        ];
        let zr = |dx: isize, dy: isize| z[(i as isize + dx + dy * pw as isize) as usize];
        let az = s[0] * zr(0, 0)
            + s[1] * zr(-1, 0)
            + s[2] * zr(-2, -2)
            + s[3] * zr(0, -2)
            + s[4] * zr(2, -2)
            + s[6] * zr(0, -1)
            + s[8] * zr(-2, 0)
            + s[9] * zr(1, 0)
            + s[10] * zr(2, 0)
            + s[12] * zr(0, 1)
            + s[14] * zr(-2, 2)
            + s[15] * zr(0, 2)
            + s[16] * zr(2, 2);
        let d = &data[c];
        let diagonal = d.diagonal + alpha * s[0];
        let rhs = d.rhs - alpha * az;
        let inverse32 = (1.0 / diagonal) as f32;
        let rhs32 = rhs as f32;
        // Also rejects values that overflow f32.
        let solvable = diagonal > 0.0 && inverse32.is_finite() && rhs32.is_finite();
        // Forward entries of s, in FORWARD order.
        let forward = [s[9], s[10], s[11], s[12], s[13], s[14], s[15], s[16]];
        *out = SystemRow {
            forward: std::array::from_fn(|k| d.forward[k] + (alpha * forward[k]) as f32),
            inverse_diagonal: if solvable { inverse32 } else { 0.0 },
            rhs: if solvable { rhs32 } else { 0.0 },
        };
    }
}

/// Rows per rayon task so that small levels run as one task.
fn rows_per_task(width: usize) -> usize {
    (8192 / width.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::camera::Intrinsics;
    use crate::model::{Lambertian, LevelGeometry};

    /// A small level with a random-looking smooth depth and a domain hole.
    fn small_level(domain_hole: bool) -> (PyramidLevel, Grid<f64>) {
        let (w, h) = (9, 8);
        let camera = Intrinsics::centred(12.0, w, h);
        let geometry = LevelGeometry::new(w, h, w, h, camera);
        let depth = Grid::from_fn(w, h, |c, r| {
            2.0 + 0.05 * ((c * 7 + r * 3) as f64).sin() + 0.03 * (r as f64 * 0.9).cos()
        });
        let image = Grid::from_fn(w, h, |c, r| 0.3 + 0.01 * ((c * 5 + r * 11) as f64).cos());
        let confidence = Grid::from_fn(w, h, |c, r| if (c + r) % 5 == 0 { 0.5 } else { 1.0 });
        let domain = Grid::from_fn(w, h, |c, r| {
            !(domain_hole && (c == 0 && r < 3 || (c == 5 && r == 4)))
        });
        (
            PyramidLevel {
                geometry,
                image,
                confidence,
                domain,
            },
            depth,
        )
    }

    #[test]
    fn rhs_is_minus_half_the_energy_gradient_and_matrix_is_symmetric() {
        for hole in [false, true] {
            let (level, depth) = small_level(hole);
            let model = Lambertian {
                intensity_scale: 1.3,
            };
            let (alpha, lambda) = (0.7, 0.05);
            let mut system = LinearSystem::new(&level);
            assert!(system.linearise_data(&model, &level, &depth, Derivatives::Exact));
            system.add_smoothness(&level, alpha, lambda);
            let energy = |z: &Grid<f64>| {
                model::energy(
                    &model,
                    &level.geometry,
                    &level.image,
                    &level.confidence,
                    &level.domain,
                    z,
                    alpha,
                    lambda,
                )
                .total
            };
            let (w, h) = depth.size();
            for q in 0..w * h {
                if !level.domain.as_slice()[q] {
                    continue;
                }
                let e = 1e-6;
                let mut plus = depth.clone();
                plus.as_mut_slice()[q] += e;
                let mut minus = depth.clone();
                minus.as_mut_slice()[q] -= e;
                let gradient = (energy(&plus) - energy(&minus)) / (2.0 * e);
                assert!(
                    (gradient
                        + 2.0 * f64::from(system.rows[system.padded_index(q % w, q / w)].rhs))
                    .abs()
                        < 1e-5 * (1.0 + gradient.abs()),
                    "hole={hole} q={q}: numeric {gradient} vs -2 rhs {}",
                    -2.0 * f64::from(system.rows[system.padded_index(q % w, q / w)].rhs)
                );
            }
            let rows = super::super::sor::explicit_rows(&system);
            for (i, row) in rows.iter().enumerate() {
                for &(j, a) in row {
                    let back = rows[j].iter().find(|(k, _)| *k == i).map(|(_, v)| *v);
                    let back = back.expect("symmetric sparsity");
                    assert!(
                        (a - back).abs() <= 1e-5 * a.abs().max(1e-3),
                        "{i},{j}: {a} vs {back}"
                    );
                }
            }
        }
    }

    #[test]
    fn stencil_lookup_is_consistent() {
        for (k, &(dx, dy)) in STENCIL.iter().enumerate() {
            assert_eq!(stencil_index(dx, dy), k);
        }
    }
}
