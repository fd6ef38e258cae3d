//! NumPy `.npy` arrays: float32/float64 writers that refuse values their
//! type cannot hold, and a reader of any real dtype, byte order and memory
//! order into a grid.

use std::fs;
use std::io::{BufWriter, Cursor, Write};
use std::path::Path;

use npyz::{DType, NpyFile, NpyHeader, Order, TypeChar, WriteOptions, WriterBuilder};

use super::error::{IoError, write_error};
use crate::grid::Grid;

/// Writes `values` (C order) as a `.npy` of `shape` in `T`, each converted
/// by `convert`, after refusing a value beyond `±limit` (what `T` holds).
fn write_npy<T>(
    path: &Path,
    shape: &[u64],
    values: &[f64],
    limit: f64,
    convert: impl Fn(f64) -> T,
) -> Result<(), IoError>
where
    T: npyz::AutoSerialize,
{
    if let Some(v) = values.iter().find(|v| v.abs() > limit) {
        return Err(write_error(
            path,
            format!("the array holds {v:e}, which the file's number type cannot hold"),
        ));
    }
    let err = |e: std::io::Error| write_error(path, e);
    let file = fs::File::create(path).map_err(err)?;
    let mut out = BufWriter::new(file);
    let mut writer = WriteOptions::<T>::new()
        .default_dtype()
        .shape(shape)
        .writer(&mut out)
        .begin_nd()
        .map_err(err)?;
    writer
        .extend(values.iter().map(|&v| convert(v)))
        .map_err(err)?;
    writer.finish().map_err(err)?;
    out.flush().map_err(err)
}

/// The shape of a grid as rows x columns.
fn shape_of<T>(grid: &Grid<T>) -> [u64; 2] {
    [grid.height() as u64, grid.width() as u64]
}

/// Writes `grid` as an H x W (rows x columns) C-order `.npy` of little-endian
/// float32. NaN (no value) is written as NaN; a value that is infinite, or
/// too large for float32, is an error and nothing is written.
pub fn write_npy_f32(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    let limit = f64::from(f32::MAX);
    write_npy(path, &shape_of(grid), grid.as_slice(), limit, |v| v as f32)
}

/// Writes a grid of 3-vectors as an H x W x 3 C-order `.npy` of
/// little-endian float32 (e.g. normals). NaN is written as NaN; a value
/// that is infinite or too large for float32 is an error.
pub fn write_npy_f32_vec3(path: &Path, grid: &Grid<[f64; 3]>) -> Result<(), IoError> {
    let [rows, columns] = shape_of(grid);
    let values = grid.as_slice().as_flattened();
    let limit = f64::from(f32::MAX);
    write_npy(path, &[rows, columns, 3], values, limit, |v| v as f32)
}

/// Writes `grid` as an H x W (rows x columns) C-order `.npy` of little-endian
/// float64. NaN is written as NaN; an infinite value is an error.
pub fn write_npy_f64(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    write_npy(path, &shape_of(grid), grid.as_slice(), f64::MAX, |v| v)
}

/// Reads all elements of `file` (whose data is known to be complete) as f64.
fn npy_values<T, R>(file: NpyFile<R>, to_f64: impl Fn(T) -> f64) -> std::io::Result<Vec<f64>>
where
    T: npyz::Deserialize,
    R: std::io::Read,
{
    let reader = file
        .data::<T>()
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string()))?;
    reader.map(|v| v.map(&to_f64)).collect()
}

/// Reads a 2-D `.npy` array as a grid with rows along the first axis.
///
/// Accepted element types, in either byte order and in C or Fortran order:
/// float32, float64, signed and unsigned integers of 1 to 8 bytes and bool
/// (converted to f64; integers beyond 2^53 lose precision, bool is 0 or 1).
/// Anything else (other dimensions, strings, records, complex, float16), a
/// truncated file or an array with no elements is an error naming the file
/// and what was found.
pub fn read_npy(path: &Path) -> Result<Grid<f64>, IoError> {
    let (shape, values, order) = read_array(path, 2)?;
    let (rows, cols) = (shape[0], shape[1]);
    let grid = match order {
        Order::C => Grid::from_vec(cols, rows, values),
        // Fortran order: the first axis (rows) varies fastest.
        Order::Fortran => Some(Grid::from_fn(cols, rows, |c, r| values[c * rows + r])),
    };
    grid.ok_or_else(|| IoError::Npy {
        path: path.to_path_buf(),
        reason: "internal error: value count does not match the shape".into(),
    })
}

