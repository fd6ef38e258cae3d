//! Issue 48 ("nothing silent"): a property over the whole option table.
//! Every option of the core's parameter table (`sfs_core::params::PARAMS`)
//! and of photometric stereo's (`PS_PARAMS`), set away from its default in
//! every solve mode, must do one of three things: change the result
//! (depth, albedo or reprojection), be refused with a message naming it,
//! or be reported unused (on stderr and in report.json's
//! `unused_options`). An option that does none of them was accepted and
//! ignored: the test lists every such option and mode.

use std::fs;
use std::path::{Path, PathBuf};

use serde_json::Value;
use sfs_core::params::{PARAMS, PS_PARAMS, ParamKind, ParamValue, SolverParams};
use tempfile::{TempDir, tempdir};

use crate::common::{assert_success, read_json, s, sfs, stderr};

/// The files whose bytes are the result of a solve.
const RESULT_FILES: [&str; 3] = ["depth.npy", "albedo.npy", "reprojection.png"];

/// A solve mode: how to run it, given extra options and an output folder.
struct Mode {
    name: &'static str,
    base: Vec<String>,
}

impl Mode {
    fn args(&self, out: &Path, extra: &[String]) -> Vec<String> {
        let mut args = self.base.clone();
        args.extend(["-q".into(), "--out".into(), s(out)]);
        args.extend(extra.iter().cloned());
        args
    }
}

