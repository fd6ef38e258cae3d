//! Lights beside the lens: the start marched in the light's frame, known
//! distances, and the honesty of the scale estimate.

mod common;

use sfs_core::light::PointLight;
use sfs_core::metrics;
use sfs_core::params::SolverParams;
use sfs_core::scene::Scene;
use sfs_core::scene::sombrero::sombrero_lit;
use sfs_core::solver::calibrate::{KnownDepth, depth_near, solve_with_known_depths};
use sfs_core::solver::{Method, Problem, solve};

/// [`common::problem`] of the scene's own image and intensity scale.
fn problem(scene: &Scene, lights: &[PointLight]) -> Problem {
    common::problem(scene, scene.image.clone(), scene.intensity_scale, lights)
}

fn flash_beside_the_lens() -> PointLight {
    PointLight {
        position: [0.5, 0.0, 0.0],
        direction: None,
        mu: 0.0,
        intensity: 1.0,
    }
}

/// An LED 1.05 in front of the camera, 0.1 above the axis (the surface
/// must stay beyond it).
fn led_before_the_camera() -> PointLight {
    PointLight {
        position: [0.0, -0.1, 1.05],
        direction: None,
        mu: 0.0,
        intensity: 1.0,
    }
}

fn rse(depth: &sfs_core::grid::Grid<f64>, scene: &Scene) -> f64 {
    metrics::rse(depth, &scene.depth_gt).expect("measurable")
}

/// A flash 0.5 beside the lens (14 degrees off the camera, seen from the
/// Sombrero) is solved nearly as well as the light at the optical centre:
/// the start is marched in the flash's own frame. Measured at 96 px: 0.0101
/// against 0.0076 centred; the plane walked up the pyramid (the start
/// before) gave 0.0247 at 256 px against 0.0020.
#[test]
fn a_flash_beside_the_lens_is_solved_nearly_as_well_as_a_centred_light() {
    let side = 96;
    let centred = sombrero_lit(side, side, &[]);
    let centred_rse = rse(
        &solve(&problem(&centred, &[]), &SolverParams::default(), &mut ())
            .expect("solves")
            .depth,
        &centred,
    );
    let lights = [flash_beside_the_lens()];
    let beside = sombrero_lit(side, side, &lights);
    let solution = solve(
        &problem(&beside, &lights),
        &SolverParams::default(),
        &mut (),
    )
    .expect("solves");
    let beside_rse = rse(&solution.depth, &beside);
    assert!(
        beside_rse <= 1.5 * centred_rse,
        "beside {beside_rse} vs centred {centred_rse}"
    );
    // A warm start refined on the full image: one level.
    assert_eq!(solution.levels.len(), 1);
}

/// One known distance (the middle pixel's) puts its point there (within
/// 0.5 %, read as the median over its window; the pixel within 1 %) and
/// gives the shape of the true scale's solve: with the light at the centre
/// exactly that solve rescaled to meet the point; beside the
/// lens (a search over `s` from `s = 1`, 2.25 below the truth) within 1.1x
/// of its RSE. (The solve's own error at the one pixel sets the depth
/// scale; docs/photographs.md.)
#[test]
fn a_known_distance_is_met_and_gives_the_true_scales_shape() {
    let side = 128;
    for lights in [vec![], vec![flash_beside_the_lens()]] {
        let scene = sombrero_lit(side, side, &lights);
        let truth = problem(&scene, &lights);
        let (c, r) = (side / 2, side / 2);
        let given = *scene.depth_gt.at(c, r);
        let true_scale = solve(&truth, &SolverParams::default(), &mut ()).expect("solves");
        // The true scale's solve rescaled to meet the point (its depth read
        // as the search reads it: the median over its window).
        let factor = given / depth_near(&true_scale.depth, c as f64, r as f64).expect("solved");
        let rescaled = true_scale.depth.map(|z| z * factor);
        let point = KnownDepth {
            column_px: c as f64,
            row_px: r as f64,
            depth: given,
        };
        let mut unknown = Problem {
            intensity_scale: 1.0,
            ..truth.clone()
        };
        let (solution, fit) = solve_with_known_depths(
            &mut unknown,
            &SolverParams::default(),
            &Method::Linearised,
            &[point],
            &mut (),
        )
        .expect("solves");
        // The point's solved depth is read over its window (the median
        // within 0.5 % of the side); the pixel itself is within 1 %.
        let at = depth_near(&solution.depth, c as f64, r as f64).expect("on the surface");
        let error = (at - given) / given;
        assert!(
            error.abs() <= 0.005,
            "{} lights: point at {at} for {given} ({error:+e})",
            lights.len()
        );
        assert!((fit.points[0].relative_residual - error).abs() < 1e-12);
        let pixel = *solution.depth.at(c, r);
        assert!(
            ((pixel - given) / given).abs() <= 0.01,
            "{} lights: pixel at {pixel} for {given}",
            lights.len()
        );
        assert!(fit.converged);
        // The rescaling with a centred light is exact: no precision to
        // measure. (Beside the lens this render's search settles in fewer
        // solves than a precision needs; the unit tests of
        // `ScalePrecision` and the shared face measure it.)
        if lights.is_empty() {
            assert_eq!(fit.scale_precision, None);
        }
        let (known_rse, rescaled_rse) = (rse(&solution.depth, &scene), rse(&rescaled, &scene));
        assert!(
            known_rse <= 1.1 * rescaled_rse,
            "{} lights: RSE {known_rse} from the known distance vs {rescaled_rse}",
            lights.len()
        );
        let s_ratio = fit.intensity_scale / scene.intensity_scale;
        assert!(
            (0.95..=1.05).contains(&s_ratio),
            "{} lights: s {s_ratio}x the truth",
            lights.len()
        );
    }
}

