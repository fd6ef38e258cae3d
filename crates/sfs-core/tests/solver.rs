//! Solver-level tests on small synthetic scenes.

use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::model::{self, Derivatives, Lambertian, LevelGeometry, PixelRay, Reflectance};
use sfs_core::params::{InitialDepth, SolverParams};
use sfs_core::scene::sombrero::{sombrero, sombrero_depth};
use sfs_core::solver::{IterationReport, LevelResult, Problem, SolveError, SolveObserver, solve};

/// The paper's set-up (pixel units, constant start, whole pyramid) with an
/// alpha for these small scenes: at 64x64 the same shape has 16x larger
/// second derivatives per pixel than at 256x256.
fn small_params() -> SolverParams {
    SolverParams::paper(0.3)
}

/// The default parameters with the paper's constant start (whole pyramid).
fn pyramid_params() -> SolverParams {
    SolverParams {
        initial_depth: InitialDepth::FromImage,
        ..SolverParams::default()
    }
}

fn problem(scene: &sfs_core::scene::Scene) -> Problem {
    Problem {
        image: scene.image.clone(),
        camera: scene.camera,
        intensity_scale: scene.intensity_scale,
        object_mask: Some(scene.object_mask.clone()),
        confidence: None,
        lights: Vec::new(),
    }
}

/// Mean |D| / mean I of the Sombrero's exact depth with the solver's upwind
/// differences.
fn upwind_residual(size: usize) -> f64 {
    let scene = sombrero(size, size);
    let model = Lambertian {
        intensity_scale: scene.intensity_scale,
    };
    reprojection_residual(&scene, &model)
}

/// Mean |D| / mean I of a scene's exact depth reprojected by `model` with
/// the solver's upwind differences.
fn reprojection_residual<M: Reflectance + ?Sized>(
    scene: &sfs_core::scene::Scene,
    model: &M,
) -> f64 {
    let (w, h) = scene.image.size();
    let geometry = LevelGeometry::new(w, h, w, h, scene.camera);
    let reprojection = model::reproject(
        model,
        &geometry,
        &scene.object_mask,
        &scene.depth_gt,
        Cancel::NEVER,
    )
    .uncancelled();
    let diff: f64 = reprojection
        .as_slice()
        .iter()
        .zip(scene.image.as_slice())
        .map(|(r, i)| (r - i).abs())
        .sum();
    diff / scene.image.as_slice().iter().sum::<f64>()
}

#[test]
fn residual_vanishes_on_the_exact_sombrero() {
    // With the exact gradient the model reproduces the image to rounding.
    let scene = sombrero(64, 64);
    let model = Lambertian {
        intensity_scale: scene.intensity_scale,
    };
    for (c, r) in [(3, 5), (31, 31), (50, 12), (63, 63)] {
        let (x, y) = scene.camera.image_xy(c as f64, r as f64);
        let (z, zx, zy) = sombrero_depth(x, y, 64);
        let ray = PixelRay {
            x_px: x,
            y_px: y,
            focal_px: scene.camera.focal_px,
        };
        let d = scene.image.at(c, r) - model.radiance(&ray, z, zx, zy);
        assert!(d.abs() < 1e-12, "D = {d} at ({c}, {r})");
    }
    // With upwind differences D is a discretisation error: small, and it
    // shrinks as the grid is refined (first-order scheme).
    let coarse = upwind_residual(128);
    let fine = upwind_residual(256);
    assert!(coarse < 0.02, "mean |D| / mean I = {coarse}");
    assert!(
        fine < 0.7 * coarse,
        "refining the grid must shrink D: {coarse} -> {fine}"
    );
}

#[test]
fn final_energy_is_well_below_the_initial_one() {
    let scene = sombrero(48, 48);
    let params = small_params();
    let solution = solve(&problem(&scene), &params, &mut ()).expect("solves");
    let model = Lambertian {
        intensity_scale: scene.intensity_scale,
    };
    let geometry = LevelGeometry::new(48, 48, 48, 48, scene.camera);
    let energy_of = |depth: &Grid<f64>| {
        model::energy(
            &model,
            &geometry,
            &scene.image,
            &Grid::filled(48, 48, 1.0),
            &scene.object_mask,
            depth,
            solution.alpha_px,
            solution.lambda_px,
            Cancel::NEVER,
        )
        .uncancelled()
        .total
    };
    let initial = energy_of(&Grid::filled(48, 48, solution.initial_depth));
    let last = energy_of(&solution.depth);
    assert!(last < 0.05 * initial, "energy {initial} -> {last}");
}

