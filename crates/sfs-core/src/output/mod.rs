//! What a run writes into an output folder, once for every front (the
//! command line and the Python package): [`OutputStage`] writes a run's
//! files as one unit under a lock on the folder ([`stage`]); [`names`] is
//! the one list of every file name the tool writes (what a later run may
//! remove as stale); [`write_solved`] writes one photograph's solve (the
//! files of `sfs-studio solve`); [`set`] writes a photometric-stereo set's
//! solve and report; [`many`] is many photographs solved one by one: which,
//! where each one's files go, and the summary table.
//!
//! Uses: `io` (the file formats), `photograph_solve` and
//! `solver::photometric` (what is written), `photo` (the pipeline's report).

pub mod many;
pub mod names;
pub mod set;
pub mod stage;

use crate::io::{self, IoError};
use crate::photograph_solve::SolvedPhotograph;

pub use names::{ground_truth_files, stage};
pub use stage::{OutputStage, remove_uncommitted};

/// Writes one photograph's solve into `stage`: depth.npy, reprojection.png,
/// input_linear.png, residual.png, confidence_used.png (a derived
/// confidence), shadow.png, occlusion_edges.png, albedo.npy and albedo.png
/// (an estimated albedo), depth16.png, mesh.ply and report.json (with the
/// ground-truth errors `(rse, rie)` where given). The caller commits.
///
/// # Errors
/// A file that cannot be written, named.
pub fn write_solved(
    stage: &mut OutputStage,
    solved: &SolvedPhotograph,
    errors: Option<(f64, f64)>,
) -> Result<(), IoError> {
    let solution = &solved.solution;
    let problem = &solved.problem;
    let camera = problem.camera;
    io::write_npy_f32(&stage.path("depth.npy"), &solution.depth)?;
    io::write_png16(&stage.path("reprojection.png"), &solution.reprojection)?;
    io::write_png16(&stage.path("input_linear.png"), &problem.image)?;
    // Residual in [-0.5, 0.5] I_ref mapped to [0, 1]: grey 0.5 = explained.
    // Mapped in place and dropped before the mesh (whose triangulation is
    // the writing's peak of memory).
    let mut residual = solved.residual();
    residual
        .as_mut_slice()
        .iter_mut()
        .for_each(|v| *v = if v.is_finite() { 0.5 + *v } else { 0.5 });
    io::write_png8(&stage.path("residual.png"), &residual)?;
    drop(residual);
    if let Some(c) = &problem.confidence
        && solved.confidence_derived
    {
        io::write_png8(&stage.path("confidence_used.png"), c)?;
    }
    if let Some(shadow) = &solution.shadow {
        io::write_mask_png(&stage.path("shadow.png"), shadow)?;
    }
    io::write_mask_png(&stage.path("occlusion_edges.png"), &solved.occlusion_edges)?;
    if let Some(fit) = &solution.albedo_fit {
        // Relative: the object's 90th percentile is 1.
        let used = fit.used_albedo(&solution.depth);
        io::write_npy_f32(&stage.path("albedo.npy"), &used)?;
        io::write_png16(
            &stage.path("albedo.png"),
            &used.map(|a| if a.is_finite() { *a } else { 0.0 }),
        )?;
    }
    io::write_depth_png16(&stage.path("depth16.png"), &solution.depth)?;
    io::write_depth_ply(
        &stage.path("mesh.ply"),
        &solution.depth,
        &camera,
        Some(&solution.reprojection),
    )?;
    io::write_json(&stage.path("report.json"), &solved.report(errors))?;
    Ok(())
}
