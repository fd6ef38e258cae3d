//! Tests of the photo pipeline.

use super::*;
use crate::io::{write_mask_png, write_png16};
use tempfile::tempdir;

fn ramp(w: usize, h: usize) -> Grid<f64> {
    Grid::from_fn(w, h, |c, r| 0.1 + 0.8 * (c + w * r) as f64 / (w * h) as f64)
}

/// `image` written as `photo.png` (16 bits) in `dir`: its path.
fn photo_png(dir: &tempfile::TempDir, image: &Grid<f64>) -> std::path::PathBuf {
    let path = dir.path().join("photo.png");
    write_png16(&path, image).unwrap();
    path
}

#[test]
fn masks_are_read_at_the_photographs_size_or_the_working_size() {
    let dir = tempdir().unwrap();
    let full = dir.path().join("full.png");
    let small = dir.path().join("small.png");
    let odd = dir.path().join("odd.png");
    write_mask_png(&full, &Grid::from_fn(8, 4, |c, _| c < 4)).unwrap();
    write_mask_png(&small, &Grid::from_fn(4, 2, |c, _| c < 2)).unwrap();
    write_mask_png(&odd, &Grid::filled(5, 5, true)).unwrap();
    let a = read_mask_at(&full, "mask", (8, 4), (4, 2)).unwrap();
    let b = read_mask_at(&small, "mask", (8, 4), (4, 2)).unwrap();
    assert_eq!(a, b);
    let e = read_mask_at(&odd, "confidence", (8, 4), (4, 2))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("odd.png") && e.contains("confidence") && e.contains("5x5"),
        "{e}"
    );
}

#[test]
fn a_confidence_averaged_to_the_working_size_stays_in_0_1() {
    // 1296 -> 600 columns: weights of 2.16 pixels whose sum rounds above
    // 1 (a painted disc on the face photograph was refused for it).
    let dir = tempdir().unwrap();
    let full = dir.path().join("confidence.png");
    write_mask_png(&full, &Grid::from_fn(1296, 8, |c, _| c % 7 != 0)).unwrap();
    let read = read_mask_at(&full, "confidence", (1296, 8), (600, 4)).unwrap();
    assert!(read.as_slice().iter().all(|v| (0.0..=1.0).contains(v)));
    assert!(read.as_slice().iter().any(|&v| v == 1.0 || v > 0.8));
}

#[test]
fn a_photograph_with_a_focal_length_becomes_the_problem_it_says() {
    let dir = tempdir().unwrap();
    let image = photo_png(&dir, &ramp(40, 30));
    let mask = dir.path().join("mask.png");
    write_mask_png(&mask, &Grid::from_fn(40, 30, |c, _| c >= 10)).unwrap();
    let input = PhotoInput {
        camera: CameraSpec::Focal {
            focal_px: 50.0,
            cx_px: None,
            cy_px: Some(14.0),
        },
        object_mask: Some(mask.clone()),
        max_side: Some(20),
        ..PhotoInput::new(&image)
    };
    let prepared = prepare(&input).unwrap();
    assert_eq!(prepared.size(), (20, 15));
    assert_eq!(prepared.full_size(), (40, 30));
    let camera = prepared.problem.camera;
    assert!((camera.focal_px - 25.0).abs() < 1e-12);
    assert!((camera.principal_x_px - 9.5).abs() < 1e-12);
    assert!((camera.principal_y_px - 6.75).abs() < 1e-12);
    assert!(prepared.problem.lights.is_empty());
    assert!(!prepared.intensity_scale_given);
    let object = prepared.problem.object_mask.as_ref().unwrap();
    assert!(!*object.at(4, 7) && *object.at(5, 7));
    assert!(prepared.report.notes.iter().any(|n| n.contains("20x15")));
    assert_eq!(input.files(), vec![image.as_path(), mask.as_path()]);
}