#[test]
fn small_sombrero_is_recovered() {
    let scene = sombrero(64, 64);
    let params = small_params();
    let solution = solve(&problem(&scene), &params, &mut ()).expect("solves");
    let errors = scene.centred_errors(&solution.depth).expect("measurable");
    // A constant depth scores 0.0445 (METHOD.md section 7); this solve
    // measured 0.023 / 0.007 when the test was written.
    assert!(errors.rse < 0.03, "RSE {}", errors.rse);
    assert!(errors.rie < 0.02, "RIE {}", errors.rie);
    let depth = solution.depth.as_slice();
    assert!(depth.iter().all(|z| z.is_finite() && *z > 0.0));
}

#[test]
fn warm_start_from_the_truth_stays_there() {
    let scene = sombrero(64, 64);
    let params = SolverParams {
        initial_depth: InitialDepth::Map(scene.depth_gt.clone()),
        ..small_params()
    };
    let solution = solve(&problem(&scene), &params, &mut ()).expect("solves");
    assert_eq!(
        solution.levels.len(),
        1,
        "a warm start refines at full resolution only"
    );
    let rse = metrics::rse(&solution.depth, &scene.depth_gt).expect("measurable");
    // The discrete minimiser sits a discretisation error away from the truth:
    // measured 0.0045 at 64x64 (alpha 0.3), 0.0014 at 128x128, 0.0008 at
    // 256x256.
    assert!(rse < 0.005, "RSE {rse}");
}

#[test]
fn numeric_and_exact_derivatives_give_the_same_result() {
    let scene = sombrero(40, 40);
    let exact = solve(&problem(&scene), &small_params(), &mut ()).expect("solves");
    let params = SolverParams {
        derivatives: Derivatives::Numeric { h_z: 1e-12 },
        ..small_params()
    };
    let numeric = solve(&problem(&scene), &params, &mut ()).expect("solves");
    // Per pixel the two agree to about 1e-4 (see model tests); over a whole
    // solve such differences can flip a few upwind branches, so compare the
    // results' quality and closeness rather than bits.
    let difference = metrics::rse(&numeric.depth, &exact.depth).expect("same size");
    let rse_exact = metrics::rse(&exact.depth, &scene.depth_gt).expect("measurable");
    let rse_numeric = metrics::rse(&numeric.depth, &scene.depth_gt).expect("measurable");
    assert!(difference < 0.01, "relative difference {difference}");
    assert!(
        (rse_exact - rse_numeric).abs() < 0.003,
        "RSE {rse_exact} vs {rse_numeric}"
    );
}

/// Records events and cancels after a number of polls.
#[derive(Default)]
struct Recorder {
    levels: Vec<(usize, usize, usize, usize)>,
    iterations: usize,
    polls: std::sync::atomic::AtomicUsize,
    cancel_at_poll: Option<usize>,
    events_after_cancel: usize,
    /// Polls before the first level arrived.
    polls_before_first_level: Option<usize>,
}

impl SolveObserver for Recorder {
    fn on_iteration(&mut self, report: &IterationReport) {
        self.iterations += 1;
        if self
            .cancel_at_poll
            .is_some_and(|n| self.polls.load(std::sync::atomic::Ordering::Relaxed) >= n)
        {
            self.events_after_cancel += 1;
        }
        assert!(report.energy.total.is_finite());
    }
    fn on_level(&mut self, result: &LevelResult) {
        self.polls_before_first_level
            .get_or_insert(self.polls.load(std::sync::atomic::Ordering::Relaxed));
        let (w, h) = result.depth.size();
        assert_eq!(result.reprojection.size(), (w, h));
        assert!(
            result.depth.as_slice().iter().all(|z| z.is_finite()),
            "Sombrero: every pixel is object"
        );
        self.levels.push((result.level, result.levels, w, h));
    }
    fn is_cancelled(&self) -> bool {
        self.polls
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.cancel_at_poll
            .is_some_and(|n| self.polls.load(std::sync::atomic::Ordering::Relaxed) >= n)
    }
}

