//! What the image cannot tell: analytic surfaces with holes of confidence 0
//! come back within the bound the holes bench uses, against the harmonic
//! fill of the true depth across the same hole (a plain smooth
//! continuation): `RSE with the hole <= 1.2 sqrt(RSE without^2 + RSE of the
//! fill^2)`. The known misses are here too, ignored with their reasons.

use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::light::LightModel;
use sfs_core::metrics;
use sfs_core::model::{LevelGeometry, Reflectance};
use sfs_core::params::{LinearSolver, SolverParams};
use sfs_core::scene::{self, Scene, sombrero::sombrero};
use sfs_core::solver::{Problem, Solution, solve};

const SIZE: usize = 128;

/// An exact image of the surface `depth(x_px, y_px) -> (z, dz/dx, dz/dy)`
/// (image-plane pixels from the principal point), lit from the optical
/// centre with `s = 1`, on the pixels where `on_object` holds.
fn analytic(
    name: &str,
    depth: impl Fn(f64, f64) -> (f64, f64, f64),
    on_object: impl Fn(f64, f64) -> bool,
) -> Scene {
    let camera = Intrinsics::centred(SIZE as f64, SIZE, SIZE);
    let pixels = LevelGeometry::new(SIZE, SIZE, SIZE, SIZE, camera);
    let model = LightModel::new(1.0, &[]);
    let mut depth_gt = Grid::filled(SIZE, SIZE, f64::NAN);
    let mut object_mask = Grid::filled(SIZE, SIZE, false);
    let image = Grid::from_fn(SIZE, SIZE, |c, r| {
        let ray = pixels.ray(c, r);
        if !on_object(ray.x_px, ray.y_px) {
            return 0.0;
        }
        let (z, zx, zy) = depth(ray.x_px, ray.y_px);
        *depth_gt.at_mut(c, r) = z;
        *object_mask.at_mut(c, r) = true;
        model.radiance(&ray, z, zx, zy)
    });
    // Exposed so that the brightest pixel is 0.9, as scenes are rendered.
    let brightest = image.as_slice().iter().copied().fold(0.0, f64::max);
    let k = 0.9 / brightest;
    Scene {
        name: name.into(),
        camera,
        intensity_scale: k,
        image: image.map(|v| v * k),
        depth_gt,
        object_mask,
        normals: None,
        lights: Vec::new(),
        material: Default::default(),
    }
}

fn plane() -> Scene {
    analytic(
        "plane",
        |x, y| (2.0 + 0.003 * x + 0.002 * y, 0.003, 0.002),
        |_, _| true,
    )
}

/// A dome: the cap of an ellipsoid of revolution, 0.8 deep, 90 px wide.
fn dome() -> Scene {
    const RADIUS_PX: f64 = 90.0;
    analytic(
        "dome",
        |x, y| {
            let root = (1.0 - (x * x + y * y) / (RADIUS_PX * RADIUS_PX)).sqrt();
            let slope = 0.8 / (RADIUS_PX * RADIUS_PX * root);
            (2.6 - 0.8 * root, slope * x, slope * y)
        },
        |x, y| x.hypot(y) < 0.85 * RADIUS_PX,
    )
}

fn solve_with(scene: &Scene, confidence: Option<Grid<f64>>, params: &SolverParams) -> Solution {
    let problem = Problem {
        image: scene.image.clone(),
        camera: scene.camera,
        intensity_scale: scene.intensity_scale,
        object_mask: Some(scene.object_mask.clone()),
        confidence,
        lights: Vec::new(),
    };
    solve(&problem, params, &mut ()).expect("an exact image solves")
}

/// `(RSE with the hole, the bound)`.
fn with_and_bound(scene: &Scene, hole: &Grid<f64>) -> (f64, f64) {
    let params = SolverParams::default();
    let rse =
        |solution: &Solution| metrics::rse(&solution.depth, &scene.depth_gt).expect("same size");
    let without = rse(&solve_with(scene, None, &params));
    let with = rse(&solve_with(scene, Some(hole.clone()), &params));
    let known = hole.map(|&c| c > 0.5);
    let fill = metrics::rse(
        &scene::harmonic_fill(&scene.depth_gt, &known),
        &scene.depth_gt,
    )
    .expect("same size");
    (with, 1.2 * without.hypot(fill))
}

fn disc() -> Grid<f64> {
    scene::disc_confidence(SIZE, SIZE, 0.5, 0.45, 0.14)
}

fn band() -> Grid<f64> {
    scene::band_confidence(SIZE, SIZE, 0.45, 0.1)
}

#[test]
fn a_plane_and_a_dome_with_a_band_missing_come_back_as_well_as_their_fill() {
    // The refinement across holes runs multigrid and kappa-holes
    // iterations: with the SOR sweeps and kappa of a start without holes
    // the plane came back at 0.0013 (bound 0.0007) and the dome at 0.0039
    // (bound 0.0024), a smooth error left on the trusted pixels.
    for scene in [plane(), dome()] {
        let (with, bound) = with_and_bound(&scene, &band());
        assert!(with <= bound, "{}: RSE {with} above {bound}", scene.name);
    }
}

