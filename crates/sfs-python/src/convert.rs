//! Values on their way to and from Python: the failures (`OSError`,
//! `KeyboardInterrupt`, `ValueError`) and the grids as numpy arrays.

use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyValueError};
use pyo3::prelude::*;

use sfs_core::grid::Grid;
use sfs_core::io::IoError;
use sfs_core::photo::PhotoError;
use sfs_core::photograph_solve::PhotographSolveError;
use sfs_core::solver::SolveError;

use crate::options::OptionError;

/// A failure on its way to Python: an `OSError` for files, a
/// `KeyboardInterrupt` for a cancelled solve, else a `ValueError`.
pub enum Failure {
    /// A file could not be read or written.
    Io(String),
    /// The solve was cancelled (Ctrl+C).
    Cancelled,
    /// Bad input.
    Value(String),
    /// An error raised in Python (a progress callback), passed on.
    Python(PyErr),
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> Self {
        match f {
            Failure::Io(m) => PyOSError::new_err(m),
            Failure::Cancelled => PyKeyboardInterrupt::new_err("the solve was cancelled"),
            Failure::Value(m) => PyValueError::new_err(m),
            Failure::Python(e) => e,
        }
    }
}

impl From<OptionError> for Failure {
    fn from(e: OptionError) -> Self {
        Failure::Value(e.0)
    }
}

impl From<IoError> for Failure {
    fn from(e: IoError) -> Self {
        Failure::Io(e.to_string())
    }
}

impl From<PhotoError> for Failure {
    fn from(e: PhotoError) -> Self {
        match e {
            PhotoError::Io(io) => Failure::Io(io.to_string()),
            other => Failure::Value(other.to_string()),
        }
    }
}

impl From<PyErr> for Failure {
    fn from(e: PyErr) -> Self {
        Failure::Python(e)
    }
}

impl Failure {
    /// A solve's failure, `what` naming what was solved ("cannot solve
    /// FILE: ...", as the command line says it).
    pub fn of_solve(what: &str, e: SolveError) -> Self {
        match e {
            SolveError::Cancelled => Failure::Cancelled,
            other => Failure::Value(format!("{what}: {other}")),
        }
    }

    /// A photograph solve's failure.
    pub fn of_photograph(what: &str, e: PhotographSolveError) -> Self {
        match e {
            PhotographSolveError::Solve(s) => Self::of_solve(what, s),
            other => Failure::Value(format!("{what}: {other}")),
        }
    }
}

/// A grid as a float32 array, H x W (moved, not copied, into numpy).
pub fn array2<'py>(py: Python<'py>, grid: &Grid<f64>) -> Bound<'py, PyArray2<f32>> {
    let (w, h) = grid.size();
    let values: Vec<f32> = grid.as_slice().iter().map(|&v| v as f32).collect();
    match Array2::from_shape_vec((h, w), values) {
        Ok(a) => a.into_pyarray(py),
        // A grid's length is its width times its height.
        Err(_) => Array2::<f32>::zeros((h, w)).into_pyarray(py),
    }
}

/// A grid of vectors as a float32 array, H x W x 3.
pub fn array3<'py>(py: Python<'py>, grid: &Grid<[f64; 3]>) -> Bound<'py, PyArray3<f32>> {
    let (w, h) = grid.size();
    let values: Vec<f32> = grid
        .as_slice()
        .iter()
        .flat_map(|v| v.map(|c| c as f32))
        .collect();
    match Array3::from_shape_vec((h, w, 3), values) {
        Ok(a) => a.into_pyarray(py),
        Err(_) => Array3::<f32>::zeros((h, w, 3)).into_pyarray(py),
    }
}
