//! `bench calibrate`: a recording in, the gyro's thermal calibration out.
//!
//! [`windows::calibration_data`] turns a recording's arrays ([`crate::load`]) into record
//! windows; [`calibrate_recording`] runs `bench_analysis::calibrate` on them and compares with
//! the recording's `bench.gyro_model` (the truth, for a simulated run); [`json`] writes the
//! machine-readable result; [`report`] the HTML/SVG/PNG report. The calibration file itself is
//! `bench_recording::model_file`.

pub mod held;
pub mod json;
pub mod quality;
pub mod report;
pub mod windows;

use std::path::Path;

use bench_analysis::calibrate::{
    calibrate, thermal_error_removal, CalibrateOptions, Calibration, Expected, ExpectedSource,
    ThermalErrorRemoval,
};
use bench_analysis::compensation::{compensate, Compensation, CompensationOptions};
use bench_analysis::joint_fit::JointFitOptions;
use bench_analysis::AnalysisError;
use bench_physics::{GyroModel, ModelKey};

use bench_recording::{Recording, RecordingError};

use crate::load::LoadError;
pub use windows::{calibration_data, CalibrationData, WindowSpan};

/// Why a recording cannot be calibrated.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The recording could not be read.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The recording's arrays could not be read.
    #[error(transparent)]
    Load(#[from] LoadError),
    /// No step has a label starting with `record`.
    #[error(
        "no record windows: none of the {steps} steps of /bench/step is labelled `record …`, \
         so nothing marks calibration data"
    )]
    NoRecordWindows {
        /// Steps in the file.
        steps: usize,
    },
    /// The analysis rejected the data.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
}

/// Settings of [`calibrate_recording`] beyond the analysis' own.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CalibrateSettings {
    /// T0 of the coefficients, °C; `None`: the recording model's `reference_temperature`, or
    /// 20 °C without one.
    pub reference_temperature_c: Option<f64>,
    /// Bootstrap replicates; `None`: the analysis default.
    pub replicates: Option<usize>,
    /// Skip the thermal-lag profile.
    pub no_lag: bool,
    /// What the user expects of coefficients before the data (`--prior KEY=VALUE±SIGMA`): the
    /// identifiability test's size and the value held when the run does not determine one,
    /// in place of the nominal model's.
    pub priors: Vec<Prior>,
}

/// A prior on a calibrated coefficient: `KEY=VALUE±SIGMA`, contract key and SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prior {
    /// The coefficient (one of `ModelKey::CALIBRATED`).
    pub key: ModelKey,
    /// Expected value, SI.
    pub value: f64,
    /// Its 1σ, SI (≥ 0).
    pub sigma: f64,
}

impl std::str::FromStr for Prior {
    type Err = String;

    /// `temp_rate_coeff=1.45e-5±3e-6` (or `+-` for `±`; SI units, the contract's keys: `bias`,
    /// `scale_factor_error`, `temp_coeff`, `temp_rate_coeff`).
    fn from_str(text: &str) -> Result<Self, String> {
        let (key, rest) =
            text.split_once('=').ok_or_else(|| format!("`{text}`: expected KEY=VALUE±SIGMA"))?;
        let key = key.trim();
        let k = ModelKey::from_key(key).filter(|k| ModelKey::CALIBRATED.contains(k)).ok_or_else(
            || {
                format!(
                    "`{key}`: a prior is for a calibrated coefficient: {}",
                    ModelKey::CALIBRATED.map(|k| k.key()).join(", ")
                )
            },
        )?;
        let (v, s) = rest
            .split_once('±')
            .or_else(|| rest.split_once("+-"))
            .ok_or_else(|| format!("`{rest}`: expected VALUE±SIGMA (or VALUE+-SIGMA), SI units"))?;
        let num = |t: &str| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("`{}`: not a finite number", t.trim()))
        };
        let (value, sigma) = (num(v)?, num(s)?);
        if sigma < 0.0 {
            return Err(format!("`{text}`: σ must not be negative"));
        }
        Ok(Prior { key: k, value, sigma })
    }
}

/// Each calibrated coefficient's expected value: a prior's, else the nominal model's for the
/// thermal coefficients. A nominal bias or scale factor is no expected value: a data sheet
/// gives them as bounds (or 0), and a unit's own offsets are what every run with the table
/// turning measures — they are judged by excitation and confounding alone, and held (at the
/// nominal value) only when the run cannot tell them at all.
fn expected_values(priors: &[Prior], nominal: Option<&GyroModel>) -> [Option<Expected>; 4] {
    std::array::from_fn(|j| {
        let key = ModelKey::CALIBRATED[j];
        match priors.iter().rev().find(|p| p.key == key) {
            Some(p) => Some(Expected {
                value: p.value,
                sigma: Some(p.sigma),
                source: ExpectedSource::Prior,
                sized: true,
            }),
            None => nominal.map(|m| Expected {
                value: m.get(key),
                sigma: None,
                source: ExpectedSource::Nominal,
                sized: matches!(key, ModelKey::TempCoeff | ModelKey::TempRateCoeff),
            }),
        }
    })
}

