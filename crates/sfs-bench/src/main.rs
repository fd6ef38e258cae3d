//! `sfs-bench`: the paper's experiments side by side in one run (`cargo run
//! -p sfs-bench --release -- --out DIR`). It renders the scenes, runs every
//! method on them (clean, noisy, with pre- and post-processing), and writes
//! `report.md`, `report.json` and the figures. This file holds the
//! arguments, the settings and what the parts share (the scene filter, the
//! RSE-over-time recorder, the peak-memory reset); `run` runs the paper's
//! experiments, `report` writes them, `paper_figures` draws them with
//! `figures`; `robustness`, `lights`, `speed` and the others are the other
//! parts.
#![deny(missing_docs)]

use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;

mod albedo;
mod corpus;
mod corpus_denoise;
mod depth_smoothing;
mod edges;
mod face;
mod figures;
mod holes;
mod lights;
mod like_for_like;
mod markdown;
mod paper_figures;
mod paper_table;
mod ps;
mod real;
mod reflectance;
mod report;
mod robustness;
mod run;
mod scenes;
mod shadows;
mod shared;
mod speed;
mod speed_photo;
use shared::{BenchArgs, Part, SCENE_NAMES};

/// Refuses an `--explicit-seconds` that is not a positive number and a
/// `--scenes` list that is empty or names an unknown scene, and a `--seed`
/// or `--large` for a part that does not use it.
fn check(args: &BenchArgs) -> Result<()> {
    if args.seed.is_some() && args.part != Part::Corpus {
        anyhow::bail!("--seed is used by --part corpus only");
    }
    if args.large && args.part != Part::Speed {
        anyhow::bail!("--large is used by --part speed only");
    }
    if let Some(s) = args.explicit_seconds
        && !(s.is_finite() && s > 0.0)
    {
        anyhow::bail!("--explicit-seconds must be a positive number of seconds (got {s})");
    }
    if let Some(list) = &args.scenes {
        let unknown: Vec<&String> = list
            .iter()
            .filter(|s| !SCENE_NAMES.iter().any(|n| n.eq_ignore_ascii_case(s)))
            .collect();
        if !unknown.is_empty() || list.is_empty() {
            anyhow::bail!(
                "invalid --scenes {}: the scenes are {}",
                list.join(","),
                SCENE_NAMES.join(", ")
            );
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let args = match BenchArgs::try_parse() {
        Ok(args) => args,
        // --help and --version are successes; a usage error exits 1, as
        // every other error (clap renders it with its own prefix).
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs the benchmark and writes the report.
fn run(args: &BenchArgs) -> Result<()> {
    let started = Instant::now();
    check(args)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create output folder {}", args.out.display()))?;
    // Each part writes `<name>.md` (the paper's parts: report.md) beside
    // its JSON.
    let name = match args.part {
        Part::Speed => speed::run(args, args.large).map(|_| "speed"),
        Part::Holes => holes::run(args).map(|_| "holes"),
        Part::Reflectance => reflectance::run(args).map(|()| "reflectance"),
        Part::Ps => ps::run(args).map(|()| "ps"),
        Part::Albedo => albedo::run(args).map(|()| "albedo"),
        Part::Edges => edges::run(args).map(|_| "edges"),
        Part::Corpus => corpus::run(args).map(|()| "corpus"),
        Part::Real => real::run(args).map(|()| "real"),
        Part::Table1 => like_for_like::run_part(args).map(|()| "table1"),
        Part::Shadows => shadows::run(args).map(|_| "shadows"),
        Part::All | Part::Paper | Part::Robustness | Part::Lights => {
            run::run(args, started).map(|()| "report")
        }
    }?;
    let written = args.out.join(format!("{name}.md"));
    eprintln!(
        "wrote {} ({:.0} s)",
        written.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
