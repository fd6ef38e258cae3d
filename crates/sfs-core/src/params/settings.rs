//! The solver's parameters and their choices ([`SolverParams`], its
//! defaults, and the accepted ranges), the plain data below the table of
//! their names (`table`) and their validation (`validate`); re-exported as
//! `params::SolverParams` and so on. Uses `model`, `material`, `grid`.

use serde::{Deserialize, Serialize};

use crate::model::Derivatives;

/// Accepted intensity scales `s`: depth grows as `sqrt(s)`, so within these
/// bounds every depth stays inside [`DEPTH_RANGE`] for any brightness a
/// 16-bit or float image holds.
pub const INTENSITY_SCALE_RANGE: (f64, f64) = (1e-30, 1e30);

/// Accepted depths (a constant initial depth, a depth map's values, a known
/// depth), in the problem's unit of depth: far inside single precision
/// (depth.npy is float32, about 3.4e38) and far above the solver's floor, so
/// any unit from nanometres to light years fits.
pub const DEPTH_RANGE: (f64, f64) = (1e-15, 1e25);

/// Accepted constant initial depths (`init-depth Z`), relative to the depth
/// the image's brightness implies (the problem's depth scale): each outer
/// iteration moves a pixel by a small fraction of its depth at most, so a
/// start a thousand times too near or too far is never walked back (a
/// start of 1e-15 ended as a constant depth with an RIE of 4.6e30).
pub const INIT_DEPTH_RELATIVE_RANGE: (f64, f64) = (1e-3, 1e3);

/// How the domain of the unknown depth is chosen (see docs/mask-and-confidence.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DomainMode {
    /// Only object pixels carry depth: upwind differences and smoothness
    /// stencils at the silhouette use object pixels only. Fits the image
    /// better (lower RIE) and is faster, but its RSE on the mesh scenes was
    /// higher and sensitive to tiny input changes at the default alpha.
    Object,
    /// The paper's set-up (default): every pixel carries depth, the background
    /// only has confidence 0 and is filled in by the smoothness term. Lowest
    /// and most stable RSE on all mesh scenes at the default alpha (docs/mask-and-confidence.md).
    #[default]
    Paper,
}

/// What alpha, lambda, the dz limit and h_z are measured in.
///
/// The image formation `I = s Q^3 / (z W)` has exact symmetries: an image
/// times `k` together with `s` is the same surface; an image times `k` alone
/// is the same shape at depth `/ sqrt(k)`; depth in other units (with `s`
/// converted) is the same shape; the same scene at another image size (same
/// field of view) is the same surface sampled more or less finely. In
/// [`Units::Relative`] every parameter is a pure number chosen so that none
/// of these changes the result; [`Units::Paper`] keeps the paper's absolute
/// meaning (pixels and depth units) for its experiments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Units {
    /// Dimensionless (default). With the problem's depth scale `Z` and
    /// brightness scale `I_ref = s / Z^2` (see [`ProblemScales`]) the energy
    /// is `sum c (D / I_ref)^2 + alpha sum Psi_lambda(S_rel^2)`, where
    /// `S_rel = f^2 S / Z` are second derivatives of depth relative to `Z`
    /// with respect to the normalised image coordinate `x / f`; `dz_limit`
    /// is a fraction of each pixel's depth and `h_z` a fraction of `Z`.
    #[default]
    Relative,
    /// The paper's: alpha and lambda per full-resolution pixel squared, with
    /// the image in its own units; `dz_limit` and `h_z` in depth units.
    Paper,
}

/// Relative noise level (of the brightness scale) above which the
/// fast-marching start works on a TV-denoised image ([`StartDenoise::Auto`]):
/// read over all trusted pixels and over the brightest quarter of them.
pub const FAST_MARCHING_DENOISE_ABOVE: f64 = 0.01;

