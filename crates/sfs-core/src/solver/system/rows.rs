//! The row kernels of the system's passes: one image row's residual and
//! Jacobian, its data part, its smoothness weights and its full rows.

use rayon::prelude::*;

use super::layout::{
    FORWARD, HALO, KZ_PLANES, MASK_PLANES, MASK_XX, MASK_XY, MASK_YY, PLANE_INVERSE_DIAGONAL,
    SLOT_OFFSET, SMOOTH_PLANES, SMOOTH_WEIGHT,
};
use crate::grid::{Confidence, Grid, Weights};
use crate::model::{self, Derivatives, Reflectance};
use crate::solver::pyramid::PyramidLevel;

/// The [`FORWARD`] entries with a data part and a smoothness part (the data
/// part keeps a copy of them to add each inner iteration's smoothness part
/// to).
pub(super) const SHARED_FORWARD: [usize; 4] = [0, 1, 3, 6];
/// The [`FORWARD`] entries with a smoothness part only, `(-2, 2)` and `(2,
/// 2)`: the residual's 5-point slots are never two rows and two columns
/// apart, so the data part there is 0 and not stored (8 bytes per pixel).
pub(super) const SMOOTH_ONLY_FORWARD: [usize; 2] = [5, 7];
/// The [`FORWARD`] entries with a data part only, `(-1, 1)` and `(1, 1)`:
/// written into the coefficients once per outer iteration.
pub(super) const DATA_ONLY_FORWARD: [usize; 2] = [2, 4];

/// Image rows per task of the data part at least: the two extra Jacobian
/// rows each task computes are then a few per cent of its work.
pub(super) const MIN_DATA_BLOCK_ROWS: usize = 32;

/// The residual `D` and its Jacobian (5 slots) of image row `row` at
/// `depth`, stored in f32 (0 off the domain; a value that f32 cannot hold
/// leaves the pixel out of the data term, like a non-finite one). False when
/// the model cannot give the requested derivatives.
pub(super) fn linearise_row<M: Reflectance + ?Sized>(
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
pub(super) struct DataRowInputs<'a> {
    pub(super) row: usize,
    pub(super) first_pixel_row: usize,
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) residual: &'a [f32],
    pub(super) jacobian: &'a [[f32; 5]],
    pub(super) confidence: &'a Confidence,
    pub(super) domain: &'a Grid<bool>,
}

/// Where [`data_row`] writes one image row.
pub(super) struct DataRowOutputs<'a> {
    /// The [`SHARED_FORWARD`] entries, a plane each.
    pub(super) forward: &'a mut [f32],
    pub(super) diagonal: &'a mut [f32],
    pub(super) rhs: &'a mut [f32],
    /// The row's block of [`LinearSystem::coefficients`], which gets the
    /// [`DATA_ONLY_FORWARD`] entries (0 off the domain).
    pub(super) coefficients: &'a mut [f32],
}

