//! What a calibration determined and what it held, said plainly: for each coefficient the run
//! does not determine ([`bench_analysis::information`]), why, in the report's units, and the
//! run that would determine it — the same sentences on the terminal, in the JSON, in
//! `calibration.toml` and in the report.

use bench_analysis::calibrate::{Calibration, HeldCoefficient};
use bench_analysis::information::{Determination, Verdict, CONFOUNDED, DETECTABLE_SIGMAS};
use bench_physics::ModelKey;
use serde::Serialize;

use crate::display::{self, coefficient_unit, si_value};

/// Why the run does not determine `d`'s coefficient, in report units.
pub fn reason(d: &Determination) -> String {
    let unit = coefficient_unit(d.key).unwrap_or(display::ONE);
    match d.verdict {
        Verdict::Determined => "determined".into(),
        Verdict::NotExcited => format!(
            "nothing in this run excites it: {} in every record window",
            match d.key {
                ModelKey::TempRateCoeff => "the temperature does not change",
                ModelKey::ScaleFactorError => "the table does not turn",
                ModelKey::TempCoeff => "the temperature stays at T0",
                _ => "its regressor is zero",
            }
        ),
        Verdict::Confounded => format!(
            "{:.1} % of its information is shared with {} (above {:.0} %): this run cannot tell \
             them apart",
            100.0 * d.confounding,
            d.confounded_with.map_or("the thermal lag", |k| k.key()),
            100.0 * CONFOUNDED
        ),
        Verdict::TooSmall => format!(
            "its σ on this run's design would be {} against an expected size of {} — {:.2}σ, \
             below the {DETECTABLE_SIGMAS:.2}σ a run needs to tell it from zero",
            si_value(unit, d.sigma_bound, 2),
            si_value(unit, d.expected_size.unwrap_or(f64::NAN), 3),
            d.expected_size.unwrap_or(f64::NAN) / d.sigma_bound
        ),
    }
}

/// The run that would determine `d`'s coefficient.
pub fn determination(d: &Determination) -> String {
    let what = match d.key {
        ModelKey::TempRateCoeff => {
            "record windows while the chamber ramps, the table turning both ways (e.g. \
             scenarios/thermal-short.toml's ±2 °C/min sweeps)"
        }
        ModelKey::ScaleFactorError => "record windows with the table turning CW and CCW",
        ModelKey::TempCoeff => "record windows at temperatures spread over the working range",
        _ => "record windows of the gyro on the table",
    };
    if d.information_short_by.is_finite() {
        format!(
            "{what}: about {}× the information on it this run holds (its σ scales as one over \
             the square root)",
            display::sig(d.information_short_by, 2)
        )
    } else {
        what.into()
    }
}

/// A held coefficient, for the JSON and the calibration file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldJson {
    /// The value used, the contract's unit.
    pub value: f64,
    /// Its 1σ when stated (a prior's), else null (a nominal value, taken as exact).
    pub sigma: Option<f64>,
    /// `prior`, `nominal` or `none` (held at 0).
    pub source: &'static str,
    /// `not_excited`, `confounded` or `too_small`.
    pub verdict: &'static str,
    /// Why, in words.
    pub reason: String,
    /// The run that would determine it.
    pub determination: String,
    /// Its Cramér–Rao σ on this run's design (null when not excited or confounded outright).
    pub sigma_bound: Option<f64>,
    /// Its expected size, when known.
    pub expected_size: Option<f64>,
}

/// `h` as JSON.
pub fn held_json(h: &HeldCoefficient) -> HeldJson {
    let d = &h.determination;
    HeldJson {
        value: h.value,
        sigma: (h.sigma > 0.0).then_some(h.sigma),
        source: h.source.key(),
        verdict: d.verdict.key(),
        reason: reason(d),
        determination: determination(d),
        sigma_bound: Some(d.sigma_bound).filter(|s| s.is_finite()),
        expected_size: d.expected_size,
    }
}

/// Every held coefficient of `cal`, with its key.
pub fn held(cal: &Calibration) -> Vec<(ModelKey, &HeldCoefficient)> {
    ModelKey::CALIBRATED
        .into_iter()
        .zip(&cal.held)
        .filter_map(|(k, h)| h.as_ref().map(|h| (k, h)))
        .collect()
}

/// One terminal line per held coefficient: `HELD key at value (source): reason; determined by …`.
pub fn lines(cal: &Calibration) -> Vec<String> {
    held(cal)
        .into_iter()
        .map(|(k, h)| {
            let unit = coefficient_unit(k).unwrap_or(display::ONE);
            let value = if h.sigma > 0.0 {
                display::si_value_sigma(unit, h.value, h.sigma)
            } else {
                si_value(unit, h.value, 4)
            };
            format!(
                "HELD {} at {value} ({}), not estimated: {}; the run that would determine it: {}",
                k.key(),
                match h.source {
                    bench_analysis::calibrate::ExpectedSource::Prior => "the prior given",
                    bench_analysis::calibrate::ExpectedSource::Nominal => "the nominal model",
                    bench_analysis::calibrate::ExpectedSource::None => "no nominal value: 0",
                },
                reason(&h.determination),
                determination(&h.determination)
            )
        })
        .collect()
}
