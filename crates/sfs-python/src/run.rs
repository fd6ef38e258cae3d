//! The solves behind the Python functions: one photograph (what
//! `sfs-studio solve` does, files included when an output folder is
//! given), a photometric-stereo set, the synthetic scenes and the ground
//! truth's errors. A solve runs on a worker thread with the GIL released;
//! the calling thread relays its progress to the Python callback and polls
//! for Ctrl+C ([`observed`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use numpy::PyReadonlyArray2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use sfs_core::grid::Grid;
use sfs_core::io;
use sfs_core::model_fit;
use sfs_core::output::{self, set as set_out};
use sfs_core::photo;
use sfs_core::photograph_solve::options::photometric_params;
use sfs_core::solver::photometric as ps;
use sfs_core::solver::{IterationReport, LevelResult, SolveObserver};

use crate::convert::{Failure, array2, array3};
use crate::options::{Options, SOLVE_OPTIONS, TakenSolve, flag};

/// One step of a solve's progress: done, total, what is being done.
type Step = (u64, u64, String);

/// The worker's observer: progress out through a channel, cancellation in
/// through a flag.
struct Relay<'a> {
    cancel: &'a AtomicBool,
    steps: crossbeam_channel::Sender<Step>,
    /// Outer iterations per level (a single photograph's solve), or 0 to
    /// count levels (a set's).
    kappa: usize,
    level: u64,
}

impl SolveObserver for Relay<'_> {
    fn on_iteration(&mut self, report: &IterationReport) {
        if self.kappa == 0 {
            return;
        }
        let _ = self.steps.send(sfs_core::photograph_solve::progress_step(
            report, self.kappa,
        ));
    }

    fn on_level(&mut self, result: &LevelResult) {
        if self.kappa == 0 {
            self.level += 1;
            let _ = self.steps.send((
                self.level,
                self.level.max(1),
                format!("level {}x{}", result.geometry.width, result.geometry.height),
            ));
        }
    }

    fn is_cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// Runs `work` on a worker thread with the GIL released; meanwhile this
/// thread passes each step to `progress` (`progress(done, total,
/// message)`) and polls for signals: Ctrl+C sets the cancel flag the
/// worker's observer answers, and the signal's exception is raised once the
/// worker has stopped. An exception in `progress` cancels alike.
fn observed<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    kappa: usize,
    work: impl FnOnce(&mut dyn SolveObserver) -> T + Send,
) -> Result<T, Failure> {
    let cancel = AtomicBool::new(false);
    let (sender, steps) = crossbeam_channel::unbounded::<Step>();
    std::thread::scope(|scope| {
        let cancel = &cancel;
        let worker = scope.spawn(move || {
            let mut relay = Relay {
                cancel,
                steps: sender,
                kappa,
                level: 0,
            };
            work(&mut relay)
        });
        let mut raised: Option<PyErr> = None;
        loop {
            let step = py.detach(|| steps.recv_timeout(Duration::from_millis(50)));
            match step {
                Ok((done, total, message)) => {
                    if raised.is_none()
                        && let Some(callback) = progress
                        && let Err(e) = callback.call1((done, total, message))
                    {
                        cancel.store(true, Ordering::Relaxed);
                        raised = Some(e);
                    }
                }
                Err(crossbeam_channel::RecvTimeoutError::Timeout) => {}
                Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
            }
            if raised.is_none()
                && let Err(e) = py.check_signals()
            {
                cancel.store(true, Ordering::Relaxed);
                raised = Some(e);
            }
        }
        let result = py
            .detach(|| worker.join())
            .map_err(|_| Failure::Value("the solve stopped on an internal error".into()))?;
        match raised {
            Some(e) => Err(Failure::Python(e)),
            None => Ok(result),
        }
    })
}

