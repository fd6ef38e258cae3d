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
