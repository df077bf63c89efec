//! `bench verify RECORDING --calibration FILE`: a calibration file applied to another run of the
//! same gyro — the production step after calibration, often at other temperatures — and judged:
//! per record window the gyro's error against the table before and after compensation, in
//! °/h, against what the calibration states (its covariance, the gyro's noise) and against the
//! run's acceptance limit on the bias (`bench.acceptance` `bias_rad_s`: every window's
//! compensated error within it at ≈ 95 %). The arithmetic is
//! `bench_analysis::compensation`'s.
//!
//! Verdict, first that applies: **worse** — the compensation makes the gyro worse than
//! uncompensated beyond what its stated uncertainty allows (the coefficient responsible named);
//! **fail** — a window beyond the acceptance limit; **beyond σ** — a window's compensated error
//! beyond what the calibration and the noise allow (|z| above the Bonferroni level at 1 %
//! over the windows): the calibration does not hold on this run; else **pass**.

use std::collections::BTreeMap;
use std::path::Path;

use bench_analysis::calibrate::{model_series_windows, TemperatureSeries};
use bench_analysis::compensation::{compensate, Compensation};
use bench_analysis::joint_fit::NoiseSpec;
use bench_analysis::windows::RecordWindow;
use bench_physics::ModelKey;
use bench_recording::model_file::{CalibrationFile, HOLDABLE_KEYS};
use bench_recording::Recording;
use serde::Serialize;

use crate::acceptance::{judge, Judgement};
use crate::calibrate::{calibration_data, compensation_options, CalibrateError, CalibrationData};
use crate::display::{self, RATE};

/// Version of the verification JSON.
pub const VERIFY_JSON_VERSION: u32 = 1;

/// The verdict of a verification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VerifyVerdict {
    /// Compensated error within the calibration's σ and the limits; not worse.
    Pass,
    /// The compensation makes the gyro worse.
    Worse,
    /// A window's compensated error beyond the acceptance limit.
    Fail,
    /// A window's compensated error beyond what the calibration states.
    BeyondSigma,
}

impl VerifyVerdict {
    /// As printed.
    pub fn text(self) -> &'static str {
        match self {
            VerifyVerdict::Pass => "PASS",
            VerifyVerdict::Worse => "FAIL: the compensation makes the gyro worse",
            VerifyVerdict::Fail => "FAIL: beyond the acceptance limit",
            VerifyVerdict::BeyondSigma => {
                "FAIL: the compensated error is beyond what the calibration states"
            }
        }
    }
}

/// The acceptance limit on the bias, judged on every window's compensated error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyAcceptance {
    /// The limit on |bias| after compensation, rad/s (`bench.acceptance` `bias_rad_s`).
    pub limit: f64,
    /// The worst window's judgement (`pass`, `fail`, `inconclusive`).
    pub result: Judgement,
    /// That window's label.
    pub window: String,
}

/// A verification.
#[derive(Debug, Clone)]
pub struct VerifyOutcome {
    /// The verification run's data.
    pub data: CalibrationData,
    /// The calibration applied.
    pub calibration: CalibrationFile,
    /// Its windows at the model temperature the calibration's model uses.
    pub model_windows: Vec<RecordWindow>,
    /// Per window, before and after.
    pub compensation: Compensation,
    /// Against the run's bias limit, when it has one.
    pub acceptance: Option<VerifyAcceptance>,
    /// The verdict.
    pub verdict: VerifyVerdict,
}

/// The calibration's covariance over (bias, scale factor, k_t, k_dt), SI: its `[covariance]`
/// (else `[uncertainty]` on the diagonal), a held coefficient's stated σ on the diagonal.
pub fn file_covariance(cal: &CalibrationFile) -> [[f64; 4]; 4] {
    let mut c = [[0.0; 4]; 4];
    let index = |name: &str| HOLDABLE_KEYS.iter().position(|(_, k)| *k == name);
    match &cal.covariance {
        Some(cov) => {
            for (a, ka) in cov.keys.iter().enumerate() {
                for (b, kb) in cov.keys.iter().enumerate() {
                    if let (Some(i), Some(j)) = (index(ka), index(kb)) {
                        c[i][j] = cov.matrix[a][b];
                    }
                }
            }
        }
        None => {
            let u = &cal.uncertainty;
            let diag = [
                u.bias_rad_s,
                u.scale_factor_error,
                u.temp_coeff_rad_s_per_c,
                u.temp_rate_coeff_rad_s_per_c_s,
            ];
            for (j, s) in diag.iter().enumerate() {
                c[j][j] = s.map_or(0.0, |s| s * s);
            }
        }
    }
    for (name, h) in &cal.held {
        if let (Some(j), Some(s)) = (index(name), h.sigma) {
            c[j][j] = s * s;
        }
    }
    c
}

