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
//! for bin means. Bins end at data gaps. Lost samples leave holes that no sample covers: a
//! bin's gyro mean is over the covered time, and so is its reference — the holes' increments
//! of the steady line they lie on are taken out. Across a rate change that matters: one lost
//! 50 ms in a 10 s bin that holds a 10 °/min reversal moves the mean rate over the whole span
//! by up to 1.4e-5 rad/s against the covered one. A hole inside the change itself, where no
//! line holds, leaves the bin out. Averaging removes the table's rate ripple (16 cycles
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

/// A step between samples beyond this many median intervals is a gap: bins end there.
pub const GAP: f64 = 2.5;
/// A step beyond this many median intervals has lost samples: the next one covers only its own
/// interval.
pub const LOST: f64 = 1.5;

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
            let gap = step > GAP * nominal_dt;
            gap_before.push(gap);
            // A sample is the mean over its own interval: after lost samples (or a gap) it
            // covers one nominal interval, and the lost ones' stay uncovered ([`make_bins`]).
            dt.push(if step > LOST * nominal_dt { nominal_dt } else { step });
        }
        let air_c: Vec<f64> =
            t.iter().map(|&x| interp(&run.chamber_time_s, &run.chamber_temp_c, x)).collect();
        let (temp_c, temp_rate_c_s) = match &run.gyro_temp_c {
            Some(g) => (g.clone(), local_linear_rate(&t, g, TEMP_RATE_WINDOW_S)?),
            None => coil_temperature(&t, &air_c, lag_s)?,
        };
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

/// Spacing of the points the coil temperature's rate is regressed on, s ([`coil_temperature`]).
pub const COIL_RATE_GRID_S: f64 = 0.5;

