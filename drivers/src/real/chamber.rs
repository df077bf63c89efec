//! Chamber controllers over Modbus RTU or TCP (Watlow F4, Watlow F4T, Eurotherm 3216, or any
//! controller described by a [`RegisterMap`]).
//!
//! Framing, CRC and function codes are tokio-modbus's; this driver only decides which registers
//! to read and write ([`crate::protocol::modbus_map`]) and turns the two levels of failure
//! tokio-modbus reports — a transport/protocol [`tokio_modbus::Error`] around a device
//! [`ExceptionCode`] — into [`DeviceError`] kinds, keeping them apart:
//!
//! | failure | kind |
//! |---|---|
//! | no reply within `request_timeout_s` | `Timeout` |
//! | bytes came back but no valid frame (bad CRC, garbage) before the timeout | `Protocol` |
//! | reply for another request (header / function mismatch), undecodable frame | `Protocol` |
//! | port closed, connection reset | `Link` |
//! | exception 1 illegal function | `Unsupported` |
//! | exception 2 illegal data address | `Unsupported` (the map does not fit the controller) |
//! | exception 3 illegal data value | `OutOfRange` |
//! | exception 4 server device failure | `DeviceFault` |
//! | exception 5 acknowledge, 6 busy | `NotReady` |
//!
//! Transient failures (`Timeout`, `Protocol`, `Link`) are retried `retries` times with a
//! doubling back-off ([`super::link::RetryPolicy`], the one policy of line and Modbus devices);
//! a TCP connection (whose stream may then hold a late reply) and a failed serial port are
//! reopened on the next attempt. Exceptions are not retried. Times are in seconds
//! (`request_timeout_s`, `retry_backoff_s`); the older `request_timeout_ms` and
//! `retry_backoff_ms` are still read, and a config giving both forms of one is refused.
//!
//! **Ramps.** If the map has a set-point rate-limit register (Eurotherm 35), `set_target` writes
//! the rate there and then the set point (through the remote set point 26 on the Eurotherm, never
//! the EEPROM target register 2), and the controller ramps. Otherwise the driver ramps itself:
//! [`Chamber::service`] writes a new set point every `step_period_s` of bench time, moving from
//! the working set point at the commanded rate, and only when the value quantised to the
//! resolution changes. Bench time comes from the [`Clock`] given to [`ModbusChamber::connect`];
//! request timeouts are wall-clock time (a link property).
//!
//! Register facts come from device-facts.md; where a fact was inferred from third-party drivers
//! rather than a manual (F4 model register 0 = 5270, Eurotherm decimals and rate units), a lab
//! must confirm it against its controller's manual.
//!
//! ```
//! use bench_drivers::real::chamber::ModbusChamberConfig;
//! let cfg: ModbusChamberConfig = toml::from_str(r#"
//!     endpoint = { tcp = { addr = "192.168.0.30:502" } }
//!     map = "eurotherm_3216"
//! "#).unwrap();
//! assert_eq!(cfg.unit_id, 1);
//! assert_eq!(cfg.request_timeout(), std::time::Duration::from_millis(300));
//! ```

use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context as TaskContext, Poll};
use std::time::Duration;

use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio_modbus::client::{Context, Reader, Writer};
use tokio_modbus::{ExceptionCode, Slave};

use super::link::RetryPolicy;
use crate::protocol::modbus_map::{Preset, RateUnits, RegisterMap, RegisterWrite};
use crate::transport::{BoxStream, Endpoint};
use crate::{
    BenchTime, Chamber, ChamberCapabilities, ChamberReading, Clock, DeviceError, DeviceInfo,
    DeviceResult, ErrorKind,
};
use bench_recording::status;

/// A built-in map by name, or a map spelled out in the config.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum MapChoice {
    /// `map = "watlow_f4" | "watlow_f4t" | "eurotherm_3216"`.
    Preset(Preset),
    /// `[chamber.map]` with the fields of [`RegisterMap`].
    Custom(RegisterMap),
}

impl<'de> Deserialize<'de> for MapChoice {
    /// A preset by name (`"watlow_f4"`, `"watlow_f4t"`, `"eurotherm_3216"`) or a custom map as a
    /// table; a wrong name is reported with the allowed ones.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = MapChoice;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a preset name (\"watlow_f4\", \"watlow_f4t\", \"eurotherm_3216\") or a register map table")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<MapChoice, E> {
                Preset::deserialize(serde::de::value::StrDeserializer::<E>::new(v))
                    .map(MapChoice::Preset)
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, m: A) -> Result<MapChoice, A::Error> {
                RegisterMap::deserialize(serde::de::value::MapAccessDeserializer::new(m))
                    .map(MapChoice::Custom)
            }
        }
        d.deserialize_any(V)
    }
}

