//! The shared face as the benchmarks use it: its seven photographs read as
//! one photometric-stereo set and solved, the tool's own reconstruction
//! that single photographs are measured against.

use std::path::{Path, PathBuf};

use anyhow::Result;

use sfs_core::grid::Grid;
use sfs_core::photo::{self, CameraSpec, LightSpec, PhotoInput, PreparedPhoto};
use sfs_core::solver::calibrate::KnownDepth;
use sfs_core::solver::photometric::{
    PhotometricParams, PhotometricProblem, PhotometricSolution, solve_photometric,
};

/// The set, read and solved.
pub(super) struct FaceSet {
    /// The photographs, in LED order.
    pub images: Vec<PathBuf>,
    /// The set's input (`one_of_set` gives each photograph's).
    pub input: PhotoInput,
    /// The set as the pipeline prepared it (its camera, the rig).
    pub prepared: PreparedPhoto,
    /// The set's problem (each photograph's light).
    pub problem: PhotometricProblem,
    /// Its reconstruction: depth and albedo.
    pub solution: PhotometricSolution,
}

/// The shared face (`near_ps_human1/` in `real`) at a working size of
/// `max_side` (the photographs' own without), solved at the set's defaults;
/// `None` when its calibration is missing.
pub(super) fn face_set(real: &Path, max_side: Option<usize>) -> Result<Option<FaceSet>> {
    let Some(input) = face_input(real, max_side) else {
        return Ok(None);
    };
    let images = input.images.clone();
    let prepared = photo::prepare(&input)?;
    let problem = photo::photometric_problem(&prepared, &input)?;
    let solution = solve_photometric(&problem, &PhotometricParams::default(), &mut ())?;
    Ok(Some(FaceSet {
        images,
        input,
        prepared,
        problem,
        solution,
    }))
}

/// The shared face's photographs (`near_ps_human1/` in `real`, its LEDs
/// in order) as one photometric-stereo input with the set's calibration,
/// mask and ambient photograph, at a working size of `max_side`; `None`
/// when its calibration or every photograph is missing.
pub(super) fn face_input(real: &Path, max_side: Option<usize>) -> Option<PhotoInput> {
    let dir = real.join("near_ps_human1");
    let camera = dir.join("calibration.json");
    if !camera.is_file() {
        return None;
    }
    let images: Vec<PathBuf> = (1..=8)
        .map(|k| dir.join(format!("led{k}.png")))
        .filter(|p| p.is_file())
        .collect();
    let first = images.first()?.clone();
    Some(PhotoInput {
        images,
        camera: CameraSpec::File(camera),
        lights: LightSpec::CameraFile { picks: Vec::new() },
        object_mask: Some(dir.join("mask.png")),
        ambient: Some(dir.join("ambient.png")).filter(|p| p.is_file()),
        photometric_stereo: true,
        max_side,
        ..PhotoInput::new(&first)
    })
}

/// The set's albedo made relative (its brightest 1; at least 0.02, 1 off
/// the face), as a single photograph's solve takes a known albedo.
pub(super) fn relative_albedo(albedo: &Grid<f64>) -> Grid<f64> {
    let white = albedo
        .as_slice()
        .iter()
        .copied()
        .filter(|a| a.is_finite() && *a > 0.0)
        .fold(0.0, f64::max);
    albedo.map(|a| {
        if a.is_finite() && *a > 0.0 {
            (a / white).max(0.02)
        } else {
            1.0
        }
    })
}

/// The nearest point of a solved surface (on the face: the nose tip) as a
/// known depth; `None` when nothing was solved.
pub(super) fn nearest_point(depth: &Grid<f64>) -> Option<KnownDepth> {
    let w = depth.width();
    depth
        .as_slice()
        .iter()
        .enumerate()
        .filter(|(_, z)| z.is_finite() && **z > 0.0)
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(q, z)| KnownDepth {
            column_px: (q % w) as f64,
            row_px: (q / w) as f64,
            depth: *z,
        })
}