/// Several known distances are fitted in least squares: the residuals
/// satisfy the normal equation, and making the second of two points 10 %
/// farther moves them apart (the first's up, the second's down, about 5 %
/// each).
#[test]
fn several_known_distances_are_fitted_in_least_squares() {
    let scene = sombrero_lit(48, 48, &[]);
    let truth = problem(&scene, &[]);
    let at = |c: usize, r: usize, factor: f64| KnownDepth {
        column_px: c as f64,
        row_px: r as f64,
        depth: factor * *scene.depth_gt.at(c, r),
    };
    let params = SolverParams::default();
    let fit = |points: &[KnownDepth]| {
        let mut p = truth.clone();
        solve_with_known_depths(&mut p, &params, &Method::Linearised, points, &mut ())
            .expect("solves")
            .1
    };
    let consistent = fit(&[at(10, 10, 1.0), at(30, 24, 1.0)]);
    let conflicting = fit(&[at(10, 10, 1.0), at(30, 24, 1.1)]);
    let shift =
        |k: usize| conflicting.points[k].relative_residual - consistent.points[k].relative_residual;
    assert!(
        shift(0) > 0.03 && shift(1) < -0.03,
        "{consistent:?} {conflicting:?}"
    );
    // Least squares in relative terms: sum r (1 + r) = 0 at the optimum
    // (exact with the centred light, where the fit rescales the depth).
    for fit in [&consistent, &conflicting] {
        let normal: f64 = fit
            .points
            .iter()
            .map(|p| p.relative_residual * (1.0 + p.relative_residual))
            .sum();
        assert!(normal.abs() < 1e-9, "{fit:?}");
    }
}

/// A known distance that cannot be met is an error naming the pixel, not a
/// panic: off the object, or not a positive distance.
#[test]
fn a_bad_known_distance_is_refused_with_the_pixel_named() {
    let mut scene = sombrero_lit(32, 32, &[]);
    *scene.object_mask.at_mut(0, 0) = false;
    let params = SolverParams::default();
    for (point, says) in [
        (
            KnownDepth {
                column_px: 0.0,
                row_px: 0.0,
                depth: 2.0,
            },
            "0,0",
        ),
        (
            KnownDepth {
                column_px: 5.0,
                row_px: 6.0,
                depth: -1.0,
            },
            "positive",
        ),
        (
            KnownDepth {
                column_px: 5.0,
                row_px: 6.0,
                depth: f64::NAN,
            },
            "positive",
        ),
    ] {
        let mut p = problem(&scene, &[]);
        let error =
            solve_with_known_depths(&mut p, &params, &Method::Linearised, &[point], &mut ())
                .expect_err("refused");
        assert!(error.to_string().contains(says), "{error}");
    }
}

