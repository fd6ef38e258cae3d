//! The command line's usage: `--help` of every subcommand, and bad inputs,
//! each refused with its problem named and nothing written.

use std::fs;
use std::path::Path;

use serde_json::Value;
use tempfile::tempdir;

use crate::common::{
    Fixture, assert_help_mentions, assert_refused, assert_said, assert_success, expect_failure, s,
    sfs, stderr, stdout, strings,
};

#[test]
fn help_of_every_subcommand() {
    for (sub, options) in [
        (
            "solve",
            &[
                "--alpha",
                "--lambda",
                "--eta",
                "--kappa",
                "--inner-iters",
                "--sor-iters",
                "--omega",
                "--dz-limit",
                "--init-depth",
                "--camera",
                "--focal",
                "--mask",
                "--confidence",
                "--srgb",
                "--gt",
                "--out",
            ][..],
        ),
        (
            "synth",
            &["--size", "--noise", "--seed", "--inpaint-disc", "--out"][..],
        ),
        ("eval", &["--depth", "--gt"][..]),
    ] {
        assert_help_mentions(&[sub], options);
    }
    let text = assert_help_mentions(&[], &["synth", "solve", "eval"]);
    assert!(!text.contains("bench"), "--help lists bench:\n{text}");
}

/// The benchmarks are the sfs-bench binary: `sfs-studio bench` (with any
/// arguments, `--help` too) fails, says where they went and repeats its
/// arguments in the command to run.
#[test]
fn bench_points_to_the_sfs_bench_binary() {
    for (args, command) in [
        (
            &["bench"][..],
            "cargo run -p sfs-bench --release -- --out DIR",
        ),
        (
            &["bench", "--part", "robustness", "--out", "r"][..],
            "cargo run -p sfs-bench --release -- --part robustness --out r",
        ),
        (
            &["bench", "--help"][..],
            "cargo run -p sfs-bench --release -- --help",
        ),
    ] {
        let out = sfs(args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = stderr(&out);
        assert!(err.contains("sfs-bench"), "{err}");
        assert!(err.contains(command), "{args:?}: {err}");
        assert!(stdout(&out).is_empty(), "{}", stdout(&out));
    }
}

#[test]
fn missing_image() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let image = fx.path("missing.png");
    expect_failure(
        &fx.solve_focal_args(&image, &out, &[]),
        &out,
        &["missing.png"],
    );
}

#[test]
fn text_file_as_image() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let image = fx.write("x.png", "this is not a PNG\n");
    expect_failure(&fx.solve_focal_args(&image, &out, &[]), &out, &["x.png"]);
}

#[test]
fn directory_as_image() {
    let fx = Fixture::new();
    let out = fx.path("r");
    expect_failure(
        &fx.solve_focal_args(&fx.scene, &out, &[]),
        &out,
        &[&s(&fx.scene)],
    );
}

#[test]
fn images_below_3x3_are_too_small() {
    let fx = Fixture::new();
    for side in [1, 2] {
        let out = fx.path(&format!("r{side}"));
        let image = fx.grey_png(&format!("tiny{side}.png"), side, side, 128);
        let err = expect_failure(
            &fx.solve_focal_args(&image, &out, &[]),
            &out,
            &[&format!("tiny{side}.png"), "3x3"],
        );
        assert!(err.contains("at least"), "{err}");
    }
}

#[test]
fn mask_and_confidence_of_another_size() {
    let fx = Fixture::new();
    let small = s(&fx.grey_png("small.png", 20, 20, 255));
    for option in ["--mask", "--confidence"] {
        let out = fx.path(&format!("r{option}"));
        expect_failure(
            &fx.solve_args(&out, &[option, &small]),
            &out,
            &["small.png", "20x20", &option[2..]],
        );
    }
}

/// A uniform 40x40 image of `value` named `name` is refused, saying `why`.
#[track_caller]
fn grey_image_refused(name: &str, value: u8, why: &str) {
    let fx = Fixture::new();
    let out = fx.path("r");
    let image = fx.grey_png(name, 40, 40, value);
    expect_failure(&fx.solve_focal_args(&image, &out, &[]), &out, &[name, why]);
}

#[test]
fn black_image() {
    grey_image_refused("black.png", 0, "black on every");
}

#[test]
fn saturated_image() {
    grey_image_refused("white.png", 255, "saturated");
}

/// `solve IMAGE --focal ... -q --out OUT` with `focal_args` for the focal length.
fn solve_with_focal(fx: &Fixture, focal_args: &[&str], out: &Path) -> Vec<String> {
    let mut args = vec!["solve".to_string(), fx.scene_file("image16.png")];
    args.extend(focal_args.iter().map(|a| a.to_string()));
    args.extend(["-q".into(), "--out".into(), s(out)]);
    args
}

