//! The whole run as arrays, and its reduction to time bins.
//!
//! **Table input.** The table reports its angle in encoder steps (1″ on an ST1300), so angle
//! differences over a second are far noisier than the gyro. In rate mode the table turns at a
//! constant rate between commands, so each stretch of constant `rate_command` is fitted with
//! one straight line over its *settled* part (samples whose residual from the line of its
//! second half stays within 5× that half's RMS scatter); between settled
//! parts the table accelerates. The input over a bin is the fitted angle's increment between
//! the bin's edges, and edges are never placed inside an acceleration, so a bin that holds one
//! gets its exact angle increment whatever the acceleration profile.
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
use crate::temperature_rate::local_linear_rate;

/// A stretch of constant commanded table rate, fitted by a line over its settled part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableSegment {
    /// Settled from, s.
    pub start_s: f64,
    /// Settled until, s.
    pub end_s: f64,
    /// Fitted angle at `start_s`, rad.
    pub angle0_rad: f64,
    /// Fitted rate, rad/s.
    pub rate_rad_s: f64,
}

impl TableSegment {
    fn angle(&self, t: f64) -> f64 {
        self.angle0_rad + self.rate_rad_s * (t - self.start_s)
    }
}

/// The table's motion as settled line segments plus its angle ripple (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct TableMotion {
    /// Segments in time order, not overlapping.
    pub segments: Vec<TableSegment>,
    /// Angle ripple as harmonics of the table angle: (cycles per revolution, sin and cos
    /// amplitudes in rad).
    pub ripple: Vec<(u32, f64, f64)>,
}

/// Highest ripple harmonic searched, cycles per revolution.
pub const RIPPLE_MAX_CYCLES: u32 = 64;

impl TableMotion {
    /// Fit the table stream (module docs).
    pub fn fit(time_s: &[f64], angle_rad: &[f64], command: &[f64]) -> TableMotion {
        let n = time_s.len().min(angle_rad.len()).min(command.len());
        let mut segments = Vec::new();
        let mut i0 = 0;
        while i0 < n {
            let mut i1 = i0 + 1;
            while i1 < n && command[i1] == command[i0] {
                i1 += 1;
            }
            if let Some(s) = settled_line(&time_s[i0..i1], &angle_rad[i0..i1]) {
                segments.push(s);
            }
            i0 = i1;
        }
        let ripple = fit_ripple(&segments, time_s, angle_rad);
        TableMotion { segments, ripple }
    }

    fn ripple_angle(&self, theta: f64) -> f64 {
        self.ripple
            .iter()
            .map(|&(k, a, b)| {
                let (s, c) = (f64::from(k) * theta).sin_cos();
                a * s + b * c
            })
            .sum()
    }

    fn ripple_slope(&self, theta: f64) -> f64 {
        self.ripple
            .iter()
            .map(|&(k, a, b)| {
                let kf = f64::from(k);
                let (s, c) = (kf * theta).sin_cos();
                kf * (a * c - b * s)
            })
            .sum()
    }

    /// The segment settled at `t`, if any.
    pub fn segment_at(&self, t: f64) -> Option<&TableSegment> {
        let k = self.segments.partition_point(|s| s.start_s <= t);
        let s = self.segments.get(k.checked_sub(1)?)?;
        (t <= s.end_s).then_some(s)
    }

    /// Fitted angle at `t` (rad), where the table is settled: the line plus the ripple.
    pub fn angle(&self, t: f64) -> Option<f64> {
        self.segment_at(t).map(|s| {
            let line = s.angle(t);
            if s.rate_rad_s == 0.0 {
                line
            } else {
                line + self.ripple_angle(line)
            }
        })
    }

    /// Fitted rate at `t` (rad/s), where the table is settled, ripple included.
    pub fn rate(&self, t: f64) -> Option<f64> {
        self.segment_at(t).map(|s| s.rate_rad_s * (1.0 + self.ripple_slope(s.angle(t))))
    }

    /// Fitted steady rate of the segment at `t` (no ripple), rad/s.
    pub fn steady_rate(&self, t: f64) -> Option<f64> {
        self.segment_at(t).map(|s| s.rate_rad_s)
    }
}