/// One photograph's solve (several photographs: summed, lights on
/// together), as `sfs-studio solve`: `options` is a JSON object of the
/// command line's options in snake case; with `out` the same files are
/// written there. Returns a dict: depth, reprojection, normals, albedo
/// (None without an estimated albedo), report (report.json's text),
/// warnings, seconds.
#[pyfunction]
#[pyo3(signature = (images, camera, options, out = None, progress = None))]
pub fn solve_photograph<'py>(
    py: Python<'py>,
    images: Vec<PathBuf>,
    camera: Option<PathBuf>,
    options: &str,
    out: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
) -> Result<Bound<'py, PyDict>, Failure> {
    let progress = progress.as_ref();
    let mut options = Options::from_json(options)?;
    let first = images
        .first()
        .cloned()
        .ok_or_else(|| Failure::Value("no photograph given".into()))?;
    let given = TakenSolve::take(&mut options, camera)?;
    options.finish(SOLVE_OPTIONS)?;
    if let Some(dir) = &given.gt {
        io::ground_truth::check_ground_truth(dir, true).map_err(|e| Failure::Value(e.0))?;
    }
    let input = given.options.photo_input(&images)?;
    let prepared = py.detach(|| photo::prepare(&input))?;
    let mut stage = match &out {
        Some(dir) => {
            let mut stage = output::stage(dir)?;
            let mut named: Vec<PathBuf> =
                given.options.init_depth.iter().map(PathBuf::from).collect();
            if let Some(dir) = &given.gt {
                named.extend(output::ground_truth_files(dir));
            }
            stage.keep_inputs(
                input
                    .files()
                    .into_iter()
                    .chain(named.iter().map(PathBuf::as_path)),
            );
            Some(stage)
        }
        None => None,
    };
    let size = prepared.size();
    let job = given.options.job(prepared)?;
    let what = format!("cannot solve {}", first.display());
    let mut warnings: Vec<String> =
        model_fit::darkness_warning(&job.problem.image, job.problem.object_mask.as_ref())
            .into_iter()
            .collect();
    let truth = match &given.gt {
        Some(dir) => {
            let truth =
                io::ground_truth::read_ground_truth(dir).map_err(|e| Failure::Value(e.0))?;
            io::ground_truth::check_size(&truth, dir, size).map_err(|e| Failure::Value(e.0))?;
            Some(truth)
        }
        None => None,
    };
    let job = &job;
    let solved = observed(py, progress, job.params.kappa, |observer| job.run(observer))?
        .map_err(|e| Failure::of_photograph(&what, e))?;
    let solution = &solved.solution;
    let errors = match &truth {
        Some(truth) => {
            let e = sfs_core::metrics::errors_with_model(
                &solution.depth,
                &truth.depth,
                &truth.image,
                solved.problem.camera,
                &solved.problem.model(solution.material),
            )
            .map_err(|e| Failure::Value(format!("{what}: {e}")))?;
            Some((e.rse, e.rie))
        }
        None => None,
    };
    if let (Some(mut stage), Some(dir)) = (stage.take(), &out) {
        output::write_solved(&mut stage, &solved, errors)?;
        stage
            .commit()
            .map_err(|e| Failure::Io(format!("cannot finish writing {}: {e}", dir.display())))?;
    }
    warnings.extend(solved.warnings.iter().cloned());
    let report =
        serde_json::to_string(&solved.report(errors)).map_err(|e| Failure::Value(e.to_string()))?;
    let normals = ps::depth_normals(&solution.depth, solved.problem.camera);
    let dict = PyDict::new(py);
    dict.set_item("depth", array2(py, &solution.depth))?;
    dict.set_item("reprojection", array2(py, &solution.reprojection))?;
    dict.set_item("normals", array3(py, &normals))?;
    match &solution.albedo_fit {
        Some(fit) => dict.set_item("albedo", array2(py, &fit.used_albedo(&solution.depth)))?,
        None => dict.set_item("albedo", py.None())?,
    }
    dict.set_item("report", report)?;
    dict.set_item("warnings", PyList::new(py, warnings)?)?;
    dict.set_item("seconds", solution.seconds)?;
    Ok(dict)
}

