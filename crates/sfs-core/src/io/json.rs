//! JSON files of any serde value.

use std::fs;
use std::path::Path;

use serde::Serialize;

use super::error::{IoError, write_error};

/// Writes any serde value as pretty JSON, with a final newline.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), IoError> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| write_error(path, e))?;
    text.push('\n');
    fs::write(path, text).map_err(|e| write_error(path, e))
}
