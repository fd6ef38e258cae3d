//! End-to-end tests of the `sfs-studio` binary: `synth`, `solve` and `eval`
//! on tiny scenes, `--help`, and bad inputs (non-zero exit, a message naming
//! the problem, and nothing left in the output folder).

use std::collections::BTreeSet;
use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use sfs_core::params::SolverParams;
use tempfile::{TempDir, tempdir};

/// The binary under test.
const BIN: &str = env!("CARGO_BIN_EXE_sfs-studio");

/// Files `synth` writes (with `--noise` and `--inpaint-disc`), the hidden
/// manifest of the run's outputs included.
const SYNTH_FILES: [&str; 8] = [
    ".sfs-studio-outputs",
    "image16.png",
    "image8.png",
    "noisy8.png",
    "confidence.png",
    "mask.png",
    "depth_gt.npy",
    "scene.json",
];

/// Files `solve` writes, the hidden manifest of the run's outputs included.
const SOLVE_FILES: [&str; 11] = [
    ".sfs-studio-outputs",
    "albedo.npy",
    "albedo.png",
    "depth.npy",
    "depth16.png",
    "input_linear.png",
    "reprojection.png",
    "residual.png",
    "occlusion_edges.png",
    "mesh.ply",
    "report.json",
];

/// Runs the binary with `args`.
fn sfs<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cannot start the sfs-studio binary")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts a run succeeded, showing its output otherwise.
#[track_caller]
fn assert_success(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed with {}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        stdout(out),
        stderr(out)
    );
}

/// Names of the entries of `dir` (empty if it does not exist).
fn entries(dir: &Path) -> Vec<String> {
    match fs::read_dir(dir) {
        Ok(read) => {
            let mut names: Vec<String> = read
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        }
        Err(_) => Vec::new(),
    }
}

/// Paths as strings, for argument lists.
fn s(path: &Path) -> String {
    path.to_str().expect("temporary paths are UTF-8").to_owned()
}

fn read_json(path: &Path) -> Value {
    let text =
        fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}

/// A temporary folder holding `synth sombrero --size 40x40` with noise and
/// an inpainting disc in `scene/`.
struct Fixture {
    tmp: TempDir,
    scene: PathBuf,
}

impl Fixture {
    fn new() -> Self {
        let tmp = tempdir().unwrap();
        let scene = tmp.path().join("scene");
        let out = sfs([
            "synth",
            "sombrero",
            "--size",
            "40x40",
            "--noise",
            "10",
            "--seed",
            "3",
            "--inpaint-disc",
            "0.5,0.5,0.2",
            "--out",
            &s(&scene),
        ]);
        assert_success(&out, "synth sombrero");
        Self { tmp, scene }
    }

    /// A path in the temporary folder (not created).
    fn path(&self, name: &str) -> PathBuf {
        self.tmp.path().join(name)
    }

    /// `D/name` as a string.
    fn scene_file(&self, name: &str) -> String {
        s(&self.scene.join(name))
    }

