//! `bench diagnose`: where a recording departs from the simulation of the same run, which
//! physics the model left out, and the model with it put in.
//!
//! [`crate::load`] turns a recording (any writer's, per the contract) into the whole run's
//! arrays ([`bench_analysis::run::RunSeries`]) and its nominal model (`bench.gyro_model`, its
//! `effect.*` keys included); [`diagnose_recording`] runs
//! [`bench_analysis::diagnose::diagnose`], then **re-simulates** the run with the updated model
//! (the same physics, [`bench_physics::effects`], driven by the recording's inputs) to show
//! the fit it gives; [`json`] writes the machine-readable result (`docs/diagnose.md`);
//! [`located`] lays out where the mismatch sits, step by step, for the console and the figures;
//! [`report`] the HTML/SVG/PNG report.

pub mod json;
pub mod located;
pub mod report;

use std::path::Path;

use bench_analysis::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use bench_analysis::AnalysisError;
use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use bench_recording::{Recording, RecordingError};

use crate::load::{LoadError, RunData};

/// Why a recording cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The recording could not be read.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The recording's arrays could not be read.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// No nominal model: neither `--model` nor `bench.gyro_model`.
    #[error(
        "no nominal model: the recording has no bench.gyro_model metadata; give one with \
         --model MODEL.toml"
    )]
    NoModel,
    /// The analysis rejected the data.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
}

/// A diagnosis with its inputs and the re-simulation under the updated model.
#[derive(Debug, Clone)]
pub struct DiagnoseOutcome {
    /// What was read.
    pub data: RunData,
    /// The nominal model used, and where it came from (`--model` path or `bench.gyro_model`).
    pub nominal: (GyroModel, Effects, String),
    /// The settings it ran with.
    pub options: DiagnoseOptions,
    /// The diagnosis.
    pub diagnosis: Diagnosis,
    /// The same run diagnosed against the updated model (the re-simulation): its residual
    /// RMS and verdict show whether the updated model file reproduces the recording.
    pub resimulated: Option<Diagnosis>,
}

/// Diagnose `rec` against `nominal` (model, effects, source name) or else the recording's own
/// `bench.gyro_model`. A nominal model from elsewhere brings its gyro's effects only: the
/// table's motion and the clocks are the recording's own ([`Effects::on_the_bench_of`]; none
/// where it states none), never another bench's.
pub fn diagnose_recording(
    rec: &Recording,
    nominal: Option<(GyroModel, Effects, String)>,
    opts: &DiagnoseOptions,
) -> Result<DiagnoseOutcome, DiagnoseError> {
    diagnose_run(crate::load::load(rec)?, nominal, opts)
}

/// [`diagnose_recording`] on a recording's arrays ([`crate::load::load`]); the [`Recording`]
/// they came from need not be held meanwhile (its decoded messages are the larger part of the
/// memory).
pub fn diagnose_run(
    data: RunData,
    nominal: Option<(GyroModel, Effects, String)>,
    opts: &DiagnoseOptions,
) -> Result<DiagnoseOutcome, DiagnoseError> {
    let nominal = match nominal {
        Some((model, effects, source)) => {
            let own = data.model.as_ref().map(|m| m.effects).unwrap_or_default();
            (model, effects.on_the_bench_of(&own), source)
        }
        None => {
            let m = data.model.clone().ok_or(DiagnoseError::NoModel)?;
            (m.model, m.effects, "bench.gyro_model".into())
        }
    };
    let diagnosis = diagnose(&data.series, &nominal.0, &nominal.1, opts)?;
    // The re-simulation needs the residual and the verdict on parameters, not a new search.
    let resim_opts = DiagnoseOptions { max_effects: 0, ..opts.clone() };
    let resimulated =
        diagnose(&data.series, &diagnosis.model, &diagnosis.effects, &resim_opts).ok();
    Ok(DiagnoseOutcome { data, nominal, options: opts.clone(), diagnosis, resimulated })
}

/// [`diagnose_recording`] on a file.
pub fn diagnose_file(
    path: &Path,
    nominal: Option<(GyroModel, Effects, String)>,
    opts: &DiagnoseOptions,
) -> Result<DiagnoseOutcome, DiagnoseError> {
    let rec = Recording::load(path)?;
    diagnose_recording(&rec, nominal, opts)
}

/// The caveats a diagnosis's verdict carries: every effect not in the updated model that is
/// nearly collinear with a term that is (or a set of them, `a + b`), with the largest size the
/// data cannot rule out (in display units; "of any size" where the model's terms span it). They matter most for `consistent` and `parameters_only`: a term in the model
/// may hold an effect that this recording cannot show.
pub fn verdict_caveats(d: &bench_analysis::diagnose::Diagnosis) -> Vec<String> {
    d.identifiability()
        .iter()
        .filter(|c| !c.effect_accepted)
        .map(|c| {
            let size = if c.bound.is_finite() {
                format!(
                    "up to {}",
                    crate::display::si_value(crate::display::for_si(c.unit), c.bound, 2)
                )
            } else {
                "of any size (the model's terms span it)".to_string()
            };
            format!(
                "{} cannot be told apart from {} on this recording (ρ = {:.3}): a {} {} {size} \
                 is not ruled out (95 %)",
                c.effect.key(),
                c.with_name(),
                c.rho,
                c.effect.key(),
                crate::display::parameter_name(c.parameter),
            )
        })
        .collect()
}