/// The windows of `data` at the model temperature of `cal`: the gyro's sensor, else the
/// chamber air through the calibration's lag; smoothed with its rate over the whole run.
fn model_windows(
    data: &CalibrationData,
    cal: &CalibrationFile,
    rate_window_s: f64,
) -> Vec<RecordWindow> {
    let tau = cal.gyro_model.0.thermal_time_constant;
    let series: TemperatureSeries = if data.run.gyro_sensor() || tau <= 0.0 {
        data.temperature.clone()
    } else {
        data.chamber.lagged(tau)
    };
    let windows: Vec<RecordWindow> = data
        .windows
        .iter()
        .map(|w| w.with_model_temperature(series.sample(w.time_s())).unwrap_or_else(|_| w.clone()))
        .collect();
    model_series_windows(&windows, &series, rate_window_s)
}

/// Apply `cal` to the recording `rec` and judge it (module docs).
pub fn verify_recording(
    rec: &Recording,
    cal: &CalibrationFile,
) -> Result<VerifyOutcome, CalibrateError> {
    let data = calibration_data(crate::load::load(rec)?)?;
    let rate_window_s = bench_analysis::calibrate::CalibrateOptions::default().joint.rate_window_s;
    let windows = model_windows(&data, cal, rate_window_s);
    let model = cal.model();
    let noise = NoiseSpec { arw: model.arw, flicker_floor: model.bias_instability, rrw: 0.0 };
    let latitude = data.run.series.latitude_deg.filter(|_| model.earth_rate);
    let opts = compensation_options(
        &model,
        file_covariance(cal),
        latitude,
        data.run.series.axis_up,
        rate_window_s,
        Some(noise).filter(|n| n.arw > 0.0 || n.flicker_floor > 0.0),
    );
    let compensation = compensate(&windows, &opts)?;
    let acceptance = data.run.acceptance.get("bias_rad_s").map(|&limit| {
        let judged: Vec<(Judgement, &str)> = compensation
            .windows
            .iter()
            .map(|w| {
                (
                    judge(w.compensated, w.sigma_calibration.hypot(w.sigma_noise), limit),
                    w.label.as_str(),
                )
            })
            .collect();
        let worst = judged
            .iter()
            .find(|j| j.0 == Judgement::Fail)
            .or_else(|| judged.iter().find(|j| j.0 != Judgement::Pass))
            .or_else(|| judged.first())
            .copied();
        VerifyAcceptance {
            limit,
            result: worst.map_or(Judgement::NotEstimated, |w| w.0),
            window: worst.map_or_else(String::new, |w| w.1.to_owned()),
        }
    });
    let verdict = if compensation.worse {
        VerifyVerdict::Worse
    } else if acceptance.as_ref().is_some_and(|a| a.result == Judgement::Fail) {
        VerifyVerdict::Fail
    } else if !compensation.within_sigma() {
        VerifyVerdict::BeyondSigma
    } else {
        VerifyVerdict::Pass
    };
    Ok(VerifyOutcome {
        data,
        calibration: cal.clone(),
        model_windows: windows,
        compensation,
        acceptance,
        verdict,
    })
}

/// Load `path` and verify `cal` on it.
pub fn verify_file(path: &Path, cal: &CalibrationFile) -> Result<VerifyOutcome, CalibrateError> {
    verify_recording(&Recording::load(path)?, cal)
}

/// One window before and after, SI.
#[derive(Debug, Clone, Serialize)]
pub struct WindowJson {
    /// Label.
    pub label: String,
    /// First and last sample, s since time zero.
    pub start_s: f64,
    /// Last sample, s.
    pub end_s: f64,
    /// Samples.
    pub samples: usize,
    /// Mean model temperature, °C.
    pub mean_temperature: f64,
    /// Mean dT/dt, °C/s.
    pub mean_temperature_rate: f64,
    /// Mean table rate, rad/s.
    pub mean_table_rate: f64,
    /// Mean error without compensation, rad/s.
    pub uncompensated: f64,
    /// Mean error with it, rad/s.
    pub compensated: f64,
    /// The calibration's uncertainty of the compensated error here, rad/s.
    pub sigma_calibration: f64,
    /// The noise of the window mean, rad/s.
    pub sigma_noise: f64,
    /// Compensated over the two in quadrature.
    pub z: Option<f64>,
    /// What each coefficient's term takes out here, rad/s.
    pub terms: BTreeMap<&'static str, f64>,
}

