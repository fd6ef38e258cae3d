//! End-to-end tests of the `sfs-bench` binary on tiny configurations: each
//! part's report and its checks, `--help`, and bad options refused.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use serde_json::Value;
use tempfile::{TempDir, tempdir};

/// The binary under test.
const BIN: &str = env!("CARGO_BIN_EXE_sfs-bench");
/// The workspace's root: the runs start there, as `cargo run -p sfs-bench`
/// from the repository does, so the default `../shared` folders resolve.
const RUN_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

// Running the binary and reading its output, as the CLI's tests do.
#[path = "../../../tests/support/binary.rs"]
mod binary;
use binary::{assert_help_mentions, read_json, run_into, s, sfs, stderr};

/// The report `sfs-bench --quick --part PART ARGS` wrote, in a temporary
/// folder that lives as long as it.
struct QuickPart {
    /// Holds the output folder.
    _dir: TempDir,
    /// The part's name.
    part: String,
    /// The output folder.
    out: PathBuf,
    /// `PART.json`.
    report: Value,
}

impl QuickPart {
    /// Runs `sfs-bench --quick --part PART ARGS --out OUT`, asserts it
    /// succeeded and reads `OUT/PART.json`.
    #[track_caller]
    fn run(part: &str, args: &[&str]) -> Self {
        let dir = tempdir().expect("temp dir");
        let out = dir.path().join(part);
        let mut all = vec!["--part", part];
        all.extend(args);
        run_into(&out, "--quick", &all);
        let report = read_json(&out.join(format!("{part}.json")));
        Self {
            _dir: dir,
            part: part.to_owned(),
            out,
            report,
        }
    }

    /// The report's rows.
    fn rows(&self) -> &[Value] {
        self.report["rows"].as_array().expect("rows")
    }

    /// Asserts that `PART.md` holds `text`.
    #[track_caller]
    fn assert_markdown_has(&self, text: &str) {
        let path = self.out.join(format!("{}.md", self.part));
        let md = fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
        assert!(
            md.contains(text),
            "no {text:?} in {}:
{md}",
            path.display()
        );
    }
}

/// The string values of `key` over `rows`.
fn names<'a>(rows: &'a [Value], key: &str) -> BTreeSet<&'a str> {
    rows.iter().map(|r| r[key].as_str().expect(key)).collect()
}

/// Asserts that the string values of `key` over `rows` are `expected`, in
/// any order.
#[track_caller]
fn assert_names(rows: &[Value], key: &str, expected: &[&str]) {
    assert_eq!(
        names(rows, key),
        BTreeSet::from_iter(expected.iter().copied())
    );
}

#[test]
fn help_lists_the_options() {
    assert_help_mentions(
        &[],
        &[
            "--meshes",
            "--quick",
            "--scenes",
            "--explicit-seconds",
            "--out",
        ],
    );
}

/// `bench --part albedo --quick` on the Sombrero: every light, pattern and
/// noise level, three RSEs each; a uniform clean render is solved exactly
/// as with albedo 1 (auto finds no edge or does not use it), a clean patch
/// render with auto comes within 1.5x of the true albedo given and far
/// below albedo 1, and a smooth albedo (no edge) is left as albedo 1.
#[test]
fn bench_albedo_solves_each_render_three_ways() {
    let run = QuickPart::run("albedo", &["--scenes", "sombrero"]);
    assert!(run.out.join("albedo.md").is_file());
    let rows = run.rows();
    assert_eq!(rows.len(), 16, "2 lights x 4 albedos x 2 noise levels");
    for row in rows {
        let value = |key: &str| row[key].as_f64().expect("a number");
        for key in ["rse_one", "rse_auto", "rse_true", "seconds"] {
            assert!(value(key).is_finite() && value(key) >= 0.0, "{key}: {row}");
        }
        if value("noise") > 0.0 {
            continue;
        }
        match row["pattern"].as_str().expect("pattern") {
            "uniform" | "smooth" => {
                assert_eq!(value("rse_auto"), value("rse_one"), "{row}");
            }
            "patches" => {
                assert_eq!(row["auto_used"], true, "{row}");
                assert!(value("rse_auto") <= 1.5 * value("rse_true"), "{row}");
                assert!(value("rse_auto") < 0.5 * value("rse_one"), "{row}");
                assert!(value("albedo_error") < value("albedo_error_one"), "{row}");
            }
            _ => {}
        }
    }
}

