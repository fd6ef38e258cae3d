//! One photograph's solve after the photo pipeline, written once for every
//! front: what the command line's `solve` and the viewer both do with a
//! prepared photograph. A [`PhotographSolve`] holds what a front collected
//! (the problem, parameters, method, known distances, the pipeline's
//! report); it refuses what cannot be solved ([`PhotographSolve::refusal`],
//! [`PhotographSolve::known_depths`]), decides the depth unit and solves
//! ([`PhotographSolve::solve`], through
//! [`crate::solver::depth_unit::solve_photograph`], which decides the
//! albedo and material too), and measures the result
//! ([`PhotographSolve::finish`]): the fit, the per-photograph fits, the
//! occlusion edges, the shadow share, the notes and the warnings, and the
//! report ([`SolvedPhotograph::report`], `report.json`). [`options`] reads
//! the user's options into the pipeline's input and a checked solve. The
//! fronts only collect inputs, show outputs and write files.
//!
//! Uses: `photo` (the report and the summed photographs), `solver` (the
//! solve, the depth unit, the fits), `model_fit`, `light`, `params`,
//! `metrics`.

pub mod options;
mod report;

use crate::grid::Grid;
use crate::model_fit::{self, ModelFit};
use crate::params::{self, InitialDepth, SolverParams};
use crate::photo::{self, PhotoFit, PhotoReport, PreparedPhoto, SummedPhoto};
use crate::solver::calibrate::KnownDepth;
use crate::solver::depth_unit::{self, DepthUnit, DistanceCues, UnitSource};
use crate::solver::{Method, Problem, Solution, SolveError, SolveObserver};

pub use report::{DepthRange, SolveInput, SolveReport};

/// One outer iteration of a solve as a progress step: `(done, total,
/// message)` counted in outer iterations over `kappa` per level, for every
/// front's progress bar.
pub fn progress_step(report: &crate::solver::IterationReport, kappa: usize) -> (u64, u64, String) {
    let total = (report.levels * kappa) as u64;
    let done = (report.level * kappa + report.iteration + 1) as u64;
    (
        done.min(total),
        total,
        format!(
            "level {}/{} {}x{}  E = {:.4e}",
            report.level + 1,
            report.levels,
            report.width,
            report.height,
            report.energy.total
        ),
    )
}

/// A known distance is met when the solved depth there is within this
/// share of the given one.
pub const KNOWN_DEPTH_MET: f64 = 0.005;

/// A distance the user knows at a pixel of the photograph as given (not
/// the working copy): the surface there lies at `depth` (the camera's
/// unit).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KnownDistance {
    /// Pixel column in the photograph as given.
    pub column_px: f64,
    /// Pixel row in the photograph as given.
    pub row_px: f64,
    /// The distance (depth, the camera's unit).
    pub depth: f64,
}

/// Why a known distance cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum KnownDistanceError {
    /// The distance is not a positive finite number.
    #[error("the distance must be a positive number, not {0}")]
    NotPositive(f64),
    /// The distance is outside the depths the solver represents.
    #[error("the distance must lie in [{min:e}, {max:e}] depth units (check its unit)")]
    OutOfRange {
        /// Smallest depth.
        min: f64,
        /// Largest depth.
        max: f64,
    },
    /// The pixel is outside the photograph.
    #[error("the pixel is outside the {width}x{height} photograph")]
    Outside {
        /// Photograph width.
        width: usize,
        /// Photograph height.
        height: usize,
    },
    /// The pixel is not on the object mask.
    #[error(
        "the pixel is off the object (the object mask): a known distance must be a point of \
         the surface"
    )]
    OffObject,
}

