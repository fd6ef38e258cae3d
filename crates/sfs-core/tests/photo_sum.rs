//! Several photographs summed by the photo pipeline: the sum is saturated
//! only where one of the photographs was (measured on each one's decoded
//! values, resampled to the working size as "any source pixel"), not where
//! the sum passes 1; the solver and the model-fit summary follow that
//! record; each photograph with a light of its own is kept for the fit per
//! photograph. One photograph is read as before.

use std::path::{Path, PathBuf};

use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::io::{write_json, write_png16};
use sfs_core::light::{LightModel, PointLight};
use sfs_core::model::{self, LevelGeometry};
use sfs_core::model_fit;
use sfs_core::params::SolverParams;
use sfs_core::photo::{self, CameraSpec, PhotoInput, PreparedPhoto, ScaleSpec};
use sfs_core::scene::sombrero::sombrero_lit;
use sfs_core::solver::{self, Problem, SolveError};

const SIZE: usize = 48;

/// The three lights, just beside the lens (left, right, above), at the
/// Sombrero's distance of about 2.
fn lights() -> [PointLight; 3] {
    [[0.1, 0.0], [-0.1, 0.0], [0.0, -0.1]].map(|[x, y]| PointLight {
        position: [x, y, 0.0],
        ..PointLight::CENTRED
    })
}

/// The Sombrero under each light alone with one intensity scale, chosen so
/// that each photograph's brightest pixel is `brightest`; and that scale.
fn photographs(brightest: f64) -> ([Grid<f64>; 3], f64) {
    let scenes = lights().map(|light| sombrero_lit(SIZE, SIZE, &[light]));
    // sombrero_lit renders each with its brightest pixel at 0.9.
    let s = scenes
        .iter()
        .map(|scene| scene.intensity_scale)
        .fold(f64::INFINITY, f64::min)
        * brightest
        / 0.9;
    let images = scenes
        .each_ref()
        .map(|scene| scene.image.map(|v| v * s / scene.intensity_scale));
    (images, s)
}

/// Writes `images` as `a.png`, `b.png`, `c.png` (16-bit, linear) and a
/// camera file whose lights name them; returns the photographs' paths and
/// the file.
fn write_set(dir: &Path, images: &[Grid<f64>; 3]) -> (Vec<PathBuf>, PathBuf) {
    let names = ["a.png", "b.png", "c.png"];
    let paths: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    for (path, image) in paths.iter().zip(images) {
        write_png16(path, image).expect("the photograph is written");
    }
    let lights: Vec<serde_json::Value> = lights()
        .iter()
        .zip(names)
        .map(|(light, name)| {
            serde_json::json!({"position": light.position, "intensity": 1.0, "image": name})
        })
        .collect();
    let camera = dir.join("camera.json");
    let half = (SIZE as f64 - 1.0) / 2.0;
    write_json(
        &camera,
        &serde_json::json!({
            "width": SIZE, "height": SIZE, "focal": SIZE as f64, "cx": half, "cy": half,
            "lights": lights
        }),
    )
    .expect("the camera file is written");
    (paths, camera)
}

fn input(paths: Vec<PathBuf>, camera: &Path, s: f64) -> PhotoInput {
    PhotoInput {
        images: paths.clone(),
        camera: CameraSpec::File(camera.to_path_buf()),
        intensity_scale: ScaleSpec::Given(s),
        ..PhotoInput::new(&paths[0])
    }
}

fn object_values(prepared: &PreparedPhoto) -> impl Iterator<Item = f64> + '_ {
    prepared.problem.image.as_slice().iter().copied()
}