#[test]
fn bench_edges_compares_the_truth_with_the_answer_and_finds_contours() {
    let meshes = Path::new(RUN_DIR).join("../shared/meshes");
    let run = QuickPart::run(
        "edges",
        &["--scenes", "sombrero,suzanne", "--meshes", &s(&meshes)],
    );
    let rows = run.rows();
    let suzanne_there = meshes.join("suzanne.obj").is_file();
    assert_eq!(
        rows.len(),
        if suzanne_there { 8 } else { 4 },
        "two sizes, clean and noisy"
    );
    for row in rows {
        let value = |key: &str| row[key].as_f64().unwrap();
        for key in ["default_rse", "truth_start_rse", "fast_marching_rse"] {
            assert!(value(key) > 0.0 && value(key) < 0.5, "{key}: {row}");
        }
        for key in [
            "truth_data_energy",
            "default_data_energy",
            "non_crossing_ratio",
            "best_pair_ratio",
        ] {
            assert!(value(key) > 0.0 && value(key).is_finite(), "{key}: {row}");
        }
        let sombrero = row["scene"] == "sombrero";
        // The analytic scene has no depth jump; Suzanne's ears and crown
        // lie behind jumps (steeper than 87 degrees from one pixel to the
        // next at 128 pixels; at 64 the same jumps look like slopes).
        if sombrero {
            assert_eq!(value("jump_share"), 0.0, "{row}");
        } else if row["size"] == "128x64" {
            assert!(value("jump_share") > 0.01, "{row}");
        }
        assert_eq!(row["paper_rse"].is_null(), value("noise") == 0.0, "{row}");
    }
    run.assert_markdown_has("| sombrero | 64x64 | 0 |");
}

#[test]
fn bench_holes_measures_every_hole_against_the_harmonic_fill() {
    let run = QuickPart::run("holes", &["--scenes", "sombrero"]);
    let rows = run.rows();
    assert_eq!(rows.len(), 8, "four holes, clean and noisy");
    assert_names(rows, "hole", &["band", "blobs", "disc", "silhouette"]);
    for row in rows {
        let value = |key: &str| row[key].as_f64().unwrap();
        let (without, fill) = (value("rse_no_hole"), value("rse_harmonic_fill"));
        assert!(
            without > 0.0 && fill > 0.0 && value("rse_hole") > 0.0,
            "{row}"
        );
        assert!(
            (value("target") - 1.2 * without.hypot(fill)).abs() < 1e-12,
            "{row}"
        );
        assert!(
            value("hole_share") > 0.02 && value("hole_share") < 0.5,
            "{row}"
        );
    }
    run.assert_markdown_has("| sombrero | 128x128 | 0 | disc |");
}

#[test]
fn bench_speed_reports_every_method_side_by_side() {
    let run = QuickPart::run("speed", &["--scenes", "sombrero"]);
    let rows = run.rows();
    assert_names(
        rows,
        "method",
        &[
            "defaults",
            "fast marching",
            "fixed counts",
            "multigrid",
            "paper schedule",
            "step tolerance 1e-4",
        ],
    );
    for row in rows {
        assert_eq!(row["size"], "256x256");
        let rse = row["rse"].as_f64().unwrap();
        assert!(rse.is_finite() && rse < 0.1, "{row}");
        let rie = row["rie"].as_f64().unwrap();
        assert!(rie.is_finite() && rie < 0.1, "{row}");
        assert!(!row["curve"].as_array().unwrap().is_empty(), "{row}");
    }
    // The adaptive stops run fewer inner iterations than the fixed counts.
    let inner = |method: &str| {
        rows.iter()
            .find(|r| r["method"] == method)
            .and_then(|r| r["inner_iterations"].as_u64())
            .expect("inner iterations")
    };
    assert!(inner("defaults") < inner("fixed counts"));
    // The clean Sombrero's depth settles after its first outer iteration:
    // the step tolerance stops there (one inner iteration, the defaults five).
    assert!(inner("step tolerance 1e-4") < inner("defaults"));
    // SOR against V-cycles on the same system: both reduce the residual,
    // 4 cycles further than 40 sweeps.
    let convergence = run.report["convergence"].as_array().expect("convergence");
    assert_eq!(convergence.len(), 1);
    let c = &convergence[0];
    let value = |key: &str| c[key].as_f64().expect(key);
    assert!(value("sor_after_40") < value("sor_after_10") && value("sor_after_10") < 1.0);
    assert!(value("cycle_after_4") < value("sor_after_40"), "{c}");
    assert!(run.out.join("speed.md").exists());
    assert!(run.out.join("speed-sombrero-256x256.png").exists());
}