#[test]
fn levels_arrive_coarse_to_fine_with_growing_sizes() {
    let scene = sombrero(64, 48);
    let mut recorder = Recorder::default();
    let params = pyramid_params();
    let solution = solve(&problem(&scene), &params, &mut recorder).expect("solves");
    let levels = &recorder.levels;
    assert!(levels.len() > 3);
    assert_eq!(levels.len(), solution.levels.len());
    for (k, &(index, count, w, h)) in levels.iter().enumerate() {
        assert_eq!((index, count), (k, levels.len()));
        if k > 0 {
            assert!(
                w >= levels[k - 1].2
                    && h >= levels[k - 1].3
                    && w * h > levels[k - 1].2 * levels[k - 1].3
            );
        }
    }
    assert_eq!(levels.last().map(|l| (l.2, l.3)), Some((64, 48)));
    assert_eq!(recorder.iterations, levels.len() * params.kappa);
    // One poll per coarser level built, then one per SOR sweep; and between
    // the long passes: 3 in the preparation (after validation, the scales
    // and the noise estimate), 2 before the first level (after copying the
    // start and its energy), one per level (its system allocated), and per
    // outer iteration after the linearisation, each assembly and each
    // energy. Besides, the passes over a level poll once per row (per block
    // of rows in the data part): the start's energy, and per outer
    // iteration the linearisation (two passes), two passes per assembly and
    // the energy of each trial step (at most 5 with backtracking); each SOR
    // sweep once per band of rows.
    let outer = levels.len() * params.kappa;
    let inner = outer * params.inner_iterations;
    let sweeps = inner * params.sor_iterations;
    let rows: usize = solution.levels.iter().map(|l| l.height).sum();
    // After the linearisation, each assembly, each trial step and its keeping.
    let between_passes =
        levels.len() - 1 + sweeps + 3 + 2 + levels.len() + outer + inner + 2 * outer;
    // Each SOR sweep polls once per band of rows.
    let bands: usize = solution
        .levels
        .iter()
        .map(|l| sfs_core::solver::sor::band_count(l.height))
        .sum();
    let per_row_most = 48
        + rows * params.kappa * (2 + 2 * params.inner_iterations + 5)
        + bands * params.kappa * params.inner_iterations * params.sor_iterations;
    let polls = recorder.polls.load(std::sync::atomic::Ordering::Relaxed);
    assert!(
        polls > between_passes && polls <= between_passes + per_row_most,
        "{polls} polls: {between_passes} between passes, at most {per_row_most} per row"
    );
}

#[test]
fn cancel_stops_within_one_sweep() {
    let scene = sombrero(64, 64);
    for cancel_at in [1, 7, 500] {
        let mut recorder = Recorder {
            cancel_at_poll: Some(cancel_at),
            ..Default::default()
        };
        let result = solve(&problem(&scene), &pyramid_params(), &mut recorder);
        assert!(matches!(result, Err(SolveError::Cancelled)), "{result:?}");
        // After the poll that said "cancelled", only the rest of that pass's
        // rows poll once each (and skip their work) before the solver stops.
        let polls = recorder.polls.load(std::sync::atomic::Ordering::Relaxed);
        assert!(
            polls >= cancel_at && polls <= cancel_at + 64 + 1,
            "cancelled at poll {cancel_at}, {polls} polls"
        );
        assert_eq!(recorder.events_after_cancel, 0);
    }
}

#[test]
fn cancel_reaches_the_fast_marching_start_and_its_denoising() {
    // A noisy image: the default start TV-denoises, fills and marches
    // before the first SOR sweep; each of them polls.
    let scene = sombrero(96, 96);
    let noisy = sfs_core::scene::add_noise(&scene.image, 25.0, 3);
    let mut p = problem(&scene);
    p.image = noisy;
    let mut whole = Recorder::default();
    solve(&p, &SolverParams::default(), &mut whole).expect("solves");
    let before_start = whole.polls_before_first_level.expect("levels arrive");
    // The preparation polls per row (a few hundred polls here); the
    // denoising and fast marching go on polling well past it.
    assert!(before_start > 1000, "{before_start} polls before the start");
    for cancel_at in [
        1,
        2,
        5,
        before_start / 2,
        before_start * 3 / 4,
        before_start - 1,
    ] {
        let mut recorder = Recorder {
            cancel_at_poll: Some(cancel_at),
            ..Default::default()
        };
        let result = solve(&p, &SolverParams::default(), &mut recorder);
        assert!(matches!(result, Err(SolveError::Cancelled)), "{result:?}");
        // Only the rest of the pass that saw it polls once per row.
        let polls = recorder.polls.load(std::sync::atomic::Ordering::Relaxed);
        assert!(
            polls >= cancel_at && polls <= cancel_at + 96 + 1,
            "cancelled at poll {cancel_at}, {polls} polls"
        );
        assert!(
            recorder.levels.is_empty(),
            "no level before the start is done"
        );
    }
}

