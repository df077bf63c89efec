//! `bench recover IN OUT`: rebuild a readable, indexed MCAP file from a truncated one.

use std::path::PathBuf;
use std::process::ExitCode;

use super::say::say;
use anyhow::Context as _;

/// Arguments of `bench recover`.
#[derive(clap::Args, Debug)]
pub struct RecoverArgs {
    /// The damaged recording.
    pub input: PathBuf,
    /// The new file; an existing one is refused unless `--force`.
    pub output: PathBuf,
    /// Overwrite an existing output file.
    #[arg(long)]
    pub force: bool,
    /// Also write what was kept and where the input broke as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// No text on stdout.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Copy every complete record into a fresh indexed file; say how much was kept and where the
/// input broke.
pub fn run(args: RecoverArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.input, &[super::kind::Kind::Recording])?;
    if args.output.exists() && args.input.canonicalize().ok() == args.output.canonicalize().ok() {
        let e = super::exit::UsageError(format!(
            "{} is both the input and the output: recover into a new file",
            args.input.display()
        ));
        return Err(e.into());
    }
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(Some(&args.output))?;
    outputs.file(args.json.as_deref())?;
    let report = bench_recording::recover::recover_file(&args.input, &args.output)
        .with_context(|| format!("cannot recover {}", args.input.display()))?;
    if !args.quiet {
        super::say::write(&report.to_string());
        say!("written to {}", args.output.display());
    }
    if let Some(path) = &args.json {
        let j = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "input_bytes": report.input_bytes,
            "complete": report.complete,
            "messages": report.messages,
            "total_messages": report.total_messages(),
            "schemas": report.schemas,
            "channels": report.channels,
            "metadata": report.metadata,
            "attachments": report.attachments,
            "orphans": report.orphans,
            "break": report.break_at.as_ref().map(|b| serde_json::json!({
                "at_byte": b.at_byte,
                "after_record": b.after_record,
                "reason": b.reason,
            })),
        });
        std::fs::write(path, serde_json::to_string_pretty(&j)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