    /// `solve D/image16.png --camera D/scene.json -q --out OUT` plus `extra`.
    fn solve_args(&self, out: &Path, extra: &[&str]) -> Vec<String> {
        let mut args: Vec<String> = vec![
            "solve".into(),
            self.scene_file("image16.png"),
            "--camera".into(),
            self.scene_file("scene.json"),
            "-q".into(),
            "--out".into(),
            s(out),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    }

    /// `solve IMAGE --focal 40 -q --out OUT` plus `extra`.
    fn solve_focal_args(&self, image: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
        let mut args: Vec<String> = vec![
            "solve".into(),
            s(image),
            "--focal".into(),
            "40".into(),
            "-q".into(),
            "--out".into(),
            s(out),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    }

    /// Writes a grey 8-bit PNG of one value.
    fn grey_png(&self, name: &str, width: u32, height: u32, value: u8) -> PathBuf {
        let path = self.path(name);
        image::GrayImage::from_pixel(width, height, image::Luma([value]))
            .save(&path)
            .unwrap();
        path
    }

    fn write(&self, name: &str, contents: &str) -> PathBuf {
        let path = self.path(name);
        fs::write(&path, contents).unwrap();
        path
    }
}

/// Runs a command that must fail: non-zero exit, stderr containing every
/// one of `needles`, and `out` holding no files (no complete outputs, no
/// `*.partial` leftovers). Returns stderr.
#[track_caller]
fn expect_failure(args: &[String], out: &Path, needles: &[&str]) -> String {
    let result = sfs(args);
    let err = stderr(&result);
    assert!(
        !result.status.success(),
        "expected failure but it succeeded: {args:?}\nstderr:\n{err}"
    );
    assert_ne!(
        result.status.code(),
        None,
        "killed by a signal (a crash?): {args:?}\nstderr:\n{err}"
    );
    for needle in needles {
        assert!(
            err.contains(needle),
            "stderr does not mention `{needle}` for {args:?}:\n{err}"
        );
    }
    assert!(
        !err.contains("panicked"),
        "the binary panicked for {args:?}:\n{err}"
    );
    let left = entries(out);
    assert!(
        left.is_empty(),
        "{} holds {left:?} after a failed run of {args:?}",
        out.display()
    );
    err
}

// ---------------------------------------------------------------------------
// Happy paths
// ---------------------------------------------------------------------------

#[test]
fn synth_solve_eval_round_trip() {
    let fx = Fixture::new();
    let names = entries(&fx.scene);
    let expected: Vec<String> = {
        let mut v: Vec<String> = SYNTH_FILES.iter().map(|f| f.to_string()).collect();
        v.sort();
        v
    };
    assert_eq!(names, expected, "synth wrote the wrong files");

    let camera = read_json(&fx.scene.join("scene.json"));
    let keys: BTreeSet<&str> = camera
        .as_object()
        .expect("scene.json is an object")
        .keys()
        .map(String::as_str)
        .collect();
    let expected_keys: BTreeSet<&str> = [
        "name",
        "width",
        "height",
        "focal",
        "cx",
        "cy",
        "intensity_scale",
        "intensity_scale_measured",
    ]
    .into();
    assert_eq!(keys, expected_keys);
    assert_eq!(camera["intensity_scale_measured"], true);
    assert_eq!(camera["width"], 40);
    assert_eq!(camera["height"], 40);
    assert!(camera["focal"].as_f64().unwrap() > 0.0);

    // Solve against the ground truth, through the paper's whole pyramid.
    let r = fx.path("result");
    let mut args = fx.solve_args(&r, &["--init-depth", "from-image"]);
    args.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args), "solve");
    let mut expected: Vec<String> = SOLVE_FILES.iter().map(|f| f.to_string()).collect();
    expected.sort();
    assert_eq!(entries(&r), expected, "solve wrote the wrong files");
    // `--albedo auto` (the default) on a uniform render: the estimate is
    // reported and not used; albedo.npy holds 1 on the surface.
    let albedo_report = read_json(&r.join("report.json"));
    assert_eq!(
        albedo_report["albedo_fit"]["used"], false,
        "{albedo_report}"
    );
    let used = sfs_core::io::read_npy(&r.join("albedo.npy")).expect("albedo.npy");
    assert!(used.as_slice().iter().all(|a| a.is_nan() || *a == 1.0));
    // `--albedo 1`: no estimate, no albedo files, the same depth.
    let plain = fx.path("albedo_one");
    let mut args_one = fx.solve_args(&plain, &["--init-depth", "from-image", "--albedo", "1"]);
    args_one.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args_one), "solve --albedo 1");
    assert!(!plain.join("albedo.npy").exists() && !plain.join("albedo.png").exists());
    assert!(read_json(&plain.join("report.json"))["albedo_fit"].is_null());
    assert_eq!(
        std::fs::read(plain.join("depth.npy")).expect("depth.npy"),
        std::fs::read(r.join("depth.npy")).expect("depth.npy"),
        "albedo auto unused must solve exactly as albedo 1"
    );

    let report = read_json(&r.join("report.json"));
    let rse = report["rse"].as_f64().expect("report.rse is a number");
    assert!(rse.is_finite() && (0.0..0.1).contains(&rse), "rse {rse}");
    assert!(
        report["rie"]
            .as_f64()
            .expect("report.rie is a number")
            .is_finite()
    );
    assert!(
        report["seconds"]
            .as_f64()
            .expect("report.seconds is a number")
            >= 0.0
    );
    let levels = report["levels"]
        .as_array()
        .expect("report.levels is an array");
    assert!(!levels.is_empty());
    let widths: Vec<u64> = levels
        .iter()
        .map(|l| l["width"].as_u64().expect("level width"))
        .collect();
    assert!(
        widths.windows(2).all(|w| w[0] < w[1]),
        "level widths do not grow: {widths:?}"
    );
    assert_eq!(*widths.last().unwrap(), 40);
    assert_eq!(report["parameters"]["alpha"], "auto");
    assert_eq!(report["parameters"]["units"], "relative");
    let chosen = report["alpha_used"].as_f64().expect("alpha_used");
    assert!(chosen > 0.0 && chosen < 1e-3, "auto alpha {chosen}");
    assert_eq!(
        report["parameters"]["lambda"].as_f64(),
        Some(SolverParams::default().lambda)
    );

    // The depth map has the image's size and positive depth on the object.
    let depth = sfs_core::io::read_npy(&r.join("depth.npy")).unwrap();
    assert_eq!(depth.size(), (40, 40));
    assert!(depth.as_slice().iter().any(|z| z.is_finite() && *z > 0.0));

    // eval agrees with the report.
    let out = sfs([
        "eval",
        "--depth",
        &s(&r.join("depth.npy")),
        "--gt",
        &s(&fx.scene),
    ]);
    assert_success(&out, "eval");
    let printed: Value = serde_json::from_str(stdout(&out).trim())
        .unwrap_or_else(|e| panic!("eval printed no JSON ({e}): {}", stdout(&out)));
    let eval_rse = printed["rse"].as_f64().expect("eval rse");
    assert!(
        (eval_rse - rse).abs() <= 1e-6,
        "eval rse {eval_rse} != report rse {rse}"
    );
    assert!(printed["rie"].as_f64().is_some());

    // Warm start from the result: one level at full resolution.
    let warm = fx.path("warm");
    let depth_path = s(&r.join("depth.npy"));
    let args = fx.solve_args(&warm, &["--init-depth", &depth_path, "--kappa", "2"]);
    assert_success(&sfs(&args), "solve --init-depth depth.npy");
    let report = read_json(&warm.join("report.json"));
    let levels = report["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 1, "a warm start skips the coarse levels");
    assert_eq!(levels[0]["width"], 40);
    assert_eq!(report["parameters"]["init_depth"], depth_path.as_str());
    assert!(report["rse"].is_null(), "no --gt, no rse");
}

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
fn synth_renders_a_mesh() {
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes/suzanne.obj");
    if !mesh.is_file() {
        eprintln!("skipped: {} does not exist", mesh.display());
        return;
    }
    let tmp = tempdir().unwrap();
    let d = tmp.path().join("suzanne");
    let out = sfs(["synth", &s(&mesh), "--size", "64x32", "--out", &s(&d)]);
    assert_success(&out, "synth suzanne.obj");
    let mask = image::open(d.join("mask.png")).unwrap().to_luma8();
    assert_eq!(mask.dimensions(), (64, 32));
    let values: BTreeSet<u8> = mask.pixels().map(|p| p.0[0]).collect();
    assert!(
        values.contains(&0) && values.len() >= 2,
        "the mask should show object and background: {values:?}"
    );
    let camera = read_json(&d.join("scene.json"));
    assert_eq!(camera["name"], "suzanne");
    assert_eq!(
        (camera["width"].clone(), camera["height"].clone()),
        (64.into(), 32.into())
    );
}

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
        (
            "bench",
            &[
                "--meshes",
                "--quick",
                "--scenes",
                "--explicit-seconds",
                "--out",
            ][..],
        ),
    ] {
        let out = sfs([sub, "--help"]);
        assert_success(&out, &format!("{sub} --help"));
        let text = stdout(&out);
        for option in options {
            assert!(
                text.contains(option),
                "`{sub} --help` does not mention {option}:\n{text}"
            );
        }
    }
    let out = sfs(["--help"]);
    assert_success(&out, "--help");
    let text = stdout(&out);
    for sub in ["synth", "solve", "eval", "bench"] {
        assert!(text.contains(sub), "--help does not list {sub}:\n{text}");
    }
}

