//! The binary's side of the output folders: Ctrl-C and SIGTERM remove a
//! run's half-written outputs ([`sfs_core::output::remove_uncommitted`]).
//! The staging itself is the core's ([`sfs_core::output::OutputStage`]),
//! shared with the Python package.

pub use sfs_core::output::OutputStage;

/// Makes Ctrl-C and SIGTERM remove this process's uncommitted staging
/// folders and exit with status 130; a commit in progress finishes first, so
/// a destination never holds half of a run. Call once, early, from a
/// command-line program; an error means the handler could not be installed.
pub fn install_interrupt_cleanup() -> Result<(), String> {
    ctrlc::set_handler(|| {
        if sfs_core::output::remove_uncommitted() {
            eprintln!("interrupted: the unfinished output was removed");
        } else {
            eprintln!("interrupted");
        }
        std::process::exit(130);
    })
    .map_err(|e| e.to_string())
}