#[test]
fn no_camera_is_an_error_unless_a_guess_is_allowed() {
    let dir = tempdir().unwrap();
    let image = photo_png(&dir, &ramp(36, 24));
    let e = prepare(&PhotoInput::new(&image)).unwrap_err().to_string();
    assert!(e.contains("no camera"), "{e}");
    let guessed = prepare(&PhotoInput {
        camera: CameraSpec::Exif { guess: true },
        ..PhotoInput::new(&image)
    })
    .unwrap();
    assert_eq!(guessed.report.camera.source, CameraSource::Guess);
    assert!((guessed.problem.camera.focal_px - 50.0).abs() < 1e-12);
    assert!(guessed.report.notes.iter().any(|n| n.contains("guess")));
}

/// `image` prepared with a focal length of 20 px and `albedo` divided out.
fn prepared_with_albedo(image: &Path, albedo: PathBuf) -> PreparedPhoto {
    prepare(&PhotoInput {
        camera: CameraSpec::Focal {
            focal_px: 20.0,
            cx_px: None,
            cy_px: None,
        },
        albedo: Some(albedo),
        ..PhotoInput::new(image)
    })
    .unwrap()
}

#[test]
fn an_albedo_map_is_judged_on_the_photograph_as_taken() {
    // A bright photograph of a surface whose albedo map reads 0.5
    // (a relative map): divided out, every value passes the top of the
    // range, yet only the one pixel saturated as taken is.
    let dir = tempdir().unwrap();
    let taken = Grid::from_fn(10, 10, |c, r| if (c, r) == (3, 4) { 1.0 } else { 0.9 });
    let image = photo_png(&dir, &taken);
    let albedo = dir.path().join("albedo.png");
    write_png16(&albedo, &Grid::filled(10, 10, 0.5)).unwrap();
    let prepared = prepared_with_albedo(&image, albedo);
    // Divided by 2 (exact), the light's intensity with it.
    assert_eq!(prepared.report.sum_divisor, Some(2.0));
    assert!((*prepared.problem.image.at(0, 0) - 0.9).abs() < 1e-4);
    let intensity: f64 = prepared.problem.lights.iter().map(|l| l.intensity).sum();
    assert_eq!(intensity, 0.5);
    assert!(prepared.report.notes.iter().any(|n| n.contains("as taken")));
    // Only the pixel saturated in the photograph is left out.
    let confidence = prepared.problem.confidence.as_ref().unwrap();
    let left_out: Vec<(usize, usize)> = (0..10)
        .flat_map(|r| (0..10).map(move |c| (c, r)))
        .filter(|&(c, r)| *confidence.at(c, r) == 0.0)
        .collect();
    assert_eq!(left_out, vec![(3, 4)]);
    assert!((prepared.report.clipped_share.unwrap() - 0.01).abs() < 1e-12);
}

/// `--albedo out/albedo.npy` (the tool's own output) was "not an
/// image": a `.npy` map is read as its values.
#[test]
fn an_albedo_npy_map_is_divided_out_like_an_image() {
    let dir = tempdir().unwrap();
    let image = photo_png(&dir, &Grid::filled(10, 10, 0.4));
    let albedo = dir.path().join("albedo.npy");
    let map = Grid::from_fn(10, 10, |c, _| if c < 5 { f64::NAN } else { 0.5 });
    crate::io::write_npy_f32(&albedo, &map).unwrap();
    let prepared = prepared_with_albedo(&image, albedo);
    assert!((*prepared.problem.image.at(9, 0) - 0.8).abs() < 1e-4);
    // NaN (the background of a solve's albedo.npy) is not trusted.
    assert!((prepared.report.albedo_untrusted_share - 0.5).abs() < 1e-12);
}

/// Writes `image` as a grey 32-bit float TIFF.
fn write_float_tiff(path: &Path, image: &Grid<f64>) {
    use tiff::encoder::{TiffEncoder, colortype};
    let values: Vec<f32> = image.as_slice().iter().map(|&v| v as f32).collect();
    let mut encoder = TiffEncoder::new(std::fs::File::create(path).unwrap()).unwrap();
    encoder
        .write_image::<colortype::Gray32Float>(image.width() as u32, image.height() as u32, &values)
        .unwrap();
}

