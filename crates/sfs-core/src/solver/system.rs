//! One Gauss-Newton step's sparse symmetric linear system
//! `(J^T C J + alpha A(Psi')) dz = -J^T C D - alpha A(Psi') z` on one level,
//! stored as a 17-point stencil per pixel (METHOD.md section 4).
//!
//! The data part `J^T C J`, `-J^T C D` is built once per outer iteration
//! (lagged upwind branches); the smoothness part is added for every inner
//! iteration with the current `Psi'`. Both are assembled by gathering, so rows
//! are built in parallel without write conflicts.

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::{self, Derivatives, Reflectance};

use super::problem::rows_per_task;
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

/// Offsets of the 5-point slots `[centre, left, right, up, down]`.
const SLOT_OFFSET: [(isize, isize); 5] = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)];

/// Halo (rows/columns) around the padded vectors so that stencil reads never
/// leave them.
pub const HALO: usize = 2;

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

/// Planes per padded row of [`LinearSystem::coefficients`]: the 8 forward
/// coefficients, then `1 / diagonal`, then the right-hand side.
pub const PLANES: usize = 10;
/// Plane of `1 / diagonal` in a row block.
pub const PLANE_INVERSE_DIAGONAL: usize = 8;
/// Plane of the right-hand side in a row block.
pub const PLANE_RHS: usize = 9;