/// Reads an H x W x 3 `.npy` array (C order; e.g. normals) as a grid of
/// 3-vectors; element types as [`read_npy`].
pub fn read_npy_vec3(path: &Path) -> Result<Grid<[f64; 3]>, IoError> {
    let (shape, values, order) = read_array(path, 3)?;
    let bad = |reason: String| IoError::Npy {
        path: path.to_path_buf(),
        reason,
    };
    if shape[2] != 3 || order != Order::C {
        return Err(bad(format!(
            "expected an H x W x 3 array in C order, found shape {shape:?}"
        )));
    }
    let (rows, cols) = (shape[0], shape[1]);
    Ok(Grid::from_fn(cols, rows, |c, r| {
        let q = 3 * (r * cols + c);
        [values[q], values[q + 1], values[q + 2]]
    }))
}

/// The shape (of `dims` axes), values and memory order of a `.npy` file.
fn read_array(path: &Path, dims: usize) -> Result<(Vec<usize>, Vec<f64>, Order), IoError> {
    let bad = |reason: String| IoError::Npy {
        path: path.to_path_buf(),
        reason,
    };
    let bytes = fs::read(path).map_err(|cause| IoError::Read {
        path: path.to_path_buf(),
        cause,
    })?;
    let mut cursor = Cursor::new(bytes.as_slice());
    let header =
        NpyHeader::from_reader(&mut cursor).map_err(|e| bad(format!("bad header: {e}")))?;
    let shape = header.shape().to_vec();
    if shape.len() != dims {
        return Err(bad(format!(
            "expected a {dims}-D array, found {}-D with shape {:?}",
            shape.len(),
            shape
        )));
    }
    let sizes: Vec<usize> = shape
        .iter()
        .map(|&n| usize::try_from(n).map_err(|_| bad(format!("shape {shape:?} is too large"))))
        .collect::<Result<_, _>>()?;
    let count = sizes
        .iter()
        .try_fold(1usize, |acc, &n| acc.checked_mul(n))
        .ok_or_else(|| bad(format!("shape {shape:?} is too large")))?;
    if count == 0 {
        return Err(bad(format!("the array is empty (shape {shape:?})")));
    }
    let dtype = header.dtype();
    let type_str = match &dtype {
        DType::Plain(t) => t.clone(),
        other => return Err(bad(format!("unsupported element type {}", other.descr()))),
    };
    let item_size = dtype
        .num_bytes()
        .ok_or_else(|| bad(format!("unsupported element type {type_str}")))?;
    let available = bytes.len() as u64 - cursor.position();
    let needed = (count as u64).checked_mul(item_size as u64);
    if needed.is_none_or(|n| n > available) {
        return Err(bad(format!(
            "the file is truncated: shape {shape:?} of {type_str} needs {} bytes of data, found {available}",
            needed.map_or_else(|| "too many".to_string(), |n| n.to_string())
        )));
    }
    let order = header.order();
    let file = NpyFile::with_header(header, cursor);
    let values = match (type_str.type_char(), item_size) {
        (TypeChar::Float, 8) => npy_values(file, |v: f64| v),
        (TypeChar::Float, 4) => npy_values(file, |v: f32| f64::from(v)),
        (TypeChar::Int, 1) => npy_values(file, |v: i8| f64::from(v)),
        (TypeChar::Int, 2) => npy_values(file, |v: i16| f64::from(v)),
        (TypeChar::Int, 4) => npy_values(file, |v: i32| f64::from(v)),
        (TypeChar::Int, 8) => npy_values(file, |v: i64| v as f64),
        (TypeChar::Uint, 1) => npy_values(file, |v: u8| f64::from(v)),
        (TypeChar::Uint, 2) => npy_values(file, |v: u16| f64::from(v)),
        (TypeChar::Uint, 4) => npy_values(file, |v: u32| f64::from(v)),
        (TypeChar::Uint, 8) => npy_values(file, |v: u64| v as f64),
        (TypeChar::Bool, 1) => npy_values(file, |v: bool| if v { 1.0 } else { 0.0 }),
        _ => {
            return Err(bad(format!(
                "unsupported element type {type_str} (expected float32, float64, an integer or bool)"
            )));
        }
    }
    .map_err(|e| bad(format!("bad data: {e}")))?;
    if values.len() != count {
        return Err(bad(format!(
            "expected {count} values, read {}",
            values.len()
        )));
    }
    Ok((sizes, values, order))
}

