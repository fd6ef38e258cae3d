//! A file replaced all at once: written under a temporary name beside it,
//! flushed to the disk, then renamed, so a reader (or a crash) sees the old
//! file or the new one, never half of one.

use std::fs;
use std::path::Path;

use super::error::IoError;

/// Runs `write` on a temporary file beside `path` (`.NAME.PID.partial`),
/// flushes it to disk and renames it to `path`; on failure the temporary is
/// removed and `path` is untouched.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), IoError>,
) -> Result<(), IoError> {
    let name = path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let temporary = path.with_file_name(format!(".{name}.{}.partial", std::process::id()));
    let result = write(&temporary).and_then(|()| {
        let sync = fs::OpenOptions::new()
            .write(true)
            .open(&temporary)
            .and_then(|f| f.sync_all());
        sync.map_err(|e| IoError::Write {
            path: temporary.clone(),
            cause: e.into(),
        })?;
        fs::rename(&temporary, path).map_err(|cause| {
            let (from, to) = (temporary.clone(), path.to_path_buf());
            IoError::Rename { from, to, cause }
        })
    });
    if result.is_err() {
        // The temporary is ours alone; a failure to remove it changes nothing.
        let _ = fs::remove_file(&temporary);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use tempfile::tempdir;

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary() {
        let dir = tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, |p| {
            fs::write(p, "old").map_err(|e| super::super::error::write_error(p, e))
        })
        .unwrap();
        let failed = write_atomic(&path, |p| {
            fs::write(p, "half").map_err(|e| super::super::error::write_error(p, e))?;
            Err(super::super::error::write_error(p, "disk full"))
        });
        assert!(failed.is_err());
        assert_eq!(fs::read_to_string(&path).unwrap(), "old");
        let names: Vec<_> = fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "the temporary is removed");
        write_atomic(&path, |p| {
            fs::write(p, "new").map_err(|e| super::super::error::write_error(p, e))
        })
        .unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "new");
    }
}
