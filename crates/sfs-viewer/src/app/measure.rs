//! The measurement hooks: screenshots (on request, and `--screenshot` once
//! the first solve is on screen), frame-time statistics and the latency
//! trials of `--stats`. Uses egui for the screenshot request only; it reads
//! the session's state and never changes it itself.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use eframe::egui;

use sfs_core::io;

/// A screenshot that arrived, with where to save it.
type Screenshot = (PathBuf, Arc<egui::ColorImage>);

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

/// What the app tells [`Measurement::after_frame`] about its state.
pub struct AppState {
    /// Jobs finished so far (any outcome).
    pub completed_jobs: usize,
    /// A solve is running.
    pub running: bool,
    /// A solve waits for the debounce.
    pub solve_pending: bool,
    /// The newest prepared level is on screen (or levels are not prepared).
    pub newest_level_shown: bool,
    /// Why there is nothing to show: no image open, or the last solve
    /// failed.
    pub failure: Option<String>,
}

/// Screenshots and statistics.
pub struct Measurement {
    /// Where `--screenshot` saves (then the app closes).
    screenshot_path: Option<PathBuf>,
    /// Where `--stats` writes on exit.
    stats_path: Option<PathBuf>,
    /// Parameter changes to time (with `stats_path`).
    latency_trials: usize,
    screenshot_requested: bool,
    screenshots: (
        crossbeam_channel::Sender<Screenshot>,
        crossbeam_channel::Receiver<Screenshot>,
    ),
    frames_after_finish: usize,
    stats: Stats,
    /// Where a `--screenshot` run's failure goes.
    failure: ExitReport,
}

impl Measurement {
    /// Hooks for the `--screenshot`, `--stats` and `--latency-trials`
    /// options.
    pub fn new(
        screenshot_path: Option<PathBuf>,
        stats_path: Option<PathBuf>,
        latency_trials: usize,
        failure: ExitReport,
    ) -> Self {
        Self {
            screenshot_path,
            stats_path,
            latency_trials,
            screenshot_requested: false,
            screenshots: crossbeam_channel::unbounded(),
            frames_after_finish: 0,
            failure,
            stats: Stats::default(),
        }
    }

    /// Whether this is a measurement run (`--stats`): it changes alpha
    /// itself, so the user's settings are not stored.
    pub fn is_measuring(&self) -> bool {
        self.stats_path.is_some()
    }

    /// At the start of a frame's UI: the interval since the last frame.
    pub fn frame_started(&mut self, running: bool) {
        if let Some(last) = self.stats.last_frame {
            let ms = last.elapsed().as_secs_f64() * 1e3;
            self.stats.frame_intervals_ms.push(ms);
            if running {
                self.stats.busy_frame_intervals_ms.push(ms);
            } else if self.frames_after_finish > 1 {
                // Continuous repaints while nothing is solved: the baseline.
                self.stats.idle_frame_intervals_ms.push(ms);
            }
        }
        self.stats.last_frame = Some(Instant::now());
    }

    /// At the end of a frame's UI, started at `started`.
    pub fn frame_finished(&mut self, started: Instant) {
        self.stats.ui_ms.push(started.elapsed().as_secs_f64() * 1e3);
    }

    /// The first level of a job went to preparation as `generation`.
    pub fn first_level_submitted(&mut self, generation: u64) {
        self.stats.first_level_generation = Some(generation);
    }