/// The options of one photograph's solve that a set does not take: each
/// is refused with the reason.
const SINGLE_ONLY: &[&str] = &[
    "known_depth",
    "distance",
    "init_depth",
    "albedo",
    "gt",
    "auto_confidence",
    "method",
];

/// The set's own options.
const SET_ONLY: &[&str] = &["ps_smoothness", "ps_robust_scale", "ps_no_cast_shadows"];

/// The options a set takes: one photograph's less [`SINGLE_ONLY`], and its
/// own.
fn set_options() -> Vec<&'static str> {
    SOLVE_OPTIONS
        .iter()
        .filter(|o| !SINGLE_ONLY.contains(o))
        .chain(SET_ONLY)
        .copied()
        .collect()
}

/// Photometric stereo on a set of photographs, each taken by a light of
/// its own (the camera file's lights named by image, or `light` given per
/// photograph in order): the core's set solve; with `out` the files of
/// `sfs-studio solve --photometric-stereo` are written there. Returns a
/// dict: depth, normals, albedo, reprojection (None), report (the text of
/// the command line's report.json), warnings, seconds.
#[pyfunction]
#[pyo3(signature = (images, camera, options, out = None, progress = None))]
pub fn solve_set<'py>(
    py: Python<'py>,
    images: Vec<PathBuf>,
    camera: Option<PathBuf>,
    options: &str,
    out: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
) -> Result<Bound<'py, PyDict>, Failure> {
    let progress = progress.as_ref();
    let mut options = Options::from_json(options)?;
    let smoothness = options
        .text("ps_smoothness")
        .unwrap_or_else(|| "auto".into());
    let robust = options
        .text("ps_robust_scale")
        .unwrap_or_else(|| "auto".into());
    let no_cast_shadows = options.switch("ps_no_cast_shadows")?;
    let params = photometric_params(&smoothness, &robust, no_cast_shadows)?;
    let intensities_given = options.has("light_intensity");
    for &single in SINGLE_ONLY {
        if options.has(single) {
            return Err(Failure::Value(format!(
                "{} does not apply to photometric stereo (a set solves its own depth, \
                 normals and albedo)",
                flag(single)
            )));
        }
    }
    let count = images.len();
    let given = TakenSolve::take(&mut options, camera)?;
    if let Some((spec, _)) = given.options.table.first() {
        return Err(Failure::Value(format!(
            "{} is a parameter of one photograph's solve; a set takes ps_smoothness, \
             ps_robust_scale and ps_no_cast_shadows",
            flag(&spec.name.replace('-', "_"))
        )));
    }
    options.finish(&set_options())?;
    let mut input = given.options.photo_input(&images)?;
    input.photometric_stereo = true;
    input.given_intensities = intensities_given;
    let input = &input;
    let prepared = py.detach(|| photo::prepare(input))?;
    let problem = photo::photometric_problem(&prepared, input)?;
    let problem = &problem;
    // The destination is locked and checked writable before the solve.
    let stage = match &out {
        Some(dir) => {
            let mut stage = output::stage(dir)?;
            stage.keep_inputs(input.files());
            Some(stage)
        }
        None => None,
    };
    let params = &params;
    let what = format!("cannot solve the set of {count} photographs");
    let solution = observed(py, progress, 0, |observer| {
        ps::solve_photometric(problem, params, observer)
    })?
    .map_err(|e| Failure::of_solve(&what, e))?;
    let warnings = ps::warnings(&solution);
    let report = set_out::set_report(&prepared.report, params, &solution, None, None, &warnings)
        .map_err(|e| Failure::Value(format!("{what}: {e}")))?;
    if let (Some(mut stage), Some(dir)) = (stage, &out) {
        set_out::write_set(&mut stage, &prepared.problem.camera, &solution, &report)?;
        stage
            .commit()
            .map_err(|e| Failure::Io(format!("cannot finish writing {}: {e}", dir.display())))?;
    }
    let dict = PyDict::new(py);
    dict.set_item("depth", array2(py, &solution.depth))?;
    dict.set_item("normals", array3(py, &solution.normals))?;
    dict.set_item("albedo", array2(py, &solution.albedo))?;
    dict.set_item("reprojection", py.None())?;
    dict.set_item("report", report.to_string())?;
    dict.set_item("warnings", PyList::new(py, warnings)?)?;
    dict.set_item("seconds", solution.seconds)?;
    Ok(dict)
}

