//! Real rate-table driver: an Actidyn (ST1300 class) or Acutronic ACUTROL controller over a
//! serial port or TCP, behind the [`RateTable`] trait.
//!
//! One driver, [`RateTableDriver`], speaks either [`Dialect`] through the pure codecs in
//! [`crate::protocol::actidyn`] and [`crate::protocol::acutrol`]. Both command sets are
//! **inferred from public third-party client code, not from the manufacturers' manuals** (see
//! `docs/protocols/table.md`); so are the error codes in [`actidyn_errors`].
//!
//! What goes on the wire (axis 1):
//!
//! | call | Actidyn | ACUTROL |
//! |---|---|---|
//! | session start (connect, reconnect) | `RMT 0:ALC 0` | `:utility:lockout on`, `:interlock:open 1`, `:interlock:reset 1`, `:interlock:close 1` |
//! | [`RateTable::read`] (also the connect probe) | `PRV 1,?:MOD 1,?` | `:read:position 1`, `:read:rate 1` |
//! | [`RateTable::set_rate`] | `MOD 1,RAT:RAT 1,<°/s>,<°/s²>` | `:mode:rate 1` (when not already in rate mode), `:demand:rate 1, <°/s>` |
//! | [`RateTable::stop`] | `MOD 1,STP` | `:demand:rate 1, 0` |
//! | [`RateTable::service`] when due | `ALC 0` (keep-alive) | nothing |
//! | [`RateTableDriver::release`] | `MOD 1,OFF:LOC 0` | `:mode:off 1`, `:interlock:open 1`, `:utility:lockout off` |
//!
//! Link behaviour ([`super::link`], the one retry policy of line and Modbus devices): every
//! exchange waits at most `reply_timeout_s` (wall-clock time: it bounds I/O) and is retried
//! `retries` times with a doubling back-off on timeouts, link faults and unreadable replies. A link fault drops the connection; the next attempt reopens the endpoint
//! and repeats the session start. An unreadable reply is counted ([`LinkCounters`]), skipped,
//! and the command is sent again; device error replies are not retried. The keep-alive period is
//! bench time on the driver's [`Clock`], so a scaled-time run against a simulator keeps the same
//! 20 s / 30 s relation as the real controller.
//!
//! ```no_run
//! # async fn demo() -> Result<(), bench_drivers::DeviceError> {
//! use bench_drivers::protocol::Dialect;
//! use bench_drivers::real::table::{RateTableDriver, TableDriverConfig};
//! use bench_drivers::transport::Endpoint;
//! use bench_drivers::RateTable;
//! let cfg = TableDriverConfig::new(Endpoint::Tcp { addr: "192.168.0.20:62000".into() }, Dialect::Actidyn);
//! let mut table = RateTableDriver::connect(cfg).await?;
//! table.set_rate(10.0_f64.to_radians() / 60.0, 1.0_f64.to_radians()).await?;
//! let reading = table.read().await?;
//! # let _ = reading; Ok(()) }
//! ```

use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use bench_physics::units::{ARCSEC, DEG};
use serde::{Deserialize, Serialize};

pub use super::link::LinkCounters;
use super::link::{shown, Attempt, LineLink, RetryPolicy};
use crate::clock::{Clock, SystemClock};
use crate::protocol::{actidyn, acutrol};
use crate::protocol::{Dialect, LineFormat};
use crate::transport::Endpoint;
use crate::{
    DeviceError, DeviceInfo, DeviceResult, ErrorKind, RateTable, TableCapabilities, TableMode,
    TableReading,
};
use bench_recording::status;