/// The data part of image row `row`: `J^T C J` (forward entries, the
/// diagonal) and `-J^T C D`.
pub(super) fn data_row(inputs: &DataRowInputs<'_>, out: DataRowOutputs<'_>) {
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
pub(super) const BACKWARD: u8 = u8::MAX;

/// For slots `s` and `t` of one pixel's 5-point residual, where `J_s J_t`
/// lands in the row of slot `s`'s pixel: 0 for the diagonal, `1 + k` for
/// forward entry `FORWARD[k]`, [`BACKWARD`] for the backward half (not
/// stored).
pub(super) const KEPT_ENTRY: [[u8; 5]; 5] = {
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

/// `K z^k` of image row `row` of the linearisation point `z` (`width x
/// height`, row-major): `z[-1] - 2 z + z[+1]` across and down and the
/// four-point mixed difference, in f64 (z is large, the differences small)
/// and rounded to f32, into the `[xx, yy, xy]` planes of `out` ([`KZ_PLANES`]
/// planes of the padded width; the halo is not written). 0 where
/// `mask_block` (the row's [`MASK_PLANES`] of stencil masks) says the stencil
/// leaves the domain, so that `W K z^k` is 0 there whatever the depth off
/// the domain. Neighbours past the grid's edge read the edge pixel (their
/// masks are 0).
///
/// Computed where it is used, by the weights' pass and the assembly, rather
/// than stored for the level (12 bytes per pixel); the same values as
/// stored ones.
#[inline(always)]
pub(super) fn kz_row(
    z: &[f64],
    width: usize,
    height: usize,
    row: usize,
    mask_block: &[u8],
    out: &mut [f32],
) {
    let (w, pw) = (width, width + 2 * HALO);
    let up = &z[row.saturating_sub(1) * w..][..w];
    let mid = &z[row * w..][..w];
    let down = &z[(row + 1).min(height - 1) * w..][..w];
    let mask = window(mask_block, HALO, 0, w);
    debug_assert_eq!(mask_block.len(), MASK_PLANES * pw);
    let mut planes = out[..KZ_PLANES * pw]
        .chunks_exact_mut(pw)
        .map(|p| &mut p[HALO..HALO + w]);
    let mut next = || planes.next().unwrap_or_default();
    let [xx, yy, xy] = [next(), next(), next()];
    let kept = |m: u8, bit: u8, v: f64| if m & bit != 0 { v as f32 } else { 0.0 };
    // One column with its neighbours clamped to the grid.
    let mut column = |c: usize| {
        let (l, r) = (c.saturating_sub(1), (c + 1).min(w - 1));
        let centre = 2.0 * mid[c];
        xx[c] = kept(mask[c], MASK_XX, mid[l] - centre + mid[r]);
        yy[c] = kept(mask[c], MASK_YY, up[c] - centre + down[c]);
        xy[c] = kept(mask[c], MASK_XY, down[r] - up[r] - down[l] + up[l]);
    };
    column(0);
    column(w - 1);
    if w < 3 {
        return;
    }
    // The interior as straight loops over equal slices (they vectorise):
    // column c = i + 1, the same arithmetic as `column`.
    let n = w - 2;
    let (ml, mc, mr) = (&mid[..n], &mid[1..n + 1], &mid[2..n + 2]);
    let (ul, uc, ur) = (&up[..n], &up[1..n + 1], &up[2..n + 2]);
    let (dl, dc, dr) = (&down[..n], &down[1..n + 1], &down[2..n + 2]);
    let mask = &mask[1..n + 1];
    let (xx, yy, xy) = (&mut xx[1..n + 1], &mut yy[1..n + 1], &mut xy[1..n + 1]);
    for i in 0..n {
        let centre = 2.0 * mc[i];
        xx[i] = kept(mask[i], MASK_XX, ml[i] - centre + mr[i]);
    }
    for i in 0..n {
        let centre = 2.0 * mc[i];
        yy[i] = kept(mask[i], MASK_YY, uc[i] - centre + dc[i]);
    }
    for i in 0..n {
        xy[i] = kept(mask[i], MASK_XY, dr[i] - ur[i] - dl[i] + ul[i]);
    }
}

/// What [`weight_row`] reads.
pub(super) struct WeightInputs<'a> {
    pub(super) padded_width: usize,
    pub(super) width: usize,
    /// `[k_xx, k_yy, k_xy]`: `1/h_x^2`, `1/h_y^2`, `1/(4 h_x h_y)`.
    pub(super) scale: [f32; 3],
    /// `[k_xx^2, k_yy^2, 2 k_xy^2]`.
    pub(super) weight_scale: [f32; 3],
    pub(super) inverse_lambda_squared: f32,
    pub(super) dz: &'a [f32],
}

/// `W = Psi'(S^2(z^k + dz)) k^2` per stencil (0 where the stencil leaves the
/// domain, as `mask_block` says) for image row `row`, from the row's `K z^k`
/// (`kz`, as [`kz_row`] writes it) into its block of weights.
#[inline(always)]
pub(super) fn weight_row(
    inputs: &WeightInputs<'_>,
    row: usize,
    mask_block: &[u8],
    kz: &[f32],
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
    let plane = |k: usize| window(kz, k * pw + HALO, 0, n);
    let mask = window(mask_block, HALO, 0, n);
    let [kzxx, kzyy, kzxy] = [0, 1, 2].map(plane);
    let mut planes = block[SMOOTH_WEIGHT * pw..(SMOOTH_WEIGHT + 3) * pw]
        .chunks_exact_mut(pw)
        .map(|p| &mut p[HALO..HALO + n]);
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
        let bit = |b: u8| f32::from(u8::from(mask[c] & b != 0));
        let (mx, my, mxy) = (bit(MASK_XX), bit(MASK_YY), bit(MASK_XY));
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
pub(super) struct RowInputs<'a> {
    pub(super) row: usize,
    pub(super) padded_width: usize,
    pub(super) alpha: f64,
    pub(super) data_forward: &'a [f32],
    pub(super) data_diagonal: &'a [f32],
    pub(super) data_rhs: &'a [f32],
    pub(super) domain: &'a [bool],
    /// The weights' row blocks of the whole level.
    pub(super) smooth: &'a [f32],
    /// `K z^k` of image rows `row - 1`, `row`, `row + 1` ([`kz_row`]'s
    /// planes; all 0 for a row outside the image).
    pub(super) kz: [&'a [f32]; 3],
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
pub(super) fn assemble_row<'a>(inputs: &RowInputs<'a>, block: &mut [f32]) {
    let pw = inputs.padded_width;
    let n = inputs.domain.len();
    let row = inputs.row + HALO;
    let smooth = inputs.smooth;
    // Plane `k` of padded row `row + dy`, shifted by `dx` columns.
    let span = |k: usize, dx: isize, dy: isize| {
        let start = (row.wrapping_add_signed(dy) * SMOOTH_PLANES + k) * pw + HALO;
        window(smooth, start, dx, n)
    };
    // Plane `k` of `K z^k` in image row `row + dy` (`dy` in -1..=1),
    // shifted by `dx` columns.
    let kz_span = |k: usize, dx: isize, dy: isize| {
        let rows = inputs.kz[dy.wrapping_add(1) as usize];
        window(rows, k * pw + HALO, dx, n)
    };
    let (wxx, wyy, wxy) = (SMOOTH_WEIGHT, SMOOTH_WEIGHT + 1, SMOOTH_WEIGHT + 2);
    let (kxx, kyy, kxy) = (0, 1, 2);
    let (left, here, right) = (span(wxx, -1, 0), span(wxx, 0, 0), span(wxx, 1, 0));
    let (up, here_y, down) = (span(wyy, 0, -1), span(wyy, 0, 0), span(wyy, 0, 1));
    // Mixed stencils at p = q - (a, b): names give (a, b) as m/p signs.
    let mm = span(wxy, 1, 1);
    let pm = span(wxy, -1, 1);
    let mp = span(wxy, 1, -1);
    let pp = span(wxy, -1, -1);
    let (kx_l, kx_c, kx_r) = (kz_span(kxx, -1, 0), kz_span(kxx, 0, 0), kz_span(kxx, 1, 0));
    let (ky_u, ky_c, ky_d) = (kz_span(kyy, 0, -1), kz_span(kyy, 0, 0), kz_span(kyy, 0, 1));
    let (k_pp, k_pm) = (kz_span(kxy, -1, -1), kz_span(kxy, -1, 1));
    let (k_mp, k_mm) = (kz_span(kxy, 1, -1), kz_span(kxy, 1, 1));
    let data_forward: [&[f32]; SHARED_FORWARD.len()] =
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
    // and are in place since the data part (`DATA_ONLY_FORWARD`); those at
    // (-2,2) and (2,2) have no data part (`SMOOTH_ONLY_FORWARD`: a stored
    // data part of 0, as once).
    // One plain loop per entry (a macro, not a closure, so that every slice
    // is indexed directly and the loops vectorise).
    let alpha32 = alpha as f32;
    let [f0, f1, _, f3, _, f5, f6, f7] = forward_out;
    const { assert!(SMOOTH_ONLY_FORWARD[0] == 5 && SMOOTH_ONLY_FORWARD[1] == 7) };
    macro_rules! fill {
        ($out:expr, $k:expr, |$c:ident| $smooth:expr) => {{
            let (out, data) = (&mut $out[..n], &data_forward[$k][..n]);
            for $c in 0..n {
                let value = data[$c] + alpha32 * $smooth;
                out[$c] = if domain[$c] { value } else { 0.0 };
            }
        }};
        ($out:expr, |$c:ident| $smooth:expr) => {{
            let out = &mut $out[..n];
            for $c in 0..n {
                // `0 + x`, as with a stored data part of 0 (it turns -0 into 0).
                let value = 0.0f32 + alpha32 * $smooth;
                out[$c] = if domain[$c] { value } else { 0.0 };
            }
        }};
    }
    // The data planes are in SHARED_FORWARD order.
    fill!(f0, 0, |c| -2.0 * (here[c] + right[c]));
    fill!(f1, 1, |c| right[c] - mm[c] - mp[c]);
    fill!(f3, 2, |c| -2.0 * (here_y[c] + down[c]));
    fill!(f5, |c| pm[c]);
    fill!(f6, 3, |c| down[c] - mm[c] - pm[c]);
    fill!(f7, |c| mm[c]);
}

/// `K z^k` of three consecutive image rows, kept by one task of the
/// assembly as it walks its rows in order: each row is computed once per
/// task (the first row's neighbours above once more), not stored for the
/// level.
pub(super) struct KzRows {
    /// Three slots of [`KZ_PLANES`] padded planes; image row `x` lives in
    /// slot `x mod 3`.
    values: Vec<f32>,
    /// The image row in each slot (`isize::MIN`: none yet).
    rows: [isize; 3],
    padded_width: usize,
}

impl KzRows {
    /// Empty slots for rows of `padded_width`.
    pub(super) fn new(padded_width: usize) -> Self {
        Self {
            values: vec![0.0; 3 * KZ_PLANES * padded_width],
            rows: [isize::MIN; 3],
            padded_width,
        }
    }

    /// `K z^k` of image rows `row - 1`, `row` and `row + 1` of `z` (`width x
    /// height`; a row outside the image is all 0), with the stencils' masks
    /// `masks` of the whole level (row blocks of [`MASK_PLANES`] padded
    /// planes), computing only the rows not already held.
    #[inline(always)]
    pub(super) fn around(
        &mut self,
        z: &[f64],
        (width, height): (usize, usize),
        masks: &[u8],
        row: usize,
    ) -> [&[f32]; 3] {
        let pw = self.padded_width;
        let len = KZ_PLANES * pw;
        let row = row as isize;
        for x in row - 1..=row + 1 {
            let slot = x.rem_euclid(3) as usize;
            if self.rows[slot] == x {
                continue;
            }
            let out = &mut self.values[slot * len..(slot + 1) * len];
            if x < 0 || x as usize >= height {
                out.fill(0.0);
            } else {
                let x = x as usize;
                let mask_block = &masks[(x + HALO) * MASK_PLANES * pw..][..MASK_PLANES * pw];
                kz_row(z, width, height, x, mask_block, out);
            }
            self.rows[slot] = x;
        }
        let at = |x: isize| {
            let slot = x.rem_euclid(3) as usize;
            &self.values[slot * len..(slot + 1) * len]
        };
        [at(row - 1), at(row), at(row + 1)]
    }
}

/// The blocks of image rows `0..height` of a buffer laid out as padded row
/// blocks of `block_len` values (the halo rows skipped), with their image row
/// index, in parallel tasks of at least `min_rows` rows.
pub(super) fn image_row_blocks<T: Send>(
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