/// Planes per padded row of [`LinearSystem::smooth`].
const SMOOTH_PLANES: usize = 6;
/// First of the three `[xx, yy, xy]` planes of each kind in a smoothness row
/// block.
const SMOOTH_KZ: usize = 0;
const SMOOTH_WEIGHT: usize = 3;
/// Planes per padded row of [`LinearSystem::masks`]: `[xx, yy, xy]`.
const MASK_PLANES: usize = 3;

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
    /// row (row `r` owns `[6 r w, 6 (r + 1) w)`), the diagonal and the
    /// right-hand side. The data-only couplings ([`DATA_ONLY_FORWARD`]) go
    /// straight into [`Self::coefficients`]. Held as f64 words (3 per
    /// pixel) and used as f32 (6 per pixel) through bytemuck: between an
    /// outer iteration's last assembly and the next linearisation the data
    /// part is dead, and the same memory holds the backtracking's copy of the
    /// depth ([`Self::stash_depth`]; 8 bytes per pixel not allocated).
    data_forward: Vec<f64>,
    /// The data part is the current linearisation's (not overwritten by a
    /// stashed depth).
    data_current: bool,
    data_diagonal: Vec<f32>,
    data_rhs: Vec<f32>,
    /// Smoothness planes, padded like `dz_padded` (0 in the halo), each
    /// kind as `[xx, yy, xy]`: `K z^k`, the unscaled stencils applied to the
    /// linearisation point (`z[-1] - 2 z + z[+1]` and the four-point mixed
    /// difference; 0 where the stencil leaves the domain), per outer
    /// iteration; weights `W = Psi' k^2` (mixed doubled: it enters `S^2`
    /// twice), per inner iteration (`W K z^k` is formed where it is used).
    /// Stored as row blocks like [`Self::coefficients`] ([`SMOOTH_PLANES`]
    /// planes of padded rows), so that the planes of one row are neighbours
    /// in memory rather than separate page-aligned buffers whose equal
    /// offsets collide in the L1 cache.
    smooth: Vec<f32>,
    /// The stencils' masks in the same row-block layout ([`MASK_PLANES`]
    /// planes of bytes): 1 where that stencil centred at the pixel lies in the
    /// domain, else 0.
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
                        at(-1, 0) && at(1, 0),
                        at(0, -1) && at(0, 1),
                        at(-1, -1) && at(1, -1) && at(-1, 1) && at(1, 1),
                    ];
                    for (k, on) in flags.into_iter().enumerate() {
                        block[k * pw + c + HALO] = u8::from(on);
                    }
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
        let z = depth.as_slice();
        let masks = &self.masks;
        image_row_blocks(&mut self.smooth, SMOOTH_PLANES * pw, height, min_rows).for_each(
            |(r, block)| {
                if cancel.is_cancelled() {
                    return;
                }
                let mask_block = &masks[(r + HALO) * MASK_PLANES * pw..];
                let mask = |k: usize, c: usize| mask_block[k * pw + c + HALO] != 0;
                let kz = &mut block[SMOOTH_KZ * pw..(SMOOTH_KZ + 3) * pw];
                let (xx, rest) = kz.split_at_mut(pw);
                let (yy, xy) = rest.split_at_mut(pw);
                // Neighbours past the grid's edge read the edge pixel: the
                // masks are 0 for every stencil that leaves the grid.
                let at = |c: usize, dc: isize, dr: isize| {
                    let cc = c.saturating_add_signed(dc).min(w - 1);
                    let rr = r.saturating_add_signed(dr).min(height - 1);
                    z[rr * w + cc]
                };
                for c in 0..w {
                    // Differences in f64 (z is large, they are small), stored in f32.
                    // 0 where the stencil leaves the domain, so that
                    // `W K z^k` is 0 there whatever the depth off the domain.
                    let centre = 2.0 * z[r * w + c];
                    let kept = |k: usize, v: f64| if mask(k, c) { v as f32 } else { 0.0 };
                    xx[c + HALO] = kept(0, at(c, -1, 0) - centre + at(c, 1, 0));
                    yy[c + HALO] = kept(1, at(c, 0, -1) - centre + at(c, 0, 1));
                    xy[c + HALO] =
                        kept(2, at(c, 1, 1) - at(c, 1, -1) - at(c, -1, 1) + at(c, -1, -1));
                }
            },
        );
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
    /// linearisation point of [`Self::linearise_data`] plus the current
    /// unknowns) and sets the full rows for the current inner iteration.
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
        alpha: f64,
        lambda: f64,
        cancel: Cancel<'_>,
    ) -> Result<f64, Cancelled> {
        let change = self.update_weights(level, lambda, cancel)?;
        self.assemble(level, alpha, cancel)?;
        Ok(change)
    }

    /// The first pass of [`Self::add_smoothness`] alone: the weights `W` at
    /// `z^k + dz` and their relative change, without setting the rows (they
    /// keep the previous weights until [`Self::assemble`]). A caller
    /// that stops the inner iterations once the weights have settled learns
    /// so without paying for rows it will not solve. Polls `cancel` per
    /// block of rows, as there.
    pub fn update_weights(
        &mut self,
        level: &PyramidLevel,
        lambda: f64,
        cancel: Cancel<'_>,
    ) -> Result<f64, Cancelled> {
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
        let (changed, total) =
            image_row_blocks(&mut self.smooth, SMOOTH_PLANES * pw, self.height, min_rows)
                .map(|(r, block)| {
                    if cancel.is_cancelled() {
                        return (0.0, 0.0);
                    }
                    let mask_block = &masks[(r + HALO) * MASK_PLANES * pw..][..MASK_PLANES * pw];
                    simd.run(|| weight_row(&inputs, r, mask_block, block))
                })
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
    /// data part and the current weights `W` (polling `cancel` per block of
    /// rows, as there).
    pub fn assemble(
        &mut self,
        level: &PyramidLevel,
        alpha: f64,
        cancel: Cancel<'_>,
    ) -> Result<(), Cancelled> {
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
        let data_diagonal = &self.data_diagonal;
        let data_rhs = &self.data_rhs;
        let domain = level.domain.as_slice();
        image_row_blocks(&mut self.coefficients, PLANES * pw, self.height, min_rows).for_each(
            |(r, block)| {
                if cancel.is_cancelled() {
                    return;
                }
                let inputs = RowInputs {
                    row: r,
                    padded_width: pw,
                    alpha,
                    data_forward: &data_forward[6 * r * w..6 * (r + 1) * w],
                    data_diagonal: &data_diagonal[r * w..(r + 1) * w],
                    data_rhs: &data_rhs[r * w..(r + 1) * w],
                    domain: &domain[r * w..(r + 1) * w],
                    smooth,
                };
                simd.run(|| assemble_row(&inputs, block));
            },
        );
        cancel.check()
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

/// The [`FORWARD`] entries with a smoothness part (the data part keeps a
/// copy of them to add each inner iteration's smoothness part to).
const SHARED_FORWARD: [usize; 6] = [0, 1, 3, 5, 6, 7];
/// The [`FORWARD`] entries with a data part only, `(-1, 1)` and `(1, 1)`:
/// written into the coefficients once per outer iteration.
const DATA_ONLY_FORWARD: [usize; 2] = [2, 4];

/// Image rows per task of the data part at least: the two extra Jacobian
/// rows each task computes are then a few per cent of its work.
const MIN_DATA_BLOCK_ROWS: usize = 32;

/// The residual `D` and its Jacobian (5 slots) of image row `row` at
/// `depth`, stored in f32 (0 off the domain; a value that f32 cannot hold
/// leaves the pixel out of the data term, like a non-finite one). False when
/// the model cannot give the requested derivatives.
fn linearise_row<M: Reflectance + ?Sized>(
    model: &M,
    level: &PyramidLevel,
    depth: &Grid<f64>,
    derivatives: Derivatives,
    row: usize,
    residual: &mut [f32],
    jacobian: &mut [[f32; 5]],
) -> bool {
    let geometry = level.geometry;
    let h = geometry.spacing;
    let mut ok = true;
    for c in 0..residual.len() {
        residual[c] = 0.0;
        jacobian[c] = [0.0; 5];
        if !level.domain.at(c, row) {
            continue;
        }
        let nb = model::neighbourhood(depth, &level.domain, c, row);
        let (branches, _, _) = nb.upwind(h);
        let values = nb.values();
        let ray = geometry.ray(c, row);
        match model::residual_and_jacobian(
            model,
            &ray,
            *level.image.at(c, row),
            &values,
            branches,
            h,
            derivatives,
        ) {
            Some((d, jac)) => {
                let (d32, jac32) = (d as f32, jac.map(|v| v as f32));
                if d32.is_finite() && jac32.iter().all(|v| v.is_finite()) {
                    residual[c] = d32;
                    jacobian[c] = jac32;
                }
            }
            None => ok = false,
        }
    }
    ok
}

/// What [`data_row`] reads: the residual and Jacobian of pixel rows
/// `first_pixel_row..`, as many as the buffers hold.
struct DataRowInputs<'a> {
    row: usize,
    first_pixel_row: usize,
    width: usize,
    height: usize,
    residual: &'a [f32],
    jacobian: &'a [[f32; 5]],
    confidence: &'a Confidence,
    domain: &'a Grid<bool>,
}

/// Where [`data_row`] writes one image row.
struct DataRowOutputs<'a> {
    /// The [`SHARED_FORWARD`] entries, a plane each.
    forward: &'a mut [f32],
    diagonal: &'a mut [f32],
    rhs: &'a mut [f32],
    /// The row's block of [`LinearSystem::coefficients`], which gets the
    /// [`DATA_ONLY_FORWARD`] entries (0 off the domain).
    coefficients: &'a mut [f32],
}

