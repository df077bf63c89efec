//! [`Gyro`] drivers for KVH serial outputs (`docs/protocols/gyro-serial.md`):
//!
//! - [`Kvh1750Gyro`]: KVH 1750/1775 format A, 36-byte frames with CRC-32/MPEG-2 (921600 baud
//!   native). One sensing axis (x, y or z) is used; the gyro field (default delta angle, rad) is
//!   turned into a rate with the configured sample rate. Temperature from the frame (1 °C
//!   resolution); the 7-bit counter (0..127) gives gap detection modulo 128.
//! - [`Dsp3000Gyro`]: KVH DSP-3000, 100 Hz ASCII lines (38400 8N1) or 1000 Hz 4-byte binary
//!   words (115200). No counter, no time stamp and no temperature (`temperature_c` is
//!   `None`): the device's clock is its fixed output rate, so `seq` counts its frames since the
//!   first and `device_time` is the first arrival plus `seq` periods ([`FixedRateClock`]).
//!   Frames that arrived damaged are counted (a garbled line; the bytes between two good
//!   binary words); frames that never arrived are recognised from the arrival times where the
//!   host resolves a period. Either makes `seq` jump, with `SEQ_GAP`.
//!
//! Both resynchronise on junk and count corrupt frames (CRC, parity, garbled lines) in
//! [`GyroLinkStats::corrupt`]; the next good sample carries `AFTER_CORRUPT`. No sample within
//! `watchdog_periods` sample periods of bench time is a `Timeout` error.

use std::sync::Arc;

use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use tokio::io::AsyncReadExt;

use super::gyro_link::{
    default_watchdog_periods, FixedRateClock, GyroLinkStats, SeqTracker, Watchdog,
};
use crate::protocol::kvh1750;
use crate::protocol::kvh_dsp3000::{AsciiDecoder, BinaryDecoder, DataType};
use crate::protocol::DecodeError;
use crate::transport::{open_serial, BoxStream, SerialSettings};
use crate::{
    Clock, DeviceError, DeviceInfo, DeviceResult, ErrorKind, Gyro, GyroCapabilities, GyroSample,
};
use bench_recording::status;

/// A sensing axis of a multi-axis unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z (the default).
    #[default]
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// What the KVH 1750's gyro fields carry (set on the unit; the ICD default is delta angle in
/// rad).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kvh1750Output {
    /// Delta angle, rad (default).
    #[default]
    DeltaAngleRad,
    /// Delta angle, °.
    DeltaAngleDeg,
    /// Rate, rad/s.
    RateRadS,
    /// Rate, °/s.
    RateDegS,
}

fn default_1750_rate() -> f64 {
    1000.0
}
fn default_1750_model() -> String {
    "KVH 1750/1775 IMU (format A)".to_owned()
}
fn default_1750_max_rate() -> f64 {
    490.0
}
fn default_temp_range() -> (f64, f64) {
    (-40.0, 60.0)
}

/// Configuration of a [`Kvh1750Gyro`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Kvh1750Config {
    /// Serial port (the unit's native rate is 921600 baud).
    pub serial: SerialSettings,
    /// The unit's configured output rate, Hz (default 1000): divides delta angles into rates.
    #[serde(default = "default_1750_rate")]
    pub sample_rate_hz: f64,
    /// The sensing axis used (default z).
    #[serde(default)]
    pub axis: Axis,
    /// What the gyro fields carry (default delta angle, rad).
    #[serde(default)]
    pub output: Kvh1750Output,
    /// No sample within this many sample periods of bench time is a `Timeout` (default 10).
    #[serde(default = "default_watchdog_periods")]
    pub watchdog_periods: f64,
    /// Model string (default `KVH 1750/1775 IMU (format A)`).
    #[serde(default = "default_1750_model")]
    pub model: String,
    /// Input range, °/s (default 490: check the unit's datasheet).
    #[serde(default = "default_1750_max_rate")]
    pub max_rate_deg_s: f64,
    /// Operating temperature range, °C (default -40..60: check the unit's datasheet).
    #[serde(default = "default_temp_range")]
    pub operating_temp_c: (f64, f64),
}