/// The three scenes: the Sombrero lit from the optical centre with a
/// confidence hole, the Sombrero lit from beside the lens with cast
/// shadows, and a four-LED photometric-stereo set.
fn modes(tmp: &TempDir) -> Vec<Mode> {
    let synth = |name: &str, extra: &[&str]| -> PathBuf {
        let dir = tmp.path().join(name);
        let mut args = vec![
            "synth".to_owned(),
            "sombrero".into(),
            "--size".into(),
            "40x40".into(),
            "--noise".into(),
            "4".into(),
            "--out".into(),
            s(&dir),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        assert_success(&sfs(&args), name);
        dir
    };
    let centred = synth("centred", &["--inpaint-disc", "0.5,0.5,0.2"]);
    let beside = synth("beside", &["--light", "0.4,0,0", "--shadows"]);
    let set = synth("set", &["--ps-leds", "4"]);
    let file = |dir: &Path, name: &str| s(&dir.join(name));
    vec![
        Mode {
            name: "one photograph, light at the optical centre, a confidence hole",
            base: vec![
                "solve".into(),
                file(&centred, "noisy8.png"),
                "--camera".into(),
                file(&centred, "scene.json"),
                "--confidence".into(),
                file(&centred, "confidence.png"),
            ],
        },
        Mode {
            name: "one photograph, light beside the lens, cast shadows",
            base: vec![
                "solve".into(),
                file(&beside, "noisy8.png"),
                "--camera".into(),
                file(&beside, "scene.json"),
            ],
        },
        Mode {
            name: "photometric stereo, four LEDs",
            base: vec![
                "solve".into(),
                "--photometric-stereo".into(),
                file(&set, "led01.png"),
                file(&set, "led02.png"),
                file(&set, "led03.png"),
                file(&set, "led04.png"),
                "--camera".into(),
                file(&set, "scene.json"),
                "--mask".into(),
                file(&set, "mask.png"),
            ],
        },
    ]
}

/// Values away from the default that the option's range admits: for a
/// number one step towards each end of its range (a decade for a
/// logarithmic one), for a choice every other word.
fn other_values(kind: ParamKind, default: ParamValue) -> Vec<String> {
    match (kind, default) {
        (ParamKind::Choice(words), ParamValue::Choice(d)) => words
            .iter()
            .filter(|w| **w != d)
            .map(|w| (*w).to_owned())
            .collect(),
        (ParamKind::Count { min, max }, ParamValue::Count(d)) => {
            let mut values = vec![(d * 4).clamp(min, max), (d / 4).clamp(min, max)];
            values.retain(|v| *v != d);
            values.dedup();
            values.iter().map(ToString::to_string).collect()
        }
        (ParamKind::Real { min, max, log, .. }, default) => {
            // `auto` by default (alpha): a value a user would set.
            let d = match default {
                ParamValue::Real(v) => v,
                _ => 1e-3,
            };
            let mut values = if log && d > 0.0 {
                vec![d * 10.0, d / 10.0]
            } else {
                vec![d + 0.5 * (max - d), d - 0.5 * (d - min)]
            };
            values = values.into_iter().map(|v| v.clamp(min, max)).collect();
            values.retain(|v| *v != d || !matches!(default, ParamValue::Real(_)));
            values.dedup();
            values.iter().map(|v| format!("{v}")).collect()
        }
        _ => Vec::new(),
    }
}

/// Every option of both tables with the values to try.
fn option_values() -> Vec<(String, Vec<String>)> {
    let defaults = SolverParams::default();
    let mut options: Vec<(String, Vec<String>)> = PARAMS
        .iter()
        .map(|spec| {
            let values = other_values(spec.kind, (spec.get)(&defaults));
            (spec.name.to_owned(), values)
        })
        .collect();
    for spec in PS_PARAMS {
        options.push((spec.name.to_owned(), vec!["1e-3".into(), "1".into()]));
    }
    options.retain(|(_, values)| !values.is_empty());
    options
}

/// What a run did with its option.
#[derive(Debug, PartialEq)]
enum Outcome {
    Changed,
    Refused,
    ReportedUnused,
    /// Exit 0, the same result, nothing said.
    Ignored,
    /// A failure that does not name the option.
    FailedUnnamed(String),
}

/// What a run found: its result files and its report without the
/// parameters it was given, the unused options and the timings.
struct Baseline {
    files: Vec<Option<Vec<u8>>>,
    findings: Value,
}

/// The report without what only echoes the options or measures time.
fn findings(report: &Value) -> Value {
    match report {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| {
                    !matches!(
                        k.as_str(),
                        "parameters" | "unused_options" | "seconds" | "phases"
                    ) && !k.ends_with("_seconds")
                })
                .map(|(k, v)| (k.clone(), findings(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(findings).collect()),
        other => other.clone(),
    }
}

fn result_bytes(out: &Path) -> Vec<Option<Vec<u8>>> {
    RESULT_FILES
        .iter()
        .map(|name| fs::read(out.join(name)).ok())
        .collect()
}

fn outcome(mode: &Mode, out: &Path, name: &str, value: &str, baseline: &Baseline) -> Outcome {
    let flag = format!("--{name}");
    let run = sfs(mode.args(out, &[flag.clone(), value.to_owned()]));
    let err = stderr(&run);
    if !run.status.success() {
        return if err.contains(&flag) || err.contains(&format!("parameter {name}")) {
            Outcome::Refused
        } else {
            Outcome::FailedUnnamed(err)
        };
    }
    let report = read_json(&out.join("report.json"));
    if result_bytes(out) != baseline.files || findings(&report) != baseline.findings {
        return Outcome::Changed;
    }
    let in_report = report["unused_options"].as_array().is_some_and(|list| {
        list.iter()
            .any(|u| u.as_str().is_some_and(|u| u.contains(&flag)))
    });
    if in_report && err.contains(&format!("unused option {flag}")) {
        Outcome::ReportedUnused
    } else {
        Outcome::Ignored
    }
}

#[test]
fn every_option_changes_the_result_or_is_refused_or_reported_unused() {
    let tmp = tempdir().expect("temporary folder");
    let options = option_values();
    assert!(
        options.len() > 25,
        "the tables hold {} options",
        options.len()
    );
    let mut silent = Vec::new();
    for (m, mode) in modes(&tmp).iter().enumerate() {
        let base_out = tmp.path().join(format!("base{m}"));
        let run = sfs(mode.args(&base_out, &[]));
        assert_success(&run, mode.name);
        let baseline = Baseline {
            files: result_bytes(&base_out),
            findings: findings(&read_json(&base_out.join("report.json"))),
        };
        assert!(baseline.files[0].is_some(), "{}: no depth.npy", mode.name);
        // Per option: changed for some value, or each value refused or
        // reported unused (a value inside a range may not bind, say a
        // minimum iteration count below what convergence needs anyway).
        let mut k = 0;
        for (name, values) in &options {
            let mut outcomes = Vec::new();
            for value in values {
                let out = tmp.path().join(format!("run{m}_{k}"));
                k += 1;
                outcomes.push((value, outcome(mode, &out, name, value, &baseline)));
                // Keep the temporary folder small.
                let _ = fs::remove_dir_all(&out);
            }
            let acts = outcomes.iter().any(|(_, o)| *o == Outcome::Changed);
            let said = outcomes
                .iter()
                .all(|(_, o)| matches!(o, Outcome::Refused | Outcome::ReportedUnused));
            if !(acts || said) {
                silent.push(format!("{}: --{name}: {outcomes:?}", mode.name));
            }
        }
    }
    assert!(
        silent.is_empty(),
        "{} options were accepted and ignored (or failed without naming the option):\n{}",
        silent.len(),
        silent.join("\n")
    );
}

/// The other schemes and `synth`: what the adversarial probe of issue 48
/// found accepted and ignored (bit-identical output, nothing said).
#[test]
fn the_other_schemes_report_what_they_leave_unused_and_synth_refuses_it() {
    let tmp = tempdir().expect("temporary folder");
    let scene = tmp.path().join("scene");
    let synth = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "synth".to_owned(),
            "sombrero".into(),
            "--size".into(),
            "32x32".into(),
            "--out".into(),
            s(out),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        sfs(&args)
    };
    assert_success(&synth(&[], &scene), "synth sombrero");
    for (extra, named) in [
        (&["--rotation", "0,90,0"][..], "--rotation"),
        (&["--distance", "3"][..], "--distance"),
        (&["--seed", "7"][..], "--seed"),
    ] {
        let run = synth(extra, &tmp.path().join("refused"));
        assert!(!run.status.success(), "synth {extra:?} was accepted");
        assert!(stderr(&run).contains(named), "{}", stderr(&run));
    }
    for (extra, said) in [
        (
            &["--method", "explicit", "--sor-iters", "3"][..],
            "unused option --sor-iters 3: the explicit scheme",
        ),
        (
            &["--method", "fast-marching", "--init-depth", "3"][..],
            "unused option --init-depth 3: fast marching",
        ),
        (
            &["--method", "fast-marching", "--units", "paper"][..],
            "unused option --units paper: fast marching",
        ),
    ] {
        let out = tmp.path().join("solve");
        let mut args = vec![
            "solve".to_owned(),
            s(&scene.join("image16.png")),
            "--camera".into(),
            s(&scene.join("scene.json")),
            "-q".into(),
            "--out".into(),
            s(&out),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        let run = sfs(&args);
        assert_success(&run, &format!("solve {extra:?}"));
        assert!(stderr(&run).contains(said), "{extra:?}: {}", stderr(&run));
        let report = read_json(&out.join("report.json"));
        let entry = said.trim_start_matches("unused option ");
        let listed = report["unused_options"].as_array().is_some_and(|list| {
            list.iter()
                .any(|u| u.as_str().is_some_and(|u| u.starts_with(entry)))
        });
        assert!(listed, "{extra:?}: {}", report["unused_options"]);
        let _ = std::fs::remove_dir_all(&out);
    }
}