/// A gyro without its own sensor: its coil's temperature at times `t` (s), behind the chamber
/// air `air_c` (°C) through a first-order lag of `lag_s`, and that temperature's rate (°C/s,
/// local linear regression over [`TEMP_RATE_WINDOW_S`]) — what the model is driven by.
///
/// The lag's output is smooth (no readout steps: the lag has spread them), so away from the
/// run's ends its rate is regressed on its samples every [`COIL_RATE_GRID_S`] (120 per window)
/// and interpolated back: the same regression to well within the error the chamber's readout
/// steps leave in it, for a fraction of its cost (the diagnosis computes it at every lag it
/// tries, on every gyro sample).
pub fn coil_temperature(
    t: &[f64],
    air_c: &[f64],
    lag_s: f64,
) -> Result<(Vec<f64>, Vec<f64>), AnalysisError> {
    let temp_c = lag_temperature(t, air_c, lag_s);
    let n = t.len();
    let span = if n > 1 { t[n - 1] - t[0] } else { 0.0 };
    let stride = if span > 0.0 {
        ((COIL_RATE_GRID_S * (n - 1) as f64 / span).floor() as usize).max(1)
    } else {
        1
    };
    // Within a window of either end the regression is one-sided and sensitive to the lag's
    // start-up curvature: there it runs on every sample (over the samples its windows reach).
    let (w, half) = (TEMP_RATE_WINDOW_S, TEMP_RATE_WINDOW_S / 2.0);
    if stride == 1 || span <= 4.0 * w {
        let rate_c_s = local_linear_rate(t, &temp_c, w)?;
        return Ok((temp_c, rate_c_s));
    }
    let tg: Vec<f64> = t.iter().step_by(stride).copied().collect();
    let yg: Vec<f64> = temp_c.iter().step_by(stride).copied().collect();
    let rg = local_linear_rate(&tg, &yg, w)?;
    let mut rate_c_s = crate::interp::interp_at(&tg, &rg, t);
    let head = t.partition_point(|&x| x < t[0] + w);
    let head_reach = t.partition_point(|&x| x <= t[head.saturating_sub(1)] + half);
    let exact = local_linear_rate(&t[..head_reach], &temp_c[..head_reach], w)?;
    rate_c_s[..head].copy_from_slice(&exact[..head]);
    let tail = t.partition_point(|&x| x <= t[n - 1] - w);
    let tail_reach = t.partition_point(|&x| x < t[tail] - half);
    let exact = local_linear_rate(&t[tail_reach..], &temp_c[tail_reach..], w)?;
    rate_c_s[tail..].copy_from_slice(&exact[tail - tail_reach..]);
    Ok((temp_c, rate_c_s))
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
    /// Table input over the bin's covered time from the fitted angle, rad/s (table frame, not
    /// axis-signed).
    pub table_rate_rad_s: f64,
    /// Change of the fitted table rate across the bin divided by its covered time, rad/s²: the
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
            let s0 = motion.segment_index_at(start);
            let s1 = motion.segment_index_at(t_end);
            // Intervals no sample covers (samples lost before one of the bin's): the gyro's mean
            // is over the covered time, so the reference must be too. A hole inside one steady
            // segment takes that line's increment out; a hole where no line holds (inside a
            // rate change) leaves the covered increment unknown, and the bin out.
            let mut hole_angle = 0.0;
            let mut hole_s = 0.0;
            let mut known = true;
            for j in first + 1..end {
                let (h0, h1) = (native.t[j - 1], native.t[j] - native.dt[j]);
                if h1 <= h0 + 1e-9 {
                    continue;
                }
                let same = matches!(
                    (motion.segment_index_at(h0), motion.segment_index_at(h1)),
                    (Some(x), Some(y)) if x == y
                );
                match (same, motion.angle(h0), motion.angle(h1)) {
                    (true, Some(b0), Some(b1)) => {
                        hole_angle += b1 - b0;
                        hole_s += h1 - h0;
                    }
                    _ => known = false,
                }
            }
            let covered = t_end - start - hole_s;
            if !known || covered <= 0.0 {
                k = end;
                continue;
            }
            let (r0, r1) = (motion.rate(start).unwrap_or(0.0), motion.rate(t_end).unwrap_or(0.0));
            bins.push(Bin {
                first,
                end,
                start_s: start,
                end_s: t_end,
                table_rate_rad_s: (a1 - a0 - hole_angle) / covered,
                table_accel_rad_s2: (r1 - r0) / covered,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::steady::TableSegment;

    /// The coil's rate regressed on its samples every half second is the full-rate regression
    /// to 5 % of what the chamber's 0.1 °C readout steps alone may move it by (median 1e-4 of
    /// it), and the full regression's own within a window of either end (the temperature is
    /// the lag's, untouched): a 20 Hz gyro for 3 h behind air read at 1 Hz in 0.1 °C steps,
    /// ramping at ±2 °C/min between holds, at the shortest lag the search tries and two longer.
    #[test]
    fn the_coils_rate_on_a_half_second_grid_is_the_full_rate_regression() {
        let t: Vec<f64> = (1..=20 * 3 * 3600).map(|k| k as f64 * 0.05).collect();
        let profile = |x: f64| {
            let p = x % 3600.0;
            let ramp = 2.0 / 60.0;
            if p < 900.0 {
                20.0 + ramp * p
            } else if p < 1800.0 {
                50.0
            } else if p < 2700.0 {
                50.0 - ramp * (p - 1800.0)
            } else {
                20.0
            }
        };
        // The chamber's 1 Hz readings in 0.1 °C steps, interpolated at the gyro's samples (as
        // `Native::build` does).
        let (rt, rv): (Vec<f64>, Vec<f64>) =
            (0..=3 * 3600).map(|k| (k as f64, (profile(k as f64) * 10.0).round() / 10.0)).unzip();
        let air = crate::interp::interp_at(&rt, &rv, &t);
        // What the chamber's 0.1 °C readout steps alone may move a regressed rate by.
        let bound = crate::temperature_rate::quantisation_rate_bound(0.1, TEMP_RATE_WINDOW_S);
        for lag_s in [30.0, 100.0, 400.0] {
            let (temp, rate) = coil_temperature(&t, &air, lag_s).expect("computes");
            assert_eq!(temp, lag_temperature(&t, &air, lag_s));
            let full = local_linear_rate(&t, &temp, TEMP_RATE_WINDOW_S).expect("computes");
            let mut diff: Vec<f64> = rate.iter().zip(&full).map(|(a, b)| (a - b).abs()).collect();
            // Within a window (60 s, 1199 samples) of either end, the full regression's own
            // (the tail's to rounding: its sums are refreshed at other samples).
            let m = diff.len();
            assert!(diff[..1199].iter().all(|&d| d == 0.0), "head");
            assert!(diff[m - 1199..].iter().all(|&d| d < 1e-15), "tail");
            diff.sort_by(f64::total_cmp);
            let (median, worst) = (diff[diff.len() / 2], diff[diff.len() - 1]);
            assert!(worst < 0.05 * bound, "lag {lag_s} s: worst {worst:e} °C/s, bound {bound:e}");
            assert!(median < 1e-4 * bound, "lag {lag_s} s: median {median:e} °C/s");
        }
    }

    const W: f64 = 2.908_882_086_657_216e-3; // 10 °/min, rad/s

    /// CW at 10 °/min until 99.5 s, a reversal, CCW from 100.5 s; the gyro at 20 Hz from 0 to
    /// 200 s without the samples ending at `lost`.
    fn reversal(lost: &[f64]) -> (Native, TableMotion) {
        let seg = |start_s: f64, end_s: f64, angle0_rad: f64, rate: f64| TableSegment {
            start_s,
            end_s,
            angle0_rad,
            rate_rad_s: rate,
            command_rad_s: rate,
            scatter_rad: 0.0,
            readings: 1000,
            rate_sigma_rad_s: 0.0,
        };
        let motion = TableMotion {
            segments: vec![seg(0.0, 99.5, 0.0, -W), seg(100.5, 200.0, -99.5 * W, W)],
            ..TableMotion::default()
        };
        let t: Vec<f64> = (1..=4000)
            .map(|i| f64::from(i) * 0.05)
            .filter(|t| !lost.iter().any(|l| (t - l).abs() < 1e-6))
            .collect();
        let n = t.len();
        let mut dt = vec![0.05; n];
        let mut gap_before = vec![false; n];
        gap_before[0] = true;
        for k in 1..n {
            // As Native::build: a step over LOST intervals covers one nominal interval.
            if t[k] - t[k - 1] > LOST * 0.05 {
                dt[k] = 0.05;
            }
            gap_before[k] = t[k] - t[k - 1] > GAP * 0.05;
        }
        let z = vec![0.0; n];
        let native = Native {
            t,
            dt,
            gap_before,
            v: z.clone(),
            temp_c: z.clone(),
            temp_rate_c_s: z.clone(),
            air_c: z.clone(),
            angle_mid_rad: z.clone(),
            table_rate_rad_s: z,
        };
        (native, motion)
    }

    fn reversal_bin(bins: &[Bin]) -> Option<&Bin> {
        bins.iter().find(|b| b.transition)
    }

    #[test]
    fn a_bin_across_a_reversal_takes_its_reference_over_the_covered_time() {
        // Whole: the bin 90..100.5 s, its increment from the two lines.
        let (native, motion) = reversal(&[]);
        let bins = make_bins(&native, &motion, 10.0);
        let b = reversal_bin(&bins).expect("the reversal's bin");
        assert!((b.start_s - 90.0).abs() < 1e-9 && (b.end_s - 100.5).abs() < 1e-9, "{b:?}");
        let (a0, a1) = (-90.0 * W, -99.5 * W);
        assert!((b.table_rate_rad_s - (a1 - a0) / 10.5).abs() < 1e-15, "{b:?}");
        assert!((b.table_accel_rad_s2 - 2.0 * W / 10.5).abs() < 1e-15, "{b:?}");

        // The sample ending at 95 s lost (CW at −W over 94.95..95): the gyro covers 10.45 s,
        // and its mean over them is (a1 − a0 + W·0.05)/10.45, not (a1 − a0)/10.5.
        let (native, motion) = reversal(&[95.0]);
        let bins = make_bins(&native, &motion, 10.0);
        let b = reversal_bin(&bins).expect("the reversal's bin");
        let want = (a1 - a0 + W * 0.05) / 10.45;
        assert!((b.table_rate_rad_s - want).abs() < 1e-15, "{} vs {want}", b.table_rate_rad_s);
        // The whole span's mean is off by 1.3e-6 rad/s (up to W·h/S = 1.4e-5 in a bin centred
        // on the reversal): the error bins used to make, 100 times a quiet FOG's bin noise.
        assert!(((a1 - a0) / 10.5 - want).abs() > 1.2e-6);
        assert!((b.table_accel_rad_s2 - 2.0 * W / 10.45).abs() < 1e-15, "{b:?}");

        // Lost inside the reversal (no line holds there): the bin is left out.
        let (native, motion) = reversal(&[100.0]);
        let bins = make_bins(&native, &motion, 10.0);
        assert!(reversal_bin(&bins).is_none(), "{bins:?}");
        // In a steady bin a hole changes nothing: the covered mean is the line's rate.
        let (native, motion) = reversal(&[45.0]);
        let bins = make_bins(&native, &motion, 10.0);
        let b = bins.iter().find(|b| b.start_s < 45.0 && b.end_s > 45.0).expect("bin");
        assert!((b.table_rate_rad_s + W).abs() < 1e-15, "{b:?}");
    }
}
