//! The viewer: an eframe (wgpu) application for loading an image, painting
//! masks, tuning parameters while a worker thread solves, and inspecting the
//! levels as they arrive in 2-D and 3-D. The only module that uses egui.
//!
//! [`ViewerApp`] only wires four parts together, each with one job:
//! - `session`: the open document (image, camera, masks, their autosave) and
//!   its solve (worker, debounce, the job's state);
//! - `level_prep`: the thread that turns each level into meshes and panel
//!   images;
//! - `panels`: the drawing (menu, controls, 2-D panels, 3-D view), which
//!   edits the document in place and returns [`Action`]s for the rest;
//! - `measure`: screenshots, frame statistics and latency trials.

mod document;
mod energy_plot;
mod images;
mod level_prep;
mod measure;
mod panels;
mod session;
mod settings;
mod view3d;

use std::path::{Path, PathBuf};
use std::time::Instant;

use eframe::egui;

use crate::mask_edit::Layer;
use crate::worker::Worker;
use sfs_core::params::Alpha;

pub use document::{
    CameraSource, CameraState, Document, KnownDistance, OpenOptions, PhotoSet, sample_image_path,
    set_images_in,
};
pub use measure::ExitReport;
pub use panels::{Action, Panel2d};
pub use session::{CompareState, EnergyPoint, Export, LevelView, Progress, SolveState, per_pixel};
pub use settings::{InitialChoice, ParamSettings, SetParamSettings, Settings, Tool};

/// eframe application id (storage folder name).
pub const APP_ID: &str = "sfs-studio";

/// How the viewer starts.
#[derive(Clone, Debug, Default)]
pub struct ViewerOptions {
    /// Image to open (`None`: the built-in sample), or a folder holding a
    /// photometric-stereo set.
    pub image: Option<PathBuf>,
    /// Further photographs: with `image`, one photometric-stereo set.
    pub set_images: Vec<PathBuf>,
    /// The 2-D panel shown first (`None`: the input).
    pub panel: Option<Panel2d>,
    /// Show the albedo (a set's or a single solve's) on the surface (the
    /// 3-D view's texture).
    pub albedo_texture: bool,
    /// How to read the image: its camera file, mask, ambient frame,
    /// vignetting, albedo map, confidence mask and sRGB choice (the sRGB
    /// choice also for File > Open later). Its `max_side` is not read: the
    /// working size is [`max_side`](Self::max_side).
    pub open: OpenOptions,
    /// Alpha override.
    pub alpha: Option<Alpha>,
    /// Working-size override (longest side in pixels, 0 = full size).
    pub max_side: Option<usize>,
    /// Save a screenshot here when the first solve has finished, then exit.
    pub screenshot: Option<PathBuf>,
    /// Write frame-time statistics here on exit (JSON); with
    /// `latency_trials`, also the time from a parameter change to the first
    /// new level on screen.
    pub stats: Option<PathBuf>,
    /// Parameter changes to time after the first solve (with `stats`).
    pub latency_trials: usize,
    /// Folder for the mask autosaves (`None`: eframe's storage folder).
    pub data_dir: Option<PathBuf>,
    /// Ignore persisted settings (tests).
    pub fresh_settings: bool,
    /// Where a `--screenshot` run leaves why it failed (the image did not
    /// open, the solve failed, the screenshot was not saved), for the
    /// command to exit non-zero with it once the window has closed.
    pub failure: ExitReport,
}

/// The viewer application.
pub struct ViewerApp {
    options: ViewerOptions,
    settings: Settings,
    session: session::Session,
    levels: level_prep::LevelPrep,
    panels: panels::Panels,
    measure: measure::Measurement,
    notice: Option<String>,
}

