//! `bench validate SCENARIO [--bench CONFIG]`: check a scenario against the bench's capabilities
//! (the simulated bench's, a bench config's `[limits]`, or a replayed recording's) without
//! connecting to anything or moving anything.

use std::path::PathBuf;
use std::process::ExitCode;

use super::exit::Exit;

use super::say::say;
use bench::bench_config::{BenchSource, ConfigError};
use bench::scenario::{Capabilities, LoadError};
use serde_json::json;

/// Arguments of `bench validate`.
#[derive(clap::Args, Debug)]
pub struct ValidateArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// Bench config (TOML): check the scenario against the lab's own `[limits]` (each limit
    /// it does not give is the simulated bench's), or against a `[replay]`'s recording. Nothing
    /// is connected.
    #[arg(long, short)]
    pub bench: Option<PathBuf>,
    /// Also write the result as JSON (ok, steps, estimate, every error located).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Print only errors.
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Print every problem of a bench config, located; the exit code.
pub fn config_invalid(e: &ConfigError) -> Option<ExitCode> {
    match e {
        ConfigError::Invalid { .. } | ConfigError::Several(_) => {
            eprintln!("{e}");
            let n = if let ConfigError::Several(v) = e { v.len() } else { 1 };
            eprintln!("{n} error(s) in the bench config; nothing was run");
            Some(Exit::Invalid.into())
        }
        _ => None,
    }
}

/// The capabilities to validate against, and what they are, for the message.
fn capabilities(args: &ValidateArgs) -> anyhow::Result<Result<(Capabilities, String), ExitCode>> {
    let Some(spec) = &args.bench else {
        return Ok(Ok((bench::simulate::capabilities(), "the simulated bench".into())));
    };
    match BenchSource::load(spec) {
        Ok(BenchSource::Devices(config)) => {
            let (caps, given) = config.limits();
            let what = if given {
                format!("{}'s [limits] (the simulated bench's where it gives none)", spec.display())
            } else if config.is_simulated() {
                format!("the simulated bench of {}", spec.display())
            } else {
                format!(
                    "the simulated bench's capabilities: {} has no [limits], and its devices \
                     report theirs only when `bench run` connects",
                    spec.display()
                )
            };
            Ok(Ok((caps, what)))
        }
        Ok(BenchSource::Replay(replay)) => {
            let data = bench::replay::ReplayData::load(&replay.replay.recording)?;
            Ok(Ok((
                data.capabilities(),
                format!("the replay of {}", replay.replay.recording.display()),
            )))
        }
        Err(e) => match config_invalid(&e) {
            Some(code) => Ok(Err(code)),
            None => Err(e.into()),
        },
    }
}

/// Validate; print every problem as `file:line:column: message`. Exit 3 if invalid.
pub fn run(args: ValidateArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.scenario, &[super::kind::Kind::Scenario])?;
    if let Some(b) = &args.bench {
        super::kind::expect(b, &[super::kind::Kind::BenchConfig])?;
    }
    super::outputs::Outputs::new(args.force).file(args.json.as_deref())?;
    let (caps, against) = match capabilities(&args)? {
        Ok(c) => c,
        Err(code) => return Ok(code),
    };
    match bench::scenario::load(&args.scenario, &caps) {
        Ok(plan) => {
            let records = plan
                .steps
                .iter()
                .filter(|s| bench_recording::message::is_record_label(&s.label))
                .count();
            let estimate = plan.estimate();
            if !args.quiet {
                say!(
                    "{}: ok against {against} — {} steps ({} record windows), about {} of bench \
                     time, gyro at {} Hz",
                    args.scenario.display(),
                    plan.steps.len(),
                    records,
                    bench::progress::hms(estimate.total.as_secs_f64()),
                    plan.gyro.sample_rate_hz
                );
            }
            if let Some(i) = estimate.timeout_step {
                let s = &plan.steps[i];
                eprintln!(
                    "warning: {}: step {} ({}) would time out on the simulated bench's physics \
                     (chamber lag, the gyro's thermal lag): the run would abort there",
                    s.origin, s.index, s.label
                );
            }
            if let Some(path) = &args.json {
                super::write_json(
                    path,
                    &json!({
                        "scenario": args.scenario.display().to_string(),
                        "ok": true,
                        "against": against,
                        "steps": plan.steps.len(),
                        "record_windows": records,
                        "estimated_bench_time_s": estimate.total.as_secs_f64(),
                        "estimated_timeout_step": estimate.timeout_step,
                        "errors": [],
                    }),
                )?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(LoadError::Invalid(errors)) => {
            for e in errors.iter() {
                eprintln!("{e}");
            }
            eprintln!("{}: {} error(s) against {against}", args.scenario.display(), errors.len());
            if let Some(path) = &args.json {
                let list: Vec<_> = errors
                    .iter()
                    .map(|e| json!({"file": e.file, "line": e.line, "column": e.column, "message": e.message}))
                    .collect();
                super::write_json(
                    path,
                    &json!({"scenario": args.scenario.display().to_string(), "ok": false, "against": against, "errors": list}),
                )?;
            }
            Ok(Exit::Invalid.into())
        }
        Err(e) => Err(e.into()),
    }
}
