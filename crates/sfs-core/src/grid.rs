//! A dense 2-D grid of values in row-major order, the image/depth/mask container
//! shared by every layer.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cancel::{Cancel, Cancelled};

/// Rows per parallel task of a pass over a `width`-pixel-wide image (about
/// 8192 pixels), so that small images run as one task.
pub fn rows_per_task(width: usize) -> usize {
    (8192 / width.max(1)).max(1)
}

/// Runs `row(r, values_of_row_r)` over the rows of the row-major buffer
/// `values` (`width` wide), rows in parallel, polling `cancel` before each
/// row and skipping the rest once it says yes; `Err` then (the buffer is
/// incomplete).
pub fn for_rows<T: Send>(
    values: &mut [T],
    width: usize,
    cancel: Cancel<'_>,
    row: impl Fn(usize, &mut [T]) + Sync,
) -> Result<(), Cancelled> {
    values
        .par_chunks_mut(width.max(1))
        .enumerate()
        .with_min_len(rows_per_task(width))
        .for_each(|(r, values)| {
            if !cancel.is_cancelled() {
                row(r, values);
            }
        });
    cancel.check()
}

/// A dense row-major 2-D array: `data[row * width + column]`.
///
/// Column `i` runs along image x (left to right), row `j` along image y (top to
/// bottom), as in METHOD.md section 1.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Grid<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

impl<T: Clone> Grid<T> {
    /// A `width` x `height` grid filled with `value`.
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }
}

impl<T> Grid<T> {
    /// Wraps `data` (row-major, `width * height` values).
    ///
    /// Returns `None` when the length does not match the size.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Option<Self> {
        (data.len() == width * height).then_some(Self {
            width,
            height,
            data,
        })
    }

    /// Builds a grid by calling `f(column, row)` for every cell.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for row in 0..height {
            for column in 0..width {
                data.push(f(column, row));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True when the grid has no cells.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Row-major index of `(column, row)`.
    #[inline]
    pub fn index(&self, column: usize, row: usize) -> usize {
        row * self.width + column
    }

    /// The value at `(column, row)`; panics outside the grid.
    #[inline]
    pub fn at(&self, column: usize, row: usize) -> &T {
        &self.data[row * self.width + column]
    }

    /// Mutable value at `(column, row)`; panics outside the grid.
    #[inline]
    pub fn at_mut(&mut self, column: usize, row: usize) -> &mut T {
        &mut self.data[row * self.width + column]
    }

    /// The value at `(column, row)` with the coordinates clamped into the grid
    /// (Neumann border: the nearest edge value continues outwards).
    #[inline]
    pub fn at_clamped(&self, column: isize, row: isize) -> &T {
        let c = column.clamp(0, self.width as isize - 1) as usize;
        let r = row.clamp(0, self.height as isize - 1) as usize;
        &self.data[r * self.width + c]
    }

    /// All values, row-major.
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    /// All values, row-major, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// Consumes the grid and returns its row-major values.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// A new grid of the same size with `f` applied to every value.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Grid<U> {
        Grid {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }

    /// A new grid with `f` applied to the values of `self` and `other` at
    /// each pixel; `other` must have the same size (extra values of the
    /// larger one are ignored otherwise).
    pub fn zip_map<U, V>(&self, other: &Grid<U>, mut f: impl FnMut(&T, &U) -> V) -> Grid<V> {
        Grid {
            width: self.width,
            height: self.height,
            data: self
                .data
                .iter()
                .zip(&other.data)
                .map(|(a, b)| f(a, b))
                .collect(),
        }
    }
}

impl Grid<f64> {
    /// The finite values, in pixel order (NaN and infinities left out).
    pub fn finite_values(&self) -> Vec<f64> {
        self.data
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect()
    }

    /// The finite positive values, in pixel order: what a depth or an
    /// albedo holds where it is known.
    pub fn finite_positive_values(&self) -> Vec<f64> {
        self.data
            .iter()
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect()
    }

    /// The largest `|a - b|` over the pixels of this grid and `other` in
    /// pixel order, as far as the shorter goes (0 for none; NaN skipped).
    pub fn max_abs_difference(&self, other: &Grid<f64>) -> f64 {
        self.data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }
}

/// Per-pixel weights in [0, 1] read by index (`row * width + column`): a
/// confidence map, as a plain `Grid<f64>` or as a compact [`Confidence`].
pub trait Weights: Sync {
    /// The weight of pixel `index`.
    fn weight(&self, index: usize) -> f64;
}