impl MapChoice {
    /// The register map.
    pub fn map(&self) -> RegisterMap {
        match self {
            MapChoice::Preset(p) => RegisterMap::preset(*p),
            MapChoice::Custom(m) => m.clone(),
        }
    }
}

/// Capabilities to report (the controller cannot tell them). Defaults: the ST1300's chamber.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CapabilityConfig {
    /// Lowest set point, °C (default −55).
    pub min_temp_c: f64,
    /// Highest set point, °C (default +185).
    pub max_temp_c: f64,
    /// Fastest heating ramp, °C/s (default 5 °C/min).
    pub max_heat_rate_c_s: f64,
    /// Fastest cooling ramp, °C/s, positive (default 3.5 °C/min).
    pub max_cool_rate_c_s: f64,
    /// Resolution of set points and readings, °C (default 0.1); the stepping ramp writes only
    /// when the set point quantised to this changes.
    pub temp_resolution_c: f64,
}

impl Default for CapabilityConfig {
    fn default() -> Self {
        Self {
            min_temp_c: -55.0,
            max_temp_c: 185.0,
            max_heat_rate_c_s: 5.0 / 60.0,
            max_cool_rate_c_s: 3.5 / 60.0,
            temp_resolution_c: 0.1,
        }
    }
}

/// A register that must hold a known value (identifies the controller at connection).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelCheck {
    /// Register address (Watlow F4: 0).
    pub register: u16,
    /// Expected word (Watlow F4: 5270).
    pub value: u16,
}

/// How to reach and drive a Modbus chamber controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModbusChamberConfig {
    /// Serial port (Modbus RTU) or TCP server (Modbus TCP).
    pub endpoint: Endpoint,
    /// Modbus unit (slave) id (default 1, the controllers' factory address).
    #[serde(default = "default_unit_id")]
    pub unit_id: u8,
    /// Register map: a preset name or a custom map.
    pub map: MapChoice,
    /// Time to wait for each reply, wall-clock s (default 0.3; [`Self::request_timeout`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request_timeout_s: Option<f64>,
    /// The same in ms: the older key, still read. Give one or the other.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub request_timeout_ms: Option<u64>,
    /// Extra attempts after a transient failure (default 2).
    #[serde(default = "default_retries")]
    pub retries: u32,
    /// Wait before the first retry, wall-clock s, doubled for each further one (default 0.05;
    /// [`Self::retry_policy`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retry_backoff_s: Option<f64>,
    /// The same in ms: the older key, still read. Give one or the other.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retry_backoff_ms: Option<u64>,
    /// Bench time between set-point writes when the driver ramps itself, s (default 1).
    #[serde(default = "default_step_period_s")]
    pub step_period_s: f64,
    /// Units of the map's rate-limit register (default per minute).
    #[serde(default)]
    pub rate_units: RateUnits,
    /// Register checked at connection, e.g. `{ register = 0, value = 5270 }` for a Watlow F4
    /// (default none: only the process value is read).
    #[serde(default)]
    pub model_check: Option<ModelCheck>,
    /// Capabilities to report.
    #[serde(default)]
    pub capabilities: CapabilityConfig,
}

fn default_unit_id() -> u8 {
    1
}
/// Default of `request_timeout_s`.
const DEFAULT_TIMEOUT_S: f64 = 0.3;
/// Default of `retry_backoff_s`.
const DEFAULT_BACKOFF_S: f64 = 0.05;
fn default_retries() -> u32 {
    2
}
fn default_step_period_s() -> f64 {
    1.0
}

impl ModbusChamberConfig {
    /// A config with every default for `endpoint` and `map`.
    pub fn new(endpoint: Endpoint, map: MapChoice) -> Self {
        Self {
            endpoint,
            unit_id: default_unit_id(),
            map,
            request_timeout_s: None,
            request_timeout_ms: None,
            retries: default_retries(),
            retry_backoff_s: None,
            retry_backoff_ms: None,
            step_period_s: default_step_period_s(),
            rate_units: RateUnits::default(),
            model_check: None,
            capabilities: CapabilityConfig::default(),
        }
    }

    /// The settings given in both forms, seconds and the older milliseconds: (seconds key,
    /// milliseconds key) of each. A config must give one or the other.
    pub fn given_twice(&self) -> Vec<(&'static str, &'static str)> {
        let mut out = Vec::new();
        if self.request_timeout_s.is_some() && self.request_timeout_ms.is_some() {
            out.push(("request_timeout_s", "request_timeout_ms"));
        }
        if self.retry_backoff_s.is_some() && self.retry_backoff_ms.is_some() {
            out.push(("retry_backoff_s", "retry_backoff_ms"));
        }
        out
    }

