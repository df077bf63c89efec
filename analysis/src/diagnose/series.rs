//! The whole run as arrays, and its reduction to time bins.
//!
//! **Table input.** The table reports its angle in encoder steps (1″ on an ST1300), so angle
//! differences over a second are far noisier than the gyro. Its steady motion comes from
//! [`crate::steady`] (straight lines over the steady parts of each stretch of constant
//! command, the rule calibration uses too). The input over a bin is the fitted angle's
//! increment between the bin's edges, and edges are never placed inside an acceleration, so a
//! bin that holds one gets its exact angle increment whatever the acceleration profile.
//!
//! **Bins.** Samples are averaged over bins of about `bin_s` seconds (10 s by default): the
//! gyro's mean rate is its angle increment over the bin divided by the bin's span, and every
//! regressor of the linear model is averaged the same way, so the linear model holds exactly
//! for bin means. Bins end at data gaps. Averaging removes the table's rate ripple (16 cycles
//! per revolution, a 2.25 s period at 10 °/min) and keeps everything slower than a bin.

use bench_physics::effects::{lag_temperature, HysteresisState};

use crate::error::AnalysisError;
use crate::interp::interp;
pub use crate::run::{RunSeries, StepSpan};
use crate::steady::TableMotion;
use crate::temperature_rate::local_linear_rate;

/// Per-sample quantities at the gyro's rate that the bins average.
#[derive(Debug, Clone)]
pub struct Native {
    /// Sample end times, s.
    pub t: Vec<f64>,
    /// Sample interval lengths, s.
    pub dt: Vec<f64>,
    /// Whether a sample starts a new contiguous stretch (after a gap).
    pub gap_before: Vec<bool>,
    /// Gyro output, rad/s.
    pub v: Vec<f64>,
    /// Model temperature (sensor, or air through the nominal lag), °C.
    pub temp_c: Vec<f64>,
    /// Its rate, °C/s (local linear regression, [`crate::temperature_rate`]).
    pub temp_rate_c_s: Vec<f64>,
    /// Chamber air at the sample, °C.
    pub air_c: Vec<f64>,
    /// Table angle at the middle of the sample, rad (interpolated readings).
    pub angle_mid_rad: Vec<f64>,
    /// Table rate where settled (the segment's slope), else from the readings, rad/s.
    pub table_rate_rad_s: Vec<f64>,
}

/// Window of the temperature-rate filter, s.
pub const TEMP_RATE_WINDOW_S: f64 = 60.0;

impl Native {
    /// Build the per-sample arrays; `lag_s` is the nominal model's air-to-gyro lag, used when
    /// the gyro has no sensor.
    pub fn build(
        run: &RunSeries,
        motion: &TableMotion,
        lag_s: f64,
    ) -> Result<Native, AnalysisError> {
        let n = run.gyro_time_s.len();
        if n < 100 {
            return Err(AnalysisError::TooFewSamples {
                what: "diagnosis".into(),
                got: n,
                min: 100,
            });
        }
        if run.gyro_rate_rad_s.len() != n {
            return Err(AnalysisError::LengthMismatch {
                label: "gyro".into(),
                array: "gyro_rate_rad_s",
                got: run.gyro_rate_rad_s.len(),
                expected: n,
            });
        }
        if run.table_time_s.len() < 2 || run.chamber_time_s.is_empty() {
            return Err(AnalysisError::Insufficient(
                "diagnosis needs the table and chamber streams (at least 2 table samples)".into(),
            ));
        }
        let t = run.gyro_time_s.clone();
        let nominal_dt = crate::timebase::median_interval(&t).unwrap_or(f64::NAN);
        if nominal_dt.is_nan() || nominal_dt <= 0.0 {
            return Err(AnalysisError::TimeNotIncreasing { label: "gyro".into(), index: 1 });
        }
        let mut dt = Vec::with_capacity(n);
        let mut gap_before = Vec::with_capacity(n);
        for k in 0..n {
            let step = if k == 0 { f64::INFINITY } else { t[k] - t[k - 1] };
            if step <= 0.0 {
                return Err(AnalysisError::TimeNotIncreasing { label: "gyro".into(), index: k });
            }
            let gap = step > 2.5 * nominal_dt;
            gap_before.push(gap);
            dt.push(if gap { nominal_dt } else { step });
        }
        let air_c: Vec<f64> =
            t.iter().map(|&x| interp(&run.chamber_time_s, &run.chamber_temp_c, x)).collect();
        let temp_c = match &run.gyro_temp_c {
            Some(g) => g.clone(),
            None => lag_temperature(&t, &air_c, lag_s),
        };
        let temp_rate_c_s = local_linear_rate(&t, &temp_c, TEMP_RATE_WINDOW_S)?;
        let mut angle_mid_rad = Vec::with_capacity(n);
        let mut table_rate_rad_s = Vec::with_capacity(n);
        for k in 0..n {
            let mid = t[k] - 0.5 * dt[k];
            angle_mid_rad.push(interp(&run.table_time_s, &run.table_angle_rad, mid));
            let rate = motion.rate(mid).unwrap_or_else(|| {
                let a = interp(&run.table_time_s, &run.table_angle_rad, t[k]);
                let b = interp(&run.table_time_s, &run.table_angle_rad, t[k] - dt[k]);
                (a - b) / dt[k]
            });
            table_rate_rad_s.push(rate);
        }
        Ok(Native {
            t,
            dt,
            gap_before,
            v: run.gyro_rate_rad_s.clone(),
            temp_c,
            temp_rate_c_s,
            air_c,
            angle_mid_rad,
            table_rate_rad_s,
        })
    }

