//! What the viewer remembers between runs (parameters, brush, view, recent
//! files), kept apart from runtime state and stored through eframe's storage.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::mask_edit::{Layer, Mode};
use std::collections::BTreeMap;

use sfs_core::params::photometric::PS_SMOOTHNESS;
use sfs_core::params::{AlbedoChoice, InitialDepth, PARAMS, SolverParams};
use sfs_core::solver::photometric::PhotometricParams;

/// Key of the settings in eframe's storage.
pub const STORAGE_KEY: &str = "sfs-studio-settings";

/// Most recent files kept.
pub const RECENT_FILES: usize = 10;

/// The solver parameters, stored by their names in the parameter table
/// ([`sfs_core::params::PARAMS`]) in the table's text form, so that a renamed,
/// removed or out-of-range stored value falls back to its default instead of
/// failing the whole settings file. The initial depth is fast marching,
/// "from the image" or a constant (a depth file is a CLI feature).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ParamSettings {
    /// Table name -> value as text; parameters not here take their defaults.
    pub values: BTreeMap<String, String>,
    /// Initial depth.
    pub initial_depth: InitialChoice,
    /// Where the albedo comes from: estimated with the shape (`auto`, the
    /// default for photographs) or 1.
    pub albedo: AlbedoChoice,
}

impl Default for ParamSettings {
    fn default() -> Self {
        Self {
            values: BTreeMap::new(),
            initial_depth: InitialChoice::default(),
            albedo: AlbedoChoice::Auto,
        }
    }
}

/// The viewer's choice of initial depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum InitialChoice {
    /// Fast marching, refined at full resolution (the default).
    #[default]
    FastMarching,
    /// The paper's constant depth from the brightest pixel, whole pyramid.
    FromImage,
    /// A constant depth (depth units), whole pyramid.
    Constant(f64),
}

impl ParamSettings {
    /// The table parameters of `params` that differ from the defaults (so
    /// that a later, better default reaches users who never changed the
    /// value) and its initial depth (a map becomes the default).
    pub fn from_params(params: &SolverParams) -> Self {
        let defaults = SolverParams::for_units(params.units);
        Self {
            values: PARAMS
                .iter()
                .filter(|s| (s.get)(params) != (s.get)(&defaults) || s.name == "units")
                .map(|s| (s.name.to_string(), (s.get)(params).to_string()))
                .collect(),
            initial_depth: match params.initial_depth {
                InitialDepth::Constant(z) => InitialChoice::Constant(z),
                InitialDepth::FromImage => InitialChoice::FromImage,
                _ => InitialChoice::FastMarching,
            },
            albedo: params.albedo,
        }
    }

    /// Full solver parameters: the stored values that parse and fit their
    /// range over the defaults of the stored units.
    pub fn to_params(&self) -> SolverParams {
        let mut params = sfs_core::params::table::params_from(
            PARAMS
                .iter()
                .filter_map(|s| Some((s, s.parse(self.values.get(s.name)?).ok()?))),
        );
        params.initial_depth = match self.initial_depth {
            InitialChoice::FastMarching => InitialDepth::FastMarching,
            InitialChoice::FromImage => InitialDepth::FromImage,
            InitialChoice::Constant(z) => InitialDepth::Constant(z),
        };
        params.albedo = self.albedo;
        params
    }

    /// Applies `change` to the parameters (through [`Self::to_params`]).
    pub fn update(&mut self, change: impl FnOnce(&mut SolverParams)) {
        let mut params = self.to_params();
        change(&mut params);
        *self = Self::from_params(&params);
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
    /// Shows over the input what the last solve took out as shadow.
    pub show_shadows: bool,
    /// Shows over the input where the last solve grazes the view beside a
    /// much brighter pixel (occluding contours, or dark albedo).
    pub show_contours: bool,
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
            show_shadows: true,
            show_contours: true,
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
    /// Show a texture on the surface instead of [`Self::colour`]: the
    /// photograph, or a set's albedo ([`Self::albedo_texture`]).
    pub photo_texture: bool,
    /// With [`Self::photo_texture`], a set's albedo instead of the
    /// photograph (once the set is solved).
    pub albedo_texture: bool,
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
            photo_texture: false,
            albedo_texture: false,
            light_yaw_deg: 25.0,
            light_pitch_deg: 20.0,
        }
    }
}

/// The photometric-stereo scheme's settings the viewer keeps (the rest
/// are [`PhotometricParams`]'s defaults).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SetParamSettings {
    /// Smoothness weight (relative); `None`: automatic from the
    /// photographs' noise.
    pub alpha: Option<f64>,
}

impl SetParamSettings {
    /// Smallest and largest smoothness the control offers: the core's
    /// `ps-smoothness` entry's slider, inside its rule.
    pub const ALPHA_RANGE: (f64, f64) = match PS_SMOOTHNESS.slider {
        Some(range) => range,
        None => (0.0, 0.0), // never: the entry has a slider
    };

