//! Rate of temperature change from quantised readings.
//!
//! Chamber and gyro temperature sensors report in steps (0.1 °C for a typical chamber
//! controller, 0.01 °C for the simulated gyro), so differencing successive readings gives
//! spikes and zeros. The filter here is a **centred local linear regression**: the rate at
//! sample `i` is the least-squares slope of the readings whose time lies within `±W/2` of
//! `t_i` (truncated at the ends of the series). On uniform samples this is the first-derivative
//! Savitzky–Golay filter of order 1 (and, by symmetry, of order 2) over `W` seconds.
//!
//! Cost: O(n) with running sums (refreshed exactly every 1024 samples).
//!
//! Error bound: a reading error bounded by `q/2` (quantisation step `q`) moves the slope over
//! a full window of length `W` by at most `(q/2)·Σ|t−t̄| / Σ(t−t̄)² ≈ 1.5·q/W` (uniform,
//! dense samples), and a constant ramp is reproduced exactly. The filter delays nothing but
//! averages a changing rate over `W`: a rate that changes on a time scale shorter than `W` is
//! smoothed.

use crate::error::AnalysisError;

/// Worst-case slope error (°C/s) of [`local_linear_rate`] over a full window of `window_s`
/// seconds for readings quantised in steps of `quantum_c`: `1.5·q/W`.
pub fn quantisation_rate_bound(quantum_c: f64, window_s: f64) -> f64 {
    1.5 * quantum_c / window_s
}

/// dT/dt (°C/s) at every sample of `temp_c` (°C, sampled at strictly increasing `time_s`, s)
/// by a centred local linear regression over `window_s` seconds (module docs). Windows
/// holding fewer than 3 samples are widened to the nearest 3.
pub fn local_linear_rate(
    time_s: &[f64],
    temp_c: &[f64],
    window_s: f64,
) -> Result<Vec<f64>, AnalysisError> {
    Ok(local_linear(time_s, temp_c, window_s)?.into_iter().map(|(slope, _)| slope).collect())
}

/// The temperature itself (°C) at every sample, smoothed by the same centred local linear
/// regression as [`local_linear_rate`]: the regression line's value there. Quantisation steps
/// of `q` become errors of about `q/√(12·n)` for `n` readings per window, and a ramp is
/// reproduced exactly.
pub fn local_linear_value(
    time_s: &[f64],
    temp_c: &[f64],
    window_s: f64,
) -> Result<Vec<f64>, AnalysisError> {
    Ok(local_linear(time_s, temp_c, window_s)?.into_iter().map(|(_, value)| value).collect())
}

/// [`local_linear_value`] and [`local_linear_rate`] from one pass: the smoothed temperature
/// (°C) and its rate (°C/s) at every sample, the same numbers as the two calls give.
pub fn local_linear_value_and_rate(
    time_s: &[f64],
    temp_c: &[f64],
    window_s: f64,
) -> Result<(Vec<f64>, Vec<f64>), AnalysisError> {
    Ok(local_linear(time_s, temp_c, window_s)?
        .into_iter()
        .map(|(slope, value)| (value, slope))
        .unzip())
}

/// (slope, value) of the centred local linear regression at every sample.
fn local_linear(
    time_s: &[f64],
    temp_c: &[f64],
    window_s: f64,
) -> Result<Vec<(f64, f64)>, AnalysisError> {
    let n = time_s.len();
    if temp_c.len() != n {
        return Err(AnalysisError::LengthMismatch {
            label: "temperature rate".into(),
            array: "temp_c",
            got: temp_c.len(),
            expected: n,
        });
    }
    if n < 3 {
        return Err(AnalysisError::TooFewSamples {
            what: "temperature rate".into(),
            got: n,
            min: 3,
        });
    }
    if !(window_s.is_finite() && window_s > 0.0) {
        return Err(AnalysisError::InvalidParameter {
            name: "window_s",
            value: window_s,
            why: "must be a positive number of seconds",
        });
    }
    let half = window_s / 2.0;
    let mut out = Vec::with_capacity(n);
    let (mut lo, mut hi) = (0usize, 0usize); // window is lo..hi (exclusive)
    let mut sums = WindowSums::default();
    for i in 0..n {
        let t = time_s[i];
        // Refresh the running sums exactly every so often, about the current sample: keeps
        // rounding from accumulating and the sums small (no cancellation).
        if i % 1024 == 0 {
            sums = WindowSums::over(time_s, temp_c, lo, hi, time_s[i], temp_c[i]);
        }
        while time_s[lo] < t - half {
            sums.remove(time_s[lo], temp_c[lo]);
            lo += 1;
        }
        if hi < i + 1 {
            for k in hi..=i {
                sums.add(time_s[k], temp_c[k]);
            }
            hi = i + 1;
        }
        while hi < n && time_s[hi] <= t + half {
            sums.add(time_s[hi], temp_c[hi]);
            hi += 1;
        }
        if hi - lo >= 3 {
            out.push(sums.slope_value(t, temp_c[i]));
        } else {
            // At least 3 samples: widen at whichever side has room.
            let (mut a, mut b) = (lo, hi);
            while b - a < 3 {
                a = a.saturating_sub(1);
                if b - a < 3 && b < n {
                    b += 1;
                }
            }
            let (s, v) = slope_value(&time_s[a..b], &temp_c[a..b], t);
            out.push((s, v));
        }
    }
    Ok(out)
}

