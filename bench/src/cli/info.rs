//! `bench info RECORDING`: what a recording holds.

use std::path::PathBuf;
use std::process::ExitCode;

use super::say::asked;
use anyhow::Context as _;
use bench_recording::{ChannelReport, End, Gap, RecordingInfo};
use serde_json::{json, Value};

/// Arguments of `bench info`.
#[derive(clap::Args, Debug)]
pub struct InfoArgs {
    /// Recording (MCAP).
    pub recording: PathBuf,
    /// Write the report as JSON to this file (`-` for stdout, instead of the text).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// No text report on stdout (with `--json FILE`).
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

fn gaps(g: &[Gap]) -> Value {
    g.iter().map(|g| json!({"from_s": g.from_s, "to_s": g.to_s})).collect()
}

fn channel(c: &ChannelReport) -> Value {
    json!({
        "topic": c.topic,
        "schema_name": c.schema_name,
        "message_encoding": c.message_encoding,
        "count": c.count,
        "first_s": c.first_s,
        "last_s": c.last_s,
        "periodic": c.periodic,
        "mean_rate_hz": c.mean_rate_hz,
        "median_period_s": c.median_period_s,
        "gaps": gaps(&c.gaps),
        "timing_from": if c.device_time.is_some() { "log_time and publish_time" } else { "log_time" },
        "device_time": c.device_time.as_ref().map(|d| json!({
            "mean_rate_hz": d.mean_rate_hz,
            "median_period_s": d.median_period_s,
            "periodic": d.periodic,
            "gaps": gaps(&d.gaps),
        })),
    })
}

/// The damaged parts skipped, times in s from the first message.
fn damage(info: &RecordingInfo) -> Value {
    let t0 = info.start_ns.unwrap_or(0);
    let s = |t: u64| bench_recording::reader::seconds_since(t0, t);
    let parts: Vec<Value> = info
        .damage
        .entries
        .iter()
        .map(|d| {
            json!({
                "at_byte": d.at_byte,
                "bytes": d.bytes,
                "what": d.to_string(),
                "span_s": d.span_ns.map(|(a, b)| [s(a), s(b)]),
                "messages_lost": d.lost,
                "in_summary": d.in_summary,
            })
        })
        .collect();
    json!({
        "damaged": !info.damage.is_empty(),
        "summary": info.damage.summary(),
        "chunks_damaged": info.damage.chunks_damaged(),
        "bytes_skipped": info.damage.bytes_skipped(),
        "bad_messages": info.damage.bad_messages,
        "parts": parts,
        "parts_unlisted": info.damage.unlisted_messages,
    })
}

/// `bench info` as JSON (times in s from the first message, SI).
pub fn to_json(info: &RecordingInfo) -> Value {
    let end = match &info.end {
        End::Complete => json!({"complete": true}),
        End::Cut { at_byte, reason } => {
            json!({"complete": false, "cut_at_byte": at_byte, "reason": reason})
        }
        End::Reading => json!({"complete": false}),
    };
    let metadata: serde_json::Map<String, Value> =
        info.metadata.iter().map(|(n, m)| (n.clone(), json!(m))).collect();
    json!({
        "version": 1,
        "path": info.path.as_ref().map(|p| p.display().to_string()),
        "bytes": info.bytes,
        "start": info.start_ns.map(bench_recording::writer::rfc3339_utc),
        "start_ns": info.start_ns,
        "duration_s": info.duration_s,
        "duration": bench_recording::human_duration(info.duration_s),
        "outcome": info.outcome,
        "end": end,
        "container": info.container.as_ref().map(|c| json!({
            "library": c.library,
            "profile": c.profile,
            "summary": c.summary,
            "chunk_count": c.chunk_count,
            "chunks_by_compression": c.chunks_by_compression,
            "message_count": c.message_count,
            "schema_count": c.schema_count,
            "channel_count": c.channel_count,
            "attachment_count": c.attachment_count,
            "metadata_count": c.metadata_count,
            "message_encodings": c.message_encodings,
            "schema_encodings": c.schema_encodings,
            "message_start_ns": c.message_start_ns,
            "message_end_ns": c.message_end_ns,
        })),
        "chunks": {"read": info.chunks.0, "crc_checked": info.chunks.1},
        "damage": damage(info),
        "channels": info.channels.iter().map(channel).collect::<Vec<_>>(),
        "steps": info.steps.iter().map(|s| json!({
            "index": s.index, "name": s.name, "label": s.label,
            "start_s": s.start_s, "end_s": s.end_s, "abort_s": s.abort_s,
        })).collect::<Vec<_>>(),
        "metadata": metadata,
        "attachments": info.attachments.iter().map(|(n, m, size)| json!({"name": n, "media_type": m, "bytes": size})).collect::<Vec<_>>(),
    })
}

/// Print duration, channels with counts and rates, gaps, steps, metadata and outcome.
pub fn run(args: InfoArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.recording, &[super::kind::Kind::Recording])?;
    super::outputs::Outputs::new(args.force).file(args.json.as_deref())?;
    let info = bench_recording::info(&args.recording)
        .with_context(|| format!("cannot read {}", args.recording.display()))?;
    match &args.json {
        Some(p) if p.as_os_str() == "-" => {
            asked!("{}", serde_json::to_string_pretty(&to_json(&info))?);
            return Ok(ExitCode::SUCCESS);
        }
        Some(p) => super::write_json(p, &to_json(&info))?,
        None => {}
    }
    if !args.quiet {
        super::say::write(&info.to_string());
    }
    Ok(ExitCode::SUCCESS)
}
