//! What the estimators above the solver found, as the plain data a
//! [`Solution`](super::problem::Solution) carries: the `--albedo auto` fit
//! ([`AlbedoFit`], made by `albedo_fit`) and the `--reflectance auto` fit
//! ([`MaterialFit`], made by `material_fit`), with the albedo decision's
//! bar. Here, below the solver core, so that the core holds the fits
//! without importing the estimators that make them (they import the core).
//! Uses `albedo` (the edge rule), `albedo_texture`, `grid` and `material`.

use serde::Serialize;

use crate::albedo::EdgeRule;
use crate::albedo_texture::TextureSummary;
use crate::grid::Grid;
use crate::material::Material;

/// The share of albedo 1's misfit the estimate must remove to be used: the
/// albedo prior's cost of its edges. Without it, noise decided: on renders
/// of uniform albedo with sigma 20 noise (`synth --noise 20`, 8-bit) the
/// estimate's few edges (0.1-1.5 % of the object) removed 1-12 % of the
/// misfit and made RSE up to 2.2x worse (Suzanne 256 px); real albedo
/// removed 25 % (the face) to 96 % (the Sombrero with lines).
pub const MIN_GAIN: f64 = 0.2;

/// A decision within this of its bar (the misfit ratio against `1 -
/// max(MIN_GAIN, noise share)`) is a close call, said in the summary and
/// as a warning: small changes of the estimate move the ratio by as much
/// (measured on the albedo bench: a shading-corrected edge step or a
/// contour test moved ratios by up to 0.04, 0.70 to 0.66 and 0.77 to 0.75,
/// and flipped the noisy centred Bunny with lines from albedo 1 at RSE
/// 0.019 to its estimate at 0.117), so the photograph hardly tells the
/// estimate from shading.
pub const CLOSE_MARGIN: f64 = 0.05;

/// The raw numbers of the decided estimate's test on the working copy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Evidence {
    /// `sum c (I - R)^2` with albedo 1.
    pub misfit_one: f64,
    /// `sum c (I - rho R)^2` with the estimate.
    pub misfit_with: f64,
    /// Pixels in the sums.
    pub pixels: usize,
    /// The estimate's edge and cut pairs as the working copy counts them.
    pub working_pairs: f64,
    /// The median of albedo 1's squared residuals.
    pub one_median_sq: f64,
    /// The working copy's noise sigma (image units).
    pub noise_sigma: f64,
}

/// What `--albedo auto` found and decided.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlbedoFit {
    /// The estimated relative albedo at the problem's size (1 off the
    /// object and where no edge is found); the solve divided it out only
    /// when [`Self::used`]. `None` where albedo 1 stands and no estimate is
    /// kept: no edge was found, or the estimate was rejected and the solve
    /// let it go ([`Self::forget_rejected`]), so that a full-size grid of
    /// ones or of an unused estimate (8 bytes per pixel) is not held
    /// through the solve. Always `Some` when [`Self::used`].
    #[serde(skip)]
    pub albedo: Option<Grid<f64>>,
    /// Whether the solve used the estimate (else albedo 1).
    pub used: bool,
    /// The estimate's misfit to the photograph over albedo 1's, both with
    /// their solved shapes on the working copy, or at the full size (see
    /// [`Self::working_side`]); below 1: the estimate explains it better.
    /// NaN when there was nothing to compare.
    pub misfit_ratio: f64,
    /// The decision's margin: the bar `1 - max(MIN_GAIN, noise_share)`
    /// minus [`Self::misfit_ratio`] (positive: used). Within
    /// [`CLOSE_MARGIN`] of 0 the decision is a close call. NaN when there
    /// was nothing to compare.
    pub margin: f64,
    /// Share of the object's pixels beside an albedo edge (on the working
    /// copy and at the full size, summed; at most 1).
    pub edge_share: f64,
    /// Share of the variance of the object's log brightness that the
    /// albedo explains.
    pub explained_share: f64,
    /// The lowest albedo over the object (relative: the object's 90th
    /// percentile is 1).
    pub min_albedo: f64,
    /// The edge step used (`albedo-edge`).
    pub edge_log_step: f64,
    /// A given edge step left the decision as the default's would have:
    /// no edge found with it, nor with the default step.
    pub edge_step_without_effect: bool,
    /// Which edges the decided estimate holds: every step, or only the
    /// steps their chain confirms.
    pub edge_rule: EdgeRule,
    /// Steps the decided estimate cut out of its integration (its chain did
    /// not confirm them: contours, shadows' edges), at both scales.
    pub cut_pairs: usize,
    /// Fine texture read as darker albedo (`crate::albedo_texture`): the
    /// change of log albedo per unit of texture measured in the image
    /// (NaN when it could not be, or no edge carries it), whether it is part of the estimate, its
    /// band-passed correlation with the brightness the edges leave, and the
    /// share of the trusted object it darkens by more than 10 %.
    pub texture: TextureSummary,
    /// The image's noise the edges were measured against (image units).
    pub noise_sigma: f64,
    /// The share of albedo 1's misfit the estimate's edges could remove by
    /// fitting the noise alone (2 sigma^2 per edge on the working copy);
    /// the estimate must remove more than this and than [`MIN_GAIN`].
    pub noise_share: f64,
    /// The power of two the divided image and the intensity scale were
    /// divided by (1 when unused).
    pub divisor: f64,
    /// Longest side, pixels, of the images the decision compared: the
    /// working copy, or the photograph's full size where a known-depth
    /// search gave each explanation its own scale.
    pub working_side: usize,
    /// The raw sums the decision was made from (on the working copy).
    pub evidence: Evidence,
    /// Seconds spent estimating and comparing.
    pub seconds: f64,
    /// The decision in plain words.
    pub summary: String,
}

