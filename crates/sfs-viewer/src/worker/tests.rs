//! The worker's tests: a real solver thread driven through its channels (levels,
//! known distances, reflectance auto, cancellation, superseding, failures,
//! shutdown, back-pressure, photometric-stereo sets).

#[test]
fn join_within_leaves_a_stuck_thread_behind() {
    let (release, stuck_on) = crossbeam_channel::bounded::<()>(0);
    let stuck = std::thread::spawn(move || {
        let _ = stuck_on.recv();
    });
    // Would never return if it joined: the thread waits for `release`.
    join_within(stuck, Duration::from_millis(20));
    drop(release);
    let quick = std::thread::spawn(|| {});
    join_within(quick, SHUTDOWN_WAIT);
}
use std::sync::atomic::AtomicUsize;

use sfs_core::camera::Intrinsics;
use sfs_core::grid::Grid;
use sfs_core::material::Material;
use sfs_core::params::ReflectanceChoice;
use sfs_core::scene::sombrero::sombrero;

use sfs_core::photograph_solve::KnownDistance;
use sfs_core::solver::Method;
use sfs_core::solver::calibrate::KnownDepth;

use super::*;

/// Generous: a wait that fails means a lost event, not a slow machine.
const PATIENCE: Duration = Duration::from_secs(60);

/// The problem of a rendered scene as it stands: its image, camera, scale
/// and object mask, the light at the optical centre, no confidence map.
fn scene_problem(scene: sfs_core::scene::Scene) -> Problem {
    Problem {
        image: scene.image,
        camera: scene.camera,
        intensity_scale: scene.intensity_scale,
        object_mask: Some(scene.object_mask),
        confidence: None,
        lights: Vec::new(),
    }
}

fn sombrero_request(side: usize) -> SolveRequest {
    let problem = scene_problem(sombrero(side, side));
    // The paper's constant start: the whole pyramid, many levels.
    let params = SolverParams {
        initial_depth: InitialDepth::FromImage,
        ..SolverParams::default()
    };
    SolveRequest::new(problem, params, Method::Linearised, true)
}

/// The 64x64 Sombrero (light at the optical centre, default parameters)
/// with one known distance at its pixel (40, 24): 1.5 times the true
/// depth there, so the scale must move.
fn known_depth_request(distance_factor: f64) -> (SolveRequest, KnownDepth) {
    let scene = sfs_core::scene::sombrero::sombrero_lit(64, 64, &[]);
    let (column, row) = (40, 24);
    let point = KnownDepth {
        column_px: column as f64,
        row_px: row as f64,
        depth: distance_factor * scene.depth_gt.at(column, row),
    };
    let mut request = SolveRequest::new(
        scene_problem(scene),
        SolverParams::default(),
        Method::Linearised,
        false,
    );
    request.known_distances = vec![KnownDistance {
        column_px: point.column_px,
        row_px: point.row_px,
        depth: point.depth,
    }];
    (request, point)
}

/// A 1x1 image: the solver rejects it.
fn tiny_request() -> SolveRequest {
    let mut request = sombrero_request(3);
    request.problem.image = Grid::filled(1, 1, 0.5);
    request.problem.camera = Intrinsics::centred(1.0, 1, 1);
    request.problem.object_mask = None;
    request
}

fn spawn_counting() -> (Worker, Arc<AtomicUsize>) {
    let wakes = Arc::new(AtomicUsize::new(0));
    let counter = Arc::clone(&wakes);
    let waker = Box::new(move || {
        counter.fetch_add(1, Ordering::SeqCst);
    });
    (Worker::spawn(waker).expect("spawn"), wakes)
}

fn next_event(worker: &mut Worker) -> Event {
    match worker.recv_timeout(PATIENCE) {
        Some(event) => event,
        None => panic!("no event within {PATIENCE:?}"),
    }
}

/// Events until the terminal event of `job` (inclusive).
fn events_until_end(worker: &mut Worker, job: JobId) -> Vec<Event> {
    let mut events = vec![next_event(worker)];
    while !events
        .last()
        .is_some_and(|e| e.is_terminal() && e.job() == job)
    {
        events.push(next_event(worker));
    }
    events
}

fn wait_for_progress(worker: &mut Worker, job: JobId) {
    loop {
        let event = next_event(worker);
        assert!(
            event.job() == job && !event.is_terminal(),
            "{}",
            kind(Some(&event))
        );
        if let Event::Progress { .. } = event {
            return;
        }
    }
}

/// The levels streamed among `events`, in order.
fn streamed_levels(events: &[Event]) -> Vec<&LevelResult> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Level { result, .. } => Some(result),
            _ => None,
        })
        .collect()
}