#[test]
fn a_large_solve_sends_a_preview_first() {
    // 640x560: above the preview threshold (512x512 pixels).
    let scene = sombrero(640, 560);
    let mut recorder = Recorder::default();
    let solution = solve(&problem(&scene), &SolverParams::default(), &mut recorder).unwrap();
    let levels = &recorder.levels;
    assert_eq!(levels.len(), 3, "{levels:?}");
    // The preview (longest side 256), then the start and the refined depth.
    assert_eq!(levels[0], (0, 3, 256, 224));
    assert_eq!(levels[1], (1, 3, 640, 560));
    assert_eq!(levels[2], (2, 3, 640, 560));
    // The preview does not change the result: the solution is the finest level's.
    assert!(solution.depth.as_slice().iter().all(|z| z.is_finite()));
    // Below the threshold there is no preview.
    let mut small = Recorder::default();
    solve(
        &problem(&sombrero(256, 256)),
        &SolverParams::default(),
        &mut small,
    )
    .unwrap();
    assert_eq!(small.levels.len(), 2);
}

#[test]
fn clipped_pixels_are_not_trusted() {
    // A highlight clipped at the top of the range: the solve must be the
    // one with those pixels painted as confidence 0, not one that bends the
    // surface towards the light to explain a value the model cannot reach.
    let scene = sombrero(48, 48);
    let mut clipped = problem(&scene);
    clipped.image = scene.image.map(|&v| (v * 2.5).min(1.0));
    let mut painted = clipped.clone();
    painted.confidence = Some(clipped.image.map(|&v| if v >= 1.0 { 0.0 } else { 1.0 }));
    let highlight = clipped
        .image
        .as_slice()
        .iter()
        .filter(|&&v| v >= 1.0)
        .count();
    assert!(
        highlight > 20,
        "the test needs a clipped region ({highlight} pixels)"
    );
    let params = SolverParams::default();
    let a = solve(&clipped, &params, &mut ()).expect("solves");
    let b = solve(&painted, &params, &mut ()).expect("solves");
    assert_eq!(a.depth, b.depth);
}

/// With a light off the optical centre (an anisotropic LED beside the lens)
/// the numeric and the exact derivatives of the residual agree at every
/// pixel of the Sombrero, and both drive the solver to the Sombrero (the
/// depths themselves differ by up to a few per cent: with a light off the
/// centre a tilt of the surface trades against the light's offset almost
/// freely, so round-off picks slightly different points along that valley).
#[test]
fn numeric_and_exact_derivatives_agree_with_lights_off_centre() {
    use sfs_core::light::LightModel;
    use sfs_core::model::{Spacing, neighbourhood};
    use sfs_core::scene::sombrero::sombrero_lit;
    let light = led_beside_the_lens();
    let scene = sombrero_lit(48, 48, &[light]);
    let model = LightModel::new(scene.intensity_scale, &[light]);
    let geometry = LevelGeometry::new(48, 48, 48, 48, scene.camera);
    let h = Spacing { x: 1.0, y: 1.0 };
    let mut worst: f64 = 0.0;
    for r in 0..48 {
        for c in 0..48 {
            let nb = neighbourhood(&scene.depth_gt, &scene.object_mask, c, r);
            let (branches, _, _) = nb.upwind(h);
            let values = nb.values();
            let ray = geometry.ray(c, r);
            let i = *scene.image.at(c, r);
            let (d_exact, j_exact) = model::residual_and_jacobian(
                &model,
                &ray,
                i,
                &values,
                branches,
                h,
                Derivatives::Exact,
            )
            .unwrap();
            let (d_numeric, j_numeric) = model::residual_and_jacobian(
                &model,
                &ray,
                i,
                &values,
                branches,
                h,
                Derivatives::Numeric { h_z: 1e-6 },
            )
            .unwrap();
            assert!((d_exact - d_numeric).abs() < 1e-12);
            let scale = j_exact.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-9);
            for k in 0..5 {
                worst = worst.max((j_exact[k] - j_numeric[k]).abs() / scale);
            }
        }
    }
    assert!(
        worst < 1e-5,
        "exact and numeric jacobians differ by {worst} of their scale"
    );
    let lit = Problem {
        lights: vec![light],
        ..problem(&scene)
    };
    let rse_with = |derivatives| {
        let params = SolverParams {
            derivatives,
            ..SolverParams::default()
        };
        metrics::rse(
            &solve(&lit, &params, &mut ()).unwrap().depth,
            &scene.depth_gt,
        )
        .unwrap()
    };
    let (exact, numeric) = (
        rse_with(Derivatives::Exact),
        rse_with(Derivatives::Numeric { h_z: 1e-6 }),
    );
    assert!(exact < 0.05, "rse {exact}");
    assert!(
        (numeric - exact).abs() < 0.2 * exact,
        "numeric {numeric} exact {exact}"
    );
}