/// Least-squares line `a + b·(t − t0)` over `t`, `y`: (a, b, rms residual).
fn line(t: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = t.len() as f64;
    let t0 = t[0];
    let tm = t.iter().map(|v| v - t0).sum::<f64>() / n;
    let ym = y.iter().sum::<f64>() / n;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (a, b) in t.iter().zip(y) {
        let dx = a - t0 - tm;
        sxx += dx * dx;
        sxy += dx * (b - ym);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let a = ym - slope * tm;
    let rms =
        (t.iter().zip(y).map(|(x, v)| (v - a - slope * (x - t0)).powi(2)).sum::<f64>() / n).sqrt();
    (a, slope, rms)
}

/// The settled part of one constant-command stretch and its line (module docs); `None` when
/// fewer than 8 samples are settled.
fn settled_line(t: &[f64], y: &[f64]) -> Option<TableSegment> {
    let n = t.len();
    if n < 8 {
        return None;
    }
    // Core: the second half (the acceleration is at the start; the end is cut below).
    let core = n / 2;
    let (a, b, rms) = line(&t[core..], &y[core..]);
    let tol = 5.0 * rms + 1e-12;
    let resid = |k: usize| (y[k] - a - b * (t[k] - t[core])).abs();
    // First index from which everything up to the core is within tolerance.
    let mut first = core;
    while first > 0 && resid(first - 1) <= tol {
        first -= 1;
    }
    let mut last = n - 1;
    while last > core && resid(last) > tol {
        last -= 1;
    }
    // Readings quantised to q hide a departure below q/2: the acceleration may still run
    // for a moment after the first reading that sits on the line. Two readings more on each
    // side put the edge safely inside the steady motion.
    let (first, last) = (first + 2, last.saturating_sub(2));
    if last < first + 8 {
        return None;
    }
    let (a, b, _) = line(&t[first..=last], &y[first..=last]);
    Some(TableSegment { start_s: t[first], end_s: t[last], angle0_rad: a, rate_rad_s: b })
}

/// Angle ripple of the rotating segments: the harmonics of the table angle (1 to
/// [`RIPPLE_MAX_CYCLES`] cycles per revolution) whose power in the readings' departure from
/// the segment lines stands above the readings' scatter (χ²₂ at 1e-4 over the harmonics
/// searched), fitted by projection (the harmonics are near-orthogonal over many turns).
fn fit_ripple(segments: &[TableSegment], t: &[f64], y: &[f64]) -> Vec<(u32, f64, f64)> {
    let mut theta = Vec::new();
    let mut resid = Vec::new();
    for s in segments.iter().filter(|s| s.rate_rad_s != 0.0) {
        let a = t.partition_point(|x| *x < s.start_s);
        let b = t.partition_point(|x| *x <= s.end_s);
        for k in a..b {
            let line = s.angle(t[k]);
            theta.push(line);
            resid.push(y[k] - line);
        }
    }
    let n = theta.len();
    if n < 1000 {
        return Vec::new();
    }
    // A harmonic is searched only where the angles covered span two of its cycles.
    let (lo, hi) =
        theta.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    let span_rad = hi - lo;
    let var = resid.iter().map(|r| r * r).sum::<f64>() / n as f64;
    // Power of a harmonic, a² + b², from noise alone: ≈ (2σ²/n)·χ²₂.
    // Floor: 1e-9 rad of ripple is far below any encoder's resolution.
    let threshold =
        (2.0 * var / n as f64 * 2.0 * (f64::from(RIPPLE_MAX_CYCLES) / 1e-4).ln()).max(1e-18);
    // Σ r·sin kθ and Σ r·cos kθ for every k at once: e^{ikθ} by repeated rotation.
    let kmax = RIPPLE_MAX_CYCLES as usize;
    let mut ss = vec![0.0; kmax + 1];
    let mut sc = vec![0.0; kmax + 1];
    for (th, r) in theta.iter().zip(&resid) {
        let (s1, c1) = th.sin_cos();
        let (mut s, mut c) = (s1, c1);
        for k in 1..=kmax {
            ss[k] += r * s;
            sc[k] += r * c;
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        }
    }
    let mut out = Vec::new();
    for k in 1..=RIPPLE_MAX_CYCLES {
        let kf = f64::from(k);
        if kf * span_rad < 2.0 * std::f64::consts::TAU {
            continue;
        }
        let (a, b) = (2.0 * ss[k as usize] / n as f64, 2.0 * sc[k as usize] / n as f64);
        if a * a + b * b > threshold {
            out.push((k, a, b));
        }
    }
    out
}

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
        let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        d.sort_by(f64::total_cmp);
        let nominal_dt = d[d.len() / 2];
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_lines_recover_rates_and_settled_spans_through_quantisation() {
        // 0 → 0.01 rad/s at 0.02 rad/s² from t = 10 s; readings quantised to 5e-6 rad.
        let q = 4.848e-6;
        let dt = 0.05;
        let mut t = Vec::new();
        let mut a = Vec::new();
        let mut c = Vec::new();
        for k in 0..4000 {
            let x = k as f64 * dt;
            let angle = if x < 10.0 {
                0.0
            } else if x < 10.5 {
                0.01 * (x - 10.0).powi(2)
            } else {
                0.0025 + 0.01 * (x - 10.5)
            };
            t.push(x);
            a.push((angle / q).round() * q);
            c.push(if x < 10.0 { 0.0 } else { 0.01 });
        }
        let m = TableMotion::fit(&t, &a, &c);
        assert_eq!(m.segments.len(), 2);
        assert!(m.segments[0].rate_rad_s.abs() < 1e-12);
        assert!((m.segments[1].rate_rad_s - 0.01).abs() < 1e-7, "{:?}", m.segments[1]);
        // Settled after the acceleration ends, within one reading step.
        assert!(m.segments[1].start_s >= 10.45 && m.segments[1].start_s < 10.7);
        // Fitted angle in the acceleration is undefined; after it, the line.
        assert!(m.angle(10.2).is_none());
        assert!((m.angle(100.0).unwrap_or(f64::NAN) - (0.0025 + 0.01 * 89.5)).abs() < 1e-6);
    }
}