/// The variant and job, for messages (events hold whole depth maps).
fn kind(event: Option<&Event>) -> String {
    let Some(event) = event else {
        return "nothing".into();
    };
    let name = match event {
        Event::Started { .. } => "Started",
        Event::Progress { .. } => "Progress",
        Event::Level { .. } => "Level",
        Event::Finished { .. } => "Finished",
        Event::SetFinished { .. } => "SetFinished",
        Event::Failed { .. } => "Failed",
        Event::Cancelled { .. } => "Cancelled",
    };
    format!("{name} of {}", event.job())
}

fn failure(event: Option<&Event>) -> &str {
    match event {
        Some(Event::Failed { error, .. }) => error,
        other => panic!("expected Failed, got {}", kind(other)),
    }
}

fn finished(event: Option<&Event>) -> bool {
    matches!(event, Some(Event::Finished { .. }))
}

#[test]
fn small_solve_reports_levels_coarse_to_fine_and_finishes() {
    let (mut worker, wakes) = spawn_counting();
    assert!(worker.latest_job().is_none() && !worker.is_busy());
    let job = worker.submit(sombrero_request(32));
    assert!(worker.latest_job() == Some(job) && worker.is_busy());
    let mut events = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    while worker.is_busy() {
        assert!(Instant::now() < deadline, "no Finished within {PATIENCE:?}");
        events.extend(worker.drain(Duration::from_millis(5)));
        thread::sleep(Duration::from_millis(1));
    }
    assert!(events.iter().all(|e| e.job() == job));
    let Some(Event::Started { level_sizes, .. }) = events.first() else {
        panic!("first event is {}", kind(events.first()));
    };
    assert!(level_sizes.len() > 1 && level_sizes.last() == Some(&(32, 32)));
    assert!(
        level_sizes
            .windows(2)
            .all(|p| p[0].0 < p[1].0 && p[0].1 < p[1].1)
    );
    let levels = streamed_levels(&events);
    assert_eq!(levels.len(), level_sizes.len());
    for (index, (result, size)) in levels.iter().zip(level_sizes).enumerate() {
        assert_eq!((result.level, result.levels), (index, level_sizes.len()));
        assert_eq!(result.depth.size(), *size);
    }
    assert!(events.iter().any(|e| matches!(e, Event::Progress { .. })));
    let Some(Event::Finished { solved, .. }) = events.last() else {
        panic!("last event is {}", kind(events.last()));
    };
    let solution = &solved.solution;
    assert_eq!(solution.depth.size(), (32, 32));
    assert_eq!(solution.levels.len(), level_sizes.len());
    assert_eq!(events.iter().filter(|e| e.is_terminal()).count(), 1);
    // The waker runs just after each send: let it catch up.
    while wakes.load(Ordering::SeqCst) < events.len() {
        assert!(Instant::now() < deadline, "waker called too rarely");
        thread::sleep(Duration::from_millis(1));
    }
    assert!(worker.drain(Duration::from_secs(1)).next().is_none());
}

#[test]
fn a_known_depth_sets_the_scale_and_the_fit_reaches_the_ui() {
    let (mut worker, _) = spawn_counting();
    let (request, point) = known_depth_request(1.5);
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    let Some(Event::Finished { solved, .. }) = events.last() else {
        panic!("last event is {}", kind(events.last()));
    };
    let solution = &solved.solution;
    let known_depth_fit = solved.depth_unit.as_ref().and_then(|u| u.fit.as_ref());
    let (c, r) = (point.column_px as usize, point.row_px as usize);
    let solved = *solution.depth.at(c, r);
    assert!(
        ((solved - point.depth) / point.depth).abs() < 5e-3,
        "solved {solved}, given {}",
        point.depth
    );
    let fit = known_depth_fit.expect("the fit is reported");
    assert_eq!(fit.points.len(), 1);
    assert!(fit.converged && fit.solves >= 1, "{fit:?}");
    assert!(fit.points[0].relative_residual.abs() < 5e-3, "{fit:?}");
    // Depth goes as sqrt(s): 1.5 times the depth, about 2.25 times s = 2.
    assert!(
        (3.5..5.5).contains(&fit.intensity_scale),
        "{}",
        fit.intensity_scale
    );
    // The last level on screen is the finished depth.
    let last_level = events
        .iter()
        .rev()
        .find_map(|e| match e {
            Event::Level { result, .. } => Some(result),
            _ => None,
        })
        .expect("levels streamed");
    assert_eq!(*last_level.depth, solution.depth);
    // Without known depths there is no fit.
    let job = worker.submit(sombrero_request(32));
    let events = events_until_end(&mut worker, job);
    let Some(Event::Finished { solved, .. }) = events.last() else {
        panic!("last event is {}", kind(events.last()));
    };
    assert!(solved.depth_unit.as_ref().is_some_and(|u| u.fit.is_none()));
}