/// Three photographs each below 1 whose sum passes 1 on most of the
/// object: nothing is saturated, nothing untrusted; the solver gets the sum
/// divided by 4 with the lights' intensities alike and solves it (the sum
/// as it was, read as clipped where it passes 1, is refused); each
/// photograph is kept with its own light for the fit per photograph.
#[test]
fn a_sum_above_1_of_photographs_below_1_is_not_saturated() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (images, s) = photographs(0.95);
    let sum = images[0]
        .zip_map(&images[1], |a, b| a + b)
        .zip_map(&images[2], |a, b| a + b);
    let above = sum.as_slice().iter().filter(|&&v| v >= 1.0).count();
    assert!(above * 2 > sum.len(), "most of the sum passes 1 ({above})");
    let (paths, camera) = write_set(dir.path(), &images);
    let prepared = photo::prepare(&input(paths.clone(), &camera, s)).expect("the pair is read");

    let clipped = prepared
        .clipped
        .as_ref()
        .expect("a sum records its clipping");
    assert!(clipped.as_slice().iter().all(|&c| !c));
    assert_eq!(prepared.report.clipped_share, Some(0.0));
    assert!(prepared.problem.confidence.is_none(), "nothing untrusted");
    assert!(!prepared.confidence_derived);
    assert_eq!(prepared.report.sum_divisor, Some(4.0));
    assert!(object_values(&prepared).all(|v| v < 1.0));
    for light in &prepared.problem.lights {
        assert_eq!(light.intensity, 0.25);
    }
    // The problem's image is the sum as read, divided (16-bit quantisation).
    let worst = prepared
        .problem
        .image
        .as_slice()
        .iter()
        .zip(sum.as_slice())
        .map(|(p, s)| (4.0 * p - s).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-4, "sum off by {worst}");

    // The fit summary: nothing saturated, where the sum's own values say
    // most of it is.
    let domain = Grid::filled(SIZE, SIZE, true);
    let image = &prepared.problem.image;
    let fit =
        model_fit::measure_photographs(image, image, &domain, None, 0.5, prepared.photographs());
    assert_eq!(fit.saturated_share, 0.0);
    assert!(fit.warnings.is_empty(), "{:?}", fit.warnings);
    let by_value = model_fit::measure(&sum, &sum, &domain, None, 1.0);
    assert!(by_value.saturated_share > 0.5, "{by_value:?}");
    // Neither a highlight in the suggested confidence.
    let (_, counts) =
        model_fit::suggest_confidence_photographs(image, &domain, None, prepared.photographs());
    assert_eq!(counts.saturated, 0);

    // The solver takes the sum for what it is; read by its value it would
    // have been clipped on most of the object and refused.
    let as_clipped = Problem {
        image: sum,
        lights: lights().to_vec(),
        ..prepared.problem.clone()
    };
    let refused = solver::solve(&as_clipped, &SolverParams::default(), &mut ());
    assert!(
        matches!(&refused, Err(SolveError::Input(m)) if m.contains("saturated")),
        "{refused:?}"
    );
    let solution = solver::solve(&prepared.problem, &SolverParams::default(), &mut ())
        .expect("the sum solves");

    // Each photograph with its own light, on its own scale.
    assert_eq!(prepared.photos.len(), 3);
    for (k, each) in prepared.photos.iter().enumerate() {
        assert_eq!(each.path, paths[k]);
        assert_eq!(each.light_index, k);
        assert_eq!(each.light.intensity, 1.0);
        let worst = each
            .image
            .as_slice()
            .iter()
            .zip(images[k].as_slice())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "photograph {k} off by {worst}");
    }
    let fits = photo::fit_per_photo(
        &prepared.photos,
        &solution,
        prepared.problem.camera,
        prepared.problem.intensity_scale,
        prepared.problem.confidence.as_ref(),
        4.0,
    );
    assert_eq!(fits.len(), 3);
    for (k, fit) in fits.iter().enumerate() {
        assert_eq!(fit.image, paths[k]);
        assert!(fit.fit.rie_trusted < 0.15, "photograph {k}: {:?}", fit.fit);
        assert_eq!(fit.fit.saturated_share, 0.0);
    }
    // On the photographs' own scale: their reprojections, each under its
    // own light, add up to the sum's (the solver's, times the divisor).
    let domain = solution.depth.map(|z| z.is_finite());
    let geometry = LevelGeometry::new(SIZE, SIZE, SIZE, SIZE, prepared.problem.camera);
    let mut added = Grid::filled(SIZE, SIZE, 0.0);
    for each in &prepared.photos {
        let model = LightModel::new(prepared.problem.intensity_scale, &[each.light]);
        let one = model::reproject(&model, &geometry, &domain, &solution.depth, Cancel::NEVER)
            .uncancelled();
        added = added.zip_map(&one, |a, b| a + b);
    }
    let worst = added
        .as_slice()
        .iter()
        .zip(solution.reprojection.as_slice())
        .map(|(a, r)| (a - 4.0 * r).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-9,
        "the reprojections add up to the sum's, off by {worst}"
    );
}

