//! [`Gyro`] over CAN: bench's own frame set ([`crate::protocol::gyro_can`],
//! `docs/protocols/gyro-can.md`) on any [`CanBus`] (SLCAN adapter or SocketCAN).
//!
//! Each sample is a delta-angle frame and a housekeeping frame paired by sequence number; the
//! rate is the delta angle divided by the sample period (from the info frame once it arrives,
//! the configured rate until then). The driver flags `SEQ_GAP` when the 32-bit device counter
//! skips, counts and skips corrupt lines and unpaired frames (`AFTER_CORRUPT` on the next
//! sample), and returns a `Timeout` error when no sample arrives within
//! [`CanGyroConfig::watchdog_periods`] sample periods of bench time.
//!
//! ```
//! let cfg: bench_drivers::real::gyro_can::CanGyroConfig = toml::from_str(r#"
//!     sample_rate_hz = 20.0
//!     [transport]
//!     kind = "slcan"
//!     serial = { path = "/dev/ttyACM0", baud = 115200 }
//! "#).unwrap();
//! assert_eq!(cfg.watchdog_periods, 10.0);
//! assert_eq!(cfg.ids.delta_angle, 0x180);
//! ```

use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

use super::can::{BusStatus, CanBus};
use super::gyro_link::{default_watchdog_periods, GyroLinkStats, SeqTracker, Watchdog};
use super::slcan::{SlcanBus, SlcanOptions};
use crate::protocol::gyro_can::{GyroCanIds, SampleAssembler};
use crate::protocol::slcan::Bitrate;
use crate::transport::SerialSettings;
use crate::{
    Clock, DeviceError, DeviceInfo, DeviceResult, ErrorKind, Gyro, GyroCapabilities, GyroSample,
};
use bench_recording::status;

/// Which CAN transport the gyro is on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum CanTransport {
    /// A Lawicel SLCAN adapter on a serial port.
    Slcan {
        /// The adapter's serial port (USB CDC adapters ignore the baud rate).
        serial: SerialSettings,
        /// CAN bit rate, bit/s: one of 10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k, 1M
        /// (default 500 000).
        #[serde(default = "default_bitrate")]
        bitrate: u32,
        /// Adapter status poll (`F`) period, s of bench time; 0 = never (default 1).
        #[serde(default = "default_status_poll_s")]
        status_poll_s: f64,
    },
    /// A Linux SocketCAN interface (bit rate set with `ip link`).
    Socketcan {
        /// Interface name, e.g. `can0`.
        interface: String,
    },
}

fn default_bitrate() -> u32 {
    500_000
}
fn default_status_poll_s() -> f64 {
    1.0
}
fn default_rate_hz() -> f64 {
    20.0
}
fn default_open_timeout_s() -> f64 {
    1.0
}
fn default_model() -> String {
    "FOG on CAN (bench frame set)".to_owned()
}
fn default_max_rate_deg_s() -> f64 {
    500.0
}
fn default_temp_range() -> (f64, f64) {
    (-40.0, 60.0)
}

/// Configuration of a [`CanGyro`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanGyroConfig {
    /// Transport (required).
    pub transport: CanTransport,
    /// Frame ids (default 0x180/0x181/0x182, 11-bit).
    #[serde(default)]
    pub ids: GyroCanIds,
    /// The gyro's output rate, Hz, used until its info frame arrives (default 20).
    #[serde(default = "default_rate_hz")]
    pub sample_rate_hz: f64,
    /// No sample within this many sample periods of bench time is a `Timeout` (default 10).
    #[serde(default = "default_watchdog_periods")]
    pub watchdog_periods: f64,
    /// How long opening the adapter may take, s of bench time (default 1).
    #[serde(default = "default_open_timeout_s")]
    pub open_timeout_s: f64,
    /// Model string for the recording (default `FOG on CAN (bench frame set)`).
    #[serde(default = "default_model")]
    pub model: String,
    /// Input range, °/s (default 500).
    #[serde(default = "default_max_rate_deg_s")]
    pub max_rate_deg_s: f64,
    /// Operating temperature range, °C (default -40..60, the seed FOG).
    #[serde(default = "default_temp_range")]
    pub operating_temp_c: (f64, f64),
}

impl CanGyroConfig {
    /// Defaults for a gyro on an SLCAN adapter at `path`.
    pub fn slcan(path: impl Into<String>) -> Self {
        Self {
            transport: CanTransport::Slcan {
                serial: SerialSettings {
                    path: path.into(),
                    baud: 115_200,
                    parity: Default::default(),
                    data_bits: 8,
                    stop_bits: 1,
                },
                bitrate: default_bitrate(),
                status_poll_s: default_status_poll_s(),
            },
            ids: GyroCanIds::default(),
            sample_rate_hz: default_rate_hz(),
            watchdog_periods: default_watchdog_periods(),
            open_timeout_s: default_open_timeout_s(),
            model: default_model(),
            max_rate_deg_s: default_max_rate_deg_s(),
            operating_temp_c: default_temp_range(),
        }
    }

