//! `solve` on rendered scenes: its options and parameters, the methods and
//! their chaining, lights off the centre, the working size, a camera file of
//! another size, a dark image, and a glossy render with its model.

use serde_json::Value;
use tempfile::tempdir;

use crate::common::{
    Fixture, assert_said, assert_success, expect_failure, read_json, s, set_solve_args, sfs,
    solve_scene, solve_scene_args, stderr, stdout, synth_in_temp, synth_into, synth_line,
};

#[test]
fn solve_with_focal_and_intensity_scale() {
    let fx = Fixture::new();
    let r = fx.path("r");
    let image = fx.scene.join("image16.png");
    let args = fx.solve_focal_args(&image, &r, &["--intensity-scale", "2"]);
    assert_success(&sfs(&args), "solve --focal --intensity-scale");
    let report = read_json(&r.join("report.json"));
    let camera = &report["input"]["camera"];
    assert_eq!(camera["focal"].as_f64(), Some(40.0));
    assert_eq!(camera["intensity_scale"].as_f64(), Some(2.0));
    assert_eq!(camera["cx"].as_f64(), Some(19.5));
    assert!(r.join("depth.npy").is_file());
}

#[test]
fn solve_with_mask_confidence_and_every_parameter() {
    let fx = Fixture::new();
    let r = fx.path("r");
    let mask = fx.scene_file("mask.png");
    let confidence = fx.scene_file("confidence.png");
    let args = fx.solve_args(
        &r,
        &[
            "--mask",
            &mask,
            "--confidence",
            &confidence,
            "--alpha",
            "0.01",
            "--kappa",
            "2",
            "--inner-iters",
            "2",
            "--sor-iters",
            "3",
            "--omega",
            "1.2",
            "--dz-limit",
            "0.02",
            "--eta",
            "0.8",
            "--init-depth",
            "1.8",
        ],
    );
    assert_success(&sfs(&args), "solve with every option");
    let report = read_json(&r.join("report.json"));
    let p = &report["parameters"];
    assert_eq!(p["alpha"].as_f64(), Some(0.01));
    assert_eq!(report["alpha_used"].as_f64(), Some(0.01));
    assert_eq!(p["kappa"], 2);
    assert_eq!(p["inner-iters"], 2);
    assert_eq!(p["sor-iters"], 3);
    assert_eq!(p["omega"].as_f64(), Some(1.2));
    assert_eq!(p["dz-limit"].as_f64(), Some(0.02));
    assert_eq!(p["eta"].as_f64(), Some(0.8));
    assert_eq!(p["init_depth"], "1.8");
    assert_eq!(report["initial_depth"].as_f64(), Some(1.8));
    for level in report["levels"].as_array().unwrap() {
        assert_eq!(level["energies"].as_array().unwrap().len(), 2, "kappa = 2");
    }
}

#[test]
fn solve_picks_the_method_and_chains_one_into_another() {
    let fx = Fixture::new();
    // Fast marching alone, then the linearised solver refining its depth.
    let fm = fx.path("fm");
    let mut args = fx.solve_args(&fm, &["--method", "fast-marching"]);
    args.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args), "solve --method fast-marching");
    let report = read_json(&fm.join("report.json"));
    assert_eq!(report["parameters"]["method"], "fast_marching");
    let fm_rse = report["rse"].as_f64().expect("rse");
    let chained = fx.path("chained");
    let depth = s(&fm.join("depth.npy"));
    let mut args = fx.solve_args(&chained, &["--init-depth", &depth]);
    args.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args), "solve --init-depth fm/depth.npy");
    let report = read_json(&chained.join("report.json"));
    assert_eq!(report["parameters"]["method"], "linearised");
    let rse = report["rse"].as_f64().expect("rse");
    assert!(
        rse < 0.05 && fm_rse < 0.05,
        "rse {rse}, fast marching {fm_rse}"
    );
    // The explicit scheme runs from the same command.
    let explicit = fx.path("explicit");
    let args = fx.solve_args(
        &explicit,
        &["--method", "explicit", "--init-depth", "from-image"],
    );
    assert_success(&sfs(&args), "solve --method explicit");
    assert_eq!(
        read_json(&explicit.join("report.json"))["parameters"]["method"],
        "explicit"
    );
    // A start that is neither a method, a number nor a file is named.
    let bad = fx.path("bad");
    expect_failure(
        &fx.solve_args(&bad, &["--init-depth", "sideways"]),
        &bad,
        &["--init-depth", "sideways"],
    );
}

