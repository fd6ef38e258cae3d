//! What every bench part writes alike: its `<name>.json` and `<name>.md`,
//! the report of a part over rendered scenes, and markdown's heading,
//! table heads and the skipped meshes' line. Depends on serde and the
//! bench's command line only, so every part (and `report`) may use it.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

/// Writes a part's markdown `md` as `<name>.md` into `out`, naming the file
/// when it cannot.
pub(crate) fn write_markdown(out: &Path, name: &str, md: &str) -> Result<()> {
    let path = out.join(format!("{name}.md"));
    std::fs::write(&path, md).with_context(|| format!("cannot write {}", path.display()))
}

/// Writes a part's report as `<name>.json` and its markdown `md` as
/// `<name>.md` into `out`.
pub(crate) fn write_part<T: Serialize>(out: &Path, name: &str, report: &T, md: &str) -> Result<()> {
    sfs_core::io::write_json(&out.join(format!("{name}.json")), report)?;
    write_markdown(out, name, md)
}

/// The report of a part over rendered scenes (`holes`, `shadows`, `edges`):
/// its rows and the mesh scenes skipped.
#[derive(Clone, Debug, Serialize)]
pub struct SceneReport<R> {
    /// The command line.
    pub command: String,
    /// The rows.
    pub rows: Vec<R>,
    /// Mesh scenes whose file was missing.
    pub skipped: Vec<String>,
}

impl<R: Serialize> SceneReport<R> {
    /// The report of `rows` and `skipped` under this run's command line,
    /// written into `out` as `<name>.json` and, by `markdown`, `<name>.md`.
    pub(crate) fn write(
        out: &Path,
        name: &str,
        rows: Vec<R>,
        skipped: Vec<String>,
        markdown: fn(&Self) -> String,
    ) -> Result<Self> {
        let report = Self {
            command: super::shared::command_line(),
            rows,
            skipped,
        };
        write_part(out, name, &report, &markdown(&report))?;
        Ok(report)
    }
}

/// A part's markdown begun: `title` as its heading, then the command line
/// that ran it.
pub(crate) fn markdown_head(title: &str, command: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# {title}\n");
    let _ = writeln!(md, "Command: `{command}`\n");
    md
}

/// Writes a markdown table's `header` row (`| a | b |`) and the separator
/// row under it, one `---` a column.
pub(crate) fn table_head(md: &mut String, header: &str) {
    let columns = header.matches('|').count().saturating_sub(1);
    let _ = writeln!(md, "{header}");
    let _ = writeln!(md, "|{}", " --- |".repeat(columns));
}

/// Writes a markdown table: its `header` row and the separator under it
/// ([`table_head`]), then the line `line(row)` (`| a | b |`) of each of
/// `rows`.
pub(crate) fn table<R>(
    md: &mut String,
    header: &str,
    rows: impl IntoIterator<Item = R>,
    line: impl Fn(R) -> String,
) {
    table_head(md, header);
    for row in rows {
        let _ = writeln!(md, "{}", line(row));
    }
}

/// Writes the line `title` (as given, e.g. `"\n## Part\n"`) and under it
/// the [`table`] of `rows`; nothing when there is no row.
pub(crate) fn titled_table<R>(
    md: &mut String,
    title: &str,
    header: &str,
    rows: &[R],
    line: impl Fn(&R) -> String,
) {
    if !rows.is_empty() {
        let _ = writeln!(md, "{title}");
        table(md, header, rows, line);
    }
}

/// Writes the line naming the mesh scenes skipped because their file was
/// missing (nothing when none was).
pub(crate) fn skipped_meshes(md: &mut String, skipped: &[String]) {
    if !skipped.is_empty() {
        let _ = writeln!(md, "\nSkipped (mesh missing): {}", skipped.join(", "));
    }
}
