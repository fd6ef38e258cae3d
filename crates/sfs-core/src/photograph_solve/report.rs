//! `report.json`: everything a photograph's solve decided and measured,
//! the same from every front.

use serde::Serialize;

use crate::photo::{PhotoFit, PhotoReport};
use crate::solver::albedo_fit::AlbedoFit;
use crate::solver::depth_unit::DepthUnit;
use crate::solver::material_fit::MaterialFit;
use crate::solver::{LevelReport, PhaseTimes};

/// The depth picture's range (`depth16.png`: near white, far black).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DepthRange {
    /// Depth shown white.
    pub near_white: f64,
    /// Depth shown black.
    pub far_black: f64,
}

/// The input as solved: the photo pipeline's report (with the intensity
/// scale the solve ended with) and the distances given.
#[derive(Clone, Debug, Serialize)]
pub struct SolveInput {
    /// The pipeline's report.
    #[serde(flatten)]
    pub photo: PhotoReport,
    /// Known distances as given: pixel column and row of the photograph as
    /// given, distance.
    pub known_depth: Vec<[f64; 3]>,
    /// The object's distance as given.
    pub distance: Option<f64>,
}

/// `report.json`.
#[derive(Debug, Serialize)]
pub struct SolveReport<'a> {
    /// The input as solved.
    pub input: &'a SolveInput,
    /// Which cue set the depth unit, how precisely, the shading search and
    /// how the solve met the known distances (working-size pixels).
    pub depth_unit: Option<&'a DepthUnit>,
    /// What the pipeline and the solve say of the input and the unit.
    pub notes: &'a [String],
    /// Every parameter.
    pub parameters: serde_json::Value,
    /// The material the surface was solved as (with `--reflectance auto`,
    /// the fitted one).
    pub material: crate::material::Material,
    /// With `--reflectance auto`: every candidate and the verdict.
    pub material_fit: Option<&'a MaterialFit>,
    /// With `--albedo auto`: the estimate and whether the solve used it.
    pub albedo_fit: Option<&'a AlbedoFit>,
    /// The smoothness weight used (the parameters' units).
    pub alpha_used: f64,
    /// The smoothness weight per pixel.
    pub alpha_px: f64,
    /// The Charbonnier scale per pixel.
    pub lambda_px: f64,
    /// The problem's scales.
    pub scales: &'a crate::params::ProblemScales,
    /// The initial depth the solve started from.
    pub initial_depth: f64,
    /// Whether the fast-marching start marched a TV-denoised image (absent
    /// when no such start was marched).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_denoised: Option<bool>,
    /// The image's noise as the solve read it (absent for fast marching).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<crate::solver::NoiseReading>,
    /// Every level of the pyramid.
    pub levels: &'a [LevelReport],
    /// Time per phase.
    pub phases: &'a PhaseTimes,
    /// The energy at the end.
    pub final_energy: &'a crate::model::Energy,
    /// Seconds of the solve.
    pub seconds: f64,
    /// How well the depth explains the image.
    pub model_fit: &'a crate::model_fit::ModelFit,
    /// Several photographs, each with its own light: the fit of the depth
    /// to each one alone under its light.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub model_fit_per_photo: &'a [PhotoFit],
    /// Share of the object taken out of the data term as shadow (lights off
    /// the optical centre only; shadow.png marks it).
    pub shadow_share: Option<f64>,
    /// Options given that this input leaves without effect (each also a
    /// warning).
    pub unused_options: &'a [String],
    /// Every warning, most telling first.
    pub warnings: &'a [String],
    /// The depth picture's range.
    pub depth16_png_range: Option<DepthRange>,
    /// Relative surface error against a ground truth.
    pub rse: Option<f64>,
    /// Relative image error against a ground truth's image.
    pub rie: Option<f64>,
}
