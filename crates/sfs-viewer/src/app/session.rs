//! The document session: the open image with its camera and masks, the
//! autosave of the masks and of the known distances, and the solve of that
//! document (the worker, the debounced re-solve, the state of the job on
//! screen, the fit of the known distances; for a photometric-stereo set its
//! solve, and one photograph solved alone to compare). No drawing; uses `document`,
//! `worker`, `solver`, `metrics`, `mask_edit`, `io`, and `images` for the
//! display mapping it keeps.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::mask_edit::{self, Layer, Masks};
use crate::worker::{Event, JobId, SetRequest, Worker};
use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::metrics;
use sfs_core::model_fit::ModelFit;
use sfs_core::params::SolverParams;
use sfs_core::photograph_solve::{PhotographSolve, SolvedPhotograph};
use sfs_core::solver::albedo_fit::divide_out;
use sfs_core::solver::calibrate::KnownDepthFit;
use sfs_core::solver::depth_unit::DepthUnit;
use sfs_core::solver::photometric::{
    PhotometricParams, PhotometricSolution, SingleComparison, compare_single,
};
use sfs_core::solver::{LevelResult, Solution};

use super::document::{Document, KnownDistance, OpenOptions};
use super::images::DisplayMapping;
use super::level_prep::LevelInputs;

/// While a slider is dragged, solve after it rests this long.
const DEBOUNCE: Duration = Duration::from_millis(200);
/// Write the mask autosave this long after the last edit.
const AUTOSAVE_DELAY: Duration = Duration::from_secs(1);
/// Time per frame for draining worker events.
const EVENT_BUDGET: Duration = Duration::from_millis(6);
/// The known distances' file in an image's autosave folder (the one of the
/// photograph, whatever the working size: the points are in its pixels).
const KNOWN_DEPTHS_FILE: &str = "known-depths.json";
const KNOWN_DEPTHS_FORMAT: u32 = 1;

/// Contents of [`KNOWN_DEPTHS_FILE`].
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct KnownDepthsFile {
    format: u32,
    /// The photograph's size the points belong to.
    width: usize,
    height: usize,
    points: Vec<KnownDistance>,
    /// The object's distance given (its median depth), if any.
    #[serde(default)]
    distance: Option<f64>,
}

/// One level as received.
pub struct LevelView {
    /// Level index (0 = coarsest).
    pub level: usize,
    /// Levels in the job.
    pub levels: usize,
    /// Depth at the level's size (shared with the level's mesh preparation).
    pub depth: Arc<Grid<f64>>,
    /// Reprojection at the level's size (shared likewise).
    pub reprojection: Arc<Grid<f64>>,
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
    /// Outer iteration within the level (from 0); `None` for a level
    /// without iterations (a fast-marching start).
    pub iteration: Option<usize>,
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
    /// From the submission to the final result, seconds: the whole wait
    /// (the depth unit's searches and the albedo decision included, which
    /// the final solve's own `seconds` leave out).
    pub waited_seconds: Option<f64>,
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
    /// The final result with everything the core measured of it (the
    /// depth unit, the fit, the occlusion edges, the shadow share, the
    /// warnings, the report).
    pub solved: Option<Box<SolvedPhotograph>>,
    /// RSE and RIE against the ground truth.
    pub errors: Option<(f64, f64)>,
    /// With known distances, the solve of the scale search now running
    /// (from 1; each one streams its levels anew), 0 before its first level.
    pub search_solve: usize,
    /// Why the last job failed.
    pub failure: Option<String>,
    /// Jobs finished so far (any outcome).
    pub completed_jobs: usize,
    /// A set's final result: depth, normals, albedo, each photograph's fit.
    pub set: Option<Box<PhotometricSolution>>,
}

impl SolveState {
    /// The running job has ended (finished, failed or cancelled).
    fn end_job(&mut self) {
        self.running = false;
        self.completed_jobs += 1;
    }

    /// The final result's solution.
    pub fn finished(&self) -> Option<&Solution> {
        self.solved.as_deref().map(|s| &s.solution)
    }

    /// How well the final result explains the image.
    pub fn fit(&self) -> Option<&ModelFit> {
        self.solved.as_deref().map(|s| &s.fit)
    }

    /// Share of the object the final result took out as shadow (lights off
    /// the optical centre).
    pub fn shadow_share(&self) -> Option<f64> {
        self.solved.as_deref().and_then(|s| s.shadow_share)
    }

    /// Where the final result grazes the view beside a much brighter pixel
    /// ([`sfs_core::model_fit::occlusion_edges`]).
    pub fn occlusion_edges(&self) -> Option<&Grid<bool>> {
        self.solved.as_deref().map(|s| &s.occlusion_edges)
    }