/// The finished solution of `job`'s events, which must end with it.
fn finished_solution(events: &[Event]) -> &Solution {
    match events.last() {
        Some(Event::Finished { solved, .. }) => &solved.solution,
        other => panic!("last event is {}", kind(other)),
    }
}

/// Checks a fit of `reflectance auto` and that the solve used its
/// material.
fn assert_fitted(solution: &Solution) {
    let fit = solution
        .material_fit
        .as_ref()
        .expect("reflectance auto reports its fit");
    assert_eq!(
        fit.trials.len(),
        sfs_core::solver::material_fit::candidates().len()
    );
    assert_eq!(fit.trials[0].material, fit.best);
    assert_eq!(solution.material, fit.material);
    assert!(!fit.summary.is_empty());
}

#[test]
fn reflectance_auto_fits_the_material_and_the_fit_reaches_the_ui() {
    let (mut worker, _) = spawn_counting();
    let mut request = sombrero_request(32);
    request.params.reflectance = ReflectanceChoice::Auto;
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    let solution = finished_solution(&events);
    assert_fitted(solution);
    assert_eq!(solution.depth.size(), (32, 32));
    // A given material: no fit.
    let mut request = sombrero_request(32);
    request.params.reflectance = ReflectanceChoice::OrenNayar;
    request.params.roughness_rad = 0.45;
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    let solution = finished_solution(&events);
    assert!(solution.material_fit.is_none());
    assert_eq!(
        solution.material,
        Material::OrenNayar {
            roughness_rad: 0.45
        }
    );
    // With a known distance: fitted before the search, which meets it.
    let (mut request, point) = known_depth_request(1.5);
    request.params.reflectance = ReflectanceChoice::Auto;
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    let Some(Event::Finished { solved, .. }) = events.last() else {
        panic!("last event is {}", kind(events.last()));
    };
    let unit = solved.depth_unit.as_ref().expect("the unit is decided");
    let fit = unit.fit.as_ref().expect("the fit is reported");
    assert!(fit.converged, "{fit:?}");
    let solution = finished_solution(&events);
    assert_fitted(solution);
    let solved = *solution
        .depth
        .at(point.column_px as usize, point.row_px as usize);
    assert!(
        ((solved - point.depth) / point.depth).abs() < 5e-3,
        "solved {solved}, given {}",
        point.depth
    );
    // A light off the centre, scale estimated: as Lambertian, then the
    // material is fitted at the estimated scale.
    let a = 40f64.to_radians();
    let light = sfs_core::light::PointLight {
        position: [2.0 * a.sin(), 0.0, 2.0 * (1.0 - a.cos())],
        ..sfs_core::light::PointLight::CENTRED
    };
    let scene = sfs_core::scene::sombrero::sombrero_lit(48, 48, &[light]);
    let request = SolveRequest::new(
        Problem {
            image: scene.image,
            camera: scene.camera,
            intensity_scale: 1.0,
            object_mask: Some(scene.object_mask),
            confidence: None,
            lights: vec![light],
        },
        SolverParams {
            reflectance: ReflectanceChoice::Auto,
            ..SolverParams::default()
        },
        Method::Linearised,
        false,
    );
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    assert!(matches!(
        events.last(),
        Some(Event::Finished { solved, .. }) if solved.depth_unit.is_some()
    ));
    assert_fitted(finished_solution(&events));
}

#[test]
fn a_non_positive_known_depth_fails_the_job_without_a_panic() {
    let (mut worker, _) = spawn_counting();
    for distance in [0.0, -1.0, f64::NAN] {
        let (mut request, _) = known_depth_request(1.0);
        request.known_distances[0].depth = distance;
        let job = worker.submit(request);
        let error = failure(events_until_end(&mut worker, job).last()).to_owned();
        assert!(error.contains("must be a positive number"), "{error}");
        assert!(!error.contains("panicked"), "{error}");
    }
    // Off the image: refused before the search, and the worker lives on.
    let (mut request, _) = known_depth_request(1.0);
    request.known_distances[0].column_px = 640.0;
    let job = worker.submit(request);
    let error = failure(events_until_end(&mut worker, job).last()).to_owned();
    assert!(error.contains("outside the 64x64 photograph"), "{error}");
    let (request, _) = known_depth_request(1.0);
    let job = worker.submit(request);
    assert!(finished(events_until_end(&mut worker, job).last()));
}