/// A pixel clipped in one photograph is saturated in the sum (confidence 0,
/// counted by the fit summary), whatever the sum's value there; the rest
/// is trusted.
#[test]
fn a_pixel_clipped_in_one_photograph_is_saturated_in_the_sum() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (mut images, s) = photographs(0.3);
    *images[1].at_mut(30, 12) = 1.0;
    let (paths, camera) = write_set(dir.path(), &images);
    let prepared = photo::prepare(&input(paths, &camera, s)).expect("the pair is read");
    let clipped = prepared
        .clipped
        .as_ref()
        .expect("a sum records its clipping");
    let marked: Vec<(usize, usize)> = (0..SIZE * SIZE)
        .filter(|&q| clipped.as_slice()[q])
        .map(|q| (q % SIZE, q / SIZE))
        .collect();
    assert_eq!(marked, vec![(30, 12)]);
    let confidence = prepared.problem.confidence.as_ref().expect("untrusted");
    assert_eq!(*confidence.at(30, 12), 0.0);
    assert_eq!(
        confidence.as_slice().iter().filter(|&&c| c == 1.0).count(),
        SIZE * SIZE - 1
    );
    assert!(prepared.confidence_derived);
    assert_eq!(
        prepared.report.sum_divisor,
        Some(1.0),
        "the sum stays below 1"
    );
    let share = 1.0 / (SIZE * SIZE) as f64;
    assert_eq!(prepared.report.clipped_share, Some(share));
    let domain = Grid::filled(SIZE, SIZE, true);
    let image = &prepared.problem.image;
    let fit =
        model_fit::measure_photographs(image, image, &domain, None, 0.5, prepared.photographs());
    assert_eq!(fit.saturated_share, share);
    // Only the photograph that clipped it says so on its own.
    assert!(!*prepared.photos[0].clipped.at(30, 12));
    assert!(*prepared.photos[1].clipped.at(30, 12));
}

/// At a working size, a working pixel is saturated when any of its source
/// pixels was: a clipped pixel on the boundary of two working pixels marks
/// both (in each direction).
#[test]
fn clipping_is_resampled_as_any_source_pixel() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (mut images, s) = photographs(0.3);
    // 48 -> 20 pixels: 2.4 source pixels each; source pixel 7 straddles
    // working pixels 2 ([4.8, 7.2)) and 3 ([7.2, 9.6)).
    *images[0].at_mut(7, 7) = 1.0;
    let (paths, camera) = write_set(dir.path(), &images);
    let prepared = photo::prepare(&PhotoInput {
        max_side: Some(20),
        ..input(paths, &camera, s)
    })
    .expect("the pair is read");
    assert_eq!(prepared.size(), (20, 20));
    let clipped = prepared
        .clipped
        .as_ref()
        .expect("a sum records its clipping");
    let marked: Vec<(usize, usize)> = (0..400)
        .filter(|&q| clipped.as_slice()[q])
        .map(|q| (q % 20, q / 20))
        .collect();
    assert_eq!(marked, vec![(2, 2), (3, 2), (2, 3), (3, 3)]);
    // The sum averaged there is below 1: its value would not say.
    assert!(*prepared.problem.image.at(3, 3) < 1.0);
    assert_eq!(prepared.photos[0].image.size(), (20, 20));
}

/// Photographs clipped on most of the object are refused, as one such
/// photograph is by the solver.
#[test]
fn photographs_clipped_on_most_of_the_object_are_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (images, s) = photographs(0.3);
    let clipped = [
        images[0].map(|v| (v * 30.0).min(1.0)),
        images[1].clone(),
        images[2].clone(),
    ];
    let (paths, camera) = write_set(dir.path(), &clipped);
    let error = photo::prepare(&input(paths, &camera, s))
        .expect_err("refused")
        .to_string();
    assert!(error.contains("saturated"), "{error}");
}

/// One photograph is read as before: no record of clipping (the solver
/// finds it by value), no divisor, no photograph kept apart, the image as
/// decoded.
#[test]
fn one_photograph_is_read_as_before() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (mut images, s) = photographs(0.95);
    *images[0].at_mut(5, 5) = 1.0;
    let (paths, camera) = write_set(dir.path(), &images);
    let prepared = photo::prepare(&input(vec![paths[0].clone()], &camera, s)).expect("read");
    assert!(prepared.clipped.is_none());
    assert!(prepared.photos.is_empty());
    assert_eq!(prepared.report.sum_divisor, None);
    assert_eq!(prepared.report.clipped_share, None);
    assert!(prepared.problem.confidence.is_none());
    assert_eq!(prepared.problem.lights[0].intensity, 1.0);
    let decoded = sfs_core::io::read_image(&paths[0], false).expect("read back");
    assert_eq!(prepared.problem.image, decoded);
    let json = serde_json::to_value(&prepared.report).expect("serialises");
    assert!(json.get("sum_divisor").is_none() && json.get("clipped_share").is_none());
}
