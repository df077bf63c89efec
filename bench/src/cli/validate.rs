//! `bench validate SCENARIO`: check a scenario against the bench's capabilities.

use std::path::PathBuf;
use std::process::ExitCode;

use super::exit::Exit;

use bench::scenario::LoadError;

/// Arguments of `bench validate`.
#[derive(clap::Args, Debug)]
pub struct ValidateArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
}

/// Validate; print every problem as `file:line:column: message`. Exit 2 if invalid.
pub fn run(args: ValidateArgs) -> anyhow::Result<ExitCode> {
    let caps = bench::simulate::capabilities();
    match bench::scenario::load(&args.scenario, &caps) {
        Ok(plan) => {
            let records = plan.steps.iter().filter(|s| s.label.starts_with("record")).count();
            println!(
                "{}: ok — {} steps ({} record windows), about {} of bench time, gyro at {} Hz",
                args.scenario.display(),
                plan.steps.len(),
                records,
                bench::progress::hms(plan.estimated_duration().as_secs_f64()),
                plan.gyro.sample_rate_hz
            );
            Ok(ExitCode::SUCCESS)
        }
        Err(LoadError::Invalid(errors)) => {
            for e in errors.iter() {
                eprintln!("{e}");
            }
            eprintln!("{}: {} error(s)", args.scenario.display(), errors.len());
            Ok(Exit::Invalid.into())
        }
        Err(e) => Err(e.into()),
    }
}
