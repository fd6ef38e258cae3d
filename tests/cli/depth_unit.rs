//! The depth unit of a solve: known distances, the object's distance and a
//! rig's aim, each reported in plain words.

use std::path::Path;
use std::process::Output;

use tempfile::tempdir;

use crate::common::{
    assert_refused, assert_said, assert_success, read_json, solve_scene, solve_scene_args, stderr,
    synth_in_temp, synth_into, truth_depth,
};

/// `solve SCENE/IMAGE` with its camera file, the intensity scale unknown
/// (`--intensity-scale auto`) and `extra`, into `out`.
fn solve_auto(scene: &Path, image: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["--intensity-scale", "auto"];
    args.extend(extra);
    solve_scene(scene, image, out, &args)
}

/// The object's distance the solve met, from its report.
fn solved_distance(report: &serde_json::Value) -> f64 {
    report["depth_unit"]["solved_distance"]
        .as_f64()
        .expect("the solved distance")
}

/// With a light beside the lens: without a known distance the solve says
/// plainly that the image does not determine the depth unit (and the
/// search's verdict is in the report); with two `--known-depth` points the
/// report lists each one's residual, and the first lands within 0.5 %.
#[test]
fn known_distances_are_reported_and_an_undetermined_scale_is_said() {
    let (dir, scene) = synth_in_temp("scene", "sombrero --size 64x64 --light 0.5,0,0");
    let truth = truth_depth(&scene);
    let out = dir.path().join("auto");
    let run = solve_auto(&scene, "image16.png", &out, &[]);
    assert_success(&run, "solve with s auto");
    let report = read_json(&out.join("report.json"));
    let determined = report["depth_unit"]["shading"]["well_determined"]
        .as_bool()
        .expect("the verdict");
    // A flash has no direction: no rig, no aim; the shading decides or the
    // unit is a guess.
    let source = if determined { "shading" } else { "guess" };
    assert_eq!(report["depth_unit"]["source"], source, "{report}");
    let warned = report["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .any(|w| w.as_str().is_some_and(|w| w.contains("does not determine")));
    assert_eq!(warned, !determined, "{}", stderr(&run));
    let out = dir.path().join("known");
    let (a, b) = (*truth.at(32, 32), *truth.at(20, 40));
    let run = solve_auto(
        &scene,
        "image16.png",
        &out,
        &[
            "--known-depth",
            &format!("32,32,{a}"),
            "--known-depth",
            &format!("20,40,{b}"),
        ],
    );
    assert_success(&run, "solve with two known distances");
    let report = read_json(&out.join("report.json"));
    let points = report["depth_unit"]["fit"]["points"]
        .as_array()
        .expect("the fit's points");
    assert_eq!(points.len(), 2);
    for point in points {
        let residual = point["relative_residual"].as_f64().expect("a residual");
        assert!(residual.abs() < 0.02, "{point}");
    }
    assert_said(&run, "given");
    assert!(report["depth_unit"]["shading"].is_null());
    assert_eq!(report["depth_unit"]["source"], "known_depths");
}

/// `--distance`: the solved surface's median depth meets the object's
/// distance given (within the search's tolerance of 2 %), the report says
/// so; with a centred light the
/// rescaling is exact. It is refused beside `--known-depth` or a given
/// intensity scale, and when it is not a positive distance.
#[test]
fn an_object_distance_sets_the_depth_unit() {
    let dir = tempdir().expect("temp dir");
    for (name, light) in [("beside", Some("0.5,0,0")), ("centred", None)] {
        let mut args = vec!["sombrero", "--size", "64x64"];
        if let Some(light) = light {
            args.extend(["--light", light]);
        }
        let scene = synth_into(&dir.path().join(name), &args);
        let truth = truth_depth(&scene);
        let median = sfs_core::solver::calibrate::median_depth(&truth);
        let out = dir.path().join(format!("{name}-out"));
        let given = 1.2 * median;
        let run = solve_auto(
            &scene,
            "image16.png",
            &out,
            &["--distance", &given.to_string()],
        );
        assert_success(&run, "solve with --distance");
        let report = read_json(&out.join("report.json"));
        assert_eq!(report["depth_unit"]["source"], "distance", "{report}");
        let solved = solved_distance(&report);
        let tolerance = if light.is_some() { 0.021 } else { 1e-9 };
        assert!(
            (solved / given - 1.0).abs() < tolerance,
            "{name}: solved {solved}, given {given}"
        );
        assert_said(&run, "depth unit from the given object distance");
    }
    let scene = dir.path().join("centred");
    let out = dir.path().join("refused");
    for (extra, says) in [
        (
            vec!["--distance", "2", "--known-depth", "20,20,2"],
            "cannot be used with",
        ),
        (
            vec!["--distance", "2", "--intensity-scale", "3"],
            "--distance and --intensity-scale 3",
        ),
        (vec!["--distance=-1"], "--distance -1"),
        (vec!["--distance", "0"], "must be a positive distance"),
    ] {
        assert_refused(
            &solve_scene_args(&scene, "image16.png", &out, &extra),
            &[says],
        );
    }
}

/// A camera file that lists a rig of LEDs aimed at the object (as `synth
/// --ps-leds` writes one): one of its photographs solved with its scale
/// unknown (a photograph's case: the set's file says it) takes the depth unit from where the LEDs are aimed, within the 25 %
/// it promises, and says so.
#[test]
fn a_rig_s_aim_sets_the_depth_unit_at_the_defaults() {
    let (dir, scene) = synth_in_temp("set", "sombrero --size 64x64 --ps-leds 4");
    let truth = truth_depth(&scene);
    let median = sfs_core::solver::calibrate::median_depth(&truth);
    let camera = read_json(&scene.join("scene.json"));
    let first = camera["lights"][0]["image"]
        .as_str()
        .expect("the first light's image")
        .to_owned();
    let out = dir.path().join("one");
    let run = solve_auto(&scene, &first, &out, &[]);
    assert_success(&run, "solve one LED's photograph, its scale unknown");
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["depth_unit"]["source"], "rig_aim", "{report}");
    let solved = solved_distance(&report);
    assert!(
        (solved / median - 1.0).abs() < 0.25,
        "solved {solved}, true {median}"
    );
    assert_said(&run, "depth unit from the LEDs' aim point (4 lights)");
}