/// Why a photograph is not solved.
#[derive(Debug, thiserror::Error)]
pub enum PhotographSolveError {
    /// Nothing to solve: the reason, naming the input that causes it.
    #[error("{0}")]
    Refused(String),
    /// A known distance cannot be used.
    #[error("known distance at pixel ({x}, {y}): {error}", x = .point.column_px, y = .point.row_px)]
    KnownDistance {
        /// The point as given.
        point: KnownDistance,
        /// Why.
        error: KnownDistanceError,
    },
    /// The object's distance is not a positive finite number.
    #[error("the object's distance {0} must be a positive distance (the camera file's unit)")]
    Distance(f64),
    /// The solve failed or was cancelled.
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// Everything a front collected for one photograph's solve.
#[derive(Clone, Debug)]
pub struct PhotographSolve {
    /// The working-size problem (image, camera, masks, lights, scale).
    pub problem: Problem,
    /// Solver parameters.
    pub params: SolverParams,
    /// The scheme.
    pub method: Method,
    /// The initial depth as the user gave it (a file name, a number), for
    /// the report; `None`: the parameters' own.
    pub initial_depth_given: Option<String>,
    /// The photo pipeline's report (files, camera, lights, notes).
    pub photo: PhotoReport,
    /// The photograph's own size `(width, height)`.
    pub full_size: (usize, usize),
    /// Where a photograph was clipped (saturated), working size.
    pub clipped: Option<Grid<bool>>,
    /// The photographs of a sum, each with its own light.
    pub photos: Vec<SummedPhoto>,
    /// Whether the intensity scale was given (measured): it sets the unit.
    pub scale_given: bool,
    /// Whether the confidence was derived by the pipeline (written out as
    /// `confidence_used.png`).
    pub confidence_derived: bool,
    /// Distances the user knows at pixels of the photograph as given.
    pub known_distances: Vec<KnownDistance>,
    /// The object's distance (median depth) the user gives.
    pub distance: Option<f64>,
}

impl PhotographSolve {
    /// A solve of a problem that came from no file (a render, a test): the
    /// report describes the problem itself; the intensity scale counts as
    /// given where `scale_given`.
    pub fn new(problem: Problem, params: SolverParams, method: Method, scale_given: bool) -> Self {
        let (width, height) = problem.image.size();
        let camera = problem.camera;
        let photo = PhotoReport {
            images: Vec::new(),
            full_width: width,
            full_height: height,
            width,
            height,
            srgb: false,
            srgb_reason: "linear data".into(),
            ambient: None,
            ambient_clamped_share: 0.0,
            vignetting: None,
            albedo: None,
            albedo_untrusted_share: 0.0,
            mask: None,
            confidence: None,
            auto_confidence: None,
            camera: photo::CameraReport {
                focal: camera.focal_px,
                cx: camera.principal_x_px,
                cy: camera.principal_y_px,
                source: photo::CameraSource::Given,
                intensity_scale: problem.intensity_scale,
                intensity_scale_given: scale_given,
                units: None,
            },
            lights: problem.lights.clone(),
            rig_lights: Vec::new(),
            float_scale: None,
            sum_divisor: None,
            clipped_share: None,
            notes: Vec::new(),
        };
        Self {
            problem,
            params,
            method,
            initial_depth_given: None,
            photo,
            full_size: (width, height),
            clipped: None,
            photos: Vec::new(),
            scale_given,
            confidence_derived: false,
            known_distances: Vec::new(),
            distance: None,
        }
    }

    /// A solve of a prepared photograph with `params` and `method`, no
    /// distance given (a copy of the photograph: see [`Self::from_prepared`]).
    pub fn of_prepared(prepared: &PreparedPhoto, params: SolverParams, method: Method) -> Self {
        Self::from_prepared(prepared.clone(), params, method)
    }

    /// [`Self::of_prepared`] taking the prepared photograph, so that its
    /// image is not copied (8 bytes per pixel for a front that has no other
    /// use for it).
    pub fn from_prepared(prepared: PreparedPhoto, params: SolverParams, method: Method) -> Self {
        let full_size = prepared.full_size();
        Self {
            problem: prepared.problem,
            params,
            method,
            initial_depth_given: None,
            photo: prepared.report,
            full_size,
            clipped: prepared.clipped,
            photos: prepared.photos,
            scale_given: prepared.intensity_scale_given,
            confidence_derived: prepared.confidence_derived,
            known_distances: Vec::new(),
            distance: None,
        }
    }

    /// The unit of depth the camera file names, else `"depth units"`.
    pub fn unit_name(&self) -> &str {
        self.photo.camera.units.as_deref().unwrap_or("depth units")
    }

