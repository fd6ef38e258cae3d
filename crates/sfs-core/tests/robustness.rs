//! The robustness suite: seeded random problems with random in-range
//! parameters (every solve ends with finite depth or a clear error, never a
//! panic), and byte-mutated files for every loader (an error naming the
//! file, never a panic). Reproducible: the seeds are fixed, and a failure
//! prints the case.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::params::{PARAMS, ParamKind, ParamValue, SolverParams};
use sfs_core::solver::{Problem, SolveError, solve};

/// A random image: smooth shading, constant, noise, with black or
/// saturated patches.
fn random_image(rng: &mut StdRng, w: usize, h: usize) -> Grid<f64> {
    let kind = rng.random_range(0..4);
    let (a, b) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
    let mut image = Grid::from_fn(w, h, |c, r| match kind {
        0 => 0.2 + 0.7 * ((c as f64 * a * 0.3).sin() * (r as f64 * b * 0.3).cos()).abs(),
        1 => a,
        2 => rng_free_hash(c, r, a),
        _ => (c + r) as f64 / (w + h) as f64,
    });
    // Patches of black or clipped pixels.
    for _ in 0..rng.random_range(0..3) {
        let (c0, r0) = (rng.random_range(0..w), rng.random_range(0..h));
        let value = if rng.random_bool(0.5) { 0.0 } else { 1.0 };
        for r in r0..(r0 + 4).min(h) {
            for c in c0..(c0 + 4).min(w) {
                *image.at_mut(c, r) = value;
            }
        }
    }
    image
}

/// Deterministic pseudo-noise in [0, 1) from a pixel and a seed.
fn rng_free_hash(c: usize, r: usize, seed: f64) -> f64 {
    let x = (c as f64 * 12.9898 + r as f64 * 78.233 + seed * 37.719).sin() * 43758.5453;
    x - x.floor()
}

/// Parameters with every real drawn log-uniformly (or uniformly from 0)
/// across its whole accepted range, words at random, and counts kept small
/// (a count's range bounds work, which a few hundred solves cannot spend).
fn random_params(rng: &mut StdRng) -> (SolverParams, Vec<String>) {
    let mut params = SolverParams::default();
    let mut chosen = Vec::new();
    for spec in PARAMS {
        if !rng.random_bool(0.4) {
            continue;
        }
        let value = match spec.kind {
            ParamKind::Real { min, max, auto, .. } => {
                if auto && rng.random_bool(0.2) {
                    ParamValue::Auto
                } else if min <= 0.0 {
                    ParamValue::Real(if rng.random_bool(0.2) {
                        min
                    } else {
                        rng.random_range(min..=max).min(max)
                    })
                } else {
                    let t: f64 = rng.random_range(0.0..=1.0);
                    ParamValue::Real((min.ln() + t * (max.ln() - min.ln())).exp().clamp(min, max))
                }
            }
            ParamKind::Count { min, max } => {
                ParamValue::Count(rng.random_range(min..=max.min(min.max(1) + 4)))
            }
            ParamKind::Choice(words) => ParamValue::Choice(words[rng.random_range(0..words.len())]),
        };
        if spec.check(value).is_ok() {
            (spec.set)(&mut params, value);
            chosen.push(format!("{}={value}", spec.name));
        }
    }
    // kappa-max must be at least kappa; other combinations are the
    // solver's to refuse.
    params.kappa_max = params.kappa_max.max(params.kappa);
    (params, chosen)
}

#[test]
fn random_problems_end_in_finite_depth_or_a_clear_error() {
    let mut rng = StdRng::seed_from_u64(0x5f5_2026);
    let (mut solved, mut refused) = (0, 0);
    for case in 0..300 {
        let (w, h) = (rng.random_range(2..=64), rng.random_range(2..=64));
        let image = random_image(&mut rng, w, h);
        let object_mask = rng
            .random_bool(0.4)
            .then(|| Grid::from_fn(w, h, |c, r| rng_free_hash(c, r, 0.3) < 0.8));
        let confidence = rng
            .random_bool(0.3)
            .then(|| Grid::from_fn(w, h, |c, r| rng_free_hash(c, r, 0.7)));
        let problem = Problem {
            image,
            camera: Intrinsics::centred(rng.random_range(0.5..200.0), w, h),
            intensity_scale: 10f64.powf(rng.random_range(-3.0..3.0)),
            object_mask,
            confidence,
            lights: Vec::new(),
        };
        let (params, chosen) = random_params(&mut rng);
        let label = format!("case {case}: {w}x{h}, {chosen:?}");
        let outcome = catch_unwind(AssertUnwindSafe(|| solve(&problem, &params, &mut ())));
        match outcome {
            Err(_) => panic!("{label}: the solver panicked"),
            Ok(Ok(solution)) => {
                solved += 1;
                let object = problem.object_mask.clone();
                for (q, z) in solution.depth.as_slice().iter().enumerate() {
                    let on_object = object.as_ref().is_none_or(|m| m.as_slice()[q]);
                    assert!(
                        !on_object || (z.is_finite() && *z > 0.0),
                        "{label}: depth {z} at pixel {q}"
                    );
                }
                assert!(
                    solution
                        .reprojection
                        .as_slice()
                        .iter()
                        .all(|v| v.is_finite()),
                    "{label}: reprojection not finite"
                );
            }
            Ok(Err(SolveError::Cancelled)) => panic!("{label}: cancelled without a request"),
            Ok(Err(e)) => {
                refused += 1;
                let message = e.to_string();
                eprintln!("{label}: {message}");
                assert!(message.len() > 10, "{label}: unclear error {message:?}");
            }
        }
    }
    eprintln!("solved {solved}, refused {refused}");
    // Not vacuous: most of them solve, some are refused (2-pixel sides,
    // black or saturated images).
    assert!(
        solved > 150 && refused > 0,
        "solved {solved}, refused {refused}"
    );
}