#[cfg(test)]
mod tests {
    use super::*;
    use tempfile::tempdir;

    fn ramp(w: usize, h: usize) -> Grid<f64> {
        Grid::from_fn(w, h, |i, j| (i + w * j) as f64 / (w * h - 1) as f64)
    }

    #[test]
    fn npy_round_trips_keep_nan() {
        let dir = tempdir().unwrap();
        let mut g = ramp(4, 3);
        *g.at_mut(1, 2) = f64::NAN;
        *g.at_mut(3, 0) = -2.5e10;
        for (name, f32_file) in [("a32.npy", true), ("a64.npy", false)] {
            let p = dir.path().join(name);
            if f32_file {
                write_npy_f32(&p, &g).unwrap();
            } else {
                write_npy_f64(&p, &g).unwrap();
            }
            let back = read_npy(&p).unwrap();
            assert_eq!(back.size(), (4, 3));
            for (a, b) in g.as_slice().iter().zip(back.as_slice()) {
                if a.is_nan() {
                    assert!(b.is_nan());
                } else if f32_file {
                    assert_eq!(*b, *a as f32 as f64);
                } else {
                    assert_eq!(a, b);
                }
            }
        }
    }

    /// A hand-made `.npy` (version 1.0) with the given header dict and data.
    fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
        let mut text = dict.to_string();
        while !(10 + text.len() + 1).is_multiple_of(64) {
            text.push(' ');
        }
        text.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((text.len() as u16).to_le_bytes());
        out.extend(text.as_bytes());
        out.extend(data);
        out
    }

    #[test]
    fn reads_fortran_order_big_endian_npy() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("f.npy");
        // 2 rows x 3 columns, value 10 r + c, stored column by column.
        let mut data = Vec::new();
        for c in 0..3 {
            for r in 0..2 {
                data.extend((10.0 * r as f64 + c as f64).to_be_bytes());
            }
        }
        let dict = "{'descr': '>f8', 'fortran_order': True, 'shape': (2, 3), }";
        fs::write(&p, npy_bytes(dict, &data)).unwrap();
        let g = read_npy(&p).unwrap();
        assert_eq!(g.size(), (3, 2));
        assert_eq!(g.as_slice(), &[0.0, 1.0, 2.0, 10.0, 11.0, 12.0]);

        // Fortran order written by npyz, float32.
        let q = dir.path().join("f32.npy");
        let mut out = BufWriter::new(fs::File::create(&q).unwrap());
        let mut w = WriteOptions::<f32>::new()
            .default_dtype()
            .shape(&[2, 3])
            .order(Order::Fortran)
            .writer(&mut out)
            .begin_nd()
            .unwrap();
        w.extend([0.0, 10.0, 1.0, 11.0, 2.0, 12.0]).unwrap();
        w.finish().unwrap();
        out.flush().unwrap();
        drop(out);
        assert_eq!(read_npy(&q).unwrap(), g);
    }

    #[test]
    fn npy_errors_name_the_file_and_what_was_found() {
        let dir = tempdir().unwrap();
        let p = dir.path().join("v.npy");
        // A `.npy` file of `header` (padded) and `data` at `path`.
        let write = |path: &Path, header: &str, data: &[u8]| {
            fs::write(path, npy_bytes(header, data)).unwrap();
        };
        let data: Vec<u8> = [1.0f64, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        write(
            &p,
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }",
            &data,
        );
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(
            e.contains(&p.display().to_string()) && e.contains("1-D"),
            "{e}"
        );

        // Truncated: the header promises far more than the file holds.
        write(
            &p,
            "{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }",
            &data,
        );
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("truncated"), "{e}");

        // Integers convert; strings do not.
        let ints: Vec<u8> = [1i32, -2, 3, 4]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        write(
            &p,
            "{'descr': '<i4', 'fortran_order': False, 'shape': (2, 2), }",
            &ints,
        );
        assert_eq!(read_npy(&p).unwrap().as_slice(), &[1.0, -2.0, 3.0, 4.0]);
        write(
            &p,
            "{'descr': '|S4', 'fortran_order': False, 'shape': (2, 2), }",
            &ints,
        );
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains("unsupported element type"), "{e}");

        fs::write(&p, "not npy").unwrap();
        let e = read_npy(&p).unwrap_err().to_string();
        assert!(e.contains(&p.display().to_string()), "{e}");
        let e = read_npy(&dir.path().join("none.npy"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.npy"), "{e}");
    }
}
