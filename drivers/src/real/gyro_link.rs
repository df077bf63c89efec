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

/// Sequence-gap detection for a device counter of `modulus` values (`None` = no counter).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SeqTracker {
    modulus: u64,
    last: Option<u64>,
}

impl SeqTracker {
    /// A tracker for a counter that wraps at `modulus` (e.g. 128, 2³²).
    pub(crate) fn new(modulus: u64) -> Self {
        Self { modulus: modulus.max(1), last: None }
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
}