/// Configuration of a real rate table (a `[table]` section of a bench config).
///
/// Only `endpoint` is required. Capabilities default to **conservative guesses**: no ST1300
/// spec sheet is public, so `max_rate_deg_s` and `max_accel_deg_s2` must be set from the lab's
/// table documentation before scenarios that need more are run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableDriverConfig {
    /// Where the controller is reached (serial port or TCP; the public Actidyn client used TCP
    /// port 62000, ACUTROL clients 9888).
    pub endpoint: Endpoint,
    /// Controller language (default `actidyn`).
    #[serde(default)]
    pub dialect: Dialect,
    /// Axis number (default 1).
    #[serde(default = "default_axis")]
    pub axis: u8,
    /// Longest wait for one reply, s of wall-clock time (default 0.5). Also the TCP connect
    /// timeout, with a floor of 1 s.
    #[serde(default = "default_reply_timeout_s")]
    pub reply_timeout_s: f64,
    /// How many times an exchange is retried after a timeout, link fault or unreadable reply
    /// (default 3, so 4 attempts in all).
    #[serde(default = "default_retries")]
    pub retries: u32,
    /// Wait before the first retry, s of wall-clock time, doubled at each further retry
    /// (default 0.05: 50, 100, 200 ms).
    #[serde(default = "default_retry_backoff_s")]
    pub retry_backoff_s: f64,
    /// Actidyn keep-alive period, s of bench time (default 20): [`RateTable::service`] sends
    /// `ALC 0` when this much time has passed since the last one. The controller switches the
    /// drive off if alarms are not cleared within 30 s. 0 disables the keep-alive (only for
    /// testing the controller's watchdog). Ignored for ACUTROL.
    #[serde(default = "default_keep_alive_s")]
    pub keep_alive_s: f64,
    /// Acceleration used when a caller passes 0 to `set_rate` or `stop`, °/s² (default 1).
    #[serde(default = "default_accel_deg_s2")]
    pub default_accel_deg_s2: f64,
    /// Largest rate magnitude reported and enforced, °/s (default 100: a conservative guess,
    /// the ST1300's limit is not public).
    #[serde(default = "default_max_rate_deg_s")]
    pub max_rate_deg_s: f64,
    /// Largest acceleration magnitude reported and enforced, °/s² (default 10: a conservative
    /// guess, the ST1300's limit is not public).
    #[serde(default = "default_max_accel_deg_s2")]
    pub max_accel_deg_s2: f64,
    /// Position readout resolution, arc-seconds (default 1, the ST1300's positioning accuracy).
    #[serde(default = "default_resolution_arcsec")]
    pub position_resolution_arcsec: f64,
    /// Model reported in [`DeviceInfo`] (default `Actidyn ST1300` or `Acutronic ACUTROL table`).
    #[serde(default)]
    pub model: Option<String>,
    /// ACUTROL: write short keyword forms (`:M:R 1`) instead of long ones (default false).
    #[serde(default)]
    pub acutrol_short_form: bool,
    /// ACUTROL: decimals of demand values (default 6; the public client wrote 3, which limits
    /// 10 °/min to 0.2 %: set 3 if the controller rejects more).
    #[serde(default = "default_acutrol_decimals")]
    pub acutrol_decimals: u8,
}

fn default_axis() -> u8 {
    1
}
fn default_reply_timeout_s() -> f64 {
    0.5
}
fn default_retries() -> u32 {
    3
}
fn default_retry_backoff_s() -> f64 {
    0.05
}
fn default_keep_alive_s() -> f64 {
    actidyn::KEEP_ALIVE_S
}
fn default_accel_deg_s2() -> f64 {
    1.0
}
fn default_max_rate_deg_s() -> f64 {
    100.0
}
fn default_max_accel_deg_s2() -> f64 {
    10.0
}
fn default_resolution_arcsec() -> f64 {
    1.0
}
fn default_acutrol_decimals() -> u8 {
    6
}

impl TableDriverConfig {
    /// A configuration with every default.
    pub fn new(endpoint: Endpoint, dialect: Dialect) -> Self {
        Self {
            endpoint,
            dialect,
            axis: default_axis(),
            reply_timeout_s: default_reply_timeout_s(),
            retries: default_retries(),
            retry_backoff_s: default_retry_backoff_s(),
            keep_alive_s: default_keep_alive_s(),
            default_accel_deg_s2: default_accel_deg_s2(),
            max_rate_deg_s: default_max_rate_deg_s(),
            max_accel_deg_s2: default_max_accel_deg_s2(),
            position_resolution_arcsec: default_resolution_arcsec(),
            model: None,
            acutrol_short_form: false,
            acutrol_decimals: default_acutrol_decimals(),
        }
    }

    /// Checks that every number is usable; the error names the field.
    pub fn validate(&self) -> Result<(), DeviceError> {
        let positive = [
            ("reply_timeout_s", self.reply_timeout_s),
            ("default_accel_deg_s2", self.default_accel_deg_s2),
            ("max_rate_deg_s", self.max_rate_deg_s),
            ("max_accel_deg_s2", self.max_accel_deg_s2),
            ("position_resolution_arcsec", self.position_resolution_arcsec),
        ];
        let non_negative =
            [("retry_backoff_s", self.retry_backoff_s), ("keep_alive_s", self.keep_alive_s)];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0 && v < 1e9) {
                return Err(config_error(format!("{name} = {v}: expected a positive number")));
            }
        }
        for (name, v) in non_negative {
            if !(v.is_finite() && (0.0..1e9).contains(&v)) {
                return Err(config_error(format!("{name} = {v}: expected a number ≥ 0")));
            }
        }
        if self.acutrol_decimals > 9 {
            return Err(config_error(format!(
                "acutrol_decimals = {}: expected 0..=9",
                self.acutrol_decimals
            )));
        }
        Ok(())
    }

    /// The retry policy of its exchanges.
    pub fn retry_policy(&self) -> RetryPolicy {
        RetryPolicy::from_seconds(self.retries, self.retry_backoff_s)
    }

    fn acutrol_encoding(&self) -> acutrol::Encoding {
        acutrol::Encoding {
            form: if self.acutrol_short_form { acutrol::Form::Short } else { acutrol::Form::Long },
            decimals: self.acutrol_decimals,
        }
    }
}

