//! What the gyro drivers share: link counters, device-sequence gap detection and the sample
//! watchdog.

use std::time::Duration;

use crate::{DeviceError, ErrorKind};

/// Link counters of a gyro driver. Counters only grow.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GyroLinkStats {
    /// Samples returned.
    pub samples: u64,
    /// Frames, lines or words that failed to decode (bad CRC, parity, garbled text) and were
    /// skipped.
    pub corrupt: u64,
    /// CAN frames whose partner (delta angle ↔ housekeeping) never came, skipped.
    pub unpaired: u64,
    /// Samples flagged with a device sequence gap.
    pub seq_gaps: u64,
    /// Samples missing according to the device counter (modulo its width).
    pub missing: u64,
    /// Watchdog timeouts returned.
    pub timeouts: u64,
}

/// Sequence-gap detection for a device counter of `modulus` values, and the device's clock
/// that the counter is: samples since the first, wraps and gaps included.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SeqTracker {
    modulus: u64,
    last: Option<u64>,
    /// Sample periods since the first sample (the counter unwrapped).
    count: u64,
    /// Bench time of the first sample: the device clock's zero on the bench-time scale.
    anchor: Option<Duration>,
}

impl SeqTracker {
    /// A tracker for a counter that wraps at `modulus` (e.g. 128, 2³²).
    pub(crate) fn new(modulus: u64) -> Self {
        Self { modulus: modulus.max(1), last: None, count: 0, anchor: None }
    }

    /// The device's time stamp of the sample last observed, from its counter: the first
    /// sample's arrival (bench time) plus the counted sample periods of `period_s` each. Wraps
    /// of the counter are unwrapped; a silence longer than the counter's range is counted
    /// from `now` (bench time of this sample's arrival) — whole wraps the counter cannot show.
    pub(crate) fn device_time(&mut self, now: Duration, period_s: f64) -> Option<Duration> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return None;
        }
        let anchor = *self.anchor.get_or_insert(now);
        let counted = self.count as f64 * period_s;
        let waited = now.saturating_sub(anchor).as_secs_f64();
        let range = self.modulus as f64 * period_s;
        // Arrival lags the device by latency and jitter (much less than half the range): more
        // than half a range behind arrival means wraps went unseen.
        if waited - counted > 0.5 * range {
            let wraps = ((waited - counted) / range).round() as u64;
            self.count += wraps * self.modulus;
        }
        Some(anchor + Duration::from_secs_f64(self.count as f64 * period_s))
    }

    /// Record `seq`; returns the number of samples missing before it (0 = continuous; the
    /// first sample is never a gap).
    pub(crate) fn observe(&mut self, seq: u64) -> u64 {
        let m = self.modulus;
        let missing = match self.last {
            None => 0,
            Some(last) => {
                let expected = (last % m + 1) % m;
                (seq % m + m - expected) % m
            }
        };
        if self.last.is_some() {
            self.count += 1 + missing;
        }
        self.last = Some(seq % m);
        missing
    }
}

/// The clock of a device with no counter and no time stamp that sends at a fixed output rate
/// (KVH DSP-3000): frames counted since the first, at `period_s` each, with the frames the host
/// never saw counted too.
///
/// A frame that arrived damaged is counted by the caller ([`FixedRateClock::lost`]): one
/// garbled line or word is one frame. A frame that never arrived is recognised from the arrival
/// times: each sample's lag, arrival − (first arrival + count·period), is latency plus jitter,
/// and its minimum over a window of [`FixedRateClock::WINDOW_S`] is the latency alone. A host
/// hiccup delays samples that then arrive in a burst (the next window's minimum is back down);
/// a lost frame raises every later lag by a period (the minimum steps up and stays). A window
/// whose minimum stepped up by k periods (within a quarter period) over the last one counts k
/// lost frames — but only when the minima resolve a period: the steps of the last windows
/// must lie within a tenth of a period of whole periods (median; host jitter and the device's
/// drift move them off). The loss is placed at the end of the window that showed it: up to two
/// windows of samples before it are stamped k periods early.
#[derive(Debug, Clone)]
pub(crate) struct FixedRateClock {
    period_s: f64,
    /// Bench time of the first sample: the device clock's zero.
    anchor: Option<Duration>,
    /// Periods since the first sample, lost frames included.
    count: u64,
    /// Frames in the current window so far, and the smallest lag among them, s.
    in_window: u64,
    window_min_s: f64,
    /// The last window's smallest lag, s.
    last_min_s: Option<f64>,
    /// How far the last windows' steps of the smallest lag were from whole periods, s (at most
    /// [`Self::HISTORY`]).
    steps_s: std::collections::VecDeque<f64>,
}

