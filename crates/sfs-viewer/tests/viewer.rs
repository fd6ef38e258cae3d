//! The real viewer under egui_kittest (wgpu on the CPU, no display): open the
//! sample by path, set alpha through its slider, paint and undo, solve to
//! completion with levels coarse to fine, bad input.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use eframe::egui;
use eframe::egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use sfs_viewer::app::{Export, Panel2d, ViewerApp, ViewerOptions, sample_image_path};

fn options(data_dir: &std::path::Path) -> ViewerOptions {
    ViewerOptions {
        image: sample_image_path(),
        data_dir: Some(data_dir.to_path_buf()),
        fresh_settings: true,
        ..ViewerOptions::default()
    }
}

fn harness(options: ViewerOptions) -> Harness<'static, ViewerApp> {
    Harness::builder()
        .with_size(egui::vec2(1280.0, 800.0))
        .wgpu()
        .build_eframe(move |cc| ViewerApp::new(cc, options))
}

/// Steps the harness (real time passes between steps, so the worker runs)
/// until `done` or the deadline; a hang check, not a speed assertion.
fn step_until(harness: &mut Harness<'_, ViewerApp>, done: impl Fn(&ViewerApp) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while !done(harness.state()) {
        assert!(
            Instant::now() < deadline,
            "the viewer did not get there in 120 s"
        );
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The sample opened in a fresh data folder (returned: it lives as long as
/// the harness needs it), after one frame or, with `solved`, once its first
/// solve has finished.
fn the_sample(solved: bool) -> (tempfile::TempDir, Harness<'static, ViewerApp>) {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut harness = harness(options(dir.path()));
    if solved {
        step_until(&mut harness, |app| app.solve_state().finished().is_some());
    } else {
        harness.step();
    }
    (dir, harness)
}

/// What `what` takes from the finished solve, if there is one.
fn from_the_solve<T>(
    harness: &Harness<'_, ViewerApp>,
    what: impl FnOnce(&sfs_core::solver::Solution) -> Option<T>,
) -> Option<T> {
    harness.state().solve_state().finished().and_then(what)
}

/// Runs `change`, then steps until a solve other than the one running
/// before it has finished.
fn solve_after(
    harness: &mut Harness<'_, ViewerApp>,
    change: impl FnOnce(&mut Harness<'_, ViewerApp>),
) {
    let before = harness.state().solve_state().job;
    change(harness);
    step_until(harness, |app| {
        app.solve_state().job != before && app.solve_state().finished().is_some()
    });
}

/// Clicks the widget labelled `label` (through accesskit: it may lie below
/// the fold) and lets two frames pass.
fn click(harness: &mut Harness<'_, ViewerApp>, label: &str) {
    harness.get_by_label(label).click_accesskit();
    harness.step();
    harness.step();
}

/// The point `(dx, dy)` from the bottom-left corner of the input panel's
/// tab.
fn in_the_input(harness: &Harness<'_, ViewerApp>, dx: f32, dy: f32) -> egui::Pos2 {
    let tab = harness.get_by_label("input + mask").rect();
    egui::pos2(tab.left() + dx, tab.bottom() + dy)
}

/// Drags the pointer from `start` to `end` in eight moves: a brush stroke.
fn stroke(harness: &mut Harness<'_, ViewerApp>, start: egui::Pos2, end: egui::Pos2) {
    harness.hover_at(start);
    harness.step();
    harness.drag_at(start);
    harness.step();
    for k in 1..=8 {
        harness.hover_at(start + (end - start) * (k as f32 / 8.0));
        harness.step();
    }
    harness.drop_at(end);
    harness.step();
    harness.step();
}

/// Types `text` into the text field labelled `field` and confirms it with
/// the button labelled `button`.
fn enter(harness: &mut Harness<'_, ViewerApp>, field: &str, button: &str, text: &str) {
    harness
        .get_by_role_and_label(Role::TextInput, field)
        .set_text_value_accesskit(text);
    harness.step();
    click(harness, button);
}

/// Whether any label contains one of `texts`.
fn shows_any(harness: &Harness<'_, ViewerApp>, texts: &[&str]) -> bool {
    texts
        .iter()
        .any(|text| harness.query_by_label_contains(text).is_some())
}

/// Opens the sample again and returns the notice it leaves.
fn reopen_the_sample(harness: &mut Harness<'_, ViewerApp>) -> String {
    let ctx = harness.ctx.clone();
    let sample = sample_image_path().expect("sample");
    harness.state_mut().open(&ctx, &sample);
    harness.state().notice().unwrap_or_default().to_string()
}

/// Steps until the comparison of a single photograph with the set is done
/// and asserts it did not fail.
fn until_compared(harness: &mut Harness<'_, ViewerApp>) {
    step_until(harness, |app| {
        let c = app.compare_state();
        !c.running && (c.comparison.is_some() || c.failure.is_some())
    });
    let compare = harness.state().compare_state();
    assert!(compare.failure.is_none(), "{:?}", compare.failure);
}

#[test]
fn solves_the_sample_and_streams_its_levels_and_reports_errors() {
    let (dir, mut harness) = the_sample(true);
    let app = harness.state();
    // The default: the fast-marching start, then the refined surface.
    let sizes = &app.solve_state().arrived;
    assert_eq!(sizes, &vec![(256, 256); 2], "levels: {sizes:?}");
    let (rse, rie) = app
        .solve_state()
        .errors
        .expect("the sample has ground truth");
    assert!(rse < 0.02 && rie < 0.03, "rse {rse} rie {rie}");
    // "done in" is the whole wait, which holds the final solve.
    let solve_seconds = app.solve_state().finished().map(|s| s.seconds);
    let waited = app.solve_state().waited_seconds;
    assert!(
        waited.zip(solve_seconds).is_some_and(|(w, s)| w >= s),
        "waited {waited:?}, the solve {solve_seconds:?}"
    );
    // Every export writes a readable file.
    let app = harness.state_mut();
    for (name, what) in [
        ("depth.npy", Export::DepthNpy),
        ("depth16.png", Export::DepthPng),
        ("mesh.ply", Export::MeshPly),
        ("mesh.obj", Export::MeshObj),
        ("reprojection.png", Export::Reprojection),
    ] {
        let path = dir.path().join(name);
        app.export(&path, what);
        let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        assert!(
            size > 1000,
            "{name}: {size} bytes, notice {:?}",
            app.notice()
        );
    }
    let depth = sfs_core::io::read_npy(&dir.path().join("depth.npy")).expect("npy");
    assert_eq!(depth.size(), (256, 256));
    let obj = std::fs::read_to_string(dir.path().join("mesh.obj")).expect("obj");
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("v ")).count(),
        256 * 256
    );
}

#[test]
fn alpha_slider_changes_the_parameter_and_starts_a_new_solve() {
    let (_dir, mut harness) = the_sample(false);
    let first_job = harness.state().solve_state().job;
    assert!(first_job.is_some());
    harness
        .get_by_role_and_label(Role::Slider, "alpha")
        .set_value_accesskit(2.5e-7);
    harness.step();
    assert_eq!(
        harness.state().params().to_params().alpha,
        sfs_core::params::Alpha::Value(2.5e-7)
    );
    // After the debounce a new job replaces the first one.
    step_until(&mut harness, |app| app.solve_state().job != first_job);
    step_until(&mut harness, |app| app.solve_state().finished().is_some());
}

/// The open document's confidence mask.
fn confidence(harness: &Harness<'_, ViewerApp>) -> sfs_core::grid::Grid<f32> {
    harness
        .state()
        .document()
        .expect("sample open")
        .masks
        .confidence()
        .clone()
}

#[test]
fn painting_changes_the_mask_and_undo_restores_it() {
    let (_dir, mut harness) = the_sample(false);
    let before = confidence(&harness);
    // A stroke across the middle of the image panel.
    let start = in_the_input(&harness, 120.0, 250.0);
    stroke(&mut harness, start, start + egui::vec2(120.0, 40.0));
    let doc = harness.state().document().expect("sample open");
    let painted = doc
        .masks
        .confidence()
        .as_slice()
        .iter()
        .filter(|&&c| c < 1.0)
        .count();
    assert!(painted > 50, "the stroke painted {painted} pixels");
    assert!(doc.masks.can_undo());
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.step();
    let after = confidence(&harness);
    assert_eq!(after, before);
    // Redo brings the stroke back.
    harness.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    harness.step();
    assert_ne!(
        harness.state().document().expect("open").masks.confidence(),
        &before
    );
}

#[test]
fn bad_files_leave_the_open_image_and_say_why() {
    let (dir, mut harness) = the_sample(false);
    let bad = dir.path().join("broken.png");
    std::fs::write(&bad, b"not a png").expect("write");
    let wrong_mask = dir.path().join("mask-small.png");
    image::GrayImage::new(10, 10)
        .save(&wrong_mask)
        .expect("write mask");
    let camera = dir.path().join("camera.json");
    std::fs::write(&camera, br#"{"width": 256}"#).expect("write");
    let ctx = harness.ctx.clone();
    let app = harness.state_mut();
    let sample: PathBuf = app.document().expect("open").path.clone();
    for (path, expect) in [
        (&bad, "broken.png"),
        (&wrong_mask, "mask-small.png"),
        (&camera, "camera.json"),
    ] {
        app.drop_file(&ctx, path);
        let notice = app.notice().unwrap_or_default().to_string();
        assert!(notice.contains(expect), "{expect}: {notice}");
        assert_eq!(app.document().expect("still open").path, sample);
    }
    harness.step();
}

#[test]
fn the_fit_is_reported_and_suggested_confidence_is_one_undoable_edit() {
    let (_dir, mut harness) = the_sample(true);
    // The sample fits the model: a summary, no warning.
    let fit = harness
        .state()
        .solve_state()
        .fit()
        .cloned()
        .expect("a model-fit summary after the solve");
    assert!(fit.rie_trusted < 0.05, "{fit:?}");
    assert!(fit.warnings.is_empty(), "{fit:?}");
    // Measured once per result: the Sombrero has no occluding contour.
    let contours = harness
        .state()
        .solve_state()
        .occlusion_edges()
        .cloned()
        .expect("occluding contours measured with the fit");
    assert!(!contours.as_slice().iter().any(|&on| on));
    assert_eq!(fit.occlusion_edge_share, 0.0);
    harness.get_by_label("contours");
    // The fit in one line: the sample is explained, no warning.
    harness.get_by_label_contains("fit good: RIE");
    // The albedo is estimated by default (a photograph's default) and the
    // uniform sample's estimate is not used: its solve is albedo 1's.
    let albedo =
        from_the_solve(&harness, |s| s.albedo_fit.clone()).expect("albedo auto reports its fit");
    assert!(!albedo.used, "{}", albedo.summary);
    // What the surface carries as its albedo texture: 1 wherever solved.
    let surface = harness
        .state()
        .surface_albedo()
        .expect("a single solve's albedo");
    assert!(surface.as_slice().iter().any(|a| a.is_finite()));
    assert!(
        surface
            .as_slice()
            .iter()
            .filter(|a| a.is_finite())
            .all(|&a| a == 1.0)
    );
    harness.get_by_label("estimate the albedo");
    // The 2-D panels' "albedo" tab, beside the photo section's albedo file
    // and the 3-D view's texture choice.
    assert_eq!(harness.query_all_by_label("albedo").count(), 3);
    let before = confidence(&harness);
    // (below the fold of the controls since the Mask section grew the
    // shadows box: accesskit)
    click(&mut harness, "suggest confidence");
    let suggested = confidence(&harness);
    let lowered = suggested
        .as_slice()
        .iter()
        .zip(before.as_slice())
        .filter(|(a, b)| a < b)
        .count();
    assert!(lowered > 0, "the suggestion lowered nothing");
    assert!(
        suggested
            .as_slice()
            .iter()
            .zip(before.as_slice())
            .all(|(a, b)| a <= b),
        "a suggestion only lowers the confidence"
    );
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.step();
    assert_eq!(confidence(&harness), before, "undo rejects the suggestion");
}

#[test]
fn a_screenshot_run_records_why_it_failed() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A run of `image` that takes the screenshot `shot`, and its report.
    let screenshot_run = |image: PathBuf, shot: &str| {
        let failure = sfs_viewer::app::ExitReport::default();
        let harness = harness(ViewerOptions {
            image: Some(image),
            screenshot: Some(dir.path().join(shot)),
            failure: failure.clone(),
            ..options(dir.path())
        });
        (harness, failure)
    };
    // Not an image: nothing opens, the run must fail with the reason.
    let text = dir.path().join("text.png");
    std::fs::write(&text, "hello").expect("write");
    let (mut first, failure) = screenshot_run(text, "shot.png");
    for _ in 0..10 {
        first.step();
    }
    let message = failure.get().expect("a failure is recorded");
    assert!(message.contains("text.png"), "{message}");

    // A black image opens but cannot be solved: the reason is recorded.
    let black = dir.path().join("black.png");
    sfs_core::io::write_png8(&black, &sfs_core::grid::Grid::filled(16, 16, 0.0)).expect("write");
    let (mut harness, failure) = screenshot_run(black, "shot2.png");
    step_until(&mut harness, |app| app.solve_state().failure.is_some());
    harness.step();
    let message = failure.get().expect("a failure is recorded");
    assert!(message.contains("black"), "{message}");
}

#[test]
fn an_image_wider_than_the_texture_limit_opens() {
    let dir = tempfile::tempdir().expect("temp dir");
    let wide = dir.path().join("wide.png");
    let image =
        sfs_core::grid::Grid::from_fn(9000, 6, |c, r| 0.2 + 0.5 * ((c + r) % 7) as f64 / 7.0);
    sfs_core::io::write_png8(&wide, &image).expect("write");
    let mut harness = harness(ViewerOptions {
        image: Some(wide),
        max_side: Some(0),
        ..options(dir.path())
    });
    step_until(&mut harness, |app| app.solve_state().completed_jobs > 0);
    harness.step();
    assert_eq!(
        harness.state().document().map(|d| d.size()),
        Some((9000, 6))
    );
}

#[test]
fn the_input_shows_the_photograph_as_it_looks_and_hovering_reads_linear_values() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A dark linear image, as a photograph is: 0.02 with a square of 0.05.
    let path = dir.path().join("dark.png");
    let image = sfs_core::grid::Grid::from_fn(64, 48, |c, r| {
        if (16..48).contains(&c) && (12..36).contains(&r) {
            0.05
        } else {
            0.02
        }
    });
    sfs_core::io::write_png16(&path, &image).expect("write");
    let mut harness = harness(ViewerOptions {
        image: Some(path),
        ..options(dir.path())
    });
    harness.step();
    // The document (what the solver gets) keeps the linear values.
    let doc = harness.state().document().expect("open");
    let largest_change = doc
        .image
        .zip_map(&image, |a, b| (a - b).abs())
        .as_slice()
        .iter()
        .copied()
        .fold(0.0, f64::max);
    assert!(largest_change < 1e-4, "{largest_change}");
    // Shown with the exposure that makes the 99th percentile (0.05) white.
    harness.get_by_label("shown ×20, sRGB");
    // Hovering the image reads the linear value, not the displayed one
    // (once the solve is done: its result adds the albedo tab's row, which
    // moves the image down; so down the panel until the readout appears).
    step_until(&mut harness, |app| app.solve_state().finished().is_some());
    let tab = harness.get_by_label("input + mask").rect();
    let linear = (1..16).any(|k| {
        harness.hover_at(egui::pos2(
            tab.left() + 200.0,
            tab.bottom() + 25.0 * k as f32,
        ));
        harness.step();
        harness.step();
        shows_any(&harness, &["I 0.0500", "I 0.0200"])
    });
    assert!(linear, "no linear value in the hover readout");
}