/// Whether the fast-marching start marches a TV-denoised image
/// (`--start-denoise`). The refinement always fits the image as given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StartDenoise {
    /// Denoised when the image reads noisy: its noise above
    /// [`FAST_MARCHING_DENOISE_ABOVE`] of the brightness scale both over
    /// all trusted pixels and over the brightest quarter of them, where the
    /// surface faces the light and its own detail shows least
    /// (docs/paper-table1.md, "The start's denoising").
    #[default]
    Auto,
    /// Always denoised (with the noise level read over all trusted pixels
    /// as the TV weight).
    On,
    /// Never: fast marching reads the image as given.
    Off,
}

/// The smoothness weight: chosen by the solver, or given.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Alpha {
    /// Chosen from the image (default): see `solver::auto_alpha`.
    #[default]
    Auto,
    /// A given value, in the parameters' [`Units`].
    Value(f64),
}

impl Alpha {
    /// The given value, `None` for [`Alpha::Auto`].
    pub fn value(self) -> Option<f64> {
        match self {
            Alpha::Auto => None,
            Alpha::Value(v) => Some(v),
        }
    }
}

impl std::fmt::Display for Alpha {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Alpha::Auto => write!(f, "auto"),
            Alpha::Value(v) => write!(f, "{v}"),
        }
    }
}

impl std::str::FromStr for Alpha {
    type Err = String;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        if text.eq_ignore_ascii_case("auto") {
            return Ok(Alpha::Auto);
        }
        text.parse::<f64>()
            .map(Alpha::Value)
            .map_err(|_| format!("'{text}' is neither 'auto' nor a number"))
    }
}

/// The scales of a problem that make [`Units::Relative`] dimensionless.
///
/// `depth` is the median over trusted object pixels of the depth at which
/// the pixel would have its brightness if it faced the light,
/// `Q sqrt(s / I)` (an upper bound of the true depth for a Lambertian
/// surface, robust to noise and highlights). It scales with `1/sqrt(k)` when
/// the image is multiplied by `k`, with the unit of depth, and not with the
/// image size. `intensity = s / depth^2` is the brightness of a surface at
/// that depth facing the light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ProblemScales {
    /// Depth scale `Z`, depth units.
    pub depth: f64,
    /// Brightness scale `I_ref = s / Z^2`, image units.
    pub intensity: f64,
    /// Focal length, pixels.
    pub focal_px: f64,
}

impl ProblemScales {
    /// `alpha` in pixel units for a relative `alpha`:
    /// `alpha_px = alpha I_ref^2 f^4 / Z^2`.
    pub fn alpha_px(&self, alpha_relative: f64) -> f64 {
        alpha_relative * self.intensity.powi(2) * self.focal_px.powi(4) / self.depth.powi(2)
    }

    /// The relative `alpha` of a pixel-unit one (inverse of [`Self::alpha_px`]).
    pub fn alpha_relative(&self, alpha_px: f64) -> f64 {
        alpha_px * self.depth.powi(2) / (self.intensity.powi(2) * self.focal_px.powi(4))
    }

    /// `lambda` in pixel units for a relative `lambda`: `lambda_px = lambda Z / f^2`.
    pub fn lambda_px(&self, lambda_relative: f64) -> f64 {
        lambda_relative * self.depth / (self.focal_px * self.focal_px)
    }
}

/// How each inner iteration's linear system is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolver {
    /// The default: multigrid where a full-resolution start is refined
    /// across holes (object pixels of confidence below 0.5), whose fill is
    /// smooth error as wide as the hole; SOR everywhere else, where it was
    /// measured as accurate and faster.
    #[default]
    Auto,
    /// The paper's: SOR sweeps (`sor_iterations` at most).
    Sor,
    /// Geometric multigrid V-cycles (Galerkin coarse levels, SOR smoothing;
    /// `cycles` at most): moves smooth error that SOR needs hundreds of
    /// sweeps for.
    Multigrid,
}

impl LinearSolver {
    /// The solver a level runs: [`LinearSolver::Auto`] resolved for a level
    /// that refines a start across holes (`refines_holes`) or not.
    pub fn resolved(self, refines_holes: bool) -> Self {
        match self {
            Self::Auto if refines_holes => Self::Multigrid,
            Self::Auto => Self::Sor,
            chosen => chosen,
        }
    }
}