fn config_error(msg: String) -> DeviceError {
    DeviceError::new(ErrorKind::Other, format!("table driver config: {msg}"))
}

/// Tracks whole turns of a position readout that wraps (at 360° or ±180°), so the reported
/// angle is unwrapped. Needs readings less than half a turn apart.
#[derive(Debug, Clone, Copy, Default)]
struct Unwrapper {
    last_deg: Option<f64>,
    turns: i64,
}

impl Unwrapper {
    fn update(&mut self, raw_deg: f64) -> f64 {
        if let Some(last) = self.last_deg {
            let d = raw_deg - last;
            if d > 180.0 {
                self.turns -= 1;
            } else if d < -180.0 {
                self.turns += 1;
            }
        }
        self.last_deg = Some(raw_deg);
        raw_deg + 360.0 * self.turns as f64
    }
}

/// What a telemetry read returns, in the controller's units.
#[derive(Debug, Clone, Copy)]
struct Telemetry {
    position_deg: f64,
    rate_deg_s: f64,
    /// The mode, when the controller reports it.
    mode: Option<TableMode>,
}

/// A controller dialect: its commands for each of the driver's calls, its replies, its
/// session. One implementation per dialect ([`ActidynLine`], [`AcutrolLine`]); the driver
/// holds one and never asks which.
#[async_trait]
trait Controller: Send {
    /// The model reported when the config names none.
    fn default_model(&self) -> &'static str;
    /// Whether the link is open.
    fn connected(&self) -> bool;
    /// Link statistics.
    fn counters(&self) -> LinkCounters;
    /// The drive alarm: set by the controller's alarm reply or an unexpected drive-off,
    /// cleared by a rate command it accepts.
    fn alarm(&mut self) -> &mut bool;
    /// Open the link and take remote control (with retries).
    async fn connect(&mut self) -> DeviceResult<()>;
    /// Clear the controller's alarms.
    async fn clear_alarms(&mut self) -> DeviceResult<()>;
    /// Drive off, control back to the front panel.
    async fn release(&mut self) -> DeviceResult<()>;
    /// Rate mode at `rate_deg_s`; `mode` is the mode as commanded, updated as it changes.
    async fn set_rate(
        &mut self,
        mode: &mut TableMode,
        rate_deg_s: f64,
        accel_deg_s2: f64,
    ) -> DeviceResult<()>;
    /// A controlled stop; `mode` as in [`Controller::set_rate`].
    async fn stop(&mut self, mode: &mut TableMode) -> DeviceResult<()>;
    /// Position, rate and (where the dialect reports it) the mode.
    async fn read(&mut self) -> DeviceResult<Telemetry>;
    /// What must be sent on time (a keep-alive), when due.
    async fn service(&mut self) -> DeviceResult<()>;
}

/// A dialect on its line link.
#[async_trait]
trait OnLine: Send {
    /// The format of its reply lines.
    type Replies: LineFormat;
    /// The link.
    fn link(&mut self) -> &mut LineLink<Self::Replies>;
    /// Take remote control on an open link, one attempt.
    async fn session(&mut self) -> DeviceResult<()>;
}

/// Reopen `c`'s link and start its session if the link was dropped.
async fn ensure_open<C: OnLine>(c: &mut C) -> DeviceResult<()> {
    if c.link().is_open() {
        return Ok(());
    }
    c.link().open().await?;
    c.link().counters.reconnects += 1;
    tracing::info!(endpoint = %c.link().endpoint, "rate table link reopened");
    if let Err(e) = c.session().await {
        if e.kind() == ErrorKind::Link {
            c.link().close();
        }
        return Err(e);
    }
    Ok(())
}

/// Open `c`'s link and take remote control, with retries.
async fn open_session<C: OnLine>(c: &mut C) -> DeviceResult<()> {
    c.link().open().await?;
    with_retries(c, "session start", |me| {
        Box::pin(async move {
            ensure_open(me).await?;
            me.session().await
        })
    })
    .await
}

/// One exchange of `c` under the link's retry policy (`attempt` reopens the link and restarts
/// the session first when it was dropped). Retries are counted; an error after the last
/// attempt says how many were made.
async fn with_retries<C, T, A>(c: &mut C, what: &str, attempt: A) -> DeviceResult<T>
where
    C: OnLine,
    T: Send,
    A: for<'a> FnMut(&'a mut C) -> Attempt<'a, T, DeviceError> + Send,
{
    let policy = c.link().policy;
    let r = policy.run(c, what, attempt, |c, e| c.link().note_failure(e)).await;
    c.link().counters.retries += u64::from(r.attempts.saturating_sub(1));
    r.result.map_err(|e| {
        if e.kind().is_transient() {
            DeviceError::new(e.kind(), format!("{} ({} attempts)", e.message(), r.attempts))
        } else {
            e
        }
    })
}