/// A float image has no fixed white: the Sombrero at 3x ("saturated")
/// and at 0.001x ("too dark", "near-black") solves to the depth of 1x,
/// with the intensity scale found from the object's distance, and
/// without a saturation or darkness warning (issue 48 item 11).
#[test]
fn h5_a_float_photograph_solves_alike_at_any_exposure() {
    use crate::photograph_solve::PhotographSolve;
    use crate::solver::Method;
    let dir = tempdir().unwrap();
    let scene = crate::scene::sombrero::sombrero(48, 48);
    let distance = 1.5 * crate::solver::calibrate::median_depth(&scene.depth_gt);
    let solve = |exposure: f64| {
        let path = dir.path().join(format!("sombrero-{exposure}.tif"));
        write_float_tiff(&path, &scene.image.map(|v| v * exposure));
        let prepared = prepare(&PhotoInput {
            camera: CameraSpec::Focal {
                focal_px: scene.camera.focal_px,
                cx_px: Some(scene.camera.principal_x_px),
                cy_px: Some(scene.camera.principal_y_px),
            },
            ..PhotoInput::new(&path)
        })
        .unwrap();
        let mut job = PhotographSolve::of_prepared(
            &prepared,
            crate::params::SolverParams::default(),
            Method::Linearised,
        );
        job.distance = Some(distance);
        assert_eq!(job.refusal(), None, "{exposure}x");
        let solved = job.run(&mut ()).unwrap();
        (prepared, solved)
    };
    let (_, one) = solve(1.0);
    for exposure in [3.0, 0.001] {
        let (prepared, solved) = solve(exposure);
        // Scaled by a power of two into [1/2, 1), said in the report.
        let scale = prepared.report.float_scale.unwrap();
        assert_eq!(scale.log2().fract(), 0.0, "{scale}");
        let top = prepared
            .problem
            .image
            .as_slice()
            .iter()
            .fold(0.0, |a: f64, &b| a.max(b));
        assert!((0.5..1.0).contains(&top), "{exposure}x: brightest {top}");
        assert!(
            prepared
                .report
                .notes
                .iter()
                .any(|n| n.contains("float samples")),
            "{:?}",
            prepared.report.notes
        );
        for warning in &solved.warnings {
            assert!(
                !warning.contains("saturated")
                    && !warning.contains("dark")
                    && !warning.contains("near-black"),
                "{exposure}x: {warning}"
            );
        }
        assert_eq!(solved.fit.saturated_share, 0.0, "{exposure}x");
        assert_eq!(solved.fit.near_black_share, 0.0, "{exposure}x");
        for (a, b) in solved
            .solution
            .depth
            .as_slice()
            .iter()
            .zip(one.solution.depth.as_slice())
            .filter(|(a, _)| a.is_finite())
        {
            // The 32-bit floats' rounding (3e-7 measured).
            assert!((a / b - 1.0).abs() < 2e-6, "{exposure}x: depth {a} vs {b}");
        }
    }
}

/// Negative float pixels (noise below a dark frame) are read as 0 and
/// said, with their share; an ambient frame of another kind than the
/// photograph (integer beside float) is refused, naming it.
#[test]
fn h5_negative_float_pixels_are_read_as_zero_and_said() {
    let dir = tempdir().unwrap();
    let path = dir.path().join("dark-subtracted.tif");
    let image = Grid::from_fn(20, 10, |c, r| {
        if c < 5 && r < 2 {
            -0.01
        } else {
            0.2 + 0.01 * c as f64
        }
    });
    write_float_tiff(&path, &image);
    let input = PhotoInput {
        camera: CameraSpec::Focal {
            focal_px: 20.0,
            cx_px: None,
            cy_px: None,
        },
        ..PhotoInput::new(&path)
    };
    let prepared = prepare(&input).unwrap();
    let note = prepared
        .report
        .notes
        .iter()
        .find(|n| n.contains("negative"))
        .unwrap_or_else(|| panic!("{:?}", prepared.report.notes));
    assert!(
        note.contains("dark-subtracted.tif")
            && note.contains("5.00 %")
            && note.contains("10 pixels"),
        "{note}"
    );
    assert_eq!(*prepared.problem.image.at(0, 0), 0.0);
    // 0.39 -> 0.78: scaled by 2, the light with it.
    assert_eq!(prepared.report.float_scale, Some(2.0));
    assert_eq!(prepared.problem.lights.len(), 1);
    assert_eq!(prepared.problem.lights[0].intensity, 2.0);

    let ambient = dir.path().join("ambient.png");
    write_png16(&ambient, &Grid::filled(20, 10, 0.01)).unwrap();
    let e = prepare(&PhotoInput {
        ambient: Some(ambient),
        ..input
    })
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("ambient.png") && e.contains("integer samples"),
        "{e}"
    );
}

