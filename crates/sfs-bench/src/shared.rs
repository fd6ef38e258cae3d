//! What the parts share: the arguments, the settings of the paper's
//! experiments, the scene filter, the RSE-over-time recorder and the peak
//! memory reset.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use clap::Parser;
use sfs_core::cancel::{Cancel, Uncancelled};
use sfs_core::grid::Grid;
use sfs_core::metrics;
use sfs_core::solver::{LevelResult, SolveObserver, pyramid};

/// The paper's experiments side by side: every method on the test scenes,
/// clean and noisy; writes report.md, report.json and figures.
#[derive(Debug, Parser)]
#[command(name = "sfs-bench", version, long_about = None)]
pub struct BenchArgs {
    /// Folder with stanford-bunny.obj, dragon.obj and suzanne.obj; mesh
    /// scenes whose file is missing are skipped (and listed in the report).
    #[arg(long, default_value = "../shared/meshes")]
    pub meshes: PathBuf,
    /// Folder with the real photographs (`near_ps_human1/`), for
    /// `--part reflectance`; skipped (and listed) when missing.
    #[arg(long, default_value = "../shared/real")]
    pub real: PathBuf,
    /// A few minutes in all: every scene at a quarter of its size per side,
    /// a 5 s budget for the explicit scheme.
    #[arg(long)]
    pub quick: bool,
    /// Only these scenes (comma separated): sombrero, bunny, dragon,
    /// suzanne, highres; face (the shared photograph, `--part
    /// reflectance`); led1 ... led8 and render-led1 ... (`--part real`).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Option<Vec<String>>,
    /// Time budget of the explicit scheme per solve, in seconds (default 150,
    /// quick 5); the high-resolution scene gets a fifth of it.
    #[arg(long, value_name = "SECONDS")]
    pub explicit_seconds: Option<f64>,
    /// Which part to run: `paper` (the paper's tables and figures in its own
    /// units), `robustness` (the defaults over scenes, sizes, noise and
    /// exposure), `lights`, `all` (these four), `holes` (holes of confidence
    /// 0 against the harmonic fill of the true depth; holes.md, holes.json),
    /// `shadows` (a light off the axis with cast shadows; shadows.md,
    /// shadows.json), `reflectance` (Lambert, Oren-Nayar and Blinn-Phong
    /// renders solved with the matched model, as Lambertian and with auto,
    /// and the shared face with each model; reflectance.md,
    /// reflectance.json), `ps` (near-light photometric stereo on renders
    /// with a patch albedo and on the shared face; ps.md, ps.json), `edges`
    /// (occlusion edges: the truth's data energy against the answer's and
    /// the detected contours; edges.md, edges.json), `albedo` (albedo from
    /// one photograph: renders with textured albedos solved with albedo 1,
    /// auto and the true albedo, and the shared face; albedo.md,
    /// albedo.json), `real` (the shared face's photographs at the
    /// defaults, with a distance and a known depth, and renders of it;
    /// real.md, real.json), `corpus` (the rates of the automatic decisions over
    /// a randomized corpus of renders; corpus.md, corpus.json) or
    /// `speed` (time, memory and
    /// RSE over time at 256x256 and 1920x1080, with fast marching and the
    /// paper's schedule; writes speed.md and speed.json).
    #[arg(long, value_enum, default_value = "all")]
    pub part: Part,
    /// With `--part speed`: also an 18-megapixel (5184x3456) scene.
    #[arg(long)]
    pub large: bool,
    /// With `--part corpus`: which draw of the randomized corpus (0, the
    /// default, is the one the decisions' bars were chosen on; any other
    /// is a fresh corpus to check them on).
    #[arg(long)]
    pub seed: Option<u64>,
    /// The image sides the corpus draws from (`--part corpus`; its
    /// default 64,96,128,192,256). Small sides (16-48) measure the
    /// decisions where an image holds few pixels per feature.
    #[arg(long, value_delimiter = ',', default_values_t = [64usize, 96, 128, 192, 256])]
    pub corpus_sides: Vec<usize>,
    /// Output folder (created if needed).
    #[arg(long)]
    pub out: PathBuf,
}