/// The data part of image row `row`: `J^T C J` (forward entries, the
/// diagonal) and `-J^T C D`.
fn data_row(inputs: &DataRowInputs<'_>, out: DataRowOutputs<'_>) {
    let (w, r) = (inputs.width, inputs.row);
    let pw = w + 2 * HALO;
    for c in 0..w {
        // The diagonal and the forward entries: the backward half is the
        // forward half of other pixels (the matrix is symmetric).
        let mut kept = [0.0f64; 1 + FORWARD.len()];
        let mut rhs = 0.0;
        if *inputs.domain.at(c, r) {
            for (s, &(sx, sy)) in SLOT_OFFSET.iter().enumerate() {
                // p is the pixel whose slot s is q = (c, r).
                let (pc, pr) = (c as isize - sx, r as isize - sy);
                if pc < 0 || pr < 0 || pc as usize >= w || pr as usize >= inputs.height {
                    continue;
                }
                let p = pr as usize * w + pc as usize;
                let local = (pr as usize - inputs.first_pixel_row) * w + pc as usize;
                let j_p = inputs.jacobian[local];
                let j_pq = f64::from(j_p[s]);
                if j_pq == 0.0 {
                    continue;
                }
                let weight = inputs.confidence.weight(p) * j_pq;
                rhs -= weight * f64::from(inputs.residual[local]);
                for (t, &entry) in KEPT_ENTRY[s].iter().enumerate() {
                    let j_pt = f64::from(j_p[t]);
                    if entry != BACKWARD && j_pt != 0.0 {
                        kept[usize::from(entry)] += weight * j_pt;
                    }
                }
            }
        }
        let entry = |k: usize| kept[1 + k] as f32;
        for (plane, &k) in SHARED_FORWARD.iter().enumerate() {
            out.forward[plane * w + c] = entry(k);
        }
        for &k in &DATA_ONLY_FORWARD {
            out.coefficients[k * pw + HALO + c] = if *inputs.domain.at(c, r) {
                entry(k)
            } else {
                0.0
            };
        }
        out.diagonal[c] = kept[0] as f32;
        out.rhs[c] = rhs as f32;
    }
}