impl Kvh1750Config {
    /// Defaults for a unit on `path` at 921600 baud.
    pub fn new(path: impl Into<String>) -> Self {
        Self {
            serial: serial(path, 921_600),
            sample_rate_hz: default_1750_rate(),
            axis: Axis::default(),
            output: Kvh1750Output::default(),
            watchdog_periods: default_watchdog_periods(),
            model: default_1750_model(),
            max_rate_deg_s: default_1750_max_rate(),
            operating_temp_c: default_temp_range(),
        }
    }
}

fn serial(path: impl Into<String>, baud: u32) -> SerialSettings {
    SerialSettings {
        path: path.into(),
        baud,
        parity: Default::default(),
        data_bits: 8,
        stop_bits: 1,
    }
}

/// Problems of the settings both KVH drivers share, each with the config key it is about:
/// what `bench validate --bench` and the bench config loader report at that key.
#[allow(clippy::too_many_arguments)]
fn common_problems(
    serial: &SerialSettings,
    rate_hz: f64,
    watchdog: f64,
    max_rate_deg_s: f64,
    operating_temp_c: (f64, f64),
    model: &str,
) -> Vec<(&'static str, String)> {
    let mut v = Vec::new();
    if serial.path.trim().is_empty() {
        v.push(("serial", "serial.path is empty: name the port (e.g. /dev/ttyUSB0)".to_string()));
    }
    if serial.baud == 0 {
        v.push(("serial", "serial.baud must be > 0".to_string()));
    }
    if !(5..=8).contains(&serial.data_bits) {
        v.push(("serial", format!("serial.data_bits = {} must be 5..8", serial.data_bits)));
    }
    if !(1..=2).contains(&serial.stop_bits) {
        v.push(("serial", format!("serial.stop_bits = {} must be 1 or 2", serial.stop_bits)));
    }
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        v.push(("sample_rate_hz", format!("sample_rate_hz = {rate_hz} must be > 0")));
    }
    if !(watchdog.is_finite() && watchdog >= 1.0) {
        v.push(("watchdog_periods", format!("watchdog_periods = {watchdog} must be ≥ 1")));
    }
    if !(max_rate_deg_s.is_finite() && max_rate_deg_s > 0.0) {
        v.push(("max_rate_deg_s", format!("max_rate_deg_s = {max_rate_deg_s} must be > 0")));
    }
    let (lo, hi) = operating_temp_c;
    if !(lo.is_finite() && hi.is_finite() && lo > -273.15 && lo < hi) {
        v.push((
            "operating_temp_c",
            format!(
                "operating_temp_c = [{lo}, {hi}] must be [min, max] °C with -273.15 < min < max"
            ),
        ));
    }
    if model.trim().is_empty() {
        v.push(("model", "model is empty".to_string()));
    }
    v
}

fn first_problem(problems: Vec<(&'static str, String)>) -> DeviceResult<()> {
    match problems.into_iter().next() {
        Some((_, m)) => Err(DeviceError::new(ErrorKind::OutOfRange, m)),
        None => Ok(()),
    }
}

fn check_common(rate_hz: f64, watchdog: f64) -> DeviceResult<()> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(DeviceError::new(
            ErrorKind::OutOfRange,
            format!("sample_rate_hz = {rate_hz} must be > 0"),
        ));
    }
    if !(watchdog.is_finite() && watchdog >= 1.0) {
        return Err(DeviceError::new(
            ErrorKind::OutOfRange,
            format!("watchdog_periods = {watchdog} must be ≥ 1"),
        ));
    }
    Ok(())
}

/// Bytes from a port, read in cancel-safe chunks.
struct Port {
    stream: BoxStream,
    name: String,
}

impl Port {
    async fn read(&mut self, buf: &mut [u8]) -> DeviceResult<usize> {
        let n = self.stream.read(buf).await.map_err(|e| {
            DeviceError::new(ErrorKind::Link, format!("{}: read failed: {e}", self.name))
                .with_source(e)
        })?;
        if n == 0 {
            return Err(DeviceError::new(ErrorKind::Link, format!("{}: port closed", self.name)));
        }
        Ok(n)
    }
}