#[test]
fn bench_quick_on_a_tiny_configuration_writes_a_report_that_parses() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("bench");
    run_into(
        &out,
        "--quick",
        &["--scenes", "sombrero", "--explicit-seconds", "0.5"],
    );
    let report = read_json(&out.join("report.json"));
    let rows = report["rows"].as_array().expect("rows");
    let methods = names(rows, "method");
    for method in [
        "linearised",
        "explicit",
        "fast_marching",
        "linearised+pre",
        "linearised+post",
        "fast_marching+pre",
        "fast_marching+post",
    ] {
        assert!(methods.contains(method), "no row for {method}: {methods:?}");
    }
    for row in rows {
        assert_eq!(row["scene"], "sombrero");
        for key in ["noise", "rse", "rie", "seconds", "peak_mib"] {
            let v = row[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v >= 0.0, "{key} of {row}");
        }
        assert!(row.get("alpha").is_some(), "alpha in {row}");
        // Every method recovers something better than garbage.
        assert!(row["rse"].as_f64().unwrap_or(1.0) < 0.3, "{row}");
    }
    let noises: BTreeSet<u64> = rows
        .iter()
        .map(|r| r["noise"].as_f64().unwrap_or(-1.0) as u64)
        .collect();
    assert_eq!(noises, BTreeSet::from([0, 20]));
    // The explicit budget was honoured and reported.
    let explicit = rows
        .iter()
        .find(|r| r["method"] == "explicit")
        .expect("explicit row");
    assert_eq!(explicit["budget_exhausted"], true);
    assert!(explicit["seconds"].as_f64().unwrap_or(0.0) < 5.0);
    assert!(!report["speedups"].as_array().expect("speedups").is_empty());
    assert!(report["machine"]["cores"].as_u64().unwrap_or(0) >= 1);
    // The robustness table: the defaults clean and noisy at two sizes, each
    // beside the best alpha of its sweep, and the size series.
    let robustness = &report["robustness"];
    let table = robustness["rows"].as_array().expect("robustness rows");
    assert_eq!(table.len(), 4, "2 sizes x clean/noisy: {table:?}");
    for row in table {
        for key in [
            "default_rse",
            "chosen_alpha",
            "best_rse",
            "best_alpha",
            "truth_start_rse",
            "fast_marching_rse",
            "seconds",
        ] {
            let v = row[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v >= 0.0, "{key} of {row}");
        }
        let (default, best) = (
            row["default_rse"].as_f64().unwrap_or(1.0),
            row["best_rse"].as_f64().unwrap_or(0.0),
        );
        assert!(best <= default && default < 0.1, "{row}");
    }
    assert!(!robustness["sizes"].as_array().expect("sizes").is_empty());
    let md = fs::read_to_string(out.join("report.md")).expect("report.md");
    for heading in ["Table 1", "Table 2", "Table 3", "Peak memory", "Robustness"] {
        assert!(md.contains(heading), "report.md lacks {heading}");
    }
    let plot = image::open(out.join("rse_time_sombrero.png")).expect("RSE plot is a PNG");
    assert!(plot.width() > 100 && plot.height() > 100);
}

#[test]
fn bench_rejects_a_bad_budget_and_writes_nothing() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("bench");
    let run = sfs(["--explicit-seconds", "0", "--out", &s(&out)]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("--explicit-seconds"),
        "{}",
        stderr(&run)
    );
    assert!(!out.exists());
}

/// `--seed` draws the corpus and `--large` adds a size to the speed part;
/// with any other part either is refused by name, before anything is run or
/// written (an option is used or refused, never ignored).
#[test]
fn bench_refuses_an_option_its_part_does_not_use() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("bench");
    for (part, option, value) in [
        ("speed", "--seed", Some("1")),
        ("robustness", "--seed", Some("0")),
        ("corpus", "--large", None),
        ("albedo", "--large", None),
    ] {
        let mut args = vec!["--part", part, option];
        args.extend(value);
        let out_arg = s(&out);
        args.extend(["--out", out_arg.as_str()]);
        let run = sfs(args);
        assert!(!run.status.success(), "{part} {option} was accepted");
        assert!(stderr(&run).contains(option), "{}", stderr(&run));
        assert!(!out.exists(), "{part} {option} wrote {}", out.display());
    }
}