/// A Sombrero lit from beside the lens (mu = 1 LED) is solved back with the
/// light where it is, far better than with the light assumed at the centre;
/// the scene file carries the lights, `solve` reads them.
#[test]
fn off_centre_light_is_solved_back_and_ignoring_it_costs() {
    let tmp = tempdir().unwrap();
    let scene = synth_line(
        &tmp.path().join("lit"),
        "sombrero --size 64x64 --light 0.5,-0.4,0 --light-dir -0.2,0.2,1 --light-mu 1",
    );
    let camera = read_json(&scene.join("scene.json"));
    assert_eq!(camera["lights"][0]["mu"], 1.0);
    let rse = |out: &str, extra: &[&str]| {
        let r = tmp.path().join(out);
        let gt = s(&scene);
        let mut args = vec!["--gt", &gt, "-q"];
        args.extend(extra);
        assert_success(&solve_scene(&scene, "image16.png", &r, &args), out);
        read_json(&r.join("report.json"))["rse"].as_f64().unwrap()
    };
    let with_light = rse("with", &[]);
    let ignored = rse("ignored", &["--light", "0,0,0"]);
    assert!(with_light < 0.05, "with the light model: rse {with_light}");
    assert!(
        ignored > 3.0 * with_light,
        "ignored {ignored} vs {with_light}"
    );
    // Fast marching knows only the centred light and says so.
    let out = solve_scene(
        &scene,
        "image16.png",
        &tmp.path().join("fm"),
        &["--method", "fast-marching", "-q"],
    );
    assert!(!out.status.success());
    assert_said(&out, "optical centre only");
}

/// `--max-side` solves at a working size: outputs at that size, the report
/// says both sizes, intrinsics follow (the RSE against a ground truth
/// rendered at the working size stays small).
#[test]
fn max_side_solves_at_a_working_size() {
    let tmp = tempdir().unwrap();
    let big = tmp.path().join("big");
    let small = tmp.path().join("small");
    for (dir, size) in [(&big, "96x64"), (&small, "48x32")] {
        synth_into(dir, &["sombrero", "--size", size]);
    }
    let r = tmp.path().join("r");
    let args = [
        "solve",
        &s(&big.join("image16.png")),
        "--focal",
        "96",
        "--intensity-scale",
        "2",
        "--max-side",
        "48",
        "--gt",
        &s(&small),
        "-q",
        "--out",
        &s(&r),
    ];
    assert_success(&sfs(args), "solve --max-side");
    let depth = sfs_core::io::read_npy(&r.join("depth.npy")).unwrap();
    assert_eq!(depth.size(), (48, 32));
    let report = read_json(&r.join("report.json"));
    assert_eq!(report["input"]["full_width"], 96);
    assert_eq!(report["input"]["width"], 48);
    assert!((report["input"]["camera"]["focal"].as_f64().unwrap() - 48.0).abs() < 1e-9);
    let rse = report["rse"].as_f64().unwrap();
    assert!(rse < 0.05, "rse at the working size {rse}");
}

/// A camera file calibrated for twice the image size gives the same solve
/// as the right one (the intrinsics are scaled).
#[test]
fn calibration_for_another_size_is_scaled() {
    let fx = Fixture::new();
    let camera = read_json(&fx.scene.join("scene.json"));
    let f = camera["focal"].as_f64().unwrap();
    let doubled = fx.path("double.json");
    std::fs::write(
        &doubled,
        format!(
            r#"{{"calibration_width": 80, "calibration_height": 80, "focal": {},
                "cx": 39.5, "cy": 39.5, "intensity_scale": 2}}"#,
            2.0 * f
        ),
    )
    .unwrap();
    let a = fx.path("a");
    let b = fx.path("b");
    assert_success(&sfs(fx.solve_args(&a, &[])), "solve");
    let mut args = fx.solve_args(&b, &[]);
    args[3] = s(&doubled);
    assert_success(&sfs(&args), "solve with a doubled calibration");
    let za = sfs_core::io::read_npy(&a.join("depth.npy")).unwrap();
    let zb = sfs_core::io::read_npy(&b.join("depth.npy")).unwrap();
    let worst = za
        .as_slice()
        .iter()
        .zip(zb.as_slice())
        .filter(|(x, _)| x.is_finite())
        .map(|(x, y)| ((x - y) / x).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "relative difference {worst}");
}

/// A nearly black photograph is called too dark, up front and in the
/// report's warnings; the model-fit summary is in the report.
#[test]
fn a_dark_image_gets_a_plain_warning() {
    let tmp = tempdir().unwrap();
    let scene = synth_line(&tmp.path().join("dark"), "sombrero --size 32x32");
    let image = sfs_core::io::read_image(&scene.join("image16.png"), false).unwrap();
    let dark = tmp.path().join("dark.png");
    sfs_core::io::write_png16(&dark, &image.map(|v| v * 0.0008)).unwrap();
    let r = tmp.path().join("r");
    let out = sfs(["solve", &s(&dark), "--focal", "32", "--out", &s(&r)]);
    assert_success(&out, "solve a dark image");
    assert_said(&out, "too dark");
    let report = read_json(&r.join("report.json"));
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("too dark"))
    );
    assert!(report["model_fit"]["rie_trusted"].is_number());
    // The same image at a normal exposure has no darkness warning.
    let r2 = tmp.path().join("r2");
    let out = sfs([
        "solve",
        &s(&scene.join("image16.png")),
        "--focal",
        "32",
        "--out",
        &s(&r2),
    ]);
    assert_success(&out, "solve the lit image");
    assert!(!stderr(&out).contains("too dark"), "{}", stderr(&out));
}

