//! `sfs-studio view` (and no subcommand): open the viewer.

use std::path::PathBuf;

use anyhow::{Result, anyhow};
use clap::Args;

use sfs_core::photo::Vignetting;
use sfs_viewer::app::{OpenOptions, Panel2d, ViewerOptions};

/// Options of `sfs-studio view`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct ViewArgs {
    /// Image to open (8/16-bit PNG, TIFF, JPEG). A `scene.json`,
    /// `mask.png` and `depth_gt.npy` beside it (a `synth` folder) are used.
    /// Several images, or a folder whose `scene.json`/`calibration.json`
    /// names each photograph by its light (`image`), open as one
    /// photometric-stereo set (a folder's `mask.png` and `ambient.png` are
    /// used).
    #[arg(value_parser = super::parse::parse_path, num_args = 1.., required = true, value_name = "IMAGE|FOLDER")]
    pub images: Vec<PathBuf>,
    /// Camera file (keys of `synth`'s scene.json).
    #[arg(long, value_parser = super::parse::parse_path)]
    pub camera: Option<PathBuf>,
    /// Confidence PNG (0 = untrusted .. 255 = trusted; at the photograph's
    /// size or the working size): the confidence layer starts from it, as
    /// `solve --confidence` (an autosaved painting of this image wins, and
    /// the status line says so).
    #[arg(long, value_parser = super::parse::parse_path)]
    pub confidence: Option<PathBuf>,
    /// Object mask PNG (255 = object).
    #[arg(long, value_parser = super::parse::parse_path)]
    pub mask: Option<PathBuf>,
    /// sRGB decoding: `on`, `off` or `auto` (on for JPEG and 8-bit
    /// photographs, off for 16-bit, float and linear-marked PNGs); `--srgb`
    /// alone means on.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on")]
    pub srgb: super::solve::SrgbArg,
    /// A frame with every light off (same camera settings), subtracted from
    /// the image.
    #[arg(long, value_name = "FILE", value_parser = super::parse::parse_path)]
    pub ambient: Option<PathBuf>,
    /// Vignetting correction: `cos4` (the pinhole's natural fall-off) or a
    /// flat-field image (a uniform white target) [default: none].
    #[arg(long, value_name = "cos4|FILE")]
    pub vignetting: Option<String>,
    /// A known albedo map (linear, relative), divided out; pixels with
    /// albedo below 0.02 are not trusted.
    #[arg(long, value_name = "FILE", value_parser = super::parse::parse_path)]
    pub albedo: Option<PathBuf>,
    /// Smoothness weight alpha in relative units, or `auto` (else the
    /// remembered value; default auto).
    #[arg(long)]
    pub alpha: Option<String>,
    /// Working size: a longer image side is area-averaged down to this many
    /// pixels before solving (0 = full size; else the remembered value,
    /// default 1500).
    #[arg(long, value_name = "PIXELS")]
    pub max_side: Option<usize>,
    /// Save a screenshot here once the solve has finished, then exit.
    #[arg(long, value_name = "PATH.png", value_parser = super::parse::parse_path)]
    pub screenshot: Option<PathBuf>,
    /// Write UI frame-time statistics (JSON) here on exit.
    #[arg(long, value_name = "PATH.json", value_parser = super::parse::parse_path)]
    pub stats: Option<PathBuf>,
    /// With --stats: after the first solve, change alpha this many times and
    /// time each change to the first new level on screen.
    #[arg(long, default_value_t = 0)]
    pub latency_trials: usize,
    /// The 2-D panel shown first: input, reprojection, residual, depth,
    /// depth-error (against a ground truth), albedo (a set's, or the albedo
    /// a photograph was solved with), normals or photo-residual (a set's).
    #[arg(long, value_name = "PANEL", value_parser = parse_panel)]
    pub panel: Option<Panel2d>,
    /// Show the albedo (a set's, or the one a photograph was solved with) on
    /// the 3-D surface (its texture) once solved.
    #[arg(long)]
    pub albedo_texture: bool,
    /// Window size in points, WIDTHxHEIGHT.
    #[arg(long, value_parser = super::parse::parse_size, default_value = "1280x800")]
    pub window: (usize, usize),
}

/// Opens the viewer on `args.image`.
pub fn run(args: &ViewArgs) -> Result<()> {
    let alpha = match &args.alpha {
        Some(text) => {
            let spec = sfs_core::params::table::spec("alpha")
                .ok_or_else(|| anyhow!("no alpha in the parameter table"))?;
            Some(match spec.parse(text)? {
                sfs_core::params::ParamValue::Real(v) => sfs_core::params::Alpha::Value(v),
                _ => sfs_core::params::Alpha::Auto,
            })
        }
        None => None,
    };
    for path in &args.images {
        let exists = path.is_file() || args.images.len() == 1 && path.is_dir();
        if !exists {
            return Err(anyhow!("image {} does not exist", path.display()));
        }
    }
    let options = ViewerOptions {
        image: args.images.first().cloned(),
        set_images: args.images.iter().skip(1).cloned().collect(),
        panel: args.panel,
        albedo_texture: args.albedo_texture,
        open: OpenOptions {
            camera: args.camera.clone(),
            mask: args.mask.clone(),
            ambient: args.ambient.clone(),
            vignetting: Vignetting::from_option(args.vignetting.as_deref()),
            albedo: args.albedo.clone(),
            confidence: args.confidence.clone(),
            srgb: match args.srgb {
                super::solve::SrgbArg::On => Some(true),
                super::solve::SrgbArg::Off => Some(false),
                super::solve::SrgbArg::Auto => None,
            },
            ..OpenOptions::default()
        },
        alpha,
        max_side: args.max_side,
        screenshot: args.screenshot.clone(),
        stats: args.stats.clone(),
        latency_trials: args.latency_trials,
        ..ViewerOptions::default()
    };
    launch(options, args.window)
}