    /// Time to wait for each reply, wall-clock: `request_timeout_s`, or the older
    /// `request_timeout_ms`, or 0.3 s.
    pub fn request_timeout(&self) -> Duration {
        seconds(self.request_timeout_s, self.request_timeout_ms, DEFAULT_TIMEOUT_S)
    }

    /// The retry policy of its requests: `retries`, and `retry_backoff_s` (or the older
    /// `retry_backoff_ms`, or 0.05 s) doubling.
    pub fn retry_policy(&self) -> RetryPolicy {
        let backoff = seconds(self.retry_backoff_s, self.retry_backoff_ms, DEFAULT_BACKOFF_S);
        RetryPolicy { retries: self.retries, backoff }
    }

    /// Check values that serde cannot (`connect` does; so does `bench validate --bench`).
    pub fn validate(&self) -> DeviceResult<()> {
        let bad = |m: String| Err(DeviceError::new(ErrorKind::OutOfRange, m));
        let c = &self.capabilities;
        if let Some((s, ms)) = self.given_twice().first() {
            return bad(format!("`{s}` and the older `{ms}` give the same setting: keep `{s}`"));
        }
        if !(self.step_period_s.is_finite() && self.step_period_s > 0.0) {
            return bad(format!("step_period_s = {} must be positive", self.step_period_s));
        }
        let timeout_s = self.request_timeout_s.unwrap_or(DEFAULT_TIMEOUT_S);
        if !(timeout_s.is_finite() && timeout_s > 0.0 && timeout_s < 1e6)
            || self.request_timeout_ms == Some(0)
        {
            return bad("request_timeout_s must be a positive number of seconds".into());
        }
        let backoff_s = self.retry_backoff_s.unwrap_or(DEFAULT_BACKOFF_S);
        if !(backoff_s.is_finite() && (0.0..1e6).contains(&backoff_s)) {
            return bad(format!("retry_backoff_s = {backoff_s} must be a number of seconds ≥ 0"));
        }
        let rates = [c.max_heat_rate_c_s, c.max_cool_rate_c_s, c.temp_resolution_c];
        if !(c.min_temp_c < c.max_temp_c && rates.iter().all(|r| r.is_finite() && *r > 0.0)) {
            return bad(format!(
                "capabilities: need min_temp_c < max_temp_c and positive rates and resolution, \
                 got {c:?}"
            ));
        }
        Ok(())
    }
}

/// A setting in seconds, or in the older milliseconds, or `default_s`.
fn seconds(s: Option<f64>, ms: Option<u64>, default_s: f64) -> Duration {
    match (s, ms) {
        (Some(s), _) => Duration::try_from_secs_f64(s).unwrap_or(Duration::ZERO),
        (None, Some(ms)) => Duration::from_millis(ms),
        (None, None) => Duration::from_secs_f64(default_s),
    }
}

/// Counts bytes received, so a timeout can tell "nothing came back" from "garbage came back".
struct Counting {
    inner: BoxStream,
    received: Arc<AtomicU64>,
}

impl std::fmt::Debug for Counting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Counting").field("received", &self.received).finish_non_exhaustive()
    }
}

impl AsyncRead for Counting {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut TaskContext<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let r = Pin::new(&mut self.inner).poll_read(cx, buf);
        let n = buf.filled().len().saturating_sub(before);
        self.received.fetch_add(n as u64, Ordering::Relaxed);
        r
    }
}

impl AsyncWrite for Counting {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut TaskContext<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut self.inner).poll_write(cx, buf)
    }
    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut TaskContext<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }
    fn poll_shutdown(
        mut self: Pin<&mut Self>,
        cx: &mut TaskContext<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

/// One register operation.
#[derive(Debug, Clone)]
enum Op {
    /// Read holding registers (function 3).
    Read { addr: u16, count: u16 },
    /// Write one register (function 6) or several (function 16).
    Write { addr: u16, words: Vec<u16> },
}

impl std::fmt::Display for Op {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Op::Read { addr, count } => write!(f, "read holding register {addr} ×{count} (fc 3)"),
            Op::Write { addr, words } if words.len() == 1 => {
                write!(f, "write register {addr} = {words:04X?} (fc 6)")
            }
            Op::Write { addr, words } => {
                write!(f, "write registers {addr}.. = {words:04X?} (fc 16)")
            }
        }
    }
}