#[test]
fn a_glossy_render_is_recovered_with_its_model_and_eval_measures_with_it() {
    let (dir, scene) = synth_in_temp(
        "glossy",
        "sombrero --size 64x64 --reflectance blinn-phong --specular 0.3 --shininess 30",
    );
    let camera = read_json(&scene.join("scene.json"));
    assert_eq!(camera["material"]["model"], "blinn-phong");
    assert_eq!(camera["material"]["shininess"], 30.0);
    let solve = |name: &str, extra: &[&str]| -> Value {
        let result = dir.path().join(name);
        let gt = s(&scene);
        let mut args = vec!["--gt", &gt, "--quiet"];
        args.extend(extra);
        assert_success(&solve_scene(&scene, "image16.png", &result, &args), name);
        read_json(&result.join("report.json"))
    };
    let matched = solve(
        "matched",
        &[
            "--reflectance",
            "blinn-phong",
            "--specular",
            "0.3",
            "--shininess",
            "30",
        ],
    );
    let lambert = solve("lambert", &[]);
    assert_eq!(matched["material"]["model"], "blinn-phong");
    assert_eq!(matched["parameters"]["reflectance"], "blinn-phong");
    assert_eq!(lambert["material"]["model"], "lambert");
    let rse = |r: &Value| r["rse"].as_f64().expect("rse");
    assert!(
        rse(&matched) < 0.5 * rse(&lambert),
        "matched {} against Lambert {}",
        rse(&matched),
        rse(&lambert)
    );
    // eval measures with scene.json's material: the matched solve explains
    // the image, and the RIE eval prints is the one solve reported.
    let eval = sfs([
        "eval",
        "--depth",
        &s(&dir.path().join("matched").join("depth.npy")),
        "--gt",
        &s(&scene),
    ]);
    assert_success(&eval, "eval");
    let measured: Value = serde_json::from_str(stdout(&eval).trim()).expect("eval prints JSON");
    let rie = |r: &Value| r["rie"].as_f64().expect("rie");
    assert!((rie(&measured) - rie(&matched)).abs() < 1e-6 * (1.0 + rie(&matched)));
    // Auto reports the models and solves as Lambertian.
    let auto = solve("auto", &["--reflectance", "auto"]);
    assert_eq!(auto["material"]["model"], "lambert");
    assert_eq!(auto["material_fit"]["determined"], false);
    assert_eq!(
        auto["material_fit"]["trials"].as_array().map(Vec::len),
        Some(sfs_core::solver::material_fit::candidates().len())
    );
    // A model's parameter without its model, or out of range, is refused.
    let refused = dir.path().join("refused");
    let with = |extra: &[&str]| solve_scene_args(&scene, "image16.png", &refused, extra);
    expect_failure(
        &with(&["--roughness", "0.4"]),
        &refused,
        &["roughness", "oren-nayar"],
    );
    expect_failure(
        &with(&["--reflectance", "blinn-phong", "--shininess", "0"]),
        &refused,
        &["shininess"],
    );
    expect_failure(
        &with(&[
            "--method",
            "fast-marching",
            "--reflectance",
            "oren-nayar",
            "--roughness",
            "0.9",
        ]),
        &refused,
        &["fast marching", "oren-nayar"],
    );
}

/// `synth --ps-leds 3` at 32x32 in `DIR/set`.
fn small_set(dir: &std::path::Path) -> std::path::PathBuf {
    synth_line(&dir.join("set"), "sombrero --size 32x32 --ps-leds 3")
}