/// A backward stencil entry in [`KEPT_ENTRY`].
const BACKWARD: u8 = u8::MAX;

/// For slots `s` and `t` of one pixel's 5-point residual, where `J_s J_t`
/// lands in the row of slot `s`'s pixel: 0 for the diagonal, `1 + k` for
/// forward entry `FORWARD[k]`, [`BACKWARD`] for the backward half (not
/// stored).
const KEPT_ENTRY: [[u8; 5]; 5] = {
    let mut table = [[BACKWARD; 5]; 5];
    let mut s = 0;
    while s < 5 {
        let mut t = 0;
        while t < 5 {
            let dx = SLOT_OFFSET[t].0 - SLOT_OFFSET[s].0;
            let dy = SLOT_OFFSET[t].1 - SLOT_OFFSET[s].1;
            if dx == 0 && dy == 0 {
                table[s][t] = 0;
            }
            let mut k = 0;
            while k < FORWARD.len() {
                if FORWARD[k].0 == dx && FORWARD[k].1 == dy {
                    table[s][t] = 1 + k as u8;
                }
                k += 1;
            }
            t += 1;
        }
        s += 1;
    }
    table
};

/// What [`weight_row`] reads.
struct WeightInputs<'a> {
    padded_width: usize,
    width: usize,
    /// `[k_xx, k_yy, k_xy]`: `1/h_x^2`, `1/h_y^2`, `1/(4 h_x h_y)`.
    scale: [f32; 3],
    /// `[k_xx^2, k_yy^2, 2 k_xy^2]`.
    weight_scale: [f32; 3],
    inverse_lambda_squared: f32,
    dz: &'a [f32],
}

/// `W = Psi'(S^2(z^k + dz)) k^2` per stencil (0 where the stencil leaves the
/// domain, as `mask_block` says) for image row `row`.
#[inline(always)]
fn weight_row(
    inputs: &WeightInputs<'_>,
    row: usize,
    mask_block: &[u8],
    block: &mut [f32],
) -> (f64, f64) {
    let pw = inputs.padded_width;
    let n = inputs.width;
    let i0 = (row + HALO) * pw + HALO;
    let pwi = pw as isize;
    let dz = inputs.dz;
    let span = |offset: isize| {
        let start = i0.wrapping_add_signed(offset);
        &dz[start..start + n]
    };
    let (left, centre, right) = (span(-1), span(0), span(1));
    let (up, down) = (span(-pwi), span(pwi));
    let (up_left, up_right) = (span(-pwi - 1), span(-pwi + 1));
    let (down_left, down_right) = (span(pwi - 1), span(pwi + 1));
    let (inputs_part, outputs) = block.split_at_mut(SMOOTH_WEIGHT * pw);
    let plane = |k: usize| window(inputs_part, k * pw + HALO, 0, n);
    let [mxx, myy, mxy] = [0, 1, 2].map(|k| window(mask_block, k * pw + HALO, 0, n));
    let [kzxx, kzyy, kzxy] = [SMOOTH_KZ, SMOOTH_KZ + 1, SMOOTH_KZ + 2].map(plane);
    let mut planes = outputs.chunks_exact_mut(pw).map(|p| &mut p[HALO..HALO + n]);
    let mut next = || planes.next().unwrap_or_default();
    let [wxx, wyy, wxy] = [next(), next(), next()];
    let [sxx, syy, sxy] = inputs.scale;
    let [gxx, gyy, gxy] = inputs.weight_scale;
    let il2 = inputs.inverse_lambda_squared;
    let (mut changed, mut total) = (0.0f32, 0.0f32);
    for c in 0..n {
        let txx = kzxx[c] + (left[c] - 2.0 * centre[c] + right[c]);
        let tyy = kzyy[c] + (up[c] - 2.0 * centre[c] + down[c]);
        let txy = kzxy[c] + (down_right[c] - up_right[c] - down_left[c] + up_left[c]);
        let (zxx, zyy, zxy) = (txx * sxx, tyy * syy, txy * sxy);
        let (mx, my, mxy) = (f32::from(mxx[c]), f32::from(myy[c]), f32::from(mxy[c]));
        let s2 = mx * zxx * zxx + my * zyy * zyy + 2.0 * mxy * zxy * zxy;
        let psi = 1.0 / (1.0 + s2 * il2).sqrt();
        let (axx, ayy, axy) = (mx * psi * gxx, my * psi * gyy, mxy * psi * gxy);
        changed += ((axx - wxx[c]).abs() + (ayy - wyy[c]).abs()) + (axy - wxy[c]).abs();
        total += (axx + ayy) + axy;
        wxx[c] = axx;
        wyy[c] = ayy;
        wxy[c] = axy;
    }
    (f64::from(changed), f64::from(total))
}