/// The Sombrero rendered with one light at the camera centre (as `synth`
/// without options): a dict of image, depth_gt, mask and camera (a camera
/// file's JSON text: intrinsics and intensity scale).
#[pyfunction]
#[pyo3(signature = (width, height))]
pub fn synth_sombrero(py: Python<'_>, width: usize, height: usize) -> PyResult<Bound<'_, PyDict>> {
    check_synth_size(width, height, 1)?;
    let scene = py.detach(|| {
        sfs_core::scene::sombrero::sombrero_shaded(width, height, &[], Default::default())
    });
    let camera = sfs_core::camera_file::CameraFile {
        name: Some(scene.name.clone()),
        intensity_scale: Some(scene.intensity_scale),
        ..sfs_core::camera_file::CameraFile::new(scene.camera, width, height)
    };
    let dict = PyDict::new(py);
    dict.set_item("image", array2(py, &scene.image))?;
    dict.set_item("depth_gt", array2(py, &scene.depth_gt))?;
    dict.set_item(
        "mask",
        array2(py, &scene.object_mask.map(|&m| f64::from(u8::from(m)))),
    )?;
    dict.set_item("camera", camera_json(&camera)?)?;
    Ok(dict)
}

/// Refuses a size the renderer cannot or should not make.
fn check_synth_size(width: usize, height: usize, count: usize) -> PyResult<()> {
    if width < 16 || height < 16 {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "size {width}x{height}: at least 16x16 pixels"
        )));
    }
    sfs_core::memory::check(
        &format!("rendering {count} photographs of {width}x{height} pixels"),
        sfs_core::memory::synth_estimate((width, height)).saturating_mul(count as u64 + 2),
        "choose a smaller size",
    )
    .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))
}

/// A camera file as JSON text.
fn camera_json(camera: &sfs_core::camera_file::CameraFile) -> PyResult<String> {
    serde_json::to_string(camera)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))
}

