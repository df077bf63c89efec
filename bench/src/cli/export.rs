//! `bench export REC.mcap --format csv|parquet [--out DIR] [--merged]`: one table per channel,
//! and with `--merged` the gyro samples with the table and chamber readings as of each.

use std::path::PathBuf;
use std::process::ExitCode;

use super::say::{asked, say};
use anyhow::Context as _;
use bench_recording::export::Format;

/// Table format.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum FormatArg {
    /// Comma-separated text.
    Csv,
    /// Apache Parquet.
    Parquet,
}

/// Arguments of `bench export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// The recording.
    pub recording: PathBuf,
    /// Table format.
    #[arg(long, value_enum, default_value = "csv")]
    pub format: FormatArg,
    /// Output directory (default: the recording's name without `.mcap`, beside it).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Also write `merged.csv|parquet`: one row per gyro sample with the latest table and
    /// chamber readings at or before it (as-of join) and its record window's label.
    #[arg(long)]
    pub merged: bool,
    /// Also write what was exported as JSON here (`-` for stdout): each table's topic, rows
    /// and path, the topics skipped, and where the recording is cut.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Print nothing (errors aside).
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Export and list the tables written.
pub fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.recording, &[super::kind::Kind::Recording])?;
    let out = args.out.clone().unwrap_or_else(|| args.recording.with_extension(""));
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.dir(&out)?;
    outputs.file(args.json.as_deref())?;
    outputs.prepare()?;
    let format = match args.format {
        FormatArg::Csv => Format::Csv,
        FormatArg::Parquet => Format::Parquet,
    };
    let report =
        bench_recording::export::export_file_with(&args.recording, &out, format, args.merged)
            .with_context(|| format!("cannot export {}", args.recording.display()))?;
    if args.json.as_deref() != Some(std::path::Path::new("-")) {
        for t in &report.tables {
            say!("{:<16} {:>9} rows  {}", t.topic, t.rows, t.path.display());
        }
        for (topic, enc) in &report.skipped {
            say!("{topic:<16} skipped: message encoding `{enc}` is not json");
        }
        if let Some((at, reason)) = &report.cut {
            say!("the recording is cut at byte {at} ({reason}): exported up to there");
        }
    }
    if let Some(path) = &args.json {
        let v = serde_json::json!({
            "recording": args.recording.display().to_string(),
            "format": match format { Format::Csv => "csv", Format::Parquet => "parquet" },
            "tables": report.tables.iter().map(|t| serde_json::json!({
                "topic": t.topic, "rows": t.rows, "path": t.path.display().to_string()})).collect::<Vec<_>>(),
            "skipped": report.skipped.iter().map(|(topic, enc)| serde_json::json!({
                "topic": topic, "message_encoding": enc})).collect::<Vec<_>>(),
            "cut": report.cut.as_ref().map(|(at, reason)| serde_json::json!({
                "at_byte": at, "reason": reason.to_string()})),
        });
        let text = serde_json::to_string_pretty(&v)?;
        if path.as_os_str() == "-" {
            asked!("{text}");
        } else {
            std::fs::write(path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    Ok(ExitCode::SUCCESS)
}