/// The upwind differences pick the one-sided difference from the depth
/// alone (the larger descent, its sign restored), whatever the light: with a
/// light beside the lens the true Sombrero is explained by its upwind
/// reprojection as well as with the light at the centre (mean |D| / mean I
/// within 1.5x), and the picked difference has the sign of the central one
/// wherever the depth is monotone across the pixel.
#[test]
fn upwind_differences_keep_their_sign_with_lights_off_centre() {
    use sfs_core::light::{LightModel, PointLight};
    use sfs_core::model::{Branch, Spacing, neighbourhood};
    use sfs_core::scene::sombrero::sombrero_lit;
    let light = led_beside_the_lens();
    let size = 128;
    let residual = |lights: &[PointLight]| {
        let scene = sombrero_lit(size, size, lights);
        let model = LightModel::new(scene.intensity_scale, lights);
        reprojection_residual(&scene, &model)
    };
    let (centred, beside) = (residual(&[]), residual(&[light]));
    eprintln!("upwind residual at the truth: centred {centred:.5}, beside {beside:.5}");
    assert!(beside < 1.5 * centred, "centred {centred} beside {beside}");
    // Signs: on monotone stretches the upwind difference has the central
    // difference's sign.
    let scene = sombrero_lit(size, size, &[light]);
    let h = Spacing { x: 1.0, y: 1.0 };
    let mut wrong = 0;
    for r in 1..size - 1 {
        for c in 1..size - 1 {
            let nb = neighbourhood(&scene.depth_gt, &scene.object_mask, c, r);
            let (branches, gx, _) = nb.upwind(h);
            let (left, right) = (nb.left.unwrap(), nb.right.unwrap());
            let monotone = (nb.centre - left) * (right - nb.centre) > 0.0;
            if monotone && branches.x != Branch::Zero && gx * (right - left) < 0.0 {
                wrong += 1;
            }
        }
    }
    assert_eq!(wrong, 0, "upwind differences against the central sign");
}

/// An LED (mu = 1) beside the lens, aimed at the Sombrero.
fn led_beside_the_lens() -> sfs_core::light::PointLight {
    sfs_core::light::PointLight {
        position: [0.5, -0.4, 0.0],
        direction: Some([-0.2, 0.2, 1.0]),
        mu: 1.0,
        intensity: 1.0,
    }
    .validated(1)
    .unwrap()
}

/// Asserts the first solution's RSE against `scene`'s truth is at most
/// 1.05 times the second's (`case` and the names say which).
#[track_caller]
fn assert_rse_within_5_percent(
    scene: &sfs_core::scene::Scene,
    [(name, solution), (reference_name, reference)]: [(&str, &sfs_core::solver::Solution); 2],
    case: &str,
) {
    let rse = |s: &sfs_core::solver::Solution| {
        metrics::rse(&s.depth, &scene.depth_gt).expect("measurable")
    };
    let (rse_solution, rse_reference) = (rse(solution), rse(reference));
    assert!(
        rse_solution <= 1.05 * rse_reference,
        "{case}: {name} {rse_solution} vs {reference_name} {rse_reference}"
    );
}

/// The adaptive stops keep the fixed schedule's answer. They stop the inner
/// iterations once Psi' has settled where they would only polish the step:
/// on a large image (512 px, where one solve's sweeps reach only locally) and
/// where the fast-marching start is nearly the minimum (the clean 64 and
/// 256 px Sombreros: a step far inside the crop), each with at most a third
/// of the inner iterations. Where the sweeps converge the system and the
/// step is large (the noisy 64 px Sombrero, far from the minimum), the later
/// inner iterations lengthen the step: all of them run, and the answer is
/// the fixed schedule's bit for bit.
#[test]
fn adaptive_stops_keep_the_fixed_schedules_answer() {
    for (size, noise) in [(512, 0.0), (256, 0.0), (64, 0.0), (64, 20.0)] {
        let scene = sombrero(size, size);
        let mut problem = problem(&scene);
        if noise > 0.0 {
            problem.image = sfs_core::scene::add_noise(&scene.image, noise, 7);
        }
        let adaptive = solve(&problem, &SolverParams::default(), &mut ()).expect("solves");
        let fixed = SolverParams::default().with_fixed_schedule();
        let fixed = solve(&problem, &fixed, &mut ()).expect("solves");
        let case = format!("{size} px, noise {noise}");
        assert_rse_within_5_percent(&scene, [("adaptive", &adaptive), ("fixed", &fixed)], &case);
        let (inner_adaptive, inner_fixed) = (
            adaptive.phases.inner_iterations,
            fixed.phases.inner_iterations,
        );
        // 5 outer iterations x 9 inner ones in the fixed schedule.
        assert_eq!(inner_fixed, 45);
        if noise == 0.0 {
            // Measured 5 (one per outer iteration) at each size.
            assert!(
                inner_adaptive * 3 <= inner_fixed,
                "{size} px: {inner_adaptive} inner iterations vs {inner_fixed}"
            );
        } else {
            assert_eq!(inner_adaptive, inner_fixed, "{size} px, noise {noise}");
            assert_eq!(adaptive.depth.as_slice(), fixed.depth.as_slice());
        }
    }
}