/// Which reflectance model the solver uses: [`crate::material::ReflectanceChoice`]
/// (beside the models' table it names).
pub use crate::material::ReflectanceChoice;

/// Where the solver takes the surface's albedo from (`--albedo`): 1
/// everywhere (the paper's; the library's default), or estimated from the
/// image and kept only where it explains the photograph better
/// (`solver::albedo_fit`; the command line's and the viewer's default for
/// photographs). A given map is divided out by the photo pipeline first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AlbedoChoice {
    /// Albedo 1: the image's brightness is all shading.
    #[default]
    One,
    /// Estimated with the shape (`solver::albedo_fit`).
    Auto,
}

/// How each Gauss-Newton update is controlled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StepControl {
    /// The paper's: crop `|dz| <= dz_limit` per pixel and apply.
    Crop,
    /// Crop, then halve the whole step (at most 4 times) until the level's
    /// energy does not increase; the last halving is applied regardless.
    #[default]
    Backtracking,
}

/// Initial depth `z^0`.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum InitialDepth {
    /// Fast marching (default): the Prados-Faugeras equation solved on the
    /// image (TV-denoised when its estimated noise exceeds
    /// `FAST_MARCHING_DENOISE_ABOVE` of the brightness scale, untrusted
    /// pixels filled by diffusion first), then refined by the linearised
    /// solver at full resolution like [`InitialDepth::Map`]. A global shape
    /// in a fraction of a second; the coarse-to-fine path from a constant
    /// depth ends in a wrong low-frequency shape more often (docs/results.md,
    /// "Globalisation").
    #[default]
    FastMarching,
    /// The paper's constant depth from the image: at the brightest trusted
    /// object pixel `b` of the coarsest level, assume the surface faces the
    /// light, `z0 = Q_b sqrt(s / I_b)`; the whole pyramid runs from it.
    FromImage,
    /// The start [`InitialDepth::FastMarching`] falls back to where fast
    /// marching cannot serve (lights far off the optical centre, a material
    /// whose brightness does not grow as the surface turns to the light):
    /// the pyramid walked up from [`InitialDepth::FromImage`]'s constant
    /// (from the plane that best explains the image, lights off the
    /// centre); on an image more than twice
    /// [`WALK_SIDE`](crate::solver::WALK_SIDE) on a side, walked on a
    /// working copy of that side and refined at full size. The searches of
    /// the depth unit name it for all their solves, so that no solve of a
    /// search changes its start.
    Walk,
    /// A constant depth (depth units, > 0).
    Constant(f64),
    /// Warm start from a full-resolution depth map (NaN where unknown): the
    /// coarse levels are skipped and the map is refined at full resolution.
    Map(crate::grid::Grid<f64>),
}

