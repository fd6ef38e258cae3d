//! The viewer: an eframe (wgpu) application for loading an image, painting
//! masks, tuning parameters while a worker thread solves, and inspecting the
//! levels as they arrive in 2-D and 3-D. The only module that uses egui.

mod document;
mod images;
mod settings;
mod ui;
mod view3d;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use eframe::egui;

use crate::grid::Grid;
use crate::io;
use crate::mask_edit::{self, ImagePoint, Layer, Masks};
use crate::metrics;
use crate::params::Alpha;
use crate::solver::{LevelResult, Problem, Solution};
use crate::worker::{Event, JobId, SolveRequest, Worker};

pub use document::{CameraSource, CameraState, Document, exif_focal_35mm, sample_image_path};
pub use settings::{InitialChoice, ParamSettings, Settings, Tool};
pub use ui::Export;

/// eframe application id (storage folder name).
pub const APP_ID: &str = "sfs-studio";

/// While a slider is dragged, solve after it rests this long.
const DEBOUNCE: Duration = Duration::from_millis(200);
/// Write the mask autosave this long after the last edit.
const AUTOSAVE_DELAY: Duration = Duration::from_secs(1);
/// Time per frame for draining worker events.
const EVENT_BUDGET: Duration = Duration::from_millis(6);

/// How the viewer starts.
#[derive(Clone, Debug, Default)]
pub struct ViewerOptions {
    /// Image to open (`None`: the built-in sample).
    pub image: Option<PathBuf>,
    /// Camera JSON to apply after opening.
    pub camera: Option<PathBuf>,
    /// Object mask PNG to load after opening.
    pub mask: Option<PathBuf>,
    /// Read the image as sRGB.
    pub srgb: bool,
    /// Alpha override.
    pub alpha: Option<Alpha>,
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
}

/// Which 2-D panel is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Panel2d {
    /// The input with the mask overlay (paint here).
    Input,
    /// The reprojected image of the latest level.
    Reprojection,
    /// `|input - reprojection|`.
    Difference,
    /// Depth with a colour map.
    Depth,
    /// `|depth - ground truth|` (with ground truth).
    DepthError,
}

/// One level as received.
pub struct LevelView {
    /// Level index (0 = coarsest).
    pub level: usize,
    /// Levels in the job.
    pub levels: usize,
    /// Depth at the level's size.
    pub depth: Grid<f64>,
    /// Reprojection at the level's size.
    pub reprojection: Grid<f64>,
}

/// Progress of the running job.
#[derive(Clone, Debug, Default)]
pub struct Progress {
    /// Level index and count.
    pub level: usize,
    /// Number of levels.
    pub levels: usize,
    /// Level size.
    pub size: (usize, usize),
    /// Outer iteration.
    pub iteration: usize,
    /// Total energy divided by the level's pixel count (see [`per_pixel`]).
    pub energy_per_pixel: f64,
    /// Time since the job started.
    pub elapsed: Duration,
}

/// One point of the energy plot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnergyPoint {
    /// Level index (0 = coarsest).
    pub level: usize,
    /// Total energy divided by the level's pixel count ([`per_pixel`]).
    pub per_pixel: f64,
}

/// The energy per pixel of a `(width, height)` level: the total divided by
/// `width * height`, the same for iteration reports and level results, so
/// that levels of different sizes compare (the total grows with the pixel
/// count). With the default (paper) domain every pixel is in the domain, so
/// this equals `LevelResult::energy_per_pixel`.
pub fn per_pixel(total: f64, (width, height): (usize, usize)) -> f64 {
    total / (width * height).max(1) as f64
}

/// State of the solve shown on screen.
#[derive(Default)]
pub struct SolveState {
    /// The newest job.
    pub job: Option<JobId>,
    /// When it was submitted.
    pub submitted: Option<Instant>,
    /// Running (no terminal event yet).
    pub running: bool,
    /// Level sizes of the newest job as they arrived (coarse to fine).
    pub arrived: Vec<(usize, usize)>,
    /// Latest level.
    pub latest: Option<LevelView>,
    /// Energy per pixel after every outer iteration of the job (and of
    /// every level without iterations), coarse to fine.
    pub energies: Vec<EnergyPoint>,
    /// Progress.
    pub progress: Progress,
    /// Final result.
    pub finished: Option<Box<Solution>>,
    /// RSE and RIE against the ground truth.
    pub errors: Option<(f64, f64)>,
    /// Why the last job failed.
    pub failure: Option<String>,
    /// Jobs finished so far (any outcome).
    pub completed_jobs: usize,
}