/// Up the pyramid from a constant, every inner iteration runs: there the
/// later sweeps keep removing smooth error (docs/speed.md).
#[test]
fn the_whole_pyramid_runs_every_inner_iteration() {
    let scene = sombrero(48, 48);
    let params = pyramid_params();
    let solution = solve(&problem(&scene), &params, &mut ()).expect("solves");
    let outer: usize = solution.levels.iter().map(|l| l.energies.len()).sum();
    assert_eq!(
        solution.phases.inner_iterations,
        outer * params.inner_iterations
    );
    assert_eq!(
        solution.phases.linear_iterations,
        outer * params.inner_iterations * params.sor_iterations
    );
}

/// The multigrid linear solver (V-cycles to a tenth of the residual)
/// refines the fast-marching start as well as SOR, with far fewer smoothing
/// passes. Every inner iteration runs in both (no adaptive inner stop, which
/// stops them at different points), so they solve the same systems' count.
#[test]
fn multigrid_linear_solver_solves_as_well_as_sor() {
    for noise in [0.0, 20.0] {
        let scene = sombrero(64, 64);
        let mut problem = problem(&scene);
        if noise > 0.0 {
            problem.image = sfs_core::scene::add_noise(&scene.image, noise, 7);
        }
        let every_inner = SolverParams {
            inner_tolerance: 0.0,
            ..SolverParams::default()
        };
        let sor = solve(&problem, &every_inner, &mut ()).expect("solves");
        let params = SolverParams {
            linear_solver: sfs_core::params::LinearSolver::Multigrid,
            linear_tolerance: 0.1,
            ..every_inner
        };
        let multigrid = solve(&problem, &params, &mut ()).expect("solves");
        let case = format!("noise {noise}");
        assert_rse_within_5_percent(&scene, [("multigrid", &multigrid), ("SOR", &sor)], &case);
        // A cycle smooths 4 times (and works on the coarser grids): fewer
        // than half of SOR's sweeps (measured 45 cycles against 450).
        assert!(
            4 * multigrid.phases.linear_iterations * 2 < sor.phases.linear_iterations,
            "noise {noise}: {} cycles vs {} sweeps",
            multigrid.phases.linear_iterations,
            sor.phases.linear_iterations
        );
    }
}

/// An iteration count whose bound never binds is reported unused (issue 48):
/// one inner iteration where the default's tolerance stops after the first
/// anyway (the clean Sombrero, docs/speed.md), and a kappa-max above the
/// default's where the level tolerance stops every level at the default's
/// count. Each gives the default's depth bit for bit, and says so.
#[test]
fn counts_that_never_bind_are_reported_unused() {
    let scene = sombrero(64, 64);
    let problem = problem(&scene);
    let default = solve(&problem, &SolverParams::default(), &mut ()).expect("solves");
    assert!(
        default.unused_parameters.is_empty(),
        "{:?}",
        default.unused_parameters
    );
    let one_inner = SolverParams {
        inner_iterations: 1,
        ..SolverParams::default()
    };
    let loose_cap = SolverParams {
        kappa_max: 20,
        level_tolerance: 0.5,
        ..SolverParams::default()
    };
    for (name, params) in [("inner-iters", one_inner), ("kappa-max", loose_cap)] {
        let solved = solve(&problem, &params, &mut ()).expect("solves");
        assert_eq!(solved.depth.as_slice(), default.depth.as_slice(), "{name}");
        assert!(
            solved
                .unused_parameters
                .iter()
                .any(|u| u.starts_with(&format!("--{name} "))),
            "{name}: {:?}",
            solved.unused_parameters
        );
    }
    // Where the count binds it is not reported: the cap alone runs on.
    let cap_alone = SolverParams {
        kappa_max: 20,
        ..SolverParams::default()
    };
    let solved = solve(&problem, &cap_alone, &mut ()).expect("solves");
    assert!(
        !solved
            .unused_parameters
            .iter()
            .any(|u| u.starts_with("--kappa-max")),
        "{:?}",
        solved.unused_parameters
    );
}