/// Running sums of a window's points about an origin `(x0, y0)`.
#[derive(Debug, Default, Clone, Copy)]
struct WindowSums {
    x0: f64,
    y0: f64,
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
}

impl WindowSums {
    fn over(x: &[f64], y: &[f64], lo: usize, hi: usize, x0: f64, y0: f64) -> Self {
        let mut s = Self { x0, y0, ..Self::default() };
        for k in lo..hi {
            s.add(x[k], y[k]);
        }
        s
    }
    fn add(&mut self, x: f64, y: f64) {
        let (dx, dy) = (x - self.x0, y - self.y0);
        self.n += 1.0;
        self.sx += dx;
        self.sy += dy;
        self.sxx += dx * dx;
        self.sxy += dx * dy;
    }
    fn remove(&mut self, x: f64, y: f64) {
        let (dx, dy) = (x - self.x0, y - self.y0);
        self.n -= 1.0;
        self.sx -= dx;
        self.sy -= dy;
        self.sxx -= dx * dx;
        self.sxy -= dx * dy;
    }
    /// Slope, and the line's value at `x` (`y_near`: a reading near it, for a degenerate
    /// window).
    fn slope_value(&self, x: f64, y_near: f64) -> (f64, f64) {
        let vxx = self.sxx - self.sx * self.sx / self.n;
        let vxy = self.sxy - self.sx * self.sy / self.n;
        if vxx > 0.0 {
            let b = vxy / vxx;
            let (xm, ym) = (self.sx / self.n, self.sy / self.n);
            (b, self.y0 + ym + b * (x - self.x0 - xm))
        } else {
            (0.0, y_near)
        }
    }
}

