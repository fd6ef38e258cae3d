//! The system's memory layout: the 17-point stencil's offsets, the
//! forward half stored per pixel, the halo and the planes of each padded
//! row. Below both the system (`system.rs`, which re-exports the public
//! ones) and its row kernels (`rows`). Uses nothing.

/// Offsets `(dx, dy)` of the 17-point stencil; entry 0 is the pixel itself,
/// entry 1 its left neighbour (the one SOR has just updated), the rest grouped
/// by row so the sweep can address each row with one pointer.
#[rustfmt::skip] // a line per row of the stencil
pub const STENCIL: [(isize, isize); 17] = [
    (0, 0), (-1, 0),
    (-2, -2), (0, -2), (2, -2),
    (-1, -1), (0, -1), (1, -1),
    (-2, 0), (1, 0), (2, 0),
    (-1, 1), (0, 1), (1, 1),
    (-2, 2), (0, 2), (2, 2),
];

/// Offsets of the 5-point slots `[centre, left, right, up, down]`.
pub(super) const SLOT_OFFSET: [(isize, isize); 5] = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)];

/// Halo (rows/columns) around the padded vectors so that stencil reads never
/// leave them.
pub const HALO: usize = 2;

/// Offsets of the 8 *forward* stencil entries (after the pixel in row-major
/// order). The matrix is symmetric: the coefficient of a backward offset `-o`
/// in row `q` is the forward coefficient `o` stored with the pixel `q - o`.
#[rustfmt::skip] // a line per row of the stencil
pub const FORWARD: [(isize, isize); 8] = [
    (1, 0), (2, 0),
    (-1, 1), (0, 1), (1, 1),
    (-2, 2), (0, 2), (2, 2),
];

/// Planes per padded row of [`LinearSystem::coefficients`](super::LinearSystem::coefficients): the 8 forward
/// coefficients, then `1 / diagonal`, then the right-hand side.
pub const PLANES: usize = 10;
/// Plane of `1 / diagonal` in a row block.
pub const PLANE_INVERSE_DIAGONAL: usize = 8;
/// Plane of the right-hand side in a row block.
pub const PLANE_RHS: usize = 9;

/// Planes per padded row of [`LinearSystem::smooth`](super::LinearSystem::smooth):
/// the weights `[xx, yy, xy]`.
pub(super) const SMOOTH_PLANES: usize = 3;
/// First of the three `[xx, yy, xy]` weight planes in a smoothness row block.
pub(super) const SMOOTH_WEIGHT: usize = 0;
/// Planes per padded row of `K z^k` as the row kernels compute it (`[xx,
/// yy, xy]`, `rows::kz_row`); held only for the rows a task is working on.
pub(super) const KZ_PLANES: usize = 3;
/// Planes per padded row of [`LinearSystem::masks`](super::LinearSystem::masks):
/// one plane of bytes, the stencils `[xx, yy, xy]` as the bits
/// [`MASK_XX`], [`MASK_YY`], [`MASK_XY`] (1 byte per pixel, not 3).
pub(super) const MASK_PLANES: usize = 1;
/// The bit of the `z_xx` stencil in a mask byte.
pub(super) const MASK_XX: u8 = 1;
/// The bit of the `z_yy` stencil in a mask byte.
pub(super) const MASK_YY: u8 = 2;
/// The bit of the mixed stencil in a mask byte.
pub(super) const MASK_XY: u8 = 4;
