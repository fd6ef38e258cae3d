//! One Gauss-Newton step's sparse symmetric linear system
//! `(J^T C J + alpha A(Psi')) dz = -J^T C D - alpha A(Psi') z` on one level,
//! stored as a 17-point stencil per pixel (METHOD.md section 4).
//!
//! The data part `J^T C J`, `-J^T C D` is built once per outer iteration
//! (lagged upwind branches); the smoothness part is added for every inner
//! iteration with the current `Psi'`. Both are assembled by gathering, so rows
//! are built in parallel without write conflicts.

mod layout;
mod rows;

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};
use crate::grid::Grid;
use crate::model::{Derivatives, Reflectance};

use super::problem::rows_per_task;
use super::pyramid::PyramidLevel;
pub use layout::{FORWARD, HALO, PLANE_INVERSE_DIAGONAL, PLANE_RHS, PLANES, STENCIL};
use layout::{KZ_PLANES, MASK_PLANES, MASK_XX, MASK_XY, MASK_YY, SMOOTH_PLANES};
use rows::{
    DataRowInputs, DataRowOutputs, KzRows, MIN_DATA_BLOCK_ROWS, RowInputs, SHARED_FORWARD,
    WeightInputs, assemble_row, data_row, image_row_blocks, kz_row, linearise_row, weight_row,
};

/// One row of the full system (40 bytes): the diagonal, the right-hand side
/// and the forward half of the off-diagonals. Stored in f32 to halve the
/// memory traffic of the sweeps (memory-bound at 1920x1080); the stored
/// rounding changes an update by about 1e-7 relative, far below what a few
/// sweeps resolve.
///
/// [`LinearSystem`] keeps these fields in separate planes (see
/// [`LinearSystem::coefficients`]) so that the sweep reads each as a
/// contiguous vector; [`LinearSystem::row`] gathers one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

/// The linear system of one level with its work buffers.
pub struct LinearSystem {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The full system rows, padded like `dz_padded` (zero in the halo), as
    /// planes: padded row `r` owns the block `[r * PLANES * pw, (r + 1) *
    /// PLANES * pw)`, made of [`PLANES`] planes of `pw` values each (field `k`
    /// of [`SystemRow`] in plane `k`, see [`PLANE_INVERSE_DIAGONAL`],
    /// [`PLANE_RHS`]), `pw` the padded width.
    pub coefficients: Vec<f32>,
    /// Unknowns `dz` with a [`HALO`]-wide border of zeros, row-major with
    /// width `width + 2 HALO`. f32: the unknowns are increments bounded by the
    /// dz crop, and f32 vectors halve the sweep's traffic and double its SIMD
    /// width.
    pub dz_padded: Vec<f32>,
    /// Work rows of the fast sweep, sized by `sor::sweep` on its first use
    /// (the system does not know the sweep's band layout).
    pub(crate) sweep_scratch: Vec<f32>,
    /// Data part (per outer iteration): the forward coefficients that the
    /// smoothness part adds to, as [`SHARED_FORWARD`]`.len()` planes per image
    /// row (row `r` owns `[4 r w, 4 (r + 1) w)`), the diagonal and the
    /// right-hand side. The data-only couplings ([`DATA_ONLY_FORWARD`]) go
    /// straight into [`Self::coefficients`]; the smoothness-only ones
    /// (`SMOOTH_ONLY_FORWARD`) have no data part. Held as f64 words (2 per
    /// pixel) and used as f32 (4 per pixel) through bytemuck: between an
    /// outer iteration's last assembly and the next linearisation the data
    /// part is dead, and the same memory holds the backtracking's copy of the
    /// depth ([`Self::stash_depth`]; 8 bytes per pixel not allocated).
    data_forward: Vec<f64>,
    /// The data part is the current linearisation's (not overwritten by a
    /// stashed depth).
    data_current: bool,
    data_diagonal: Vec<f32>,
    data_rhs: Vec<f32>,
    /// Smoothness weights, padded like `dz_padded` (0 in the halo), as
    /// `[xx, yy, xy]`: `W = Psi' k^2` (mixed doubled: it enters `S^2`
    /// twice), per inner iteration. Stored as row blocks like
    /// [`Self::coefficients`] ([`SMOOTH_PLANES`] planes of padded rows), so
    /// that the planes of one row are neighbours in memory rather than
    /// separate page-aligned buffers whose equal offsets collide in the L1
    /// cache. `K z^k`, the unscaled stencils applied to the linearisation
    /// point, is not stored: the weights' pass and the assembly compute it
    /// from the depth row by row (`rows::kz_row`; 12 bytes per pixel less).
    smooth: Vec<f32>,
    /// Address and length of the depth last linearised at (checked by the
    /// passes that read `K z^k` from the depth they are given).
    linearised_at: (usize, usize),
    /// The stencils' masks in the same row-block layout ([`MASK_PLANES`]
    /// plane of bytes): bit [`MASK_XX`], [`MASK_YY`] or [`MASK_XY`] set
    /// where that stencil centred at the pixel lies in the domain.
    masks: Vec<u8>,
}