#[test]
fn the_start_selector_says_what_is_used_with_lights_off_the_centre() {
    let (dir, mut harness) = the_sample(false);
    let plane = "fast marching (in the lights' frame)";
    harness.get_by_label("fast marching");
    assert!(harness.query_by_label(plane).is_none());
    // The sample's camera with one light beside the camera.
    let camera = dir.path().join("camera.json");
    std::fs::write(
        &camera,
        br#"{"width": 256, "height": 256, "focal": 256.0, "cx": 127.5, "cy": 127.5,
            "intensity_scale": 2.0, "lights": [{"position": [1.0, 0.0, 0.0]}]}"#,
    )
    .expect("write");
    let ctx = harness.ctx.clone();
    harness.state_mut().drop_file(&ctx, &camera);
    assert_eq!(harness.state().notice(), None);
    harness.step();
    harness.get_by_label(plane);
    harness.get_by_label("from image (lights off the centre: best-fitting plane)");
    // With the lights switched off the solve has the paper's centred light
    // (the check box may lie below the fold of the controls: accesskit).
    click(&mut harness, "solve with the lights where they are");
    harness.get_by_label("fast marching");
    assert!(harness.query_by_label(plane).is_none());
}

#[test]
fn the_shadow_the_solve_took_out_is_shown_and_suggested() {
    // A Sombrero lit 40 degrees off the axis with cast shadows, its camera
    // file (with the light) beside it, as `synth --shadows` writes them.
    let dir = tempfile::tempdir().expect("temp dir");
    let a = 40f64.to_radians();
    let light = sfs_core::light::PointLight {
        position: [2.0 * a.sin(), 0.0, 2.0 * (1.0 - a.cos())],
        ..sfs_core::light::PointLight::CENTRED
    };
    let (scene, truth) = sfs_core::scene::shadow::with_cast_shadows(
        |lights: &[sfs_core::light::PointLight]| {
            Ok::<_, ()>(sfs_core::scene::sombrero::sombrero_lit(96, 96, lights))
        },
        &[light],
    )
    .expect("renders");
    let image = dir.path().join("image16.png");
    sfs_core::io::write_png16(&image, &scene.image).expect("write");
    std::fs::write(
        dir.path().join("scene.json"),
        format!(
            r#"{{"width": 96, "height": 96, "focal": 96.0, "cx": 47.5, "cy": 47.5,
                "intensity_scale": {}, "lights": [{{"position": {:?}}}]}}"#,
            scene.intensity_scale, light.position
        ),
    )
    .expect("write");
    let mut harness = harness(ViewerOptions {
        image: Some(image.clone()),
        ..options(dir.path())
    });
    step_until(&mut harness, |app| app.solve_state().finished().is_some());
    let shadow = from_the_solve(&harness, |s| s.shadow.clone())
        .expect("a light off the axis: the solve reports its shadow");
    let found = shadow.as_slice().iter().filter(|&&s| s).count();
    let agree = shadow
        .as_slice()
        .iter()
        .zip(truth.as_slice())
        .filter(|(a, b)| a == b)
        .count();
    assert!(found > 100, "the shadow is found: {found} pixels");
    assert!(
        agree as f64 >= 0.99 * (96.0 * 96.0),
        "{agree} of 9216 agree"
    );
    harness.get_by_label_contains("of the object taken out of the data term");
    harness.get_by_label("shadows");
    // Suggest confidence proposes the same pixels at 0.
    click(&mut harness, "suggest confidence");
    let suggested = confidence(&harness);
    for (q, &s) in shadow.as_slice().iter().enumerate() {
        if s {
            assert_eq!(suggested.as_slice()[q], 0.0, "pixel {q} is shadow");
        }
    }
}