/// Shared by both drivers: port, watchdog, counters.
struct Link {
    port: Port,
    clock: Arc<dyn Clock>,
    watchdog: Watchdog,
    stats: GyroLinkStats,
    after_corrupt: bool,
    rate_hz: f64,
}

impl Link {
    fn new(stream: BoxStream, name: String, clock: Arc<dyn Clock>, rate_hz: f64, wd: f64) -> Self {
        let last = clock.now();
        Self {
            port: Port { stream, name },
            clock,
            watchdog: Watchdog { periods: wd, last },
            stats: GyroLinkStats::default(),
            after_corrupt: false,
            rate_hz,
        }
    }

    /// Read more bytes into `buf` within the watchdog; `Ok(n)`.
    async fn read(&mut self, buf: &mut [u8]) -> DeviceResult<usize> {
        let deadline = self.watchdog.deadline(self.rate_hz);
        let now = self.clock.now();
        let clock = self.clock.clone();
        let got = if now >= deadline {
            None
        } else {
            crate::clock::timeout(&*clock, deadline - now, self.port.read(buf)).await
        };
        match got {
            Some(r) => r,
            None => {
                self.stats.timeouts += 1;
                Err(self.watchdog.expired(clock.now(), self.rate_hz, &self.port.name))
            }
        }
    }

    fn corrupt(&mut self, e: &DecodeError) {
        self.stats.corrupt += 1;
        self.after_corrupt = true;
        tracing::warn!(port = %self.port.name, error = %e, "gyro: corrupt data skipped");
    }

    fn finish(&mut self, mut s: GyroSample) -> GyroSample {
        if std::mem::take(&mut self.after_corrupt) {
            s.status |= status::gyro::AFTER_CORRUPT;
        }
        self.stats.samples += 1;
        self.watchdog.last = self.clock.now();
        s
    }
}

/// A KVH 1750/1775 IMU used as a single-axis gyro.
pub struct Kvh1750Gyro {
    link: Link,
    dec: kvh1750::Decoder,
    axis: Axis,
    output: Kvh1750Output,
    seq: SeqTracker,
    info: DeviceInfo<GyroCapabilities>,
}

impl Kvh1750Gyro {
    /// Open the serial port.
    pub fn open(config: &Kvh1750Config, clock: Arc<dyn Clock>) -> DeviceResult<Self> {
        let stream = open_serial(&config.serial)?;
        Self::with_stream(Box::new(stream), config, clock)
    }

    /// On an already open byte stream (the config's serial settings only name it).
    pub fn with_stream(
        stream: BoxStream,
        config: &Kvh1750Config,
        clock: Arc<dyn Clock>,
    ) -> DeviceResult<Self> {
        check_common(config.sample_rate_hz, config.watchdog_periods)?;
        config.validate()?;
        let name = format!("kvh1750 {}", config.serial.path);
        Ok(Self {
            info: DeviceInfo {
                model: config.model.clone(),
                driver: format!("{name} at {} baud", config.serial.baud),
                capabilities: GyroCapabilities {
                    sample_rates_hz: vec![config.sample_rate_hz],
                    max_rate_rad_s: config.max_rate_deg_s.to_radians(),
                    operating_temp_c: config.operating_temp_c,
                    has_temperature: true,
                },
            },
            link: Link::new(stream, name, clock, config.sample_rate_hz, config.watchdog_periods),
            dec: kvh1750::Decoder::new(),
            axis: config.axis,
            output: config.output,
            seq: SeqTracker::new(u64::from(kvh1750::SEQ_MAX) + 1),
        })
    }

    /// Link counters.
    pub fn stats(&self) -> GyroLinkStats {
        self.link.stats
    }