/// Frame timing for `--stats`.
#[derive(Default)]
struct Stats {
    last_frame: Option<Instant>,
    frame_intervals_ms: Vec<f64>,
    ui_ms: Vec<f64>,
    busy_frame_intervals_ms: Vec<f64>,
    idle_frame_intervals_ms: Vec<f64>,
    latencies_ms: Vec<f64>,
    trial_started: Option<Instant>,
    /// Preparation generation of the current job's first level.
    first_level_generation: Option<u64>,
    trials_done: usize,
}

/// A screenshot that arrived, with where to save it.
type Screenshot = (PathBuf, std::sync::Arc<egui::ColorImage>);

/// A drag in the image panel in progress.
enum Gesture {
    Stroke,
    Rectangle(ImagePoint),
    Lasso(Vec<ImagePoint>),
}

/// Textures of the 2-D panels.
#[derive(Default)]
struct Textures {
    input: Option<egui::TextureHandle>,
    overlay: Option<(u64, egui::TextureHandle)>,
    reprojection: Option<egui::TextureHandle>,
    difference: Option<(egui::TextureHandle, [f64; 2])>,
    depth: Option<(egui::TextureHandle, [f64; 2])>,
    depth_error: Option<(egui::TextureHandle, [f64; 2])>,
}

/// The viewer application.
pub struct ViewerApp {
    options: ViewerOptions,
    settings: Settings,
    document: Option<Document>,
    worker: Option<Worker>,
    solve: SolveState,
    textures: Textures,
    panel: Panel2d,
    zoom: f32,
    pan: egui::Vec2,
    gesture: Option<Gesture>,
    dirty_since: Option<Instant>,
    mask_revision_solved: u64,
    autosave_due: Option<Instant>,
    data_dir: Option<PathBuf>,
    surface: view3d::SurfaceView,
    meshes: Option<view3d::MeshBuilder>,
    mesh_generation: u64,
    /// The image and ground truth of the running job, shared with the
    /// level-preparation thread.
    level_inputs: Option<view3d::LevelInputs>,
    notice: Option<String>,
    screenshot_requested: bool,
    screenshots: (
        crossbeam_channel::Sender<Screenshot>,
        crossbeam_channel::Receiver<Screenshot>,
    ),
    frames_after_finish: usize,
    stats: Stats,
    hover: Option<String>,
}