#[test]
fn a_known_distance_is_picked_typed_solved_to_and_restored() {
    let (_dir, mut harness) = the_sample(true);
    // "Set distance", then a click on the object in the input panel.
    harness.get_by_label("Set distance").click_accesskit();
    harness.step();
    let at = in_the_input(&harness, 120.0, 250.0);
    harness.hover_at(at);
    harness.step();
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
    }
    harness.step();
    harness.step();
    let picked = harness
        .query_all_by_label_contains("pixel (")
        .any(|node| node.value().is_some_and(|v| v.starts_with("pixel (")));
    assert!(picked, "no pixel was picked");
    // A distance that is not positive is refused, nothing changes.
    for bad in ["-5", "0", "NaN", "far"] {
        enter(&mut harness, "distance", "OK", bad);
        let refused = shows_any(&harness, &["must be a positive number", "is not a number"]);
        assert!(refused, "{bad} was not refused with a message");
        let doc = harness.state().document().expect("open");
        assert!(doc.known_depths.is_empty(), "{bad} was taken");
    }
    // The change re-solves; the fit comes with the result.
    solve_after(&mut harness, |harness| {
        enter(harness, "distance", "OK", "3.0")
    });
    let doc = harness.state().document().expect("open");
    assert_eq!(doc.known_depths.len(), 1);
    let point = doc.known_depths[0];
    assert_eq!(point.depth, 3.0);
    let (c, r) = doc.working_pixel(point.column_px, point.row_px);
    let solve = harness.state().solve_state();
    let fit = solve.known_depth_fit().expect("the fit is reported");
    assert_eq!(fit.points.len(), 1);
    let solved = *solve
        .finished()
        .expect("finished")
        .depth
        .at(c as usize, r as usize);
    assert!((solved - 3.0).abs() < 0.005 * 3.0, "solved {solved}");
    harness.step();
    harness.get_by_label_contains("from 1 known distance; residuals");
    harness.get_by_label_contains("3.000 depth units, solved 3.0");
    // Kept beside the masks' autosave: reopening the image restores it.
    let notice = reopen_the_sample(&mut harness);
    let app = harness.state();
    assert_eq!(app.document().expect("open").known_depths, vec![point]);
    assert!(notice.contains("restored 1 known distance"), "{notice}");
    // Removed, it is gone, and the next solve has no fit.
    harness.step();
    click(&mut harness, "remove");
    assert!(
        harness
            .state()
            .document()
            .expect("open")
            .known_depths
            .is_empty()
    );
    step_until(&mut harness, |app| app.solve_state().finished().is_some());
    assert!(harness.state().solve_state().known_depth_fit().is_none());
}

