//! `bench diagnose`: where a recording departs from the simulation of the same run, which
//! physics the model left out, and the model with it put in.
//!
//! [`load`] turns a recording (any writer's, per the contract) into the whole run's arrays
//! ([`bench_analysis::diagnose::series::RunSeries`]) and its nominal model (`bench.gyro_model`,
//! its `effect.*` keys included); [`diagnose_recording`] runs
//! [`bench_analysis::diagnose::diagnose`], then **re-simulates** the run with the updated model
//! (the same physics, [`bench_physics::effects`], driven by the recording's inputs) to show
//! the fit it gives; [`json`] writes the machine-readable result (`docs/diagnose.md`);
//! [`report`] the HTML/SVG/PNG report.

pub mod json;
pub mod monte_carlo;
pub mod report;

use std::collections::BTreeMap;
use std::path::Path;

use bench_analysis::diagnose::series::{RunSeries, StepSpan};
use bench_analysis::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use bench_analysis::AnalysisError;
use bench_physics::effects::Effects;
use bench_physics::GyroModel;

use crate::calibrate::load::{site, strictly_increasing};
use crate::record::schema::{META_GYRO_MODEL, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_TABLE};
use crate::record::StepEvent;
use crate::recording::{Recording, RecordingError};

/// Why a recording cannot be diagnosed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The recording could not be read.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// A required channel is missing or nearly empty.
    #[error("{topic}: {messages} usable message(s); diagnosis needs this channel")]
    MissingChannel {
        /// Channel.
        topic: &'static str,
        /// Usable messages.
        messages: usize,
    },
    /// Site metadata not as the contract says.
    #[error(transparent)]
    Site(#[from] crate::calibrate::CalibrateError),
    /// No nominal model: neither `--model` nor `bench.gyro_model`.
    #[error(
        "no nominal model: the recording has no bench.gyro_model metadata; give one with \
         --model MODEL.toml"
    )]
    NoModel,
    /// `bench.gyro_model` has a bad value.
    #[error("metadata bench.gyro_model: {0}")]
    BadModel(String),
    /// The analysis rejected the data.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
}

/// What [`load`] reads from a recording.
#[derive(Debug, Clone)]
pub struct DiagnoseData {
    /// The run's arrays, times in s from the first message.
    pub run: RunSeries,
    /// `bench.gyro_model` and its effects, if the recording has one.
    pub model: Option<(GyroModel, Effects)>,
    /// Keys of `bench.gyro_model` that neither the model nor the effects know.
    pub unknown_keys: BTreeMap<String, String>,
    /// Time origin: the first message's `log_time`, ns since the Unix epoch.
    pub origin_ns: u64,
    /// Gyro samples left out for a non-zero status or a non-finite rate.
    pub bad_gyro_samples: usize,
}

fn secs(ns: u64, origin: u64) -> f64 {
    (ns as f64 - origin as f64) * 1e-9
}