/// The step tolerance stops a clean Sombrero's refinement once the depth
/// stopped moving (its fast-marching start is nearly the minimum: at 256 px
/// the first outer iteration moves the depth by about 5e-5 of itself, at
/// 128 px the second): fewer outer iterations than five, the same RSE within
/// 5 %. Unit invariant: the same count with the depth in another unit. Up a pyramid (no start to
/// refine) it does nothing and says so.
#[test]
fn the_step_tolerance_stops_a_refinement_whose_depth_has_settled() {
    let scene = sombrero(128, 128);
    let problem = problem(&scene);
    let full = solve(&problem, &SolverParams::default(), &mut ()).expect("solves");
    let settling = SolverParams {
        step_tolerance: 1e-4,
        ..SolverParams::default()
    };
    let settled = solve(&problem, &settling, &mut ()).expect("solves");
    let outer = |s: &sfs_core::solver::Solution| -> usize {
        s.levels.iter().map(|l| l.energies.len()).sum()
    };
    assert_eq!(outer(&full), 5);
    assert!(outer(&settled) < 5, "{} outer iterations", outer(&settled));
    assert_rse_within_5_percent(&scene, [("settled", &settled), ("full", &full)], "clean");
    // Another unit of depth (the intensity scale with the square of it).
    let mut in_mm = problem.clone();
    in_mm.intensity_scale *= 1e6;
    let settled_mm = solve(&in_mm, &settling, &mut ()).expect("solves");
    assert_eq!(outer(&settled_mm), outer(&settled));
    // A tolerance far below any step: the full schedule, bit for bit.
    let tight = SolverParams {
        step_tolerance: 1e-12,
        ..SolverParams::default()
    };
    let tight = solve(&problem, &tight, &mut ()).expect("solves");
    assert_eq!(tight.depth.as_slice(), full.depth.as_slice());
    let pyramid = SolverParams {
        step_tolerance: 1e-4,
        ..pyramid_params()
    };
    let walked = solve(&problem, &pyramid, &mut ()).expect("solves");
    assert!(
        walked
            .unused_parameters
            .iter()
            .any(|u| u.starts_with("--step-tolerance ")),
        "{:?}",
        walked.unused_parameters
    );
}

/// Offers one memo to every solve and counts what it hears.
struct Remembering {
    memo: std::sync::Arc<sfs_core::solver::SolveMemo>,
    levels: usize,
    iterations: usize,
}

impl SolveObserver for Remembering {
    fn on_iteration(&mut self, _report: &IterationReport) {
        self.iterations += 1;
    }
    fn on_level(&mut self, _result: &LevelResult) {
        self.levels += 1;
    }
    fn memo(&self) -> Option<std::sync::Arc<sfs_core::solver::SolveMemo>> {
        Some(std::sync::Arc::clone(&self.memo))
    }
}

#[test]
fn a_working_copy_solved_again_in_one_pipeline_is_recalled_with_its_levels() {
    let scene = sombrero(64, 48);
    let params = pyramid_params();
    let mut observer = Remembering {
        memo: Default::default(),
        levels: 0,
        iterations: 0,
    };
    let bits = |s: &sfs_core::solver::Solution| -> Vec<u64> {
        s.depth.as_slice().iter().map(|z| z.to_bits()).collect()
    };
    let first = solve(&problem(&scene), &params, &mut observer).expect("solves");
    let heard = (observer.levels, observer.iterations);
    assert!(heard.0 > 3 && heard.1 >= heard.0, "{heard:?}");
    assert!(first.phases.linear_seconds > 0.0);
    // The same problem and parameters: the kept answer, the same messages
    // again, and no work counted.
    let again = solve(&problem(&scene), &params, &mut observer).expect("solves");
    assert_eq!(bits(&again), bits(&first));
    assert_eq!(again.levels.len(), first.levels.len());
    assert_eq!(
        (observer.levels, observer.iterations),
        (2 * heard.0, 2 * heard.1)
    );
    assert_eq!(again.phases.linear_seconds, 0.0);
    // Anything else is solved: another intensity scale, other parameters.
    let mut brighter = problem(&scene);
    brighter.intensity_scale *= 1.5;
    let other = solve(&brighter, &params, &mut observer).expect("solves");
    assert!(other.phases.linear_seconds > 0.0);
    assert_ne!(bits(&other), bits(&first));
    let fewer = SolverParams {
        kappa: params.kappa - 1,
        ..params.clone()
    };
    let other = solve(&problem(&scene), &fewer, &mut observer).expect("solves");
    assert!(other.phases.linear_seconds > 0.0);
    // Without a memo every solve is solved.
    let plain = solve(&problem(&scene), &params, &mut ()).expect("solves");
    assert!(plain.phases.linear_seconds > 0.0);
    assert_eq!(bits(&plain), bits(&first));
}