impl AlbedoFit {
    /// The albedo the solve used, NaN where `depth` has no surface: the
    /// estimate when [`Self::used`], else 1 (what `albedo.npy` holds and
    /// the viewer's albedo tab shows).
    pub fn used_albedo(&self, depth: &Grid<f64>) -> Grid<f64> {
        let uniform = |z: &f64| if z.is_finite() { 1.0 } else { f64::NAN };
        match self.used_estimate() {
            Some(albedo) => albedo.zip_map(depth, |a, z| if z.is_finite() { *a } else { f64::NAN }),
            None => depth.map(uniform),
        }
    }

    /// The estimate when the solve used it, else `None` (albedo 1).
    pub fn used_estimate(&self) -> Option<&Grid<f64>> {
        self.albedo.as_ref().filter(|_| self.used)
    }

    /// Lets a rejected estimate go (albedo 1 stands: nothing reads it
    /// after the decision but a known-distance search, which compares it
    /// before this is called).
    pub fn forget_rejected(&mut self) {
        if !self.used {
            self.albedo = None;
        }
    }

    /// Decides with `ratio`, the estimate's misfit to the photograph over
    /// albedo 1's: used when below `1 - max(MIN_GAIN, noise_share)`; says
    /// so in the summary.
    pub fn decide(&mut self, ratio: f64) {
        self.misfit_ratio = ratio;
        let bar = 1.0 - MIN_GAIN.max(self.noise_share);
        self.margin = bar - ratio;
        self.used = ratio < bar;
        let mut summary = if self.used {
            format!(
                "albedo estimated: {:.1} % of the object beside an albedo edge{}{}, down to \
                 {:.2} of the common albedo; with its shape it reproduces the photograph {:.0} % \
                 better than albedo 1 ({:.0} % of the log brightness's variance is albedo)",
                100.0 * self.edge_share,
                self.rule_words(),
                self.texture_words(),
                self.min_albedo,
                100.0 * (1.0 - ratio),
                100.0 * self.explained_share
            )
        } else {
            format!(
                "albedo 1: the estimated albedo ({:.1} % of the object beside an edge{}{}) \
                 reproduces the photograph with its shape x{ratio:.2} as well as albedo 1, short \
                 of the {:.0} % it must remove (the prior's cost of its edges, and what they \
                 could gain by fitting the noise): its edges are taken for shading (occluding \
                 contours, creases, noise)",
                100.0 * self.edge_share,
                self.rule_words(),
                self.texture_words(),
                100.0 * (1.0 - bar)
            )
        };
        if let Some(close) = self.close_call() {
            summary.push_str("; ");
            summary.push_str(&close);
        }
        self.summary = summary;
    }

    /// Whether the decision was within [`CLOSE_MARGIN`] of its bar.
    pub fn is_close_call(&self) -> bool {
        self.margin.abs() < CLOSE_MARGIN
    }

    /// When the decision was a close call ([`Self::is_close_call`]), what
    /// that means for the user, in plain words; else `None`.
    pub fn close_call(&self) -> Option<String> {
        self.is_close_call().then(|| {
            let advice = if self.used {
                "compare with --albedo 1"
            } else {
                "where the marks are known, give them as --albedo FILE or paint them out of \
                 the confidence"
            };
            format!(
                "a close call (misfit x{:.2} against a bar of x{:.2}): the photograph hardly \
                 tells this albedo from shading, and the depth can differ much with the other \
                 choice; {advice}",
                self.misfit_ratio,
                self.misfit_ratio + self.margin,
            )
        })
    }

    /// The edge rule in words (empty for every step as an edge).
    fn rule_words(&self) -> String {
        match self.edge_rule {
            EdgeRule::Steps => String::new(),
            EdgeRule::Chains => format!(
                ", only steps their chain confirms ({} pairs cut as contours or shadows' edges)",
                self.cut_pairs
            ),
        }
    }

    /// The texture's part of the estimate in words (empty when unused).
    fn texture_words(&self) -> String {
        if self.texture.used {
            format!(
                ", {:.0} % darkened by fine texture (hair; log slope {:.1}, correlation {:.2}; \
                 carried by the edges, which alone are tested below)",
                100.0 * self.texture.darkened_share,
                self.texture.log_slope,
                self.texture.correlation
            )
        } else {
            String::new()
        }
    }
}

/// One candidate of the fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MaterialTrial {
    /// The material solved.
    pub material: Material,
    /// The solve's final energy on the working copy (relative to the
    /// best candidate's: 1 for the best).
    pub relative_energy: f64,
    /// `sqrt(sum c (I - R)^2 / sum c I^2)` of that solve.
    pub relative_residual: f64,
}

/// What `--reflectance auto` found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaterialFit {
    /// The material the solve used: Lambert (the fit reports, it does not
    /// decide; see the module).
    pub material: Material,
    /// The candidate with the lowest energy on the working copy.
    pub best: Material,
    /// Whether the image determined the material: false (see the module;
    /// kept in the report so that no reader takes `best` for a finding).
    pub determined: bool,
    /// How much lower the best candidate's energy is than Lambert's, as a
    /// share (0: Lambert is best).
    pub energy_gain: f64,
    /// Every candidate, best first.
    pub trials: Vec<MaterialTrial>,
    /// Side of the working copy, pixels.
    pub working_side: usize,
    /// Seconds the fit took.
    pub seconds: f64,
    /// The finding in plain words.
    pub summary: String,
}