/// The Actidyn dialect (ST1300 class): `MNEMONIC axis,args` commands joined by `:` on one
/// line, a keep-alive `ALC 0` within the controller's 30 s.
struct ActidynLine {
    link: LineLink<actidyn::ReplyLines>,
    axis: u8,
    clock: Arc<dyn Clock>,
    keep_alive_s: f64,
    last_keep_alive: Duration,
    alarm: bool,
}

#[async_trait]
impl OnLine for ActidynLine {
    type Replies = actidyn::ReplyLines;
    fn link(&mut self) -> &mut LineLink<actidyn::ReplyLines> {
        &mut self.link
    }

    /// Take remote control: `RMT 0:ALC 0`, one attempt.
    async fn session(&mut self) -> DeviceResult<()> {
        self.once(&[actidyn::Command::Remote, actidyn::Command::ClearAlarms]).await?;
        self.last_keep_alive = self.clock.now();
        Ok(())
    }
}

impl ActidynLine {
    fn axis(&self) -> actidyn::Axis {
        actidyn::Axis::Number(self.axis)
    }

    /// One exchange, one attempt: the replies, one per command, or the first error.
    async fn once(&mut self, cmds: &[actidyn::Command]) -> DeviceResult<Vec<actidyn::Reply>> {
        let line = actidyn::encode_commands(cmds)?;
        self.link.send(&line).await?;
        let deadline = self.link.deadline();
        loop {
            match self.link.decoder.next_message() {
                None => self.link.fill(&line, deadline).await?,
                Some(Err(e)) => return Err(self.link.protocol_error(&line, e)),
                Some(Ok(replies)) => {
                    let answers = replies.len() == cmds.len()
                        && replies.iter().zip(cmds).all(|(r, c)| r.answers(c));
                    if !answers {
                        self.link.counters.stale_replies += 1;
                        tracing::debug!(?replies, "reply to another command skipped");
                        continue;
                    }
                    for r in &replies {
                        if let actidyn::ReplyBody::Error { code, message } = &r.body {
                            let kind = actidyn::error_kind(*code);
                            if *code == actidyn::errors::DRIVE_ALARM {
                                self.alarm = true;
                            }
                            return Err(DeviceError::new(
                                kind,
                                format!(
                                    "sent `{}` on {}, the controller refused `{} {}`: error {code} {message}",
                                    shown(&line),
                                    self.link.endpoint,
                                    r.mnemonic.as_str(),
                                    r.axis
                                ),
                            ));
                        }
                    }
                    return Ok(replies);
                }
            }
        }
    }

    /// An exchange with retries.
    async fn exchange(&mut self, cmds: &[actidyn::Command]) -> DeviceResult<Vec<actidyn::Reply>> {
        let cmds = cmds.to_vec();
        with_retries(self, "rate-table exchange", move |me| {
            let cmds = cmds.clone();
            Box::pin(async move {
                ensure_open(me).await?;
                me.once(&cmds).await
            })
        })
        .await
    }
}