impl LinearSystem {
    /// Allocates the system for a level, its masks built by rows in
    /// parallel, polling `cancel` per row.
    pub fn new(level: &PyramidLevel, cancel: Cancel<'_>) -> Result<Self, Cancelled> {
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
        let pw = w + 2 * HALO;
        let padded = pw * (h + 2 * HALO);
        let mut masks = vec![0u8; padded * MASK_PLANES];
        image_row_blocks(&mut masks, MASK_PLANES * pw, h, rows_per_task(w)).for_each(
            |(r, block)| {
                if cancel.is_cancelled() {
                    return;
                }
                for c in 0..w {
                    let at = |dc, dr| inside(c, r, dc, dr);
                    if !at(0, 0) {
                        continue;
                    }
                    let flags = [
                        (at(-1, 0) && at(1, 0), MASK_XX),
                        (at(0, -1) && at(0, 1), MASK_YY),
                        (at(-1, -1) && at(1, -1) && at(-1, 1) && at(1, 1), MASK_XY),
                    ];
                    block[c + HALO] = flags
                        .into_iter()
                        .fold(0, |bits, (on, bit)| if on { bits | bit } else { bits });
                }
            },
        );
        cancel.check()?;
        let padded = (w + 2 * HALO) * (h + 2 * HALO);
        Ok(Self {
            width: w,
            height: h,
            coefficients: vec![0.0; padded * PLANES],
            dz_padded: vec![0.0; padded],
            sweep_scratch: Vec::new(),
            data_forward: vec![0.0; SHARED_FORWARD.len() * n / 2],
            data_current: false,
            data_diagonal: vec![0.0; n],
            data_rhs: vec![0.0; n],
            smooth: vec![0.0; padded * SMOOTH_PLANES],
            linearised_at: (0, 0),
            masks,
        })
    }

    /// Bytes held by the system's buffers (all proportional to the pixel count).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.coefficients.capacity() * size_of::<f32>()
            + self.dz_padded.capacity() * size_of::<f32>()
            + self.sweep_scratch.capacity() * size_of::<f32>()
            + self.data_forward.capacity() * size_of::<f64>()
            + (self.data_diagonal.capacity() + self.data_rhs.capacity()) * size_of::<f32>()
            + self.smooth.capacity() * size_of::<f32>()
            + self.masks.capacity()
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

    /// Keeps a copy of `depth` (this level's size) in the data part's
    /// memory: the data part is lost until the next
    /// [`Self::linearise_data`] (an assembly before it panics).
    pub fn stash_depth(&mut self, depth: &Grid<f64>) {
        let n = depth.as_slice().len();
        assert_eq!(n, self.width * self.height, "a depth of this level");
        self.data_current = false;
        let min_len = rows_per_task(self.width) * self.width;
        self.data_forward[..n]
            .par_iter_mut()
            .zip(depth.as_slice().par_iter())
            .with_min_len(min_len)
            .for_each(|(to, from)| *to = *from);
    }