#[test]
fn bad_focal_lengths() {
    let fx = Fixture::new();
    for (k, focal_args) in [
        &["--focal", "0"][..],
        &["--focal=-3"][..],
        &["--focal", "nan"][..],
    ]
    .into_iter()
    .enumerate()
    {
        let out = fx.path(&format!("r{k}"));
        expect_failure(&solve_with_focal(&fx, focal_args, &out), &out, &["focal"]);
    }
}

#[test]
fn bad_solver_parameters_are_named() {
    let fx = Fixture::new();
    for (k, (option, value, name)) in [
        ("--alpha=-1", "-1", "alpha"),
        ("--eta=1.5", "1.5", "eta"),
        ("--eta=0", "0", "eta"),
        ("--kappa=0", "0", "kappa"),
    ]
    .into_iter()
    .enumerate()
    {
        let out = fx.path(&format!("r{k}"));
        let err = expect_failure(&fx.solve_args(&out, &[option]), &out, &[name]);
        assert!(
            err.contains(&format!("{name} = {value}")),
            "the message should show {name} = {value}: {err}"
        );
    }
    // The same values as separate arguments (clap's other spelling).
    for (k, (option, value)) in [("--eta", "1.5"), ("--eta", "0"), ("--kappa", "0")]
        .into_iter()
        .enumerate()
    {
        let out = fx.path(&format!("s{k}"));
        expect_failure(
            &fx.solve_args(&out, &[option, value]),
            &out,
            &[&option[2..]],
        );
    }
}

/// Negative values written as a separate argument (`--focal -3`, `--alpha -1`)
/// are rejected by clap as unknown arguments (`unexpected argument '-3'
/// found`) without naming the option; a legitimate negative principal point
/// (`--cx -1`) cannot be given that way at all.
#[test]
fn negative_values_as_separate_arguments() {
    let fx = Fixture::new();
    let focal = fx.path("focal");
    expect_failure(
        &solve_with_focal(&fx, &["--focal", "-3"], &focal),
        &focal,
        &["focal"],
    );
    let alpha = fx.path("alpha");
    expect_failure(
        &fx.solve_args(&alpha, &["--alpha", "-1"]),
        &alpha,
        &["alpha"],
    );
    // A principal point left of the image is valid.
    let cx = fx.path("cx");
    let args = solve_with_focal(&fx, &["--focal", "40", "--cx", "-1"], &cx);
    assert_success(&sfs(&args), "solve --cx -1");
}

/// clap's rendered usage errors already start with `error: `, and `main`
/// adds another.
#[test]
fn usage_errors_have_one_error_prefix() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let err = expect_failure(&fx.solve_args(&out, &["--nonsense"]), &out, &["--nonsense"]);
    assert!(!err.contains("error: error:"), "{err}");
}

#[test]
fn unreadable_camera_files() {
    let fx = Fixture::new();
    let image = s(&fx.scene.join("image16.png"));
    let good = fs::read_to_string(fx.scene.join("scene.json")).unwrap();
    let mut without_focal: Value = serde_json::from_str(&good).unwrap();
    without_focal.as_object_mut().unwrap().remove("focal");
    let mut wrong_size: Value = serde_json::from_str(&good).unwrap();
    wrong_size["width"] = 30.into();
    let cases: [(&str, Option<String>, &[&str]); 4] = [
        ("nope.json", None, &["nope.json"]),
        (
            "malformed.json",
            Some("{\"width\": 40,".into()),
            &["malformed.json"],
        ),
        (
            "nofocal.json",
            Some(without_focal.to_string()),
            &["nofocal.json", "focal"],
        ),
        (
            "wrongsize.json",
            Some(wrong_size.to_string()),
            &["wrongsize.json", "30x40"],
        ),
    ];
    for (name, contents, needles) in cases {
        let camera = match contents {
            Some(text) => fx.write(name, &text),
            None => fx.path(name),
        };
        let out = fx.path(&format!("r-{name}"));
        let args: Vec<String> = vec![
            "solve".into(),
            image.clone(),
            "--camera".into(),
            s(&camera),
            "-q".into(),
            "--out".into(),
            s(&out),
        ];
        expect_failure(&args, &out, needles);
    }
}

#[test]
fn malformed_obj_files() {
    let fx = Fixture::new();
    let cases = [
        (
            "garbage.obj",
            "hello world\nv 1 2\nf one two three\n\x01\x02\n",
        ),
        (
            "badindex.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n",
        ),
    ];
    for (name, contents) in cases {
        let obj = fx.write(name, contents);
        let out = fx.path(&format!("r-{name}"));
        let args = strings(&["synth", &s(&obj), "--size", "16x16", "--out", &s(&out)]);
        expect_failure(&args, &out, &[name]);
    }
}