impl FixedRateClock {
    /// Length of a window, s of bench time (at least 10 frames).
    pub(crate) const WINDOW_S: f64 = 0.5;
    /// Windows of history judged before a step is believed.
    const HISTORY: usize = 8;
    const MIN_HISTORY: usize = 3;

    /// A clock of `period_s` per frame.
    pub(crate) fn new(period_s: f64) -> Self {
        Self {
            period_s,
            anchor: None,
            count: 0,
            in_window: 0,
            window_min_s: f64::INFINITY,
            last_min_s: None,
            steps_s: std::collections::VecDeque::new(),
        }
    }

    fn window_frames(&self) -> u64 {
        ((Self::WINDOW_S / self.period_s).round() as u64).max(10)
    }

    /// `n` frames the device sent that arrived damaged (counted, never seen as samples).
    pub(crate) fn lost(&mut self, n: u64) {
        if self.anchor.is_some() {
            self.count += n;
        }
    }

    /// A sample arrived at bench time `now`: its device time (the first arrival plus the
    /// periods counted) and the frames found lost before it by their arrival times.
    pub(crate) fn sample(&mut self, now: Duration) -> (Duration, u64) {
        let Some(anchor) = self.anchor else {
            self.anchor = Some(now);
            return (now, 0);
        };
        let p = self.period_s;
        self.count += 1;
        let lag = now.as_secs_f64() - anchor.as_secs_f64() - self.count as f64 * p;
        self.window_min_s = self.window_min_s.min(lag);
        self.in_window += 1;
        let mut missing = 0;
        if self.in_window >= self.window_frames() {
            let min = self.window_min_s;
            if let Some(last) = self.last_min_s {
                let step = min - last;
                let k = (step / p).round();
                let off = (step - k * p).abs();
                let mut sorted: Vec<f64> = self.steps_s.iter().copied().collect();
                sorted.sort_by(f64::total_cmp);
                let quiet = sorted.len() >= Self::MIN_HISTORY
                    && sorted.get(sorted.len() / 2).is_some_and(|m| *m < 0.1 * p);
                if k >= 1.0 && off <= 0.25 * p && quiet {
                    missing = k as u64;
                    self.count += missing;
                }
                self.steps_s.push_back(off);
                if self.steps_s.len() > Self::HISTORY {
                    self.steps_s.pop_front();
                }
            }
            self.last_min_s = Some(min - missing as f64 * p);
            self.in_window = 0;
            self.window_min_s = f64::INFINITY;
        }
        (anchor + Duration::from_secs_f64(self.count as f64 * p), missing)
    }

    /// Periods counted since the first frame (the sample counter `seq`).
    pub(crate) fn count(&self) -> u64 {
        self.count
    }
}

/// The sample watchdog: no sample within `periods` sample periods (bench time) is a timeout.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Watchdog {
    pub(crate) periods: f64,
    /// Bench time of the last sample (or of the open, or of the last timeout).
    pub(crate) last: Duration,
}

impl Watchdog {
    /// The deadline for the next sample at `rate_hz`.
    pub(crate) fn deadline(&self, rate_hz: f64) -> Duration {
        let period = if rate_hz > 0.0 { 1.0 / rate_hz } else { 1.0 };
        self.last + Duration::from_secs_f64((self.periods * period).clamp(0.0, 1e6))
    }

    /// The timeout error (and restart the watchdog at `now`).
    pub(crate) fn expired(&mut self, now: Duration, rate_hz: f64, what: &str) -> DeviceError {
        let waited = now.saturating_sub(self.last);
        self.last = now;
        DeviceError::new(
            ErrorKind::Timeout,
            format!(
                "{what}: no gyro sample within {} sample periods at {rate_hz} Hz ({:.3} s bench time)",
                self.periods,
                waited.as_secs_f64()
            ),
        )
    }
}