/// Least-squares slope of `y` on `x` and the line's value at `at` (two-pass, centred for
/// precision).
fn slope_value(x: &[f64], y: &[f64], at: f64) -> (f64, f64) {
    let l = crate::stats::line(x.iter().copied().zip(y.iter().copied()));
    (l.slope.unwrap_or(0.0), l.at(at, 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::quantise;

    #[test]
    fn quantised_ramp_slope_is_recovered_within_the_bound() {
        // 1 °C/min ramp read at 20 Hz in 0.1 °C steps: one step every 6 s.
        let dt = 0.05;
        let rate = 1.0 / 60.0;
        let q = 0.1;
        let w = 120.0;
        let t: Vec<f64> = (0..72_000).map(|i| i as f64 * dt).collect();
        let temp: Vec<f64> = t.iter().map(|&t| quantise(-40.0 + 0.0123 + rate * t, q)).collect();
        let est = local_linear_rate(&t, &temp, w).expect("valid input");
        let bound = quantisation_rate_bound(q, w);
        assert!((bound - 1.25e-3).abs() < 1e-12);
        // Full windows only (the ends see half a window).
        let interior = &est[(w / dt) as usize..est.len() - (w / dt) as usize];
        let worst = interior.iter().map(|e| (e - rate).abs()).fold(0.0, f64::max);
        assert!(worst <= bound, "worst {worst} > bound {bound}");
        // The sawtooth error averages well below the worst case: 0.1 °C per 120 s window over
        // 20 steps leaves a few per cent.
        assert!(worst < 0.05 * rate, "worst {worst}");
        // Naive differencing is useless on the same data: 0 or q/dt = 2 °C/s.
        let naive_max = temp.windows(2).map(|w| (w[1] - w[0]) / dt).fold(0.0, f64::max);
        assert!(naive_max > 100.0 * rate);
    }

    #[test]
    fn one_pass_gives_the_value_and_the_rate_of_the_two_calls_bit_for_bit() {
        let t: Vec<f64> =
            (0..3000).map(|i| 1.0e4 + i as f64 * 0.05 + 1e-3 * (i % 7) as f64).collect();
        let temp: Vec<f64> =
            t.iter().map(|&t| quantise(20.0 + 5.0 * (t / 300.0).sin(), 0.01)).collect();
        let (value, rate) = local_linear_value_and_rate(&t, &temp, 30.0).expect("valid");
        assert_eq!(value, local_linear_value(&t, &temp, 30.0).expect("valid"));
        assert_eq!(rate, local_linear_rate(&t, &temp, 30.0).expect("valid"));
        assert!(rate.iter().any(|&r| r != 0.0) && value.iter().any(|&v| v != temp[0]));
    }

    #[test]
    fn exact_ramp_is_exact_even_at_the_ends_and_plateau_is_zero() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.5).collect();
        let ramp: Vec<f64> = t.iter().map(|&t| 3.0 - 0.02 * t).collect();
        for r in local_linear_rate(&t, &ramp, 10.0).expect("valid") {
            assert!((r + 0.02).abs() < 1e-12);
        }
        let flat = vec![25.0; t.len()];
        assert!(local_linear_rate(&t, &flat, 10.0).expect("valid").iter().all(|&r| r == 0.0));
        // A window shorter than the sample spacing is widened to 3 samples, not a 0/0.
        let r = local_linear_rate(&t, &ramp, 0.1).expect("valid");
        assert!((r[0] + 0.02).abs() < 1e-12 && (r[199] + 0.02).abs() < 1e-12);
    }

    #[test]
    fn running_sums_give_the_direct_slope_over_long_irregular_series() {
        // Irregular times far from zero, a wandering signal: every output equals the slope of
        // its window computed directly (the refresh keeps rounding from accumulating).
        let mut t = Vec::new();
        let mut x = 1.0e5;
        for i in 0..5000u64 {
            x += 0.05 + 0.01 * ((i * 37 % 11) as f64 / 11.0);
            t.push(x);
        }
        let y: Vec<f64> =
            t.iter().map(|&t| 20.0 + (t * 0.01).sin() + 1e-3 * (t * 7.0).cos()).collect();
        let w = 3.0;
        let fast = local_linear_rate(&t, &y, w).expect("valid");
        for (i, f) in fast.iter().enumerate() {
            let (a, b) = (
                t.partition_point(|&s| s < t[i] - w / 2.0),
                t.partition_point(|&s| s <= t[i] + w / 2.0),
            );
            let direct = slope_value(&t[a..b], &y[a..b], 0.0).0;
            assert!((f - direct).abs() < 1e-9 * (1.0 + direct.abs()), "{i}: {f} vs {direct}");
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let t = [0.0, 1.0, 2.0];
        assert!(local_linear_rate(&t, &[1.0, 2.0], 1.0).is_err());
        assert!(local_linear_rate(&t[..2], &[1.0, 2.0], 1.0).is_err());
        assert!(local_linear_rate(&t, &[1.0, 2.0, 3.0], 0.0).is_err());
        assert!(local_linear_rate(&t, &[1.0, 2.0, 3.0], f64::NAN).is_err());
    }

    #[test]
    fn smoothed_values_follow_a_quantised_ramp_within_a_fraction_of_a_step() {
        let t: Vec<f64> = (0..12_000).map(|k| k as f64 * 0.05).collect();
        let truth: Vec<f64> = t.iter().map(|x| 20.0 + x / 60.0).collect();
        let q = 0.01;
        let read: Vec<f64> = truth.iter().map(|v| (v / q).round() * q).collect();
        let smooth = local_linear_value(&t, &read, 60.0).expect("valid");
        let worst = smooth.iter().zip(&truth).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        // 1200 readings per window: far below the step (0.01 °C).
        assert!(worst < 0.1 * q, "{worst}");
        let exact = local_linear_value(&t, &truth, 60.0).expect("valid");
        assert!(exact.iter().zip(&truth).all(|(a, b)| (a - b).abs() < 1e-9));
    }
}
