//! What the end-to-end tests share: the binary and its runs, the files
//! `synth` and `solve` write, the Sombrero fixture and the checks of a
//! refused run.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use tempfile::{TempDir, tempdir};

/// The binary under test.
pub(crate) const BIN: &str = env!("CARGO_BIN_EXE_sfs-studio");
/// The folder the runs start in: the package's, where `cargo test` starts
/// them too.
const RUN_DIR: &str = env!("CARGO_MANIFEST_DIR");

// Running the binary and reading its output, as the bench's tests do.
#[path = "../support/binary.rs"]
mod binary;
pub(crate) use binary::{
    assert_help_mentions, assert_success, read_json, run_into, s, sfs, stderr, stdout,
};

/// Files `synth` writes (with `--noise` and `--inpaint-disc`), the hidden
/// manifest of the run's outputs included.
pub(crate) const SYNTH_FILES: [&str; 8] = [
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
pub(crate) const SOLVE_FILES: [&str; 11] = [
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

/// Names of the entries of `dir` (empty if it does not exist).
pub(crate) fn entries(dir: &Path) -> Vec<String> {
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

/// A temporary folder holding `synth sombrero --size 40x40` with noise and
/// an inpainting disc in `scene/`.
pub(crate) struct Fixture {
    tmp: TempDir,
    pub(crate) scene: PathBuf,
}

impl Fixture {
    pub(crate) fn new() -> Self {
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
    pub(crate) fn path(&self, name: &str) -> PathBuf {
        self.tmp.path().join(name)
    }

    /// `D/name` as a string.
    pub(crate) fn scene_file(&self, name: &str) -> String {
        s(&self.scene.join(name))
    }

    /// `solve D/image16.png --camera D/scene.json -q --out OUT` plus `extra`.
    pub(crate) fn solve_args(&self, out: &Path, extra: &[&str]) -> Vec<String> {
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
    pub(crate) fn solve_focal_args(&self, image: &Path, out: &Path, extra: &[&str]) -> Vec<String> {
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
    pub(crate) fn grey_png(&self, name: &str, width: u32, height: u32, value: u8) -> PathBuf {
        let path = self.path(name);
        image::GrayImage::from_pixel(width, height, image::Luma([value]))
            .save(&path)
            .unwrap();
        path
    }

    pub(crate) fn write(&self, name: &str, contents: &str) -> PathBuf {
        let path = self.path(name);
        fs::write(&path, contents).unwrap();
        path
    }
}

/// Runs a command that must fail: non-zero exit, stderr containing every
/// one of `needles`, and `out` holding no files (no complete outputs, no
/// `*.partial` leftovers). Returns stderr.
#[track_caller]
pub(crate) fn expect_failure(args: &[String], out: &Path, needles: &[&str]) -> String {
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

/// Runs `args` and asserts it fails with a message containing every one of
/// `says`.
#[track_caller]
pub(crate) fn assert_refused(args: &[String], says: &[&str]) {
    let run = sfs(args);
    assert!(!run.status.success(), "{args:?} succeeded");
    let message = stderr(&run);
    for part in says {
        assert!(message.contains(part), "{args:?}: {message}");
    }
}

/// Runs `synth ARGS --out DIR` (`args` start with the model), asserts it
/// succeeded and returns `DIR`.
#[track_caller]
pub(crate) fn synth_into(dir: &Path, args: &[&str]) -> PathBuf {
    run_into(dir, "synth", args);
    dir.to_path_buf()
}

/// Runs `solve SCENE/IMAGE --camera SCENE/scene.json EXTRA --out OUT` on a
/// folder `synth` wrote and returns the run, unchecked.
pub(crate) fn solve_scene(scene: &Path, image: &str, out: &Path, extra: &[&str]) -> Output {
    sfs(solve_scene_args(scene, image, out, extra))
}

/// The arguments of [`solve_scene`]: `solve SCENE/IMAGE --camera
/// SCENE/scene.json EXTRA --out OUT`.
pub(crate) fn solve_scene_args(
    scene: &Path,
    image: &str,
    out: &Path,
    extra: &[&str],
) -> Vec<String> {
    let mut args: Vec<String> = vec![
        "solve".into(),
        s(&scene.join(image)),
        "--camera".into(),
        s(&scene.join("scene.json")),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    args.extend(["--out".into(), s(out)]);
    args
}

/// [`synth_into`] with the arguments written as one command line (words
/// split at spaces): `synth_line(dir, "sombrero --size 64x64")`.
#[track_caller]
pub(crate) fn synth_line(dir: &Path, line: &str) -> PathBuf {
    synth_into(dir, &line.split_whitespace().collect::<Vec<_>>())
}

/// The depth `synth` wrote as the truth into `scene`.
pub(crate) fn truth_depth(scene: &Path) -> sfs_core::grid::Grid<f64> {
    sfs_core::io::read_npy(&scene.join("depth_gt.npy")).expect("depth_gt.npy")
}

/// `solve --photometric-stereo SET/led01.png .. SET/ledNN.png` (`photos`
/// of them, as `synth --ps-leds` names them) `--camera SET/scene.json`,
/// then `extra`, then `--out OUT`.
pub(crate) fn set_solve_args(set: &Path, photos: usize, extra: &[&str], out: &Path) -> Vec<String> {
    let mut args: Vec<String> = vec!["solve".into(), "--photometric-stereo".into()];
    args.extend((1..=photos).map(|k| s(&set.join(format!("led{k:02}.png")))));
    args.extend(["--camera".into(), s(&set.join("scene.json"))]);
    args.extend(extra.iter().map(|a| a.to_string()));
    args.extend(["--out".into(), s(out)]);
    args
}

/// A temporary folder with [`synth_line`]`(DIR/name, line)` written in it:
/// the folder and the scene's folder.
#[track_caller]
pub(crate) fn synth_in_temp(name: &str, line: &str) -> (TempDir, PathBuf) {
    let dir = tempdir().expect("temp dir");
    let scene = synth_line(&dir.path().join(name), line);
    (dir, scene)
}

/// Asserts the run's stderr contains `text`, showing it otherwise.
#[track_caller]
pub(crate) fn assert_said(out: &Output, text: &str) {
    let said = stderr(out);
    assert!(said.contains(text), "{said}");
}

/// `words` as owned strings, for an argument list.
pub(crate) fn strings(words: &[&str]) -> Vec<String> {
    words.iter().map(|w| w.to_string()).collect()
}