    /// Copies the depth kept by [`Self::stash_depth`] back into `depth`.
    pub fn restore_depth(&self, depth: &mut Grid<f64>) {
        let n = depth.as_slice().len();
        assert!(!self.data_current, "a depth was stashed");
        let min_len = rows_per_task(self.width) * self.width;
        depth
            .as_mut_slice()
            .par_iter_mut()
            .zip(self.data_forward[..n].par_iter())
            .with_min_len(min_len)
            .for_each(|(to, from)| *to = *from);
    }

    /// Sets every unknown to 0, polling `cancel` per 8192 unknowns (the
    /// first clear faults in the unknowns' fresh pages: tens of milliseconds
    /// at photograph size) and skipping the rest once it says yes.
    pub fn clear_dz(&mut self, cancel: Cancel<'_>) -> Result<(), Cancelled> {
        self.dz_padded.par_chunks_mut(8192).for_each(|chunk| {
            if !cancel.is_cancelled() {
                chunk.fill(0.0);
            }
        });
        cancel.check()
    }

    /// Copies the unknowns into a `width x height` grid.
    pub fn dz_grid(&self) -> Grid<f64> {
        Grid::from_fn(self.width, self.height, |c, r| {
            f64::from(self.dz_padded[self.padded_index(c, r)])
        })
    }

