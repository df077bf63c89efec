//! The machine-readable result of `bench calibrate --json FILE` (documented in
//! `docs/calibrate.md`). Numbers in SI units (rad/s, °C, s); absent estimates are `null`.

use std::collections::BTreeMap;

use bench_analysis::calibrate::WindowKind;
use bench_physics::ModelKey;
use serde::Serialize;

use super::CalibrationOutcome;

/// Version of this JSON layout.
pub const JSON_VERSION: u32 = 3;

/// A value with its 1σ standard error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Coefficient {
    /// Estimate.
    pub value: f64,
    /// 1σ standard error (GLS: the Cramér–Rao bound, scaled up by a whitened residual RMS
    /// above 1; OLS: the larger of block bootstrap and noise model).
    pub sigma: f64,
    /// Moving-block bootstrap σ (of the whitened residuals for GLS).
    pub sigma_bootstrap: f64,
    /// Noise-model (Allan) σ — for GLS the Cramér–Rao bound; null without a noise model.
    pub sigma_noise_model: Option<f64>,
    /// Naive OLS σ, for comparison only.
    pub sigma_naive: f64,
    /// The OLS value, for comparison only.
    pub value_ols: f64,
    /// The OLS value's σ under the noise model, for comparison only; null without one.
    pub sigma_ols: Option<f64>,
}

/// A noise term with its confidence interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseTermJson {
    /// Value, SI.
    pub value: f64,
    /// Interval low end.
    pub low: f64,
    /// Interval high end.
    pub high: f64,
    /// τ at which it was read, s.
    pub tau_s: f64,
    /// True when the curve never shows the term's slope: the value is an upper bound.
    pub upper_bound: bool,
}

/// The JSON document.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationJson {
    /// Layout version.
    pub version: u32,
    /// Recording file.
    pub recording: String,
    /// T0 of the coefficients, °C.
    pub reference_temperature: f64,
    /// The joint fit's estimator: `gls` (under the noise model) or `ols`; null without a fit.
    pub estimator: Option<&'static str>,
    /// RMS of the GLS whitened residual (≈ 1 when the noise model fits); null for OLS.
    pub whitened_residual_rms: Option<f64>,
    /// Joint fit, keyed by `bench.gyro_model` key: the coefficients estimated (a held one is
    /// in `held`, never here).
    pub coefficients: BTreeMap<String, Coefficient>,
    /// Coefficients the run does not determine, held at a value and not estimated: the value,
    /// where it comes from, why, and the run that would determine it.
    pub held: BTreeMap<String, super::held::HeldJson>,
    /// Per coefficient, the identifiability test made before the fit
    /// (`bench_analysis::information`).
    pub identifiability: BTreeMap<String, IdentifiabilityJson>,
    /// Covariance of the estimated coefficients (their σ² on the diagonal), rows and columns
    /// in `covariance_keys` order, contract units; null for OLS.
    pub covariance: Option<Vec<Vec<f64>>>,
    /// The order of `covariance`'s rows and columns: the estimated coefficients.
    pub covariance_keys: Vec<&'static str>,
    /// The seed method's values (no σ: the method gives none), keyed likewise.
    pub seed_method: BTreeMap<String, f64>,
    /// IEEE 952 noise terms: `arw` (rad/√s), `bias_instability` (the flicker floor, rad/s, as
    /// in `bench.gyro_model`), `bias_instability_b` (IEEE B = floor/0.664), `rate_random_walk`
    /// (rad/s/√s).
    pub noise: BTreeMap<String, NoiseTermJson>,
    /// Confidence level of the noise intervals.
    pub noise_confidence: Option<f64>,
    /// The noise model carried into the coefficients' σ (least-squares fit of the whole Allan
    /// curve): `arw` rad/√s, `flicker_floor` rad/s, `rrw` rad/s/√s.
    pub noise_model: Option<BTreeMap<String, f64>>,
    /// Thermal lag, s, fitted with the coefficients; null where the lag was not estimated
    /// (`gyro_model` then carries the model's value, as `calibration.toml` does).
    pub thermal_time_constant: Option<f64>,
    /// Its 1σ, s, when fitted; null otherwise.
    pub thermal_time_constant_sigma: Option<f64>,
    /// The calibrated model as `bench.gyro_model` keys.
    pub gyro_model: BTreeMap<String, f64>,
    /// Against the recording's `bench.gyro_model`, when present.
    pub truth: Option<TruthJson>,
    /// Windows used.
    pub windows: Vec<WindowJson>,
    /// What the data lack, and what could still be estimated.
    pub missing: Vec<String>,
    /// Whether the fit fits: `verdict` (`sound`/`poor`), each check, the residual's largest
    /// excursions with what the table and chamber were doing.
    pub fit: super::quality::FitQuality,
    /// The angle-domain fit (the seed's navigation method), beside the rate domain.
    pub angle_domain: Option<AngleDomainJson>,
    /// What the record steps hold outside the windows used, with the cause, in time order.
    pub excluded: Vec<ExcludedJson>,
    /// Record steps with no steady part long enough to use.
    pub unused_steps: Vec<String>,
    /// Each channel's time base: device stamps, device counter or host stamps, and for a device
    /// clock the host stamps' drift, jitter and largest delay against it.
    pub time_bases: Vec<TimeBaseJson>,
    /// The coefficients against the recording's acceptance limits (`bench.acceptance`), with
    /// its `bench.station`; null when the recording has no limits ([`crate::acceptance`]).
    pub acceptance: Option<crate::acceptance::Acceptance>,
    /// The calibration applied to this run's own windows: the error before and after, per
    /// window (`bench_analysis::compensation`); null without a joint fit.
    pub compensation: Option<crate::verify::CompensationJson>,
    /// The calibration applied to a verification run (`--verify`), when given.
    pub verification: Option<crate::verify::VerifyJson>,
}