#[test]
fn cancel_stops_a_running_solve() {
    let (mut worker, _) = spawn_counting();
    let job = worker.submit(sombrero_request(192));
    wait_for_progress(&mut worker, job);
    worker.cancel(job);
    let events = events_until_end(&mut worker, job);
    assert!(matches!(events.last(), Some(Event::Cancelled { .. })));
    assert!(events.iter().all(|e| e.job() == job && !finished(Some(e))));
    assert!(!worker.is_busy());
}

#[test]
fn a_newer_job_supersedes_an_older_one() {
    let (mut worker, _) = spawn_counting();
    let old = worker.submit(sombrero_request(192));
    let new = worker.submit(sombrero_request(32));
    assert!(new > old && worker.latest_job() == Some(new));
    let events = events_until_end(&mut worker, new);
    assert!(finished(events.last()));
    // The old job may or may not have started before the new one came.
    let of_old: Vec<&Event> = events.iter().filter(|e| e.job() == old).collect();
    assert!(matches!(of_old.last(), Some(Event::Cancelled { .. })));
    assert_eq!(of_old.iter().filter(|e| e.is_terminal()).count(), 1);
    let new_started = events
        .iter()
        .position(|e| e.job() == new && matches!(e, Event::Started { .. }))
        .expect("new job started");
    assert!(events[new_started..].iter().all(|e| e.job() == new));
}

struct PanicOnIteration;

impl SolveObserver for PanicOnIteration {
    fn on_iteration(&mut self, report: &IterationReport) {
        panic!("injected fault at level {}", report.level);
    }
}

#[test]
fn errors_and_panics_fail_the_job_and_the_worker_lives_on() {
    let calls = Arc::new(AtomicUsize::new(0));
    let counter = Arc::clone(&calls);
    let solve_fn: SolveFn = Arc::new(
        move |job: &SolveRequest, observer: &mut dyn SolveObserver| {
            if counter.fetch_add(1, Ordering::SeqCst) == 0 {
                // Panics inside the solve, on a rayon worker.
                job.run(&mut PanicOnIteration)
            } else {
                job.run(observer)
            }
        },
    );
    let mut worker = Worker::spawn_with(Box::new(|| {}), solve_fn).expect("spawn");
    let job = worker.submit(sombrero_request(32));
    let error = failure(events_until_end(&mut worker, job).last()).to_owned();
    assert!(error.contains("injected fault at level 0"), "{error}");
    let job = worker.submit(tiny_request());
    let error = failure(events_until_end(&mut worker, job).last()).to_owned();
    assert!(error.contains("1x1"), "{error}");
    // Invalid parameters: no level sizes (the pyramid would not end).
    let mut request = sombrero_request(32);
    request.params.eta = 1.0;
    let job = worker.submit(request);
    let events = events_until_end(&mut worker, job);
    let Event::Started { level_sizes, .. } = &events[0] else {
        panic!("first event is {}", kind(Some(&events[0])));
    };
    assert!(level_sizes.is_empty());
    assert!(failure(events.last()).contains("eta"));
    let job = worker.submit(sombrero_request(32));
    assert!(finished(events_until_end(&mut worker, job).last()));
    assert_eq!(calls.load(Ordering::SeqCst), 4);
}

#[test]
fn dropping_the_worker_during_a_solve_joins_the_thread() {
    let (mut worker, _) = spawn_counting();
    let job = worker.submit(sombrero_request(192));
    wait_for_progress(&mut worker, job);
    let (done_sender, done) = bounded(1);
    thread::spawn(move || {
        drop(worker);
        done_sender.send(()).expect("test receiver alive");
    });
    assert!(done.recv_timeout(PATIENCE).is_ok(), "drop hung");
}

#[test]
fn a_ui_that_does_not_drain_cannot_block_submit_forever() {
    let (worker, _) = spawn_counting();
    // Far more jobs than both channels hold, submitted without draining:
    // the thread drops stale events instead of waiting for the UI.
    let (back_sender, back) = bounded(1);
    thread::spawn(move || {
        let mut worker = worker;
        let mut last = None;
        for _ in 0..4 * (COMMAND_CAPACITY + EVENT_CAPACITY) {
            last = Some(worker.submit(tiny_request()));
        }
        back_sender
            .send((worker, last))
            .expect("test receiver alive");
    });
    let Ok((mut worker, Some(last))) = back.recv_timeout(PATIENCE) else {
        panic!("submit blocked for {PATIENCE:?}");
    };
    failure(events_until_end(&mut worker, last).last());
    assert!(!worker.is_busy());
}