#[test]
#[ignore = "known miss (issue 21): the dome's hidden top comes back 0.060 beyond the truth's range over the hole (a dent), the plane 0.018"]
fn a_disc_hiding_the_point_that_faces_the_light_is_filled_without_spikes() {
    // The disc hides the plane's foot point and the dome's top: fast
    // marching has no point facing the light there (the bench's misses are
    // of this kind, see docs/holes-and-shadows.md). The fill still stays within the depths
    // the truth spans over the hole: no spike, no cliff, no drift. Every
    // scene's worst excursion is reported together.
    let mut misses = Vec::new();
    for scene in [plane(), dome()] {
        let hole = disc();
        let solution = solve_with(&scene, Some(hole.clone()), &SolverParams::default());
        let inside: Vec<(f64, f64)> = solution
            .depth
            .as_slice()
            .iter()
            .zip(scene.depth_gt.as_slice())
            .zip(hole.as_slice())
            .filter(|((_, t), c)| t.is_finite() && **c < 0.5)
            .map(|((z, t), _)| (*z, *t))
            .collect();
        assert!(
            inside.len() > 500,
            "{}: the disc is on the object",
            scene.name
        );
        let low = inside.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let high = inside.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
        assert!(
            inside.iter().all(|p| p.0.is_finite()),
            "{}: a depth in the hole is not finite",
            scene.name
        );
        let beyond = inside
            .iter()
            .map(|&(z, _)| (low - z).max(z - high))
            .fold(0.0, f64::max);
        if beyond > 0.0 {
            misses.push(format!(
                "{}: a depth {beyond:.4} outside the truth's {low:.4}..{high:.4} over the hole",
                scene.name
            ));
        }
    }
    assert!(misses.is_empty(), "{}", misses.join("; "));
}

#[test]
fn the_sombrero_with_a_band_missing_comes_back_as_well_as_its_fill() {
    let scene = sombrero(SIZE, SIZE);
    let (with, bound) = with_and_bound(&scene, &band());
    assert!(with <= bound, "RSE {with} above {bound}");
}

#[test]
#[ignore = "known miss (issue 21): the disc hides the plane's foot point, the only point facing the light; RSE 0.0018 against a bound of 0.0006"]
fn a_plane_with_its_foot_point_missing_comes_back_as_well_as_its_fill() {
    let (with, bound) = with_and_bound(&plane(), &disc());
    assert!(with <= bound, "RSE {with} above {bound}");
}

#[test]
#[ignore = "known miss (issue 21): the disc hides the Sombrero's peak, the only point of the central region facing the light; every start recovers a bowl there (RSE 0.097 at 256x256)"]
fn the_sombrero_with_its_peak_missing_comes_back_as_well_as_its_fill() {
    let scene = sombrero(SIZE, SIZE);
    let (with, bound) = with_and_bound(&scene, &disc());
    assert!(with <= bound, "RSE {with} above {bound}");
}

/// The defaults' depth and the depth with the schedule of a problem
/// without holes (SOR, `kappa` iterations) on the same problem.
fn defaults_and_plain_schedule(
    scene: &Scene,
    image: Grid<f64>,
    hole: Grid<f64>,
) -> (Grid<f64>, Grid<f64>) {
    let problem = Problem {
        image,
        camera: scene.camera,
        intensity_scale: scene.intensity_scale,
        object_mask: Some(scene.object_mask.clone()),
        confidence: Some(hole),
        lights: Vec::new(),
    };
    let defaults = SolverParams::default();
    let plain = SolverParams {
        linear_solver: LinearSolver::Sor,
        kappa_holes: defaults.kappa,
        ..SolverParams::default()
    };
    let solved = |params: &SolverParams| solve(&problem, params, &mut ()).expect("solves").depth;
    (solved(&defaults), solved(&plain))
}

#[test]
fn only_a_wide_hole_in_a_clean_image_gets_the_schedule_for_holes() {
    let scene = sombrero(SIZE, SIZE);
    // Specks: single untrusted pixels (as clipped pixels of a noisy
    // image are) are no holes: the solve is the one without holes.
    let specks = Grid::from_fn(SIZE, SIZE, |c, r| match (c % 9 == 4) && (r % 9 == 4) {
        true => 0.0,
        false => 1.0,
    });
    let (defaults, plain) = defaults_and_plain_schedule(&scene, scene.image.clone(), specks);
    assert_eq!(defaults, plain, "specks took the schedule for holes");
    // A band is a hole: multigrid and kappa-holes iterations run.
    let (defaults, plain) = defaults_and_plain_schedule(&scene, scene.image.clone(), band());
    assert_ne!(
        defaults, plain,
        "a band did not take the schedule for holes"
    );
    // In noise the schedule is the one without holes, band or not.
    let noisy = scene::add_noise(&scene.image, 20.0, 1);
    let (defaults, plain) = defaults_and_plain_schedule(&scene, noisy, band());
    assert_eq!(defaults, plain, "a noisy image took the schedule for holes");
}