    /// The depth unit the last solve decided: which cue set it, how
    /// precisely.
    pub fn depth_unit(&self) -> Option<&DepthUnit> {
        self.solved.as_deref().and_then(|s| s.depth_unit.as_ref())
    }

    /// How the final result met the known distances (`None` without them).
    pub fn known_depth_fit(&self) -> Option<&KnownDepthFit> {
        self.depth_unit()
            .and_then(|u| u.fit.as_ref())
            .filter(|f| !f.points.is_empty())
    }

    /// The intensity scale `s = I_ref Z^2` the final result used
    /// (estimated or given).
    pub fn intensity_scale_used(&self) -> Option<f64> {
        let solution = self.finished()?;
        let s_used = solution.scales.intensity * solution.scales.depth.powi(2);
        s_used.is_finite().then_some(s_used)
    }

    /// Every warning of the final result, most telling first.
    pub fn warnings(&self) -> &[String] {
        self.solved.as_deref().map_or(&[], |s| &s.warnings)
    }
}

/// One photograph of a set solved alone with the single-image method, and
/// how far its shape is from the set's.
#[derive(Default)]
pub struct CompareState {
    /// Its job (it supersedes the set's, which has finished).
    pub job: Option<JobId>,
    /// The photograph (index in the set).
    pub photo: usize,
    /// Running.
    pub running: bool,
    /// [`compare_single`]'s numbers.
    pub comparison: Option<SingleComparison>,
    /// `k z_single - z_set` (`k`: the comparison's scale), NaN where either
    /// has no surface.
    pub difference: Option<Grid<f64>>,
    /// Why it could not be solved or compared.
    pub failure: Option<String>,
    /// Comparisons finished so far (keys the panel's texture).
    pub completed: usize,
    /// Whether the photograph was solved with the set's albedo divided out.
    pub with_set_albedo: bool,
}

/// What `Session::export` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Export {
    /// Depth as float32 `.npy` (NaN = no surface).
    DepthNpy,
    /// Depth as 16-bit PNG (near = white).
    DepthPng,
    /// Triangle mesh, binary PLY with the reprojection as colour.
    MeshPly,
    /// Triangle mesh, Wavefront OBJ.
    MeshObj,
    /// Reprojected image, 16-bit linear PNG.
    Reprojection,
    /// Everything the solve decided and measured (`report.json`, the same
    /// as `solve` writes).
    Report,
}

/// A level of the job on screen, to prepare for display.
pub struct ArrivedLevel {
    /// The level as the solver reported it.
    pub result: LevelResult,
    /// The job's full-size inputs to show it against.
    pub inputs: LevelInputs,
    /// Whether it is the job's first level.
    pub first_of_job: bool,
}

/// The open document and its solve.
pub struct Session {
    /// The open image, if any.
    pub document: Option<Document>,
    /// The solve on screen.
    pub solve: SolveState,
    /// How the input panel (and the reprojection) shows the document's
    /// image: the automatic viewing exposure over the object, then sRGB.
    /// Recomputed when an image is opened or re-read and when an object
    /// mask is loaded from a file, not while painting (the view stays
    /// still); the solver and the hover readout keep the linear values.
    pub display: DisplayMapping,
    worker: Option<Worker>,
    /// Folder of the mask autosaves (`None`: no autosave).
    data_dir: Option<PathBuf>,
    /// Parameters, camera or masks changed at this time: solve after the
    /// debounce.
    dirty_since: Option<Instant>,
    mask_revision_solved: u64,
    autosave_due: Option<Instant>,
    /// The inputs of the running job, for the level preparation.
    level_inputs: Option<LevelInputs>,
    /// One photograph of the set solved alone, compared with the set.
    pub compare: CompareState,
    /// The last level of the job on screen (shown again with another
    /// texture).
    last_level: Option<LevelResult>,
    /// The surface carries a set's albedo instead of the image.
    albedo_texture: bool,
}

impl Session {
    /// A session without a document.
    pub fn new(worker: Option<Worker>, data_dir: Option<PathBuf>) -> Self {
        Self {
            document: None,
            solve: SolveState::default(),
            display: DisplayMapping::default(),
            worker,
            data_dir,
            dirty_since: None,
            mask_revision_solved: 0,
            autosave_due: None,
            level_inputs: None,
            compare: CompareState::default(),
            last_level: None,
            albedo_texture: false,
        }
    }