    /// Why this photograph cannot be solved at all (`None`: it can): too
    /// dark on every object pixel, with the cause where the input names
    /// one (an empty object mask, an ambient frame as bright as the
    /// photograph, an albedo of zero).
    pub fn refusal(&self) -> Option<String> {
        let image = &self.problem.image;
        let object = self.problem.object_mask.as_ref();
        let reason = model_fit::too_dark_to_solve(image, object)?;
        let report = &self.photo;
        if object.is_some_and(|m| !m.as_slice().iter().any(|&o| o)) {
            return Some(format!(
                "the object mask {} marks no pixel as object (white = object)",
                report
                    .mask
                    .as_deref()
                    .map_or_else(String::new, |p| p.display().to_string())
            ));
        }
        if let Some(ambient) = &report.ambient
            && !image
                .as_slice()
                .iter()
                .zip(0..)
                .any(|(&v, q)| v > 0.0 && object.is_none_or(|m| m.as_slice()[q]))
        {
            return Some(format!(
                "after subtracting the ambient frame {} the image is black on every object \
                 pixel: the ambient frame is at least as bright as the photograph there (the \
                 wrong frame, or the two swapped?)",
                ambient.display()
            ));
        }
        if let Some(albedo) = &report.albedo
            && report.albedo_untrusted_share >= 0.999
        {
            return Some(format!(
                "the albedo {} is zero (below the smallest albedo divided out) on every object \
                 pixel",
                albedo.display()
            ));
        }
        Some(reason)
    }

    /// The working-size pixel of a photograph pixel:
    /// `((x + 0.5) * w / W - 0.5).round()`.
    pub fn working_pixel(&self, column_px: f64, row_px: f64) -> (f64, f64) {
        working_pixel(self.full_size, self.problem.image.size(), column_px, row_px)
    }

    /// A known distance as the solver takes it (working-size pixel), or
    /// why it cannot be used.
    pub fn known_depth(&self, point: &KnownDistance) -> Result<KnownDepth, KnownDistanceError> {
        known_depth(
            point,
            self.full_size,
            self.problem.image.size(),
            self.problem.object_mask.as_ref(),
        )
    }

    /// Every known distance as the solver takes it, or the first that
    /// cannot be used.
    pub fn known_depths(&self) -> Result<Vec<KnownDepth>, PhotographSolveError> {
        self.known_distances
            .iter()
            .map(|point| {
                self.known_depth(point)
                    .map_err(|error| PhotographSolveError::KnownDistance {
                        point: *point,
                        error,
                    })
            })
            .collect()
    }

    /// Options given that this input leaves without effect (each also a
    /// warning).
    pub fn unused_options(&self) -> Vec<String> {
        let mut unused = Vec::new();
        if self.params.shadow_bound && self.problem.light_is_centred() {
            unused.push(
                "--shadow-bound on: the light is at the optical centre, so the surface casts no \
                 shadow the camera sees and there is nothing to bound"
                    .into(),
            );
        }
        if matches!(self.method, Method::FastMarching(_)) {
            if let Some(start) = &self.initial_depth_given {
                unused.push(format!(
                    "--init-depth {start}: fast marching computes the depth from the image \
                     alone, from no start"
                ));
            }
            if self.problem.confidence.is_some() {
                unused.push(
                    "--confidence / --auto-confidence: fast marching weighs every object pixel \
                     alike (it has no confidence)"
                        .into(),
                );
            }
        }
        unused
    }

    /// The cues to the depth unit: the known distances (checked), the
    /// object's distance, whether the scale was given, the rig's lights.
    pub fn distance_cues(&self) -> Result<DistanceCues, PhotographSolveError> {
        if let Some(d) = self.distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(PhotographSolveError::Distance(d));
        }
        Ok(DistanceCues {
            known_depths: self.known_depths()?,
            distance: self.distance,
            scale_given: self.scale_given,
            rig_lights: self.photo.rig_lights.clone(),
        })
    }

    /// Solves: refuses what cannot be solved, decides the depth unit (and
    /// with `--albedo auto` / `--reflectance auto` the albedo and the
    /// material) and solves. Returns the problem with the intensity scale
    /// used, the solution and the depth unit.
    ///
    /// # Errors
    /// [`PhotographSolveError::Refused`] for an image too dark to solve, a
    /// known distance or object distance that cannot be used, else the
    /// solver's error (cancelled included).
    pub fn solve(
        &self,
        observer: &mut dyn SolveObserver,
    ) -> Result<(Problem, Solution, DepthUnit), PhotographSolveError> {
        if let Some(reason) = self.refusal() {
            return Err(PhotographSolveError::Refused(reason));
        }
        let cues = self.distance_cues()?;
        self.solve_problem(self.problem.clone(), &cues, observer)
    }

