//! End-to-end tests of the `sfs-studio` binary: `synth`, `solve` and `eval`
//! on tiny scenes, `--help`, and bad inputs (non-zero exit, a message naming
//! the problem, and nothing left in the output folder).
//!
//! One test binary (one link): a module per command, the helpers in `common`.

mod common;
mod depth_unit;
mod floats;
#[cfg(feature = "gui")]
mod fronts;
mod options;
mod photographs;
mod photometric_fit;
mod solve;
mod solve_many;
mod synth;
mod usage;