/// One failed attempt, with the two levels of tokio-modbus's result kept apart.
#[derive(Debug)]
enum Failure {
    /// No reply within the timeout; `bytes` bytes were received meanwhile.
    NoReply { bytes: u64 },
    /// Transport or framing error (outer level).
    Modbus(tokio_modbus::Error),
    /// The controller answered with an exception (inner level).
    Exception(ExceptionCode),
    /// Opening the endpoint failed.
    Open(DeviceError),
}

/// The meaning of a Modbus exception code.
pub fn exception_meaning(code: u8) -> &'static str {
    match code {
        1 => "illegal function",
        2 => "illegal data address",
        3 => "illegal data value",
        4 => "server device failure",
        5 => "acknowledge (busy with a long command)",
        6 => "server device busy",
        8 => "memory parity error",
        0x0A => "gateway path unavailable",
        0x0B => "gateway target device failed to respond",
        _ => "unknown exception",
    }
}

/// An exception is the controller's considered answer, so none is transient: resending the
/// same request cannot help. Illegal function and illegal address mean the register map does not
/// fit this controller (`Unsupported`).
fn exception_kind(code: u8) -> ErrorKind {
    match code {
        1 | 2 => ErrorKind::Unsupported,
        3 => ErrorKind::OutOfRange,
        5 | 6 => ErrorKind::NotReady,
        _ => ErrorKind::DeviceFault,
    }
}

impl Failure {
    fn kind(&self) -> ErrorKind {
        match self {
            Failure::NoReply { bytes: 0 } => ErrorKind::Timeout,
            Failure::NoReply { .. } => ErrorKind::Protocol,
            Failure::Modbus(tokio_modbus::Error::Protocol(_)) => ErrorKind::Protocol,
            Failure::Modbus(tokio_modbus::Error::Transport(e)) => match e.kind() {
                std::io::ErrorKind::TimedOut => ErrorKind::Timeout,
                std::io::ErrorKind::InvalidData => ErrorKind::Protocol,
                _ => ErrorKind::Link,
            },
            Failure::Exception(c) => exception_kind(u8::from(*c)),
            Failure::Open(e) => e.kind(),
        }
    }

    fn describe(&self, timeout: Duration) -> String {
        match self {
            Failure::NoReply { bytes: 0 } => format!("no reply within {timeout:?}"),
            Failure::NoReply { bytes } => format!(
                "{bytes} byte(s) received within {timeout:?} but no valid reply frame \
                 (bad CRC or garbled reply)"
            ),
            Failure::Modbus(e) => format!("{e}"),
            Failure::Exception(c) => {
                let code = u8::from(*c);
                format!("Modbus exception 0x{code:02X} ({})", exception_meaning(code))
            }
            Failure::Open(e) => e.to_string(),
        }
    }
}

/// A set-point ramp the driver runs itself (controllers without a rate-limit register).
#[derive(Debug, Clone, Copy)]
struct Stepping {
    start_c: f64,
    start_t: BenchTime,
    rate_c_s: f64,
    target_c: f64,
    /// Last set point written, quantised, °C.
    written_c: f64,
    written_at: BenchTime,
}

impl Stepping {
    fn at(&self, t: BenchTime) -> f64 {
        let dt = t.saturating_sub(self.start_t).as_secs_f64();
        let d = self.target_c - self.start_c;
        let moved = (self.rate_c_s * dt).min(d.abs());
        self.start_c + moved.copysign(d)
    }
}

/// A chamber controller driven over Modbus.
pub struct ModbusChamber {
    config: ModbusChamberConfig,
    map: RegisterMap,
    info: DeviceInfo<ChamberCapabilities>,
    clock: Arc<dyn Clock>,
    ctx: Option<Context>,
    received: Arc<AtomicU64>,
    decimals: u8,
    target_c: f64,
    /// Last set point written (or read at connection), °C.
    setpoint_c: f64,
    stepping: Option<Stepping>,
}

fn quantise(v: f64, res: f64) -> f64 {
    (v / res).round() * res
}