/// `bench --part albedo --quick` on the Sombrero: every light, pattern and
/// noise level, three RSEs each; a uniform clean render is solved exactly
/// as with albedo 1 (auto finds no edge or does not use it), a clean patch
/// render with auto comes within 1.5x of the true albedo given and far
/// below albedo 1, and a smooth albedo (no edge) is left as albedo 1.
#[test]
fn bench_albedo_solves_each_render_three_ways() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("albedo");
    let run = sfs([
        "bench",
        "--part",
        "albedo",
        "--quick",
        "--scenes",
        "sombrero",
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "bench --part albedo");
    assert!(out.join("albedo.md").is_file());
    let report = read_json(&out.join("albedo.json"));
    let rows = report["rows"].as_array().expect("rows");
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
    let meshes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes");
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("edges");
    let run = sfs([
        "bench",
        "--part",
        "edges",
        "--quick",
        "--scenes",
        "sombrero,suzanne",
        "--meshes",
        &s(&meshes),
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "bench --part edges");
    let report = read_json(&out.join("edges.json"));
    let rows = report["rows"].as_array().expect("rows");
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
    let md = std::fs::read_to_string(out.join("edges.md")).expect("edges.md");
    assert!(md.contains("| sombrero | 64x64 | 0 |"), "{md}");
}

#[test]
fn bench_holes_measures_every_hole_against_the_harmonic_fill() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("holes");
    let run = sfs([
        "bench",
        "--part",
        "holes",
        "--quick",
        "--scenes",
        "sombrero",
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "bench --part holes");
    let report = read_json(&out.join("holes.json"));
    let rows = report["rows"].as_array().expect("rows");
    let holes: BTreeSet<&str> = rows.iter().map(|r| r["hole"].as_str().unwrap()).collect();
    assert_eq!(
        holes,
        BTreeSet::from(["band", "blobs", "disc", "silhouette"])
    );
    assert_eq!(rows.len(), 8, "four holes, clean and noisy");
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
    let md = std::fs::read_to_string(out.join("holes.md")).expect("holes.md");
    assert!(md.contains("| sombrero | 128x128 | 0 | disc |"), "{md}");
}

#[test]
fn synth_shadows_has_ground_truth_and_solve_takes_the_shadow_out() {
    let dir = tempdir().expect("temp dir");
    let scene = dir.path().join("scene");
    let run = sfs([
        "synth",
        "sombrero",
        "--size",
        "96x96",
        "--light",
        "1.29,0,0.47",
        "--shadows",
        "--out",
        &s(&scene),
    ]);
    assert_success(&run, "synth --shadows");
    let truth = image::open(scene.join("shadow.png"))
        .expect("shadow.png")
        .to_luma8();
    let in_shadow = truth.pixels().filter(|p| p.0[0] > 127).count();
    assert!(
        in_shadow > 100,
        "the light 40 degrees off casts a shadow: {in_shadow}"
    );
    let out = dir.path().join("solved");
    let run = sfs([
        "solve",
        &s(&scene.join("image16.png")),
        "--camera",
        &s(&scene.join("scene.json")),
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "solve of the shadowed render");
    assert!(
        stderr(&run).contains("taken out of the data term"),
        "{}",
        stderr(&run)
    );
    let found = image::open(out.join("shadow.png"))
        .expect("solve writes shadow.png")
        .to_luma8();
    let agree = found
        .pixels()
        .zip(truth.pixels())
        .filter(|(a, b)| (a.0[0] > 127) == (b.0[0] > 127))
        .count();
    assert!(
        agree as f64 >= 0.99 * (96.0 * 96.0),
        "the solve's shadow is the render's: {agree} of 9216 agree"
    );
    let report = read_json(&out.join("report.json"));
    let share = report["shadow_share"].as_f64().expect("shadow_share");
    assert!((share - in_shadow as f64 / 9216.0).abs() < 0.01, "{share}");
}

#[test]
fn bench_speed_reports_every_method_side_by_side() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("speed");
    let run = sfs([
        "bench",
        "--part",
        "speed",
        "--quick",
        "--scenes",
        "sombrero",
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "bench --part speed");
    let report = read_json(&out.join("speed.json"));
    let rows = report["rows"].as_array().expect("rows");
    let methods: BTreeSet<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(
        methods,
        BTreeSet::from([
            "defaults",
            "fast marching",
            "fixed counts",
            "multigrid",
            "paper schedule"
        ])
    );
    for row in rows {
        assert_eq!(row["size"], "256x256");
        let rse = row["rse"].as_f64().unwrap();
        assert!(rse.is_finite() && rse < 0.1, "{row}");
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
    // SOR against V-cycles on the same system: both reduce the residual,
    // 4 cycles further than 40 sweeps.
    let convergence = report["convergence"].as_array().expect("convergence");
    assert_eq!(convergence.len(), 1);
    let c = &convergence[0];
    let value = |key: &str| c[key].as_f64().expect(key);
    assert!(value("sor_after_40") < value("sor_after_10") && value("sor_after_10") < 1.0);
    assert!(value("cycle_after_4") < value("sor_after_40"), "{c}");
    assert!(out.join("speed.md").exists());
    assert!(out.join("speed-sombrero-256x256.png").exists());
}

#[test]
fn bench_quick_on_a_tiny_configuration_writes_a_report_that_parses() {
    let dir = tempdir().expect("temp dir");
    let out = dir.path().join("bench");
    let run = sfs([
        "bench",
        "--quick",
        "--scenes",
        "sombrero",
        "--explicit-seconds",
        "0.5",
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "bench --quick");
    let report = read_json(&out.join("report.json"));
    let rows = report["rows"].as_array().expect("rows");
    let methods: BTreeSet<&str> = rows
        .iter()
        .map(|r| r["method"].as_str().expect("method"))
        .collect();
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
    let run = sfs(["bench", "--explicit-seconds", "0", "--out", &s(&out)]);
    assert!(!run.status.success());
    assert!(
        stderr(&run).contains("--explicit-seconds"),
        "{}",
        stderr(&run)
    );
    assert!(!out.exists());
}

// ---------------------------------------------------------------------------
// Bad inputs: each must fail, name the problem and write nothing.
// ---------------------------------------------------------------------------

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

#[test]
fn black_image() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let image = fx.grey_png("black.png", 40, 40, 0);
    expect_failure(
        &fx.solve_focal_args(&image, &out, &[]),
        &out,
        &["black.png", "black on every"],
    );
}

#[test]
fn saturated_image() {
    let fx = Fixture::new();
    let out = fx.path("r");
    let image = fx.grey_png("white.png", 40, 40, 255);
    expect_failure(
        &fx.solve_focal_args(&image, &out, &[]),
        &out,
        &["white.png", "saturated"],
    );
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
        let args: Vec<String> = vec![
            "synth".into(),
            s(&obj),
            "--size".into(),
            "16x16".into(),
            "--out".into(),
            s(&out),
        ];
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
    let scene = tmp.path().join("lit");
    assert_success(
        &sfs([
            "synth",
            "sombrero",
            "--size",
            "64x64",
            "--light",
            "0.5,-0.4,0",
            "--light-dir",
            "-0.2,0.2,1",
            "--light-mu",
            "1",
            "--out",
            &s(&scene),
        ]),
        "synth with a light",
    );
    let camera = read_json(&scene.join("scene.json"));
    assert_eq!(camera["lights"][0]["mu"], 1.0);
    let rse = |out: &str, extra: &[&str]| {
        let r = tmp.path().join(out);
        let mut args = vec![
            "solve".to_string(),
            s(&scene.join("image16.png")),
            "--camera".into(),
            s(&scene.join("scene.json")),
            "--gt".into(),
            s(&scene),
            "-q".into(),
            "--out".into(),
            s(&r),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        assert_success(&sfs(&args), out);
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
    let out = sfs([
        "solve",
        &s(&scene.join("image16.png")),
        "--camera",
        &s(&scene.join("scene.json")),
        "--method",
        "fast-marching",
        "-q",
        "--out",
        &s(&tmp.path().join("fm")),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("optical centre only"),
        "{}",
        stderr(&out)
    );
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
        assert_success(
            &sfs(["synth", "sombrero", "--size", size, "--out", &s(dir)]),
            "synth",
        );
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
    let scene = tmp.path().join("dark");
    assert_success(
        &sfs(["synth", "sombrero", "--size", "32x32", "--out", &s(&scene)]),
        "synth",
    );
    let image = sfs_core::io::read_image(&scene.join("image16.png"), false).unwrap();
    let dark = tmp.path().join("dark.png");
    sfs_core::io::write_png16(&dark, &image.map(|v| v * 0.0008)).unwrap();
    let r = tmp.path().join("r");
    let out = sfs(["solve", &s(&dark), "--focal", "32", "--out", &s(&r)]);
    assert_success(&out, "solve a dark image");
    assert!(stderr(&out).contains("too dark"), "{}", stderr(&out));
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

/// Two photographs of the Sombrero, each under a light of its own that a
/// camera file ties to it by name, bright enough that their sum passes 1
/// on most of the object though neither is clipped: the solve trusts the
/// sum (nothing saturated), and the report has the fit of the depth to
/// each photograph alone under its light.
#[test]
fn two_photographs_get_a_model_fit_each() {
    use sfs_core::light::PointLight;
    let tmp = tempdir().unwrap();
    let lights = [0.1, -0.1].map(|x| PointLight {
        position: [x, 0.0, 0.0],
        ..PointLight::CENTRED
    });
    let scenes = lights.map(|l| sfs_core::scene::sombrero::sombrero_lit(40, 40, &[l]));
    // One intensity scale for both, each photograph's brightest at 0.95.
    let scale = scenes
        .iter()
        .map(|scene| scene.intensity_scale)
        .fold(f64::INFINITY, f64::min)
        * 0.95
        / 0.9;
    let names = ["left.png", "right.png"];
    for (scene, name) in scenes.iter().zip(names) {
        let image = scene.image.map(|v| v * scale / scene.intensity_scale);
        sfs_core::io::write_png16(&tmp.path().join(name), &image).unwrap();
    }
    let camera = tmp.path().join("camera.json");
    let entries: Vec<Value> = lights
        .iter()
        .zip(names)
        .map(|(l, name)| serde_json::json!({"position": l.position, "image": name}))
        .collect();
    fs::write(
        &camera,
        serde_json::json!({
            "width": 40, "height": 40, "focal": 40.0, "cx": 19.5, "cy": 19.5,
            "lights": entries
        })
        .to_string(),
    )
    .unwrap();
    let r = tmp.path().join("r");
    let out = sfs([
        "solve",
        &s(&tmp.path().join(names[0])),
        &s(&tmp.path().join(names[1])),
        "--camera",
        &s(&camera),
        "--intensity-scale",
        &scale.to_string(),
        "--out",
        &s(&r),
    ]);
    assert_success(&out, "solve two photographs");
    let err = stderr(&out);
    for name in names {
        assert!(err.contains(&format!("{name} alone")), "{err}");
    }
    let report = read_json(&r.join("report.json"));
    assert_eq!(report["model_fit"]["saturated_share"], 0.0, "{report}");
    assert_eq!(report["input"]["clipped_share"], 0.0);
    assert_eq!(report["input"]["sum_divisor"], 2.0);
    let each = report["model_fit_per_photo"].as_array().unwrap();
    assert_eq!(each.len(), 2, "{report}");
    for (k, (fit, name)) in each.iter().zip(names).enumerate() {
        assert!(fit["image"].as_str().unwrap().ends_with(name), "{fit}");
        assert_eq!(fit["light_index"], k);
        let rie = fit["rie_trusted"].as_f64().unwrap();
        assert!(rie < 0.15, "{name}: {fit}");
        assert!(fit["poor_share"].is_number());
    }
    // One photograph has no fit per photograph.
    let one = tmp.path().join("one");
    assert_success(
        &sfs([
            "solve",
            &s(&tmp.path().join(names[0])),
            "--camera",
            &s(&camera),
            "--intensity-scale",
            &scale.to_string(),
            "-q",
            "--out",
            &s(&one),
        ]),
        "solve one photograph",
    );
    let report = read_json(&one.join("report.json"));
    assert!(report.get("model_fit_per_photo").is_none(), "{report}");
    assert!(report["input"].get("sum_divisor").is_none(), "{report}");
}

/// With a light beside the lens: without a known distance the solve says
/// plainly that the image does not determine the depth unit (and the
/// search's verdict is in the report); with two `--known-depth` points the
/// report lists each one's residual, and the first lands within 0.5 %.
#[test]
fn known_distances_are_reported_and_an_undetermined_scale_is_said() {
    let dir = tempdir().expect("temp dir");
    let scene = dir.path().join("scene");
    let run = sfs([
        "synth",
        "sombrero",
        "--size",
        "64x64",
        "--light",
        "0.5,0,0",
        "--out",
        &s(&scene),
    ]);
    assert_success(&run, "synth with a flash beside the lens");
    let truth = sfs_core::io::read_npy(&scene.join("depth_gt.npy")).expect("depth_gt.npy");
    let out = dir.path().join("auto");
    let run = sfs([
        "solve",
        &s(&scene.join("image16.png")),
        "--camera",
        &s(&scene.join("scene.json")),
        "--intensity-scale",
        "auto",
        "--out",
        &s(&out),
    ]);
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
    let run = sfs([
        "solve",
        &s(&scene.join("image16.png")),
        "--camera",
        &s(&scene.join("scene.json")),
        "--intensity-scale",
        "auto",
        "--known-depth",
        &format!("32,32,{a}"),
        "--known-depth",
        &format!("20,40,{b}"),
        "--out",
        &s(&out),
    ]);
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
    assert!(stderr(&run).contains("given"), "{}", stderr(&run));
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
        let scene = dir.path().join(name);
        let mut args = vec![
            "synth".to_owned(),
            "sombrero".into(),
            "--size".into(),
            "64x64".into(),
            "--out".into(),
            s(&scene),
        ];
        if let Some(light) = light {
            args.extend(["--light".into(), light.into()]);
        }
        assert_success(&sfs(&args), "synth");
        let truth = sfs_core::io::read_npy(&scene.join("depth_gt.npy")).expect("depth_gt.npy");
        let median = sfs_core::solver::calibrate::median_depth(&truth);
        let out = dir.path().join(format!("{name}-out"));
        let given = 1.2 * median;
        let run = sfs([
            "solve",
            &s(&scene.join("image16.png")),
            "--camera",
            &s(&scene.join("scene.json")),
            "--intensity-scale",
            "auto",
            "--distance",
            &given.to_string(),
            "--out",
            &s(&out),
        ]);
        assert_success(&run, "solve with --distance");
        let report = read_json(&out.join("report.json"));
        assert_eq!(report["depth_unit"]["source"], "distance", "{report}");
        let solved = report["depth_unit"]["solved_distance"]
            .as_f64()
            .expect("the solved distance");
        let tolerance = if light.is_some() { 0.021 } else { 1e-9 };
        assert!(
            (solved / given - 1.0).abs() < tolerance,
            "{name}: solved {solved}, given {given}"
        );
        assert!(
            stderr(&run).contains("depth unit from the given object distance"),
            "{}",
            stderr(&run)
        );
    }
    let scene = dir.path().join("centred");
    let image = s(&scene.join("image16.png"));
    let camera = s(&scene.join("scene.json"));
    let out = s(&dir.path().join("refused"));
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
        let mut args = vec![
            "solve".to_owned(),
            image.clone(),
            "--camera".into(),
            camera.clone(),
        ];
        args.extend(extra.iter().map(|a| (*a).to_owned()));
        args.extend(["--out".to_owned(), out.clone()]);
        assert_refused(&args, &[says]);
    }
}

/// A camera file that lists a rig of LEDs aimed at the object (as `synth
/// --ps-leds` writes one): one of its photographs solved with its scale
/// unknown (a photograph's case: the set's file says it) takes the depth unit from where the LEDs are aimed, within the 25 %
/// it promises, and says so.
#[test]
fn a_rig_s_aim_sets_the_depth_unit_at_the_defaults() {
    let dir = tempdir().expect("temp dir");
    let scene = dir.path().join("set");
    let run = sfs([
        "synth",
        "sombrero",
        "--size",
        "64x64",
        "--ps-leds",
        "4",
        "--out",
        &s(&scene),
    ]);
    assert_success(&run, "synth a set of four LEDs");
    let truth = sfs_core::io::read_npy(&scene.join("depth_gt.npy")).expect("depth_gt.npy");
    let median = sfs_core::solver::calibrate::median_depth(&truth);
    let camera = read_json(&scene.join("scene.json"));
    let first = camera["lights"][0]["image"]
        .as_str()
        .expect("the first light's image")
        .to_owned();
    let out = dir.path().join("one");
    let run = sfs([
        "solve",
        &s(&scene.join(&first)),
        "--camera",
        &s(&scene.join("scene.json")),
        "--intensity-scale",
        "auto",
        "--out",
        &s(&out),
    ]);
    assert_success(&run, "solve one LED's photograph, its scale unknown");
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["depth_unit"]["source"], "rig_aim", "{report}");
    let solved = report["depth_unit"]["solved_distance"]
        .as_f64()
        .expect("the solved distance");
    assert!(
        (solved / median - 1.0).abs() < 0.25,
        "solved {solved}, true {median}"
    );
    assert!(
        stderr(&run).contains("depth unit from the LEDs' aim point (4 lights)"),
        "{}",
        stderr(&run)
    );
}

/// Runs `args` and asserts it fails with a message containing every one of
/// `says`.
#[track_caller]
fn assert_refused(args: &[String], says: &[&str]) {
    let run = sfs(args);
    assert!(!run.status.success(), "{args:?} succeeded");
    let message = stderr(&run);
    for part in says {
        assert!(message.contains(part), "{args:?}: {message}");
    }
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
        assert!(stderr(&run).contains("reach no pixel"), "{}", stderr(&run));
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
    assert!(
        stderr(&run).contains("behind the camera"),
        "{}",
        stderr(&run)
    );
}

#[test]
fn a_glossy_render_is_recovered_with_its_model_and_eval_measures_with_it() {
    let dir = tempdir().expect("temp dir");
    let scene = dir.path().join("glossy");
    let out = sfs([
        "synth",
        "sombrero",
        "--size",
        "64x64",
        "--reflectance",
        "blinn-phong",
        "--specular",
        "0.3",
        "--shininess",
        "30",
        "--out",
        &s(&scene),
    ]);
    assert_success(&out, "synth with blinn-phong");
    let camera = read_json(&scene.join("scene.json"));
    assert_eq!(camera["material"]["model"], "blinn-phong");
    assert_eq!(camera["material"]["shininess"], 30.0);
    let solve = |name: &str, extra: &[&str]| -> Value {
        let result = dir.path().join(name);
        let mut args = vec![
            "solve".to_string(),
            s(&scene.join("image16.png")),
            "--camera".into(),
            s(&scene.join("scene.json")),
            "--gt".into(),
            s(&scene),
            "--quiet".into(),
            "--out".into(),
            s(&result),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        assert_success(&sfs(&args), name);
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
    let base = [
        "solve".to_string(),
        s(&scene.join("image16.png")),
        "--camera".into(),
        s(&scene.join("scene.json")),
        "--out".into(),
        s(&refused),
    ];
    let with = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    };
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

// ---------------------------------------------------------------------------
// Photometric stereo
// ---------------------------------------------------------------------------

/// `synth --ps-leds 4` writes a set with its truth; `solve
/// --photometric-stereo` reads it through the pipeline, writes depth,
/// normals, albedo and a residual per photograph, measures against the
/// truth and compares one photograph's single-image solve; bad sets are
/// refused naming the file, with nothing written.
#[test]
fn photometric_stereo_end_to_end() {
    let dir = tempdir().expect("temp dir");
    let set = dir.path().join("set");
    let out = sfs([
        "synth",
        "sombrero",
        "--size",
        "48x48",
        "--ps-leds",
        "4",
        "--out",
        &s(&set),
    ]);
    assert_success(&out, "synth --ps-leds");
    let files = entries(&set);
    for name in [
        "led01.png",
        "led04.png",
        "mask.png",
        "depth_gt.npy",
        "normals_gt.npy",
        "albedo_gt.npy",
        "scene.json",
    ] {
        assert!(files.contains(&name.to_owned()), "{files:?}");
    }
    let images: Vec<String> = (1..=4)
        .map(|k| s(&set.join(format!("led{k:02}.png"))))
        .collect();
    let solved = dir.path().join("solved");
    let mut args: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    args.extend(images.iter().cloned());
    args.extend([
        "--camera".into(),
        s(&set.join("scene.json")),
        "--mask".into(),
        s(&set.join("mask.png")),
        "--gt".into(),
        s(&set),
        "--compare-single".into(),
        "led02.png".into(),
        "--out".into(),
        s(&solved),
    ]);
    let out = sfs(&args);
    assert_success(&out, "solve --photometric-stereo");
    let written = entries(&solved);
    for name in [
        "depth.npy",
        "normals.npy",
        "normals.png",
        "albedo.npy",
        "albedo.png",
        "residual_01.png",
        "residual_04.png",
        "single_depth.npy",
        "mesh.ply",
        "report.json",
    ] {
        assert!(written.contains(&name.to_owned()), "{written:?}");
    }
    let report = read_json(&solved.join("report.json"));
    assert_eq!(report["mode"], "photometric_stereo");
    assert_eq!(report["photographs"].as_array().map(Vec::len), Some(4));
    let rse = report["errors"]["rse"].as_f64().expect("rse");
    let normals = report["errors"]["mean_normal_error_deg"]
        .as_f64()
        .expect("normal error");
    let albedo = report["errors"]["albedo_median_relative_error"]
        .as_f64()
        .expect("albedo error");
    assert!(rse < 0.05 && normals < 5.0 && albedo < 0.05, "{report}");
    assert!(
        report["single_image"]["rse_to_set"].as_f64().is_some(),
        "{report}"
    );
    assert!(stderr(&out).contains("alone (single-image method"));

    // Bad sets: the message names what is wrong, nothing is written.
    let bad = dir.path().join("bad");
    let mut one: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    one.push(images[0].clone());
    one.extend([
        "--camera".into(),
        s(&set.join("scene.json")),
        "--out".into(),
        s(&bad),
    ]);
    expect_failure(&one, &bad, &["at least 2 photographs"]);
    let mut twice: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    twice.extend(images[..2].iter().cloned());
    twice.extend([
        "--focal".into(),
        "48".into(),
        "--light".into(),
        "0.1,0,0".into(),
        "--light".into(),
        "0.1,0,0".into(),
        "--out".into(),
        s(&bad),
    ]);
    expect_failure(&twice, &bad, &["led01.png", "led02.png", "same light"]);
    let mut counts: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    counts.extend(images[..3].iter().cloned());
    counts.extend([
        "--focal".into(),
        "48".into(),
        "--light".into(),
        "0.1,0,0".into(),
        "--out".into(),
        s(&bad),
    ]);
    expect_failure(&counts, &bad, &["3 photographs but 1 lights"]);
    let mut unknown: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    unknown.extend(images.iter().cloned());
    unknown.extend([
        "--camera".into(),
        s(&set.join("scene.json")),
        "--photo-confidence".into(),
        "led09.png=x.png".into(),
        "--out".into(),
        s(&bad),
    ]);
    expect_failure(&unknown, &bad, &["led09.png", "not one of the photographs"]);
}