/// One coefficient's identifiability.
#[derive(Debug, Clone, Serialize)]
pub struct IdentifiabilityJson {
    /// `determined`, `not_excited`, `confounded` or `too_small`.
    pub verdict: &'static str,
    /// Its Cramér–Rao σ on this run's design, contract unit (null when not excited or
    /// confounded outright, or without a noise model).
    pub sigma_bound: Option<f64>,
    /// Share of its information the other coefficients carry, 0–1.
    pub confounding: Option<f64>,
    /// The coefficient it is most correlated with.
    pub confounded_with: Option<&'static str>,
    /// Its expected size (a prior's, else the nominal model's), when known.
    pub expected_size: Option<f64>,
}

/// The angle-domain fit.
#[derive(Debug, Clone, Serialize)]
pub struct AngleDomainJson {
    /// Why it could not run, else null.
    pub error: Option<String>,
    /// Keyed by `bench.gyro_model` key: value, σ (bound × max(1, whitened RMS)), bound.
    pub coefficients: BTreeMap<String, AngleCoefficient>,
    /// RMS of the whitened residual (≈ 1 when the noise model fits).
    pub whitened_residual_rms: Option<f64>,
    /// Angle readings used.
    pub readings: usize,
    /// Steady stretches used.
    pub stretches: usize,
    /// Gyro samples bridged (lost or flagged) inside the stretches.
    pub bridged_samples: usize,
    /// RMS angle misclosure over the readings before and after calibration, rad.
    pub misclosure_rms_before: Option<f64>,
    /// After calibration (each stretch's offset removed too), rad.
    pub misclosure_rms_after: Option<f64>,
}

/// One angle-domain coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AngleCoefficient {
    /// Estimate.
    pub value: f64,
    /// 1σ.
    pub sigma: f64,
    /// The Cramér–Rao bound under the noise model.
    pub sigma_bound: f64,
}

/// A span of a record step left out.
#[derive(Debug, Clone, Serialize)]
pub struct ExcludedJson {
    /// The step's label.
    pub step: String,
    /// From, s since time zero.
    pub start: f64,
    /// Until, s.
    pub end: f64,
    /// Length, s.
    pub seconds: f64,
    /// `reversal`, `start`, `stop`, `rate_change`, `no_table_data` or `not_steady`.
    pub why: &'static str,
    /// Good gyro samples in it.
    pub samples: usize,
}