    fn sample(&mut self, f: &kvh1750::Frame) -> GyroSample {
        let i = self.axis.index();
        let v = f64::from(f.gyro.get(i).copied().unwrap_or(f32::NAN));
        let rate = match self.output {
            Kvh1750Output::DeltaAngleRad => v * self.link.rate_hz,
            Kvh1750Output::DeltaAngleDeg => v.to_radians() * self.link.rate_hz,
            Kvh1750Output::RateRadS => v,
            Kvh1750Output::RateDegS => v.to_radians(),
        };
        let mut st = 0;
        if !f.gyro_valid(i) || !rate.is_finite() {
            st |= status::gyro::INVALID;
        }
        let missing = self.seq.observe(u64::from(f.seq));
        if missing > 0 {
            st |= status::gyro::SEQ_GAP;
            self.link.stats.seq_gaps += 1;
            self.link.stats.missing += missing;
        }
        // The device's clock: its counter at the configured output rate.
        let device_time = self.seq.device_time(self.link.clock.now(), 1.0 / self.link.rate_hz);
        self.link.finish(GyroSample {
            rate_rad_s: rate,
            temperature_c: Some(f64::from(f.temp_c)),
            seq: u64::from(f.seq),
            status: st,
            device_time,
        })
    }
}

#[async_trait]
impl Gyro for Kvh1750Gyro {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        &self.info
    }

    /// The next frame's sample. Cancel-safe; `Timeout` from the watchdog.
    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let mut buf = [0u8; 4096];
        loop {
            while let Some(r) = self.dec.next_frame() {
                match r {
                    Ok(f) => return Ok(self.sample(&f)),
                    Err(e) => self.link.corrupt(&e),
                }
            }
            let n = self.link.read(&mut buf).await?;
            self.dec.push(buf.get(..n).unwrap_or_default());
        }
    }

    fn sample_rate_hz(&self) -> f64 {
        self.link.rate_hz
    }
}

/// The DSP-3000 output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dsp3000Format {
    /// 100 Hz ASCII lines, 38400 baud (default).
    #[default]
    Ascii,
    /// 1000 Hz 4-byte binary words, 115200 baud.
    Binary,
}

/// What the DSP-3000's ASCII value is (set on the unit; binary words carry their own type).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dsp3000AsciiOutput {
    /// Rate, °/s (default).
    #[default]
    RateDegS,
    /// Incremental angle, °.
    IncrementalAngleDeg,
}

fn default_dsp_model() -> String {
    "KVH DSP-3000 FOG".to_owned()
}
fn default_dsp_max_rate() -> f64 {
    375.0
}
fn default_true() -> bool {
    true
}

/// Configuration of a [`Dsp3000Gyro`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Dsp3000Config {
    /// Serial port (38400 baud for ASCII, 115200 for binary).
    pub serial: SerialSettings,
    /// Output format (default ASCII).
    #[serde(default)]
    pub format: Dsp3000Format,
    /// Output rate, Hz (default: 100 for ASCII, 1000 for binary).
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Meaning of the ASCII value (default rate °/s).
    #[serde(default)]
    pub ascii_output: Dsp3000AsciiOutput,
    /// Drop the first ASCII line, which may be the tail of a line when the port opens while
    /// the gyro streams (default true).
    #[serde(default = "default_true")]
    pub mid_stream: bool,
    /// No sample within this many sample periods of bench time is a `Timeout` (default 10).
    #[serde(default = "default_watchdog_periods")]
    pub watchdog_periods: f64,
    /// Model string (default `KVH DSP-3000 FOG`).
    #[serde(default = "default_dsp_model")]
    pub model: String,
    /// Input range, °/s (default 375: check the unit's datasheet).
    #[serde(default = "default_dsp_max_rate")]
    pub max_rate_deg_s: f64,
    /// Operating temperature range, °C (default -40..60: check the unit's datasheet).
    #[serde(default = "default_temp_range")]
    pub operating_temp_c: (f64, f64),
}