impl ViewerApp {
    /// Builds the app: settings from storage, the worker, the level
    /// preparation, the 3-D renderer, and the first document (the sample or
    /// `options.image`).
    pub fn new(cc: &eframe::CreationContext<'_>, options: ViewerOptions) -> Self {
        let mut settings: Settings = if options.fresh_settings {
            Settings::default()
        } else {
            cc.storage
                .and_then(|s| eframe::get_value(s, settings::STORAGE_KEY))
                .unwrap_or_default()
        };
        if let Some(alpha) = options.alpha {
            settings.params.update(|p| p.alpha = alpha);
        }
        if let Some(max_side) = options.max_side {
            settings.max_side = max_side;
        }
        if options.albedo_texture {
            settings.view.photo_texture = true;
            settings.view.albedo_texture = true;
        }
        let ctx = cc.egui_ctx.clone();
        let waker = move || ctx.request_repaint();
        let mut notice = None;
        let (single, set) = solver_leaving_a_core();
        let worker = match Worker::spawn_with_set(Box::new(waker.clone()), single, set) {
            Ok(w) => Some(w),
            Err(e) => {
                notice = Some(format!("cannot start the solver thread: {e}"));
                None
            }
        };
        let (levels, _) = level_prep::LevelPrep::spawn(waker);
        let available = match cc.wgpu_render_state.as_ref() {
            Some(rs) => view3d::install(rs),
            None => Err("3-D view needs the wgpu renderer".into()),
        };
        let data_dir = options
            .data_dir
            .clone()
            .or_else(|| eframe::storage_dir(APP_ID));
        let mut app = Self {
            settings,
            session: session::Session::new(worker, data_dir),
            levels,
            panels: panels::Panels::new(available),
            measure: measure::Measurement::new(
                options.screenshot.clone(),
                options.stats.clone(),
                options.latency_trials,
                options.failure.clone(),
            ),
            notice,
            options: options.clone(),
        };
        let path = options.image.clone().or_else(sample_image_path);
        match path {
            Some(path) => {
                let base = app.open_options();
                let open = OpenOptions {
                    srgb: base.srgb,
                    max_side: base.max_side,
                    ..options.open.clone()
                };
                let mut paths = vec![path];
                paths.extend(options.set_images.iter().cloned());
                app.open_paths_with(&cc.egui_ctx, &paths, &open);
                if let Some(panel) = options.panel {
                    app.panels.show_panel(panel);
                }
                // Start at once, not after the debounce.
                app.start_solve();
            }
            None => app.notice = Some(
                "the built-in sample (assets/sombrero/image16.png) was not found; use File > Open"
                    .into(),
            ),
        }
        app
    }

    /// The open document.
    pub fn document(&self) -> Option<&Document> {
        self.session.document.as_ref()
    }

    /// The solve shown on screen.
    pub fn solve_state(&self) -> &SolveState {
        &self.session.solve
    }

    /// The current message (error or note), if any.
    pub fn notice(&self) -> Option<&str> {
        self.notice.as_deref()
    }

    /// Current parameters.
    pub fn params(&self) -> &ParamSettings {
        &self.settings.params
    }

    /// Selects a 2-D panel.
    pub fn show_panel(&mut self, panel: Panel2d) {
        self.panels.show_panel(panel);
    }

    /// How File > Open reads an image: the sRGB choice given at start and
    /// the working size; camera file and mask found beside it.
    fn open_options(&self) -> OpenOptions {
        OpenOptions {
            srgb: self.options.open.srgb,
            max_side: (self.settings.max_side > 0).then_some(self.settings.max_side),
            ..OpenOptions::default()
        }
    }

    /// Opens an image by path (File > Open and drops end here). On failure
    /// the previous document stays and the error is shown.
    pub fn open(&mut self, ctx: &egui::Context, path: &Path) {
        self.open_with(ctx, path, &self.open_options());
    }

    /// Opens an image with `options` (files, corrections, working size).
    pub fn open_with(&mut self, ctx: &egui::Context, path: &Path, options: &OpenOptions) {
        self.open_paths_with(ctx, &[path.to_path_buf()], options);
    }

    /// Opens one image, a set folder, or several photographs as one
    /// photometric-stereo set (File > Open photometric set, dropped files,
    /// the command line). On failure the previous document stays and the
    /// error is shown.
    pub fn open_paths(&mut self, ctx: &egui::Context, paths: &[PathBuf]) {
        self.open_paths_with(ctx, paths, &self.open_options());
    }

    /// [`Self::open_paths`] with `options`.
    pub fn open_paths_with(
        &mut self,
        ctx: &egui::Context,
        paths: &[PathBuf],
        options: &OpenOptions,
    ) {
        match self.session.open_paths(paths, options) {
            Ok(notes) => {
                // A set folder is remembered (it opens again as the set).
                if let [path] = paths {
                    self.settings.remember(path.clone());
                }
                self.panels.document_opened(ctx, &self.session);
                self.notice = (!notes.is_empty()).then(|| notes.join("; "));
            }
            Err(e) => self.notice = Some(e),
        }
    }