    /// The scheme's settings: the defaults with this smoothness (a stored
    /// value outside the core's rule or the control's range is taken as
    /// auto).
    pub fn to_params(&self) -> PhotometricParams {
        PhotometricParams {
            alpha: PS_SMOOTHNESS.in_slider(self.alpha),
            ..PhotometricParams::default()
        }
    }
}

/// Everything persisted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// Working size: photographs whose longest side exceeds this are opened
    /// area-averaged down to it (0: full size).
    pub max_side: usize,
    /// Solver parameters.
    pub params: ParamSettings,
    /// A photometric-stereo set's parameters.
    pub set_params: SetParamSettings,
    /// Brush and overlay.
    pub brush: BrushSettings,
    /// 3-D view.
    pub view: ViewPrefs,
    /// Recently opened images, newest first.
    pub recent_files: Vec<PathBuf>,
}

/// The viewer's default working size (longest side, pixels): interactive at
/// a photograph's size.
pub const DEFAULT_MAX_SIDE: usize = 1500;

impl Default for Settings {
    fn default() -> Self {
        Self {
            max_side: DEFAULT_MAX_SIDE,
            params: ParamSettings::default(),
            set_params: SetParamSettings::default(),
            brush: BrushSettings::default(),
            view: ViewPrefs::default(),
            recent_files: Vec::new(),
        }
    }
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
        let mut p = ParamSettings::default();
        p.update(|params| {
            params.alpha = sfs_core::params::Alpha::Value(4.2e-7);
            params.kappa = 7;
            params.initial_depth = InitialDepth::Constant(1.5);
        });
        assert_eq!(ParamSettings::from_params(&p.to_params()), p);
        assert_eq!(p.to_params().kappa, 7);
        // A stored value out of range or of a removed parameter is dropped.
        p.values.insert("eta".into(), "7".into());
        p.values.insert("gone".into(), "1".into());
        assert_eq!(p.to_params().eta, SolverParams::default().eta);
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

    /// A smoothness out of the core's rule: the viewer's control does not
    /// keep it, as the core's validation refuses it.
    #[test]
    fn the_sets_smoothness_range_is_the_cores_rule() {
        let (low, high) = SetParamSettings::ALPHA_RANGE;
        assert!(PS_SMOOTHNESS.admits(low) && PS_SMOOTHNESS.admits(high) && low < high);
        let bad = -1e-6;
        let stored = SetParamSettings { alpha: Some(bad) };
        assert_eq!(stored.to_params().alpha, None);
        let core = PhotometricParams {
            alpha: Some(bad),
            ..PhotometricParams::default()
        };
        assert_eq!(core.validate().expect_err("refused").name, "ps-smoothness");
        assert!(PS_SMOOTHNESS.parse("-1e-6").is_err());
    }

    #[test]
    fn the_sets_smoothness_round_trips_and_a_bad_stored_one_is_auto() {
        let mut s = Settings::default();
        assert_eq!(s.set_params.to_params().alpha, None);
        s.set_params.alpha = Some(3e-6);
        let json = serde_json::to_string(&s).expect("serialises");
        let back: Settings = serde_json::from_str(&json).expect("deserialises");
        assert_eq!(back.set_params.to_params().alpha, Some(3e-6));
        for bad in [-1.0, 0.0, f64::NAN, 5.0] {
            let stored = SetParamSettings { alpha: Some(bad) };
            assert_eq!(stored.to_params().alpha, None, "{bad}");
        }
        // Settings stored before sets existed read with the defaults.
        let old: Settings = serde_json::from_str(r#"{"max_side": 800}"#).expect("reads");
        assert_eq!(old.set_params, SetParamSettings::default());
    }

    #[test]
    fn the_reflectance_and_its_parameters_round_trip_through_the_stored_settings() {
        use sfs_core::material::Material;
        use sfs_core::params::ReflectanceChoice;
        let mut s = Settings::default();
        s.params.update(|p| {
            p.reflectance = ReflectanceChoice::OrenNayar;
            p.roughness_rad = 0.45;
        });
        assert_eq!(
            s.params.values.get("reflectance").map(String::as_str),
            Some("oren-nayar")
        );
        let json = serde_json::to_string(&s).expect("serialises");
        let back: Settings = serde_json::from_str(&json).expect("deserialises");
        assert_eq!(back, s);
        let params = back.params.to_params();
        assert_eq!(params.reflectance, ReflectanceChoice::OrenNayar);
        assert_eq!(params.roughness_rad, 0.45);
        assert_eq!(
            params.fixed_material(),
            Some(Material::OrenNayar {
                roughness_rad: 0.45
            })
        );
        // Blinn-Phong's and auto's stored words read back too; a word of
        // no model falls back to the default (Lambert).
        for (word, choice) in [
            ("blinn-phong", ReflectanceChoice::BlinnPhong),
            ("auto", ReflectanceChoice::Auto),
            ("glossy", ReflectanceChoice::Lambert),
        ] {
            let mut stored = back.params.clone();
            stored.values.insert("reflectance".into(), word.into());
            assert_eq!(stored.to_params().reflectance, choice, "{word}");
        }
    }
}