/// Every `--panel` name, in the order `--help` and the error list them.
const PANEL_NAMES: [&str; 8] = [
    "input",
    "reprojection",
    "residual",
    "depth",
    "depth-error",
    "albedo",
    "normals",
    "photo-residual",
];

/// A `--panel` name.
fn parse_panel(text: &str) -> Result<Panel2d, String> {
    Ok(match text {
        "input" => Panel2d::Input,
        "reprojection" => Panel2d::Reprojection,
        "residual" => Panel2d::Difference,
        "depth" => Panel2d::Depth,
        "depth-error" => Panel2d::DepthError,
        "albedo" => Panel2d::Albedo,
        "normals" => Panel2d::Normals,
        "photo-residual" => Panel2d::PhotoResidual,
        _ => {
            return Err(format!(
                "unknown panel {text:?}: {} or {}",
                PANEL_NAMES[..PANEL_NAMES.len() - 1].join(", "),
                PANEL_NAMES[PANEL_NAMES.len() - 1]
            ));
        }
    })
}

/// Opens the viewer on the built-in sample.
pub fn run_sample(screenshot: Option<PathBuf>) -> Result<()> {
    launch(
        ViewerOptions {
            screenshot,
            ..ViewerOptions::default()
        },
        (1280, 800),
    )
}