    /// Applies a camera file to the open image.
    pub fn load_camera(&mut self, path: &Path) {
        self.notice = self.session.load_camera(path).err();
    }

    /// Loads a mask PNG into `layer` (undoable); a wrong size is refused.
    pub fn load_mask(&mut self, layer: Layer, path: &Path) {
        self.notice = self.session.load_mask(layer, path).err();
    }

    /// Marks parameters or masks as changed: a new solve starts after the
    /// debounce.
    pub fn request_solve(&mut self) {
        self.session.request_solve();
    }

    /// Cancels the running solve.
    pub fn cancel_solve(&mut self) {
        self.session.cancel_solve();
    }

    /// Submits a solve of the open document with the current parameters
    /// and masks now.
    pub fn start_solve(&mut self) {
        self.session.start_solve(
            self.settings.params.to_params(),
            self.settings.set_params.to_params(),
        );
    }

    /// Solves photograph `index` of the open set alone with the
    /// single-image method, to compare with the set.
    pub fn solve_single(&mut self, index: usize) {
        self.session
            .solve_single(index, self.settings.params.to_params(), false);
    }

    /// [`Self::solve_single`] with the set's albedo divided out of the
    /// photograph first ("use the albedo from photometric stereo"), to
    /// compare with the single photograph's own albedo estimate.
    pub fn solve_single_with_set_albedo(&mut self, index: usize) {
        self.session
            .solve_single(index, self.settings.params.to_params(), true);
    }

    /// The comparison of one photograph solved alone with the set.
    pub fn compare_state(&self) -> &CompareState {
        &self.session.compare
    }

    /// The albedo the 3-D surface carries when its texture is the albedo:
    /// a set's, or the one the finished single-image solve used (`None`
    /// before a result, or when it estimated none).
    pub fn surface_albedo(&self) -> Option<sfs_core::grid::Grid<f64>> {
        self.session.surface_albedo()
    }

    /// The open document, to edit (tests: masks, a photograph's layer).
    pub fn document_mut(&mut self) -> Option<&mut Document> {
        self.session.document.as_mut()
    }

    /// The photometric-stereo problem a solve of the open set gets now
    /// (`None`: no set open).
    pub fn set_problem(&self) -> Option<sfs_core::solver::photometric::PhotometricProblem> {
        self.session.document.as_ref()?.set_problem()
    }

    /// Chooses which layers the mask tools paint: the set-wide masks
    /// (`None`) or photograph `index`'s own confidence.
    pub fn paint_photo(&mut self, index: Option<usize>) {
        self.panels.set_paint_photo(index);
    }

    /// Current settings.
    pub fn settings_mut(&mut self) -> &mut Settings {
        &mut self.settings
    }

    /// Writes the finished result; the outcome goes to the status line.
    pub fn export(&mut self, path: &Path, what: Export) {
        self.notice = Some(match self.session.export(path, what) {
            Ok(done) => done,
            Err(e) => e,
        });
    }