/// The object's distance typed in the Known distance section: refused when
/// it is not a positive number, else the next solve meets it (the sample's
/// light is centred: exactly, by rescaling) and says which cue set the
/// unit; reopening the image restores it, and "Clear" forgets it.
#[test]
fn an_object_distance_is_typed_solved_to_and_restored() {
    let (_dir, mut harness) = the_sample(true);
    for bad in ["-5", "0", "far"] {
        enter(&mut harness, "object distance", "Set", bad);
        let refused = shows_any(
            &harness,
            &["must be a positive distance", "is not a number"],
        );
        assert!(refused, "{bad} was not refused with a message");
        let doc = harness.state().document().expect("open");
        assert_eq!(doc.object_distance, None, "{bad} was taken");
    }
    solve_after(&mut harness, |harness| {
        enter(harness, "object distance", "Set", "4.5");
        assert_eq!(
            harness.state().document().expect("open").object_distance,
            Some(4.5)
        );
    });
    let solve = harness.state().solve_state();
    let unit = solve.depth_unit().expect("the depth unit is said");
    assert_eq!(
        unit.source,
        sfs_core::solver::depth_unit::UnitSource::Distance
    );
    assert!((unit.solved_distance - 4.5).abs() < 1e-9, "{unit:?}");
    harness.step();
    harness.get_by_label_contains("depth unit from the given object distance");
    // Kept beside the known distances: reopening the image restores it.
    let notice = reopen_the_sample(&mut harness);
    let app = harness.state();
    assert_eq!(app.document().expect("open").object_distance, Some(4.5));
    assert!(notice.contains("restored the object distance"), "{notice}");
    harness.step();
    click(&mut harness, "Clear");
    assert_eq!(
        harness.state().document().expect("open").object_distance,
        None
    );
}

