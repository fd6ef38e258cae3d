//! Where a set's solve starts: the distances along the optical axis tried
//! on the coarsest levels, and the best of them kept.

use glam::DVec3;

use super::level::{Level, Scales};
use super::levels::upsample;
use super::run::{LevelRun, run_level};
use super::set::PhotometricParams;
use crate::light::PointLight;
use crate::model::Energy;
use crate::solver::problem::{SolveError, SolveObserver};

/// Distances kept from the coarsest level for the next.
const FINALISTS: usize = 3;
/// Linearisations per distance tried.
const CANDIDATE_ITERATIONS: usize = 5;
/// Distances tried at the coarsest level.
const DISTANCE_CANDIDATES: usize = 12;

/// Where the solve starts: the surface, albedo factor and intensities at
/// `level`, the distance chosen and every distance tried with its energy.
pub(super) struct Start {
    pub(super) level: usize,
    pub(super) zeta: Vec<f64>,
    pub(super) m: Vec<f64>,
    pub(super) intensities: Vec<f64>,
    pub(super) distance: f64,
    pub(super) tried: Vec<(f64, f64)>,
}

/// Chooses the distance to start from: every candidate (or the one given)
/// is solved briefly at the coarsest level from a plane at that distance;
/// the [`FINALISTS`] best are solved again at the next level, where the
/// surface is less aliased, and the best of them is kept.
#[allow(clippy::too_many_arguments)]
pub(super) fn choose_start(
    levels: &[Level],
    lights: &[PointLight],
    intensities: &[f64],
    estimate_intensities: bool,
    scales: Scales,
    params: &PhotometricParams,
    observer: &mut dyn SolveObserver,
) -> Result<Start, SolveError> {
    let candidates = match params.initial_depth {
        Some(d) => vec![d],
        None => distance_candidates(lights),
    };
    let how = LevelRun {
        max_iterations: CANDIDATE_ITERATIONS.min(params.iterations),
        search_distance: true,
        report: None,
    };
    let per_pixel = |e: Energy, level: &Level| {
        e.total / level.domain.iter().filter(|&&d| d).count().max(1) as f64
    };
    let no_cast: Vec<Vec<bool>> = Vec::new();
    let coarsest = &levels[0];
    let n = coarsest.width * coarsest.height;
    let mut runs = Vec::new();
    let mut tried = Vec::new();
    for &d in &candidates {
        let mut zeta = vec![d.ln(); n];
        let mut m = vec![0.0; n];
        let mut phi = intensities.to_vec();
        let e = run_level(
            coarsest,
            lights,
            &mut phi,
            estimate_intensities,
            &no_cast,
            scales,
            &mut zeta,
            &mut m,
            how,
            observer,
        )?
        .energy;
        let value = per_pixel(e, coarsest);
        tried.push((d, value));
        runs.push((value, d, zeta, m, phi));
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    runs.truncate(FINALISTS);
    let mut level = 0;
    if let (Some(next), true) = (levels.get(1), runs.len() > 1) {
        level = 1;
        for run in &mut runs {
            run.2 = upsample(&run.2, coarsest, next);
            run.3 = upsample(&run.3, coarsest, next);
            let e = run_level(
                next,
                lights,
                &mut run.4,
                estimate_intensities,
                &no_cast,
                scales,
                &mut run.2,
                &mut run.3,
                how,
                observer,
            )?
            .energy;
            run.0 = per_pixel(e, next);
        }
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let Some((_, distance, zeta, m, intensities)) = runs.into_iter().next() else {
        return Err(SolveError::Input("no distance to start from".into()));
    };
    Ok(Start {
        level,
        zeta,
        m,
        intensities,
        distance,
        tried,
    })
}

/// Distances along the optical axis to start from, log-spaced: from just
/// beyond the farthest light to where the lights are 5 degrees off the
/// axis seen from the object (beyond it the photographs barely differ in
/// direction, and a set says little about the shape).
fn distance_candidates(lights: &[PointLight]) -> Vec<f64> {
    let lateral = lights
        .iter()
        .map(|l| l.position[0].hypot(l.position[1]))
        .fold(0.0, f64::max);
    let spread = lights
        .iter()
        .map(|l| DVec3::from_array(l.position).length())
        .fold(0.0, f64::max)
        .max(1e-12);
    let reach = if lateral > 0.0 { lateral } else { spread };
    let farthest = lights
        .iter()
        .map(|l| l.position[2])
        .fold(f64::MIN, f64::max);
    let lo = (farthest + 0.05 * reach).max(0.05 * reach);
    let hi = farthest.max(0.0) + reach / 5f64.to_radians().tan();
    let hi = hi.max(2.0 * lo);
    (0..DISTANCE_CANDIDATES)
        .map(|k| lo * (hi / lo).powf(k as f64 / (DISTANCE_CANDIDATES - 1) as f64))
        .collect()
}