    /// A prepared level of `generation` is on screen: ends a latency trial
    /// once the first level of its job is.
    pub fn level_shown(&mut self, generation: u64) {
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

    /// With `--stats`: whether to start the next latency trial now (after
    /// each finished solve); the caller then changes a parameter and asks
    /// for a solve, as a slider release would.
    pub fn start_latency_trial(&mut self, state: &AppState) -> bool {
        let due = self.stats_path.is_some()
            && self.stats.trials_done < self.latency_trials
            && !state.running
            && self.stats.trial_started.is_none()
            && !state.solve_pending
            && state.completed_jobs > 0;
        if due {
            self.stats.trials_done += 1;
            self.stats.trial_started = Some(Instant::now());
            self.stats.first_level_generation = None;
        }
        due
    }

    /// With `--screenshot`: once the first solve (and every latency trial)
    /// is over and its last level is shown, a few frames later, asks for
    /// the screenshot (the app closes when it is saved). When no image is
    /// open or the solve failed, the screenshot shows the error and the
    /// failure is recorded for the command to exit non-zero.
    pub fn after_frame(&mut self, ctx: &egui::Context, state: &AppState) {
        if self.screenshot_path.is_none() || self.screenshot_requested {
            return;
        }
        if let Some(failure) = &state.failure {
            self.failure.set(failure.clone());
        }
        let done = (state.failure.is_some() && !state.running && !state.solve_pending)
            || state.completed_jobs > 0
                && !state.running
                && self.stats.trials_done >= self.latency_trials
                && self.stats.trial_started.is_none()
                && !state.solve_pending
                && state.newest_level_shown;
        if done {
            self.frames_after_finish += 1;
            // With --stats, also time 40 frames with nothing to solve.
            let wait = if self.stats_path.is_some() { 42 } else { 3 };
            if self.frames_after_finish > wait {
                self.screenshot_requested = true;
                if let Some(path) = self.screenshot_path.clone() {
                    self.request_screenshot(ctx, path);
                }
            }
        }
        ctx.request_repaint();
    }

    /// Asks the integration for a screenshot of the window, saved to `path`
    /// when it arrives.
    pub fn request_screenshot(&self, ctx: &egui::Context, path: PathBuf) {
        let sender = self.screenshots.0.clone();
        let waker = ctx.clone();
        ctx.request_screenshot(move |image| {
            // The app owns the receiver; a closed app has nothing to save.
            let _ = sender.send((path, image));
            waker.request_repaint();
        });
    }

    /// Saves the screenshots that arrived; returns the errors. Closes the
    /// app after the `--screenshot` one.
    pub fn save_screenshots(&self, ctx: &egui::Context) -> Vec<String> {
        let mut errors = Vec::new();
        while let Ok((path, image)) = self.screenshots.1.try_recv() {
            match save_png(&image, &path) {
                Ok(()) => eprintln!("saved screenshot {}", path.display()),
                Err(e) => {
                    let message = format!("cannot save screenshot {}: {e}", path.display());
                    eprintln!("{message}");
                    if self.screenshot_path.as_deref() == Some(path.as_path()) {
                        self.failure.set(message.clone());
                    }
                    errors.push(message);
                }
            }
            if self.screenshot_path.as_deref() == Some(path.as_path()) {
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
        errors
    }

    /// With `--stats`: writes the frame statistics for an image of
    /// `image_size` (on exit).
    pub fn write_stats(&self, image_size: Option<(usize, usize)>) {
        let Some(path) = &self.stats_path else {
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
        let report = serde_json::json!({
            "image_size": image_size,
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

/// Writes an egui screenshot as PNG.
fn save_png(image: &egui::ColorImage, path: &Path) -> Result<(), String> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    image::RgbaImage::from_raw(w as u32, h as u32, bytes)
        .ok_or_else(|| "screenshot has an inconsistent size".to_string())
        .and_then(|img| img.save(path).map_err(|e| e.to_string()))
}

/// A message slot shared between the viewer and the code that launched it.
#[derive(Clone, Debug, Default)]
pub struct ExitReport(std::sync::Arc<std::sync::Mutex<Option<String>>>);

impl ExitReport {
    /// Records `message` (the first one wins).
    pub fn set(&self, message: String) {
        let mut slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        slot.get_or_insert(message);
    }

    /// The recorded message, if any.
    pub fn get(&self) -> Option<String> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}
