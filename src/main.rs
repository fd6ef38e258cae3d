//! The `sfs-studio` binary: command-line subcommands (the viewer comes next).

use std::process::ExitCode;

fn main() -> ExitCode {
    match sfs_studio::cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}