    /// [`Self::solve`] of `problem` (this job's, refusal checked) with
    /// `cues` (this job's).
    fn solve_problem(
        &self,
        mut problem: Problem,
        cues: &DistanceCues,
        observer: &mut dyn SolveObserver,
    ) -> Result<(Problem, Solution, DepthUnit), PhotographSolveError> {
        let (solution, unit) =
            depth_unit::solve_photograph(&mut problem, &self.params, &self.method, cues, observer)?;
        Ok((problem, solution, unit))
    }

    /// [`Self::run`] for a job solved once: the solve takes the job's
    /// image instead of a copy of it (8 bytes per pixel less at the peak).
    ///
    /// # Errors
    /// As [`Self::solve`].
    pub fn run_once(
        mut self,
        observer: &mut dyn SolveObserver,
    ) -> Result<SolvedPhotograph, PhotographSolveError> {
        if let Some(reason) = self.refusal() {
            return Err(PhotographSolveError::Refused(reason));
        }
        // Read where the image is (the known distances' working pixels).
        let cues = self.distance_cues()?;
        // What `finish` reads of the job's problem (its confidence and
        // lights) stays; only the image moves.
        let image = std::mem::replace(&mut self.problem.image, Grid::filled(0, 0, 0.0));
        let problem = Problem {
            image,
            ..self.problem.clone()
        };
        let (problem, solution, unit) = self.solve_problem(problem, &cues, observer)?;
        Ok(self.finish(problem, solution, Some(unit)))
    }

    /// [`Self::solve`] then [`Self::finish`].
    ///
    /// # Errors
    /// As [`Self::solve`].
    pub fn run(
        &self,
        observer: &mut dyn SolveObserver,
    ) -> Result<SolvedPhotograph, PhotographSolveError> {
        let (problem, solution, unit) = self.solve(observer)?;
        Ok(self.finish(problem, solution, Some(unit)))
    }

    /// Measures a solution of this photograph (`problem`: the one solved,
    /// with the intensity scale used): the fit to the image (and to each
    /// photograph of a sum), the occlusion edges, the shadow share, the
    /// notes and the warnings. `depth_unit`: `None` where the solve did
    /// not decide one.
    pub fn finish(
        &self,
        problem: Problem,
        solution: Solution,
        depth_unit: Option<DepthUnit>,
    ) -> SolvedPhotograph {
        let camera = problem.camera;
        let domain = solution.depth.map(|z| z.is_finite());
        let confidence = problem.confidence.as_ref();
        // A sum of photographs is saturated where one of them was, not
        // where its value is.
        let sum_divisor = self.photo.sum_divisor.unwrap_or(1.0);
        let fit = model_fit::measure_photographs(
            &problem.image,
            &solution.reprojection,
            &domain,
            confidence,
            solution.scales.intensity,
            model_fit::Photographs {
                saturated: self.clipped.as_ref(),
                scale: sum_divisor,
            },
        );
        // Geometry of the solved surface: where it grazes the view beside a
        // brighter surface (what lies behind was joined to the contour).
        let occlusion_edges = model_fit::occlusion_edges(&problem.image, &solution.depth, camera);
        let fit = fit.with_occlusion_edges(&occlusion_edges, &solution.depth);
        let fit_per_photo = photo::fit_per_photo(
            &self.photos,
            &solution,
            camera,
            problem.intensity_scale,
            confidence,
            sum_divisor,
        );
        let object_pixels = problem
            .object_mask
            .as_ref()
            .map_or(problem.image.len(), |m| {
                m.as_slice().iter().filter(|&&o| o).count()
            });
        let shadow_share = solution.shadow.as_ref().map(|shadow| {
            shadow.as_slice().iter().filter(|&&s| s).count() as f64 / object_pixels.max(1) as f64
        });
        let mut unused_options = self.unused_options();
        unused_options.extend(solution.unused_parameters.iter().cloned());
        let unit_name = self.unit_name().to_owned();
        let mut notes = self.photo.notes.clone();
        let mut warnings = Vec::new();
        if let Some(unit) = &depth_unit {
            unit_notes_and_warnings(unit, &unit_name, &mut notes, &mut warnings);
        }
        warnings.extend(fit.warnings.iter().cloned());
        if let Some(fit) = &solution.material_fit
            && !fit.best.is_lambert()
        {
            warnings.push(fit.summary.clone());
        }
        if let Some(close) = solution.albedo_fit.as_ref().and_then(|f| f.close_call()) {
            warnings.push(format!("albedo: {close}"));
        }
        warnings.extend(crate::light::lights_that_miss(
            &problem.lights,
            &solution.depth,
            &camera,
        ));
        warnings.extend(unused_options.iter().map(|u| format!("unused option {u}")));
        if let Some(dark) =
            model_fit::darkness_warning(&problem.image, problem.object_mask.as_ref())
            && !warnings.iter().any(|w| w.contains("too dark"))
        {
            warnings.insert(0, dark);
        }
        let mut photo = self.photo.clone();
        photo.camera.intensity_scale = problem.intensity_scale;
        photo.lights = problem.lights.clone();
        SolvedPhotograph {
            input: SolveInput {
                photo,
                known_depth: self
                    .known_distances
                    .iter()
                    .map(|p| [p.column_px, p.row_px, p.depth])
                    .collect(),
                distance: self.distance,
            },
            params: self.params.clone(),
            initial_depth_given: self.initial_depth_given.clone(),
            method: self.method.clone(),
            problem,
            solution,
            depth_unit,
            fit,
            fit_per_photo,
            occlusion_edges,
            shadow_share,
            notes,
            warnings,
            unused_options,
            confidence_derived: self.confidence_derived,
        }
    }
}

