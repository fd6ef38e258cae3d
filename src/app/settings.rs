//! What the viewer remembers between runs (parameters, brush, view, recent
//! files), kept apart from runtime state and stored through eframe's storage.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::mask_edit::{Layer, Mode};
use crate::params::{DomainMode, SmoothnessUnits, SolverParams};

/// Key of the settings in eframe's storage.
pub const STORAGE_KEY: &str = "sfs-studio-settings";

/// Most recent files kept.
pub const RECENT_FILES: usize = 10;

/// The solver parameters the viewer exposes, serialisable (the initial depth
/// is a constant or "from the image"; a depth file is a CLI feature).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ParamSettings {
    /// Smoothness weight (see `SolverParams::alpha`).
    pub alpha: f64,
    /// Charbonnier contrast (see `SolverParams::lambda`).
    pub lambda: f64,
    /// Units of alpha and lambda.
    pub smoothness_units: SmoothnessUnits,
    /// Pyramid factor.
    pub eta: f64,
    /// Outer (Gauss-Newton) iterations per level.
    pub kappa: usize,
    /// Inner fixed-point iterations on Psi'.
    pub inner_iterations: usize,
    /// SOR sweeps per inner iteration.
    pub sor_iterations: usize,
    /// SOR relaxation.
    pub omega: f64,
    /// Largest depth change per outer iteration.
    pub dz_limit: f64,
    /// Initial depth: `None` estimates it from the image.
    pub initial_depth: Option<f64>,
    /// Domain handling at the silhouette.
    pub domain: DomainMode,
}

impl Default for ParamSettings {
    fn default() -> Self {
        Self::from_params(&SolverParams::default())
    }
}

impl ParamSettings {
    /// The subset of `params` the viewer shows.
    pub fn from_params(params: &SolverParams) -> Self {
        Self {
            alpha: params.alpha,
            lambda: params.lambda,
            smoothness_units: params.smoothness_units,
            eta: params.eta,
            kappa: params.kappa,
            inner_iterations: params.inner_iterations,
            sor_iterations: params.sor_iterations,
            omega: params.omega,
            dz_limit: params.dz_limit,
            initial_depth: match params.initial_depth {
                crate::params::InitialDepth::Constant(z) => Some(z),
                _ => None,
            },
            domain: params.domain,
        }
    }

    /// Full solver parameters (the rest at their defaults).
    pub fn to_params(&self) -> SolverParams {
        SolverParams {
            alpha: self.alpha,
            lambda: self.lambda,
            smoothness_units: self.smoothness_units,
            eta: self.eta,
            kappa: self.kappa,
            inner_iterations: self.inner_iterations,
            sor_iterations: self.sor_iterations,
            omega: self.omega,
            dz_limit: self.dz_limit,
            initial_depth: match self.initial_depth {
                Some(z) => crate::params::InitialDepth::Constant(z),
                None => crate::params::InitialDepth::FromImage,
            },
            domain: self.domain,
            ..SolverParams::default()
        }
    }
}

/// The mask tool in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Tool {
    /// Freehand brush.
    #[default]
    Brush,
    /// Axis-aligned rectangle.
    Rectangle,
    /// Freehand polygon.
    Lasso,
    /// Connected pixels of similar brightness.
    FloodFill,
}

/// Brush and mask display settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct BrushSettings {
    /// Tool.
    pub tool: Tool,
    /// Layer painted.
    pub layer: Layer,
    /// Paint (exclude) or erase (restore).
    pub mode: Mode,
    /// Brush radius in image pixels.
    pub radius_px: f32,
    /// Brush hardness in [0, 1].
    pub hardness: f32,
    /// Flood-fill tolerance on linear intensity.
    pub flood_tolerance: f64,
    /// Threshold for "object = brighter than".
    pub threshold: f64,
    /// Overlay opacity in [0, 1].
    pub overlay_opacity: f32,
}

impl Default for BrushSettings {
    fn default() -> Self {
        Self {
            tool: Tool::Brush,
            layer: Layer::Confidence,
            mode: Mode::Paint,
            radius_px: 8.0,
            hardness: 0.7,
            flood_tolerance: 0.05,
            threshold: 0.02,
            overlay_opacity: 0.5,
        }
    }
}

/// Surface colouring in the 3-D view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum SurfaceColour {
    /// Grey shading.
    #[default]
    Shaded,
    /// Colour map of depth.
    Depth,
    /// Colour map of |input - reprojection|.
    Error,
}

/// 3-D view settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ViewPrefs {
    /// Colouring.
    pub colour: SurfaceColour,
    /// Draw edges instead of the filled surface.
    pub wireframe: bool,
    /// Light direction: yaw in degrees (view space, 0 = headlight).
    pub light_yaw_deg: f32,
    /// Light direction: pitch in degrees.
    pub light_pitch_deg: f32,
}

impl Default for ViewPrefs {
    fn default() -> Self {
        Self {
            colour: SurfaceColour::Shaded,
            wireframe: false,
            light_yaw_deg: 25.0,
            light_pitch_deg: 20.0,
        }
    }
}

/// Everything persisted.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// Solver parameters.
    pub params: ParamSettings,
    /// Brush and overlay.
    pub brush: BrushSettings,
    /// 3-D view.
    pub view: ViewPrefs,
    /// Recently opened images, newest first.
    pub recent_files: Vec<PathBuf>,
}

impl Settings {
    /// Puts `path` first in the recent files.
    pub fn remember(&mut self, path: PathBuf) {
        self.recent_files.retain(|p| p != &path);
        self.recent_files.insert(0, path);
        self.recent_files.truncate(RECENT_FILES);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_round_trip_and_recent_files_are_bounded() {
        let p = ParamSettings {
            alpha: 42.0,
            initial_depth: Some(1.5),
            ..ParamSettings::default()
        };
        assert_eq!(ParamSettings::from_params(&p.to_params()), p);
        let mut s = Settings::default();
        for i in 0..15 {
            s.remember(PathBuf::from(format!("{i}.png")));
        }
        s.remember(PathBuf::from("3.png"));
        assert_eq!(s.recent_files.len(), RECENT_FILES);
        assert_eq!(s.recent_files[0], PathBuf::from("3.png"));
        let json = serde_json::to_string(&s).unwrap_or_default();
        let back: Settings = serde_json::from_str(&json).unwrap_or_default();
        assert_eq!(back, s);
    }
}
