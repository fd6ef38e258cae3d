//! The native half of the Python package `sfs_studio` (imported as
//! `sfs_studio._native`; the Python half, `python/sfs_studio/`, turns
//! arrays and dicts into files and keyword options into JSON and wraps the
//! results). Every function here runs the core's own code: the photo
//! pipeline and [`sfs_core::photograph_solve`] for one photograph, the
//! core's photometric stereo for a set, the core's output writer
//! ([`sfs_core::output::write_solved`]) for the files `sfs-studio solve`
//! writes. Solves run with the GIL released; Ctrl+C cancels them (the
//! solver's observer) and raises `KeyboardInterrupt`.
//!
//! Errors: files that cannot be read or written raise `OSError`, anything
//! else the user gave raises `ValueError`, with the command line's
//! messages.

mod convert;
mod options;
mod run;

use std::path::{Path, PathBuf};

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;

use sfs_core::io::{self, SrgbMode};

use convert::{Failure, array2};

/// Reads a photograph as the command line does (sRGB decoding by `srgb`:
/// `on`, `off` or `auto`; EXIF orientation; 8/16-bit PNG, TIFF incl.
/// float, JPEG; colour to luminance): linear values, float32, H x W.
#[pyfunction]
#[pyo3(signature = (path, srgb = "auto"))]
fn read_image<'py>(
    py: Python<'py>,
    path: PathBuf,
    srgb: &str,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let mode = match srgb {
        "auto" => SrgbMode::Auto,
        "on" => SrgbMode::On,
        "off" => SrgbMode::Off,
        other => {
            return Err(PyValueError::new_err(format!(
                "srgb={other}: expected on, off or auto"
            )));
        }
    };
    let photo = py
        .detach(|| io::read_photo(&path, mode))
        .map_err(|e| PyErr::from(Failure::from(e)))?;
    Ok(array2(py, &photo.image))
}

/// Writes a float32 H x W array as a one-channel float32 TIFF (read back
/// bit for bit by the photo pipeline, which takes float images as linear):
/// how an array becomes the pipeline's input.
#[pyfunction]
fn write_float_tiff(path: PathBuf, image: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
    let view = image.as_array();
    let (h, w) = view.dim();
    let values: Vec<f32> = view.iter().copied().collect();
    write_tiff(&path, w, h, &values).map_err(PyOSError::new_err)
}

/// The TIFF writer of [`write_float_tiff`].
fn write_tiff(path: &Path, width: usize, height: usize, values: &[f32]) -> Result<(), String> {
    use tiff::encoder::{TiffEncoder, colortype};
    let cannot = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|e| cannot(&e))?;
    let mut encoder = TiffEncoder::new(std::io::BufWriter::new(file)).map_err(|e| cannot(&e))?;
    let (w, h) = (
        u32::try_from(width).map_err(|e| cannot(&e))?,
        u32::try_from(height).map_err(|e| cannot(&e))?,
    );
    encoder
        .write_image::<colortype::Gray32Float>(w, h, values)
        .map_err(|e| cannot(&e))
}

/// The photographs `paths` names (the core's rule, as `sfs-studio solve
/// --out-dir`): a folder's photographs sorted, a pattern's matches sorted,
/// files as given.
#[pyfunction]
fn photographs(paths: Vec<PathBuf>) -> PyResult<Vec<PathBuf>> {
    sfs_core::output::many::photographs(&paths).map_err(|e| PyErr::from(Failure::from(e)))
}

/// Each photograph's output folder name (its stem, or its file name where
/// two share a stem), as `sfs-studio solve --out-dir`.
#[pyfunction]
fn folder_names(paths: Vec<PathBuf>) -> Vec<String> {
    sfs_core::output::many::folder_names(&paths)
}

/// One summary row as Python sends it: file, seconds, fit, warnings,
/// error.
type RowTuple = (PathBuf, f64, Option<f64>, Vec<String>, Option<String>);

/// The summary table's text, as `sfs-studio solve --out-dir` prints it.
#[pyfunction]
fn format_table(rows: Vec<RowTuple>) -> String {
    let rows: Vec<sfs_core::output::many::Row> = rows
        .into_iter()
        .map(
            |(file, seconds, fit, warnings, error)| sfs_core::output::many::Row {
                file,
                seconds,
                fit,
                warnings,
                error,
            },
        )
        .collect();
    sfs_core::output::many::table(&rows)
}

/// The Python module `sfs_studio._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(write_float_tiff, m)?)?;
    m.add_function(wrap_pyfunction!(photographs, m)?)?;
    m.add_function(wrap_pyfunction!(folder_names, m)?)?;
    m.add_function(wrap_pyfunction!(format_table, m)?)?;
    m.add_function(wrap_pyfunction!(run::solve_photograph, m)?)?;
    m.add_function(wrap_pyfunction!(run::solve_set, m)?)?;
    m.add_function(wrap_pyfunction!(run::synth_set, m)?)?;
    m.add_function(wrap_pyfunction!(run::synth_sombrero, m)?)?;
    m.add_function(wrap_pyfunction!(run::evaluate, m)?)?;
    m.add("DEFAULT_MAX_SIDE", options::DEFAULT_MAX_SIDE)?;
    Ok(())
}
