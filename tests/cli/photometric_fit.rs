//! Issue 48, item 2: a photometric-stereo set is judged per photograph.
//! A photograph at half the exposure its calibrated intensity says is
//! named, with its light, in report.json's warnings and on stderr; the
//! clean set is not warned about.

use super::common::{assert_success, read_json, s, set_solve_args, sfs, stderr, synth_in_temp};

/// The warnings of `report.json` in `out`.
fn report_warnings(out: &std::path::Path) -> Vec<String> {
    let report = read_json(&out.join("report.json"));
    report["warnings"]
        .as_array()
        .expect("report.json has a warnings list")
        .iter()
        .filter_map(|w| w.as_str().map(str::to_owned))
        .collect()
}

#[test]
fn a_photograph_at_half_its_exposure_is_named_in_the_report_and_on_stderr() {
    let (dir, set) = synth_in_temp("set", "sombrero --size 48x48 --ps-leds 6");
    let mask = s(&set.join("mask.png"));
    let solve = |out: &std::path::Path| sfs(set_solve_args(&set, 6, &["--mask", &mask, "-q"], out));
    let clean_out = dir.path().join("clean");
    let clean = solve(&clean_out);
    assert_success(&clean, "the clean set");
    let clean_warnings = report_warnings(&clean_out);
    assert!(
        !clean_warnings.iter().any(|w| w.contains("does not fit")),
        "the clean set is judged not to fit: {clean_warnings:?}"
    );

    let photo = set.join("led03.png");
    let image = sfs_core::io::read_image(&photo, false).expect("led03.png");
    sfs_core::io::write_png16(&photo, &image.map(|v| 0.5 * v)).expect("halved led03.png");
    let halved_out = dir.path().join("halved");
    let halved = solve(&halved_out);
    assert_success(&halved, "the set with led03.png at half its exposure");
    let named: Vec<String> = report_warnings(&halved_out)
        .into_iter()
        .filter(|w| w.contains("does not fit"))
        .collect();
    assert!(
        named.len() == 1 && named[0].contains("led03.png") && named[0].contains("light (at ("),
        "{named:?}"
    );
    let said = stderr(&halved);
    assert!(said.contains("led03.png does not fit"), "{said}");
}

// Issue 48's last silent wrong answers: a photometric-stereo set whose
// camera file lists one light at twice the intensity its photograph was
// taken at, or with one photograph carrying an offset the others lack (an
// ambient light or black level), is named with the scale or the offset in
// report.json's warnings and on stderr; the clean set is not.

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