/// `n` values of `v` from `start + offset`.
#[inline(always)]
fn window<T>(v: &[T], start: usize, offset: isize, n: usize) -> &[T] {
    let start = start.wrapping_add_signed(offset);
    &v[start..start + n]
}

/// What [`assemble_row`] reads.
struct RowInputs<'a> {
    row: usize,
    padded_width: usize,
    alpha: f64,
    data_forward: &'a [f32],
    data_diagonal: &'a [f32],
    data_rhs: &'a [f32],
    domain: &'a [bool],
    smooth: &'a [f32],
}

/// Full rows of one image row into its coefficient block: data part plus
/// `alpha` times the smoothness operator `A(Psi') = K^T W K`, right-hand side
/// `-J^T C D - alpha A z^k`.
///
/// The smoothness rows come in closed form from the per-pixel weights
/// `W = [w_xx, w_yy, w_xy]` (`Psi'_p k^2`, mixed weight doubled): a z_xx
/// stencil `(1, -2, 1)` centred at `p` contributes `w_p k_pq k_pr` to row `q`;
/// summing over the three stencils that contain `q` gives the entries below,
/// likewise for z_yy; a mixed stencil at the diagonal neighbour
/// `p = q - (a, b)` contributes `+w` at `q`, `-w` at `q + (-2a, 0)` and at
/// `q + (0, -2b)`, and `+w` at `q + (-2a, -2b)`. `A z^k` is the adjoint of the
/// stencils applied to `v = W * (K z^k)`.
#[inline(always)]
fn assemble_row<'a>(inputs: &RowInputs<'a>, block: &mut [f32]) {
    let pw = inputs.padded_width;
    let n = inputs.domain.len();
    let row = inputs.row + HALO;
    let smooth = inputs.smooth;
    // Plane `k` of padded row `row + dy`, shifted by `dx` columns.
    let span = |k: usize, dx: isize, dy: isize| {
        let start = (row.wrapping_add_signed(dy) * SMOOTH_PLANES + k) * pw + HALO;
        window(smooth, start, dx, n)
    };
    let (wxx, wyy, wxy) = (SMOOTH_WEIGHT, SMOOTH_WEIGHT + 1, SMOOTH_WEIGHT + 2);
    let (kxx, kyy, kxy) = (SMOOTH_KZ, SMOOTH_KZ + 1, SMOOTH_KZ + 2);
    let (left, here, right) = (span(wxx, -1, 0), span(wxx, 0, 0), span(wxx, 1, 0));
    let (up, here_y, down) = (span(wyy, 0, -1), span(wyy, 0, 0), span(wyy, 0, 1));
    // Mixed stencils at p = q - (a, b): names give (a, b) as m/p signs.
    let mm = span(wxy, 1, 1);
    let pm = span(wxy, -1, 1);
    let mp = span(wxy, 1, -1);
    let pp = span(wxy, -1, -1);
    let (kx_l, kx_c, kx_r) = (span(kxx, -1, 0), span(kxx, 0, 0), span(kxx, 1, 0));
    let (ky_u, ky_c, ky_d) = (span(kyy, 0, -1), span(kyy, 0, 0), span(kyy, 0, 1));
    let (k_pp, k_pm) = (span(kxy, -1, -1), span(kxy, -1, 1));
    let (k_mp, k_mm) = (span(kxy, 1, -1), span(kxy, 1, 1));
    let data_forward: [&[f32]; 6] =
        std::array::from_fn(|k| &inputs.data_forward[k * n..(k + 1) * n]);
    let (data_diagonal, data_rhs) = (&inputs.data_diagonal[..n], &inputs.data_rhs[..n]);
    let domain = &inputs.domain[..n];
    let alpha = inputs.alpha;
    let (planes, tail) = block.split_at_mut(PLANE_INVERSE_DIAGONAL * pw);
    let (inverse_plane, rhs_plane) = tail.split_at_mut(pw);
    let inverse_out = &mut inverse_plane[HALO..HALO + n];
    let rhs_out = &mut rhs_plane[HALO..HALO + n];
    let mut planes = planes
        .chunks_exact_mut(pw)
        .map(|plane| &mut plane[HALO..HALO + n]);
    let forward_out: [&mut [f32]; 8] = std::array::from_fn(|_| planes.next().unwrap_or_default());
    // Separate short loops: one long loop over all these streams does not
    // vectorise (too many live pointers).
    for c in 0..n {
        let diagonal_s = (left[c] + right[c] + 4.0 * here[c])
            + (up[c] + down[c] + 4.0 * here_y[c])
            + ((mm[c] + pm[c]) + (mp[c] + pp[c]));
        // v = W K z^k (f32, as stored before); the adjoint sums cancel: f64.
        let v = |w: &[f32], kz: &[f32]| f64::from(w[c] * kz[c]);
        let az = (v(left, kx_l) - 2.0 * v(here, kx_c) + v(right, kx_r))
            + (v(up, ky_u) - 2.0 * v(here_y, ky_c) + v(down, ky_d))
            + (v(pp, k_pp) - v(pm, k_pm) - v(mp, k_mp) + v(mm, k_mm));
        let diagonal = f64::from(data_diagonal[c]) + alpha * f64::from(diagonal_s);
        let rhs = f64::from(data_rhs[c]) - alpha * az;
        let inverse32 = (1.0 / diagonal) as f32;
        let rhs32 = rhs as f32;
        // Also rejects values that overflow f32.
        let solvable = domain[c] & (diagonal > 0.0) & inverse32.is_finite() & rhs32.is_finite();
        inverse_out[c] = if solvable { inverse32 } else { 0.0 };
        rhs_out[c] = if solvable { rhs32 } else { 0.0 };
    }
    // Forward entries in FORWARD order: (1,0), (2,0), (-1,1), (0,1), (1,1),
    // (-2,2), (0,2), (2,2); those at (-1,1) and (1,1) have no smoothness part
    // and are in place since the data part (`DATA_ONLY_FORWARD`).
    // One plain loop per entry (a macro, not a closure, so that every slice
    // is indexed directly and the loops vectorise).
    let alpha32 = alpha as f32;
    let [f0, f1, _, f3, _, f5, f6, f7] = forward_out;
    macro_rules! fill {
        ($out:expr, $k:expr, |$c:ident| $smooth:expr) => {{
            let (out, data) = (&mut $out[..n], &data_forward[$k][..n]);
            for $c in 0..n {
                let value = data[$c] + alpha32 * $smooth;
                out[$c] = if domain[$c] { value } else { 0.0 };
            }
        }};
    }
    // The data planes are in SHARED_FORWARD order.
    fill!(f0, 0, |c| -2.0 * (here[c] + right[c]));
    fill!(f1, 1, |c| right[c] - mm[c] - mp[c]);
    fill!(f3, 2, |c| -2.0 * (here_y[c] + down[c]));
    fill!(f5, 3, |c| pm[c]);
    fill!(f6, 4, |c| down[c] - mm[c] - pm[c]);
    fill!(f7, 5, |c| mm[c]);
}