/// A compensation, for the JSON (also `bench calibrate`'s, on its own run).
#[derive(Debug, Clone, Serialize)]
pub struct CompensationJson {
    /// RMS over the windows of their mean error without compensation, rad/s.
    pub rms_uncompensated: f64,
    /// With it, rad/s.
    pub rms_compensated: f64,
    /// The window with the largest compensated error.
    pub worst_window: String,
    /// Its compensated error, rad/s.
    pub worst_compensated: f64,
    /// Largest |z| of a window.
    pub max_abs_z: f64,
    /// The |z| a window exceeds with probability 1 % over all windows when the calibration
    /// holds.
    pub z_threshold: f64,
    /// Whether the compensation makes the gyro worse.
    pub worse: bool,
    /// The coefficient whose compensation, left out, lowers the compensated RMS most, and that
    /// RMS, rad/s.
    pub responsible: Option<(&'static str, f64)>,
    /// Per window.
    pub windows: Vec<WindowJson>,
}

/// `c` as JSON.
pub fn compensation_json(c: &Compensation) -> CompensationJson {
    let worst = c.windows.get(c.worst);
    CompensationJson {
        rms_uncompensated: c.rms_uncompensated,
        rms_compensated: c.rms_compensated,
        worst_window: worst.map_or_else(String::new, |w| w.label.clone()),
        worst_compensated: worst.map_or(f64::NAN, |w| w.compensated),
        max_abs_z: c.max_abs_z,
        z_threshold: c.z_threshold,
        worse: c.worse,
        responsible: c.responsible.map(|(k, r)| (k.key(), r)),
        windows: c
            .windows
            .iter()
            .map(|w| WindowJson {
                label: w.label.clone(),
                start_s: w.span_s.0,
                end_s: w.span_s.1,
                samples: w.samples,
                mean_temperature: w.mean_temp_c,
                mean_temperature_rate: w.mean_rate_c_s,
                mean_table_rate: w.mean_table_rate_rad_s,
                uncompensated: w.uncompensated,
                compensated: w.compensated,
                sigma_calibration: w.sigma_calibration,
                sigma_noise: w.sigma_noise,
                z: Some(w.z).filter(|z| z.is_finite()),
                terms: ModelKey::CALIBRATED.iter().map(|k| k.key()).zip(w.terms).collect(),
            })
            .collect(),
    }
}

/// `bench verify --json`.
#[derive(Debug, Clone, Serialize)]
pub struct VerifyJson {
    /// Layout version.
    pub version: u32,
    /// The verification recording.
    pub recording: String,
    /// The calibration file applied.
    pub calibration: String,
    /// The recording the calibration came from (its `[source]`).
    pub calibrated_on: String,
    /// `pass`, `worse`, `fail` or `beyond_sigma`.
    pub verdict: VerifyVerdict,
    /// The calibration's held coefficients (not determined when it was made), by key, with why.
    pub held: BTreeMap<String, String>,
    /// Before and after, per window.
    pub compensation: CompensationJson,
    /// The bias limit judged on the windows, when the run has one.
    pub acceptance: Option<VerifyAcceptance>,
}

/// The JSON of `v` (`recording` and `calibration` as named to the user).
pub fn verify_json(v: &VerifyOutcome, recording: &str, calibration: &str) -> VerifyJson {
    VerifyJson {
        version: VERIFY_JSON_VERSION,
        recording: recording.to_owned(),
        calibration: calibration.to_owned(),
        calibrated_on: v.calibration.source.recording.clone(),
        verdict: v.verdict,
        held: v.calibration.held.iter().map(|(k, h)| (k.clone(), h.reason.clone())).collect(),
        compensation: compensation_json(&v.compensation),
        acceptance: v.acceptance.clone(),
    }
}

/// The summary lines of a compensation, report units: RMS before → after, the worst window,
/// the largest z against its level, and who is responsible when worse.
pub fn summary_lines(c: &Compensation) -> Vec<String> {
    let mut out = vec![format!(
        "error per window, RMS over {} windows: {} uncompensated → {} compensated",
        c.windows.len(),
        display::si_value(RATE, c.rms_uncompensated, 3),
        display::si_value(RATE, c.rms_compensated, 3)
    )];
    if let Some(w) = c.windows.get(c.worst) {
        out.push(format!(
            "worst window `{}` ({:.1} °C, {:+.2} °C/min): {} → {} (z {:+.1}; a calibration that \
             holds stays within ±{:.2} over these windows)",
            w.label,
            w.mean_temp_c,
            w.mean_rate_c_s * 60.0,
            display::si_value(RATE, w.uncompensated, 3),
            display::si_value(RATE, w.compensated, 3),
            w.z,
            c.z_threshold
        ));
    }
    if c.worse {
        out.push(match c.responsible {
            Some((k, r)) => format!(
                "the compensation makes the gyro worse; `{}` is responsible: left uncompensated, \
                 the RMS would be {}",
                k.key(),
                display::si_value(RATE, r, 3)
            ),
            None => "the compensation makes the gyro worse".into(),
        });
    }
    out
}