/// Every parameter of the linearised coarse-to-fine solver.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverParams {
    /// Smoothness weight `alpha`, in [`Self::units`]; default
    /// [`Alpha::Auto`] (chosen from the image's noise level). The paper used
    /// 0.003 to 3 in its own units (Table 1).
    pub alpha: Alpha,
    /// Charbonnier contrast `lambda`, in [`Self::units`]; paper 1e-3 (pixel
    /// units), default 30 relative (the same on the paper's 256x256 Sombrero).
    pub lambda: f64,
    /// Units of alpha, lambda, `dz_limit` and `h_z`; default [`Units::Relative`].
    pub units: Units,
    /// Downsampling factor `eta` in (0, 1) between pyramid levels; paper 0.9.
    pub eta: f64,
    /// Outer (Gauss-Newton) iterations `kappa` per level at least; paper 5.
    pub kappa: usize,
    /// Outer iterations per level at most: after `kappa`, a level goes on
    /// while its energy still falls by more than `level_tolerance` (relative)
    /// per iteration. Equal to `kappa` gives the paper's fixed count.
    pub kappa_max: usize,
    /// Relative energy decrease per outer iteration below which a level stops
    /// (after `kappa` iterations).
    pub level_tolerance: f64,
    /// Outer iterations at least refining a full-resolution start across
    /// holes (object pixels of confidence below 0.5; `kappa_max` rises to
    /// it there): the fill travels farther than a start without holes, and
    /// each step is cropped. Default 10.
    pub kappa_holes: usize,
    /// Inner fixed-point iterations `l_max` on Psi'; paper 9.
    pub inner_iterations: usize,
    /// SOR sweeps per inner iteration (at most, with `linear_tolerance`);
    /// paper 10. With multigrid, the smoothing sweeps are `smoothing_sweeps`.
    pub sor_iterations: usize,
    /// The linear solver of each inner iteration; default
    /// [`LinearSolver::Auto`] (multigrid across holes, SOR elsewhere).
    pub linear_solver: LinearSolver,
    /// Whether the fast-marching start marches a denoised image; default
    /// [`StartDenoise::Auto`] (when the image reads noisy).
    pub start_denoise: StartDenoise,
    /// V-cycles per inner iteration at most (multigrid); default 4.
    pub cycles: usize,
    /// SOR sweeps before and after each coarse correction of a V-cycle;
    /// default 2.
    pub smoothing_sweeps: usize,
    /// Inexact Newton: a linear solve stops once its residual has fallen by
    /// this factor (relative to its start); 0 runs the fixed count (the
    /// paper's). Default 0 (the fixed count).
    pub linear_tolerance: f64,
    /// Refining a full-resolution start, the inner iterations stop when the
    /// Charbonnier weights Psi' moved by less than this (relative, weighted)
    /// since the last linear solve and the later ones would only polish the
    /// step (a first step short against the crop, or sweeps that reach only
    /// locally); 0 runs all `inner_iterations` (the paper's). Default 0.05.
    pub inner_tolerance: f64,
    /// Refining a full-resolution start (not across holes), a level stops
    /// once an outer iteration moved the depth by less than this share of
    /// itself on average (mean |dz| over the mean depth), before `kappa`
    /// iterations if need be; 0 runs the outer iterations `kappa` and the
    /// level tolerance decide (the paper's). Default 0: 1e-4 halves the
    /// refinement's time at 1920x1080 with the same RSE, but its image fits
    /// worse (RIE +11 % on a Dragon render, +62 % on the Sombrero;
    /// docs/speed.md).
    pub step_tolerance: f64,
    /// SOR relaxation `omega` in (0, 2); the paper does not state it; default 1.5.
    pub omega: f64,
    /// Per-pixel crop of each update: `|dz| <= dz_limit` in depth units (paper
    /// units; paper 0.01), or `|dz| <= dz_limit z` (relative units; default
    /// 0.005, the paper's 0.01 on its Sombrero at depth 2).
    pub dz_limit: f64,
    /// How `dD/dz` is computed; default exact (agrees with the paper's numeric
    /// `h_z = 1e-12` to about 1e-4 and is faster). `h_z` is in [`Self::units`]
    /// (relative: a fraction of the depth scale).
    pub derivatives: Derivatives,
    /// Smallest side (pixels) of the coarsest pyramid level; default 16.
    pub min_level_side: usize,
    /// Domain handling; default [`DomainMode::Paper`].
    pub domain: DomainMode,
    /// Initial depth; default [`InitialDepth::FastMarching`].
    pub initial_depth: InitialDepth,
    /// Update control; default [`StepControl::Backtracking`] (lower energy
    /// and RIE on every test scene; see docs/results.md).
    pub step_control: StepControl,
    /// Anti-aliasing of the pyramid: Gaussian `sigma = anti_alias_sigma *
    /// sqrt(1/eta^2 - 1)` finer pixels before each downsampling (IPOL's
    /// `sigma_0`, usually 0.6). Default 0: every level is point-sampled
    /// (bilinear) from the full image, which keeps bright peaks: area
    /// averaging darkened the Sombrero's dome on coarse levels and left it too
    /// far away (RSE 0.048 against 0.018).
    pub anti_alias_sigma: f64,
    /// With lights off the optical centre, hold the full-resolution surface
    /// behind the inequality its shadow carries: a shadow pixel the
    /// recovered surface would light goes back onto the ray from the light
    /// that grazes its occluder. Default off: on the shadows bench it left
    /// RSE where it was (geometric mean 0.0425 against 0.0421), and
    /// applied on every level it was worse (0.0456).
    pub shadow_bound: bool,
    /// The reflectance model (METHOD.md section 10); default Lambert.
    pub reflectance: ReflectanceChoice,
    /// Oren-Nayar roughness `sigma`, radians (used with `oren-nayar`).
    pub roughness_rad: f64,
    /// Blinn-Phong specular weight `k_s` (used with `blinn-phong`).
    pub specular: f64,
    /// Blinn-Phong shininess `n` (used with `blinn-phong`).
    pub shininess: f64,
    /// Where the albedo comes from; default [`AlbedoChoice::One`].
    pub albedo: AlbedoChoice,
    /// The albedo prior's weight as the smallest step of log brightness
    /// between neighbours taken as an albedo edge (`crate::albedo`; used
    /// with [`AlbedoChoice::Auto`]); default 0.2.
    pub albedo_edge: f64,
}