    /// Check values that serde cannot.
    pub fn validate(&self) -> DeviceResult<()> {
        let bad = |m: String| Err(DeviceError::new(ErrorKind::OutOfRange, m));
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return bad(format!("sample_rate_hz = {} must be > 0", self.sample_rate_hz));
        }
        if !(self.watchdog_periods.is_finite() && self.watchdog_periods >= 1.0) {
            return bad(format!("watchdog_periods = {} must be ≥ 1", self.watchdog_periods));
        }
        if !(self.open_timeout_s.is_finite() && self.open_timeout_s > 0.0) {
            return bad(format!("open_timeout_s = {} must be > 0", self.open_timeout_s));
        }
        if let CanTransport::Slcan { bitrate, status_poll_s, .. } = &self.transport {
            if Bitrate::from_bits_per_s(*bitrate).is_none() {
                return bad(format!(
                    "bitrate = {bitrate}: SLCAN supports 10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k, 1M"
                ));
            }
            if !(status_poll_s.is_finite() && *status_poll_s >= 0.0) {
                return bad(format!("status_poll_s = {status_poll_s} must be ≥ 0"));
            }
        }
        Ok(())
    }
}

/// A gyro on a CAN bus.
pub struct CanGyro {
    bus: Box<dyn CanBus>,
    clock: Arc<dyn Clock>,
    info: DeviceInfo<GyroCapabilities>,
    asm: SampleAssembler,
    seq: SeqTracker,
    watchdog: Watchdog,
    after_corrupt: bool,
    stats: GyroLinkStats,
}

impl CanGyro {
    /// Open the configured transport and start listening.
    pub async fn open(config: &CanGyroConfig, clock: Arc<dyn Clock>) -> DeviceResult<Self> {
        config.validate()?;
        let bus: Box<dyn CanBus> = match &config.transport {
            CanTransport::Slcan { serial, bitrate, status_poll_s } => {
                let opts = SlcanOptions {
                    bitrate: Bitrate::from_bits_per_s(*bitrate).unwrap_or(Bitrate::K500),
                    status_poll: (*status_poll_s > 0.0)
                        .then(|| Duration::from_secs_f64(*status_poll_s)),
                    command_timeout: Duration::from_secs_f64(config.open_timeout_s),
                };
                Box::new(SlcanBus::open_serial(serial, opts, clock.clone()).await?)
            }
            CanTransport::Socketcan { interface } => {
                Box::new(super::socketcan::SocketCanBus::open(interface)?)
            }
        };
        Ok(Self::with_bus(bus, config, clock))
    }

    /// A gyro on an already open bus (any [`CanBus`]; the config's transport is not used).
    pub fn with_bus(bus: Box<dyn CanBus>, config: &CanGyroConfig, clock: Arc<dyn Clock>) -> Self {
        let info = DeviceInfo {
            model: config.model.clone(),
            driver: format!("gyro-can/{}", bus.describe()),
            capabilities: GyroCapabilities {
                sample_rates_hz: vec![config.sample_rate_hz],
                max_rate_rad_s: config.max_rate_deg_s.to_radians(),
                operating_temp_c: config.operating_temp_c,
                has_temperature: true,
            },
        };
        let now = clock.now();
        Self {
            bus,
            asm: SampleAssembler::new(config.ids, 1.0 / config.sample_rate_hz),
            clock,
            info,
            seq: SeqTracker::new(1 << 32),
            watchdog: Watchdog { periods: config.watchdog_periods, last: now },
            after_corrupt: false,
            stats: GyroLinkStats::default(),
        }
    }

    /// Link counters.
    pub fn stats(&self) -> GyroLinkStats {
        self.stats
    }

    /// The bus's counters and status flags.
    pub fn bus_status(&self) -> BusStatus {
        self.bus.status()
    }

    /// Take the bus off the CAN (SLCAN `C`).
    pub async fn close(&mut self) -> DeviceResult<()> {
        self.bus.close().await
    }
}

#[async_trait]
impl Gyro for CanGyro {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        &self.info
    }

    /// The next sample; `Timeout` after [`CanGyroConfig::watchdog_periods`] sample periods
    /// without one (the watchdog then restarts). Cancel-safe.
    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let clock = self.clock.clone();
        loop {
            let deadline = self.watchdog.deadline(self.sample_rate_hz());
            let now = clock.now();
            let got = if now >= deadline {
                None
            } else {
                crate::clock::timeout(&*clock, deadline - now, self.bus.recv()).await
            };
            let frame = match got {
                None => {
                    self.stats.timeouts += 1;
                    let what = self.bus.describe();
                    return Err(self.watchdog.expired(clock.now(), self.sample_rate_hz(), &what));
                }
                Some(Err(e)) if e.kind() == ErrorKind::Protocol => {
                    self.stats.corrupt += 1;
                    self.after_corrupt = true;
                    tracing::warn!(error = %e, "gyro CAN: corrupt frame skipped");
                    continue;
                }
                Some(Err(e)) => return Err(e),
                Some(Ok(f)) => f,
            };
            let s = match self.asm.push(&frame) {
                None => continue,
                Some(Err(e)) => {
                    self.stats.unpaired += 1;
                    self.after_corrupt = true;
                    tracing::warn!(error = %e, "gyro CAN: frame skipped");
                    continue;
                }
                Some(Ok(s)) => s,
            };
            let mut sample = s.to_gyro_sample();
            let missing = self.seq.observe(u64::from(s.seq));
            // The device's clock: its counter times its own sample interval.
            sample.device_time = self.seq.device_time(clock.now(), s.interval_s);
            if missing > 0 {
                sample.status |= status::gyro::SEQ_GAP;
                self.stats.seq_gaps += 1;
                self.stats.missing += missing;
            }
            if std::mem::take(&mut self.after_corrupt) {
                sample.status |= status::gyro::AFTER_CORRUPT;
            }
            self.stats.samples += 1;
            self.watchdog.last = clock.now();
            return Ok(sample);
        }
    }

    /// The device's rate: from its info frame once received, the configured rate until then.
    fn sample_rate_hz(&self) -> f64 {
        1.0 / self.asm.interval_s()
    }
}