pub(crate) fn default_watchdog_periods() -> f64 {
    10.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Arrivals of frames `0..n` at 100 Hz (`lost` never sent), each `latency(k)` late, through
    /// a [`FixedRateClock`]: (count, device time s, missing) per sample.
    fn arrivals(
        n: u64,
        lost: &[u64],
        drift: f64,
        latency: impl Fn(u64) -> f64,
    ) -> Vec<(u64, f64, u64)> {
        let mut c = FixedRateClock::new(0.01);
        (0..n)
            .filter(|k| !lost.contains(k))
            .map(|k| {
                let t = 100.0 + k as f64 * 0.01 * (1.0 + drift) + latency(k);
                let (dev, missing) = c.sample(Duration::from_secs_f64(t));
                (c.count(), dev.as_secs_f64(), missing)
            })
            .collect()
    }

    /// Host latency: 2 ms, up to 1.5 ms of jitter, and every 3 s a 45 ms hiccup whose samples
    /// then arrive together.
    fn busy_host(k: u64) -> f64 {
        let jitter = 0.0015 * ((k * 7919 % 101) as f64 / 100.0);
        let hiccup = if k % 300 < 5 { 0.045 - 0.01 * (k % 300) as f64 } else { 0.0 };
        0.002 + jitter + hiccup
    }

    #[test]
    fn a_fixed_rate_clock_counts_no_loss_through_jitter_hiccups_and_drift() {
        for drift in [0.0, 100e-6, -100e-6] {
            let got = arrivals(6000, &[], drift, busy_host);
            assert!(got.iter().all(|g| g.2 == 0), "drift {drift}: a phantom loss");
            assert_eq!(got.last().map(|g| g.0), Some(5999));
        }
    }

    #[test]
    fn a_fixed_rate_clock_counts_frames_that_never_arrived() {
        // Frames 1000–1002 and 4000 never arrive.
        let got = arrivals(6000, &[1000, 1001, 1002, 4000], 0.0, busy_host);
        let found: Vec<(usize, u64)> =
            got.iter().enumerate().filter(|(_, g)| g.2 > 0).map(|(i, g)| (i, g.2)).collect();
        assert_eq!(found.iter().map(|f| f.1).collect::<Vec<_>>(), [3, 1], "{found:?}");
        // Recognised within two windows (100 samples) of the loss.
        assert!((1000..1100).contains(&found[0].0) && (3997..4097).contains(&found[1].0));
        // From there on the count is the device's: sample i (i ≥ 4100) is frame i + 4.
        let first = got[0].1;
        for (i, g) in got.iter().enumerate().skip(4100) {
            assert_eq!(g.0, i as u64 + 4);
            assert!((g.1 - first - g.0 as f64 * 0.01).abs() < 1e-9);
        }
    }

    #[test]
    fn a_fixed_rate_clock_does_not_guess_when_the_host_cannot_resolve_a_period() {
        // A latency floor wandering over 30 ms against a 10 ms period (a simulator run at 10×
        // on a loaded host): the minima's steps are not whole periods, nothing is counted.
        let wander = |k: u64| {
            0.03 * (k as f64 * 0.013).sin().abs() + 0.003 * ((k * 7919 % 101) as f64 / 100.0)
        };
        let got = arrivals(6000, &[2000], 0.0, wander);
        assert!(got.iter().all(|g| g.2 == 0));
        // 30 ms of jitter over a floor every window touches does resolve the period.
        let floored = |k: u64| 0.03 * ((k * 7919 % 101) as f64 / 100.0);
        let got = arrivals(6000, &[2000], 0.0, floored);
        assert_eq!(got.iter().map(|g| g.2).sum::<u64>(), 1);
        // Damaged frames the decoder saw are counted whatever the jitter.
        let mut c = FixedRateClock::new(0.01);
        c.sample(Duration::from_secs(1));
        c.lost(2);
        c.sample(Duration::from_millis(1030));
        assert_eq!(c.count(), 3);
    }

    #[test]
    fn gaps_are_counted_modulo_the_counter_width() {
        let mut t = SeqTracker::new(128);
        assert_eq!(t.observe(126), 0);
        assert_eq!(t.observe(127), 0);
        assert_eq!(t.observe(0), 0);
        assert_eq!(t.observe(3), 2);
        let mut t = SeqTracker::new(1 << 32);
        assert_eq!(t.observe(u64::from(u32::MAX)), 0);
        assert_eq!(t.observe(0), 0);
        assert_eq!(t.observe(5), 4);
    }

    #[test]
    fn the_counter_is_a_clock_through_wraps_gaps_and_long_silences() {
        let ms = Duration::from_millis;
        let mut t = SeqTracker::new(128);
        t.observe(120);
        // Anchored at the first arrival, 3 ms late.
        assert_eq!(t.device_time(ms(1003), 0.05), Some(ms(1003)));
        t.observe(121);
        assert_eq!(t.device_time(ms(1060), 0.05), Some(ms(1053)));
        // Through the wrap, two samples lost: 124 periods after the first.
        t.observe(0);
        t.observe(3);
        assert_eq!(t.observe(4), 0);
        assert_eq!(t.device_time(ms(1003 + 12 * 50 + 7), 0.05), Some(ms(1003 + 12 * 50)));
        // Silent for 2 wraps and 10 samples (2·128 + 10 periods), the counter shows only 10.
        t.observe(14);
        let got = t.device_time(ms(1003 + (12 + 266) * 50 + 4), 0.05);
        assert_eq!(got, Some(ms(1003 + (12 + 266) * 50)));
        // No period: no clock.
        assert_eq!(t.device_time(ms(0), 0.0), None);
    }
}
