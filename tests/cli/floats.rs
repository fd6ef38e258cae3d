//! Float photographs (issue 48 item 11): a float TIFF has no fixed white,
//! so its scale does not decide saturation or darkness.

use tempfile::tempdir;

use crate::common::{assert_success, read_json, s, sfs};

/// The Sombrero as a 32-bit float TIFF at 1x, 3x and 0.001x, solved with
/// the object's distance given (the intensity scale found): the same depth
/// each time (to the floats' rounding), no "saturated", "too dark" or
/// "near-black" warning, and the report says the power of two the values
/// were scaled by.
#[test]
fn a_float_tiff_solves_alike_at_any_exposure() {
    use tiff::encoder::{TiffEncoder, colortype};
    let tmp = tempdir().unwrap();
    let scene = sfs_core::scene::sombrero::sombrero(40, 40);
    let distance = 1.5 * sfs_core::solver::calibrate::median_depth(&scene.depth_gt);
    let solve = |exposure: f64| {
        let image = tmp.path().join(format!("sombrero-{exposure}.tif"));
        let values: Vec<f32> = scene
            .image
            .as_slice()
            .iter()
            .map(|&v| (v * exposure) as f32)
            .collect();
        let file = std::fs::File::create(&image).unwrap();
        TiffEncoder::new(file)
            .unwrap()
            .write_image::<colortype::Gray32Float>(40, 40, &values)
            .unwrap();
        let out = tmp.path().join(format!("out-{exposure}"));
        let run = sfs([
            "solve",
            &s(&image),
            "--focal",
            "40",
            "--distance",
            &distance.to_string(),
            "-q",
            "--out",
            &s(&out),
        ]);
        assert_success(&run, &format!("solve the float Sombrero at {exposure}x"));
        let depth = sfs_core::io::read_npy(&out.join("depth.npy")).unwrap();
        (read_json(&out.join("report.json")), depth)
    };
    let (_, one) = solve(1.0);
    for (exposure, power) in [(3.0, -2.0), (0.001, 10.0)] {
        let (report, depth) = solve(exposure);
        assert_eq!(
            report["input"]["float_scale"],
            2f64.powf(power),
            "{exposure}x: {report}"
        );
        let notes = report["notes"].to_string();
        assert!(notes.contains(&format!("2^{power}")), "{notes}");
        for warning in report["warnings"].as_array().unwrap() {
            let warning = warning.as_str().unwrap();
            assert!(
                !warning.contains("saturated")
                    && !warning.contains("dark")
                    && !warning.contains("near-black"),
                "{exposure}x: {warning}"
            );
        }
        for (a, b) in depth.as_slice().iter().zip(one.as_slice()) {
            assert!(
                (a / b - 1.0).abs() < 2e-6 || (a.is_nan() && b.is_nan()),
                "{exposure}x: depth {a} vs {b}"
            );
        }
    }
}