fn launch(options: ViewerOptions, window: (usize, usize)) -> Result<()> {
    sfs_viewer::app::run_window(options, window)
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use clap::Parser;
    use sfs_core::grid::Grid;
    use sfs_core::photo::{self, Vignetting};
    use sfs_core::solver::Problem;
    use sfs_viewer::app::{Document, OpenOptions};

    use crate::cli::{Cli, Command};

    /// The problem `solve ARGS` builds.
    fn cli_problem(args: &[&str]) -> Problem {
        let cli = Cli::try_parse_from(["sfs-studio", "solve"].iter().chain(args))
            .unwrap_or_else(|e| panic!("{e}"));
        let Some(Command::Solve(args)) = cli.command else {
            panic!("not a solve")
        };
        let input = args.photo_input().unwrap_or_else(|e| panic!("{e:#}"));
        photo::prepare(&input)
            .unwrap_or_else(|e| panic!("{e:#}"))
            .problem
    }

    /// `a` and `b` are the same problem, bit for bit; a mask or confidence
    /// that trusts every pixel is the same as none (the viewer's masks say
    /// "none" then).
    fn assert_same(a: &Problem, b: &Problem) {
        assert_eq!(a.image, b.image, "image");
        assert_eq!(a.camera, b.camera, "camera");
        assert_eq!(a.intensity_scale, b.intensity_scale, "intensity scale");
        assert_eq!(a.lights, b.lights, "lights");
        let (w, h) = a.image.size();
        let object = |p: &Problem| p.object_mask.clone().unwrap_or(Grid::filled(w, h, true));
        assert_eq!(object(a), object(b), "object mask");
        let trust = |p: &Problem| p.confidence.clone().unwrap_or(Grid::filled(w, h, 1.0));
        assert_eq!(trust(a), trust(b), "confidence");
    }

    /// The problems `solve IMAGE --camera CAMERA --mask MASK EXTRA
    /// --max-side SIDE --out DIR/out` and the viewer (opening `IMAGE` with
    /// `options` at that working size) build.
    fn both_problems(
        image: &Path,
        [camera, mask]: [&Path; 2],
        extra: &[&str],
        max_side: usize,
        options: OpenOptions,
        dir: &Path,
    ) -> (Problem, Problem) {
        let out = dir.join("out");
        let side = max_side.to_string();
        let mut args = vec![text(image), "--camera", text(camera), "--mask", text(mask)];
        args.extend_from_slice(extra);
        args.extend(["--max-side", &side, "--out", text(&out)]);
        let options = OpenOptions {
            max_side: Some(max_side),
            ..options
        };
        (cli_problem(&args), viewer_problem(image, &options))
    }

    fn viewer_problem(image: &Path, options: &OpenOptions) -> Problem {
        Document::open(image, options)
            .unwrap_or_else(|e| panic!("{e:#}"))
            .problem()
    }

    fn text(path: &Path) -> &str {
        path.to_str()
            .unwrap_or_else(|| panic!("{} is not UTF-8", path.display()))
    }

    /// `view --panel` accepted (and its error listed) `depth-error`, which
    /// `--help` did not: every name is in both.
    #[test]
    fn the_panel_help_lists_every_panel_the_option_takes() {
        use clap::CommandFactory;
        let command = Cli::command();
        let view = command.find_subcommand("view").expect("view");
        let panel = view
            .get_arguments()
            .find(|a| a.get_id() == "panel")
            .expect("--panel");
        let help = panel.get_help().expect("help").to_string();
        let error = super::parse_panel("bogus").expect_err("unknown");
        for name in super::PANEL_NAMES {
            assert!(super::parse_panel(name).is_ok(), "{name}");
            assert!(help.contains(name), "--help lacks {name}: {help}");
            assert!(error.contains(name), "the error lacks {name}: {error}");
        }
    }

    #[test]
    fn the_viewer_and_solve_build_the_same_problem_from_the_same_files() {
        let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sombrero");
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let ambient = dir.path().join("ambient.png");
        sfs_core::io::write_png16(&ambient, &Grid::filled(256, 256, 0.02))
            .unwrap_or_else(|e| panic!("{e}"));
        let image = sample.join("image16.png");
        // The viewer finds scene.json and mask.png beside the image.
        let (cli, viewer) = both_problems(
            &image,
            [&sample.join("scene.json"), &sample.join("mask.png")],
            &["--ambient", text(&ambient), "--vignetting", "cos4"],
            200,
            OpenOptions {
                ambient: Some(ambient.clone()),
                vignetting: Vignetting::Cos4,
                ..OpenOptions::default()
            },
            dir.path(),
        );
        assert_eq!(cli.image.size(), (200, 200));
        assert!(cli.object_mask.is_some());
        assert_same(&cli, &viewer);
    }

    #[test]
    fn the_viewer_and_solve_build_the_same_problem_from_a_real_photograph() {
        let face = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/real/near_ps_human1");
        assert!(
            face.is_dir(),
            "the shared photographs are missing: {}",
            face.display()
        );
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let image = face.join("led4.png");
        let ambient = face.join("ambient.png");
        let (cli, viewer) = both_problems(
            &image,
            [&face.join("calibration.json"), &face.join("mask.png")],
            &["--ambient", text(&ambient)],
            300,
            OpenOptions {
                ambient: Some(ambient.clone()),
                ..OpenOptions::default()
            },
            dir.path(),
        );
        assert_eq!(cli.lights.len(), 1, "LED 4 alone");
        assert_same(&cli, &viewer);
    }

    #[test]
    fn a_confidence_file_reaches_the_viewer_as_it_reaches_solve() {
        let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sombrero");
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        // A disc of confidence 0 at the photograph's size; the working
        // size (200) averages it, as solve does.
        let confidence = dir.path().join("confidence.png");
        let disc = Grid::from_fn(256, 256, |c, r| {
            let (dx, dy) = (c as f64 - 128.0, r as f64 - 115.0);
            if dx.hypot(dy) < 36.0 { 0.0 } else { 1.0 }
        });
        sfs_core::io::write_png8(&confidence, &disc).unwrap_or_else(|e| panic!("{e}"));
        let image = sample.join("image16.png");
        let (cli, viewer) = both_problems(
            &image,
            [&sample.join("scene.json"), &sample.join("mask.png")],
            &["--confidence", text(&confidence)],
            200,
            OpenOptions {
                confidence: Some(confidence.clone()),
                ..OpenOptions::default()
            },
            dir.path(),
        );
        let held = |p: &Problem| {
            p.confidence
                .as_ref()
                .map_or(0, |c| c.as_slice().iter().filter(|&&v| v < 0.5).count())
        };
        assert!(held(&cli) > 1000, "the disc is untrusted");
        // The viewer's mask layers hold confidence as f32: the same values
        // to f32's precision, the rest bit for bit.
        let (mut cli, mut viewer) = (cli, viewer);
        let (a, b) = (cli.confidence.take(), viewer.confidence.take());
        assert_same(&cli, &viewer);
        let (a, b) = (
            a.unwrap_or_else(|| panic!("solve has the confidence")),
            b.unwrap_or_else(|| panic!("the viewer has the confidence")),
        );
        assert_eq!(a.size(), b.size());
        let worst = a.max_abs_difference(&b);
        assert!(worst < 1e-6, "confidence differs by {worst}");
        // A confidence file that cannot be read is left out with a note;
        // the image still opens.
        let broken = dir.path().join("broken.png");
        std::fs::write(&broken, b"not a png").unwrap_or_else(|e| panic!("{e}"));
        let doc = Document::open(
            &image,
            &OpenOptions {
                confidence: Some(broken),
                ..OpenOptions::default()
            },
        )
        .unwrap_or_else(|e| panic!("{e:#}"));
        assert!(
            doc.notes
                .iter()
                .any(|n| n.contains("ignored") && n.contains("broken.png")),
            "{:?}",
            doc.notes
        );
        assert_eq!(doc.input.confidence, None);
    }
}
