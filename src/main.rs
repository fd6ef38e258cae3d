//! The `sfs-studio` binary: the viewer (no subcommand or `view`) and the
//! command-line subcommands, all through `cli::run`.
#![deny(missing_docs)]

mod cli;
mod output;

use std::process::ExitCode;

fn main() -> ExitCode {
    // Ctrl-C and SIGTERM remove a run's half-written outputs before exiting.
    if let Err(e) = output::install_interrupt_cleanup() {
        eprintln!(
            "warning: cannot catch Ctrl-C ({e}); an interrupted run may leave a hidden staging folder in its output folder"
        );
    }
    match cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // clap's usage errors arrive rendered, with their own prefix.
            if let Some(usage) = error.downcast_ref::<cli::CliUsage>() {
                eprint!("{usage}");
            } else {
                eprintln!("error: {error:#}");
            }
            ExitCode::FAILURE
        }
    }
}