/// Whether the parameter slider labelled `label` is shown.
fn has_slider(harness: &Harness<'_, ViewerApp>, label: &str) -> bool {
    harness
        .query_by_role_and_label(Role::Slider, label)
        .is_some()
}

/// Chooses `word` in the reflectance selector.
fn choose_reflectance(harness: &mut Harness<'_, ViewerApp>, word: &str) {
    // (a pointer click: accesskit's does not open the popup)
    harness
        .get_by_role_and_label(Role::ComboBox, "reflectance")
        .click();
    harness.step();
    harness.step();
    // (in the popup, a button: alpha's "auto" is a check box)
    harness
        .get_by_role(Role::ListBox)
        .get_by_role_and_label(Role::Button, word)
        .click();
    harness.step();
    harness.step();
}

/// [`choose_reflectance`], then waits for the new solve it starts to
/// finish.
fn choose_and_solve(harness: &mut Harness<'_, ViewerApp>, word: &str) {
    solve_after(harness, |harness| choose_reflectance(harness, word));
    harness.step();
}

#[test]
fn the_reflectance_selector_shows_the_chosen_models_sliders_and_the_result_says_what_was_used() {
    use sfs_core::material::Material;
    use sfs_core::params::ReflectanceChoice;
    let (_dir, mut harness) = the_sample(true);
    harness.step();
    // Lambert, the default: no model's parameters, nothing said.
    for label in ["roughness (rad)", "specular k_s", "shininess n"] {
        assert!(!has_slider(&harness, label), "{label} shown with Lambert");
    }
    assert!(harness.query_by_label_contains("reflectance:").is_none());
    // Blinn-Phong: its two sliders, which set its parameters.
    choose_reflectance(&mut harness, "blinn-phong");
    let params = harness.state().params().to_params();
    assert_eq!(params.reflectance, ReflectanceChoice::BlinnPhong);
    assert!(has_slider(&harness, "specular k_s") && has_slider(&harness, "shininess n"));
    assert!(!has_slider(&harness, "roughness (rad)"));
    harness
        .get_by_role_and_label(Role::Slider, "shininess n")
        .set_value_accesskit(50.0);
    harness.step();
    assert_eq!(harness.state().params().to_params().shininess, 50.0);
    // Oren-Nayar: its roughness instead; the solve says what it used.
    choose_and_solve(&mut harness, "oren-nayar");
    assert!(has_slider(&harness, "roughness (rad)"));
    assert!(!has_slider(&harness, "shininess n") && !has_slider(&harness, "specular k_s"));
    let solution = harness.state().solve_state().finished().expect("solved");
    assert_eq!(
        solution.material,
        Material::OrenNayar { roughness_rad: 0.3 }
    );
    harness.get_by_label("reflectance: oren-nayar (roughness 0.300 rad)");
    assert!(harness.query_by_label_contains("material fit (").is_none());
    // Auto: fitted, the finding and the candidates reported.
    choose_and_solve(&mut harness, "auto");
    let fit = from_the_solve(&harness, |s| s.material_fit.clone()).expect("auto reports its fit");
    assert!(!has_slider(&harness, "roughness (rad)"));
    harness.get_by_label_contains("material fit (");
    harness.get_by_label_contains(&fit.summary);
    harness.get_by_label(&format!("best 5 of {} candidates", fit.trials.len()));
}