impl Weights for Grid<f64> {
    #[inline]
    fn weight(&self, index: usize) -> f64 {
        self.data[index]
    }
}

/// A confidence map in [0, 1] as the solver holds it: one byte per pixel
/// where every value is 0 or 1 (no partial weights painted: the common case,
/// 7 bytes per pixel less than `f64` at the solve's peak), the weights
/// themselves otherwise. Reads give the same `f64` values either way.
#[derive(Clone, Debug, PartialEq)]
pub enum Confidence {
    /// Every value is 0 (`false`) or 1 (`true`).
    Binary(Grid<bool>),
    /// Any values in [0, 1].
    Weights(Grid<f64>),
}

impl Confidence {
    /// `grid`, stored as [`Confidence::Binary`] when every value is exactly 0
    /// or 1; by rows in parallel, polling `cancel` per row. The `f64` grid a
    /// binary confidence replaces is freed on rayon's pool.
    pub fn from_grid(grid: Grid<f64>, cancel: Cancel<'_>) -> Result<Self, Cancelled> {
        let (width, height) = grid.size();
        let binary = grid
            .data
            .par_chunks(width.max(1))
            .with_min_len(rows_per_task(width))
            .all(|row| !cancel.is_cancelled() && row.iter().all(|&v| v == 0.0 || v == 1.0));
        cancel.check()?;
        if !binary {
            return Ok(Confidence::Weights(grid));
        }
        let mut bits = Grid::filled(width, height, false);
        let whole = for_rows(bits.as_mut_slice(), width, cancel, |r, row| {
            for (bit, &value) in row.iter_mut().zip(&grid.data[r * width..]) {
                *bit = value == 1.0;
            }
        });
        rayon::spawn(move || drop(grid));
        whole.map(|()| Confidence::Binary(bits))
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        match self {
            Confidence::Binary(grid) => grid.size(),
            Confidence::Weights(grid) => grid.size(),
        }
    }

    /// The value at `(column, row)`.
    #[inline]
    pub fn at(&self, column: usize, row: usize) -> f64 {
        match self {
            Confidence::Binary(grid) => f64::from(u8::from(*grid.at(column, row))),
            Confidence::Weights(grid) => *grid.at(column, row),
        }
    }

    /// The values as a `Grid<f64>` (a copy).
    pub fn to_grid(&self) -> Grid<f64> {
        match self {
            Confidence::Binary(grid) => grid.map(|&v| if v { 1.0 } else { 0.0 }),
            Confidence::Weights(grid) => grid.clone(),
        }
    }
}

impl Weights for Confidence {
    #[inline]
    fn weight(&self, index: usize) -> f64 {
        match self {
            Confidence::Binary(grid) => {
                if grid.data[index] {
                    1.0
                } else {
                    0.0
                }
            }
            Confidence::Weights(grid) => grid.data[index],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cancel::Uncancelled;

    #[test]
    fn a_confidence_reads_the_values_it_was_given_in_either_storage() {
        let binary = Grid::from_fn(5, 3, |c, r| if (c + r) % 2 == 0 { 1.0 } else { 0.0 });
        let partial = Grid::from_fn(5, 3, |c, r| if c == 4 { 0.25 } else { (r % 2) as f64 });
        for (grid, compact) in [(binary, true), (partial, false)] {
            let confidence = Confidence::from_grid(grid.clone(), Cancel::NEVER).uncancelled();
            assert_eq!(matches!(confidence, Confidence::Binary(_)), compact);
            assert_eq!(confidence.size(), (5, 3));
            assert_eq!(confidence.to_grid(), grid);
            for r in 0..3 {
                for c in 0..5 {
                    let q = grid.index(c, r);
                    assert_eq!(confidence.at(c, r).to_bits(), grid.at(c, r).to_bits());
                    assert_eq!(confidence.weight(q).to_bits(), grid.weight(q).to_bits());
                }
            }
        }
    }

    #[test]
    fn indexing_is_row_major() {
        let g = Grid::from_fn(3, 2, |c, r| 10 * r + c);
        assert_eq!(*g.at(2, 1), 12);
        assert_eq!(g.as_slice(), &[0, 1, 2, 10, 11, 12]);
        assert_eq!(*g.at_clamped(-1, 5), 10);
        assert!(Grid::from_vec(2, 2, vec![0; 3]).is_none());
    }
}