    /// The system as explicit sparse rows over unpadded indices (for tests and
    /// debugging). Rows of pixels that are not solved for are empty.
    pub fn explicit_rows(&self) -> Vec<Vec<(usize, f64)>> {
        let system = self;
        let (w, h) = (system.width, system.height);
        let record = |c: isize, r: isize| system.row(c as usize, r as usize);
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

    /// The row of `(column, row)`, gathered from the planes.
    pub fn row(&self, column: usize, row: usize) -> SystemRow {
        let pw = self.padded_width();
        let block = (row + HALO) * PLANES * pw;
        let at = |plane: usize| self.coefficients[block + plane * pw + column + HALO];
        SystemRow {
            forward: std::array::from_fn(at),
            inverse_diagonal: at(PLANE_INVERSE_DIAGONAL),
            rhs: at(PLANE_RHS),
        }
    }

    /// Linearises the data term at `depth` (branches frozen there) and builds
    /// `J^T C J` and `-J^T C D`. Returns false when the reflectance model
    /// cannot give the requested derivatives. Polls `cancel` per block of
    /// rows and skips the rest once it says yes (`Err`: the system is then
    /// garbage).
    pub fn linearise_data<M: Reflectance + ?Sized>(
        &mut self,
        model: &M,
        level: &PyramidLevel,
        depth: &Grid<f64>,
        derivatives: Derivatives,
        cancel: Cancel<'_>,
    ) -> Result<bool, Cancelled> {
        let w = self.width;
        let pw = self.padded_width();
        let min_rows = rows_per_task(w);
        let height = self.height;
        self.linearised_at = address(depth);
        // The residual and its Jacobian are streamed: each task linearises
        // the pixel rows its block of rows reads (its own and one more on
        // each side) into a buffer of its own, so the whole-level Jacobian
        // is never held (24 bytes per pixel; a few per cent more model
        // evaluations on the shared rows).
        let block_rows = min_rows.max(MIN_DATA_BLOCK_ROWS);
        let confidence = &level.confidence;
        let domain = &level.domain;
        let shared = SHARED_FORWARD.len();
        self.data_current = true;
        let linearised = bytemuck::cast_slice_mut::<f64, f32>(&mut self.data_forward)
            .par_chunks_mut(shared * w * block_rows)
            .zip(self.data_diagonal.par_chunks_mut(w * block_rows))
            .zip(self.data_rhs.par_chunks_mut(w * block_rows))
            .zip(self.coefficients[HALO * PLANES * pw..].par_chunks_mut(PLANES * pw * block_rows))
            .enumerate()
            .map(
                |(block, (((forward_rows, diagonal_rows), rhs_rows), coefficient_rows))| {
                    if cancel.is_cancelled() {
                        return true;
                    }
                    let r0 = block * block_rows;
                    let rows = diagonal_rows.len() / w;
                    // Pixel rows p0..p1 reach rows r0..r0 + rows through the slots.
                    let p0 = r0.saturating_sub(1);
                    let p1 = (r0 + rows + 1).min(height);
                    let mut residual = vec![0.0f32; (p1 - p0) * w];
                    let mut jacobian = vec![[0.0f32; 5]; (p1 - p0) * w];
                    let mut ok = true;
                    for (k, (res_row, jac_row)) in residual
                        .chunks_mut(w)
                        .zip(jacobian.chunks_mut(w))
                        .enumerate()
                    {
                        // Polled per row too: a block's first pass faults in
                        // megabytes of fresh pages (tens of milliseconds).
                        if cancel.is_cancelled() {
                            return true;
                        }
                        ok &= linearise_row(
                            model,
                            level,
                            depth,
                            derivatives,
                            p0 + k,
                            res_row,
                            jac_row,
                        );
                    }
                    for k in 0..rows {
                        if cancel.is_cancelled() {
                            return true;
                        }
                        data_row(
                            &DataRowInputs {
                                row: r0 + k,
                                first_pixel_row: p0,
                                width: w,
                                height,
                                residual: &residual,
                                jacobian: &jacobian,
                                confidence,
                                domain,
                            },
                            DataRowOutputs {
                                forward: &mut forward_rows[shared * k * w..shared * (k + 1) * w],
                                diagonal: &mut diagonal_rows[k * w..(k + 1) * w],
                                rhs: &mut rhs_rows[k * w..(k + 1) * w],
                                coefficients: &mut coefficient_rows[PLANES * pw * k..]
                                    [..PLANES * pw],
                            },
                        );
                    }
                    ok
                },
            )
            .reduce(|| true, |a, b| a && b);
        cancel.check().map(|()| linearised)
    }

    /// Adds the smoothness part with `Psi'` evaluated at `z^k + dz` (the
    /// linearisation point of [`Self::linearise_data`], `depth`, the same
    /// grid unchanged, plus the current unknowns) and sets the full rows for
    /// the current inner iteration.
    /// Pixels with a non-positive diagonal are not solved for (their `dz`
    /// stays 0).
    ///
    /// Two passes over rows, each written as straight loops over slices so
    /// that they vectorise (compiled for AVX2 where the CPU has it): the
    /// weights `W = Psi' k^2` with `W * (K z^k)`, then the rows.
    ///
    /// Returns the relative change of the weights since the previous call,
    /// `sum |W_new - W_old| / sum W_new` (the Charbonnier `Psi'` moved by
    /// this much, weighted): the inner fixed point has converged when it is
    /// small. The first call on a system compares with zero weights (1).
    ///
    /// Polls `cancel` per row and skips the rest once it says yes (`Err`:
    /// the system is then garbage).
    pub fn add_smoothness(
        &mut self,
        level: &PyramidLevel,
        depth: &Grid<f64>,
        alpha: f64,
        lambda: f64,
        cancel: Cancel<'_>,
    ) -> Result<f64, Cancelled> {
        let change = self.update_weights(level, depth, lambda, cancel)?;
        self.assemble(level, depth, alpha, cancel)?;
        Ok(change)
    }

    /// The first pass of [`Self::add_smoothness`] alone: the weights `W` at
    /// `z^k + dz` and their relative change, without setting the rows (they
    /// keep the previous weights until [`Self::assemble`]). A caller
    /// that stops the inner iterations once the weights have settled learns
    /// so without paying for rows it will not solve. `depth` is the
    /// linearisation point, as there. Polls `cancel` per block of rows, as
    /// there.
    pub fn update_weights(
        &mut self,
        level: &PyramidLevel,
        depth: &Grid<f64>,
        lambda: f64,
        cancel: Cancel<'_>,
    ) -> Result<f64, Cancelled> {
        self.check_linearisation_point(depth);
        let w = self.width;
        let pw = self.padded_width();
        let h = level.geometry.spacing;
        let min_rows = rows_per_task(w);
        let scale = [
            1.0 / (h.x * h.x),
            1.0 / (h.y * h.y),
            1.0 / (4.0 * h.x * h.y),
        ];
        let inputs = WeightInputs {
            padded_width: pw,
            width: w,
            // the mixed term enters S^2 twice
            weight_scale: [
                (scale[0] * scale[0]) as f32,
                (scale[1] * scale[1]) as f32,
                (2.0 * scale[2] * scale[2]) as f32,
            ],
            scale: scale.map(|k| k as f32),
            inverse_lambda_squared: (1.0 / (lambda * lambda)) as f32,
            dz: &self.dz_padded,
        };
        let simd = Simd::detect();
        let masks = &self.masks;
        let (z, height) = (depth.as_slice(), self.height);
        let (changed, total) =
            image_row_blocks(&mut self.smooth, SMOOTH_PLANES * pw, height, min_rows)
                .map_init(
                    || vec![0.0f32; KZ_PLANES * pw],
                    |kz, (r, block)| {
                        if cancel.is_cancelled() {
                            return (0.0, 0.0);
                        }
                        let mask_block =
                            &masks[(r + HALO) * MASK_PLANES * pw..][..MASK_PLANES * pw];
                        simd.run(|| {
                            kz_row(z, w, height, r, mask_block, kz);
                            weight_row(&inputs, r, mask_block, kz, block)
                        })
                    },
                )
                .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        cancel.check()?;
        Ok(if total > 0.0 {
            changed / total
        } else if changed > 0.0 {
            1.0
        } else {
            0.0
        })
    }

    /// The second pass of [`Self::add_smoothness`]: the full rows from the
    /// data part and the current weights `W` at the linearisation point
    /// `depth` (polling `cancel` per block of rows, as there).
    pub fn assemble(
        &mut self,
        level: &PyramidLevel,
        depth: &Grid<f64>,
        alpha: f64,
        cancel: Cancel<'_>,
    ) -> Result<(), Cancelled> {
        self.check_linearisation_point(depth);
        let w = self.width;
        let pw = self.padded_width();
        let min_rows = rows_per_task(w);
        let simd = Simd::detect();
        assert!(
            self.data_current,
            "the system is assembled after a linearisation, not after a stash"
        );
        let smooth = &self.smooth;
        let data_forward: &[f32] = bytemuck::cast_slice(&self.data_forward);
        let shared = SHARED_FORWARD.len();
        let data_diagonal = &self.data_diagonal;
        let data_rhs = &self.data_rhs;
        let domain = level.domain.as_slice();
        let masks = &self.masks;
        let (z, size) = (depth.as_slice(), (w, self.height));
        image_row_blocks(&mut self.coefficients, PLANES * pw, self.height, min_rows).for_each_init(
            || KzRows::new(pw),
            |kz_rows, (r, block)| {
                if cancel.is_cancelled() {
                    return;
                }
                simd.run(|| {
                    let inputs = RowInputs {
                        row: r,
                        padded_width: pw,
                        alpha,
                        data_forward: &data_forward[shared * r * w..shared * (r + 1) * w],
                        data_diagonal: &data_diagonal[r * w..(r + 1) * w],
                        data_rhs: &data_rhs[r * w..(r + 1) * w],
                        domain: &domain[r * w..(r + 1) * w],
                        smooth,
                        kz: kz_rows.around(z, size, masks, r),
                    };
                    assemble_row(&inputs, block);
                });
            },
        );
        cancel.check()
    }

    /// In debug builds, panics unless `depth` is the grid last given to
    /// [`Self::linearise_data`] (its `K z^k` is read from it).
    fn check_linearisation_point(&self, depth: &Grid<f64>) {
        debug_assert_eq!(
            address(depth),
            self.linearised_at,
            "the smoothness part is built at the depth the data part was linearised at"
        );
    }

    /// Whether pixel `(column, row)` is solved for (a positive diagonal).
    #[inline]
    pub fn is_solved(&self, column: usize, row: usize) -> bool {
        let pw = self.padded_width();
        self.coefficients[(row + HALO) * PLANES * pw + PLANE_INVERSE_DIAGONAL * pw + column + HALO]
            != 0.0
    }

    /// The full 5x5 row of `(column, row)` (index `(dy + 2) * 5 + dx + 2`,
    /// centre 12), couplings to pixels that are not solved for left out; None
    /// for a pixel that is not solved for.
    pub fn stencil(&self, column: usize, row: usize) -> Option<[f32; 25]> {
        if !self.is_solved(column, row) {
            return None;
        }
        let pw = self.padded_width();
        let here = self.row(column, row);
        let mut out = [0.0f32; 25];
        out[12] = 1.0 / here.inverse_diagonal;
        for (k, &(dx, dy)) in FORWARD.iter().enumerate() {
            // The forward coupling is stored here, the backward one at -o;
            // the halo keeps both reads inside the planes (zero there).
            let (fc, fr) = (column as isize + dx, row as isize + dy);
            let (bc, br) = (column as isize - dx, row as isize - dy);
            let inside = |c: isize, r: isize| {
                c >= 0 && r >= 0 && (c as usize) < self.width && (r as usize) < self.height
            };
            if inside(fc, fr) && self.is_solved(fc as usize, fr as usize) {
                out[((dy + 2) * 5 + dx + 2) as usize] = here.forward[k];
            }
            if inside(bc, br) && self.is_solved(bc as usize, br as usize) {
                let block = (br as usize + HALO) * PLANES * pw;
                out[((2 - dy) * 5 + 2 - dx) as usize] =
                    self.coefficients[block + k * pw + bc as usize + HALO];
            }
        }
        Some(out)
    }

    /// The residual `b - A dz` of the current unknowns into `out` (laid out
    /// like [`Self::dz_padded`], 0 outside the solved pixels); returns its
    /// squared Euclidean norm. About the cost of one sweep.
    pub fn residual_into(&self, out: &mut [f32]) -> f64 {
        assert_eq!(out.len(), self.dz_padded.len());
        let min_rows = rows_per_task(self.width);
        out.par_chunks_mut(self.padded_width())
            .enumerate()
            .with_min_len(min_rows)
            .map(|(pr, out_row)| {
                out_row.iter_mut().for_each(|v| *v = 0.0);
                let mut norm = 0.0f64;
                self.row_residuals(pr, |c, value| {
                    out_row[c] = value;
                    norm += f64::from(value) * f64::from(value);
                });
                norm
            })
            .sum()
    }

    /// The squared Euclidean norm of the residual `b - A dz`, without
    /// storing it (the same sum as [`Self::residual_into`] returns).
    /// Polls `cancel` per row.
    pub fn residual_norm_squared(&self, cancel: Cancel<'_>) -> Result<f64, Cancelled> {
        let min_rows = rows_per_task(self.width);
        let norm: f64 = (0..self.height + 2 * HALO)
            .into_par_iter()
            .with_min_len(min_rows)
            .map(|pr| {
                let mut norm = 0.0f64;
                if cancel.is_cancelled() {
                    return norm;
                }
                self.row_residuals(pr, |_, value| {
                    norm += f64::from(value) * f64::from(value);
                });
                norm
            })
            .sum();
        cancel.check().map(|()| norm)
    }

    /// The squared norm of the right-hand side over the solved pixels: the
    /// same sum as [`Self::residual_norm_squared`] at `dz = 0` (each row's
    /// part bit for bit), reading two planes instead of the whole stencil.
    /// Polls `cancel` per row.
    pub fn rhs_norm_squared(&self, cancel: Cancel<'_>) -> Result<f64, Cancelled> {
        let pw = self.padded_width();
        let (w, h) = (self.width, self.height);
        let norm: f64 = (0..h + 2 * HALO)
            .into_par_iter()
            .with_min_len(rows_per_task(w))
            .map(|pr| {
                let mut norm = 0.0f64;
                if pr < HALO || pr >= h + HALO || cancel.is_cancelled() {
                    return norm;
                }
                let here = &self.coefficients[pr * PLANES * pw..(pr + 1) * PLANES * pw];
                let inverse = &here[PLANE_INVERSE_DIAGONAL * pw..][HALO..HALO + w];
                let rhs = &here[PLANE_RHS * pw..][HALO..HALO + w];
                for (&inverse, &value) in inverse.iter().zip(rhs) {
                    if inverse != 0.0 {
                        norm += f64::from(value) * f64::from(value);
                    }
                }
                norm
            })
            .sum();
        cancel.check().map(|()| norm)
    }

    /// The residual of every solved pixel of padded row `pr`, as `(padded
    /// column, value)`.
    #[inline]
    fn row_residuals(&self, pr: usize, mut each: impl FnMut(usize, f32)) {
        let (w, h) = (self.width, self.height);
        let pw = self.padded_width();
        if pr < HALO || pr >= h + HALO {
            return;
        }
        let x = &self.dz_padded[..];
        let coefficients = &self.coefficients[..];
        let block = |k: usize| &coefficients[k * PLANES * pw..(k + 1) * PLANES * pw];
        let (here, above1, above2) = (block(pr), block(pr - 1), block(pr - 2));
        let line = |k: usize| &x[k * pw..(k + 1) * pw];
        let rows = [
            line(pr - 2),
            line(pr - 1),
            line(pr),
            line(pr + 1),
            line(pr + 2),
        ];
        for c in HALO..HALO + w {
            let inverse = here[PLANE_INVERSE_DIAGONAL * pw + c];
            if inverse == 0.0 {
                continue;
            }
            let mut sum = rows[2][c] / inverse;
            for (k, &(dx, dy)) in FORWARD.iter().enumerate() {
                let (dx, dy) = (dx, dy as usize);
                // Forward: stored here, unknown at +o.
                sum += here[k * pw + c] * rows[2 + dy][c.wrapping_add_signed(dx)];
                // Backward: stored at -o, unknown at -o.
                let back = c.wrapping_add_signed(-dx);
                let stored = match dy {
                    0 => here[k * pw + back],
                    1 => above1[k * pw + back],
                    _ => above2[k * pw + back],
                };
                sum += stored * rows[2 - dy][back];
            }
            each(c, here[PLANE_RHS * pw + c] - sum);
        }
    }
}

/// A grid's address and length: which depth a system was linearised at.
fn address(depth: &Grid<f64>) -> (usize, usize) {
    let values = depth.as_slice();
    (values.as_ptr() as usize, values.len())
}

/// Which instruction set the row loops are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Simd {
    /// Baseline for the target.
    Portable,
    /// AVX2 + FMA, chosen at run time when the CPU has both.
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
}

