//! Running a binary under test and reading what it wrote, shared by the
//! CLI's tests (`tests/cli/common.rs`) and the bench's
//! (`crates/sfs-bench/tests/bench.rs`), which include this file with
//! `#[path]`. The including module names the binary as `BIN` and the
//! folder its runs start in as `RUN_DIR`.

use std::ffi::OsStr;
use std::fs;
use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

use super::{BIN, RUN_DIR};

/// Runs the binary with `args` from `RUN_DIR`.
pub(crate) fn sfs<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    Command::new(BIN)
        .args(args)
        .current_dir(RUN_DIR)
        .output()
        .unwrap_or_else(|e| panic!("cannot start {BIN}: {e}"))
}

/// What the run wrote to stderr.
pub(crate) fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// What the run wrote to stdout.
pub(crate) fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts a run succeeded, showing its output otherwise.
#[track_caller]
pub(crate) fn assert_success(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed with {}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        stdout(out),
        stderr(out)
    );
}

/// Runs `BIN WORDS --help`, asserts it succeeded and that its text
/// mentions every one of `mentions`, and returns the text.
#[track_caller]
pub(crate) fn assert_help_mentions(words: &[&str], mentions: &[&str]) -> String {
    let mut args = words.to_vec();
    args.push("--help");
    let what = args.join(" ");
    let out = sfs(&args);
    assert_success(&out, &what);
    let text = stdout(&out);
    for mention in mentions {
        assert!(
            text.contains(mention),
            "`{what}` does not mention {mention}:\n{text}"
        );
    }
    text
}

/// Runs `BIN LEAD ARGS --out OUT` and asserts it succeeded.
#[track_caller]
pub(crate) fn run_into(out: &Path, lead: &str, args: &[&str]) {
    let mut all: Vec<String> = vec![lead.into()];
    all.extend(args.iter().map(|a| a.to_string()));
    all.extend(["--out".into(), s(out)]);
    assert_success(&sfs(&all), &format!("{lead} {}", args.join(" ")));
}

/// Paths as strings, for argument lists.
pub(crate) fn s(path: &Path) -> String {
    path.to_str().expect("temporary paths are UTF-8").to_owned()
}

/// The JSON file at `path`, naming the file when it cannot be read or
/// parsed.
pub(crate) fn read_json(path: &Path) -> Value {
    let text =
        fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}