    /// Asks the integration for a screenshot of the window, saved to `path`
    /// when it arrives.
    pub fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.measure.request_screenshot(ctx, path);
    }

    /// Dropped files: several photographs at once open as one
    /// photometric-stereo set, else each one as [`Self::drop_file`] says.
    pub fn drop_files(&mut self, ctx: &egui::Context, paths: &[PathBuf]) {
        let photos: Vec<PathBuf> = paths
            .iter()
            .filter(|p| {
                let name = p
                    .file_name()
                    .map(|n| n.to_string_lossy().to_lowercase())
                    .unwrap_or_default();
                !(name.ends_with(".json") || name.contains("mask") || name.contains("confidence"))
            })
            .cloned()
            .collect();
        if photos.len() > 1 {
            // Several photographs at once: one set (its camera file and
            // mask beside them).
            self.open_paths(ctx, &photos);
            return;
        }
        for path in paths {
            self.drop_file(ctx, path);
        }
    }

    /// One dropped file: a camera JSON applies to the open image, a PNG
    /// whose name contains `mask` or `confidence` loads into that layer, a
    /// folder opens as a set, anything else opens as a new image.
    pub fn drop_file(&mut self, ctx: &egui::Context, path: &Path) {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        let has_doc = self.session.document.is_some();
        if has_doc && name.ends_with(".json") {
            self.load_camera(path);
        } else if has_doc && name.contains("confidence") {
            self.load_mask(Layer::Confidence, path);
        } else if has_doc && name.contains("mask") {
            self.load_mask(Layer::Object, path);
        } else {
            self.open_paths(ctx, &[path.to_path_buf()]);
        }
    }

    /// Runs what the panels asked for.
    fn apply(&mut self, ctx: &egui::Context, action: Action) {
        match action {
            Action::Open(path) => self.open_paths(ctx, &[path]),
            Action::OpenSet(paths) => self.open_paths(ctx, &paths),
            Action::SolveSingle(index) => self.solve_single(index),
            Action::SolveSingleWithSetAlbedo(index) => self.solve_single_with_set_albedo(index),
            Action::LoadCamera(path) => self.load_camera(&path),
            Action::LoadMask(layer, path) => self.load_mask(layer, &path),
            Action::SaveMask(layer, path) => {
                if let Err(e) = self.session.save_mask(layer, &path) {
                    self.notice = Some(e);
                }
            }
            Action::Export(path, what) => self.export(&path, what),
            Action::Screenshot(path) => self.request_screenshot(ctx, path),
            Action::CancelSolve => self.cancel_solve(),
            Action::SolveNow => self.start_solve(),
            Action::RequestSolve => self.request_solve(),
            Action::Notice(text) => self.notice = Some(text),
            Action::DismissNotice => self.notice = None,
            Action::SuggestConfidence => {
                self.notice = Some(self.session.suggest_confidence());
            }
        }
    }

    /// Worker events to the session, its levels to the preparation thread.
    fn receive_levels(&mut self) {
        for arrived in self.session.drain_events() {
            let generation = self.levels.submit(arrived.result, arrived.inputs);
            if arrived.first_of_job {
                // The first level of this job: it is on screen when this
                // generation comes back from the preparation thread.
                self.measure
                    .first_level_submitted(generation.unwrap_or(self.levels.generation() + 1));
            }
        }
    }

    /// The debounced solve, the autosave, prepared levels, and the
    /// measurement hooks.
    fn housekeeping(&mut self, ctx: &egui::Context) {
        let (params, set_params) = (&self.settings.params, &self.settings.set_params);
        let pointer_down = ctx.input(|i| i.pointer.any_down());
        let view = &self.settings.view;
        if let Some(level) = self
            .session
            .set_albedo_texture(view.photo_texture && view.albedo_texture)
        {
            self.levels.submit(level.result, level.inputs);
        }
        if let Some(error) = self.session.tick(
            self.panels.gesture_in_progress(),
            pointer_down,
            || (params.to_params(), set_params.to_params()),
            |after| ctx.request_repaint_after(after),
        ) {
            self.notice = Some(error);
        }
        if let Some(built) = self.levels.poll() {
            let generation = built.generation;
            self.panels.show_level(ctx, built);
            self.measure.level_shown(generation);
        }
        if self.measure.start_latency_trial(&self.measured_state()) {
            // As a slider release would: change alpha, the debounce, then
            // the solve.
            let chosen = self.session.solve.finished().map_or(1e-7, |s| s.alpha);
            self.settings.params.update(|p| {
                p.alpha = match p.alpha {
                    Alpha::Value(v) => Alpha::Value(v * 1.1),
                    Alpha::Auto => Alpha::Value(chosen * 1.1),
                }
            });
            self.request_solve();
            ctx.request_repaint();
        }
        self.measure.after_frame(ctx, &self.measured_state());
    }

    fn measured_state(&self) -> measure::AppState {
        measure::AppState {
            completed_jobs: self.session.solve.completed_jobs,
            running: self.session.solve.running,
            solve_pending: self.session.solve_pending(),
            newest_level_shown: self.panels.level_generation() == Some(self.levels.generation())
                || !self.levels.is_running(),
            failure: match &self.session.document {
                None => Some(
                    self.notice
                        .clone()
                        .unwrap_or_else(|| "no image is open".into()),
                ),
                Some(_) if !self.session.solve.running => self.session.solve.failure.clone(),
                Some(_) => None,
            },
        }
    }

    /// Keyboard shortcuts, dropped files and screenshots.
    fn handle_input(&mut self, ctx: &egui::Context) {
        let (undo, redo, dropped) = ctx.input_mut(|i| {
            let redo = i.consume_shortcut(&egui::KeyboardShortcut::new(
                egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
                egui::Key::Z,
            ));
            let undo = i.consume_shortcut(&egui::KeyboardShortcut::new(
                egui::Modifiers::COMMAND,
                egui::Key::Z,
            ));
            (undo, redo, std::mem::take(&mut i.raw.dropped_files))
        });
        if let Some(doc) = &mut self.session.document {
            let (masks, _) = doc.paint_target(self.panels.paint_photo());
            if redo {
                masks.redo();
            } else if undo {
                masks.undo();
            }
        }
        let dropped: Vec<PathBuf> = dropped
            .iter()
            .map(|file| file.path().to_path_buf())
            .filter(|path| !path.as_os_str().is_empty())
            .collect();
        if !dropped.is_empty() {
            self.drop_files(ctx, &dropped);
        }
        if let Some(error) = self.measure.save_screenshots(ctx).pop() {
            self.notice = Some(error);
        }
    }
}