#[async_trait]
impl Controller for ActidynLine {
    fn default_model(&self) -> &'static str {
        "Actidyn ST1300"
    }

    fn connected(&self) -> bool {
        self.link.is_open()
    }

    fn counters(&self) -> LinkCounters {
        self.link.counters
    }

    fn alarm(&mut self) -> &mut bool {
        &mut self.alarm
    }

    async fn connect(&mut self) -> DeviceResult<()> {
        open_session(self).await
    }

    async fn clear_alarms(&mut self) -> DeviceResult<()> {
        self.exchange(&[actidyn::Command::ClearAlarms]).await?;
        self.last_keep_alive = self.clock.now();
        Ok(())
    }

    async fn release(&mut self) -> DeviceResult<()> {
        let axis = self.axis();
        self.exchange(&[
            actidyn::Command::SetMode { axis, mode: actidyn::Mode::Off },
            actidyn::Command::Local,
        ])
        .await?;
        Ok(())
    }

    async fn set_rate(
        &mut self,
        _mode: &mut TableMode,
        rate_deg_s: f64,
        accel_deg_s2: f64,
    ) -> DeviceResult<()> {
        let axis = self.axis();
        self.exchange(&[
            actidyn::Command::SetMode { axis, mode: actidyn::Mode::Rate },
            actidyn::Command::Rate { axis, rate_deg_s, accel_deg_s2 },
        ])
        .await?;
        Ok(())
    }

    /// `MOD 1,STP`: the controller's own controlled stop.
    async fn stop(&mut self, mode: &mut TableMode) -> DeviceResult<()> {
        let axis = self.axis();
        self.exchange(&[actidyn::Command::SetMode { axis, mode: actidyn::Mode::Stop }]).await?;
        *mode = TableMode::Stopped;
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<Telemetry> {
        let axis = self.axis();
        let cmds = [actidyn::Command::QueryPrv { axis }, actidyn::Command::QueryMode { axis }];
        let replies = self.exchange(&cmds).await?;
        let prv = replies.first().and_then(actidyn::Reply::prv);
        let mode = replies.get(1).and_then(actidyn::Reply::modes).and_then(|m| m.first().copied());
        let (Some(prv), Some(mode)) = (prv, mode) else {
            self.link.counters.corrupt_replies += 1;
            return Err(DeviceError::new(
                ErrorKind::Protocol,
                format!(
                    "sent `PRV {axis},?:MOD {axis},?` on {}, expected 3 values and a mode, got {replies:?}",
                    self.link.endpoint
                ),
            ));
        };
        Ok(Telemetry {
            position_deg: prv.position_deg,
            rate_deg_s: prv.rate_deg_s,
            mode: Some(table_mode(mode)),
        })
    }

    /// `ALC 0` when `keep_alive_s` of bench time has passed since the last one.
    async fn service(&mut self) -> DeviceResult<()> {
        if self.keep_alive_s <= 0.0 {
            return Ok(());
        }
        let now = self.clock.now();
        if now.saturating_sub(self.last_keep_alive).as_secs_f64() < self.keep_alive_s {
            return Ok(());
        }
        self.exchange(&[actidyn::Command::ClearAlarms]).await?;
        self.last_keep_alive = now;
        self.link.counters.keep_alives += 1;
        Ok(())
    }
}

/// The ACUTROL dialect (SCPI-like keywords, one command a line, `OK`, a value or `ERR`).
struct AcutrolLine {
    link: LineLink<acutrol::ReplyLines>,
    axis: u8,
    encoding: acutrol::Encoding,
    alarm: bool,
}

#[async_trait]
impl OnLine for AcutrolLine {
    type Replies = acutrol::ReplyLines;
    fn link(&mut self) -> &mut LineLink<acutrol::ReplyLines> {
        &mut self.link
    }

    /// Take remote control: lockout, then open, reset and close the interlock; one attempt
    /// per command.
    async fn session(&mut self) -> DeviceResult<()> {
        let a = self.axis;
        for c in [
            acutrol::Command::Lockout(true),
            acutrol::Command::InterlockOpen(a),
            acutrol::Command::InterlockReset(a),
            acutrol::Command::InterlockClose(a),
        ] {
            self.once(c).await?;
        }
        Ok(())
    }
}

impl AcutrolLine {
    /// One exchange, one attempt.
    async fn once(&mut self, cmd: acutrol::Command) -> DeviceResult<acutrol::Reply> {
        let line = cmd.encode(self.encoding)?;
        self.link.send(&line).await?;
        let deadline = self.link.deadline();
        loop {
            let reply = match self.link.decoder.next_message() {
                None => {
                    self.link.fill(&line, deadline).await?;
                    continue;
                }
                Some(Err(e)) => return Err(self.link.protocol_error(&line, e)),
                Some(Ok(r)) => r,
            };
            return match (&reply, cmd.is_query()) {
                (acutrol::Reply::Error(text), _) => Err(DeviceError::new(
                    acutrol::error_kind(text),
                    format!(
                        "sent `{}` on {}, the controller refused it: ERR {text}",
                        shown(&line),
                        self.link.endpoint
                    ),
                )),
                (acutrol::Reply::Value(_), true) | (acutrol::Reply::Ok, false) => Ok(reply),
                (other, query) => {
                    // A late answer to an earlier command: the stream is out of step.
                    self.link.counters.stale_replies += 1;
                    Err(DeviceError::new(
                        ErrorKind::Protocol,
                        format!(
                            "sent `{}` on {}, expected {}, got {other:?}",
                            shown(&line),
                            self.link.endpoint,
                            if query { "a number" } else { "OK" }
                        ),
                    ))
                }
            };
        }
    }

    /// An exchange with retries.
    async fn exchange(&mut self, cmd: acutrol::Command) -> DeviceResult<acutrol::Reply> {
        with_retries(self, "rate-table exchange", move |me| {
            Box::pin(async move {
                ensure_open(me).await?;
                me.once(cmd).await
            })
        })
        .await
    }
}