    /// Opens an image (masks and known distances restored from the
    /// autosave) and asks for a solve; returns notes for the status line.
    /// On failure the previous document stays and the error is returned.
    ///
    /// `paths` name one image, a set folder, or several photographs as one
    /// set ([`Document::open_paths`]); a set's photographs' own layers are
    /// restored too.
    pub fn open_paths(
        &mut self,
        paths: &[PathBuf],
        options: &OpenOptions,
    ) -> Result<Vec<String>, String> {
        let mut doc = Document::open_paths(paths, options).map_err(|e| format!("{e:#}"))?;
        let mut notes = std::mem::take(&mut doc.notes);
        if let (Some(dir), Some(set)) = (self.autosave_dir(&doc), &mut doc.set) {
            let size = doc.masks.size();
            let mut restored = 0;
            for (k, masks) in set.photo_masks.iter_mut().enumerate() {
                match Masks::restore(&photo_layer_dir(&dir, k), size) {
                    Ok(Some(saved)) => {
                        *masks = saved;
                        restored += 1;
                    }
                    Ok(None) => {}
                    Err(e) => notes.push(format!("photograph {}'s layer not restored: {e}", k + 1)),
                }
            }
            if restored > 0 {
                notes.push(format!(
                    "restored {restored} photograph{}'s own confidence from the autosave",
                    if restored == 1 { "" } else { "s" }
                ));
            }
        }
        if let Some(dir) = self.autosave_dir(&doc) {
            match Masks::restore(&dir, doc.size()) {
                Ok(Some(masks)) => {
                    doc.masks = masks;
                    notes.push("restored your painted masks from the autosave".into());
                    // Painted work is never dropped for a file: say which won.
                    if let Some(file) = &options.confidence {
                        notes.push(format!(
                            "the autosaved painting replaces the confidence in {} (File > Load confidence mask… reads the file)",
                            file.display()
                        ));
                    }
                }
                Ok(None) => {}
                Err(e) => notes.push(format!("autosave not restored: {e}")),
            }
        }
        if let Some(path) = self.known_depths_path(&doc) {
            match restore_known_depths(&path, &doc) {
                Ok((points, None)) if points.is_empty() => {}
                Ok((points, distance)) => {
                    if !points.is_empty() {
                        notes.push(format!(
                            "restored {} known distance{}",
                            points.len(),
                            if points.len() == 1 { "" } else { "s" }
                        ));
                    }
                    if let Some(d) = distance {
                        notes.push(format!("restored the object distance {d}"));
                    }
                    doc.known_depths = points;
                    doc.object_distance = distance;
                }
                Err(e) => notes.push(format!(
                    "known distances not restored from {}: {e}",
                    path.display()
                )),
            }
        }
        self.document = Some(doc);
        self.refresh_display();
        self.solve = SolveState::default();
        self.compare = CompareState::default();
        self.last_level = None;
        self.request_solve();
        Ok(notes)
    }

    /// Recomputes [`Session::display`] from the document's image and object
    /// mask (after the image was re-read, e.g. with sRGB decoding toggled).
    pub fn refresh_display(&mut self) {
        if let Some(doc) = &self.document {
            self.display = DisplayMapping::automatic(&doc.image, Some(doc.masks.object()));
        }
    }

    /// Lowers the confidence layer where the model cannot hold
    /// ([`sfs_core::model_fit::suggest_confidence`]; cast shadows from the last
    /// result's reprojection when there is one; with lights off the optical
    /// centre, the shadow the solve takes out,
    /// [`sfs_core::solver::shadows::shadow_mask`]); returns a sentence for
    /// the status line.
    pub fn suggest_confidence(&mut self) -> String {
        let reprojection = self.solve.finished().map(|s| s.reprojection.clone());
        let Some(doc) = &mut self.document else {
            return "no image".into();
        };
        let object = doc
            .masks
            .object_for_solver()
            .unwrap_or_else(|| Grid::filled(doc.image.width(), doc.image.height(), true));
        let reprojection = reprojection.filter(|r| r.size() == doc.image.size());
        let (proposal, mut count) =
            sfs_core::model_fit::suggest_confidence(&doc.image, &object, reprojection.as_ref());
        // With lights off the optical centre, the shadow the solve takes out
        // (the same detection): proposed at 0 too, so the painted layer
        // shows it and the user can edit it.
        let shadow = sfs_core::solver::shadows::shadow_mask(
            &doc.problem(),
            sfs_core::params::DomainMode::default(),
            sfs_core::cancel::Cancel::NEVER,
        )
        .ok()
        .flatten();
        let proposal = match &shadow {
            Some(shadow) => Grid::from_fn(proposal.width(), proposal.height(), |c, r| {
                if *shadow.at(c, r) {
                    if *proposal.at(c, r) > 0.0 {
                        count.shadow += 1;
                    }
                    0.0
                } else {
                    *proposal.at(c, r)
                }
            }),
            None => proposal,
        };
        // Off the object the confidence does not matter: keep what is there.
        let proposal = Grid::from_fn(proposal.width(), proposal.height(), |c, r| {
            if *object.at(c, r) {
                *proposal.at(c, r)
            } else {
                f64::NAN
            }
        });
        match doc.masks.lower_confidence(&proposal) {
            Ok(true) => format!(
                "confidence lowered: {} saturated, {} near-black, {} shadow, {} silhouette \
                 pixels (undo to reject; erase or paint to edit)",
                count.saturated, count.near_black, count.shadow, count.silhouette
            ),
            Ok(false) => "nothing to suggest: the confidence already covers it".into(),
            Err(e) => format!("cannot suggest confidence: {e}"),
        }
    }

