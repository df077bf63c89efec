//! The exit codes of every `bench` command: one table, documented in the README.

use std::process::ExitCode;

/// What a `bench` command's exit code says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Exit {
    /// The command did what was asked (a diagnosis found the recording consistent with the
    /// model).
    Success = 0,
    /// An error stopped the command: a file could not be read or written, a device could not
    /// be reached, or something failed inside bench.
    Error = 1,
    /// The command line was wrong (clap's own code).
    Usage = 2,
    /// A scenario, bench config or model file failed validation; every problem was listed and
    /// nothing was run.
    Invalid = 3,
    /// The run was aborted; the recording keeps everything up to the abort and names its cause.
    Aborted = 4,
    /// The calibration is incomplete: a coefficient the run does not determine was held (named,
    /// with the run that would determine it; `calibration.toml` says so in `[held]`), or the
    /// joint fit could not run on these data.
    Incomplete = 5,
    /// A diagnosis found the model's parameters off, but no missing physics.
    ParametersOnly = 6,
    /// A diagnosis found physics the model leaves out.
    MissingPhysics = 7,
    /// A calibration ran but its fit does not fit the data (whitened residual, residual
    /// excursions, bootstrap against bound, or the two domains disagree): its numbers are not
    /// to be trusted; `bench diagnose` looks for what is missing.
    FitPoor = 8,
    /// A sound calibration judged the unit beyond an acceptance limit (`bench.acceptance`):
    /// the unit fails its test.
    AcceptanceFailed = 9,
    /// A soak found a sample that arrived intact and was not recorded, memory growing, or a
    /// fault without its expected outcome.
    SoakFailed = 10,
    /// `bench verify`: the calibration makes the gyro worse on the verification run than no
    /// compensation (the coefficient responsible named).
    CompensationWorse = 11,
    /// `bench verify`: the compensated error is beyond what the calibration states (its σ and
    /// the gyro's noise): the calibration does not hold on this run.
    BeyondStatedSigma = 12,
    /// `bench design`: no procedure within the bench's limits reaches the targets (or fits
    /// the budget); the smallest σ the bench reaches is printed.
    DesignUnreachable = 13,
}

/// A command line that clap accepts but that asks for something impossible (e.g. the same
/// file as input and output): [`Exit::Usage`].
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// An error and its causes as one line, each piece of context once: a cause whose text the
/// line already holds (a device error that quotes its I/O error, a config error that quotes its
/// device error) is not repeated.
pub fn error_text(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if out.contains(&s) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&s);
    }
    out
}

impl From<Exit> for ExitCode {
    fn from(e: Exit) -> Self {
        ExitCode::from(e as u8)
    }
}

impl Exit {
    /// The code of a command that failed with `e`: [`Exit::Usage`] for a [`UsageError`],
    /// [`Exit::Invalid`] for a scenario, bench config or model file that failed validation,
    /// else [`Exit::Error`].
    pub fn of_error(e: &anyhow::Error) -> Exit {
        use bench_recording::model_file::ModelFileError;
        for cause in e.chain() {
            if cause.downcast_ref::<UsageError>().is_some() {
                return Exit::Usage;
            }
            if let Some(c) = cause.downcast_ref::<bench::bench_config::ConfigError>() {
                use bench::bench_config::ConfigError as C;
                if matches!(c, C::Invalid { .. } | C::Several(_)) {
                    return Exit::Invalid;
                }
            }
            if let Some(bench::scenario::LoadError::Invalid(_)) = cause.downcast_ref() {
                return Exit::Invalid;
            }
            if let Some(
                ModelFileError::Parse { .. }
                | ModelFileError::Invalid { .. }
                | ModelFileError::BadEffects { .. },
            ) = cause.downcast_ref()
            {
                return Exit::Invalid;
            }
        }
        Exit::Error
    }
}