#[path = "../src/test_sets.rs"]
mod test_sets;

/// Paints a stroke across the middle of the input panel.
fn stroke_across_the_input(harness: &mut Harness<'_, ViewerApp>) {
    // (the 48x48 image fills the panel's width, centred in its height)
    let start = in_the_input(harness, 40.0, 330.0);
    stroke(harness, start, start + egui::vec2(150.0, 40.0));
}

#[test]
fn a_set_folder_opens_as_one_document_solves_and_shows_its_panels() {
    let dir = tempfile::tempdir().expect("temp dir");
    let set = tempfile::tempdir().expect("temp dir");
    let images = test_sets::write_set(set.path());
    let mut harness = harness(ViewerOptions {
        image: Some(set.path().to_path_buf()),
        ..options(dir.path())
    });
    harness.step();
    let app = harness.state();
    let doc = app.document().expect("the set opens");
    assert_eq!(
        doc.set.as_ref().map(|s| s.paths.clone()),
        Some(images.clone())
    );
    step_until(&mut harness, |app| app.solve_state().set.is_some());
    let app = harness.state();
    let solution = app.solve_state().set.as_ref().expect("solved");
    assert_eq!(solution.photos.len(), test_sets::PHOTOS);
    assert!(!app.solve_state().arrived.is_empty(), "levels streamed");
    assert!(app.solve_state().failure.is_none());
    // The fit table names each photograph; the set's panels show.
    harness.get_by_label("led3.png");
    for (panel, caption) in [
        (
            Panel2d::Normals,
            "normals: red = right, green = up, blue = towards the camera",
        ),
        (
            Panel2d::PhotoResidual,
            "residual I − R of led1.png under its own light",
        ),
    ] {
        harness.state_mut().show_panel(panel);
        harness.step();
        // (a label and its text run)
        assert!(
            harness.query_all_by_value(caption).next().is_some(),
            "{caption}"
        );
    }
    harness.state_mut().show_panel(Panel2d::Albedo);
    harness.step();
    // The albedo on the surface (rebuilds the last level), then a
    // photograph's own layer painted with the brush reaches the problem.
    harness.state_mut().settings_mut().view.photo_texture = true;
    harness.state_mut().settings_mut().view.albedo_texture = true;
    harness.step();
    harness.state_mut().show_panel(Panel2d::Input);
    harness.state_mut().paint_photo(Some(2));
    harness.step();
    stroke_across_the_input(&mut harness);
    let problem = harness.state().set_problem().expect("a set");
    let own = problem.photos[2]
        .confidence
        .as_ref()
        .expect("its own layer");
    assert!(own.as_slice().iter().any(|&c| c < 1.0));
    assert!(problem.photos[0].confidence.is_none());
    assert!(problem.confidence.is_none(), "the set-wide layer untouched");
    // The edit re-solves the set; then photograph 1 alone, compared.
    step_until(&mut harness, |app| {
        app.solve_state().set.is_some() && !app.solve_state().running
    });
    harness.state_mut().solve_single(0);
    until_compared(&mut harness);
    let compare = harness.state().compare_state();
    let c = compare.comparison.as_ref().expect("compared");
    assert!(c.pixels > 100 && c.rse_to_set.is_finite(), "{c:?}");
    assert!(!compare.with_set_albedo);
    let alone = c.mean_normal_angle_deg;
    harness.state_mut().show_panel(Panel2d::SingleDifference);
    harness.step();
    // The same photograph with the set's albedo divided out: compared too.
    harness.state_mut().solve_single_with_set_albedo(0);
    until_compared(&mut harness);
    let compare = harness.state().compare_state();
    assert!(compare.with_set_albedo);
    let c = compare.comparison.as_ref().expect("compared");
    assert!(
        c.pixels > 100 && c.mean_normal_angle_deg.is_finite(),
        "{c:?} (alone: {alone})"
    );
    harness.get_by_label("use the albedo from photometric stereo");

    // Several photographs given at once: the same set.
    harness
        .state_mut()
        .open_paths(&egui::Context::default(), &images[..3]);
    let doc = harness.state().document().expect("open");
    assert_eq!(doc.set.as_ref().map(|s| s.paths.len()), Some(3));
}
