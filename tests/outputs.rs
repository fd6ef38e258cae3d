//! The binary's outputs are whole or absent: a second run into a busy
//! folder is refused at once, Ctrl-C and SIGTERM leave nothing behind, a
//! killed run is cleaned up by the next one, a bad destination is refused
//! before any work, and `synth` into a reused folder leaves no stale files.
#![cfg(unix)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

// The CLI tests' helpers: the binary, its runs, the files a solve writes
// (this test uses few of them).
#[allow(dead_code, unused_imports)]
#[path = "cli/common.rs"]
mod common;

use common::{BIN, SOLVE_FILES, assert_success, entries as names, sfs as run};

fn spawn(args: &[&str]) -> Child {
    Command::new(BIN)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start sfs-studio")
}

fn staging_folders(dir: &Path) -> usize {
    names(dir)
        .iter()
        .filter(|n| n.starts_with(".sfs-studio-staging-"))
        .count()
}

/// Waits until a run has locked `dir` and started staging (a hang check).
fn wait_for_staging(dir: &Path, child: &mut Child) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while staging_folders(dir) == 0 {
        assert!(
            child.try_wait().expect("poll").is_none(),
            "the run ended before staging"
        );
        assert!(Instant::now() < deadline, "no staging folder in 60 s");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A temporary folder holding [`scene`], and the scene's image and camera.
fn scene_in_temp() -> (tempfile::TempDir, PathBuf, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let (image, camera) = scene(tmp.path());
    (tmp, image, camera)
}

/// Sends `signal` (`-INT`, `-TERM`) to `child`; whether `kill` succeeded.
fn send(signal: &str, child: &Child) -> bool {
    Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap()
        .success()
}

/// A scene large enough that its solve takes a while (about a second).
fn scene(tmp: &Path) -> (PathBuf, PathBuf) {
    let dir = tmp.join("scene");
    let out = run([
        "synth",
        "sombrero",
        "--size",
        "640x640",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert_success(&out, "synth");
    (dir.join("image16.png"), dir.join("scene.json"))
}

fn solve_args<'a>(image: &'a Path, camera: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "solve",
        image.to_str().unwrap(),
        "--camera",
        camera.to_str().unwrap(),
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]
}

/// Starts `solve` of `image` into `out` and waits until it is staging.
fn start_solve(image: &Path, camera: &Path, out: &Path) -> Child {
    let mut child = spawn(&solve_args(image, camera, out));
    wait_for_staging(out, &mut child);
    child
}

/// The files a solve writes, sorted as [`names`] lists them.
fn solve_outputs() -> Vec<String> {
    let mut files: Vec<String> = SOLVE_FILES.iter().map(|f| f.to_string()).collect();
    files.sort();
    files
}

#[test]
fn a_second_run_into_a_busy_folder_is_refused_and_the_first_is_whole() {
    let (tmp, image, camera) = scene_in_temp();
    let out = tmp.path().join("out");
    let mut first = start_solve(&image, &camera, &out);
    let second = run(solve_args(&image, &camera, &out));
    assert!(!second.status.success());
    let message = String::from_utf8_lossy(&second.stderr);
    assert!(
        message.contains("being written by another sfs-studio run") && message.contains("out"),
        "{message}"
    );
    let status = first.wait().unwrap();
    assert!(status.success());
    assert_eq!(names(&out), solve_outputs());
}

#[test]
fn an_interrupted_run_leaves_nothing() {
    let (tmp, image, camera) = scene_in_temp();
    for signal in ["-INT", "-TERM"] {
        // Into a new folder: it is gone again.
        let out = tmp.path().join(format!("new{signal}"));
        let mut child = start_solve(&image, &camera, &out);
        assert!(send(signal, &child));
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(130), "{signal}");
        assert!(!out.exists(), "{signal}: {:?}", names(&out));
    }
    // Into a folder with an earlier result: it stays as it was.
    let out = tmp.path().join("kept");
    assert!(run(solve_args(&image, &camera, &out)).status.success());
    let before = fs::read(out.join("depth.npy")).unwrap();
    let mut child = start_solve(&image, &camera, &out);
    send("-INT", &child);
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert_eq!(names(&out), solve_outputs());
    assert_eq!(fs::read(out.join("depth.npy")).unwrap(), before);
}

#[test]
fn a_killed_run_is_cleaned_up_by_the_next() {
    let (tmp, image, camera) = scene_in_temp();
    let out = tmp.path().join("out");
    let mut child = start_solve(&image, &camera, &out);
    child.kill().unwrap(); // SIGKILL: nothing runs
    child.wait().unwrap();
    assert_eq!(staging_folders(&out), 1);
    let mut args = solve_args(&image, &camera, &out);
    args.extend(["--max-side", "200"]);
    let next = run(&args);
    assert_success(&next, "solve");
    assert_eq!(names(&out), solve_outputs());
}