/// The blocks of image rows `0..height` of a buffer laid out as padded row
/// blocks of `block_len` values (the halo rows skipped), with their image row
/// index, in parallel tasks of at least `min_rows` rows.
fn image_row_blocks<T: Send>(
    buffer: &mut [T],
    block_len: usize,
    height: usize,
    min_rows: usize,
) -> impl IndexedParallelIterator<Item = (usize, &mut [T])> {
    buffer
        .par_chunks_mut(block_len)
        .skip(HALO)
        .take(height)
        .with_min_len(min_rows)
        .enumerate()
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
        .add_smoothness(&level, alpha, 1e-3, Cancel::NEVER)
        .uncancelled();
    system
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::camera::Intrinsics;
    use crate::cancel::Uncancelled;
    use crate::model::{Lambertian, LevelGeometry};

    /// A small level with a random-looking smooth depth and a domain hole.
    fn small_level(domain_hole: bool) -> (PyramidLevel<'static>, Grid<f64>) {
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
                image: std::borrow::Cow::Owned(image),
                confidence: Confidence::from_grid(confidence, Cancel::NEVER).uncancelled(),
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
            let mut system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
            assert!(
                system
                    .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
                    .uncancelled()
            );
            system
                .add_smoothness(&level, alpha, lambda, Cancel::NEVER)
                .uncancelled();
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
                    Cancel::NEVER,
                )
                .uncancelled()
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
                    (gradient + 2.0 * f64::from(system.row(q % w, q / w).rhs)).abs()
                        < 1e-5 * (1.0 + gradient.abs()),
                    "hole={hole} q={q}: numeric {gradient} vs -2 rhs {}",
                    -2.0 * f64::from(system.row(q % w, q / w).rhs)
                );
            }
            let rows = system.explicit_rows();
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
    fn the_data_part_is_whole_across_the_blocks_of_rows() {
        // Wide enough that the data part streams its Jacobian in several
        // blocks of rows: the rows beside a block's edge read the Jacobian
        // of the next block's first row, computed twice. The right-hand
        // side there is still minus half the data energy's gradient.
        let (w, h) = (300, 3 * MIN_DATA_BLOCK_ROWS);
        assert!(rows_per_task(w).max(MIN_DATA_BLOCK_ROWS) < h);
        let camera = Intrinsics::centred(300.0, w, h);
        let depth = Grid::from_fn(w, h, |c, r| {
            2.0 + 0.05 * ((c * 7 + r * 3) as f64 * 0.1).sin() + 0.03 * (r as f64 * 0.2).cos()
        });
        let level = PyramidLevel {
            geometry: LevelGeometry::new(w, h, w, h, camera),
            image: std::borrow::Cow::Owned(Grid::from_fn(w, h, |c, r| {
                0.25 + 0.01 * ((c * 5 + r * 11) as f64).cos()
            })),
            confidence: Confidence::from_grid(
                Grid::from_fn(w, h, |c, r| if (c + r) % 5 == 0 { 0.5 } else { 1.0 }),
                Cancel::NEVER,
            )
            .uncancelled(),
            domain: Grid::filled(w, h, true),
        };
        let model = Lambertian {
            intensity_scale: 1.3,
        };
        let mut system = linearised(&level, &depth, &model);
        // alpha 0: the rows are the data part alone.
        system
            .add_smoothness(&level, 0.0, 1.0, Cancel::NEVER)
            .uncancelled();
        let data_energy = |z: &Grid<f64>| {
            model::energy(
                &model,
                &level.geometry,
                &level.image,
                &level.confidence,
                &level.domain,
                z,
                0.0,
                1.0,
                Cancel::NEVER,
            )
            .uncancelled()
            .data
        };
        let edge = rows_per_task(w).max(MIN_DATA_BLOCK_ROWS);
        for r in [edge - 2, edge - 1, edge, edge + 1, 2 * edge - 1, 2 * edge] {
            for c in [1, 150, 298] {
                let e = 1e-6;
                let mut plus = depth.clone();
                *plus.at_mut(c, r) += e;
                let mut minus = depth.clone();
                *minus.at_mut(c, r) -= e;
                let gradient = (data_energy(&plus) - data_energy(&minus)) / (2.0 * e);
                let rhs = f64::from(system.row(c, r).rhs);
                assert!(
                    (gradient + 2.0 * rhs).abs() < 1e-5 * (1.0 + gradient.abs()),
                    "({c}, {r}): numeric {gradient} vs -2 rhs {}",
                    -2.0 * rhs
                );
            }
        }
    }

    /// A new system on `level`, its data part linearised at `depth`.
    fn linearised(level: &PyramidLevel, depth: &Grid<f64>, model: &Lambertian) -> LinearSystem {
        let mut system = LinearSystem::new(level, Cancel::NEVER).uncancelled();
        assert!(
            system
                .linearise_data(model, level, depth, Derivatives::Exact, Cancel::NEVER)
                .uncancelled()
        );
        system
    }

    #[test]
    fn a_stashed_depth_comes_back_bit_for_bit_and_needs_a_new_linearisation() {
        let (level, depth) = small_level(true);
        let model = Lambertian {
            intensity_scale: 1.0,
        };
        let mut system = linearised(&level, &depth, &model);
        let odd = Grid::from_fn(9, 8, |c, r| {
            [f64::MIN_POSITIVE, -0.0, 1e300, 2.0 + (c * r) as f64 * 1e-17][(c + r) % 4]
        });
        system.stash_depth(&odd);
        let mut back = Grid::filled(9, 8, 0.0);
        system.restore_depth(&mut back);
        for (a, b) in odd.as_slice().iter().zip(back.as_slice()) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        let assembled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            system
                .add_smoothness(&level, 1.0, 1.0, Cancel::NEVER)
                .uncancelled()
        }));
        assert!(assembled.is_err(), "the data part was overwritten");
        assert!(
            system
                .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
                .uncancelled()
        );
        system
            .add_smoothness(&level, 1.0, 1.0, Cancel::NEVER)
            .uncancelled();
    }

    #[test]
    fn the_rhs_norm_is_the_residual_norm_at_zero_step() {
        // A domain with holes: unsolved pixels count in neither.
        let mut system = test_system(37, 29, |c, r| (c * 3 + r) % 11 != 0, 0.4, 1e-2);
        system.clear_dz(Cancel::NEVER).uncancelled();
        let rhs = system.rhs_norm_squared(Cancel::NEVER).uncancelled();
        let residual = system.residual_norm_squared(Cancel::NEVER).uncancelled();
        assert!(rhs > 0.0);
        assert!(
            (rhs - residual).abs() <= 1e-12 * residual,
            "{rhs} vs {residual}"
        );
        // Not at a non-zero step.
        system.dz_padded.iter_mut().for_each(|x| *x = 0.01);
        let moved = system.residual_norm_squared(Cancel::NEVER).uncancelled();
        assert!((moved - rhs).abs() > 1e-6 * rhs, "{moved} vs {rhs}");
    }

    #[test]
    fn weights_alone_leave_the_rows_until_they_are_assembled() {
        let (level, depth) = small_level(true);
        let model = Lambertian {
            intensity_scale: 1.0,
        };
        let assembled = || {
            let mut system = linearised(&level, &depth, &model);
            system
                .add_smoothness(&level, 0.5, 0.1, Cancel::NEVER)
                .uncancelled();
            system
        };
        let (mut fused, mut split) = (assembled(), assembled());
        // A step moves Psi': the weights change, the rows stay until assembled.
        for system in [&mut fused, &mut split] {
            system
                .dz_padded
                .iter_mut()
                .enumerate()
                .for_each(|(i, x)| *x = 0.05 * (i as f32 * 0.37).sin());
        }
        let before = split.coefficients.clone();
        let change = split
            .update_weights(&level, 0.1, Cancel::NEVER)
            .uncancelled();
        assert!(change > 0.0);
        assert_eq!(split.coefficients, before);
        split.assemble(&level, 0.5, Cancel::NEVER).uncancelled();
        assert_eq!(
            fused
                .add_smoothness(&level, 0.5, 0.1, Cancel::NEVER)
                .uncancelled(),
            change
        );
        assert_eq!(split.coefficients, fused.coefficients);
        assert_ne!(split.coefficients, before);
    }

    #[test]
    fn the_kept_entries_are_the_diagonal_and_the_forward_half() {
        for (s, &(sx, sy)) in SLOT_OFFSET.iter().enumerate() {
            for (t, &(tx, ty)) in SLOT_OFFSET.iter().enumerate() {
                let offset = (tx - sx, ty - sy);
                let entry = KEPT_ENTRY[s][t];
                assert!(STENCIL.contains(&offset));
                if offset == (0, 0) {
                    assert_eq!(entry, 0);
                } else if let Some(k) = FORWARD.iter().position(|&f| f == offset) {
                    assert_eq!(usize::from(entry), 1 + k);
                } else {
                    assert_eq!(entry, BACKWARD);
                    assert!(FORWARD.contains(&(-offset.0, -offset.1)));
                }
            }
        }
    }
}
