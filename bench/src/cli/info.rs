//! `bench info RECORDING`: what a recording holds.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;

/// Arguments of `bench info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// Recording (MCAP).
    pub recording: PathBuf,
}

/// Print duration, channels with counts and rates, gaps, steps, metadata and outcome.
pub fn run(args: InfoArgs) -> anyhow::Result<ExitCode> {
    let info = bench_recording::info(&args.recording)
        .with_context(|| format!("cannot read {}", args.recording.display()))?;
    print!("{info}");
    Ok(ExitCode::SUCCESS)
}