#[test]
fn h5_powers_of_two_put_a_value_in_half_one() {
    for value in [1e-30, 0.001, 0.25, 0.5, 0.75, 1.0, 3.0, 1024.0, 1e30] {
        let scale = power_of_two_into_half_one(value);
        assert_eq!(scale.log2().fract(), 0.0, "{value}");
        assert!((0.5..1.0).contains(&(value * scale)), "{value}: {scale}");
    }
    assert_eq!(power_of_two_into_half_one(0.0), 1.0);
    assert_eq!(power_of_two_into_half_one(f64::INFINITY), 1.0);
}

#[test]
fn an_albedo_below_the_floor_is_not_trusted_and_reported() {
    let dir = tempdir().unwrap();
    let image = photo_png(&dir, &ramp(10, 10));
    let albedo = dir.path().join("albedo.png");
    write_png16(
        &albedo,
        &Grid::from_fn(10, 10, |c, _| if c < 5 { 0.0 } else { 0.5 }),
    )
    .unwrap();
    let prepared = prepared_with_albedo(&image, albedo);
    assert!((prepared.report.albedo_untrusted_share - 0.5).abs() < 1e-12);
    let confidence = prepared.problem.confidence.as_ref().unwrap();
    assert_eq!((*confidence.at(0, 0), *confidence.at(9, 0)), (0.0, 1.0));
    assert!(prepared.confidence_derived);
}

/// A job solved once (`run_once`, the command line's: the image moves into
/// the solve instead of being copied) gives what `run` gives, known
/// distances included: their working pixels are read while the job still
/// holds its image (issue 50's memory work).
#[test]
fn h11_a_job_run_once_solves_as_run_does() {
    use crate::photograph_solve::{KnownDistance, PhotographSolve};
    use crate::solver::Method;
    let dir = tempdir().unwrap();
    let scene = crate::scene::sombrero::sombrero(40, 40);
    let image = dir.path().join("sombrero.png");
    let mask = dir.path().join("mask.png");
    write_png16(&image, &scene.image).unwrap();
    write_mask_png(&mask, &scene.object_mask).unwrap();
    let prepared = prepare(&PhotoInput {
        camera: CameraSpec::Focal {
            focal_px: scene.camera.focal_px,
            cx_px: Some(scene.camera.principal_x_px),
            cy_px: Some(scene.camera.principal_y_px),
        },
        object_mask: Some(mask),
        ..PhotoInput::new(&image)
    })
    .unwrap();
    let job = |prepared: PreparedPhoto| {
        let mut job = PhotographSolve::from_prepared(
            prepared,
            crate::params::SolverParams::default(),
            Method::Linearised,
        );
        job.known_distances = vec![KnownDistance {
            column_px: 20.0,
            row_px: 20.0,
            depth: 1.5 * *scene.depth_gt.at(20, 20),
        }];
        job
    };
    let by_run = job(prepared.clone()).run(&mut ()).unwrap();
    let once = job(prepared).run_once(&mut ()).unwrap();
    let bits = |g: &Grid<f64>| g.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&once.solution.depth), bits(&by_run.solution.depth));
    assert_eq!(once.problem.image, by_run.problem.image);
    assert_eq!(
        once.problem.intensity_scale.to_bits(),
        by_run.problem.intensity_scale.to_bits()
    );
    assert_eq!(once.warnings, by_run.warnings);
    assert_eq!(once.unused_options, by_run.unused_options);
    let unit = |u: &Option<crate::solver::depth_unit::DepthUnit>| serde_json::to_string(u).unwrap();
    assert_eq!(unit(&once.depth_unit), unit(&by_run.depth_unit));
}