/// Writes `count` mutations of `original` (bytes flipped, a cut, bytes
/// inserted) to `dir/NAME` and calls `load` on each: it must return, and
/// an error must name the file.
fn mutate_and_load<T>(
    original: &[u8],
    name: &str,
    count: usize,
    seed: u64,
    load: impl Fn(&Path) -> Result<T, String>,
) {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut rng = StdRng::seed_from_u64(seed);
    for k in 0..count {
        let mut bytes = original.to_vec();
        match k % 3 {
            0 => {
                for _ in 0..rng.random_range(1..8) {
                    let i = rng.random_range(0..bytes.len());
                    bytes[i] = rng.random();
                }
            }
            1 => bytes.truncate(rng.random_range(0..bytes.len())),
            _ => {
                let i = rng.random_range(0..bytes.len());
                let extra: Vec<u8> = (0..rng.random_range(1..16)).map(|_| rng.random()).collect();
                bytes.splice(i..i, extra);
            }
        }
        let path = dir.path().join(format!("{k}-{name}"));
        std::fs::write(&path, &bytes).expect("write");
        let outcome = catch_unwind(AssertUnwindSafe(|| load(&path)));
        match outcome {
            Err(_) => panic!("loading mutation {k} of {name} (seed {seed}) panicked"),
            Ok(Ok(_)) => {}
            Ok(Err(message)) => {
                let file = path.file_name().map(|f| f.to_string_lossy().into_owned());
                assert!(
                    file.is_some_and(|f| message.contains(&f)),
                    "mutation {k} of {name}: the error does not name the file: {message}"
                );
            }
        }
    }
}

fn sample_grid() -> Grid<f64> {
    Grid::from_fn(24, 16, |c, r| 0.1 + 0.8 * rng_free_hash(c, r, 0.5))
}

#[test]
fn mutated_images_masks_and_arrays_are_refused_by_name() {
    let dir = tempfile::tempdir().expect("temp dir");
    let grid = sample_grid();
    let png16 = dir.path().join("a16.png");
    sfs_core::io::write_png16(&png16, &grid).expect("png16");
    let png8 = dir.path().join("a8.png");
    sfs_core::io::write_png8(&png8, &grid).expect("png8");
    let npy = dir.path().join("a.npy");
    sfs_core::io::write_npy_f32(&npy, &grid).expect("npy");
    let tiff = dir.path().join("a.tif");
    let jpeg = dir.path().join("a.jpg");
    let rgb = image::RgbImage::from_fn(24, 16, |c, r| {
        let v = (grid.at(c as usize, r as usize) * 255.0) as u8;
        image::Rgb([v, v / 2, 255 - v])
    });
    rgb.save(&tiff).expect("tiff");
    rgb.save(&jpeg).expect("jpeg");
    let photo = |p: &Path| {
        sfs_core::io::read_photo(p, sfs_core::io::SrgbMode::Auto)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    let mask = |p: &Path| {
        sfs_core::io::read_mask(p)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    for (k, (file, name)) in [
        (&png16, "image16.png"),
        (&png8, "image8.png"),
        (&tiff, "image.tif"),
        (&jpeg, "image.jpg"),
    ]
    .into_iter()
    .enumerate()
    {
        let bytes = std::fs::read(file).expect("read");
        mutate_and_load(&bytes, name, 60, 100 + k as u64, photo);
        mutate_and_load(&bytes, &format!("mask-{name}"), 30, 200 + k as u64, mask);
    }
    let bytes = std::fs::read(&npy).expect("read");
    mutate_and_load(&bytes, "depth.npy", 90, 300, |p| {
        sfs_core::io::read_npy(p)
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
}

#[test]
fn mutated_camera_files_and_meshes_are_refused_by_name() {
    let camera = br#"{
  "width": 256, "height": 256, "focal": 256.0, "cx": 127.5, "cy": 127.5,
  "intensity_scale": 2.0, "units": "mm",
  "lights": [{"position": [10.0, 0.0, 0.0], "mu": 1.0, "intensity": 1.0}]
}
"#;
    mutate_and_load(camera, "scene.json", 150, 400, |p| {
        sfs_core::camera_file::read_camera(p)
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
    let obj = b"# a tetrahedron\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nf 1 2 3\nf 1 2 4\nf 1//1 3//1 4//1\nf 2 3 4\n";
    mutate_and_load(obj, "mesh.obj", 150, 500, |p| {
        sfs_core::scene::mesh::load_obj(p)
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
}