/// Read the run's arrays from `rec`.
pub fn load(rec: &Recording) -> Result<DiagnoseData, DiagnoseError> {
    for (topic, n) in [
        (TOPIC_GYRO, rec.gyro.len()),
        (TOPIC_TABLE, rec.table.len()),
        (TOPIC_CHAMBER, rec.chamber.len()),
    ] {
        if n < 2 {
            return Err(DiagnoseError::MissingChannel { topic, messages: n });
        }
    }
    let origin_ns = [
        rec.gyro.first().map(|m| m.log_time_ns),
        rec.table.first().map(|m| m.log_time_ns),
        rec.chamber.first().map(|m| m.log_time_ns),
        rec.steps.iter().map(|m| m.log_time_ns).min(),
    ]
    .into_iter()
    .flatten()
    .min()
    .unwrap_or(0);
    let (latitude_deg, axis_up) = site(rec)?;

    let mut gyro_time_s = Vec::with_capacity(rec.gyro.len());
    let mut gyro_rate = Vec::with_capacity(rec.gyro.len());
    let mut gyro_temp = Vec::with_capacity(rec.gyro.len());
    let mut bad = 0;
    for g in &rec.gyro {
        if g.msg.status != 0 || !g.msg.rate_rad_s.is_finite() {
            bad += 1;
            continue;
        }
        gyro_time_s.push(secs(g.log_time_ns, origin_ns));
        gyro_rate.push(g.msg.rate_rad_s);
        gyro_temp.push(g.msg.temperature_c.filter(|t| t.is_finite()).unwrap_or(f64::NAN));
    }
    strictly_increasing(&mut gyro_time_s, &mut [&mut gyro_rate, &mut gyro_temp]);
    // The gyro's sensor where it reads on most samples (gaps filled linearly).
    let readings = gyro_temp.iter().filter(|t| t.is_finite()).count();
    let gyro_temp_c = (readings >= 2 && readings * 2 > gyro_temp.len()).then(|| {
        let (ts, vs): (Vec<f64>, Vec<f64>) = gyro_time_s
            .iter()
            .zip(&gyro_temp)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| (*t, *v))
            .unzip();
        gyro_time_s
            .iter()
            .zip(&gyro_temp)
            .map(|(t, v)| {
                if v.is_finite() {
                    *v
                } else {
                    bench_analysis::diagnose::series::interp(&ts, &vs, *t)
                }
            })
            .collect()
    });

    let mut table_time_s = Vec::with_capacity(rec.table.len());
    let mut angle = Vec::with_capacity(rec.table.len());
    let mut command = Vec::with_capacity(rec.table.len());
    for t in &rec.table {
        if t.msg.angle_rad.is_finite() && t.msg.rate_command_rad_s.is_finite() {
            table_time_s.push(secs(t.log_time_ns, origin_ns));
            angle.push(t.msg.angle_rad);
            command.push(t.msg.rate_command_rad_s);
        }
    }
    strictly_increasing(&mut table_time_s, &mut [&mut angle, &mut command]);
    let mut chamber_time_s = Vec::with_capacity(rec.chamber.len());
    let mut air = Vec::with_capacity(rec.chamber.len());
    for c in rec.chamber.iter().filter(|c| c.msg.temperature_c.is_finite()) {
        chamber_time_s.push(secs(c.log_time_ns, origin_ns));
        air.push(c.msg.temperature_c);
    }
    strictly_increasing(&mut chamber_time_s, &mut [&mut air]);
    for (topic, n) in [
        (TOPIC_GYRO, gyro_time_s.len()),
        (TOPIC_TABLE, table_time_s.len()),
        (TOPIC_CHAMBER, chamber_time_s.len()),
    ] {
        if n < 2 {
            return Err(DiagnoseError::MissingChannel { topic, messages: n });
        }
    }

    // Steps: each start paired with the same step's end or abort.
    let mut events = rec.steps.clone();
    events.sort_by_key(|s| s.log_time_ns);
    let last_s = gyro_time_s.last().copied().unwrap_or(0.0);
    let mut steps = Vec::new();
    for (i, s) in events.iter().enumerate() {
        if s.msg.event != StepEvent::Start {
            continue;
        }
        let end = events[i + 1..]
            .iter()
            .find(|e| e.msg.index == s.msg.index && e.msg.event != StepEvent::Start)
            .map_or(last_s, |e| secs(e.log_time_ns, origin_ns));
        steps.push(StepSpan {
            index: s.msg.index,
            name: s.msg.name.clone(),
            label: s.msg.label.clone(),
            start_s: secs(s.log_time_ns, origin_ns),
            end_s: end,
        });
    }

    let (model, unknown_keys) = match rec.metadata(META_GYRO_MODEL) {
        None => (None, BTreeMap::new()),
        Some(meta) => {
            let (m, unknown) = GyroModel::from_metadata(meta)
                .map_err(|e| DiagnoseError::BadModel(e.to_string()))?;
            let effects = Effects::from_metadata(meta).map_err(DiagnoseError::BadModel)?;
            let unknown = unknown.into_iter().filter(|(k, _)| !k.starts_with("effect.")).collect();
            (Some((m, effects)), unknown)
        }
    };
    Ok(DiagnoseData {
        run: RunSeries {
            gyro_time_s,
            gyro_rate_rad_s: gyro_rate,
            gyro_temp_c,
            table_time_s,
            table_angle_rad: angle,
            table_rate_command_rad_s: command,
            chamber_time_s,
            chamber_temp_c: air,
            steps,
            latitude_deg,
            axis_up,
        },
        model,
        unknown_keys,
        origin_ns,
        bad_gyro_samples: bad,
    })
}

/// A diagnosis with its inputs and the re-simulation under the updated model.
#[derive(Debug, Clone)]
pub struct DiagnoseOutcome {
    /// What was read.
    pub data: DiagnoseData,
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
/// `bench.gyro_model`.
pub fn diagnose_recording(
    rec: &Recording,
    nominal: Option<(GyroModel, Effects, String)>,
    opts: &DiagnoseOptions,
) -> Result<DiagnoseOutcome, DiagnoseError> {
    let data = load(rec)?;
    let nominal = match nominal {
        Some(n) => n,
        None => {
            let (m, e) = data.model.clone().ok_or(DiagnoseError::NoModel)?;
            (m, e, "bench.gyro_model".into())
        }
    };
    let diagnosis = diagnose(&data.run, &nominal.0, &nominal.1, opts)?;
    // The re-simulation needs the residual and the verdict on parameters, not a new search.
    let resim_opts = DiagnoseOptions { max_effects: 0, ..opts.clone() };
    let resimulated = diagnose(&data.run, &diagnosis.model, &diagnosis.effects, &resim_opts).ok();
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