/// A photometric-stereo set of the Sombrero (as `synth --ps-leds COUNT`):
/// `count` LEDs around the camera aimed at the object, an albedo pattern
/// (`patches`, `lines`, `smooth` or `uniform`), cast shadows traced. A dict
/// of images (a list, in the LEDs' order), mask, depth_gt, normals_gt,
/// albedo_gt and camera (a camera file's JSON text whose lights name the
/// images `led01.png`, `led02.png`, ...).
#[pyfunction]
#[pyo3(signature = (width, height, count, albedo_pattern = "patches"))]
pub fn synth_set<'py>(
    py: Python<'py>,
    width: usize,
    height: usize,
    count: usize,
    albedo_pattern: &str,
) -> PyResult<Bound<'py, PyDict>> {
    use sfs_core::scene::{self, photometric as set};
    if !["patches", "lines", "smooth", "uniform"].contains(&albedo_pattern) {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "--albedo-pattern {albedo_pattern}: expected patches, lines, smooth or uniform"
        )));
    }
    if !(1..=output::names::MAX_SET).contains(&count) {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "--ps-leds {count}: between 1 and {}",
            output::names::MAX_SET
        )));
    }
    check_synth_size(width, height, count)?;
    let rendered = py.detach(|| {
        let leds = set::standard_leds(count, [0.0, 0.0, 2.0]);
        let albedo = if albedo_pattern == "uniform" {
            Grid::filled(width, height, 1.0)
        } else {
            set::albedo_pattern(width, height, albedo_pattern)
        };
        let render = |lights: &[sfs_core::light::PointLight]| {
            Ok::<_, String>(scene::sombrero::sombrero_shaded(
                width,
                height,
                lights,
                Default::default(),
            ))
        };
        set::render_set(render, &leds, &albedo, true)
    });
    let rendered = rendered.map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    let entries = rendered
        .lights
        .iter()
        .enumerate()
        .map(|(k, light)| {
            sfs_core::camera_file::LightEntry::of_light(
                light,
                Some(k as u32 + 1),
                Some(format!("led{:02}.png", k + 1)),
            )
        })
        .collect();
    let camera = sfs_core::camera_file::CameraFile {
        name: Some(rendered.name.clone()),
        intensity_scale: Some(rendered.intensity_scale),
        intensity_scale_measured: true,
        lights: entries,
        ..sfs_core::camera_file::CameraFile::new(rendered.camera, width, height)
    };
    let images = PyList::empty(py);
    for image in &rendered.images {
        images.append(array2(py, image))?;
    }
    let dict = PyDict::new(py);
    dict.set_item("images", images)?;
    dict.set_item(
        "mask",
        array2(py, &rendered.object_mask.map(|&m| f64::from(u8::from(m)))),
    )?;
    dict.set_item("depth_gt", array2(py, &rendered.depth_gt))?;
    dict.set_item("normals_gt", array3(py, &rendered.normals_gt))?;
    dict.set_item("albedo_gt", array2(py, &rendered.albedo_gt))?;
    dict.set_item("camera", camera_json(&camera)?)?;
    Ok(dict)
}

/// The relative surface error (rse) and reprojection error (rie) of
/// `depth` against a ground truth (`depth_gt`, the noise-free `image`, the
/// camera file at `camera`): as `sfs-studio eval`, a dict {rse, rie}.
#[pyfunction]
pub fn evaluate<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray2<'py, f32>,
    depth_gt: PyReadonlyArray2<'py, f32>,
    image: PyReadonlyArray2<'py, f32>,
    camera: PathBuf,
) -> PyResult<Bound<'py, PyDict>> {
    let grid = |a: &PyReadonlyArray2<'py, f32>| {
        let view = a.as_array();
        let (h, w) = view.dim();
        Grid::from_fn(w, h, |x, y| f64::from(view[[y, x]]))
    };
    let (depth, depth_gt, image) = (grid(&depth), grid(&depth_gt), grid(&image));
    if depth.size() != depth_gt.size() || image.size() != depth_gt.size() {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "depth is {}x{} but the ground truth is {}x{} (image {}x{})",
            depth.width(),
            depth.height(),
            depth_gt.width(),
            depth_gt.height(),
            image.width(),
            image.height()
        )));
    }
    let value = |e: &dyn std::fmt::Display| pyo3::exceptions::PyValueError::new_err(e.to_string());
    let file =
        sfs_core::camera_file::read_camera(&camera).map_err(|e| PyErr::from(Failure::from(e)))?;
    file.validate(&camera).map_err(|e| value(&e))?;
    let intrinsics = file
        .intrinsics_for(&camera, depth_gt.size())
        .map_err(|e| value(&e))?;
    let (lights, _) = file.lights_for(&camera, &[], None).map_err(|e| value(&e))?;
    let material = file.material.unwrap_or_default();
    let model = sfs_core::light::LightModel::with_material(
        file.intensity_scale.unwrap_or(1.0),
        &lights,
        material,
    );
    let errors =
        sfs_core::metrics::errors_with_model(&depth, &depth_gt, &image, intrinsics, &model)
            .map_err(|e| value(&e))?;
    let dict = PyDict::new(py);
    dict.set_item("rse", errors.rse)?;
    dict.set_item("rie", errors.rie)?;
    Ok(dict)
}