#[async_trait]
impl Controller for AcutrolLine {
    fn default_model(&self) -> &'static str {
        "Acutronic ACUTROL table"
    }

    fn connected(&self) -> bool {
        self.link.is_open()
    }

    fn counters(&self) -> LinkCounters {
        self.link.counters
    }

    fn alarm(&mut self) -> &mut bool {
        &mut self.alarm
    }

    async fn connect(&mut self) -> DeviceResult<()> {
        open_session(self).await
    }

    async fn clear_alarms(&mut self) -> DeviceResult<()> {
        let a = self.axis;
        self.exchange(acutrol::Command::InterlockReset(a)).await?;
        self.exchange(acutrol::Command::InterlockClose(a)).await?;
        Ok(())
    }

    async fn release(&mut self) -> DeviceResult<()> {
        let a = self.axis;
        self.exchange(acutrol::Command::ModeOff(a)).await?;
        self.exchange(acutrol::Command::InterlockOpen(a)).await?;
        self.exchange(acutrol::Command::Lockout(false)).await?;
        Ok(())
    }

    /// The known ACUTROL command set has no acceleration argument: the controller's own limits
    /// apply.
    async fn set_rate(
        &mut self,
        mode: &mut TableMode,
        rate_deg_s: f64,
        _accel_deg_s2: f64,
    ) -> DeviceResult<()> {
        let a = self.axis;
        if *mode != TableMode::Rate {
            self.exchange(acutrol::Command::ModeRate(a)).await?;
            *mode = TableMode::Rate;
        }
        self.exchange(acutrol::Command::DemandRate { axis: a, rate_deg_s }).await?;
        Ok(())
    }

    /// Demand rate 0, held in rate mode.
    async fn stop(&mut self, mode: &mut TableMode) -> DeviceResult<()> {
        let a = self.axis;
        self.exchange(acutrol::Command::DemandRate { axis: a, rate_deg_s: 0.0 }).await?;
        if *mode == TableMode::Rate {
            *mode = TableMode::Stopped;
        }
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<Telemetry> {
        let a = self.axis;
        let pos = self.exchange(acutrol::Command::ReadPosition(a)).await?;
        let rate = self.exchange(acutrol::Command::ReadRate(a)).await?;
        let (acutrol::Reply::Value(p), acutrol::Reply::Value(r)) = (pos, rate) else {
            return Err(DeviceError::new(ErrorKind::Protocol, "expected two values"));
        };
        Ok(Telemetry { position_deg: p, rate_deg_s: r, mode: None })
    }

    /// Nothing is due: the ACUTROL has no keep-alive.
    async fn service(&mut self) -> DeviceResult<()> {
        Ok(())
    }
}

/// The controller of `cfg`'s dialect on `cfg`'s endpoint (closed until `connect`).
fn controller(cfg: &TableDriverConfig, clock: Arc<dyn Clock>) -> Box<dyn Controller> {
    let timeout = Duration::from_secs_f64(cfg.reply_timeout_s);
    let policy = cfg.retry_policy();
    match cfg.dialect {
        Dialect::Actidyn => Box::new(ActidynLine {
            link: LineLink::new(cfg.endpoint.clone(), timeout, policy),
            axis: cfg.axis,
            last_keep_alive: clock.now(),
            clock,
            keep_alive_s: cfg.keep_alive_s,
            alarm: false,
        }),
        Dialect::Acutrol => Box::new(AcutrolLine {
            link: LineLink::new(cfg.endpoint.clone(), timeout, policy),
            axis: cfg.axis,
            encoding: cfg.acutrol_encoding(),
            alarm: false,
        }),
    }
}

/// A real rate table (Actidyn or ACUTROL dialect) behind [`RateTable`]. See the module docs
/// for what each call sends.
pub struct RateTableDriver {
    cfg: TableDriverConfig,
    info: DeviceInfo<TableCapabilities>,
    ctl: Box<dyn Controller>,
    unwrap: Unwrapper,
    rate_command_rad_s: f64,
    /// Mode as commanded by this driver.
    mode: TableMode,
}

impl std::fmt::Debug for RateTableDriver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RateTableDriver")
            .field("driver", &self.info.driver)
            .field("connected", &self.ctl.connected())
            .field("counters", &self.ctl.counters())
            .finish_non_exhaustive()
    }
}

impl RateTableDriver {
    /// Open the endpoint, take remote control and probe with a telemetry read, keeping the
    /// keep-alive on wall-clock time. See [`Self::connect_with_clock`].
    pub async fn connect(cfg: TableDriverConfig) -> DeviceResult<Self> {
        Self::connect_with_clock(cfg, Arc::new(SystemClock::new(1.0))).await
    }

