//! The parsers of option values the subcommands share: a size, a list of
//! numbers, a path.

use std::path::PathBuf;

/// Parses `WxH` (e.g. `512x256`).
pub fn parse_size(text: &str) -> Result<(usize, usize), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size `{text}` must look like WIDTHxHEIGHT, e.g. 256x256"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<usize>()
            .map_err(|_| format!("size `{text}`: `{s}` is not a whole number"))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    if w < 3 || h < 3 {
        return Err(format!(
            "size `{text}`: both sides must be at least 3 pixels"
        ));
    }
    if w.saturating_mul(h) > 100_000_000 {
        return Err(format!("size `{text}` is larger than 100 megapixels"));
    }
    Ok((w, h))
}

/// Parses a comma-separated list of exactly `N` finite numbers.
pub fn parse_floats<const N: usize>(text: &str) -> Result<[f64; N], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<f64>()
                .map_err(|_| format!("`{s}` in `{text}` is not a number"))
        })
        .collect::<Result<_, _>>()?;
    let array: [f64; N] = values
        .try_into()
        .map_err(|v: Vec<f64>| format!("`{text}` has {} values, expected {N}", v.len()))?;
    if array.iter().any(|v| !v.is_finite()) {
        return Err(format!("`{text}` contains a non-finite value"));
    }
    Ok(array)
}

/// `PathBuf` parser that rejects empty strings.
pub fn parse_path(text: &str) -> Result<PathBuf, String> {
    if text.is_empty() {
        Err("empty path".into())
    } else {
        Ok(PathBuf::from(text))
    }
}
