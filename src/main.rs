//! The `sfs-studio` binary: the viewer (no subcommand or `view`) and the
//! command-line subcommands, all through `cli::run`.

use std::process::ExitCode;

fn main() -> ExitCode {
    match sfs_studio::cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // clap's usage errors arrive rendered, with their own prefix.
            if let Some(usage) = error.downcast_ref::<sfs_studio::cli::CliUsage>() {
                eprint!("{usage}");
            } else {
                eprintln!("error: {error:#}");
            }
            ExitCode::FAILURE
        }
    }
}