/// A channel's time base.
#[derive(Debug, Clone, Serialize)]
pub struct TimeBaseJson {
    /// Topic.
    pub topic: &'static str,
    /// `device_stamps`, `device_counter` or `host`.
    pub source: &'static str,
    /// Host clock drift against the device's, ppm; null for host time and a device counter.
    pub drift_ppm: Option<f64>,
    /// A device counter's time base: host seconds per count; null otherwise.
    pub s_per_count: Option<f64>,
    /// Robust scatter of the host stamps about the device clock's line, s.
    pub jitter: Option<f64>,
    /// Largest delay of a host stamp behind the line, s.
    pub max_late: Option<f64>,
    /// Host stamps set aside as late.
    pub late_outliers: Option<usize>,
}

/// Comparison with the recording's model.
#[derive(Debug, Clone, Serialize)]
pub struct TruthJson {
    /// The recording's coefficients.
    pub coefficients: BTreeMap<String, f64>,
    /// Joint fit: max |Δk_t| over the temperature range, rad/s.
    pub joint_delta_k_t: Option<f64>,
    /// Joint fit: max |Δk_dt·Ṫ| over the dT/dt range, rad/s.
    pub joint_delta_k_dt: Option<f64>,
    /// Seed method, likewise.
    pub seed_delta_k_t: Option<f64>,
    /// Seed method, likewise.
    pub seed_delta_k_dt: Option<f64>,
    /// Thermal error removed by the joint calibration, fraction.
    pub joint_thermal_error_removed: Option<f64>,
    /// Thermal error removed by the seed calibration, fraction.
    pub seed_thermal_error_removed: Option<f64>,
}

/// One window.
#[derive(Debug, Clone, Serialize)]
pub struct WindowJson {
    /// Label.
    pub label: String,
    /// `plateau`, `ramp` or `static`.
    pub kind: &'static str,
    /// Samples.
    pub samples: usize,
    /// Mean model temperature, °C.
    pub mean_temperature: f64,
    /// Mean table rate, rad/s.
    pub mean_table_rate: f64,
}

fn model_map(m: &bench_physics::GyroModel) -> BTreeMap<String, f64> {
    m.to_metadata().into_iter().filter_map(|(k, v)| v.parse::<f64>().ok().map(|x| (k, x))).collect()
}

/// Build the JSON document of `outcome` (recording named `recording`).
pub fn to_json(outcome: &CalibrationOutcome, recording: &str) -> CalibrationJson {
    let cal = &outcome.calibration;
    let joint = cal.joint.as_ref().ok();
    let (noise, noise_confidence) = noise_json(cal);
    CalibrationJson {
        version: JSON_VERSION,
        recording: recording.to_owned(),
        reference_temperature: cal.options.joint.reference_temperature_c,
        estimator: joint.map(|j| j.estimator.as_str()),
        whitened_residual_rms: joint.map(|j| j.whitened_residual_rms).filter(|v| v.is_finite()),
        coefficients: coefficients_json(cal),
        covariance: covariance_json(cal),
        covariance_keys: estimated(cal)
            .into_iter()
            .map(|j| ModelKey::CALIBRATED[j].key())
            .collect(),
        held: super::held::held(cal)
            .into_iter()
            .map(|(k, h)| (k.key().to_owned(), super::held::held_json(h)))
            .collect(),
        identifiability: identifiability_json(cal),
        seed_method: seed_method_json(cal),
        noise,
        noise_confidence,
        noise_model: cal.noise_model.map(|n| {
            BTreeMap::from([
                ("arw".to_owned(), n.arw),
                ("flicker_floor".to_owned(), n.flicker_floor),
                ("rrw".to_owned(), n.rrw),
            ])
        }),
        thermal_time_constant: match &cal.lag {
            Some(Ok(l)) => Some(l.fitted_s()),
            _ => None,
        },
        thermal_time_constant_sigma: match &cal.lag {
            Some(Ok(l)) if l.sigma_s.is_finite() => Some(l.sigma_s),
            _ => None,
        },
        gyro_model: outcome.model.as_ref().map(model_map).unwrap_or_default(),
        truth: truth_json(outcome),
        windows: cal.windows.iter().map(window_json).collect(),
        missing: cal.missing.clone(),
        fit: outcome.quality.clone(),
        angle_domain: cal.angle.as_ref().map(angle_json),
        excluded: outcome.data.exclusions.iter().map(excluded_json).collect(),
        unused_steps: outcome.data.empty_windows.iter().map(|(l, _)| l.clone()).collect(),
        time_bases: outcome.data.run.time_bases.iter().map(time_base_json).collect(),
        acceptance: crate::acceptance::judge_calibration(outcome),
        compensation: outcome.compensation.as_ref().map(crate::verify::compensation_json),
        verification: outcome
            .verification
            .as_ref()
            .map(|(name, v)| crate::verify::verify_json(v, name, "calibration.toml")),
    }
}

