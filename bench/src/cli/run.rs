//! `bench run SCENARIO`: run a scenario and record it.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use bench::scenario::LoadError;
use bench::simulate::{SimOptions, SIM_EPOCH_NS};

/// Arguments of `bench run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// Recording to write (default: the scenario's file name with `.mcap`, in the current
    /// directory).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Seed of the simulator's random streams; the same seed gives the same recording.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Run on the embedded simulated bench (virtual time).
pub fn run(args: RunArgs, verbose: u8) -> anyhow::Result<ExitCode> {
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args.scenario.file_stem().map(|s| s.to_os_string()).unwrap_or_default();
        PathBuf::from(stem).with_extension("mcap")
    });
    let plan = match bench::scenario::load(&args.scenario, &bench::simulate::capabilities()) {
        Ok(p) => p,
        Err(LoadError::Invalid(errors)) => {
            for e in errors.iter() {
                eprintln!("{e}");
            }
            eprintln!("{}: {} error(s); nothing was run", args.scenario.display(), errors.len());
            return Ok(ExitCode::from(2));
        }
        Err(e) => return Err(e.into()),
    };
    let opts = SimOptions {
        seed: args.seed,
        epoch_ns: SIM_EPOCH_NS,
        progress: !args.quiet && std::io::stderr().is_terminal(),
    };
    let file = std::fs::File::create(&out)
        .with_context(|| format!("cannot create recording {}", out.display()))?;
    let (report, writer) = bench::simulate::run_plan(
        &plan,
        std::io::BufWriter::new(file),
        &opts,
        Some(super::console_layer(verbose)),
    )?;
    writer
        .into_inner()
        .map_err(|e| e.into_error())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("cannot write recording {}", out.display()))?;
    let peak_rss_mb = peak_rss_mb();
    println!(
        "{}: {} — {} of bench time in {:.2} s wall ({:.0}× real time), {} gyro samples, peak RSS {}",
        out.display(),
        report.outcome,
        bench::progress::hms(report.bench_time.as_secs_f64()),
        report.wall_time.as_secs_f64(),
        report.speed(),
        report.gyro_samples,
        peak_rss_mb.map_or("n/a".to_string(), |m| format!("{m:.1} MB")),
    );
    Ok(if report.outcome == "completed" { ExitCode::SUCCESS } else { ExitCode::from(3) })
}

/// Peak resident set size of this process (Linux `VmHWM`), MB.
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