impl Kvh1750Config {
    /// Every problem of the settings, with the key it is about (`serial`, `sample_rate_hz`,
    /// `watchdog_periods`, `max_rate_deg_s`, `operating_temp_c`, `model`).
    pub fn problems(&self) -> Vec<(&'static str, String)> {
        common_problems(
            &self.serial,
            self.sample_rate_hz,
            self.watchdog_periods,
            self.max_rate_deg_s,
            self.operating_temp_c,
            &self.model,
        )
    }

    /// The first of [`Kvh1750Config::problems`], as the driver refuses it.
    pub fn validate(&self) -> DeviceResult<()> {
        first_problem(self.problems())
    }
}

impl Dsp3000Config {
    /// Every problem of the settings, with the key it is about (as
    /// [`Kvh1750Config::problems`]; `sample_rate_hz` when given).
    pub fn problems(&self) -> Vec<(&'static str, String)> {
        common_problems(
            &self.serial,
            self.rate_hz(),
            self.watchdog_periods,
            self.max_rate_deg_s,
            self.operating_temp_c,
            &self.model,
        )
    }

    /// The first of [`Dsp3000Config::problems`], as the driver refuses it.
    pub fn validate(&self) -> DeviceResult<()> {
        first_problem(self.problems())
    }

    /// Defaults for a unit on `path`: 38400 baud for ASCII, 115200 for binary.
    pub fn new(path: impl Into<String>, format: Dsp3000Format) -> Self {
        let baud = match format {
            Dsp3000Format::Ascii => 38_400,
            Dsp3000Format::Binary => 115_200,
        };
        Self {
            serial: serial(path, baud),
            format,
            sample_rate_hz: None,
            ascii_output: Dsp3000AsciiOutput::default(),
            mid_stream: true,
            watchdog_periods: default_watchdog_periods(),
            model: default_dsp_model(),
            max_rate_deg_s: default_dsp_max_rate(),
            operating_temp_c: default_temp_range(),
        }
    }

    /// The output rate in use, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.sample_rate_hz.unwrap_or(match self.format {
            Dsp3000Format::Ascii => 100.0,
            Dsp3000Format::Binary => 1000.0,
        })
    }
}

enum DspDecoder {
    Ascii(AsciiDecoder, Dsp3000AsciiOutput),
    Binary(BinaryDecoder),
}

/// A KVH DSP-3000 single-axis FOG.
pub struct Dsp3000Gyro {
    link: Link,
    dec: DspDecoder,
    /// The device's clock: frames at its fixed output rate.
    clock: FixedRateClock,
    /// Frames that arrived damaged since the last sample.
    damaged: u64,
    /// Binary: stream offset just past the last good word.
    word_end: Option<u64>,
    /// `seq` of the last sample.
    last_seq: Option<u64>,
    info: DeviceInfo<GyroCapabilities>,
}

impl Dsp3000Gyro {
    /// Open the serial port.
    pub fn open(config: &Dsp3000Config, clock: Arc<dyn Clock>) -> DeviceResult<Self> {
        let stream = open_serial(&config.serial)?;
        Self::with_stream(Box::new(stream), config, clock)
    }

    /// On an already open byte stream (the config's serial settings only name it).
    pub fn with_stream(
        stream: BoxStream,
        config: &Dsp3000Config,
        clock: Arc<dyn Clock>,
    ) -> DeviceResult<Self> {
        let rate_hz = config.rate_hz();
        check_common(rate_hz, config.watchdog_periods)?;
        config.validate()?;
        let name = format!("dsp3000 {}", config.serial.path);
        let dec = match config.format {
            Dsp3000Format::Ascii if config.mid_stream => {
                DspDecoder::Ascii(AsciiDecoder::mid_stream(), config.ascii_output)
            }
            Dsp3000Format::Ascii => DspDecoder::Ascii(AsciiDecoder::new(), config.ascii_output),
            Dsp3000Format::Binary => DspDecoder::Binary(BinaryDecoder::new()),
        };
        Ok(Self {
            info: DeviceInfo {
                model: config.model.clone(),
                driver: format!("{name} ({:?}) at {} baud", config.format, config.serial.baud),
                capabilities: GyroCapabilities {
                    sample_rates_hz: vec![rate_hz],
                    max_rate_rad_s: config.max_rate_deg_s.to_radians(),
                    operating_temp_c: config.operating_temp_c,
                    has_temperature: false,
                },
            },
            link: Link::new(stream, name, clock, rate_hz, config.watchdog_periods),
            dec,
            clock: FixedRateClock::new(1.0 / rate_hz),
            damaged: 0,
            word_end: None,
            last_seq: None,
        })
    }