/// A camera file's `intensity_scale` counts as known only when the file
/// says it was measured: with a light off the centre an unmarked one is
/// treated as unknown (and a note says so); marked, it is taken; with the
/// light at the centre (where it only sets the depth unit) it is taken.
#[test]
fn a_camera_files_scale_counts_only_when_marked_measured() {
    let dir = std::env::temp_dir().join(format!("sfs-lights-measured-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let scene = sombrero_lit(16, 16, &[]);
    let image = dir.join("image.png");
    sfs_core::io::write_png16(&image, &scene.image).expect("writes");
    for (light, measured, taken) in [
        ("[0.5, 0, 0]", false, false),
        ("[0.5, 0, 0]", true, true),
        ("[0, 0, 0]", false, true),
    ] {
        let camera = dir.join("scene.json");
        std::fs::write(
            &camera,
            format!(
                r#"{{"width": 16, "height": 16, "focal": 16, "cx": 7.5, "cy": 7.5,
                    "intensity_scale": 1.0,
                    "intensity_scale_measured": {measured},
                    "lights": [{{"position": {light}}}]}}"#
            ),
        )
        .expect("writes");
        let mut input = sfs_core::photo::PhotoInput::new(&image);
        input.camera = sfs_core::photo::CameraSpec::File(camera);
        let prepared = sfs_core::photo::prepare(&input).expect("prepares");
        assert_eq!(
            prepared.intensity_scale_given, taken,
            "light {light}, measured {measured}"
        );
        let noted = prepared
            .report
            .notes
            .iter()
            .any(|n| n.contains("not marked measured"));
        assert_eq!(noted, !taken, "light {light}: {:?}", prepared.report.notes);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// An LED nearer the object than the camera (0.1 beside the axis, more
/// than half-way to a Sombrero disc 2 away, 3 degrees off the camera seen
/// from it), at the true scale. Marched in its frame, the centred march put
/// the surface as far from the camera as it is from the LED: in front of
/// it, where it could not light the side the camera sees (median depth
/// 0.86, RSE 0.57). Started from the plane up the pyramid (beyond a third of
/// the way, `light_frame::MAX_FRAME_DEPTH_SHARE`): median 2.11, RSE 0.062.
#[test]
fn an_led_in_front_of_the_camera_starts_the_surface_beyond_it() {
    let side = 96;
    let lights = [led_before_the_camera()];
    let mut scene = sombrero_lit(side, side, &lights);
    // The object a disc in the middle of the view, as a face in a portrait.
    let radius = side as f64 / 4.0;
    scene.object_mask = sfs_core::grid::Grid::from_fn(side, side, |c, r| {
        let (x, y) = (
            c as f64 + 0.5 - side as f64 / 2.0,
            r as f64 + 0.5 - side as f64 / 2.0,
        );
        x.hypot(y) <= radius
    });
    scene.depth_gt = scene
        .depth_gt
        .zip_map(&scene.object_mask, |z, on| if *on { *z } else { f64::NAN });
    let lit = problem(&scene, &lights);
    let solution = solve(&lit, &SolverParams::default(), &mut ()).expect("solves");
    let mut depths = solution.depth.finite_values();
    depths.sort_by(f64::total_cmp);
    let median = depths[depths.len() / 2];
    assert!(
        median > 1.9,
        "median depth {median}: in front of the LED at 1.05"
    );
    let solved_rse = rse(&solution.depth, &scene);
    assert!(solved_rse < 0.1, "RSE {solved_rse}");
    // The plane up the pyramid: more than one level.
    assert!(solution.levels.len() > 1);
    // The rule is the same at another exposure (image and scale x0.25).
    assert_exposure_moves_nothing(&lit, &solution.depth);
}

/// The defaults' solve of `lit` at a quarter of its exposure (image and
/// scale x0.25) gives `depth` to round-off.
fn assert_exposure_moves_nothing(lit: &Problem, depth: &sfs_core::grid::Grid<f64>) {
    let darker = Problem {
        image: lit.image.map(|v| v * 0.25),
        intensity_scale: lit.intensity_scale * 0.25,
        ..lit.clone()
    };
    let again = solve(&darker, &SolverParams::default(), &mut ()).expect("solves");
    let difference = common::largest_relative_difference(&again.depth, 1.0, depth);
    assert!(
        difference < common::ROUND_OFF,
        "exposure x0.25 moved the depth by {difference}"
    );
}

/// A known distance on an image larger than twice the working copy's
/// 256 px (the copy's search, then the full size's) meets the point
/// within 1 %, and the same input gives the same bits: nothing in
/// the search depends on timing or threads.
#[test]
fn a_known_distance_on_a_large_image_is_met_and_repeatable() {
    let side = 520;
    let lights = [flash_beside_the_lens()];
    let scene = sombrero_lit(side, side, &lights);
    let (c, r) = (side / 2, side / 3);
    let point = KnownDepth {
        column_px: c as f64,
        row_px: r as f64,
        depth: *scene.depth_gt.at(c, r),
    };
    let run = || {
        let mut unknown = Problem {
            intensity_scale: 1.0,
            ..problem(&scene, &lights)
        };
        solve_with_known_depths(
            &mut unknown,
            &SolverParams::default(),
            &Method::Linearised,
            &[point],
            &mut (),
        )
        .expect("solves")
    };
    let (first, fit) = run();
    assert!(
        fit.points[0].relative_residual.abs() < 0.01,
        "{:?}",
        fit.points
    );
    let (second, again) = run();
    let bits = |g: &sfs_core::grid::Grid<f64>| -> Vec<u64> {
        g.as_slice().iter().map(|z| z.to_bits()).collect()
    };
    assert_eq!(bits(&first.depth), bits(&second.depth));
    assert_eq!(
        fit.intensity_scale.to_bits(),
        again.intensity_scale.to_bits()
    );
}

/// Records the levels an observer is shown.
#[derive(Default)]
struct Levels(Vec<(usize, usize, (usize, usize))>);

impl sfs_core::solver::SolveObserver for Levels {
    fn on_level(&mut self, result: &sfs_core::solver::LevelResult) {
        self.0.push((
            result.level,
            result.levels,
            (result.geometry.width, result.geometry.height),
        ));
    }
}

/// Where fast marching cannot serve (an LED far in front of the camera)
/// an image more than twice `WALK_SIDE` walks the pyramid on a working
/// copy and refines its surface at full size: the observer sees the copy's
/// levels and then the full size, numbered as one solve; the report lists
/// them all; the depth is as good as the paper's walk over the whole
/// pyramid (`--init-depth from-image`) with a fraction of its inner
/// iterations' pixels; and the rule is the same at another exposure.
#[test]
fn a_large_image_the_light_far_off_walks_a_working_copy_then_refines() {
    let side = 2 * sfs_core::solver::WALK_SIDE + 28;
    let lights = [led_before_the_camera()];
    let scene = sombrero_lit(side, side, &lights);
    let lit = problem(&scene, &lights);
    let mut shown = Levels::default();
    let walked = solve(&lit, &SolverParams::default(), &mut shown).expect("solves");
    let paper = solve(
        &lit,
        &SolverParams {
            initial_depth: sfs_core::params::InitialDepth::FromImage,
            ..SolverParams::default()
        },
        &mut (),
    )
    .expect("solves");
    // The copy's levels, then the full size; one count for all.
    let count = shown.0.len();
    assert!(count > 2, "{:?}", shown.0);
    for (k, (level, levels, (w, h))) in shown.0.iter().enumerate() {
        assert_eq!((*level, *levels), (k, count), "{:?}", shown.0);
        let full = k + 1 == count;
        assert_eq!(
            full,
            (*w, *h) == (side, side),
            "level {k} of {count} is {w}x{h}"
        );
        assert!(full || w.max(h) <= &sfs_core::solver::WALK_SIDE);
    }
    // The report lists the levels solved; the observer saw the copy's
    // start (its plane) first.
    assert_eq!(walked.levels.len() + 1, count);
    assert!(walked.unused_parameters.is_empty());
    // Work: inner iterations times the level's pixels.
    let work = |s: &sfs_core::solver::Solution| -> f64 {
        s.levels
            .iter()
            .map(|l| (l.energies.len() * l.width * l.height) as f64)
            .sum()
    };
    assert!(
        work(&walked) < 0.5 * work(&paper),
        "walked {} against the paper's walk {}",
        work(&walked),
        work(&paper)
    );
    let (walked_rse, paper_rse) = (rse(&walked.depth, &scene), rse(&paper.depth, &scene));
    assert!(
        walked_rse <= 1.1 * paper_rse,
        "walked {walked_rse} against the paper's walk {paper_rse}"
    );
    assert_exposure_moves_nothing(&lit, &walked.depth);
}

/// A large photograph whose depth unit is searched (here its object's
/// distance) shows a quick look first: one level no larger than
/// `PREVIEW_WALK_SIDE`, labelled level 0 of 1, before any level of the
/// solve; the solve's own levels follow and end at the full size.
#[test]
fn a_searched_unit_shows_a_quick_look_first() {
    use sfs_core::solver::depth_unit::{DistanceCues, PREVIEW_WALK_SIDE, solve_photograph};
    let side = 2 * sfs_core::solver::WALK_SIDE + 28;
    let lights = [led_before_the_camera()];
    let scene = sombrero_lit(side, side, &lights);
    let mut depths = scene.depth_gt.finite_values();
    depths.sort_by(f64::total_cmp);
    let cues = DistanceCues {
        distance: Some(depths[depths.len() / 2]),
        ..DistanceCues::default()
    };
    let mut unknown = Problem {
        intensity_scale: 1.0,
        ..problem(&scene, &lights)
    };
    let mut shown = Levels::default();
    solve_photograph(
        &mut unknown,
        &SolverParams::default(),
        &Method::Linearised,
        &cues,
        &mut shown,
    )
    .expect("solves");
    let (level, levels, (w, h)) = shown.0[0];
    assert_eq!((level, levels), (0, 1), "{:?}", shown.0);
    assert!(w.max(h) <= PREVIEW_WALK_SIDE, "{:?}", shown.0);
    assert!(shown.0.len() > 2, "{:?}", shown.0);
    assert_eq!(shown.0.last().map(|l| l.2), Some((side, side)));
}

/// A distance the depth cannot follow (in front of an LED that sits
/// before the camera: the surface stays beyond the light whatever the
/// intensity scale) ends the search after the solves that show it, instead
/// of walking the scale through every solve allowed; it is reported unmet.
#[test]
fn a_distance_the_depth_does_not_follow_ends_the_search() {
    use sfs_core::solver::calibrate::{DistanceTarget, solve_meeting};
    let side = 96;
    let lights = [led_before_the_camera()];
    let scene = sombrero_lit(side, side, &lights);
    let mut unknown = problem(&scene, &lights);
    let (_, fit) = solve_meeting(
        &mut unknown,
        &SolverParams::default(),
        &Method::Linearised,
        &DistanceTarget::Median(0.5),
        &mut (),
    )
    .expect("solves");
    assert!(!fit.converged, "{fit:?}");
    assert!(fit.solves <= 4, "{fit:?}");
}

/// With `--albedo auto` on a large photograph whose distance is searched,
/// the albedo is decided at the scale the working copy's search found; an
/// estimate used as judged is then searched on the divided image from the
/// scale albedo 1's search corrected the plane's guess to, and albedo 1 is
/// not solved at the full size at all: every full-size solve the observer
/// sees is one the fit counts, and the distance is met.
#[test]
fn a_used_albedo_estimate_costs_no_full_size_solve_of_albedo_one() {
    use sfs_core::params::AlbedoChoice;
    use sfs_core::solver::calibrate::{
        DistanceTarget, MEDIAN_TOLERANCE, median_depth, solve_meeting,
    };
    let side = 520;
    let lights = [flash_beside_the_lens()];
    let scene = sombrero_lit(side, side, &lights);
    // Checkered albedo patches (1 and 0.55, 8 per side).
    let mut lit = problem(&scene, &lights);
    let cell = side / 8;
    lit.image = sfs_core::grid::Grid::from_fn(side, side, |c, r| {
        let albedo = if (c / cell + r / cell) % 2 == 0 {
            1.0
        } else {
            0.55
        };
        albedo * *scene.image.at(c, r)
    });
    lit.intensity_scale = 1.0;
    let distance = median_depth(&scene.depth_gt);
    let mut full_size = FullSizeSolves::default();
    let (solution, fit) = solve_meeting(
        &mut lit,
        &SolverParams {
            albedo: AlbedoChoice::Auto,
            ..SolverParams::default()
        },
        &Method::Linearised,
        &DistanceTarget::Median(distance),
        &mut full_size,
    )
    .expect("solves");
    let albedo = solution.albedo_fit.as_ref().expect("decided");
    assert!(albedo.used, "{}", albedo.summary);
    assert_eq!(full_size.0, fit.solves, "{fit:?}");
    assert_eq!(fit.solves, 1, "{fit:?}");
    let met = median_depth(&solution.depth) / distance - 1.0;
    assert!(met.abs() < MEDIAN_TOLERANCE, "{met}");
}

/// Counts the solves that end at the full size of a 520 px image.
#[derive(Default)]
struct FullSizeSolves(usize);

impl sfs_core::solver::SolveObserver for FullSizeSolves {
    fn on_level(&mut self, result: &sfs_core::solver::LevelResult) {
        if result.level + 1 == result.levels && result.geometry.width == 520 {
            self.0 += 1;
        }
    }
}