/// The solver on a rayon pool of all cores but one (at least one thread):
/// the UI thread and a software rasteriser keep a core, so frames stay
/// short while a solve runs. Falls back to the global pool.
fn solver_leaving_a_core() -> (crate::worker::SolveFn, crate::worker::SetSolveFn) {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cores.saturating_sub(1).max(1))
        .thread_name(|i| format!("sfs-solver-{i}"))
        .build()
        .ok()
        .map(std::sync::Arc::new);
    let set_pool = pool.clone();
    let single: crate::worker::SolveFn = std::sync::Arc::new(move |job, observer| match &pool {
        Some(pool) => pool.install(|| job.run(observer)),
        None => job.run(observer),
    });
    let set: crate::worker::SetSolveFn = std::sync::Arc::new(move |problem, params, observer| {
        use sfs_core::solver::photometric::solve_photometric;
        match &set_pool {
            Some(pool) => pool.install(|| solve_photometric(problem, params, observer)),
            None => solve_photometric(problem, params, observer),
        }
    });
    (single, set)
}

impl eframe::App for ViewerApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        self.receive_levels();
        self.housekeeping(ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let started = Instant::now();
        let ctx = ui.ctx().clone();
        self.measure.frame_started(self.session.solve.running);
        if self.session.solve.running {
            ctx.request_repaint();
        }
        self.handle_input(&ctx);
        let mut actions = Vec::new();
        let mut cx = panels::UiContext {
            session: &mut self.session,
            settings: &mut self.settings,
            notice: self.notice.as_deref(),
            actions: &mut actions,
        };
        self.panels.ui(ui, &mut cx);
        for action in actions {
            self.apply(&ctx, action);
        }
        self.measure.frame_finished(started);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        // Measurement runs change alpha themselves: not the user's settings.
        if self.measure.is_measuring() || self.options.fresh_settings {
            return;
        }
        eframe::set_value(storage, settings::STORAGE_KEY, &self.settings);
    }

    fn on_exit(&mut self) {
        if let Err(e) = self.session.autosave() {
            eprintln!("{e}");
        }
        self.measure
            .write_stats(self.session.document.as_ref().map(|d| d.size()));
    }
}

/// Opens the viewer in a native window of `window` points (width, height)
/// and runs it until it is closed; a failure the viewer reported while
/// running (e.g. a screenshot it could not save) is returned as the error.
pub fn run_window(options: ViewerOptions, window: (usize, usize)) -> anyhow::Result<()> {
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("sfs-studio")
            .with_inner_size([window.0 as f32, window.1 as f32])
            .with_drag_and_drop(true),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let failure = options.failure.clone();
    eframe::run_native(
        APP_ID,
        native,
        Box::new(move |cc| Ok(Box::new(ViewerApp::new(cc, options)))),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the viewer window: {e}"))?;
    match failure.get() {
        Some(message) => Err(anyhow::anyhow!("{message}")),
        None => Ok(()),
    }
}
