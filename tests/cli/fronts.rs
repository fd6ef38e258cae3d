//! One photograph through both fronts: `solve` on the command line and the
//! viewer (the real app, headless) run the core's one photograph solve, so
//! their reports agree field by field (timings aside).

use std::path::Path;
use std::time::{Duration, Instant};

use eframe::egui;
use egui_kittest::Harness;
use serde_json::Value;
use sfs_viewer::app::{Export, ViewerApp, ViewerOptions};
use tempfile::tempdir;

use crate::common::{assert_success, read_json, s, solve_scene, synth_into};

/// What adding the same numbers in another order may change, relative.
const SUM_ORDER: f64 = 1e-12;

/// Fields that measure time (they differ run to run).
fn is_timing(key: &str) -> bool {
    key == "seconds" || key == "phases" || key.ends_with("_s") || key.ends_with("_seconds")
}

/// Every path (`/a/b[3]/c`) where the two JSON values differ, timings left
/// out.
fn differences(cli: &Value, viewer: &Value, path: &str, out: &mut Vec<String>) {
    match (cli, viewer) {
        (Value::Object(a), Value::Object(b)) => {
            for key in a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))) {
                if is_timing(key) {
                    continue;
                }
                let here = format!("{path}/{key}");
                match (a.get(key), b.get(key)) {
                    (Some(x), Some(y)) => differences(x, y, &here, out),
                    (x, y) => out.push(format!("{here}: cli {x:?}, viewer {y:?}")),
                }
            }
        }
        (Value::Array(a), Value::Array(b)) if a.len() == b.len() => {
            for (k, (x, y)) in a.iter().zip(b).enumerate() {
                differences(x, y, &format!("{path}[{k}]"), out);
            }
        }
        (Value::Number(a), Value::Number(b)) => {
            let (x, y) = (
                a.as_f64().unwrap_or(f64::NAN),
                b.as_f64().unwrap_or(f64::NAN),
            );
            // The viewer solves on a pool that leaves the UI a core: a sum
            // in parallel may add in another order (the last bit of an
            // energy). Anything more is a difference.
            if a != b && (x - y).abs() > SUM_ORDER * x.abs().max(y.abs()) {
                out.push(format!("{path}: cli {a}, viewer {b}"));
            }
        }
        (a, b) if a != b => out.push(format!("{path}: cli {a}, viewer {b}")),
        _ => {}
    }
}

/// The viewer's report of `image` opened as a user opens it (the camera,
/// mask and ground truth found beside it), solved at the viewer's
/// defaults and exported.
fn viewer_report(image: &Path, data_dir: &Path, report: &Path) -> Value {
    let options = ViewerOptions {
        image: Some(image.to_path_buf()),
        data_dir: Some(data_dir.to_path_buf()),
        fresh_settings: true,
        ..ViewerOptions::default()
    };
    let mut harness: Harness<'static, ViewerApp> = Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .wgpu()
        .build_eframe(move |cc| ViewerApp::new(cc, options));
    let deadline = Instant::now() + Duration::from_secs(180);
    while harness.state().solve_state().finished().is_none() {
        assert!(
            Instant::now() < deadline,
            "the viewer did not finish in 180 s: {:?}",
            harness.state().solve_state().failure
        );
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    harness.state_mut().export(report, Export::Report);
    read_json(report)
}

/// The same scene through `solve` and through the viewer: a light at the
/// optical centre, and one beside the lens (the depth unit searched, the
/// albedo decided, the fit measured, the warnings said).
#[test]
fn the_cli_and_the_viewer_report_the_same_solve() {
    let dir = tempdir().expect("temp dir");
    for (name, light) in [("centred", None), ("beside", Some("0.5,0,0"))] {
        let mut args = vec!["sombrero", "--size", "64x64"];
        if let Some(light) = light {
            args.extend(["--light", light]);
        }
        let scene = synth_into(&dir.path().join(name), &args);
        let image = scene.join("image16.png");
        let out = dir.path().join(format!("{name}-cli"));
        let (mask, gt) = (s(&scene.join("mask.png")), s(&scene));
        let run = solve_scene(&scene, "image16.png", &out, &["--mask", &mask, "--gt", &gt]);
        assert_success(&run, "solve");
        let cli = read_json(&out.join("report.json"));
        let viewer = viewer_report(
            &image,
            &dir.path().join(format!("{name}-data")),
            &dir.path().join(format!("{name}-viewer.json")),
        );
        let mut found = Vec::new();
        differences(&cli, &viewer, "", &mut found);
        assert!(
            found.is_empty(),
            "{name}: the reports differ in {} fields:\n{}",
            found.len(),
            found.join("\n")
        );
        // Not an empty agreement: the report holds the solve.
        assert!(cli["model_fit"]["rie_trusted"].as_f64().is_some(), "{cli}");
        assert!(cli["rse"].as_f64().is_some_and(|e| e < 0.1), "{cli}");
    }
}