impl ModbusChamber {
    /// Open the endpoint, take control and probe the controller: read the implied decimals
    /// (if the map reads them), check `model_check` (if set), do the map's `on_connect` writes
    /// and read the process value and the current set point. Fails with a message naming the
    /// endpoint, unit id, the request tried and what came back (nothing, garbage, an exception).
    pub async fn connect(config: ModbusChamberConfig, clock: Arc<dyn Clock>) -> DeviceResult<Self> {
        config.validate()?;
        let map = config.map.map();
        map.validate().map_err(|e| DeviceError::new(ErrorKind::OutOfRange, e.to_string()))?;
        let caps = &config.capabilities;
        let info = DeviceInfo {
            model: map.model.clone(),
            driver: format!("modbus unit {} on {}", config.unit_id, config.endpoint),
            capabilities: ChamberCapabilities {
                min_temp_c: caps.min_temp_c,
                max_temp_c: caps.max_temp_c,
                max_heat_rate_c_s: caps.max_heat_rate_c_s,
                max_cool_rate_c_s: caps.max_cool_rate_c_s,
                temp_resolution_c: caps.temp_resolution_c,
            },
        };
        let mut me = Self {
            decimals: map.fixed_decimals().unwrap_or(0),
            map,
            info,
            clock,
            ctx: None,
            received: Arc::new(AtomicU64::new(0)),
            target_c: 0.0,
            setpoint_c: 0.0,
            stepping: None,
            config,
        };
        me.probe().await.map_err(|e| {
            DeviceError::new(
                e.kind(),
                format!(
                    "no {} controller found at unit {} on {}: {}",
                    me.map.model,
                    me.config.unit_id,
                    me.config.endpoint,
                    e.message()
                ),
            )
            .with_source(e)
        })?;
        Ok(me)
    }

    async fn probe(&mut self) -> DeviceResult<()> {
        // The process value first: the plainest request, and the one every map has (decoded
        // below, once the decimals are known).
        let (pv, count) = self.map.process_value_read();
        self.transact(&Op::Read { addr: pv, count }, "process value").await?;
        if let Some(reg) = self.map.decimals_register() {
            let w = self.transact(&Op::Read { addr: reg, count: 1 }, "decimals").await?;
            let d = w.first().copied().unwrap_or(u16::MAX);
            if d > u16::from(crate::protocol::modbus_map::MAX_DECIMALS) {
                return Err(DeviceError::new(
                    ErrorKind::Protocol,
                    format!("decimals register {reg} holds {d}, expected 0..=4"),
                ));
            }
            self.decimals = d as u8;
        }
        if let Some(RegisterWrite { register, value }) = self.map.celsius_check {
            let w = self.transact(&Op::Read { addr: register, count: 1 }, "units").await?;
            if w.first() != Some(&value) {
                return Err(DeviceError::new(
                    ErrorKind::Unsupported,
                    format!(
                        "units register {register} holds {w:?}, expected {value} (°C): the \
                         controller is not set to °C, and its temperatures would be misread; \
                         set it to °C"
                    ),
                ));
            }
        }
        if let Some(check) = self.config.model_check {
            let w = self
                .transact(&Op::Read { addr: check.register, count: 1 }, "model register")
                .await?;
            if w.first() != Some(&check.value) {
                return Err(DeviceError::new(
                    ErrorKind::Protocol,
                    format!(
                        "model register {} holds {:?}, expected {}",
                        check.register, w, check.value
                    ),
                ));
            }
        }
        let sp = match self.map.working_set_point {
            Some(wsp) => self.read_value(wsp, "working set point").await?,
            None => self.read_value(self.map.set_point, "set point").await?,
        };
        self.setpoint_c = sp;
        self.target_c = sp;
        Ok(())
    }

    /// The implied decimals in use (read from the controller for the Watlow F4).
    pub fn decimals(&self) -> u8 {
        self.decimals
    }

    fn timeout(&self) -> Duration {
        self.config.request_timeout()
    }

    async fn open(&mut self) -> Result<(), Failure> {
        let stream = self.config.endpoint.open(self.timeout()).await.map_err(Failure::Open)?;
        let counting = Counting { inner: stream, received: self.received.clone() };
        let slave = Slave(self.config.unit_id);
        let mut ctx = match self.config.endpoint {
            Endpoint::Serial(_) => tokio_modbus::client::rtu::attach_slave(counting, slave),
            Endpoint::Tcp { .. } => tokio_modbus::client::tcp::attach_slave(counting, slave),
        };
        for RegisterWrite { register, value } in self.map.on_connect.clone() {
            let op = Op::Write { addr: register, words: vec![value] };
            Self::attempt(&mut ctx, &op, &self.received, self.timeout()).await?;
        }
        self.ctx = Some(ctx);
        Ok(())
    }

