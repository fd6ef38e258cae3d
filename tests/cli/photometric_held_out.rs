//! Issue 48's last silent wrong answers: a photometric-stereo set whose
//! camera file lists one light at twice the intensity its photograph was
//! taken at, or with one photograph carrying an offset the others lack
//! (an ambient light or black level), is named with the scale or the
//! offset in report.json's warnings and on stderr; the clean set is not.

use std::path::Path;

use super::common::{assert_success, read_json, s, set_solve_args, sfs, stderr, synth_in_temp};

/// The warnings of `report.json` in `out`.
fn report_warnings(out: &Path) -> Vec<String> {
    let report = read_json(&out.join("report.json"));
    report["warnings"]
        .as_array()
        .expect("report.json has a warnings list")
        .iter()
        .filter_map(|w| w.as_str().map(str::to_owned))
        .collect()
}

/// The warnings that name a photograph of the set.
fn naming_a_photograph(warnings: &[String]) -> Vec<&String> {
    warnings.iter().filter(|w| w.contains("led0")).collect()
}

#[test]
fn a_wrong_intensity_or_an_offset_in_one_photograph_is_named_in_the_report() {
    let (dir, set) = synth_in_temp(
        "set",
        "sombrero --size 32x32 --ps-leds 5 --albedo-pattern uniform",
    );
    let mask = s(&set.join("mask.png"));
    let solve = |name: &str| {
        let out = dir.path().join(name);
        let run = sfs(set_solve_args(&set, 5, &["--mask", &mask, "-q"], &out));
        assert_success(&run, name);
        (report_warnings(&out), stderr(&run))
    };
    let (clean, _) = solve("clean");
    assert!(naming_a_photograph(&clean).is_empty(), "{clean:?}");

    // The camera file says intensity 2 for LED 2; its photograph was taken
    // at 1.
    let scene_path = set.join("scene.json");
    let original = std::fs::read_to_string(&scene_path).expect("scene.json");
    let mut scene: serde_json::Value = serde_json::from_str(&original).expect("scene.json");
    scene["lights"][1]["intensity"] = serde_json::json!(2.0);
    std::fs::write(&scene_path, scene.to_string()).expect("write scene.json");
    let (doubled, said) = solve("doubled");
    let named = naming_a_photograph(&doubled);
    assert!(
        named.len() == 1
            && named[0].contains("led02.png is 0.")
            && named[0].contains("as bright as"),
        "{doubled:?}"
    );
    assert!(said.contains("led02.png is 0."), "{said}");
    std::fs::write(&scene_path, original).expect("restore scene.json");

    // LED 5's photograph with an offset of about a quarter of its range.
    let photo = set.join("led05.png");
    let image = sfs_core::io::read_image(&photo, false).expect("led05.png");
    let top = image.as_slice().iter().copied().fold(0.0, f64::max);
    sfs_core::io::write_png16(&photo, &image.map(|v| v + 0.23 * top)).expect("lifted led05.png");
    let (lifted, said) = solve("lifted");
    let named = naming_a_photograph(&lifted);
    assert!(
        named.len() == 1 && named[0].contains("led05.png has an offset of +0."),
        "{lifted:?}"
    );
    assert!(said.contains("led05.png has an offset"), "{said}");
}
