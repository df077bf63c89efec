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