    /// One attempt on an open context.
    async fn attempt(
        ctx: &mut Context,
        op: &Op,
        received: &AtomicU64,
        timeout: Duration,
    ) -> Result<Vec<u16>, Failure> {
        let before = received.load(Ordering::Relaxed);
        let fut = async {
            match op {
                Op::Read { addr, count } => ctx.read_holding_registers(*addr, *count).await,
                Op::Write { addr, words } if words.len() == 1 => {
                    let w = words.first().copied().unwrap_or(0);
                    ctx.write_single_register(*addr, w).await.map(|r| r.map(|()| Vec::new()))
                }
                Op::Write { addr, words } => {
                    ctx.write_multiple_registers(*addr, words).await.map(|r| r.map(|()| Vec::new()))
                }
            }
        };
        match tokio::time::timeout(timeout, fut).await {
            Err(_) => Err(Failure::NoReply {
                bytes: received.load(Ordering::Relaxed).saturating_sub(before),
            }),
            Ok(Err(transport)) => Err(Failure::Modbus(transport)),
            Ok(Ok(Err(exception))) => Err(Failure::Exception(exception)),
            Ok(Ok(Ok(words))) => match op {
                Op::Read { count, .. } if words.len() != usize::from(*count) => {
                    Err(Failure::Modbus(tokio_modbus::Error::Transport(std::io::Error::new(
                        std::io::ErrorKind::InvalidData,
                        format!("{} register word(s) in the reply, expected {count}", words.len()),
                    ))))
                }
                _ => Ok(words),
            },
        }
    }

    /// One attempt of `op`, opening the link first if it is closed.
    async fn attempt_open(&mut self, op: &Op) -> Result<Vec<u16>, Failure> {
        let timeout = self.timeout();
        if self.ctx.is_none() {
            self.open().await?;
        }
        match self.ctx.as_mut() {
            Some(ctx) => Self::attempt(ctx, op, &self.received, timeout).await,
            None => Err(Failure::Open(DeviceError::new(ErrorKind::Link, "not open"))),
        }
    }

    /// Do `op` under the retry policy; `what` names it in errors.
    async fn transact(&mut self, op: &Op, what: &str) -> DeviceResult<Vec<u16>> {
        let timeout = self.timeout();
        let policy = self.config.retry_policy();
        let owned = op.clone();
        let r = policy
            .run(
                self,
                what,
                move |me| {
                    let op = owned.clone();
                    Box::pin(async move { me.attempt_open(&op).await })
                },
                |me, failure| {
                    // A broken link must be reopened, and a TCP stream may hold a late or
                    // partial reply after a timeout; a serial RTU client discards stale bytes
                    // before each request, and a TCP stream stays in step after a whole but
                    // mismatched reply.
                    let tcp = matches!(me.config.endpoint, Endpoint::Tcp { .. });
                    let kind = failure.kind();
                    if kind == ErrorKind::Link
                        || (tcp && matches!(failure, Failure::NoReply { .. }))
                    {
                        me.ctx = None;
                    }
                    kind
                },
            )
            .await;
        r.result.map_err(|failure| {
            let tries =
                if r.attempts > 1 { format!(" ({} attempts)", r.attempts) } else { String::new() };
            let msg = format!("{what}: {op}: {}{tries}", failure.describe(timeout));
            let err = DeviceError::new(failure.kind(), msg);
            match failure {
                Failure::Modbus(e) => err.with_source(e),
                Failure::Open(e) => err.with_source(e),
                _ => err,
            }
        })
    }

    async fn read_value(&mut self, addr: u16, what: &str) -> DeviceResult<f64> {
        let op = Op::Read { addr, count: self.map.encoding.word_count() };
        let words = self.transact(&op, what).await?;
        Ok(self.map.encoding.decode(&words, self.decimals)?)
    }

    async fn write_setpoint(&mut self, temp_c: f64) -> DeviceResult<()> {
        let (addr, words) = self.map.set_point_writes(temp_c, self.decimals)?;
        self.transact(&Op::Write { addr, words }, "set point").await?;
        self.setpoint_c = temp_c;
        Ok(())
    }

    fn limit_ramp(&self, from_c: f64, target_c: f64, ramp_c_s: f64) -> f64 {
        let caps = &self.info.capabilities;
        let max = if target_c >= from_c { caps.max_heat_rate_c_s } else { caps.max_cool_rate_c_s };
        if ramp_c_s > max {
            tracing::debug!(requested_c_s = ramp_c_s, used_c_s = max, "ramp limited to capability");
        }
        ramp_c_s.min(max)
    }
}

#[async_trait]
impl Chamber for ModbusChamber {
    fn info(&self) -> &DeviceInfo<ChamberCapabilities> {
        &self.info
    }

