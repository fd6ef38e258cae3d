//! Many photographs solved one by one (`sfs-studio solve --out-dir`,
//! Python's `solve_many` and its Dask form): which photographs a folder or
//! a pattern names ([`photographs`]), the output folder of each
//! ([`folder_names`]), and the one summary table ([`Row`], [`table`]).

use std::path::{Path, PathBuf};

use crate::io::IoError;

/// The file suffixes taken from a folder (any case).
pub const PHOTO_SUFFIXES: &[&str] = &["png", "jpg", "jpeg", "tif", "tiff"];

/// Whether `text` is a pattern (`*`, `?` in its file name).
fn is_pattern(text: &str) -> bool {
    text.contains(['*', '?'])
}

/// Whether `name` matches `pattern` (`*`: any run of characters, `?`: one
/// character).
pub fn matches(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    // Iterative matching with one backtrack point for the last `*`.
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || p[i] == n[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

/// The files of `dir` whose names `keep` accepts, sorted by name.
fn files_in(dir: &Path, keep: impl Fn(&str) -> bool) -> Result<Vec<PathBuf>, IoError> {
    let entries = std::fs::read_dir(dir).map_err(|cause| IoError::Read {
        path: dir.to_path_buf(),
        cause,
    })?;
    let mut found: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(&keep))
        .collect();
    found.sort();
    Ok(found)
}

/// The photographs `given` names, in order: a folder gives its photographs
/// (PNG, JPEG, TIFF; sorted by name), a pattern (`DIR/*.png`; `*` and `?`
/// in the file name) the files it matches, sorted, and a file itself.
///
/// # Errors
/// A folder that cannot be read, or a pattern that matches nothing (named).
pub fn photographs(given: &[PathBuf]) -> Result<Vec<PathBuf>, IoError> {
    let mut all = Vec::new();
    for path in given {
        let text = path.to_string_lossy();
        if path.is_dir() {
            all.extend(files_in(path, |name| {
                Path::new(name)
                    .extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| PHOTO_SUFFIXES.contains(&e.to_ascii_lowercase().as_str()))
            })?);
        } else if is_pattern(&text) {
            let dir = path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."));
            let pattern = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let found = files_in(dir, |name| matches(&pattern, name))?;
            if found.is_empty() {
                return Err(IoError::Read {
                    path: path.clone(),
                    cause: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "the pattern matches no file",
                    ),
                });
            }
            all.extend(found);
        } else {
            all.push(path.clone());
        }
    }
    Ok(all)
}

/// The output folder's name of each photograph: its file name less the
/// extension, or the whole file name where two photographs share a stem
/// (`a.png` and `a.jpg`), with a number where even that is shared (the
/// same file name from two folders).
pub fn folder_names(photos: &[PathBuf]) -> Vec<String> {
    let stem = |p: &PathBuf| {
        p.file_stem()
            .map_or_else(|| "photo".into(), |s| s.to_string_lossy().into_owned())
    };
    let name = |p: &PathBuf| {
        p.file_name()
            .map_or_else(|| "photo".into(), |s| s.to_string_lossy().into_owned())
    };
    let mut names: Vec<String> = photos
        .iter()
        .map(|p| {
            let s = stem(p);
            if photos.iter().filter(|q| stem(q) == s).count() > 1 {
                name(p)
            } else {
                s
            }
        })
        .collect();
    for k in 0..names.len() {
        if names[..k].contains(&names[k]) {
            names[k] = format!("{}-{}", names[k], k + 1);
        }
    }
    names
}

/// One photograph's line of the summary table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// The photograph.
    pub file: PathBuf,
    /// Wall-clock seconds of its whole solve (reading to writing).
    pub seconds: f64,
    /// The model fit: RIE over trusted pixels (`None`: not solved).
    pub fit: Option<f64>,
    /// Its warnings.
    pub warnings: Vec<String>,
    /// Why it was not solved.
    pub error: Option<String>,
}

/// The summary table as text: a header, then one line per photograph
/// (file name, seconds, fit, and its warnings or its error).
pub fn table(rows: &[Row]) -> String {
    let mut text = format!("{:<40} {:>8} {:>7}  warnings\n", "file", "seconds", "fit");
    for row in rows {
        let name = row.file.file_name().map_or_else(
            || row.file.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let fit = row.fit.map_or_else(|| "-".into(), |f| format!("{f:.3}"));
        let notes = match &row.error {
            Some(e) => format!("error: {e}"),
            None if row.warnings.is_empty() => "-".into(),
            None => row.warnings.join("; "),
        };
        text.push_str(&format!(
            "{name:<40} {:>8.2} {fit:>7}  {notes}\n",
            row.seconds
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_match_runs_and_single_characters() {
        assert!(matches("*.png", "a.png"));
        assert!(matches("led?.png", "led4.png"));
        assert!(!matches("led?.png", "led12.png"));
        assert!(matches("*ed*2*", "led12.png"));
        assert!(!matches("*.png", "a.png.txt"));
        assert!(matches("*", ""));
    }

    #[test]
    fn a_folder_gives_its_photographs_sorted_and_a_pattern_its_matches() {
        let dir = tempfile::tempdir().expect("temp");
        for name in ["b.png", "a.JPG", "c.txt", "d.tif"] {
            std::fs::write(dir.path().join(name), b"x").expect("write");
        }
        let found = photographs(&[dir.path().to_path_buf()]).expect("folder");
        let names: Vec<_> = found
            .iter()
            .map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        assert_eq!(
            names,
            [
                Some("a.JPG".into()),
                Some("b.png".into()),
                Some("d.tif".into())
            ]
        );
        let pattern = dir.path().join("*.png");
        assert_eq!(
            photographs(std::slice::from_ref(&pattern)).expect("pattern"),
            [dir.path().join("b.png")]
        );
        let none = dir.path().join("*.exr");
        let err = photographs(&[none]).expect_err("no match");
        assert!(err.to_string().contains("*.exr"), "{err}");
    }

    #[test]
    fn output_folders_are_stems_unless_two_photographs_share_one() {
        let photos: Vec<PathBuf> = ["x/a.png", "x/a.jpg", "x/b.png", "y/b.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        assert_eq!(
            folder_names(&photos),
            ["a.png", "a.jpg", "b.png", "b.png-4"]
        );
    }

    #[test]
    fn the_table_has_a_line_per_photograph_with_its_warnings_or_error() {
        let rows = [
            Row {
                file: "p/one.png".into(),
                seconds: 1.5,
                fit: Some(0.0123),
                warnings: vec!["dark".into()],
                error: None,
            },
            Row {
                file: "p/two.png".into(),
                seconds: 0.1,
                fit: None,
                warnings: Vec::new(),
                error: Some("cannot read".into()),
            },
        ];
        let text = table(&rows);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[1].starts_with("one.png") && lines[1].ends_with("0.012  dark"));
        assert!(lines[2].contains(" -  error: cannot read"), "{}", lines[2]);
    }
}