    /// Open the endpoint, take remote control (Actidyn `RMT 0:ALC 0`; ACUTROL lockout and
    /// interlock close) and probe with a telemetry read. The keep-alive runs on `clock`'s bench
    /// time. On failure the error says what was sent where and what came back.
    pub async fn connect_with_clock(
        cfg: TableDriverConfig,
        clock: Arc<dyn Clock>,
    ) -> DeviceResult<Self> {
        cfg.validate()?;
        let ctl = controller(&cfg, clock);
        let info = DeviceInfo {
            model: cfg.model.clone().unwrap_or_else(|| ctl.default_model().to_owned()),
            driver: format!("{}/{}", cfg.dialect, cfg.endpoint),
            capabilities: TableCapabilities {
                max_rate_rad_s: cfg.max_rate_deg_s * DEG,
                max_accel_rad_s2: cfg.max_accel_deg_s2 * DEG,
                position_resolution_rad: cfg.position_resolution_arcsec * ARCSEC,
            },
        };
        let mut me = Self {
            info,
            ctl,
            unwrap: Unwrapper::default(),
            rate_command_rad_s: 0.0,
            mode: TableMode::Off,
            cfg,
        };
        let what = format!("connecting to the {} table on {}", me.cfg.dialect, me.cfg.endpoint);
        me.ctl.connect().await.map_err(|e| context(&what, e))?;
        let r = me.read().await.map_err(|e| context(&what, e))?;
        // The probe tells the actual mode: do not claim the drive is off if it is running.
        me.mode = r.mode;
        me.rate_command_rad_s = if r.mode == TableMode::Rate { r.rate_rad_s } else { 0.0 };
        *me.ctl.alarm() = false;
        tracing::info!(driver = %me.info.driver, angle_rad = r.angle_rad, "rate table connected");
        Ok(me)
    }

    /// Link statistics.
    pub fn counters(&self) -> LinkCounters {
        self.ctl.counters()
    }

    /// The configuration in use.
    pub fn config(&self) -> &TableDriverConfig {
        &self.cfg
    }

    /// Clear the controller's alarms now (Actidyn `ALC 0`; ACUTROL `:interlock:reset`,
    /// `:interlock:close`). After a drive alarm, the next `set_rate` switches the drive on again.
    pub async fn clear_alarms(&mut self) -> DeviceResult<()> {
        self.ctl.clear_alarms().await
    }

    /// Switch the drive off and give control back to the front panel (Actidyn
    /// `MOD 1,OFF:LOC 0`; ACUTROL `:mode:off 1`, `:interlock:open 1`, `:utility:lockout off`).
    pub async fn release(&mut self) -> DeviceResult<()> {
        self.ctl.release().await?;
        self.mode = TableMode::Off;
        self.rate_command_rad_s = 0.0;
        Ok(())
    }

    fn check_rate(&self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<f64> {
        let caps = &self.info.capabilities;
        if !(rate_rad_s.is_finite() && rate_rad_s.abs() <= caps.max_rate_rad_s) {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!(
                    "rate {:.6} °/s is outside ±{} °/s (table driver config max_rate_deg_s)",
                    rate_rad_s / DEG,
                    self.cfg.max_rate_deg_s
                ),
            ));
        }
        self.check_accel(accel_rad_s2)
    }

    /// The acceleration to send, °/s² (0 → the configured default).
    fn check_accel(&self, accel_rad_s2: f64) -> DeviceResult<f64> {
        if accel_rad_s2 == 0.0 {
            return Ok(self.cfg.default_accel_deg_s2.min(self.cfg.max_accel_deg_s2));
        }
        let caps = &self.info.capabilities;
        if !(accel_rad_s2.is_finite()
            && accel_rad_s2 > 0.0
            && accel_rad_s2 <= caps.max_accel_rad_s2 * (1.0 + 1e-12))
        {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!(
                    "acceleration {:.6} °/s² is outside (0, {}] °/s² (table driver config max_accel_deg_s2)",
                    accel_rad_s2 / DEG,
                    self.cfg.max_accel_deg_s2
                ),
            ));
        }
        Ok(accel_rad_s2 / DEG)
    }

    fn reading(
        &mut self,
        raw_position_deg: f64,
        rate_deg_s: f64,
        mode: TableMode,
        drive_off_unexpected: bool,
    ) -> TableReading {
        let angle_deg = self.unwrap.update(raw_position_deg);
        let rate_rad_s = rate_deg_s * DEG;
        let mut st = 0;
        if mode == TableMode::Off {
            st |= status::table::DRIVE_OFF;
        }
        if *self.ctl.alarm() || drive_off_unexpected {
            st |= status::table::ALARM;
        }
        let tol = 1e-3 * self.rate_command_rad_s.abs() + 1e-4;
        if mode == TableMode::Rate && (rate_rad_s - self.rate_command_rad_s).abs() > tol {
            st |= status::table::SLEWING;
        }
        TableReading {
            angle_rad: angle_deg * DEG,
            rate_rad_s,
            rate_command_rad_s: self.rate_command_rad_s,
            mode,
            status: st,
            device_time: None,
        }
    }
}

fn context(what: &str, e: DeviceError) -> DeviceError {
    DeviceError::new(e.kind(), format!("{what}: {}", e.message()))
}

