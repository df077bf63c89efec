//! `bench soak`: hours of bench time through the virtual ports with faults injected at random;
//! samples sent vs recorded per channel, memory over time, every fault's outcome
//! ([`bench::soak`]).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use bench::soak::{FaultOutcome, SoakOptions, SoakReport};
use bench_report::display;

use super::exit::Exit;
use super::say::{asked, say};

/// Arguments of `bench soak`.
#[derive(clap::Args, Debug)]
pub struct SoakArgs {
    /// Bench time to cover, hours.
    #[arg(long, default_value_t = 24.0)]
    pub hours: f64,
    /// Bench time per wall time of the served simulators and the drivers.
    #[arg(long, default_value_t = bench::soak::DEFAULT_TIME_SCALE, value_name = "FACTOR")]
    pub time_scale: f64,
    /// Seed of the fault schedule and of the simulators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run this scenario segment after segment (default: a built-in 1 h thermal segment, the
    /// chamber ramping at 1 °C/min to 40 °C and 0 °C in turn while the table turns both ways).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Mean number of faults injected per bench hour (at least one per segment).
    #[arg(long, default_value_t = 3.0)]
    pub faults_per_hour: f64,
    /// Draw faults only of these kinds (comma-separated; default: every kind).
    #[arg(long, value_delimiter = ',', value_name = "KIND")]
    pub faults: Vec<bench::soak::SoakFaultKind>,
    /// Sample the memory every this many minutes of bench time.
    #[arg(long, default_value_t = 10.0, value_name = "MINUTES")]
    pub memory_every_min: f64,
    /// Keep each segment's recording in this directory (default: deleted once read back).
    #[arg(long, value_name = "DIR")]
    pub keep: Option<PathBuf>,
    /// Write everything as JSON here (`-` for stdout, then alone on it).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// No line per segment.
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Run `bench soak`.
pub fn run(args: SoakArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.json.as_deref())?;
    if let Some(dir) = &args.keep {
        outputs.dir(dir)?;
    }
    outputs.prepare()?;
    anyhow::ensure!(
        args.hours.is_finite() && args.hours > 0.0 && args.hours <= 24.0 * 365.0,
        "--hours must be a positive number of hours, got {}",
        args.hours
    );
    anyhow::ensure!(
        args.time_scale.is_finite() && args.time_scale > 0.0,
        "--time-scale must be a positive number, got {}",
        args.time_scale
    );
    anyhow::ensure!(
        args.memory_every_min.is_finite() && args.memory_every_min > 0.0,
        "--memory-every-min must be a positive number of minutes, got {}",
        args.memory_every_min
    );
    anyhow::ensure!(
        args.faults_per_hour.is_finite() && args.faults_per_hour >= 0.0,
        "--faults-per-hour must be a number ≥ 0, got {}",
        args.faults_per_hour
    );
    let scenario = match &args.scenario {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            // Validate up front with located errors, as `bench run` does.
            if let Err(e) = bench::scenario::parse(
                &text,
                &path.display().to_string(),
                &bench::simulate::capabilities(),
            ) {
                eprintln!("{e}");
                return Ok(Exit::Invalid.into());
            }
            Some((path.display().to_string(), text))
        }
        None => None,
    };
    let opts = SoakOptions {
        bench_time: Duration::from_secs_f64(args.hours * 3600.0),
        time_scale: args.time_scale,
        seed: args.seed,
        scenario,
        faults_per_hour: args.faults_per_hour,
        kinds: args.faults.clone(),
        memory_every: Duration::from_secs_f64(args.memory_every_min * 60.0),
        keep: args.keep.clone(),
        ..SoakOptions::default()
    };
    let to_stdout = args.json.as_deref() == Some(std::path::Path::new("-"));
    let say = !args.quiet && !to_stdout;
    let rt = super::run::runtime()?;
    let report = rt.block_on(bench::soak::soak(&opts, |seg, faults| {
        if say {
            let kinds: Vec<String> = faults
                .iter()
                .map(|f| format!("{:?} at {:.0} s: {:?}", f.kind, f.at_s, f.outcome))
                .collect();
            eprintln!(
                "segment {}: {:.2} h of bench time in {:.1} s — {}; faults: {}",
                seg.index,
                display::HOURS.of(seg.bench_time_s),
                seg.wall_time_s,
                seg.outcome,
                if kinds.is_empty() { "none".to_string() } else { kinds.join(", ") }
            );
        }
    }))?;
    if !to_stdout {
        print_summary(&report);
    }
    if let Some(path) = &args.json {
        if to_stdout {
            asked!("{}", serde_json::to_string_pretty(&report)?);
        } else {
            super::write_json(path, &report)?;
        }
    }
    Ok(if report.passed { Exit::Success } else { Exit::SoakFailed }.into())
}

fn print_summary(r: &SoakReport) {
    say!(
        "soak (seed {}): {:.2} h of bench time in {:.0} s wall ({:.0}× real time; asked {}×), {} \
         segment(s) of \"{}\"",
        r.seed,
        display::HOURS.of(r.bench_time_s),
        r.wall_time_s,
        r.achieved_time_scale,
        r.time_scale,
        r.segments.len(),
        r.scenario
    );
    say!(
        "  {:<16} {:>10} {:>10} {:>8} {:>8} {:>9} {:>8} {:>5} {:>6}",
        "channel",
        "sent",
        "recorded",
        "dropped",
        "silenced",
        "corrupted",
        "outside",
        "late",
        "lost"
    );
    for c in &r.channels {
        let sent = c.sent.map_or("-".to_string(), |s| s.to_string());
        say!(
            "  {:<16} {:>10} {:>10} {:>8} {:>8} {:>9} {:>8} {:>5} {:>6}",
            c.topic,
            sent,
            c.recorded,
            c.dropped,
            c.silenced,
            c.corrupted,
            c.outside_run,
            c.late,
            c.lost
        );
    }
    let count = |o: FaultOutcome| r.faults.iter().filter(|f| f.outcome == o).count();
    say!(
        "  faults: {} injected — {} recovered, {} aborted by design, {} overtaken by another's \
         abort, {} unexpected",
        r.faults.len(),
        count(FaultOutcome::Recovered),
        count(FaultOutcome::AbortedByDesign),
        count(FaultOutcome::Overtaken),
        count(FaultOutcome::Unexpected)
    );
    let m = &r.memory;
    let bounds = m
        .slope_bounds_mib_per_h
        .map_or(String::new(), |(lo, hi)| format!(" [{lo:+.2}, {hi:+.2}] at 95 %"));
    say!(
        "  memory: RSS {:.1} → {:.1} MiB, peak {:.1} MiB, slope over {:.2}–{:.2} h {}{bounds} \
         (limit {} MiB/h): {}",
        m.start_mib,
        m.end_mib,
        m.peak_mib,
        m.judged_from_h,
        m.judged_to_h,
        m.slope_mib_per_h.map_or("n/a".to_string(), |s| format!("{s:+.3} MiB/h")),
        m.limit_mib_per_h,
        m.verdict
    );
    if !m.note.is_empty() {
        say!("    ({})", m.note);
    }
    if r.passed {
        say!("  passed");
    } else {
        for p in &r.problems {
            say!("  FAILED: {p}");
        }
    }
}
