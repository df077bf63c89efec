//! `bench memory RECORDING`: the memory benchmark of the analyses. Reads a recording as a
//! stream (the gyro's samples reduced as they pass), builds its arrays and runs calibrate and
//! diagnose on them in one process, as `bench calibrate` and `bench diagnose` do, and reports each phase's wall time, its peak resident memory and the
//! peak per gyro sample (issue 29: the analyses' memory must not grow with the sample rate).
//!
//! The peak of each phase is the process's high-water mark (`VmHWM`) reset before the phase
//! (`/proc/self/clear_refs`, Linux); where it cannot be reset the figures are the peak so far,
//! and the report says so.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use super::say::say;
use anyhow::Context as _;
use bench_analysis::diagnose::DiagnoseOptions;
use bench_report::calibrate::{calibrate_run, CalibrateSettings};
use bench_report::diagnose::diagnose_run;
use serde_json::json;

/// Arguments of `bench memory`.
#[derive(clap::Args, Debug)]
pub struct MemoryArgs {
    /// Recording (MCAP).
    pub recording: PathBuf,
    /// Skip the calibration.
    #[arg(long)]
    pub no_calibrate: bool,
    /// Skip the diagnosis.
    #[arg(long)]
    pub no_diagnose: bool,
    /// Block-bootstrap replicates of the calibration (default as `bench calibrate`).
    #[arg(long)]
    pub replicates: Option<usize>,
    /// Also write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// One phase's figures.
struct Phase {
    name: &'static str,
    wall_s: f64,
    peak_mib: Option<f64>,
    rss_after_mib: Option<f64>,
}

/// Reset the process's peak RSS to its current RSS (`echo 5 > /proc/self/clear_refs`);
/// whether it was reset.
fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Run `f` as the phase `name`, measuring it.
fn phase<T>(phases: &mut Vec<Phase>, name: &'static str, f: impl FnOnce() -> T) -> T {
    reset_peak();
    let t = Instant::now();
    let out = f();
    let wall_s = t.elapsed().as_secs_f64();
    let mem = bench::process::memory_mib();
    phases.push(Phase {
        name,
        wall_s,
        peak_mib: mem.map(|m| m.1),
        rss_after_mib: mem.map(|m| m.0),
    });
    out
}

/// Measure and print.
pub fn run(args: MemoryArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(false);
    let resettable = reset_peak();
    let file_bytes = std::fs::metadata(&args.recording)
        .with_context(|| format!("cannot read {}", args.recording.display()))?
        .len();
    let mut phases = Vec::new();
    let started = Instant::now();
    let mut counts = (0, 0, 1);
    // Each analysis from the file, as its own command runs: read, arrays, messages freed.
    let analyses = [("calibrate", !args.no_calibrate), ("diagnose", !args.no_diagnose)];
    for (analysis, _) in analyses.into_iter().filter(|a| a.1) {
        let streamed = phase(&mut phases, "read and reduce", || {
            super::read_recording_stream(&args.recording, args.quiet)
        })?;
        let context = super::analysis_context(&streamed.rec, analysis, &args.recording);
        let messages = streamed.gyro.messages();
        let run = phase(&mut phases, "load", || bench_report::load::load_streamed(streamed))
            .with_context(|| context.clone())?;
        counts = (messages, run.series.gyro_time_s.len(), run.gyro_block_len);
        if analysis == "calibrate" {
            let settings = CalibrateSettings { replicates: args.replicates, ..Default::default() };
            phase(&mut phases, "calibrate", || calibrate_run(run, &settings))
                .with_context(|| context.clone())?;
        } else {
            let threads = super::diagnose::threads_from_env();
            let opts = DiagnoseOptions { threads, ..Default::default() };
            phase(&mut phases, "diagnose", || diagnose_run(run, None, &opts))
                .with_context(|| context.clone())?;
        }
    }
    let (gyro_messages, samples, block_len) = counts;
    let total_s = started.elapsed().as_secs_f64();

    let per_sample =
        |mib: Option<f64>| mib.map(|m| m * 1024.0 * 1024.0 / gyro_messages.max(1) as f64);
    let fmt = |v: Option<f64>, d: usize| v.map_or("n/a".to_owned(), |v| format!("{v:.d$}"));
    say!(
        "{}: {} bytes, {gyro_messages} gyro messages ({samples} rows of usable samples, in \
         blocks of {block_len})",
        args.recording.display(),
        file_bytes
    );
    if !resettable {
        say!("(the peak could not be reset between phases: each peak is the process's so far)");
    }
    say!("| phase | wall s | peak RSS MiB | B per gyro message | RSS after MiB |");
    say!("| --- | --- | --- | --- | --- |");
    for p in &phases {
        say!(
            "| {} | {:.2} | {} | {} | {} |",
            p.name,
            p.wall_s,
            fmt(p.peak_mib, 1),
            fmt(per_sample(p.peak_mib), 0),
            fmt(p.rss_after_mib, 1)
        );
    }
    say!("total {total_s:.2} s");
    if let Some(path) = &args.json {
        let value = json!({
            "recording": args.recording.display().to_string(),
            "file_bytes": file_bytes,
            "gyro_messages": gyro_messages,
            "usable_samples": samples,
            "gyro_block_len": block_len,
            "peak_reset_per_phase": resettable,
            "total_s": total_s,
            "phases": phases.iter().map(|p| json!({
                "phase": p.name,
                "wall_s": p.wall_s,
                "peak_rss_mib": p.peak_mib,
                "peak_bytes_per_gyro_message": per_sample(p.peak_mib),
                "rss_after_mib": p.rss_after_mib,
            })).collect::<Vec<_>>(),
        });
        super::write_json(path, &value)?;
    }
    Ok(ExitCode::SUCCESS)
}