/// The seed-style error-function comparison with a known model (the seed's Δk_t and Δk_dt).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FunctionErrors {
    /// max over the windows' temperature range of |k_t,true(T) − k_t,fit(T)|, k_t including the
    /// bias, rad/s.
    pub delta_k_t_rad_s: f64,
    /// max over the windows' dT/dt range of |k_dt,true·Ṫ − k_dt,fit·Ṫ|, rad/s.
    pub delta_k_dt_rad_s: f64,
}

/// Comparison with the recording's `bench.gyro_model`.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthComparison {
    /// The model (truth for a simulated run).
    pub model: GyroModel,
    /// The joint fit's function errors.
    pub joint: Option<FunctionErrors>,
    /// The seed method's function errors.
    pub seed: Option<FunctionErrors>,
    /// Thermal error removed by the joint calibration.
    pub joint_removal: Option<ThermalErrorRemoval>,
    /// Thermal error removed by the seed calibration.
    pub seed_removal: Option<ThermalErrorRemoval>,
}

/// A calibrated recording.
#[derive(Debug, Clone)]
pub struct CalibrationOutcome {
    /// The data as loaded.
    pub data: CalibrationData,
    /// The analysis.
    pub calibration: Calibration,
    /// The calibrated model (joint fit), if the fit succeeded.
    pub model: Option<GyroModel>,
    /// The seed method's model, if it succeeded.
    pub seed_model: Option<GyroModel>,
    /// Against the recording's model, when it has one.
    pub truth: Option<TruthComparison>,
    /// Temperature range of the windows, °C.
    pub temp_range_c: (f64, f64),
    /// dT/dt range of the windows, °C/s.
    pub rate_range_c_s: (f64, f64),
    /// Whether the fit fits ([`quality`]).
    pub quality: quality::FitQuality,
    /// The calibration applied to this run's own windows: the error before and after
    /// compensation (`bench_analysis::compensation`), when the joint fit ran.
    pub compensation: Option<Compensation>,
    /// The calibration applied to a verification run (`bench calibrate --verify`), when given:
    /// its file name and the verification.
    pub verification: Option<(String, Box<crate::verify::VerifyOutcome>)>,
}

/// The options of applying `model` (with `covariance`, NaN entries unknown) over windows of a
/// run at `latitude_deg` (`bench_analysis::compensation`).
pub fn compensation_options(
    model: &GyroModel,
    covariance: [[f64; 4]; 4],
    latitude_deg: Option<f64>,
    axis_up: bool,
    rate_window_s: f64,
    noise: Option<bench_analysis::joint_fit::NoiseSpec>,
) -> CompensationOptions {
    CompensationOptions {
        coefficients: ModelKey::CALIBRATED.map(|k| model.get(k)),
        covariance: covariance.map(|r| r.map(|c| if c.is_finite() { c } else { 0.0 })),
        reference_temperature_c: model.reference_temperature,
        latitude_deg,
        axis_up,
        rate_window_s,
        noise,
        alpha: quality::BLOCK_ALPHA,
    }
}

fn function_errors(
    truth: &GyroModel,
    fit: &GyroModel,
    temp_range_c: (f64, f64),
    rate_range_c_s: (f64, f64),
) -> FunctionErrors {
    let kt = |m: &GyroModel, t: f64| m.bias + m.temp_coeff * (t - m.reference_temperature);
    // Linear functions: the largest difference is at an end of the range.
    let dkt = [temp_range_c.0, temp_range_c.1]
        .iter()
        .map(|&t| (kt(truth, t) - kt(fit, t)).abs())
        .fold(0.0, f64::max);
    let dkdt = rate_range_c_s.0.abs().max(rate_range_c_s.1.abs())
        * (truth.temp_rate_coeff - fit.temp_rate_coeff).abs();
    FunctionErrors { delta_k_t_rad_s: dkt, delta_k_dt_rad_s: dkdt }
}

/// Load and calibrate the recording at `path`.
pub fn calibrate_file(
    path: &Path,
    settings: &CalibrateSettings,
) -> Result<CalibrationOutcome, CalibrateError> {
    let rec = Recording::load(path)?;
    calibrate_recording(&rec, settings)
}