    async fn set_target(&mut self, target_c: f64, ramp_c_s: Option<f64>) -> DeviceResult<()> {
        let caps = &self.info.capabilities;
        if !(target_c >= caps.min_temp_c && target_c <= caps.max_temp_c) {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!(
                    "target {target_c} °C is outside {}..{} °C",
                    caps.min_temp_c, caps.max_temp_c
                ),
            ));
        }
        if let Some(r) = ramp_c_s {
            if !(r.is_finite() && r > 0.0) {
                return Err(DeviceError::new(
                    ErrorKind::OutOfRange,
                    format!("ramp {r} °C/s must be a positive number"),
                ));
            }
        }
        let res = caps.temp_resolution_c;
        if let Some(rate_reg) = self.map.ramp_rate {
            // The controller ramps: rate limit first (0 = off), then the set point.
            let from = self.setpoint_c;
            let per_unit = ramp_c_s
                .map(|r| self.limit_ramp(from, target_c, r) * self.config.rate_units.seconds())
                .unwrap_or(0.0);
            let words = self.map.encoding.encode(per_unit, self.decimals)?;
            self.transact(&Op::Write { addr: rate_reg, words }, "set-point rate limit").await?;
            self.stepping = None;
            self.write_setpoint(target_c).await?;
            self.target_c = target_c;
            return Ok(());
        }
        let Some(ramp) = ramp_c_s else {
            self.stepping = None;
            self.write_setpoint(target_c).await?;
            self.target_c = target_c;
            return Ok(());
        };
        // The driver ramps: start from the working set point.
        let start_c = match self.map.working_set_point {
            Some(wsp) => self.read_value(wsp, "working set point").await?,
            None => match self.stepping {
                Some(s) => s.written_c,
                None => self.setpoint_c,
            },
        };
        let now = self.clock.now();
        let rate_c_s = self.limit_ramp(start_c, target_c, ramp);
        let first = quantise(start_c, res);
        self.stepping = Some(Stepping {
            start_c,
            start_t: now,
            rate_c_s,
            target_c,
            written_c: first,
            written_at: now,
        });
        self.target_c = target_c;
        if (first - self.setpoint_c).abs() > res / 2.0 {
            self.write_setpoint(first).await?;
        }
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<ChamberReading> {
        let temperature_c = self.read_value(self.map.process_value, "process value").await?;
        let res = self.info.capabilities.temp_resolution_c;
        let setpoint_c = match self.map.working_set_point {
            Some(wsp) => self.read_value(wsp, "working set point").await?,
            None => self.setpoint_c,
        };
        let mut st = 0;
        // Ramping until both the set point written and the working set point read are there.
        let stepping = self.stepping.is_some_and(|s| (s.written_c - s.target_c).abs() > res / 2.0);
        let ramping = stepping || (setpoint_c - self.target_c).abs() > res / 2.0;
        if ramping {
            st |= status::chamber::RAMPING;
        }
        for (bits, flag, what) in [
            (self.map.alarm, status::chamber::ALARM, "alarm status"),
            (self.map.door, status::chamber::DOOR_OPEN, "door status"),
        ] {
            let Some(bits) = bits else { continue };
            let words = self.transact(&Op::Read { addr: bits.register, count: 1 }, what).await?;
            if words.first().is_some_and(|w| bits.set_in(*w)) {
                st |= flag;
            }
        }
        Ok(ChamberReading {
            temperature_c,
            setpoint_c,
            target_c: self.target_c,
            status: st,
            device_time: None,
        })
    }

    /// Writes the next step of a driver-run ramp when one is due: every `step_period_s` of bench
    /// time, and only if the quantised set point changed; the last step is the target itself.
    async fn service(&mut self) -> DeviceResult<()> {
        let Some(mut s) = self.stepping else { return Ok(()) };
        let now = self.clock.now();
        let res = self.info.capabilities.temp_resolution_c;
        let due = now.saturating_sub(s.written_at).as_secs_f64() >= self.config.step_period_s;
        let ideal = s.at(now);
        let done = ideal == s.target_c;
        if !(due || done) {
            return Ok(());
        }
        let next = if done { s.target_c } else { quantise(ideal, res) };
        if (next - s.written_c).abs() > res / 2.0 || (done && next != s.written_c) {
            self.write_setpoint(next).await?;
            s.written_c = next;
            s.written_at = now;
        }
        self.stepping = if done { None } else { Some(s) };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_defaults_and_custom_maps_parse() {
        let cfg: ModbusChamberConfig = toml::from_str(
            r#"
            endpoint = { serial = { path = "/dev/ttyUSB0", baud = 9600 } }
            map = "watlow_f4"
            model_check = { register = 0, value = 5270 }
            "#,
        )
        .expect("parses");
        assert_eq!(cfg.map.map(), RegisterMap::preset(Preset::WatlowF4));
        assert_eq!(cfg.retries, 2);
        assert_eq!(cfg.retry_policy(), RetryPolicy::from_seconds(2, 0.05));
        assert_eq!(cfg.request_timeout(), Duration::from_millis(300));
        assert_eq!(cfg.step_period_s, 1.0);
        assert_eq!(cfg.rate_units, RateUnits::PerMinute);
        assert_eq!(cfg.capabilities, CapabilityConfig::default());
        assert_eq!(cfg.model_check, Some(ModelCheck { register: 0, value: 5270 }));

        let cfg: ModbusChamberConfig = toml::from_str(
            r#"
            endpoint = { tcp = { addr = "10.0.0.2:502" } }
            unit_id = 7
            [map]
            model = "F4T loop 2"
            process_value = 2980
            set_point = 2942
            working_set_point = 2970
            encoding = { type = "float32", word_order = "low_word_first" }
            [capabilities]
            min_temp_c = -70.0
            "#,
        )
        .expect("parses");
        assert_eq!(cfg.unit_id, 7);
        assert_eq!(cfg.map.map().process_value, 2980);
        assert_eq!(cfg.capabilities.min_temp_c, -70.0);
        assert_eq!(cfg.capabilities.max_temp_c, 185.0);
    }

    #[test]
    fn times_in_seconds_and_the_older_milliseconds_but_not_both() {
        let parse = |extra: &str| {
            toml::from_str::<ModbusChamberConfig>(&format!(
                "endpoint = {{ tcp = {{ addr = \"a:1\" }} }}\nmap = \"watlow_f4\"\n{extra}"
            ))
            .expect("parses")
        };
        let s = parse("request_timeout_s = 0.15\nretry_backoff_s = 0.01\n");
        assert_eq!(s.request_timeout(), Duration::from_millis(150));
        assert_eq!(s.retry_policy().backoff, Duration::from_millis(10));
        let ms = parse("request_timeout_ms = 150\nretry_backoff_ms = 10\n");
        assert_eq!(
            (ms.request_timeout(), ms.retry_policy()),
            (s.request_timeout(), s.retry_policy())
        );
        assert!(s.validate().is_ok() && ms.validate().is_ok());
        let both = parse("retry_backoff_s = 0.01\nretry_backoff_ms = 10\n");
        assert_eq!(both.given_twice(), [("retry_backoff_s", "retry_backoff_ms")]);
        let e = both.validate().expect_err("both forms");
        assert!(
            e.to_string().contains("`retry_backoff_s` and the older `retry_backoff_ms`"),
            "{e}"
        );
    }

    #[test]
    fn unknown_fields_are_rejected() {
        let e = toml::from_str::<ModbusChamberConfig>(
            "endpoint = { tcp = { addr = \"a:1\" } }\nmap = \"watlow_f4\"\ntimeout = 3\n",
        )
        .expect_err("unknown field");
        assert!(e.to_string().contains("timeout"), "{e}");
    }

    #[test]
    fn failures_map_to_kinds_with_the_exception_meaning() {
        let t = Duration::from_millis(300);
        let f = Failure::Exception(ExceptionCode::ServerDeviceFailure);
        assert_eq!(f.kind(), ErrorKind::DeviceFault);
        assert_eq!(f.describe(t), "Modbus exception 0x04 (server device failure)");
        assert_eq!(
            Failure::Exception(ExceptionCode::IllegalDataValue).kind(),
            ErrorKind::OutOfRange
        );
        assert_eq!(
            Failure::Exception(ExceptionCode::IllegalDataAddress).kind(),
            ErrorKind::Unsupported
        );
        assert!(!ErrorKind::Unsupported.is_transient() && !ErrorKind::DeviceFault.is_transient());
        assert_eq!(Failure::NoReply { bytes: 0 }.kind(), ErrorKind::Timeout);
        assert_eq!(Failure::NoReply { bytes: 7 }.kind(), ErrorKind::Protocol);
        let io = std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        assert_eq!(Failure::Modbus(io.into()).kind(), ErrorKind::Link);
    }

    #[test]
    fn stepping_moves_at_the_rate_and_stops_at_the_target() {
        let s = Stepping {
            start_c: 20.0,
            start_t: Duration::from_secs(10),
            rate_c_s: 0.5,
            target_c: 18.0,
            written_c: 20.0,
            written_at: Duration::from_secs(10),
        };
        assert_eq!(s.at(Duration::from_secs(12)), 19.0);
        assert_eq!(s.at(Duration::from_secs(100)), 18.0);
        assert_eq!(s.at(Duration::from_secs(5)), 20.0);
    }
}