#[test]
fn a_bad_destination_is_refused_before_solving() {
    let (tmp, image, camera) = scene_in_temp();
    let file = tmp.path().join("a-file");
    fs::write(&file, "x").unwrap();
    for out in [file.clone(), file.join("below")] {
        // Not quiet: a solve that ran would print its summary.
        let args: Vec<&str> = solve_args(&image, &camera, &out)
            .into_iter()
            .filter(|a| *a != "--quiet")
            .collect();
        let result = run(&args);
        assert!(!result.status.success());
        let message = String::from_utf8_lossy(&result.stderr);
        assert!(message.contains("a-file"), "{message}");
        // Refused up front: no solve ran, so nothing was reported solved.
        assert!(!message.contains("solved"), "{message}");
    }
    assert_eq!(fs::read_to_string(&file).unwrap(), "x");
}

#[test]
fn synth_into_a_reused_folder_leaves_no_stale_files() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scene");
    let o = out.to_str().unwrap();
    let first = run([
        "synth",
        "sombrero",
        "--size",
        "32x32",
        "--noise",
        "5",
        "--inpaint-disc",
        "0.5,0.5,0.2",
        "--out",
        o,
    ]);
    assert!(first.status.success());
    assert!(out.join("noisy8.png").exists() && out.join("confidence.png").exists());
    fs::write(out.join("notes.txt"), "mine").unwrap();
    let second = run(["synth", "sombrero", "--size", "32x32", "--out", o]);
    assert!(second.status.success());
    assert_eq!(
        names(&out),
        [
            ".sfs-studio-outputs",
            "depth_gt.npy",
            "image16.png",
            "image8.png",
            "mask.png",
            "notes.txt",
            "scene.json"
        ]
    );
}

#[test]
fn oversized_jobs_are_refused_with_the_estimate_and_the_way_out() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("big");
    // Runs `args` with `mb` MiB of memory allowed: it must fail, and its
    // message is returned.
    let refused = |args: &[&str], mb: &str| {
        let result = Command::new(BIN)
            .args(args)
            .env("SFS_STUDIO_MEMORY_MB", mb)
            .output()
            .unwrap();
        assert!(!result.status.success());
        String::from_utf8_lossy(&result.stderr).into_owned()
    };
    let message = refused(
        &[
            "synth",
            "sombrero",
            "--size",
            "8000x8000",
            "--out",
            out.to_str().unwrap(),
        ],
        "500",
    );
    assert!(
        message.contains("8000x8000") && message.contains("500 MiB") && message.contains("--size"),
        "{message}"
    );
    assert!(!out.exists());
    // A solve names the working size that would fit.
    let (image, camera) = scene(tmp.path());
    let message = refused(&solve_args(&image, &camera, &out), "150");
    assert!(
        message.contains("640x640") && message.contains("--max-side"),
        "{message}"
    );
    assert!(!out.exists());
}

#[test]
fn an_input_named_like_an_output_is_never_removed() {
    let (tmp, image, camera) = scene_in_temp();
    let out = tmp.path().join("out");
    let mut args = solve_args(&image, &camera, &out);
    args.extend(["--auto-confidence"]);
    assert!(run(&args).status.success());
    let confidence = out.join("confidence_used.png");
    assert!(confidence.exists());
    // The next run reads it (and writes no confidence_used.png itself).
    let mut args = solve_args(&image, &camera, &out);
    args.extend(["--confidence", confidence.to_str().unwrap()]);
    let result = run(&args);
    assert_success(&result, "solve");
    assert!(
        confidence.exists(),
        "an input was removed as a stale output"
    );
}

#[test]
fn a_grey_float32_tiff_solves() {
    let (tmp, image, camera) = scene_in_temp();
    let grid = sfs_core::io::read_image(&image, false).unwrap();
    let path = tmp.path().join("float.tif");
    let values: Vec<f32> = grid.as_slice().iter().map(|&v| v as f32).collect();
    let mut encoder = tiff::encoder::TiffEncoder::new(fs::File::create(&path).unwrap()).unwrap();
    encoder
        .write_image::<tiff::encoder::colortype::Gray32Float>(
            grid.width() as u32,
            grid.height() as u32,
            &values,
        )
        .unwrap();
    let out = tmp.path().join("out");
    let mut args = solve_args(&path, &camera, &out);
    args.extend(["--max-side", "160"]);
    let result = run(&args);
    assert_success(&result, "solve");
    assert!(out.join("depth.npy").exists());
}