/// `solve --photometric-stereo` of `small_set`'s photographs, by name,
/// with its camera file and mask, into `out`, plus `extra`.
fn set_args(set: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> Vec<String> {
    let mask = s(&set.join("mask.png"));
    let mut options = vec!["--mask", &mask, "-q"];
    options.extend(extra);
    set_solve_args(set, 3, &options, out)
}

/// Issue 48, item 6: with `--photometric-stereo` the single-image solver's
/// options changed nothing (bit-identical depth, the default alpha in the
/// report after `--alpha 1e-3`) without a word. Each is refused by name,
/// with the option that does the job in a set where there is one.
#[test]
fn a_set_refuses_the_single_image_options_it_would_ignore() {
    let dir = tempdir().unwrap();
    let set = small_set(dir.path());
    let out = dir.path().join("out");
    for (option, value, says) in [
        ("--alpha", "1e-3", Some("--ps-smoothness")),
        ("--reflectance", "oren-nayar", None),
        ("--eta", "0.6", None),
        ("--domain", "object", None),
        ("--units", "paper", Some("--ps-smoothness")),
        ("--shadow-bound", "on", Some("--ps-no-cast-shadows")),
        ("--albedo-edge", "0.3", None),
        ("--albedo", "1", None),
    ] {
        let args = set_args(&set, &out, &[option, value]);
        let mut needles = vec![option, "does not apply to --photometric-stereo"];
        needles.extend(says);
        expect_failure(&args, &out, &needles);
    }
}

/// Issue 48, item 6: `--albedo-edge` is the estimated albedo's prior; with
/// `--albedo 1` it was accepted and unused. It is refused, as a
/// reflectance's parameter without its reflectance is.
#[test]
fn albedo_edge_without_an_estimated_albedo_is_refused() {
    let fx = Fixture::new();
    let out = fx.path("edge");
    let args = fx.solve_args(&out, &["--albedo", "1", "--albedo-edge", "0.3"]);
    expect_failure(
        &args,
        &out,
        &["--albedo-edge", "--albedo auto", "--albedo 1"],
    );
}

/// Issue 48, item 6: `--shadow-bound on` with a centred light (no shadow
/// the camera sees) changed nothing silently: it is reported unused on
/// stderr and in report.json.
#[test]
fn shadow_bound_with_a_centred_light_is_reported_unused() {
    let fx = Fixture::new();
    let out = fx.path("bound");
    let args = fx.solve_args(&out, &["--shadow-bound", "on", "--kappa", "1"]);
    let run = sfs(&args);
    assert_success(&run, "solve --shadow-bound on");
    let err = stderr(&run);
    assert!(err.contains("unused option --shadow-bound on"), "{err}");
    let report = read_json(&out.join("report.json"));
    let unused = report["unused_options"].as_array().expect("unused_options");
    assert!(
        unused
            .iter()
            .any(|u| u.as_str().is_some_and(|u| u.contains("--shadow-bound on"))),
        "{unused:?}"
    );
    let clean = fx.path("clean");
    assert_success(&sfs(fx.solve_args(&clean, &[])), "solve");
    let report = read_json(&clean.join("report.json"));
    assert_eq!(report["unused_options"], Value::Array(Vec::new()));
}

/// Issue 48, items 7 and 8: a reused `--out` held the outputs of another
/// kind of run (a single-image solve's reprojection after a set's solve, a
/// set's normals after a single-image one); and `solve --photometric-stereo
/// DIR` said "is not an image" where `view DIR` opens the folder. A folder
/// is read as `view` reads it (its camera file's photographs, its mask) and
/// gives the same depth as the photographs named one by one.
#[test]
fn a_reused_out_holds_one_kind_of_run_and_a_set_opens_as_a_folder() {
    let fx = Fixture::new();
    let set = small_set(fx.path("").as_path());
    let out = fx.path("out");
    let single = fx.solve_args(&out, &["--kappa", "1"]);
    assert_success(&sfs(&single), "single-image solve");
    let names = crate::common::entries(&out);
    assert!(names.contains(&"reprojection.png".to_owned()), "{names:?}");
    assert_success(&sfs(set_args(&set, &out, &[])), "set solve");
    let names = assert_gone(
        &out,
        &[
            "reprojection.png",
            "residual.png",
            "input_linear.png",
            "occlusion_edges.png",
        ],
    );
    assert!(names.contains(&"normals.png".to_owned()), "{names:?}");
    let by_name = std::fs::read(out.join("depth.npy")).unwrap();

    let folder = fx.path("folder");
    let run = sfs([
        "solve",
        "--photometric-stereo",
        &s(&set),
        "-q",
        "--out",
        &s(&folder),
    ]);
    assert_success(&run, "solve --photometric-stereo DIR");
    assert_eq!(
        std::fs::read(folder.join("depth.npy")).unwrap(),
        by_name,
        "the folder's set solved otherwise than its photographs named one by one"
    );

    assert_success(&sfs(&single), "single-image solve again");
    assert_gone(
        &out,
        &[
            "normals.png",
            "normals.npy",
            "residual_01.png",
            "residual_03.png",
        ],
    );
}

/// Asserts none of `gone` is left in `out` after a run of the other kind;
/// returns the names `out` holds.
#[track_caller]
fn assert_gone(out: &std::path::Path, gone: &[&str]) -> Vec<String> {
    let names = crate::common::entries(out);
    for gone in gone {
        assert!(!names.contains(&gone.to_string()), "{gone} left: {names:?}");
    }
    names
}