/// The depth unit's words (a note) and warnings, and those of the known
/// distances' fit: the scale, each point's residual, how precisely the
/// points fix it, a point not met.
fn unit_notes_and_warnings(
    unit: &DepthUnit,
    unit_name: &str,
    notes: &mut Vec<String>,
    warnings: &mut Vec<String>,
) {
    notes.push(unit.words(unit_name));
    let mut first = Vec::new();
    if let Some(fit) = unit.fit.as_ref().filter(|f| !f.points.is_empty()) {
        notes.push(format!(
            "depth scale from the known distances: s = {:.4e} after {} solve{}; {}",
            fit.intensity_scale,
            fit.solves,
            if fit.solves == 1 { "" } else { "s" },
            fit.points
                .iter()
                .map(|p| format!(
                    "pixel {},{} given {} solved {} ({:+.2} %)",
                    p.column_px,
                    p.row_px,
                    shown(p.given),
                    shown(p.solved),
                    100.0 * p.relative_residual
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ));
        if let Some(precision) = &fit.scale_precision {
            let points = fit.points.len();
            match precision.warning(points) {
                Some(warning) => first.push(warning),
                None => notes.push(precision.words(points)),
            }
        }
        if let Some(worst) = fit
            .points
            .iter()
            .max_by(|a, b| {
                a.relative_residual
                    .abs()
                    .total_cmp(&b.relative_residual.abs())
            })
            .filter(|p| p.relative_residual.abs() > KNOWN_DEPTH_MET)
        {
            first.push(format!(
                "a known distance is not met: pixel {},{} (working size) is at {} for the given \
                 {} ({:+.2} %){}; the depth unit is off by about that much",
                worst.column_px,
                worst.row_px,
                shown(worst.solved),
                shown(worst.given),
                100.0 * worst.relative_residual,
                if fit.points.len() > 1 {
                    " (several points: they may disagree with each other)"
                } else if fit.converged {
                    ""
                } else {
                    " (the scale search did not settle)"
                }
            ));
        }
    }
    if let Some(median) = unit.fit.as_ref().and_then(|f| f.median_depth)
        && median.relative_residual.abs() > KNOWN_DEPTH_MET
        && unit.source == UnitSource::Distance
    {
        first.push(format!(
            "the object's distance is not met: the surface's median depth is {} for the given \
             {} ({:+.2} %); the depth unit is off by about that much",
            shown(median.solved),
            shown(median.given),
            100.0 * median.relative_residual
        ));
    }
    // Only a search for distances the user gave: the shading's own search
    // at the defaults has its verdict in the unit's words.
    if let Some(fit) = unit.fit.as_ref().filter(|f| !f.points.is_empty())
        && !fit.converged
        && first.is_empty()
    {
        first.push(
            "the scale search for the distances did not settle; the residuals say how far off \
             it stopped"
                .into(),
        );
    }
    // Most telling first: the loose scale, the distance not met, the unit.
    warnings.extend(first);
    if let Some(w) = unit.warning(unit_name) {
        warnings.push(w);
    }
}

/// The working-size pixel of pixel `(column_px, row_px)` of a photograph
/// of `full_size` read at `working_size`.
pub fn working_pixel(
    full_size: (usize, usize),
    working_size: (usize, usize),
    column_px: f64,
    row_px: f64,
) -> (f64, f64) {
    let (w, h) = working_size;
    let (fw, fh) = full_size;
    (
        ((column_px + 0.5) * w as f64 / fw as f64 - 0.5).round(),
        ((row_px + 0.5) * h as f64 / fh as f64 - 0.5).round(),
    )
}

/// A known distance at a pixel of a photograph of `full_size`, as the
/// solver takes it at `working_size`: or why it cannot be used (not a
/// positive depth in the solver's range, outside the photograph, off the
/// object mask).
pub fn known_depth(
    point: &KnownDistance,
    full_size: (usize, usize),
    working_size: (usize, usize),
    object: Option<&Grid<bool>>,
) -> Result<KnownDepth, KnownDistanceError> {
    let KnownDistance {
        column_px: x,
        row_px: y,
        depth,
    } = *point;
    if !(depth.is_finite() && depth > 0.0) {
        return Err(KnownDistanceError::NotPositive(depth));
    }
    let (min, max) = params::DEPTH_RANGE;
    if !(min..=max).contains(&depth) {
        return Err(KnownDistanceError::OutOfRange { min, max });
    }
    let (fw, fh) = full_size;
    if !(x >= 0.0 && y >= 0.0 && x < fw as f64 && y < fh as f64) {
        return Err(KnownDistanceError::Outside {
            width: fw,
            height: fh,
        });
    }
    let (c, r) = working_pixel(full_size, working_size, x, y);
    let (w, h) = working_size;
    let inside = c >= 0.0 && r >= 0.0 && (c as usize) < w && (r as usize) < h;
    if !inside || object.is_some_and(|m| !*m.at(c as usize, r as usize)) {
        return Err(KnownDistanceError::OffObject);
    }
    Ok(KnownDepth {
        column_px: c,
        row_px: r,
        depth,
    })
}

/// A depth or distance as the user reads it: four decimals for moderate
/// values, scientific notation for very small or large ones (`1e-6` was
/// printed as "0.0000").
pub fn shown(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-2..1e6).contains(&v.abs()) {
        format!("{v:.4e}")
    } else {
        format!("{v:.4}")
    }
}

/// A solved photograph with everything measured of it: what every front
/// shows and the report says.
#[derive(Clone, Debug)]
pub struct SolvedPhotograph {
    /// The input as solved (the pipeline's report with the intensity scale
    /// the solve ended with, the distances as given).
    pub input: SolveInput,
    /// The parameters solved with.
    pub params: SolverParams,
    /// The initial depth as the user gave it (`None`: the parameters').
    pub initial_depth_given: Option<String>,
    /// The scheme.
    pub method: Method,
    /// The problem as solved (the intensity scale the solve ended with).
    pub problem: Problem,
    /// The solver's result.
    pub solution: Solution,
    /// The depth unit: which cue set it, how precisely (`None` where the
    /// solve decided none).
    pub depth_unit: Option<DepthUnit>,
    /// How well the depth explains the image.
    pub fit: ModelFit,
    /// Several photographs with a light each: the fit to each alone.
    pub fit_per_photo: Vec<PhotoFit>,
    /// Where the surface grazes the view beside a much brighter pixel.
    pub occlusion_edges: Grid<bool>,
    /// Share of the object (the object mask, else the image) taken out of
    /// the data term as shadow.
    pub shadow_share: Option<f64>,
    /// What the pipeline and the solve say of the input and the unit.
    pub notes: Vec<String>,
    /// Everything the user should know is doubtful, most telling first.
    pub warnings: Vec<String>,
    /// Options given that this input leaves without effect.
    pub unused_options: Vec<String>,
    /// Whether the confidence was derived by the pipeline.
    pub confidence_derived: bool,
}

impl SolvedPhotograph {
    /// Every parameter as JSON, for the report: the table's, the method and
    /// the initial depth as given.
    pub fn parameters_json(&self) -> serde_json::Value {
        let mut json = params::table::to_json(&self.params);
        if let Some(object) = json.as_object_mut() {
            object.insert("method".into(), self.method.name().into());
            let initial = self.initial_depth_given.clone().unwrap_or_else(|| {
                match &self.params.initial_depth {
                    InitialDepth::FastMarching => "fast-marching".into(),
                    InitialDepth::FromImage => "image".into(),
                    InitialDepth::Walk => "walk".into(),
                    InitialDepth::Constant(z) => z.to_string(),
                    InitialDepth::Map(_) => "map".into(),
                }
            });
            object.insert("init_depth".into(), initial.into());
        }
        json
    }

    /// The residual `(I - R) / I_ref` over the solved domain (NaN off it).
    pub fn residual(&self) -> Grid<f64> {
        let domain = self.solution.depth.map(|z| z.is_finite());
        model_fit::residual_map(
            &self.problem.image,
            &self.solution.reprojection,
            &domain,
            self.solution.scales.intensity,
        )
    }
}

impl SolvedPhotograph {
    /// The report of this solve; `errors`: `(rse, rie)` against a ground
    /// truth where the front has one.
    pub fn report(&self, errors: Option<(f64, f64)>) -> SolveReport<'_> {
        let solution = &self.solution;
        SolveReport {
            input: &self.input,
            depth_unit: self.depth_unit.as_ref(),
            notes: &self.notes,
            parameters: self.parameters_json(),
            material: solution.material,
            material_fit: solution.material_fit.as_ref(),
            albedo_fit: solution.albedo_fit.as_ref(),
            alpha_used: solution.alpha,
            alpha_px: solution.alpha_px,
            lambda_px: solution.lambda_px,
            scales: &solution.scales,
            initial_depth: solution.initial_depth,
            start_denoised: solution.start_denoised,
            noise: solution.noise,
            levels: &solution.levels,
            phases: &solution.phases,
            final_energy: &solution.final_energy,
            seconds: solution.seconds,
            model_fit: &self.fit,
            model_fit_per_photo: &self.fit_per_photo,
            shadow_share: self.shadow_share,
            unused_options: &self.unused_options,
            warnings: &self.warnings,
            depth16_png_range: crate::io::depth_range(&solution.depth).map(
                |(near_white, far_black)| DepthRange {
                    near_white,
                    far_black,
                },
            ),
            rse: errors.map(|e| e.0),
            rie: errors.map(|e| e.1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::calibrate::{KnownDepthFit, KnownDepthResidual};

    /// A known depth of 1e-6 was printed as "given 0.0000".
    #[test]
    fn tiny_and_huge_depths_are_shown_with_their_digits() {
        assert_eq!(shown(1e-6), "1.0000e-6");
        assert_eq!(shown(1e14), "1.0000e14");
        assert_eq!(shown(2.5), "2.5000");
        assert_eq!(shown(0.0), "0.0000");
    }

    fn unit_with_fit(points: Vec<KnownDepthResidual>, source: UnitSource) -> DepthUnit {
        DepthUnit {
            source,
            cue_distance: f64::NAN,
            precision: 0.0,
            solved_distance: f64::NAN,
            intensity_scale: 1.0,
            aim: None,
            shading: None,
            fit: Some(KnownDepthFit {
                intensity_scale: 1.0,
                points,
                median_depth: None,
                rms_relative_residual: 0.0,
                solves: 12,
                converged: false,
                scale_precision: None,
            }),
        }
    }

    /// A scale search that did not settle is a warning where the user gave
    /// distances, and not at the defaults (no distance given), where the
    /// shading's own search is said in the unit's words.
    #[test]
    fn an_unsettled_search_warns_only_for_distances_the_user_gave() {
        let settle = |unit: &DepthUnit| {
            let (mut notes, mut warnings) = (Vec::new(), Vec::new());
            unit_notes_and_warnings(unit, "mm", &mut notes, &mut warnings);
            warnings.iter().any(|w| w.contains("did not settle"))
        };
        let point = KnownDepthResidual {
            column_px: 3.0,
            row_px: 4.0,
            given: 640.0,
            solved: 640.5,
            relative_residual: 0.0008,
        };
        assert!(settle(&unit_with_fit(vec![point], UnitSource::KnownDepths)));
        assert!(!settle(&unit_with_fit(Vec::new(), UnitSource::Guess)));
    }
}