    /// The autosave folder of a document: one per image and working size
    /// (masks painted at one working size are never overwritten by those of
    /// another; the full size keeps the plain folder).
    fn autosave_dir(&self, doc: &Document) -> Option<PathBuf> {
        self.data_dir.as_ref().map(|d| {
            let dir = mask_edit::autosave_dir(&doc.path, d);
            let (w, h) = doc.size();
            let mut name = dir.file_name().unwrap_or_default().to_os_string();
            // A set's folder: never the autosave of an image of that name.
            if let Some(set) = &doc.set {
                name.push(format!("-set{}", set.paths.len()));
            }
            if (w, h) != doc.full_size {
                name.push(format!("-{w}x{h}"));
            }
            dir.with_file_name(name)
        })
    }

    /// Where the known distances of `doc` are kept: in the autosave folder
    /// of the photograph itself (not of the working size).
    fn known_depths_path(&self, doc: &Document) -> Option<PathBuf> {
        self.data_dir
            .as_ref()
            .map(|d| mask_edit::autosave_dir(&doc.path, d).join(KNOWN_DEPTHS_FILE))
    }

    /// Writes the open document's known distances now (atomically; an
    /// empty list too, so that a cleared list stays cleared).
    pub fn save_known_depths(&self) -> Result<(), String> {
        let Some(doc) = &self.document else {
            return Ok(());
        };
        let Some(path) = self.known_depths_path(doc) else {
            return Ok(());
        };
        let file = KnownDepthsFile {
            format: KNOWN_DEPTHS_FORMAT,
            width: doc.full_size.0,
            height: doc.full_size.1,
            points: doc.known_depths.clone(),
            distance: doc.object_distance,
        };
        let failed = |e: String| format!("cannot save the known distances: {e}");
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| failed(format!("{}: {e}", dir.display())))?;
        }
        io::write_atomic(&path, |p| io::write_json(p, &file)).map_err(|e| failed(e.to_string()))
    }

    /// Adds a known distance at pixel `(column, row)` of the photograph
    /// (replacing one at the same pixel), saves the list and asks for a
    /// solve. A distance that is not positive and finite, or a pixel off
    /// the image or the object, is refused with the reason and changes
    /// nothing. `Ok` carries a note when the list could not be saved.
    pub fn set_known_depth(
        &mut self,
        column: usize,
        row: usize,
        depth: f64,
    ) -> Result<Option<String>, String> {
        let Some(doc) = &mut self.document else {
            return Err("no image is open".into());
        };
        doc.set_known_depth(KnownDistance {
            column_px: column as f64,
            row_px: row as f64,
            depth,
        })?;
        Ok(self.known_depths_changed())
    }

    /// Sets (or with `None` clears) the object's distance, its median
    /// depth in the camera's unit, saves it beside the known distances and
    /// asks for a solve. A distance that is not positive and finite is
    /// refused with the reason and changes nothing. `Ok` carries a note
    /// when it could not be saved.
    pub fn set_object_distance(&mut self, distance: Option<f64>) -> Result<Option<String>, String> {
        let Some(doc) = &mut self.document else {
            return Err("no image is open".into());
        };
        if let Some(d) = distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(format!("object distance {d}: must be a positive distance"));
        }
        if doc.object_distance == distance {
            return Ok(None);
        }
        doc.object_distance = distance;
        Ok(self.known_depths_changed())
    }

    /// Removes the known distance at `index` (nothing if there is none),
    /// saves the list and asks for a solve; returns a note when saving
    /// failed.
    pub fn remove_known_depth(&mut self, index: usize) -> Option<String> {
        let doc = self.document.as_mut()?;
        if index >= doc.known_depths.len() {
            return None;
        }
        doc.known_depths.remove(index);
        self.known_depths_changed()
    }

    /// Removes every known distance, saves the list and asks for a solve;
    /// returns a note when saving failed.
    pub fn clear_known_depths(&mut self) -> Option<String> {
        let doc = self.document.as_mut()?;
        if doc.known_depths.is_empty() {
            return None;
        }
        doc.known_depths.clear();
        self.known_depths_changed()
    }

    /// After the known distances changed: solve as after a parameter
    /// change, save them.
    fn known_depths_changed(&mut self) -> Option<String> {
        self.request_solve();
        self.save_known_depths().err()
    }

    /// Applies a camera file to the open image and asks for a solve.
    pub fn load_camera(&mut self, path: &Path) -> Result<(), String> {
        let Some(doc) = &mut self.document else {
            return Ok(());
        };
        doc.load_camera(path).map_err(|e| format!("{e:#}"))?;
        self.request_solve();
        Ok(())
    }

    /// Loads a mask PNG into `layer` (undoable); a wrong size is refused.
    pub fn load_mask(&mut self, layer: Layer, path: &Path) -> Result<(), String> {
        let Some(doc) = &mut self.document else {
            return Ok(());
        };
        let photo_size = doc.full_size;
        doc.masks
            .load_png(layer, path, photo_size)
            .map_err(|e| e.to_string())?;
        if layer == Layer::Object {
            self.refresh_display();
        }
        Ok(())
    }

    /// Writes a mask layer as PNG.
    pub fn save_mask(&self, layer: Layer, path: &Path) -> Result<(), String> {
        let Some(doc) = &self.document else {
            return Ok(());
        };
        doc.masks.save_png(layer, path).map_err(|e| e.to_string())
    }

    /// Marks parameters or masks as changed: a new solve starts after the
    /// debounce.
    pub fn request_solve(&mut self) {
        self.dirty_since = Some(Instant::now());
    }

    /// Whether a solve is waiting for the debounce.
    pub fn solve_pending(&self) -> bool {
        self.dirty_since.is_some()
    }

    /// Cancels the running solve.
    pub fn cancel_solve(&mut self) {
        if let (Some(worker), Some(job)) = (&self.worker, self.solve.job) {
            worker.cancel(job);
        }
    }

    /// Submits a solve of the open document with `params` (a set's with
    /// `set_params`) and the masks now.
    pub fn start_solve(&mut self, params: SolverParams, set_params: PhotometricParams) {
        self.dirty_since = None;
        let (Some(doc), Some(worker)) = (&self.document, &mut self.worker) else {
            return;
        };
        if let Some(problem) = doc.set_problem() {
            self.level_inputs = Some(LevelInputs {
                image: Arc::new(doc.image.clone()),
                ground_truth: None,
                object: problem.object_mask.clone().map(Arc::new),
                display: self.display,
                texture: None,
            });
            self.mask_revision_solved = doc.mask_revision();
            let job = worker.submit_set(SetRequest {
                problem,
                params: set_params,
            });
            self.compare.running = false;
            self.compare.job = None;
            self.begin_job(job);
            return;
        }
        let job = doc.photograph_solve(params);
        let refused = job.refusal().or_else(|| {
            job.known_depths()
                .err()
                .map(|e| format!("{e}; remove it or change the mask"))
        });
        if let Some(reason) = refused {
            // The running job (of other masks) is stale: no result of it
            // may appear beside this failure.
            if let Some(job) = self.solve.job.take() {
                worker.cancel(job);
            }
            self.solve.solved = None;
            self.solve.failure = Some(reason);
            self.solve.end_job();
            return;
        }
        self.level_inputs = Some(LevelInputs {
            image: Arc::new(doc.image.clone()),
            ground_truth: doc.ground_truth.clone().map(Arc::new),
            object: job.problem.object_mask.clone().map(Arc::new),
            display: self.display,
            texture: None,
        });
        self.mask_revision_solved = doc.mask_revision();
        let job = worker.submit(job);
        self.begin_job(job);
    }

    /// The state of a job just submitted.
    fn begin_job(&mut self, job: JobId) {
        let solve = &mut self.solve;
        solve.job = Some(job);
        solve.submitted = Some(Instant::now());
        solve.waited_seconds = None;
        solve.running = true;
        solve.arrived.clear();
        solve.energies.clear();
        solve.failure = None;
        solve.solved = None;
        solve.errors = None;
        solve.search_solve = 0;
        solve.set = None;
        self.last_level = None;
    }

    /// Drains the worker's events (a few milliseconds at most) into the
    /// solve state; returns the levels that arrived, for the level
    /// preparation.
    pub fn drain_events(&mut self) -> Vec<ArrivedLevel> {
        let Some(worker) = &mut self.worker else {
            return Vec::new();
        };
        let latest = worker.latest_job();
        let events: Vec<Event> = worker.drain(EVENT_BUDGET).collect();
        let mut levels = Vec::new();
        for event in events {
            if Some(event.job()) == latest && Some(event.job()) == self.compare.job {
                self.receive_comparison(event);
                continue;
            }
            if Some(event.job()) != latest || Some(event.job()) != self.solve.job {
                continue; // a superseded job
            }
            match event {
                Event::Started { .. } => {}
                Event::Progress { report, .. } => {
                    self.next_solve_of_search(report.level);
                    let size = (report.width, report.height);
                    let energy_per_pixel = per_pixel(report.energy.total, size);
                    self.solve.energies.push(EnergyPoint {
                        level: report.level,
                        iteration: Some(report.iteration),
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
                Event::Level { result, .. } => {
                    let arrived = self
                        .level_inputs
                        .clone()
                        .map(|inputs| (result.clone(), inputs));
                    self.receive_level(result);
                    if let Some((result, inputs)) = arrived {
                        levels.push(ArrivedLevel {
                            result,
                            inputs,
                            first_of_job: self.solve.arrived.len() == 1,
                        });
                    }
                }
                Event::Finished { solved, .. } => {
                    let solution = &solved.solution;
                    self.solve.errors = self.document.as_ref().and_then(|doc| {
                        let gt = doc.ground_truth.as_ref()?;
                        // RIE with the material and the scale the solve used.
                        let model = solved.problem.model(solution.material);
                        metrics::errors_with_model(
                            &solution.depth,
                            gt,
                            &doc.image,
                            solved.problem.camera,
                            &model,
                        )
                        .ok()
                        .map(|e| (e.rse, e.rie))
                    });
                    let estimated_albedo = solution.albedo_fit.is_some();
                    self.solve.waited_seconds =
                        self.solve.submitted.map(|t| t.elapsed().as_secs_f64());
                    self.solve.solved = Some(solved);
                    self.solve.end_job();
                    if self.albedo_texture
                        && estimated_albedo
                        && let Some(level) = self.textured_level()
                    {
                        levels.push(level);
                    }
                }
                Event::SetFinished { solution, .. } => {
                    self.solve.set = Some(solution);
                    self.solve.end_job();
                    if self.albedo_texture
                        && let Some(level) = self.textured_level()
                    {
                        levels.push(level);
                    }
                }
                Event::Failed { error, .. } => {
                    self.solve.failure = Some(error);
                    self.solve.end_job();
                }
                Event::Cancelled { .. } => {
                    self.solve.end_job();
                }
            }
        }
        levels
    }

    /// With known distances the worker runs several solves, each from
    /// level 0: a level below the last one plotted starts the next, whose
    /// energies replace the previous solve's.
    fn next_solve_of_search(&mut self, level: usize) {
        let last = self.solve.energies.last().map(|e| e.level);
        if last.is_none_or(|last| level < last) {
            self.solve.search_solve += 1;
            self.solve.energies.clear();
        }
    }

    fn receive_level(&mut self, result: LevelResult) {
        self.last_level = Some(result.clone());
        if self.solve.set.is_none() && self.document.as_ref().is_some_and(|d| d.set.is_some()) {
            // A set's solve reports levels, not iterations.
            self.solve.progress.level = result.level;
            self.solve.progress.levels = result.levels;
            self.solve.progress.size = result.depth.size();
            self.solve.progress.elapsed = result.elapsed;
            self.solve.progress.energy_per_pixel =
                per_pixel(result.energy.total, result.depth.size());
        }
        self.next_solve_of_search(result.level);
        let size = result.depth.size();
        self.solve.arrived.push(size);
        // A level without outer iterations (a fast-marching start) is a
        // point of its own in the energy plot.
        if self.solve.energies.last().map(|e| e.level) != Some(result.level) {
            self.solve.energies.push(EnergyPoint {
                level: result.level,
                iteration: None,
                per_pixel: per_pixel(result.energy.total, size),
            });
        }
        self.solve.latest = Some(LevelView {
            level: result.level,
            levels: result.levels,
            depth: result.depth,
            reprojection: result.reprojection,
        });
    }

    /// Whether the surface carries the albedo (a set's, or the one a single
    /// photograph's finished solve used) instead of the image; a change
    /// returns the last level again with that texture, to prepare for
    /// display.
    pub fn set_albedo_texture(&mut self, albedo: bool) -> Option<ArrivedLevel> {
        if self.albedo_texture == albedo {
            return None;
        }
        self.albedo_texture = albedo;
        self.textured_level()
    }

    /// The albedo the surface can carry: a set's, or the one the finished
    /// single-image solve used (its estimate, or 1 where it kept albedo 1;
    /// `None` when it estimated none).
    pub fn surface_albedo(&self) -> Option<Grid<f64>> {
        match &self.solve.set {
            Some(set) => Some(set.albedo.clone()),
            None => {
                let solution = self.solve.finished()?;
                Some(solution.albedo_fit.as_ref()?.used_albedo(&solution.depth))
            }
        }
    }

    /// The last level with the texture chosen (the albedo when there is one
    /// and it is chosen, else the image).
    fn textured_level(&self) -> Option<ArrivedLevel> {
        let result = self.last_level.clone()?;
        let mut inputs = self.level_inputs.clone()?;
        inputs.texture = self
            .albedo_texture
            .then(|| self.surface_albedo())
            .flatten()
            .filter(|albedo| albedo.size() == inputs.image.size())
            .map(Arc::new);
        Some(ArrivedLevel {
            result,
            inputs,
            first_of_job: false,
        })
    }

    /// Solves photograph `index` of the open set alone with the
    /// single-image method and `params`, through the same pipeline (that
    /// photograph, the set's camera file: its light found by its name; the
    /// painted masks), to compare with the set's finished shape. Needs the
    /// set's result; a failure is kept in [`CompareState::failure`].
    /// With `set_albedo` the set's albedo is divided out of the photograph
    /// (absolute when the set's intensities were measured, else `s rho`
    /// with `s = 1`) and the solve takes albedo 1.
    pub fn solve_single(&mut self, index: usize, params: SolverParams, set_albedo: bool) {
        self.compare.photo = index;
        self.compare.with_set_albedo = set_albedo;
        self.compare.comparison = None;
        self.compare.difference = None;
        self.compare.failure = None;
        let (Some(doc), Some(worker)) = (&self.document, &mut self.worker) else {
            return;
        };
        if self.solve.set.is_none() {
            self.compare.failure = Some("solve the set first".into());
            return;
        }
        let prepared = doc
            .single_input(index)
            .ok_or_else(|| format!("the set has no photograph {}", index + 1))
            .and_then(|input| sfs_core::photo::prepare(&input).map_err(|e| format!("{e}")));
        let prepared = match prepared {
            Ok(prepared) if prepared.size() == doc.size() => prepared,
            Ok(prepared) => {
                self.compare.failure = Some(format!(
                    "the photograph alone is read at {}x{}, the set at {}x{}",
                    prepared.size().0,
                    prepared.size().1,
                    doc.size().0,
                    doc.size().1
                ));
                return;
            }
            Err(e) => {
                self.compare.failure = Some(e);
                return;
            }
        };
        let mut problem = sfs_core::solver::Problem {
            camera: doc.camera.intrinsics(),
            object_mask: doc.masks.object_for_solver(),
            confidence: doc.masks.confidence_for_solver(),
            ..prepared.problem.clone()
        };
        let mut params = params;
        let mut estimate_scale = !prepared.intensity_scale_given;
        if set_albedo && let Some(set) = &self.solve.set {
            // A relative albedo is `s rho`: it carries the scale.
            let (divided, divisor) = divide_out(&problem, &set.albedo);
            problem = divided;
            if set.albedo_relative {
                problem.intensity_scale = 1.0 / divisor;
            }
            params.albedo = sfs_core::params::AlbedoChoice::One;
            estimate_scale = estimate_scale && !set.albedo_relative;
        }
        let mut request =
            PhotographSolve::of_prepared(&prepared, params, sfs_core::solver::Method::Linearised);
        request.problem = problem;
        request.scale_given = !estimate_scale;
        let job = worker.submit(request);
        self.compare.job = Some(job);
        self.compare.running = true;
    }

    /// An event of the comparison's job.
    fn receive_comparison(&mut self, event: Event) {
        match event {
            Event::Finished { solved, .. } => {
                let solution = &solved.solution;
                self.compare.running = false;
                self.compare.completed += 1;
                let (Some(set), Some(doc)) = (&self.solve.set, &self.document) else {
                    return;
                };
                let camera = doc.camera.intrinsics();
                match compare_single(&set.depth, &solution.depth, camera) {
                    Some(comparison) => {
                        let k = comparison.scale_to_set;
                        self.compare.difference =
                            Some(set.depth.zip_map(&solution.depth, |s, z| k * z - s));
                        self.compare.comparison = Some(comparison);
                    }
                    None => {
                        self.compare.failure =
                            Some("the two surfaces share no solved pixel".into());
                    }
                }
            }
            Event::Failed { error, .. } => {
                self.compare.running = false;
                self.compare.completed += 1;
                self.compare.failure = Some(error);
            }
            Event::Cancelled { .. } => {
                self.compare.running = false;
                self.compare.completed += 1;
            }
            _ => {}
        }
    }

    /// The timers: a mask edit (once no `gesture` is in progress) asks for
    /// a solve and an autosave; a pending solve starts with `params` when
    /// the pointer is up or after the debounce; a due autosave is written.
    /// Returns an autosave error; `repaint_after` is told when to look
    /// again.
    pub fn tick(
        &mut self,
        gesture: bool,
        pointer_down: bool,
        params: impl FnOnce() -> (SolverParams, PhotometricParams),
        repaint_after: impl Fn(Duration),
    ) -> Option<String> {
        if let Some(doc) = &self.document {
            let revision = doc.mask_revision();
            if revision != self.mask_revision_solved && !gesture {
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
            let dragging = pointer_down && !gesture;
            if !dragging || waited >= DEBOUNCE {
                let (params, set_params) = params();
                self.start_solve(params, set_params);
            } else {
                repaint_after(DEBOUNCE.saturating_sub(waited));
            }
        }
        if let Some(due) = self.autosave_due {
            if Instant::now() >= due {
                self.autosave_due = None;
                return self.autosave().err();
            }
            repaint_after(due - Instant::now());
        }
        None
    }

    /// Writes the masks' autosave now.
    pub fn autosave(&self) -> Result<(), String> {
        let Some(doc) = &self.document else {
            return Ok(());
        };
        let Some(dir) = self.autosave_dir(doc) else {
            return Ok(());
        };
        doc.masks
            .autosave(&dir, &doc.path)
            .map_err(|e| format!("mask autosave failed: {e}"))?;
        if let Some(set) = &doc.set {
            for (k, (masks, path)) in set.photo_masks.iter().zip(&set.paths).enumerate() {
                masks
                    .autosave(&photo_layer_dir(&dir, k), path)
                    .map_err(|e| format!("mask autosave failed: {e}"))?;
            }
        }
        Ok(())
    }

    /// Writes the finished result; returns what to say on the status line.
    pub fn export(&self, path: &Path, what: Export) -> Result<String, String> {
        if let (Some(set), Some(doc)) = (&self.solve.set, &self.document) {
            let camera = doc.camera.intrinsics();
            let result = match what {
                Export::DepthNpy | Export::DepthPng | Export::MeshPly | Export::MeshObj => {
                    write_depth(path, what, &set.depth, &camera, &set.albedo)
                }
                Export::Reprojection => {
                    return Err("a set's solve keeps each photograph's residual, not a \
                                reprojection: export the depth or the mesh"
                        .into());
                }
                Export::Report => {
                    return Err(
                        "a set's report is written by `solve --photometric-stereo`: \
                                export the depth or the mesh"
                            .into(),
                    );
                }
            };
            return result
                .map(|()| format!("wrote {}", path.display()))
                .map_err(|e| e.to_string());
        }
        let (Some(solved), Some(doc)) = (self.solve.solved.as_deref(), &self.document) else {
            return Err("nothing to export yet: the solve has not finished".into());
        };
        let solution = &solved.solution;
        let camera = doc.camera.intrinsics();
        let result = match what {
            Export::DepthNpy | Export::DepthPng | Export::MeshPly | Export::MeshObj => {
                write_depth(path, what, &solution.depth, &camera, &solution.reprojection)
            }
            Export::Reprojection => io::write_png16(path, &solution.reprojection),
            Export::Report => io::write_json(path, &solved.report(self.solve.errors)),
        };
        result
            .map(|()| format!("wrote {}", path.display()))
            .map_err(|e| e.to_string())
    }
}

/// Writes the exports made of the depth: the depth as `.npy` or 16-bit PNG,
/// the mesh as `.ply` (shaded by `shade`) or `.obj`; nothing for the others.
fn write_depth(
    path: &Path,
    what: Export,
    depth: &Grid<f64>,
    camera: &sfs_core::camera::Intrinsics,
    shade: &Grid<f64>,
) -> Result<(), io::IoError> {
    match what {
        Export::DepthNpy => io::write_npy_f32(path, depth),
        Export::DepthPng => io::write_depth_png16(path, depth).map(|_| ()),
        Export::MeshPly => io::write_depth_ply(path, depth, camera, Some(shade)),
        Export::MeshObj => io::write_depth_obj(path, depth, camera),
        Export::Reprojection | Export::Report => Ok(()),
    }
}

/// The known distances saved for `doc`'s photograph at `path`: none when
/// there is no file; an error when it is corrupt or of another photograph
/// size. Points that cannot be given (not positive, off the photograph)
/// are left out; points off the object are kept (the mask may change, and
/// the solve says why it cannot use them).
fn restore_known_depths(
    path: &Path,
    doc: &Document,
) -> Result<(Vec<KnownDistance>, Option<f64>), String> {
    let text = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((Vec::new(), None)),
        Err(e) => return Err(e.to_string()),
    };
    let file: KnownDepthsFile = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    if file.format != KNOWN_DEPTHS_FORMAT {
        return Err(format!("unknown format {}", file.format));
    }
    let (fw, fh) = doc.full_size;
    if (file.width, file.height) != (fw, fh) {
        return Err(format!(
            "saved for a {}x{} photograph but it is {fw}x{fh}",
            file.width, file.height
        ));
    }
    let points = file
        .points
        .into_iter()
        .filter(|p| {
            p.depth.is_finite()
                && p.depth > 0.0
                && p.column_px >= 0.0
                && p.row_px >= 0.0
                && p.column_px < fw as f64
                && p.row_px < fh as f64
        })
        .collect();
    let distance = file.distance.filter(|d| d.is_finite() && *d > 0.0);
    Ok((points, distance))
}

/// The autosave folder of a set's photograph `index`'s own layer, inside
/// the set's.
fn photo_layer_dir(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("photo-{}", index + 1))
}