/// The joint fit's estimated coefficients (a held one is not among them).
fn coefficients_json(
    cal: &bench_analysis::calibrate::Calibration,
) -> BTreeMap<String, Coefficient> {
    let Ok(j) = &cal.joint else { return BTreeMap::new() };
    let finite = |v: f64| v.is_finite().then_some(v);
    ModelKey::CALIBRATED
        .into_iter()
        .filter_map(|k| Some((k, j.estimate(k).filter(|e| !e.held)?)))
        .map(|(k, e)| {
            let c = Coefficient {
                value: e.value,
                sigma: e.std_err,
                sigma_bootstrap: e.bootstrap_std_err,
                sigma_noise_model: finite(e.noise_model_std_err),
                sigma_naive: e.naive_std_err,
                value_ols: e.ols_value,
                sigma_ols: finite(e.ols_noise_model_std_err),
            };
            (k.key().to_owned(), c)
        })
        .collect()
}

/// The covariance of the estimated coefficients, when every entry is finite.
fn covariance_json(cal: &bench_analysis::calibrate::Calibration) -> Option<Vec<Vec<f64>>> {
    let j = cal.joint.as_ref().ok()?;
    let est = estimated(cal);
    let c: Vec<Vec<f64>> =
        est.iter().map(|&a| est.iter().map(|&b| j.covariance[a][b]).collect()).collect();
    c.iter().flatten().all(|v| v.is_finite()).then_some(c)
}

/// The seed method's coefficients.
fn seed_method_json(cal: &bench_analysis::calibrate::Calibration) -> BTreeMap<String, f64> {
    let Ok(s) = &cal.seed else { return BTreeMap::new() };
    ModelKey::CALIBRATED
        .into_iter()
        .filter_map(|k| Some((k.key().to_owned(), s.coefficient(k)?)))
        .collect()
}

/// The IEEE 952 noise terms and their confidence level.
fn noise_json(
    cal: &bench_analysis::calibrate::Calibration,
) -> (BTreeMap<String, NoiseTermJson>, Option<f64>) {
    let Ok(a) = &cal.allan else { return (BTreeMap::new(), None) };
    let t = |n: bench_analysis::allan_fit::NoiseTerm| NoiseTermJson {
        value: n.value,
        low: n.low,
        high: n.high,
        tau_s: n.tau_s,
        upper_bound: n.upper_bound,
    };
    let noise = BTreeMap::from([
        ("arw".to_owned(), t(a.fit.arw)),
        ("bias_instability".to_owned(), t(a.fit.flicker_floor())),
        ("bias_instability_b".to_owned(), t(a.fit.bias_instability)),
        ("rate_random_walk".to_owned(), t(a.fit.rate_random_walk)),
    ]);
    (noise, Some(a.fit.confidence))
}

/// The comparison with the recording's model, when it has one.
fn truth_json(outcome: &CalibrationOutcome) -> Option<TruthJson> {
    outcome.truth.as_ref().map(|t| TruthJson {
        coefficients: model_map(&t.model),
        joint_delta_k_t: t.joint.map(|f| f.delta_k_t_rad_s),
        joint_delta_k_dt: t.joint.map(|f| f.delta_k_dt_rad_s),
        seed_delta_k_t: t.seed.map(|f| f.delta_k_t_rad_s),
        seed_delta_k_dt: t.seed.map(|f| f.delta_k_dt_rad_s),
        joint_thermal_error_removed: t.joint_removal.map(|r| r.removed()),
        seed_thermal_error_removed: t.seed_removal.map(|r| r.removed()),
    })
}