impl Default for SolverParams {
    fn default() -> Self {
        Self {
            alpha: Alpha::Auto,
            lambda: 30.0,
            units: Units::Relative,
            eta: 0.9,
            kappa: 5,
            kappa_max: 5,
            level_tolerance: 1e-3,
            kappa_holes: 10,
            inner_iterations: 9,
            sor_iterations: 10,
            linear_solver: LinearSolver::Auto,
            start_denoise: StartDenoise::Auto,
            cycles: 4,
            smoothing_sweeps: 2,
            linear_tolerance: 0.0,
            inner_tolerance: 0.05,
            step_tolerance: 0.0,
            omega: 1.5,
            dz_limit: 0.005,
            derivatives: Derivatives::Exact,
            min_level_side: 16,
            domain: DomainMode::Paper,
            initial_depth: InitialDepth::FastMarching,
            step_control: StepControl::Backtracking,
            anti_alias_sigma: 0.0,
            shadow_bound: false,
            reflectance: ReflectanceChoice::Lambert,
            roughness_rad: crate::material::ROUGHNESS.default,
            specular: crate::material::SPECULAR.default,
            shininess: crate::material::SHININESS.default,
            albedo: AlbedoChoice::One,
            albedo_edge: crate::albedo::DEFAULT_EDGE_LOG_STEP,
        }
    }
}

impl SolverParams {
    /// The paper's parameters in its own units (Section 4: eta 0.9, kappa 5,
    /// l_max 9, 10 SOR sweeps, dz_limit 0.01, lambda 1e-3, a constant initial
    /// depth from the image) with a given alpha in pixel units, and this
    /// project's step control and pyramid.
    pub fn paper(alpha_px: f64) -> Self {
        Self {
            alpha: Alpha::Value(alpha_px),
            initial_depth: InitialDepth::FromImage,
            ..Self::for_units(Units::Paper).with_fixed_schedule()
        }
    }

    /// These parameters with the paper's fixed counts: every one of the
    /// `inner_iterations` runs `sor_iterations` SOR sweeps (no adaptive
    /// stopping, SOR as the linear solver).
    pub fn with_fixed_schedule(self) -> Self {
        Self {
            linear_solver: LinearSolver::Sor,
            linear_tolerance: 0.0,
            inner_tolerance: 0.0,
            step_tolerance: 0.0,
            ..self
        }
    }

    /// The defaults with lambda and the dz limit in `units` (alpha auto).
    pub fn for_units(units: Units) -> Self {
        match units {
            Units::Relative => Self::default(),
            Units::Paper => Self {
                lambda: 1e-3,
                units: Units::Paper,
                dz_limit: 0.01,
                ..Self::default()
            },
        }
    }
}