fn table_mode(m: actidyn::Mode) -> TableMode {
    match m {
        actidyn::Mode::Off => TableMode::Off,
        actidyn::Mode::Rate => TableMode::Rate,
        // Sine motion is a position trajectory; servo-on holds position.
        actidyn::Mode::Position | actidyn::Mode::Sine => TableMode::Position,
        actidyn::Mode::ServoOn | actidyn::Mode::Stop => TableMode::Stopped,
    }
}

#[async_trait]
impl RateTable for RateTableDriver {
    fn info(&self) -> &DeviceInfo<TableCapabilities> {
        &self.info
    }

    fn link_counters(&self) -> Option<LinkCounters> {
        Some(self.counters())
    }

    async fn set_rate(&mut self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<()> {
        let accel_deg_s2 = self.check_rate(rate_rad_s, accel_rad_s2)?;
        self.ctl.set_rate(&mut self.mode, rate_rad_s / DEG, accel_deg_s2).await?;
        self.mode = TableMode::Rate;
        self.rate_command_rad_s = rate_rad_s;
        *self.ctl.alarm() = false;
        Ok(())
    }

    /// Actidyn: `MOD 1,STP`, the controller's own controlled stop (its deceleration, not
    /// `decel_rad_s2`, which is only checked). ACUTROL: demand rate 0, held in rate mode.
    async fn stop(&mut self, decel_rad_s2: f64) -> DeviceResult<()> {
        self.check_accel(decel_rad_s2)?;
        self.ctl.stop(&mut self.mode).await?;
        self.rate_command_rad_s = 0.0;
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<TableReading> {
        let t = self.ctl.read().await?;
        let mode = t.mode.unwrap_or(self.mode);
        let unexpected = t.mode == Some(TableMode::Off) && self.mode != TableMode::Off;
        if unexpected {
            tracing::warn!("the controller switched the drive off (alarm or lost keep-alive)");
            *self.ctl.alarm() = true;
            self.mode = TableMode::Off;
            self.rate_command_rad_s = 0.0;
        }
        Ok(self.reading(t.position_deg, t.rate_deg_s, mode, unexpected))
    }

    /// Actidyn: sends `ALC 0` when `keep_alive_s` of bench time has passed since the last one.
    async fn service(&mut self) -> DeviceResult<()> {
        self.ctl.service().await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwrapper_counts_turns_both_ways() {
        let mut u = Unwrapper::default();
        let got: Vec<f64> = [350.0, 359.0, 1.0, 10.0, 355.0, 181.0, 90.0]
            .into_iter()
            .map(|d| u.update(d))
            .collect();
        assert_eq!(got, vec![350.0, 359.0, 361.0, 370.0, 355.0, 181.0, 90.0]);
        let mut u = Unwrapper::default();
        let got: Vec<f64> = [170.0, -170.0, -10.0].into_iter().map(|d| u.update(d)).collect();
        assert_eq!(got, vec![170.0, 190.0, 350.0]);
    }

    #[test]
    fn error_codes_map_to_kinds() {
        assert_eq!(
            crate::protocol::actidyn::error_kind(crate::protocol::actidyn::errors::DRIVE_ALARM),
            ErrorKind::DeviceFault
        );
        assert_eq!(
            crate::protocol::actidyn::error_kind(crate::protocol::actidyn::errors::INTERLOCK),
            ErrorKind::InterlockTripped
        );
        assert_eq!(
            crate::protocol::actidyn::error_kind(crate::protocol::actidyn::errors::OUT_OF_RANGE),
            ErrorKind::OutOfRange
        );
        assert_eq!(
            crate::protocol::actidyn::error_kind(crate::protocol::actidyn::errors::NOT_REMOTE),
            ErrorKind::NotReady
        );
        assert_eq!(crate::protocol::actidyn::error_kind(999), ErrorKind::DeviceFault);
        assert_eq!(
            crate::protocol::acutrol::error_kind("interlock open"),
            ErrorKind::InterlockTripped
        );
        assert_eq!(
            crate::protocol::acutrol::error_kind("rate out of range"),
            ErrorKind::OutOfRange
        );
        assert_eq!(crate::protocol::acutrol::error_kind("not in rate mode"), ErrorKind::NotReady);
        assert_eq!(crate::protocol::acutrol::error_kind("amplifier fault"), ErrorKind::DeviceFault);
    }

    #[test]
    fn config_defaults_and_validation() {
        let c = TableDriverConfig::new(Endpoint::Tcp { addr: "x:1".into() }, Dialect::Actidyn);
        assert!(c.validate().is_ok());
        let bad = TableDriverConfig { reply_timeout_s: 0.0, ..c };
        let e = bad.validate().err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("reply_timeout_s = 0"), "{e}");
    }
}
