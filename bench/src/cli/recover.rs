//! `bench recover IN OUT`: rebuild a readable, indexed MCAP file from a truncated one.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;

/// Arguments of `bench recover`.
#[derive(clap::Args, Debug)]
pub struct RecoverArgs {
    /// The damaged recording.
    pub input: PathBuf,
    /// The new file (overwritten).
    pub output: PathBuf,
}

/// Copy every complete record into a fresh indexed file; say how much was kept and where the
/// input broke.
pub fn run(args: RecoverArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.input.canonicalize().ok() != args.output.canonicalize().ok() || !args.output.exists(),
        "the output must be a new file, not the input"
    );
    let report = bench_recording::recover::recover_file(&args.input, &args.output)
        .with_context(|| format!("cannot recover {}", args.input.display()))?;
    print!("{report}");
    println!("written to {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
