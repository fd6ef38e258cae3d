//! `solve --out-dir`: many photographs (a folder, a pattern) each solved
//! alone into a folder of its own, one summary table, the same depth as a
//! solve of each alone, and a failed photograph named without stopping the
//! others.

use std::process::Output;

use crate::common::{Fixture, assert_success, s, sfs, stdout};

/// Three copies of the fixture's render in `photos/`, and its camera file.
fn photos(fx: &Fixture) -> (std::path::PathBuf, String) {
    let dir = fx.path("photos");
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["a.png", "b.png", "c.png"] {
        std::fs::copy(fx.scene.join("image16.png"), dir.join(name)).unwrap();
    }
    std::fs::write(dir.join("notes.txt"), "not a photograph").unwrap();
    (dir, fx.scene_file("scene.json"))
}

/// `solve SOURCE --camera CAMERA --out-dir MANY`, unchecked.
fn solve_many(source: &std::path::Path, camera: &str, many: &std::path::Path) -> Output {
    sfs([
        "solve",
        &s(source),
        "--camera",
        camera,
        "--out-dir",
        &s(many),
    ])
}

#[test]
fn a_folder_is_solved_photograph_by_photograph_with_one_table() {
    let fx = Fixture::new();
    let (dir, camera) = photos(&fx);
    let many = fx.path("many");
    let out = solve_many(&dir, &camera, &many);
    assert_success(&out, "solve DIR --out-dir");
    let table = stdout(&out);
    let lines: Vec<&str> = table.lines().collect();
    assert_eq!(lines.len(), 4, "{table}");
    assert!(lines[0].starts_with("file"), "{table}");
    for (line, name) in lines[1..].iter().zip(["a.png", "b.png", "c.png"]) {
        assert!(line.starts_with(name), "{table}");
    }
    // Each photograph's depth is the solve of it alone.
    let alone = fx.path("alone");
    assert_success(
        &sfs(fx.solve_args(&alone, &[])),
        "solve of the photograph alone",
    );
    let expected = sfs_core::io::read_npy(&alone.join("depth.npy")).unwrap();
    for name in ["a", "b", "c"] {
        let depth = sfs_core::io::read_npy(&many.join(name).join("depth.npy")).unwrap();
        assert_eq!(depth.size(), expected.size(), "{name}");
        for (a, b) in depth.as_slice().iter().zip(expected.as_slice()) {
            assert!(
                a.is_nan() && b.is_nan() || (a - b).abs() <= 1e-6 * b.abs(),
                "{name}: {a} against {b}"
            );
        }
    }
}

#[test]
fn a_pattern_picks_its_photographs_and_a_failure_is_a_row() {
    let fx = Fixture::new();
    let (dir, camera) = photos(&fx);
    std::fs::write(dir.join("broken.png"), b"not a png").unwrap();
    let many = fx.path("many");
    let pattern = dir.join("b*.png");
    let out = solve_many(&pattern, &camera, &many);
    assert!(!out.status.success(), "a failed photograph fails the run");
    let table = stdout(&out);
    assert!(
        table.contains("b.png") && table.contains("broken.png"),
        "{table}"
    );
    assert!(!table.contains("a.png"), "{table}");
    assert!(table.contains("error: "), "{table}");
    assert!(many.join("b").join("depth.npy").is_file());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("1 of 2 photographs"), "{stderr}");
}