impl ViewerApp {
    /// Builds the app: settings from storage, the worker, the 3-D renderer,
    /// and the first document (the sample or `options.image`).
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
        let ctx = cc.egui_ctx.clone();
        let waker = move || ctx.request_repaint();
        let mut notice = None;
        let worker = match Worker::spawn_with(Box::new(waker.clone()), solver_leaving_a_core()) {
            Ok(w) => Some(w),
            Err(e) => {
                notice = Some(format!("cannot start the solver thread: {e}"));
                None
            }
        };
        let meshes = view3d::MeshBuilder::spawn(waker).ok();
        let available = match cc.wgpu_render_state.as_ref() {
            Some(rs) => view3d::install(rs),
            None => Err("3-D view needs the wgpu renderer".into()),
        };
        let data_dir = options
            .data_dir
            .clone()
            .or_else(|| eframe::storage_dir(APP_ID));
        let mut app = Self {
            options: options.clone(),
            settings,
            document: None,
            worker,
            solve: SolveState::default(),
            textures: Textures::default(),
            panel: Panel2d::Input,
            zoom: 1.0,
            pan: egui::Vec2::ZERO,
            gesture: None,
            dirty_since: None,
            mask_revision_solved: 0,
            autosave_due: None,
            data_dir,
            surface: view3d::SurfaceView::new(available),
            meshes,
            mesh_generation: 0,
            level_inputs: None,
            notice,
            screenshot_requested: false,
            screenshots: crossbeam_channel::unbounded(),
            frames_after_finish: 0,
            stats: Stats::default(),
            hover: None,
        };
        let path = options.image.clone().or_else(sample_image_path);
        match path {
            Some(path) => {
                app.open(&cc.egui_ctx, &path);
                if let Some(camera) = &options.camera {
                    app.load_camera(camera);
                }
                if let Some(mask) = &options.mask {
                    app.load_mask(Layer::Object, mask);
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
        self.document.as_ref()
    }

    /// The solve shown on screen.
    pub fn solve_state(&self) -> &SolveState {
        &self.solve
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
        self.panel = panel;
    }

    /// Opens an image by path (File > Open and drops end here). On failure
    /// the previous document stays and the error is shown.
    pub fn open(&mut self, ctx: &egui::Context, path: &Path) {
        match Document::open(path, self.options.srgb) {
            Ok(mut doc) => {
                let mut notes = std::mem::take(&mut doc.notes);
                if let Some(dir) = self.autosave_dir(&doc.path) {
                    match Masks::restore(&dir, doc.size()) {
                        Ok(Some(masks)) => {
                            doc.masks = masks;
                            notes.push("restored your painted masks from the autosave".into());
                        }
                        Ok(None) => {}
                        Err(e) => notes.push(format!("autosave not restored: {e}")),
                    }
                }
                self.settings.remember(path.to_path_buf());
                self.document = Some(doc);
                self.solve = SolveState::default();
                self.textures = Textures::default();
                self.surface.clear();
                self.zoom = 1.0;
                self.pan = egui::Vec2::ZERO;
                self.upload_input(ctx);
                self.notice = (!notes.is_empty()).then(|| notes.join("; "));
                self.request_solve();
            }
            Err(e) => self.notice = Some(format!("{e:#}")),
        }
    }

    fn autosave_dir(&self, image: &Path) -> Option<PathBuf> {
        self.data_dir
            .as_ref()
            .map(|d| mask_edit::autosave_dir(image, d))
    }

    /// Applies a camera file to the open image.
    pub fn load_camera(&mut self, path: &Path) {
        let Some(doc) = &mut self.document else {
            return;
        };
        match doc.load_camera(path) {
            Ok(()) => {
                self.notice = None;
                self.request_solve();
            }
            Err(e) => self.notice = Some(format!("{e:#}")),
        }
    }

    /// Loads a mask PNG into `layer` (undoable); a wrong size is refused.
    pub fn load_mask(&mut self, layer: Layer, path: &Path) {
        let Some(doc) = &mut self.document else {
            return;
        };
        match doc.masks.load_png(layer, path) {
            Ok(_) => self.notice = None,
            Err(e) => self.notice = Some(e.to_string()),
        }
    }

    /// Marks parameters or masks as changed: a new solve starts after the
    /// debounce.
    pub fn request_solve(&mut self) {
        self.dirty_since = Some(Instant::now());
    }

    /// Cancels the running solve.
    pub fn cancel_solve(&mut self) {
        if let (Some(worker), Some(job)) = (&self.worker, self.solve.job) {
            worker.cancel(job);
        }
    }

    /// Submits a solve of the open document with the current parameters
    /// and masks now.
    pub fn start_solve(&mut self) {
        self.dirty_since = None;
        let (Some(doc), Some(worker)) = (&self.document, &mut self.worker) else {
            return;
        };
        let problem = Problem {
            image: doc.image.clone(),
            camera: doc.camera.intrinsics(),
            intensity_scale: doc.camera.intensity_scale,
            object_mask: doc.masks.object_for_solver(),
            confidence: doc.masks.confidence_for_solver(),
        };
        let params = self.settings.params.to_params();
        self.level_inputs = Some(view3d::LevelInputs {
            image: std::sync::Arc::new(doc.image.clone()),
            ground_truth: doc.ground_truth.clone().map(std::sync::Arc::new),
            object: problem.object_mask.clone().map(std::sync::Arc::new),
        });
        self.mask_revision_solved = doc.masks.revision();
        let job = worker.submit(SolveRequest { problem, params });
        self.solve.job = Some(job);
        self.solve.submitted = Some(Instant::now());
        self.solve.running = true;
        self.solve.arrived.clear();
        self.solve.energies.clear();
        self.solve.failure = None;
        self.solve.finished = None;
        self.solve.errors = None;
    }

    fn upload_input(&mut self, ctx: &egui::Context) {
        if let Some(doc) = &self.document {
            self.textures.input = Some(ctx.load_texture(
                "input",
                images::grey_image(&doc.image),
                egui::TextureOptions::NEAREST,
            ));
        }
    }

    /// Drains worker events (a few milliseconds at most).
    fn handle_events(&mut self) {
        let Some(worker) = &mut self.worker else {
            return;
        };
        let latest = worker.latest_job();
        let events: Vec<Event> = worker.drain(EVENT_BUDGET).collect();
        for event in events {
            if Some(event.job()) != latest || Some(event.job()) != self.solve.job {
                continue; // a superseded job
            }
            match event {
                Event::Started { .. } => {}
                Event::Progress { report, .. } => {
                    let size = (report.width, report.height);
                    let energy_per_pixel = per_pixel(report.energy.total, size);
                    self.solve.energies.push(EnergyPoint {
                        level: report.level,
                        per_pixel: energy_per_pixel,
                    });
                    self.solve.progress = Progress {
                        level: report.level,
                        levels: report.levels,
                        size,
                        iteration: report.iteration,
                        energy_per_pixel,
                        elapsed: report.elapsed,
                    };
                }
                Event::Level { result, .. } => self.receive_level(result),
                Event::Finished { solution, .. } => {
                    self.solve.errors = self.document.as_ref().and_then(|doc| {
                        let gt = doc.ground_truth.as_ref()?;
                        metrics::errors(
                            &solution.depth,
                            gt,
                            &doc.image,
                            doc.camera.intrinsics(),
                            doc.camera.intensity_scale,
                        )
                        .ok()
                        .map(|e| (e.rse, e.rie))
                    });
                    self.solve.finished = Some(solution);
                    self.solve.running = false;
                    self.solve.completed_jobs += 1;
                }
                Event::Failed { error, .. } => {
                    self.solve.failure = Some(error);
                    self.solve.running = false;
                    self.solve.completed_jobs += 1;
                }
                Event::Cancelled { .. } => {
                    self.solve.running = false;
                    self.solve.completed_jobs += 1;
                }
            }
        }
    }

    fn receive_level(&mut self, result: LevelResult) {
        let size = result.depth.size();
        self.solve.arrived.push(size);
        if self.solve.arrived.len() == 1 {
            // The first level of this job: it is on screen when this
            // generation comes back from the preparation thread.
            self.stats.first_level_generation = Some(self.mesh_generation + 1);
        }
        // A level without outer iterations (a fast-marching start) is a
        // point of its own in the energy plot.
        if self.solve.energies.last().map(|e| e.level) != Some(result.level) {
            self.solve.energies.push(EnergyPoint {
                level: result.level,
                per_pixel: per_pixel(result.energy.total, size),
            });
        }
        if let (Some(meshes), Some(inputs)) = (&self.meshes, &self.level_inputs) {
            self.mesh_generation += 1;
            meshes.submit(view3d::MeshJob {
                generation: self.mesh_generation,
                level: result.clone(),
                inputs: inputs.clone(),
            });
        }
        self.solve.latest = Some(LevelView {
            level: result.level,
            levels: result.levels,
            depth: result.depth,
            reprojection: result.reprojection,
        });
    }

    /// Uploads a prepared level's panel images.
    fn show_panels(&mut self, ctx: &egui::Context, panels: view3d::LevelPanels) {
        let options = egui::TextureOptions::NEAREST;
        self.textures.reprojection =
            Some(ctx.load_texture("reprojection", panels.reprojection, options));
        let (difference, range) = panels.difference;
        self.textures.difference =
            Some((ctx.load_texture("difference", difference, options), range));
        let (depth, range) = panels.depth;
        self.textures.depth = Some((ctx.load_texture("depth", depth, options), range));
        self.textures.depth_error = panels
            .depth_error
            .map(|(image, range)| (ctx.load_texture("depth-error", image, options), range));
    }

    fn error_range(&self) -> f32 {
        self.textures
            .difference
            .as_ref()
            .map_or(1.0, |(_, r)| r[1] as f32)
    }

    /// Debounced solve, autosave, screenshot and stats bookkeeping.
    fn housekeeping(&mut self, ctx: &egui::Context) {
        if let Some(doc) = &self.document {
            let revision = doc.masks.revision();
            if revision != self.mask_revision_solved && self.gesture.is_none() {
                if self.dirty_since.is_none() {
                    self.dirty_since = Some(Instant::now());
                }
                if self.autosave_due.is_none() {
                    self.autosave_due = Some(Instant::now() + AUTOSAVE_DELAY);
                }
                self.mask_revision_solved = revision;
            }
        }
        if let Some(since) = self.dirty_since {
            let waited = since.elapsed();
            // A released slider, a typed value or a button starts at once;
            // while a slider is dragged, a pause of DEBOUNCE starts a solve.
            let dragging = ctx.input(|i| i.pointer.any_down()) && self.gesture.is_none();
            if !dragging || waited >= DEBOUNCE {
                self.start_solve();
            } else {
                ctx.request_repaint_after(DEBOUNCE.saturating_sub(waited));
            }
        }
        if let Some(due) = self.autosave_due {
            if Instant::now() >= due {
                self.autosave_due = None;
                self.autosave();
            } else {
                ctx.request_repaint_after(due - Instant::now());
            }
        }
        if let Some(built) = self.meshes.as_ref().and_then(|m| m.poll()) {
            let generation = built.generation;
            if let Some(panels) = self.surface.set_mesh(built) {
                self.show_panels(ctx, panels);
            }
            if let (Some(started), Some(first)) =
                (self.stats.trial_started, self.stats.first_level_generation)
                && generation >= first
            {
                self.stats
                    .latencies_ms
                    .push(started.elapsed().as_secs_f64() * 1e3);
                self.stats.trial_started = None;
            }
        }
        self.latency_trials(ctx);
        // Screenshot once the first solve is over and its last mesh is shown.
        if self.options.screenshot.is_some() && !self.screenshot_requested {
            let done = self.solve.completed_jobs > 0
                && !self.solve.running
                && self.stats.trials_done >= self.options.latency_trials
                && self.stats.trial_started.is_none()
                && self.dirty_since.is_none()
                && (self.surface.generation() == Some(self.mesh_generation)
                    || self.meshes.is_none());
            if done {
                self.frames_after_finish += 1;
                // With --stats, also time 40 frames with nothing to solve.
                let wait = if self.options.stats.is_some() { 42 } else { 3 };
                if self.frames_after_finish > wait {
                    self.screenshot_requested = true;
                    if let Some(path) = self.options.screenshot.clone() {
                        self.request_screenshot(ctx, path);
                    }
                }
            }
            ctx.request_repaint();
        }
    }

    /// With `--stats`: after each finished solve, change alpha and time the
    /// first new level.
    fn latency_trials(&mut self, ctx: &egui::Context) {
        if self.options.stats.is_none() || self.stats.trials_done >= self.options.latency_trials {
            return;
        }
        if self.solve.running || self.stats.trial_started.is_some() || self.dirty_since.is_some() {
            return;
        }
        if self.solve.completed_jobs == 0 {
            return;
        }
        self.stats.trials_done += 1;
        let chosen = self.solve.finished.as_ref().map_or(1e-7, |s| s.alpha);
        self.settings.params.update(|p| {
            p.alpha = match p.alpha {
                Alpha::Value(v) => Alpha::Value(v * 1.1),
                Alpha::Auto => Alpha::Value(chosen * 1.1),
            }
        });
        self.stats.trial_started = Some(Instant::now());
        self.stats.first_level_generation = None;
        // As a slider release would: the debounce, then the solve.
        self.request_solve();
        ctx.request_repaint();
    }

    fn autosave(&mut self) {
        let Some(doc) = &self.document else {
            return;
        };
        let Some(dir) = self.autosave_dir(&doc.path) else {
            return;
        };
        if let Err(e) = doc.masks.autosave(&dir, &doc.path) {
            self.notice = Some(format!("mask autosave failed: {e}"));
        }
    }

    /// Asks the integration for a screenshot of the window, saved to `path`
    /// when it arrives.
    pub fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        let sender = self.screenshots.0.clone();
        let waker = ctx.clone();
        ctx.request_screenshot(move |image| {
            // The app owns the receiver; a closed app has nothing to save.
            let _ = sender.send((path, image));
            waker.request_repaint();
        });
    }

    fn save_screenshot(&mut self, ctx: &egui::Context, image: &egui::ColorImage, path: &Path) {
        let [w, h] = image.size;
        let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
        let result = image::RgbaImage::from_raw(w as u32, h as u32, bytes)
            .ok_or_else(|| "screenshot has an inconsistent size".to_string())
            .and_then(|img| img.save(path).map_err(|e| e.to_string()));
        match result {
            Ok(()) => eprintln!("saved screenshot {}", path.display()),
            Err(e) => {
                self.notice = Some(format!("cannot save screenshot {}: {e}", path.display()));
                eprintln!("cannot save screenshot {}: {e}", path.display());
            }
        }
        if self.options.screenshot.as_deref() == Some(path) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    fn write_stats(&self) {
        let Some(path) = &self.options.stats else {
            return;
        };
        let summary = |v: &[f64]| {
            let mut s = v.to_vec();
            s.sort_by(|a, b| a.total_cmp(b));
            let pick = |q: f64| {
                s.get(((s.len() as f64 - 1.0) * q).round() as usize)
                    .copied()
                    .unwrap_or(f64::NAN)
            };
            serde_json::json!({"count": s.len(), "median": pick(0.5), "p95": pick(0.95), "max": pick(1.0)})
        };
        let size = self.document.as_ref().map(|d| d.size());
        let report = serde_json::json!({
            "image_size": size,
            "frame_interval_ms_while_solving": summary(&self.stats.busy_frame_intervals_ms),
            "frame_interval_ms_all": summary(&self.stats.frame_intervals_ms),
            "frame_interval_ms_idle": summary(&self.stats.idle_frame_intervals_ms),
            "ui_cpu_ms": summary(&self.stats.ui_ms),
            "change_to_first_level_ms": self.stats.latencies_ms,
        });
        if let Err(e) = io::write_json(path, &report) {
            eprintln!("cannot write stats {}: {e}", path.display());
        }
    }
}

/// The solver on a rayon pool of all cores but one (at least one thread):
/// the UI thread and a software rasteriser keep a core, so frames stay
/// short while a solve runs. Falls back to the global pool.
fn solver_leaving_a_core() -> crate::worker::SolveFn {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cores.saturating_sub(1).max(1))
        .thread_name(|i| format!("sfs-solver-{i}"))
        .build()
        .ok();
    std::sync::Arc::new(move |problem, params, observer| match &pool {
        Some(pool) => pool.install(|| crate::solver::solve(problem, params, observer)),
        None => crate::solver::solve(problem, params, observer),
    })
}

impl eframe::App for ViewerApp {
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        self.handle_events();
        self.housekeeping(ctx);
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let started = Instant::now();
        let ctx = ui.ctx().clone();
        if let Some(last) = self.stats.last_frame {
            let ms = last.elapsed().as_secs_f64() * 1e3;
            self.stats.frame_intervals_ms.push(ms);
            if self.solve.running {
                self.stats.busy_frame_intervals_ms.push(ms);
            } else if self.frames_after_finish > 1 {
                // Continuous repaints while nothing is solved: the baseline.
                self.stats.idle_frame_intervals_ms.push(ms);
            }
        }
        self.stats.last_frame = Some(Instant::now());
        if self.solve.running {
            ctx.request_repaint();
        }
        self.handle_input(&ctx);
        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui));
        egui::Panel::left("controls")
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls_ui(ui));
            });
        egui::Panel::right("view3d")
            .default_size(480.0)
            .resizable(true)
            .show(ui, |ui| self.view3d_ui(ui));
        egui::CentralPanel::default().show(ui, |ui| self.image_panel_ui(ui));
        self.stats.ui_ms.push(started.elapsed().as_secs_f64() * 1e3);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        // Measurement runs change alpha themselves: not the user's settings.
        if self.options.stats.is_some() || self.options.fresh_settings {
            return;
        }
        eframe::set_value(storage, settings::STORAGE_KEY, &self.settings);
    }

    fn on_exit(&mut self) {
        self.autosave();
        self.write_stats();
    }
}

impl ViewerApp {
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
        if let Some(doc) = &mut self.document {
            if redo {
                doc.masks.redo();
            } else if undo {
                doc.masks.undo();
            }
        }
        for file in dropped {
            let path = file.path().to_path_buf();
            self.drop_file(ctx, &path);
        }
        while let Ok((path, image)) = self.screenshots.1.try_recv() {
            self.save_screenshot(ctx, &image, &path);
        }
    }

    /// A dropped file: a camera JSON applies to the open image, a PNG whose
    /// name contains `mask` or `confidence` loads into that layer, anything
    /// else opens as a new image.
    pub fn drop_file(&mut self, ctx: &egui::Context, path: &Path) {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        let has_doc = self.document.is_some();
        if has_doc && name.ends_with(".json") {
            self.load_camera(path);
        } else if has_doc && name.contains("confidence") {
            self.load_mask(Layer::Confidence, path);
        } else if has_doc && name.contains("mask") {
            self.load_mask(Layer::Object, path);
        } else {
            self.open(ctx, path);
        }
    }
}
