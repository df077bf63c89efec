//! Time from the device where it has one: host stamps mapped onto a device's own clock.
//!
//! A lab's host stamps a sample when it arrives: a constant latency plus a few milliseconds of
//! jitter (far more on a loaded machine, and multiplied by the time scale of a simulated bench
//! run faster than real time). A device that counts its own samples (a FOG's sample counter)
//! or stamps them (a controller's clock) keeps time far better. [`fit_clock`] fits the host
//! stamps as a straight line of the device's time — `host = offset + rate·device` — robustly
//! (a late delivery or a skipped counter does not bend it); the analyses then place every
//! sample at `offset + rate·device`: the host's time axis without its jitter. The residual's
//! robust scatter is the host's jitter, reported beside the fit.

/// A host clock fitted as a line of a device clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockFit {
    /// Host time at device time 0, s.
    pub offset_s: f64,
    /// Host seconds per device second (1 + drift).
    pub rate: f64,
    /// Robust scatter of host stamps about the line (their jitter), s.
    pub jitter_s: f64,
    /// Largest delay of a host stamp behind the line, s.
    pub max_late_s: f64,
    /// Samples fitted (after outliers were set aside).
    pub samples: usize,
    /// Samples set aside as late (beyond 5 scatters of the line).
    pub outliers: usize,
}

impl ClockFit {
    /// Host time of device time `device_s`.
    pub fn host(&self, device_s: f64) -> f64 {
        self.offset_s + self.rate * device_s
    }
}

/// Least-squares line through `(x, y)` over the indices `idx`: (intercept at x = 0, slope).
/// A clock without spread in its device times runs at the host's rate (1).
fn line(x: &[f64], y: &[f64], idx: &[usize]) -> (f64, f64) {
    crate::stats::line(idx.iter().map(|&i| (x[i], y[i]))).intercept_slope(1.0)
}

/// 1.4826 × the median absolute value.
fn mad(mut r: Vec<f64>) -> f64 {
    if r.is_empty() {
        return 0.0;
    }
    r.iter_mut().for_each(|x| *x = x.abs());
    r.sort_by(f64::total_cmp);
    1.4826 * r[r.len() / 2]
}

/// Fit host stamps `host_s` as a line of device times `device_s` (same length, device times
/// increasing), setting aside stamps more than 5 robust scatters off the line (twice). `None`
/// for fewer than 10 samples.
pub fn fit_clock(device_s: &[f64], host_s: &[f64]) -> Option<ClockFit> {
    let n = device_s.len().min(host_s.len());
    if n < 10 {
        return None;
    }
    let mut idx: Vec<usize> = (0..n).collect();
    let (mut a, mut b) = line(device_s, host_s, &idx);
    let mut scatter = 0.0;
    for _ in 0..3 {
        let r: Vec<f64> = (0..n).map(|i| host_s[i] - a - b * device_s[i]).collect();
        scatter = mad(idx.iter().map(|&i| r[i]).collect());
        let limit = 5.0 * scatter.max(1e-12);
        let keep: Vec<usize> = (0..n).filter(|&i| r[i].abs() <= limit).collect();
        if keep.len() < 10 || keep.len() == idx.len() {
            break;
        }
        idx = keep;
        (a, b) = line(device_s, host_s, &idx);
    }
    let max_late_s = (0..n).map(|i| host_s[i] - a - b * device_s[i]).fold(0.0, f64::max);
    Some(ClockFit {
        offset_s: a,
        rate: b,
        jitter_s: scatter,
        max_late_s,
        samples: idx.len(),
        outliers: n - idx.len(),
    })
}

/// Median of the successive differences of `t` (a stream's nominal sample interval, robust to
/// gaps and jitter); `None` with fewer than 2 samples.
pub fn median_interval(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied()
}

/// A device counter unwrapped: each decrease is taken as a wrap of a counter of the smallest
/// power-of-two width that holds the largest value seen. Returns counts from the first.
pub fn unwrap_counter(seq: &[u64]) -> Vec<f64> {
    let max = seq.iter().copied().max().unwrap_or(0);
    let width: u128 =
        if max == u64::MAX { 1u128 << 64 } else { u128::from(max + 1).next_power_of_two() };
    let mut out = Vec::with_capacity(seq.len());
    let mut wraps: u128 = 0;
    for (k, &s) in seq.iter().enumerate() {
        if k > 0 && s < seq[k - 1] {
            wraps += 1;
        }
        let v = wraps * width + u128::from(s);
        out.push(v as f64);
    }
    if let Some(&first) = out.first() {
        out.iter_mut().for_each(|v| *v -= first);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-normal numbers (sum of 12 uniforms − 6).
    fn noise(k: usize) -> f64 {
        let mut x = (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x2545_f491_4f6c_dd1d;
        let mut s = 0.0;
        for _ in 0..12 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            s += (x >> 11) as f64 / (1u64 << 53) as f64;
        }
        s - 6.0
    }

    #[test]
    fn a_jittered_host_clock_is_fitted_to_the_device_clock() {
        // Device at 20 Hz, 5 ppm fast against the host; host stamps 12 ms late with 2 ms of
        // jitter and every 500th stamp 0.3 s late.
        let dev: Vec<f64> = (0..20_000).map(|k| k as f64 * 0.05).collect();
        let host: Vec<f64> = dev
            .iter()
            .enumerate()
            .map(|(k, d)| {
                let late = if k % 500 == 7 { 0.3 } else { 0.0 };
                100.0 + 0.012 + d * (1.0 + 5e-6) + 0.002 * noise(k) + late
            })
            .collect();
        let f = fit_clock(&dev, &host).expect("enough samples");
        assert!((f.rate - (1.0 + 5e-6)).abs() < 2e-7, "{f:?}");
        assert!((f.offset_s - 100.012).abs() < 1e-4, "{f:?}");
        assert!((f.jitter_s / 0.002 - 1.0).abs() < 0.05, "{f:?}");
        assert_eq!(f.outliers, 40, "{f:?}");
        assert!((f.max_late_s - 0.3).abs() < 0.01, "{f:?}");
        assert!(fit_clock(&dev[..5], &host[..5]).is_none());
    }

    #[test]
    fn counters_unwrap_at_their_width() {
        let seq: Vec<u64> = (120..300u64).map(|k| k % 128).collect();
        let u = unwrap_counter(&seq);
        assert!(u.iter().enumerate().all(|(k, v)| *v == k as f64), "{u:?}");
        // A gap stays a gap.
        let u = unwrap_counter(&[5, 6, 9, 10]);
        assert_eq!(u, vec![0.0, 1.0, 4.0, 5.0]);
    }
}
