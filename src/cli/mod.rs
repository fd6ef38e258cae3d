//! The command line: `synth`, `solve`, `eval` and `view` (the viewer, which
//! also opens when no subcommand is given), parsed with clap. The benchmarks
//! are a binary of their own (crate sfs-bench); a hidden `bench` points
//! there. Errors are `anyhow` chains that name the file or parameter at
//! fault; nothing here panics on user input.

use std::ffi::OsString;
use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};

mod eval;
mod lights;
mod outputs;
mod params;
mod parse;
mod photometric;
mod solve;
mod synth;
#[cfg(feature = "gui")]
mod view;

pub use eval::EvalArgs;
use parse::parse_path;
pub use solve::SolveArgs;
pub use synth::SynthArgs;
#[cfg(feature = "gui")]
pub use view::ViewArgs;

/// Perspective shape from shading (Maurer et al., GCPR 2015): recover depth
/// from one image lit by a point light at the camera centre.
#[derive(Debug, Parser)]
#[command(name = "sfs-studio", version, about, long_about = None)]
pub struct Cli {
    /// What to do; without a subcommand the viewer opens on the built-in
    /// sample (the Sombrero) and starts solving it.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// With no subcommand: save a screenshot of the viewer here once the
    /// solve has finished, then exit.
    #[arg(long, value_name = "PATH.png", value_parser = parse_path)]
    pub screenshot: Option<PathBuf>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a synthetic scene with ground truth (the Sombrero or an OBJ mesh).
    Synth(Box<SynthArgs>),
    /// Recover depth from an image.
    Solve(Box<SolveArgs>),
    /// Compare a depth map with a synthetic scene's ground truth (prints JSON).
    Eval(EvalArgs),
    /// Moved to its own binary: refused with a message that names it.
    #[command(hide = true, disable_help_flag = true)]
    Bench {
        /// Whatever followed `bench`, repeated in the message.
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Open the viewer on an image.
    #[cfg(feature = "gui")]
    View(Box<ViewArgs>),
}

/// Parses `args` (including the program name) and runs the command.
pub fn run(args: impl IntoIterator<Item = impl Into<OsString> + Clone>) -> Result<()> {
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            // --help and --version are successes; everything else is an error.
            if matches!(
                e.kind(),
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion
            ) {
                // Ignoring a failed print to a closed stdout is fine here.
                let _ = e.print();
                return Ok(());
            }
            return Err(CliUsage(e.render().to_string()).into());
        }
    };
    match cli.command {
        Some(Command::Synth(args)) => synth::run(&args),
        Some(Command::Solve(args)) if args.photometric_stereo => photometric::run(&args),
        Some(Command::Solve(args)) => solve::run(&args),
        Some(Command::Eval(args)) => eval::run(&args),
        Some(Command::Bench { args }) => Err(CliUsage(bench_moved(&args)).into()),
        #[cfg(feature = "gui")]
        Some(Command::View(args)) => view::run(&args),
        #[cfg(feature = "gui")]
        None => view::run_sample(cli.screenshot),
        #[cfg(not(feature = "gui"))]
        None => Err(anyhow::anyhow!(
            "this build has no viewer (feature `gui`); use a subcommand, see --help"
        )),
    }
}

/// What `sfs-studio bench ARGS` says: the benchmarks are the sfs-bench
/// binary, run from the repository with the same arguments.
fn bench_moved(args: &[String]) -> String {
    let mut command = String::from("cargo run -p sfs-bench --release --");
    for arg in args {
        command.push(' ');
        if arg.is_empty() || arg.contains(char::is_whitespace) {
            command.push_str(&format!("'{arg}'"));
        } else {
            command.push_str(arg);
        }
    }
    if args.is_empty() {
        command.push_str(" --out DIR");
    }
    format!(
        "error: the benchmarks are no longer part of sfs-studio; they are the sfs-bench \
         binary of the workspace. From the repository run\n\n    {command}\n\n\
         (`cargo run -p sfs-bench --release -- --help` lists the options)\n"
    )
}

/// A usage error from clap, already rendered.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CliUsage(pub String);