#[test]
fn a_problem_larger_than_a_working_copy_is_not_kept() {
    let scene = sombrero(272, 256);
    const { assert!(272 * 256 > sfs_core::solver::problem::MEMO_MAX_PIXELS) };
    let mut observer = Remembering {
        memo: Default::default(),
        levels: 0,
        iterations: 0,
    };
    let params = SolverParams::default();
    solve(&problem(&scene), &params, &mut observer).expect("solves");
    let again = solve(&problem(&scene), &params, &mut observer).expect("solves");
    assert!(again.phases.linear_seconds > 0.0);
}

/// The start's denoising decision reads noise, not surface detail: a clean
/// render of a finely rough Sombrero (pixel-scale relief shaded through the
/// model) reads noisy over all its pixels but not where it faces the light,
/// so `auto` marches the image as given and ends nearer the truth than a
/// denoised start; the same render with camera noise is denoised. The
/// reading is unit invariant.
#[test]
fn the_start_is_denoised_for_camera_noise_not_for_surface_detail() {
    use sfs_core::params::{FAST_MARCHING_DENOISE_ABOVE, StartDenoise};
    let smooth = sombrero(128, 128);
    // A fixed pseudo-random relief of 0.4 % of the depth per pixel.
    let relief = |c: usize, r: usize| {
        let k = (c as u64 * 7_919 + r as u64 * 104_729) % 1_009;
        (k as f64 / 1_009.0 - 0.5) * 0.008
    };
    let (w, h) = smooth.depth_gt.size();
    let rough_depth = Grid::from_fn(w, h, |c, r| smooth.depth_gt.at(c, r) * (1.0 + relief(c, r)));
    let rough = sfs_core::scene::shading::shade_from_depth(&sfs_core::scene::Scene {
        depth_gt: rough_depth,
        ..smooth.clone()
    });
    let with = |image: Grid<f64>, start_denoise: StartDenoise| {
        let params = SolverParams {
            start_denoise,
            ..SolverParams::default()
        };
        let solved = solve(
            &Problem {
                image,
                ..problem(&rough)
            },
            &params,
            &mut (),
        )
        .expect("solves");
        let rse = metrics::rse(&solved.depth, &rough.depth_gt).expect("rse");
        (solved, rse)
    };
    let (auto, auto_rse) = with(rough.image.clone(), StartDenoise::Auto);
    let noise = auto.noise.expect("read");
    assert!(noise.relative > FAST_MARCHING_DENOISE_ABOVE, "{noise:?}");
    assert!(
        noise.relative_facing < FAST_MARCHING_DENOISE_ABOVE,
        "{noise:?}"
    );
    assert_eq!(auto.start_denoised, Some(false));
    let (on, on_rse) = with(rough.image.clone(), StartDenoise::On);
    assert_eq!(on.start_denoised, Some(true));
    assert!(auto_rse < on_rse, "as given {auto_rse}, denoised {on_rse}");
    let noisy = sfs_core::scene::add_noise(&rough.image, 5.0, 3);
    let (auto_noisy, _) = with(noisy.clone(), StartDenoise::Auto);
    assert_eq!(auto_noisy.start_denoised, Some(true));
    // The same reading with the depth in another unit (s x 1e6).
    let unit = 1000.0;
    let scaled = Problem {
        intensity_scale: rough.intensity_scale * unit * unit,
        ..problem(&rough)
    };
    let solved = solve(&scaled, &SolverParams::default(), &mut ()).expect("solves");
    let scaled_noise = solved.noise.expect("read");
    assert!((scaled_noise.relative / noise.relative - 1.0).abs() < 1e-9);
    assert!((scaled_noise.relative_facing / noise.relative_facing - 1.0).abs() < 1e-9);
    assert_eq!(solved.start_denoised, Some(false));
}