impl Simd {
    /// The best variant this CPU runs.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Simd::Avx2Fma;
        }
        Simd::Portable
    }

    /// Runs `f`, compiled (after inlining) for this instruction set.
    #[inline(always)]
    pub(crate) fn run<R>(self, f: impl FnOnce() -> R) -> R {
        match self {
            Simd::Portable => f(),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `detect` saw AVX2 and FMA on this CPU.
            Simd::Avx2Fma => unsafe { run_avx2_fma(f) },
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn run_avx2_fma<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// A test system on a `w x h` level: a gently varying image, the depth
/// `2 + 0.02 sin(wave (c + 2 r))`, the Lambertian model with `s = 1`,
/// smoothness `alpha` with `lambda = 1e-3`, and the given domain.
#[cfg(test)]
pub(crate) fn test_system(
    w: usize,
    h: usize,
    domain: impl Fn(usize, usize) -> bool,
    wave: f64,
    alpha: f64,
) -> LinearSystem {
    use crate::camera::Intrinsics;
    use crate::cancel::Uncancelled;
    use crate::grid::Confidence;
    use crate::model::{Lambertian, LevelGeometry};
    let camera = Intrinsics::centred(w as f64, w, h);
    let level = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, camera),
        image: std::borrow::Cow::Owned(Grid::from_fn(w, h, |c, r| {
            0.3 + 0.05 * ((c * 3 + r * 7) as f64 * 0.1).sin()
        })),
        confidence: Confidence::from_grid(Grid::filled(w, h, 1.0), Cancel::NEVER).uncancelled(),
        domain: Grid::from_fn(w, h, domain),
    };
    let depth = Grid::from_fn(w, h, |c, r| 2.0 + 0.02 * ((c + 2 * r) as f64 * wave).sin());
    let mut system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
    let model = Lambertian {
        intensity_scale: 1.0,
    };
    assert!(
        system
            .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
            .uncancelled()
    );
    system
        .add_smoothness(&level, &depth, alpha, 1e-3, Cancel::NEVER)
        .uncancelled();
    system
}

#[cfg(test)]
mod tests;