/// Calibrate a loaded recording.
pub fn calibrate_recording(
    rec: &Recording,
    settings: &CalibrateSettings,
) -> Result<CalibrationOutcome, CalibrateError> {
    calibrate_run(crate::load::load(rec)?, settings)
}

/// Calibrate a recording's arrays ([`crate::load::load`]); the [`Recording`] they came from
/// need not be held meanwhile (its decoded messages are the larger part of the memory).
pub fn calibrate_run(
    run: crate::load::RunData,
    settings: &CalibrateSettings,
) -> Result<CalibrationOutcome, CalibrateError> {
    let data = calibration_data(run)?;
    let recorded = data.run.model.as_ref().map(|m| m.model.clone());
    let mut opts = CalibrateOptions {
        joint: JointFitOptions {
            reference_temperature_c: settings
                .reference_temperature_c
                .or_else(|| recorded.as_ref().map(|m| m.reference_temperature))
                .unwrap_or(20.0),
            latitude_deg: data.run.series.latitude_deg,
            axis_up: data.run.series.axis_up,
            ..JointFitOptions::default()
        },
        // With the gyro's own sensor the model temperature is that sensor's (the usual
        // practice); the lag from air is profiled only for a gyro without one. (Against a
        // sensor, the profile's χ² test with a correlation-lag n_eff found a spurious 50 s lag
        // on simulated data without any: flicker noise needs the noise-model test, not done.)
        fit_lag: !settings.no_lag && !data.run.gyro_sensor(),
        stated_flicker_floor_rad_s: recorded
            .as_ref()
            .map(|m| m.bias_instability)
            .filter(|b| *b > 0.0),
        expected: expected_values(&settings.priors, recorded.as_ref()),
        ..CalibrateOptions::default()
    };
    if let Some(r) = settings.replicates {
        opts.joint.replicates = r;
    }
    let calibration = calibrate(&data.windows, &data.readings, &data.temperature, &opts);
    let mut base = recorded.clone().unwrap_or_else(GyroModel::zero);
    if !data.run.gyro_sensor() && !matches!(calibration.lag, Some(Ok(_))) {
        // Fitted against the chamber air itself (no lag estimated): the model says so, not the
        // recorded nominal τ, by which `bench verify` and the compensation would lag the air.
        base.thermal_time_constant = 0.0;
    }
    let model = calibration.model(&base);
    let seed_model = calibration.seed.as_ref().ok().map(|s| {
        let mut m = s.to_model(&base);
        m.earth_rate = opts.joint.latitude_deg.is_some();
        m
    });

    let mut temp_range_c = (f64::INFINITY, f64::NEG_INFINITY);
    let mut rate_range_c_s = (0.0f64, 0.0f64);
    for w in &calibration.model_windows {
        for &t in w.temperature_c() {
            temp_range_c = (temp_range_c.0.min(t), temp_range_c.1.max(t));
        }
        if let Ok(r) = bench_analysis::temperature_rate::local_linear_rate(
            w.time_s(),
            w.temperature_c(),
            opts.joint.rate_window_s,
        ) {
            for d in r {
                rate_range_c_s = (rate_range_c_s.0.min(d), rate_range_c_s.1.max(d));
            }
        }
    }

    // Only a simulator's model is the data's truth; a lab's is nominal (docs/recording.md).
    let simulated = data.run.model_role == bench_recording::ModelRole::Simulation;
    let truth = recorded.filter(|_| simulated).map(|t| {
        let series = &data.temperature;
        TruthComparison {
            joint: model.as_ref().map(|m| function_errors(&t, m, temp_range_c, rate_range_c_s)),
            seed: seed_model.as_ref().map(|m| function_errors(&t, m, temp_range_c, rate_range_c_s)),
            joint_removal: model
                .as_ref()
                .and_then(|m| thermal_error_removal(&t, m, series, opts.joint.rate_window_s).ok()),
            seed_removal: seed_model
                .as_ref()
                .and_then(|m| thermal_error_removal(&t, m, series, opts.joint.rate_window_s).ok()),
            model: t,
        }
    });
    let compensation = match (&model, &calibration.joint) {
        (Some(m), Ok(j)) => compensate(
            &calibration.model_windows,
            &compensation_options(
                m,
                j.covariance,
                opts.joint.latitude_deg,
                opts.joint.axis_up,
                opts.joint.rate_window_s,
                calibration.noise_model,
            ),
        )
        .ok(),
        _ => None,
    };
    let mut out = CalibrationOutcome {
        data,
        calibration,
        model,
        seed_model,
        truth,
        temp_range_c,
        rate_range_c_s,
        quality: quality::FitQuality::default(),
        compensation,
        verification: None,
    };
    out.quality = quality::judge(&out);
    Ok(out)
}