/// `sfs-bench --part`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Part {
    /// Everything.
    All,
    /// The paper's experiments.
    Paper,
    /// The robustness table of the defaults.
    Robustness,
    /// Lights beside the lens: the light model against ignoring the light.
    Lights,
    /// Time, memory, RSE over time and responsiveness at several sizes.
    Speed,
    /// Holes of confidence 0 (disc, band, silhouette band, blobs) against
    /// the harmonic fill of the true depth (holes.md, holes.json).
    Holes,
    /// A light 30 and 45 degrees off the axis with cast shadows, against an
    /// exact hand mask and the same light without shadows (shadows.md,
    /// shadows.json).
    Shadows,
    /// Oren-Nayar and Blinn-Phong renders solved with the matched model, as
    /// Lambertian and with auto; the shared face with each model
    /// (reflectance.md, reflectance.json).
    Reflectance,
    /// Near-light photometric stereo: renders with a patch albedo under 3,
    /// 4 and 8 LEDs, clean and noisy, the invariances, and the shared face's
    /// seven photographs (ps.md, ps.json, face-*.png).
    Ps,
    /// Occlusion edges: the defaults, the truth start and fast marching; the
    /// data energy of the true depth against the answer's, where the truth's
    /// misfit lies, and the occluding contours detected in the answer
    /// against the true depth jumps (edges.md, edges.json).
    Edges,
    /// Albedo from one photograph: renders times patch, line, smooth and
    /// uniform albedos, lights centred and beside the lens, clean and
    /// sigma 5, solved with albedo 1, auto and the true albedo; the shared
    /// face's LED 4 against its seven photographs (albedo.md, albedo.json).
    Albedo,
    /// The guard of the photograph path: every shared LED photograph at the
    /// defaults, with `--distance` 10 % off and with `--known-depth`,
    /// against the seven-photograph reconstruction; renders of that face at
    /// the defaults (real.md, real.json).
    Real,
    /// The rates of the automatic decisions (depth unit, albedo) over a
    /// randomized corpus of renders (corpus.md, corpus.json).
    Corpus,
    /// The paper's Table 1 like for like: each scene rendered with mesh
    /// and with depth-map shading, clean and noisy, at the defaults, beside
    /// the paper's RSE (table1.md, table1.json).
    Table1,
}

// The paper part's settings; run.rs uses them, report.rs states them.

/// Smoothness weight of the variational methods on clean images (pixel units).
pub(crate) const ALPHA_CLEAN: f64 = 100.0;
/// On noisy images (sigma 20).
pub(crate) const ALPHA_NOISY: f64 = 2000.0;
/// Noise of the noisy images, on the 0..255 scale, and its seed.
pub(crate) const NOISE_SIGMA: f64 = 20.0;
pub(crate) const NOISE_SEED: u64 = 1;
/// Weight of the depth post-processing (depth units squared, pixel units).
pub(crate) const POST_WEIGHT: f64 = 100.0;
/// Primal-dual iterations of the TV pre-processing.
pub(crate) const TV_ITERATIONS: usize = 200;

/// Every scene `--scenes` can name.
pub(crate) const SCENE_NAMES: &[&str] = &[
    "sombrero",
    "bunny",
    "dragon",
    "suzanne",
    "highres",
    "face",
    // `--part real`: the shared face's photographs and their renders.
    "led1",
    "led2",
    "led3",
    "led4",
    "led6",
    "led7",
    "led8",
    "render-led1",
    "render-led2",
    "render-led3",
    "render-led4",
    "render-led6",
    "render-led7",
    "render-led8",
];

/// The command line this bench was run with, for its reports.
pub(crate) fn command_line() -> String {
    std::env::args().collect::<Vec<_>>().join(" ")
}

/// Whether `--scenes` asks for `name` (no `--scenes`: every scene).
pub(crate) fn wanted(args: &BenchArgs, name: &str) -> bool {
    args.scenes
        .as_ref()
        .is_none_or(|list| list.iter().any(|s| s.eq_ignore_ascii_case(name)))
}

/// The scenes the parts render: the analytic Sombrero and the three meshes.
pub(crate) const RENDERED_SCENES: [&str; 4] = ["sombrero", "bunny", "dragon", "suzanne"];

/// The [`RENDERED_SCENES`] that `--scenes` asks for, in their order.
pub(crate) fn wanted_renders(args: &BenchArgs) -> impl Iterator<Item = &'static str> + '_ {
    RENDERED_SCENES
        .into_iter()
        .filter(move |name| wanted(args, name))
}

/// Records RSE whenever a level (or a snapshot) arrives.
pub(crate) struct CurveRecorder<'a> {
    pub(crate) truth: &'a Grid<f64>,
    pub(crate) full_domain: Grid<bool>,
    pub(crate) points: Vec<(f64, f64)>,
    pub(crate) overhead: Duration,
}

impl SolveObserver for CurveRecorder<'_> {
    fn on_level(&mut self, result: &LevelResult) {
        let started = Instant::now();
        let level_domain = result.depth.map(|z| z.is_finite());
        let full = pyramid::upsample_depth(&result.depth, &level_domain, &self.full_domain);
        let full = sfs_core::solver::problem::masked(&full, &self.full_domain, Cancel::NEVER)
            .uncancelled();
        if let Ok(rse) = metrics::rse(&full, self.truth) {
            let t = result.elapsed.saturating_sub(self.overhead).as_secs_f64();
            self.points.push((t, rse));
        }
        self.overhead += started.elapsed();
    }
}

/// Resets the process's peak resident set (Linux `clear_refs` 5); false
/// where that is not possible.
pub(crate) fn reset_peak_memory() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}