    /// The hysteresis state at each sample for threshold `threshold_c_s`.
    pub fn hysteresis(&self, threshold_c_s: f64) -> Vec<f64> {
        HysteresisState::series(threshold_c_s, &self.temp_rate_c_s)
    }
}

/// One time bin: a contiguous run of gyro samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bin {
    /// First sample index.
    pub first: usize,
    /// One past the last sample index.
    pub end: usize,
    /// Start edge (start of the first sample's interval), s.
    pub start_s: f64,
    /// End edge (end of the last sample), s.
    pub end_s: f64,
    /// Table input over the bin from the fitted angle, rad/s (table frame, not axis-signed).
    pub table_rate_rad_s: f64,
    /// Change of the fitted table rate across the bin divided by its span, rad/s²: the
    /// regressor of a time-tag offset (−δ times it is the error).
    pub table_accel_rad_s2: f64,
    /// Whether the table accelerates inside the bin.
    pub transition: bool,
}

impl Bin {
    /// Span, s.
    pub fn span_s(&self) -> f64 {
        self.end_s - self.start_s
    }
    /// Centre, s.
    pub fn centre_s(&self) -> f64 {
        0.5 * (self.start_s + self.end_s)
    }
}

/// Cut the samples into bins of about `bin_s` seconds (module docs). Samples whose interval
/// starts where the table is not settled, after a gap, are skipped until it is.
pub fn make_bins(native: &Native, motion: &TableMotion, bin_s: f64) -> Vec<Bin> {
    let n = native.t.len();
    let mut bins = Vec::new();
    let mut k = 0;
    while k < n {
        let start = native.t[k] - native.dt[k];
        if motion.segment_at(start).is_none() {
            k += 1;
            continue;
        }
        let first = k;
        let mut end = k;
        loop {
            end += 1;
            let t_end = native.t[end - 1];
            let next_gap = end >= n || native.gap_before[end];
            let long_enough = t_end - start >= bin_s - 1e-9;
            if (long_enough && motion.segment_at(t_end).is_some()) || next_gap {
                break;
            }
        }
        let t_end = native.t[end - 1];
        if let (Some(a0), Some(a1)) = (motion.angle(start), motion.angle(t_end)) {
            let s0 = motion.segment_at(start).copied();
            let s1 = motion.segment_at(t_end).copied();
            let span = t_end - start;
            let (r0, r1) = (motion.rate(start).unwrap_or(0.0), motion.rate(t_end).unwrap_or(0.0));
            bins.push(Bin {
                first,
                end,
                start_s: start,
                end_s: t_end,
                table_rate_rad_s: (a1 - a0) / span,
                table_accel_rad_s2: (r1 - r0) / span,
                transition: s0 != s1,
            });
        }
        k = end;
    }
    bins
}

/// Average of `x` over each bin, weighted by the samples' intervals.
pub fn bin_mean(bins: &[Bin], dt: &[f64], mut x: impl FnMut(usize) -> f64) -> Vec<f64> {
    bins.iter()
        .map(|b| {
            let (mut s, mut w) = (0.0, 0.0);
            for (k, d) in dt.iter().enumerate().take(b.end).skip(b.first) {
                s += x(k) * d;
                w += d;
            }
            s / w
        })
        .collect()
}

/// `n` bins of 10 s with one sample each, the table at rest: the tests' time base.
#[cfg(test)]
pub(crate) fn test_bins(n: usize) -> Vec<Bin> {
    (0..n)
        .map(|i| Bin {
            first: i,
            end: i + 1,
            start_s: i as f64 * 10.0,
            end_s: (i + 1) as f64 * 10.0,
            table_rate_rad_s: 0.0,
            table_accel_rad_s2: 0.0,
            transition: false,
        })
        .collect()
}