    /// Link counters.
    pub fn stats(&self) -> GyroLinkStats {
        self.link.stats
    }

    /// The next decoded (rate rad/s, valid), `None` when more bytes are needed. Frames that
    /// arrived damaged on the way are added to `damaged`: one per garbled line; the bytes
    /// between two good binary words, four to a word.
    fn decode(&mut self) -> Option<(f64, bool)> {
        let rate_hz = self.link.rate_hz;
        loop {
            let r = match &mut self.dec {
                DspDecoder::Ascii(d, out) => d.next_sample()?.map(|s| {
                    let rad = s.value.to_radians();
                    let rate = match out {
                        Dsp3000AsciiOutput::RateDegS => rad,
                        Dsp3000AsciiOutput::IncrementalAngleDeg => rad * rate_hz,
                    };
                    (rate, s.valid)
                }),
                DspDecoder::Binary(d) => match d.next_word()? {
                    Err(e) => Err(e),
                    Ok(w) => {
                        let end = d.offset();
                        let start = end.saturating_sub(4);
                        if let Some(prev) = self.word_end.replace(end) {
                            self.damaged += (start.saturating_sub(prev) + 2) / 4;
                        }
                        match (w.rate_rad_s(), w.delta_angle_rad()) {
                            (Some(r), _) => Ok((r, w.valid)),
                            (None, Some(a)) => Ok((a * rate_hz, w.valid)),
                            (None, None) => {
                                self.damaged += 1;
                                Err(DecodeError::new(
                                    0,
                                    format!(
                                        "a rate or incremental-angle word, not {:?}",
                                        DataType::IntegratedAngle
                                    ),
                                    &w.to_u32().to_be_bytes(),
                                ))
                            }
                        }
                    }
                },
            };
            match r {
                Ok(v) => return Some(v),
                Err(e) => {
                    // A binary word's place is counted from the offsets; a line is a frame.
                    if matches!(self.dec, DspDecoder::Ascii(..)) {
                        self.damaged += 1;
                    }
                    self.link.corrupt(&e)
                }
            }
        }
    }
}

#[async_trait]
impl Gyro for Dsp3000Gyro {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        &self.info
    }

    /// The next line's or word's sample: `seq` the frames counted since the first (damaged
    /// and lost ones included), `device_time` from them at the output rate. Cancel-safe;
    /// `Timeout` from the watchdog.
    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let mut buf = [0u8; 4096];
        loop {
            if let Some((rate, valid)) = self.decode() {
                self.clock.lost(std::mem::take(&mut self.damaged));
                let (device_time, _) = self.clock.sample(self.link.clock.now());
                let seq = self.clock.count();
                let mut st = if valid { 0 } else { status::gyro::INVALID };
                let missing = self.last_seq.replace(seq).map_or(0, |last| seq - last - 1);
                if missing > 0 {
                    st |= status::gyro::SEQ_GAP;
                    self.link.stats.seq_gaps += 1;
                    self.link.stats.missing += missing;
                }
                return Ok(self.link.finish(GyroSample {
                    rate_rad_s: rate,
                    temperature_c: None,
                    seq,
                    status: st,
                    device_time: Some(device_time),
                }));
            }
            let n = self.link.read(&mut buf).await?;
            match &mut self.dec {
                DspDecoder::Ascii(d, _) => d.push(buf.get(..n).unwrap_or_default()),
                DspDecoder::Binary(d) => d.push(buf.get(..n).unwrap_or_default()),
            }
        }
    }

    fn sample_rate_hz(&self) -> f64 {
        self.link.rate_hz
    }
}