#[test]
fn output_folder_inside_a_file() {
    let fx = Fixture::new();
    let file = fx.write("afile", "a plain file\n");
    let out = file.join("sub");
    let synth: Vec<String> = ["synth", "sombrero", "--size", "16x16", "--out", &s(&out)]
        .map(String::from)
        .into();
    expect_failure(&synth, &out, &[&s(&out)]);
    expect_failure(&fx.solve_args(&out, &[]), &out, &[&s(&out)]);
    assert_eq!(fs::read_to_string(&file).unwrap(), "a plain file\n");
}

#[test]
fn no_camera_and_no_focal() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let args: Vec<String> = vec![
        "solve".into(),
        fx.scene_file("image16.png"),
        "-q".into(),
        "--out".into(),
        s(&out),
    ];
    expect_failure(&args, &out, &["--camera", "--focal"]);
}

/// The adversarial probe's cases (issue 23): each is refused with its real
/// cause, or warned about, instead of passing silently.
#[test]
fn the_probes_cases_are_refused_or_said() {
    let dir = tempdir().expect("temp dir");
    let scene = dir.path().join("scene");
    assert_success(
        &sfs(["synth", "sombrero", "--size", "48x48", "--out", &s(&scene)]),
        "synth",
    );
    let image = s(&scene.join("image16.png"));
    let out = s(&dir.path().join("out"));
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        fs::write(&path, text).expect("writes");
        s(&path)
    };
    let solve = |extra: &[&str]| -> Vec<String> {
        let mut args = vec!["solve".to_owned(), image.clone()];
        args.extend(extra.iter().map(|a| (*a).to_owned()));
        args.extend(["--out".to_owned(), out.clone()]);
        args
    };
    // A focal length the model cannot represent.
    assert_refused(&solve(&["--focal", "1e-300"]), &["--focal", "1e-300"]);
    let tiny = write(
        "tiny.json",
        r#"{"width": 48, "height": 48, "focal": 1e-300, "cx": 23.5, "cy": 23.5}"#,
    );
    assert_refused(&solve(&["--camera", &tiny]), &["`focal`", "180 degrees"]);
    // K: non-square pixels, skew, K with focal, a negative fy.
    for (name, k, says) in [
        (
            "fxfy.json",
            "[[60, 0, 23.5], [0, 40, 23.5], [0, 0, 1]]",
            "square pixels",
        ),
        (
            "skew.json",
            "[[50, 3, 23.5], [0, 50, 23.5], [0, 0, 1]]",
            "skew",
        ),
        (
            "k22.json",
            "[[50, 0, 23.5], [0, 50, 23.5], [0, 0, 2]]",
            "K[2][2]",
        ),
        (
            "negfy.json",
            "[[50, 0, 23.5], [0, -50, 23.5], [0, 0, 1]]",
            "fy = K[1][1]",
        ),
    ] {
        let file = write(name, &format!(r#"{{"width": 48, "height": 48, "K": {k}}}"#));
        assert_refused(&solve(&["--camera", &file]), &[says]);
    }
    let both = write(
        "both.json",
        r#"{"width": 48, "height": 48, "focal": 50, "cx": 23.5, "cy": 23.5,
            "K": [[50, 0, 23.5], [0, 50, 23.5], [0, 0, 1]]}"#,
    );
    assert_refused(&solve(&["--camera", &both]), &["both `K` and `focal`"]);
    // Duplicate LED numbers and image names in a camera file.
    let twice = write(
        "twice.json",
        r#"{"width": 48, "height": 48, "focal": 50, "cx": 23.5, "cy": 23.5,
            "lights": [{"position": [1, 0, 0], "led": 4}, {"position": [0, 1, 0], "led": 4}]}"#,
    );
    assert_refused(
        &solve(&["--camera", &twice, "--light-index", "4"]),
        &["entries 1 and 2", "`led` 4"],
    );
    // Conflicting options.
    let camera = s(&scene.join("scene.json"));
    assert_refused(
        &solve(&[
            "--camera",
            &camera,
            "--known-depth",
            "24,24,2",
            "--intensity-scale",
            "3",
        ]),
        &["--known-depth", "--intensity-scale 3"],
    );
    let leds = write(
        "leds.json",
        r#"{"width": 48, "height": 48, "focal": 50, "cx": 23.5, "cy": 23.5,
            "lights": [{"position": [1, 0, 0], "led": 4}, {"position": [0, 1, 0], "led": 5}]}"#,
    );
    assert_refused(
        &solve(&[
            "--camera",
            &leds,
            "--light-index",
            "4",
            "--light-index",
            "4",
        ]),
        &["--light-index 4 is given twice"],
    );
    // The real cause: an ambient frame as bright as the photograph, an
    // empty mask, a zero albedo.
    let black = dir.path().join("black.png");
    sfs_core::io::write_png16(&black, &sfs_core::grid::Grid::filled(48, 48, 0.0)).expect("png");
    let black = s(&black);
    assert_refused(
        &solve(&["--camera", &camera, "--ambient", &image]),
        &["ambient frame", "at least as bright"],
    );
    assert_refused(
        &solve(&["--camera", &camera, "--mask", &black]),
        &["marks no pixel as object"],
    );
    assert_refused(
        &solve(&["--camera", &camera, "--albedo", &black]),
        &["albedo", "zero"],
    );
    // Impossible synthetic scenes.
    for light in [
        vec!["--light", "0,0,5"],
        vec![
            "--light",
            "0.5,0,0",
            "--light-dir",
            "0,0,-1",
            "--light-mu",
            "1",
        ],
    ] {
        let mut args = vec!["synth", "sombrero", "--size", "32x32"];
        args.extend(light);
        let bad = s(&dir.path().join("bad"));
        args.extend(["--out", &bad]);
        let run = sfs(&args);
        assert!(!run.status.success(), "{args:?}");
        assert_said(&run, "reach no pixel");
    }
    // An LED pointing away from the object, and one behind the camera, are
    // warned about; --quiet keeps warnings.
    let run = sfs(solve(&[
        "--camera",
        &camera,
        "--light",
        "0.3,0,0",
        "--light-dir",
        "0,0,-1",
        "--light-mu",
        "1",
        "--intensity-scale",
        "2",
        "--quiet",
    ]));
    assert_success(&run, "solve with an LED pointing away");
    assert!(
        stderr(&run).contains("warning: light 1") && stderr(&run).contains("points away"),
        "{}",
        stderr(&run)
    );
    let run = sfs(solve(&[
        "--camera",
        &camera,
        "--light",
        "0.3,0,-1",
        "--intensity-scale",
        "2",
        "--quiet",
    ]));
    assert_success(&run, "solve with a light behind the camera");
    assert_said(&run, "behind the camera");
}