#[test]
fn drain_yields_at_least_one_event_and_stops_at_the_budget() {
    let (mut worker, _) = spawn_counting();
    let job = worker.submit(tiny_request());
    let deadline = Instant::now() + PATIENCE;
    while worker.events.len() < 2 {
        assert!(Instant::now() < deadline, "Started and Failed did not come");
        thread::sleep(Duration::from_millis(1));
    }
    let first: Vec<Event> = worker.drain(Duration::ZERO).collect();
    assert!(matches!(first[..], [Event::Started { .. }]) && worker.is_busy());
    let rest: Vec<Event> = worker.drain(Duration::from_secs(1)).collect();
    assert!(rest.len() == 1 && rest[0].job() == job);
    failure(rest.first());
    assert!(!worker.is_busy());
}

/// The synthetic set written as files, read through the photo
/// pipeline as the viewer reads it.
fn set_request(dir: &std::path::Path) -> SetRequest {
    let images = crate::test_sets::write_set(dir);
    let input = sfs_core::photo::PhotoInput {
        camera: sfs_core::photo::CameraSpec::File(dir.join("scene.json")),
        lights: sfs_core::photo::LightSpec::CameraFileOrCentred,
        object_mask: Some(dir.join("mask.png")),
        photometric_stereo: true,
        images,
        ..sfs_core::photo::PhotoInput::new(dir.join("led1.png"))
    };
    let prepared = sfs_core::photo::prepare(&input).unwrap_or_else(|e| panic!("{e}"));
    let problem =
        sfs_core::photo::photometric_problem(&prepared, &input).unwrap_or_else(|e| panic!("{e}"));
    SetRequest {
        problem,
        params: PhotometricParams::default(),
    }
}

#[test]
fn a_set_streams_its_levels_and_finishes_with_depth_normals_and_albedo() {
    let dir = tempfile::tempdir().expect("temp dir");
    let request = set_request(dir.path());
    assert_eq!(request.problem.photos.len(), crate::test_sets::PHOTOS);
    let (mut worker, _) = spawn_counting();
    let job = worker.submit_set(request.clone());
    let events = events_until_end(&mut worker, job);
    let Some(Event::Started { level_sizes, .. }) = events.first() else {
        panic!("first event is {}", kind(events.first()));
    };
    let side = crate::test_sets::SIDE;
    assert_eq!(level_sizes.last(), Some(&(side, side)));
    let levels = streamed_levels(&events);
    assert!(!levels.is_empty(), "no level streamed");
    assert!(levels.windows(2).all(|p| p[0].level < p[1].level));
    assert_eq!(levels.last().map(|l| l.depth.size()), Some((side, side)));
    let Some(Event::SetFinished { solution, .. }) = events.last() else {
        panic!("last event is {}", kind(events.last()));
    };
    assert_eq!(solution.depth.size(), (side, side));
    assert_eq!(solution.photos.len(), crate::test_sets::PHOTOS);
    let object = request.problem.object_mask.as_ref().expect("mask.png read");
    let on_object = |k: usize| *object.as_slice().get(k).unwrap_or(&false);
    let solved = solution
        .depth
        .as_slice()
        .iter()
        .zip(solution.normals.as_slice())
        .zip(solution.albedo.as_slice())
        .enumerate()
        .filter(|(k, ((z, n), a))| {
            on_object(*k) && z.is_finite() && **z > 0.0 && n[2].is_finite() && a.is_finite()
        })
        .count();
    let inside = object.as_slice().iter().filter(|&&o| o).count();
    assert!(
        solved * 10 > inside * 9,
        "{solved} of {inside} object pixels solved"
    );
    // A newer set supersedes it; a cancelled one says so.
    let old = worker.submit_set(request.clone());
    worker.cancel(old);
    let events = events_until_end(&mut worker, old);
    assert!(
        matches!(events.last(), Some(Event::Cancelled { .. })),
        "{}",
        kind(events.last())
    );
    // A set that cannot be solved fails with a message; the worker lives on.
    let mut broken = request;
    broken.problem.photos.truncate(1);
    let job = worker.submit_set(broken);
    let error = failure(events_until_end(&mut worker, job).last()).to_owned();
    assert!(error.contains("at least 2"), "{error}");
    let job = worker.submit(sombrero_request(32));
    assert!(finished(events_until_end(&mut worker, job).last()));
}