fn window_json(w: &bench_analysis::calibrate::WindowSummary) -> WindowJson {
    WindowJson {
        label: w.label.clone(),
        kind: match w.kind {
            WindowKind::Plateau => "plateau",
            WindowKind::Ramp => "ramp",
            WindowKind::Static => "static",
        },
        samples: w.samples,
        mean_temperature: w.mean_temp_c,
        mean_table_rate: w.mean_table_rate_rad_s,
    }
}

fn excluded_json(x: &super::windows::WindowExclusion) -> ExcludedJson {
    ExcludedJson {
        step: x.label.clone(),
        start: x.start_s,
        end: x.end_s,
        seconds: x.end_s - x.start_s,
        why: x.why.key(),
        samples: x.samples,
    }
}

fn time_base_json(b: &crate::load::TimeBase) -> TimeBaseJson {
    TimeBaseJson {
        topic: b.topic,
        source: b.source.key(),
        drift_ppm: b.fit.filter(|_| !counter(b)).map(|f| crate::display::PPM.of(f.rate - 1.0)),
        s_per_count: b.fit.filter(|_| counter(b)).map(|f| f.rate),
        jitter: b.fit.map(|f| f.jitter_s),
        max_late: b.fit.map(|f| f.max_late_s),
        late_outliers: b.fit.map(|f| f.outliers),
    }
}

/// Indices (`ModelKey::CALIBRATED` order) of the coefficients estimated, not held.
fn estimated(cal: &bench_analysis::calibrate::Calibration) -> Vec<usize> {
    (0..4).filter(|&j| cal.held[j].is_none()).collect()
}

fn identifiability_json(
    cal: &bench_analysis::calibrate::Calibration,
) -> BTreeMap<String, IdentifiabilityJson> {
    let Ok(d) = &cal.identifiability else { return BTreeMap::new() };
    d.iter()
        .map(|d| {
            (
                d.key.key().to_owned(),
                IdentifiabilityJson {
                    verdict: d.verdict.key(),
                    sigma_bound: Some(d.sigma_bound).filter(|s| s.is_finite()),
                    confounding: Some(d.confounding).filter(|s| s.is_finite()),
                    confounded_with: d.confounded_with.map(|k| k.key()),
                    expected_size: d.expected_size,
                },
            )
        })
        .collect()
}

fn angle_json(
    a: &Result<bench_analysis::angle_fit::AngleFit, bench_analysis::AnalysisError>,
) -> AngleDomainJson {
    let misclosure = a.as_ref().map_or((f64::NAN, f64::NAN), |a| a.misclosure_rms());
    match a {
        Err(e) => AngleDomainJson {
            error: Some(e.to_string()),
            coefficients: BTreeMap::new(),
            whitened_residual_rms: None,
            readings: 0,
            stretches: 0,
            bridged_samples: 0,
            misclosure_rms_before: None,
            misclosure_rms_after: None,
        },
        Ok(a) => AngleDomainJson {
            error: None,
            coefficients: ModelKey::CALIBRATED
                .into_iter()
                .zip(a.estimates())
                .filter(|(_, e)| !e.held)
                .map(|(k, e)| {
                    (
                        k.key().to_owned(),
                        AngleCoefficient { value: e.value, sigma: e.std_err, sigma_bound: e.bound },
                    )
                })
                .collect(),
            whitened_residual_rms: Some(a.whitened_residual_rms).filter(|v| v.is_finite()),
            readings: a.readings,
            stretches: a.stretches,
            bridged_samples: a.bridged_samples,
            misclosure_rms_before: Some(misclosure.0).filter(|v| v.is_finite()),
            misclosure_rms_after: Some(misclosure.1).filter(|v| v.is_finite()),
        },
    }
}

/// Whether a time base is a device's sample counter (its fit is s per count, not a clock's rate).
fn counter(b: &crate::load::TimeBase) -> bool {
    b.source == crate::load::TimeSource::DeviceCounter
}
