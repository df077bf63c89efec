//! Acceptance: each calibrated coefficient against the limit the recording carries for it
//! (`bench.acceptance`, the limit on |coefficient|, SI, units in the key names), with its
//! uncertainty — what a test record's pass/fail line says.
//!
//! A coefficient with a 1σ standard error σ **passes** when |value| + 2σ ≤ limit, **fails**
//! when |value| − 2σ > limit, and is **inconclusive** in between (the data cannot tell at
//! ≈ 95 %). A noise term (ARW, bias instability) is judged the same way on its confidence
//! interval: passes when its upper end is within the limit, fails when its lower end is beyond.
//! A limit for a coefficient the calibration did not estimate (held: the run does not determine
//! it) is `not_estimated`. The run
//! passes when every limit passes.

use std::collections::BTreeMap;

use bench_physics::ModelKey;
use serde::Serialize;

use crate::calibrate::CalibrationOutcome;

/// Coverage factor of the judgement (≈ 95 % two-sided).
pub const COVERAGE_K: f64 = 2.0;

/// The judgement of one coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Judgement {
    /// Within the limit, with its uncertainty.
    Pass,
    /// Beyond the limit, with its uncertainty.
    Fail,
    /// The limit is within the uncertainty.
    Inconclusive,
    /// The calibration did not estimate this coefficient.
    NotEstimated,
}

impl Judgement {
    /// As written in the JSON and on the terminal.
    pub fn key(self) -> &'static str {
        match self {
            Judgement::Pass => "pass",
            Judgement::Fail => "fail",
            Judgement::Inconclusive => "inconclusive",
            Judgement::NotEstimated => "not_estimated",
        }
    }
}

/// The display unit of a limit's key (`bias_rad_s` → °/h, …); a pure number for an unknown key.
pub fn limit_unit(key: &str) -> crate::display::Unit {
    ModelKey::from_file_key(key).map_or(crate::display::ONE, crate::display::model_key_unit)
}

/// One coefficient against its limit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// The coefficient's key (`bias_rad_s`, …).
    pub key: String,
    /// The limit on |value|, SI.
    pub limit: f64,
    /// The estimate, SI (null when not estimated).
    pub value: Option<f64>,
    /// Its 1σ standard error (null for a noise term or when not estimated).
    pub sigma: Option<f64>,
    /// The interval judged: |value| ∓ 2σ, or a noise term's confidence interval.
    pub interval: Option<(f64, f64)>,
    /// The judgement.
    pub judgement: Judgement,
}

/// Every limit judged, and the run's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Acceptance {
    /// `bench.station` as recorded (unit serial, operator, station).
    pub station: BTreeMap<String, String>,
    /// One check per limit, by key.
    pub checks: Vec<Check>,
    /// `pass` when every check passes, `fail` when any fails, else `inconclusive`.
    pub result: Judgement,
    /// `bench.acceptance` entries that could not be used.
    pub problems: Vec<String>,
}

/// Judge |value| ± k·σ against `limit`.
pub fn judge(value: f64, sigma: f64, limit: f64) -> Judgement {
    if !value.is_finite() {
        return Judgement::NotEstimated;
    }
    let sigma = if sigma.is_finite() { sigma.abs() } else { f64::INFINITY };
    judge_interval(value.abs() - COVERAGE_K * sigma, value.abs() + COVERAGE_K * sigma, limit)
}

/// Judge an interval of |coefficient| against `limit`.
pub fn judge_interval(low: f64, high: f64, limit: f64) -> Judgement {
    if high <= limit {
        Judgement::Pass
    } else if low > limit {
        Judgement::Fail
    } else {
        Judgement::Inconclusive
    }
}

/// The calibration's coefficients against the recording's limits; `None` when the recording
/// carries no `bench.acceptance`.
pub fn judge_calibration(out: &CalibrationOutcome) -> Option<Acceptance> {
    let run = &out.data.run;
    if run.acceptance.is_empty() && run.acceptance_problems.is_empty() {
        return None;
    }
    let cal = &out.calibration;
    let mut checks = Vec::new();
    for (key, &limit) in &run.acceptance {
        let model_key = ModelKey::from_file_key(key);
        let joint = cal
            .joint
            .as_ref()
            .ok()
            .zip(model_key)
            .and_then(|(j, k)| j.estimate(k))
            // A held coefficient was not measured: its limit cannot be judged.
            .filter(|e| !e.held);
        let noise = cal.allan.as_ref().ok().zip(model_key).and_then(|(a, k)| match k {
            ModelKey::Arw => Some(a.fit.arw),
            ModelKey::BiasInstability => Some(a.fit.flicker_floor()),
            _ => None,
        });
        let check = match (joint, noise) {
            (Some(e), _) => {
                let s = e.std_err.abs();
                Check {
                    key: key.clone(),
                    limit,
                    value: Some(e.value),
                    sigma: Some(s),
                    interval: Some((
                        (e.value.abs() - COVERAGE_K * s).max(0.0),
                        e.value.abs() + COVERAGE_K * s,
                    )),
                    judgement: judge(e.value, s, limit),
                }
            }
            (None, Some(n)) => Check {
                key: key.clone(),
                limit,
                value: Some(n.value),
                sigma: None,
                interval: Some((n.low, n.high)),
                judgement: judge_interval(n.low, n.high, limit),
            },
            (None, None) => Check {
                key: key.clone(),
                limit,
                value: None,
                sigma: None,
                interval: None,
                judgement: Judgement::NotEstimated,
            },
        };
        checks.push(check);
    }
    let result = if checks.iter().any(|c| c.judgement == Judgement::Fail) {
        Judgement::Fail
    } else if !checks.is_empty() && checks.iter().all(|c| c.judgement == Judgement::Pass) {
        Judgement::Pass
    } else {
        Judgement::Inconclusive
    };
    Some(Acceptance {
        station: run.station.clone(),
        checks,
        result,
        problems: run.acceptance_problems.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_fail_and_inconclusive_at_two_sigma() {
        assert_eq!(judge(1.0, 0.1, 1.3), Judgement::Pass);
        assert_eq!(judge(-1.0, 0.1, 1.2), Judgement::Pass, "the magnitude is judged");
        assert_eq!(judge(1.0, 0.1, 1.1), Judgement::Inconclusive);
        assert_eq!(judge(1.0, 0.1, 0.9), Judgement::Inconclusive);
        assert_eq!(judge(1.0, 0.1, 0.7), Judgement::Fail);
        assert_eq!(judge(1.0, f64::NAN, 10.0), Judgement::Inconclusive, "no σ, no pass");
        assert_eq!(judge(f64::NAN, 0.1, 1.0), Judgement::NotEstimated);
        assert_eq!(judge_interval(0.5, 0.9, 1.0), Judgement::Pass);
        assert_eq!(judge_interval(1.1, 1.5, 1.0), Judgement::Fail);
        assert_eq!(judge_interval(0.9, 1.1, 1.0), Judgement::Inconclusive);
    }
}