/// Issue 48's misleading messages: each names the option the user gave,
/// the value and what is accepted.
#[test]
fn messages_name_the_option_given_and_what_is_accepted() {
    let fx = Fixture::new();
    let run = |k: &str, extra: &[&str], says: &[&str]| {
        let out = fx.path(k);
        expect_failure(&fx.solve_args(&out, extra), &out, says);
    };
    // --kappa alone above kappa-max's default.
    run(
        "kappa",
        &["--kappa", "10"],
        &["kappa = 10", "(the default", "--kappa-max 10"],
    );
    // An init depth far from the image's depth, both ways.
    run(
        "init-small",
        &["--init-depth", "1e-15"],
        &["init-depth = 1e-15"],
    );
    run(
        "init-large",
        &["--init-depth", "1e25"],
        &["init-depth = 1e25"],
    );
    // An absurd known depth names --known-depth, not the intensity scale.
    let out = fx.path("known");
    let err = expect_failure(
        &fx.solve_args(&out, &["--known-depth", "20,20,1e30"]),
        &out,
        &["--known-depth", "1e25"],
    );
    assert!(!err.contains("intensity scale must"), "{err}");
    // Neither a word nor a file: the value and what is accepted.
    for (k, (option, value)) in [
        ("--albedo", "0"),
        ("--albedo", "2"),
        ("--vignetting", "bogus"),
    ]
    .into_iter()
    .enumerate()
    {
        run(
            &format!("word{k}"),
            &[option, value],
            &[&format!("{option} {value}"), "accepted", "FILE"],
        );
    }
    // A camera file holding both spellings of the width, and an array.
    let camera: Value =
        serde_json::from_str(&fs::read_to_string(fx.scene.join("scene.json")).unwrap()).unwrap();
    let mut both = camera.clone();
    both["calibration_width"] = camera["width"].clone();
    for (name, text, says) in [
        (
            "both.json",
            both.to_string(),
            "`width` and `calibration_width` are the same key",
        ),
        (
            "array.json",
            format!("[{camera}]"),
            "a camera file is a JSON object",
        ),
    ] {
        let file = fx.write(name, &text);
        let out = fx.path(&format!("r-{name}"));
        let args: Vec<String> = vec![
            "solve".into(),
            fx.scene_file("image16.png"),
            "--camera".into(),
            s(&file),
            "-q".into(),
            "--out".into(),
            s(&out),
        ];
        expect_failure(&args, &out, &[says]);
    }
}

/// `--albedo` takes the albedo.npy a solve writes.
#[test]
fn a_solves_albedo_npy_is_taken_back_as_albedo() {
    let fx = Fixture::new();
    let first = fx.path("first");
    assert_success(&sfs(fx.solve_args(&first, &[])), "solve");
    let albedo = s(&first.join("albedo.npy"));
    let again = fx.path("again");
    assert_success(
        &sfs(fx.solve_args(&again, &["--albedo", &albedo])),
        "solve --albedo albedo.npy",
    );
}
