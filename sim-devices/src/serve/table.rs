//! A rate-table controller simulator: any [`RateTable`] (normally the physics-based
//! [`crate::SimTable`]) served line by line in the Actidyn or ACUTROL dialect through the
//! controller side of the codecs, on a pseudo-terminal or a TCP listener.
//!
//! The controller's behaviour is bench's reading of the public client code
//! (`docs/protocols/table.md`), **not the manufacturers' manuals**:
//!
//! - Actidyn: `RMT 0` takes remote control; motion and mode commands are refused
//!   ([`actidyn_errors::NOT_REMOTE`]) until then. `MOD 1,RAT` (or `MOD 1,1`) switches the drive
//!   on, `RAT` is accepted only in rate mode, `MOD 1,STP` decelerates at
//!   [`TableServeOptions::stop_decel_deg_s2`] and holds, `MOD 1,OFF` stops and switches off.
//!   Watchdog: while the drive is on, if no `ALC` arrives within
//!   [`TableServeOptions::watchdog_s`] of bench time (30 s), the drive is dropped: the table
//!   stops, the mode reads `OFF`, and mode and motion commands are refused with
//!   [`actidyn_errors::DRIVE_ALARM`] until `ALC` clears the alarm and a mode is set again.
//!   Telemetry (`PRV`, `POS ?`, `MOD ?`) is always answered. The position is reported wrapped
//!   to [0, 360)°.
//! - ACUTROL: `:utility:lockout on` = remote, `:interlock:close` needs remote, `:mode:rate` needs
//!   the interlock closed, `:demand:rate` needs rate mode (reached at
//!   [`TableServeOptions::acutrol_accel_deg_s2`]; the wire has no acceleration),
//!   `:interlock:open` and `:mode:off` stop the table. Refusals are `ERR <text>` with the
//!   keywords [`bench_drivers::protocol::acutrol::error_kind`] reads. Position and position
//!   demands are not simulated (refused).
//!
//! Faults ([`FaultSwitch`], consulted for every request line): [`Fault::Silence`] — requests are
//! read and neither executed nor answered; [`Fault::Corrupt`] — every n-th reply has one byte
//! (in the middle of the line, never the terminator) XOR-ed with 0x80, so it is no longer ASCII;
//! [`Fault::Drop`] — every n-th reply is not sent; [`Fault::Disconnect`] — once, on the next
//! request: TCP closes the connection, serial goes silent for `seconds` of bench time;
//! [`Fault::StuckTable`] — rate commands are acknowledged but not forwarded to the table;
//! [`Fault::DriveAlarm`] — the drive drops at the next request with the drive on, as on a
//! missed keep-alive (once; the fault then switches itself off).

use std::io;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::actidyn::errors as actidyn_errors;
use bench_drivers::protocol::Dialect;
use bench_drivers::protocol::{actidyn, acutrol};
use bench_drivers::{Clock, DeviceError, ErrorKind, RateTable, TableReading};
use bench_physics::units::DEG;
use futures::future::BoxFuture;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpListener;

use crate::faults::{Fault, FaultCounter, FaultSwitch};
use crate::ports::Pty;

/// How the simulated controller behaves.
#[derive(Debug, Clone)]
pub struct TableServeOptions {
    /// Dialect served (default Actidyn).
    pub dialect: Dialect,
    /// Faults to consult for every request (default: a new switch, no faults).
    pub faults: FaultSwitch,
    /// Actidyn watchdog: bench seconds without `ALC` after which the drive is dropped
    /// (default 30).
    pub watchdog_s: f64,
    /// Deceleration of `MOD 1,STP`, `MOD 1,OFF`, a watchdog drop and an opened interlock, °/s²
    /// (default 10).
    pub stop_decel_deg_s2: f64,
    /// ACUTROL: acceleration used for rate demands, °/s² (default 10).
    pub acutrol_accel_deg_s2: f64,
    /// ACUTROL: reply number format (default long form, 6 decimals).
    pub acutrol_encoding: acutrol::Encoding,
    /// The one axis simulated (default 1).
    pub axis: u8,
}

impl TableServeOptions {
    /// Defaults for `dialect` with fault switch `faults`.
    pub fn new(dialect: Dialect, faults: FaultSwitch) -> Self {
        Self {
            dialect,
            faults,
            watchdog_s: 30.0,
            stop_decel_deg_s2: 10.0,
            acutrol_accel_deg_s2: 10.0,
            acutrol_encoding: acutrol::Encoding::default(),
            axis: 1,
        }
    }
}

impl Default for TableServeOptions {
    fn default() -> Self {
        Self::new(Dialect::Actidyn, FaultSwitch::new())
    }
}

/// What a serving session saw, shared with tests and the control port. Counters only grow.
#[derive(Debug, Default)]
pub struct TableServerStats {
    /// Request lines received (including ones not answered).
    pub requests: AtomicU64,
    /// Reply lines sent.
    pub replies: AtomicU64,
    /// Request lines that did not parse (not answered).
    pub bad_requests: AtomicU64,
    /// Replies corrupted by [`Fault::Corrupt`].
    pub corrupted: AtomicU64,
    /// `ALC` commands received (Actidyn).
    pub alarm_clears: AtomicU64,
    /// Times the watchdog dropped the drive (Actidyn).
    pub watchdog_trips: AtomicU64,
    /// Times [`Fault::DriveAlarm`] dropped the drive.
    pub drive_alarms: AtomicU64,
    /// Connections accepted (TCP) or sessions served.
    pub connections: AtomicU64,
    /// State requests (Actidyn `PRV`, ACUTROL rate reads: one per driver poll) answered with
    /// an intact reply: the samples this controller sent.
    pub state_replies: AtomicU64,
    /// State requests whose reply [`Fault::Corrupt`] damaged.
    pub state_corrupted: AtomicU64,
    /// State requests whose reply [`Fault::Drop`] withheld.
    pub state_dropped: AtomicU64,
    /// State requests not answered because the line was silent ([`Fault::Silence`], a serial
    /// [`Fault::Disconnect`]).
    pub state_silenced: AtomicU64,
    /// Bench time of the last intact state reply, ns (0: none yet).
    pub last_state_reply_ns: AtomicU64,
}

impl TableServerStats {
    /// Read one counter.
    pub fn get(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
    }
}

fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::Relaxed);
}

/// Which kind of port a stream is, for [`Fault::Disconnect`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortKind {
    /// A TCP connection: a disconnect closes it.
    Tcp,
    /// A serial line (pty): a disconnect makes it go silent for a while.
    Serial,
}

/// Why [`TableController::serve`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ServeEnd {
    /// The peer closed the stream.
    Closed,
    /// [`Fault::Disconnect`] closed it.
    Disconnected,
}

/// Axis mode of the simulated controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum CtlMode {
    Off,
    Hold,
    Rate,
    Stop,
}

impl CtlMode {
    fn actidyn(self) -> actidyn::Mode {
        match self {
            CtlMode::Off => actidyn::Mode::Off,
            CtlMode::Hold => actidyn::Mode::ServoOn,
            CtlMode::Rate => actidyn::Mode::Rate,
            CtlMode::Stop => actidyn::Mode::Stop,
        }
    }
}

/// The simulated controller in front of a table: its session state survives reconnections.
pub struct TableController<T> {
    table: T,
    clock: Arc<dyn Clock>,
    opts: TableServeOptions,
    stats: Arc<TableServerStats>,
    remote: bool,
    interlock_closed: bool,
    mode: CtlMode,
    alarm: bool,
    last_alc: Duration,
    last_accel_deg_s2: f64,
    silent_until: Option<Duration>,
    corrupt: FaultCounter,
    drop: FaultCounter,
}

/// A controller error reply: code (Actidyn) and text.
struct Refusal(u16, String);

fn refuse(code: u16, text: impl Into<String>) -> Refusal {
    // Neither dialect's error text may contain ':' or line breaks.
    let t: String =
        text.into().chars().map(|c| if matches!(c, ':' | '\r' | '\n') { ';' } else { c }).collect();
    Refusal(code, t)
}

fn refusal_of(e: &DeviceError) -> Refusal {
    let code = match e.kind() {
        ErrorKind::OutOfRange => actidyn_errors::OUT_OF_RANGE,
        ErrorKind::InterlockTripped => actidyn_errors::INTERLOCK,
        ErrorKind::NotReady => actidyn_errors::WRONG_MODE,
        _ => actidyn_errors::DRIVE_ALARM,
    };
    let text = match e.kind() {
        ErrorKind::OutOfRange => format!("out of range; {}", e.message()),
        _ => e.message().to_owned(),
    };
    refuse(code, text)
}

impl<T: RateTable> TableController<T> {
    /// A controller in local mode, drive off, in front of `table`.
    pub fn new(table: T, clock: Arc<dyn Clock>, opts: TableServeOptions) -> Self {
        Self {
            last_alc: clock.now(),
            table,
            clock,
            opts,
            stats: Arc::default(),
            remote: false,
            interlock_closed: false,
            mode: CtlMode::Off,
            alarm: false,
            last_accel_deg_s2: 0.0,
            silent_until: None,
            corrupt: FaultCounter::default(),
            drop: FaultCounter::default(),
        }
    }

    /// Counters shared with whoever watches the server.
    pub fn stats(&self) -> Arc<TableServerStats> {
        self.stats.clone()
    }

    /// The table behind the controller.
    pub fn table(&mut self) -> &mut T {
        &mut self.table
    }

    fn drive_on(&self) -> bool {
        self.mode != CtlMode::Off
    }

    /// When the watchdog will drop the drive, if it is armed.
    fn watchdog_deadline(&self) -> Option<Duration> {
        (self.opts.dialect == Dialect::Actidyn && self.drive_on() && !self.alarm)
            .then(|| self.last_alc + Duration::from_secs_f64(self.opts.watchdog_s.max(0.0)))
    }

    /// Drop the drive if the keep-alive is overdue, or on [`Fault::DriveAlarm`] (once, the
    /// first time the drive is on).
    async fn check_watchdog(&mut self) {
        if self.drive_on() && self.opts.faults.find(|f| matches!(f, Fault::DriveAlarm)).is_some() {
            self.opts.faults.remove(&Fault::DriveAlarm);
            tracing::warn!("drive alarm fault: simulated drive dropped");
            bump(&self.stats.drive_alarms);
            self.alarm = true;
            self.halt().await;
            self.mode = CtlMode::Off;
        }
        let Some(deadline) = self.watchdog_deadline() else { return };
        if self.clock.now() < deadline {
            return;
        }
        tracing::warn!(
            watchdog_s = self.opts.watchdog_s,
            "no ALC in time: simulated drive dropped"
        );
        bump(&self.stats.watchdog_trips);
        self.alarm = true;
        self.halt().await;
        self.mode = CtlMode::Off;
    }

    /// Decelerate the table to rest (best effort: the table model never refuses a valid stop).
    async fn halt(&mut self) {
        if let Err(e) = self.table.stop(self.opts.stop_decel_deg_s2 * DEG).await {
            tracing::warn!(error = %e, "simulated table refused to stop");
        }
    }

    fn watchdog_sleep(&self) -> BoxFuture<'static, ()> {
        match self.watchdog_deadline() {
            Some(t) => self.clock.sleep_until(t),
            None => Box::pin(futures::future::pending()),
        }
    }

    async fn reading(&mut self) -> Result<TableReading, Refusal> {
        self.table.read().await.map_err(|e| refusal_of(&e))
    }

    fn wrapped_deg(r: &TableReading) -> f64 {
        let d = (r.angle_rad / DEG).rem_euclid(360.0);
        // rem_euclid can round up to exactly 360.0.
        if d >= 360.0 {
            0.0
        } else {
            d
        }
    }

    fn axis_ok(&self, axis: actidyn::Axis) -> bool {
        matches!(axis, actidyn::Axis::All) || axis == actidyn::Axis::Number(self.opts.axis)
    }

    async fn actidyn_command(&mut self, c: &actidyn::Command) -> actidyn::Reply {
        match self.actidyn_execute(c).await {
            Ok(values) => actidyn::Reply::values(c, values),
            Err(Refusal(code, text)) => actidyn::Reply::error(c, code, text),
        }
    }

    async fn actidyn_execute(
        &mut self,
        c: &actidyn::Command,
    ) -> Result<Vec<actidyn::Value>, Refusal> {
        use actidyn::{Command as C, Mode, Value};
        if !self.axis_ok(c.axis()) && !matches!(c, C::Remote | C::Local | C::ClearAlarms) {
            return Err(refuse(actidyn_errors::OUT_OF_RANGE, format!("no axis {}", c.axis())));
        }
        let needs_remote = !matches!(
            c,
            C::Remote
                | C::Local
                | C::ClearAlarms
                | C::QueryMode { .. }
                | C::QueryPosition { .. }
                | C::QueryPrv { .. }
        );
        if needs_remote && !self.remote {
            return Err(refuse(actidyn_errors::NOT_REMOTE, "not in remote (send RMT 0)"));
        }
        let alarm = || {
            refuse(
                actidyn_errors::DRIVE_ALARM,
                "drive alarm; keep-alive ALC missed, send ALC 0 then a mode",
            )
        };
        match *c {
            C::Remote => self.remote = true,
            C::Local => self.remote = false,
            C::ClearAlarms => {
                bump(&self.stats.alarm_clears);
                self.last_alc = self.clock.now();
                self.alarm = false;
            }
            C::SetMode { mode, .. } => match mode {
                Mode::Off => {
                    self.halt().await;
                    self.mode = CtlMode::Off;
                }
                Mode::Stop => {
                    self.halt().await;
                    if self.drive_on() {
                        self.mode = CtlMode::Stop;
                    }
                }
                Mode::ServoOn | Mode::Rate if self.alarm => return Err(alarm()),
                Mode::ServoOn => {
                    self.halt().await;
                    self.mode = CtlMode::Hold;
                }
                Mode::Rate => self.mode = CtlMode::Rate,
                Mode::Position | Mode::Sine => {
                    return Err(refuse(actidyn_errors::UNSUPPORTED, "mode not simulated"))
                }
            },
            C::Rate { .. } if self.alarm => return Err(alarm()),
            C::Rate { rate_deg_s, accel_deg_s2, .. } => {
                if self.mode != CtlMode::Rate {
                    return Err(refuse(actidyn_errors::WRONG_MODE, "not in rate mode (MOD 1,RAT)"));
                }
                if self.opts.faults.find(|f| matches!(f, Fault::StuckTable)).is_some() {
                    tracing::debug!(rate_deg_s, "stuck table: rate command acknowledged, ignored");
                } else {
                    self.table
                        .set_rate(rate_deg_s * DEG, accel_deg_s2 * DEG)
                        .await
                        .map_err(|e| refusal_of(&e))?;
                    self.last_accel_deg_s2 = accel_deg_s2;
                }
            }
            C::Position { .. } | C::Sine { .. } => {
                return Err(refuse(actidyn_errors::UNSUPPORTED, "motion not simulated"))
            }
            C::QueryMode { .. } => return Ok(vec![Value::Mode(self.mode.actidyn())]),
            C::QueryPosition { .. } => {
                let r = self.reading().await?;
                return Ok(vec![Value::Number(Self::wrapped_deg(&r))]);
            }
            C::QueryPrv { .. } => {
                let r = self.reading().await?;
                let slewing = r.status & bench_recording::status::table::SLEWING != 0;
                let accel = if slewing {
                    (r.rate_command_rad_s - r.rate_rad_s).signum() * self.last_accel_deg_s2
                } else {
                    0.0
                };
                return Ok(vec![
                    Value::Number(Self::wrapped_deg(&r)),
                    Value::Number(r.rate_rad_s / DEG),
                    Value::Number(accel),
                ]);
            }
        }
        Ok(Vec::new())
    }

    async fn acutrol_command(&mut self, c: acutrol::Command) -> acutrol::Reply {
        match self.acutrol_execute(c).await {
            Ok(r) => r,
            Err(Refusal(_, text)) => acutrol::Reply::Error(text),
        }
    }

    async fn acutrol_execute(&mut self, c: acutrol::Command) -> Result<acutrol::Reply, Refusal> {
        use acutrol::{Command as C, Reply};
        let axis = match c {
            C::Lockout(_) => self.opts.axis,
            C::InterlockOpen(a)
            | C::InterlockReset(a)
            | C::InterlockClose(a)
            | C::ModeOff(a)
            | C::ModeRate(a)
            | C::ModePosition(a)
            | C::ReadRate(a)
            | C::ReadPosition(a)
            | C::DemandRate { axis: a, .. }
            | C::DemandPosition { axis: a, .. } => a,
        };
        let code = actidyn_errors::DRIVE_ALARM;
        if axis != self.opts.axis {
            return Err(refuse(code, format!("axis {axis} out of range")));
        }
        let needs_remote = !matches!(c, C::Lockout(_) | C::ReadRate(_) | C::ReadPosition(_));
        if needs_remote && !self.remote {
            return Err(refuse(code, "not in remote; front panel lockout is off"));
        }
        match c {
            C::Lockout(on) => self.remote = on,
            C::InterlockOpen(_) => {
                self.interlock_closed = false;
                if self.drive_on() {
                    self.halt().await;
                }
                self.mode = CtlMode::Off;
            }
            C::InterlockReset(_) => self.alarm = false,
            C::InterlockClose(_) => self.interlock_closed = true,
            C::ModeOff(_) => {
                self.halt().await;
                self.mode = CtlMode::Off;
            }
            C::ModeRate(_) => {
                if !self.interlock_closed {
                    return Err(refuse(code, "interlock open"));
                }
                self.mode = CtlMode::Rate;
            }
            C::ModePosition(_) | C::DemandPosition { .. } => {
                return Err(refuse(code, "position control not simulated"))
            }
            C::DemandRate { rate_deg_s, .. } => {
                if self.mode != CtlMode::Rate {
                    return Err(refuse(code, "not in rate mode"));
                }
                if self.opts.faults.find(|f| matches!(f, Fault::StuckTable)).is_none() {
                    let accel = self.opts.acutrol_accel_deg_s2;
                    self.table
                        .set_rate(rate_deg_s * DEG, accel * DEG)
                        .await
                        .map_err(|e| refusal_of(&e))?;
                    self.last_accel_deg_s2 = accel;
                }
            }
            C::ReadRate(_) => return Ok(Reply::Value(self.reading().await?.rate_rad_s / DEG)),
            C::ReadPosition(_) => {
                let r = self.reading().await?;
                return Ok(Reply::Value(Self::wrapped_deg(&r)));
            }
        }
        Ok(Reply::Ok)
    }

    /// Whether the line is being swallowed by a silence or serial-disconnect fault.
    fn swallowed(&mut self, port: PortKind) -> Option<ServeEnd> {
        let faults = &self.opts.faults;
        if let Some(f @ Fault::Disconnect { seconds }) =
            faults.find(|f| matches!(f, Fault::Disconnect { .. }))
        {
            faults.remove(&f);
            match port {
                PortKind::Tcp => return Some(ServeEnd::Disconnected),
                PortKind::Serial => {
                    let s = Duration::from_secs_f64(seconds.clamp(0.0, 1e6));
                    self.silent_until = Some(self.clock.now() + s);
                }
            }
        }
        None
    }

    fn is_silent(&mut self) -> bool {
        if let Some(t) = self.silent_until {
            if self.clock.now() < t {
                return true;
            }
            self.silent_until = None;
        }
        self.opts.faults.silent()
    }

    /// Apply the reply faults: `None` = do not send.
    fn faulted_reply(&mut self, mut bytes: Vec<u8>) -> Option<Vec<u8>> {
        let faults = &self.opts.faults;
        if let Some(Fault::Drop { every }) = faults.find(|f| matches!(f, Fault::Drop { .. })) {
            if self.drop.tick(every) {
                return None;
            }
        }
        if let Some(Fault::Corrupt { every }) = faults.find(|f| matches!(f, Fault::Corrupt { .. }))
        {
            if self.corrupt.tick(every) {
                let body = bytes.iter().take_while(|b| **b != b'\r' && **b != b'\n').count();
                if let Some(b) = bytes.get_mut(body / 2) {
                    *b ^= 0x80;
                    bump(&self.stats.corrupted);
                }
            }
        }
        Some(bytes)
    }

    /// Execute one received request line (already decoded) and produce the reply bytes.
    async fn answer_actidyn(&mut self, cmds: Vec<actidyn::Command>) -> Option<Vec<u8>> {
        let mut replies = Vec::with_capacity(cmds.len());
        for c in &cmds {
            replies.push(self.actidyn_command(c).await);
        }
        match actidyn::encode_replies(&replies) {
            Ok(b) => Some(b),
            Err(e) => {
                tracing::warn!(error = %e, "simulated controller could not encode its reply");
                None
            }
        }
    }

    async fn answer_acutrol(&mut self, c: acutrol::Command) -> Option<Vec<u8>> {
        let r = self.acutrol_command(c).await;
        match r.encode(self.opts.acutrol_encoding) {
            Ok(b) => Some(b),
            Err(e) => {
                tracing::warn!(error = %e, "simulated controller could not encode its reply");
                None
            }
        }
    }

    /// Serve one stream until the peer closes it or a disconnect fault does. Requests are
    /// handled in order, one reply line per request line; the watchdog runs meanwhile.
    pub async fn serve<S: AsyncRead + AsyncWrite + Unpin>(
        &mut self,
        mut stream: S,
        port: PortKind,
    ) -> io::Result<ServeEnd> {
        bump(&self.stats.connections);
        let mut actidyn_dec = actidyn::CommandDecoder::new();
        let mut acutrol_dec = acutrol::CommandDecoder::new();
        let mut buf = [0u8; 1024];
        loop {
            let watchdog = self.watchdog_sleep();
            let n = tokio::select! {
                r = stream.read(&mut buf) => r?,
                () = watchdog => {
                    self.check_watchdog().await;
                    continue;
                }
            };
            if n == 0 {
                return Ok(ServeEnd::Closed);
            }
            let got = buf.get(..n).unwrap_or_default();
            match self.opts.dialect {
                Dialect::Actidyn => actidyn_dec.push(got),
                Dialect::Acutrol => acutrol_dec.push(got),
            }
            loop {
                let request = match self.opts.dialect {
                    Dialect::Actidyn => match actidyn_dec.next_message() {
                        None => break,
                        Some(r) => r.map(Request::Actidyn),
                    },
                    Dialect::Acutrol => match acutrol_dec.next_message() {
                        None => break,
                        Some(r) => r.map(Request::Acutrol),
                    },
                };
                bump(&self.stats.requests);
                let state = match &request {
                    Ok(Request::Actidyn(cmds)) => {
                        cmds.iter().any(|c| matches!(c, actidyn::Command::QueryPrv { .. }))
                    }
                    Ok(Request::Acutrol(c)) => matches!(c, acutrol::Command::ReadRate(_)),
                    Err(_) => false,
                };
                self.check_watchdog().await;
                if let Some(end) = self.swallowed(port) {
                    if state {
                        bump(&self.stats.state_silenced);
                    }
                    return Ok(end);
                }
                if self.is_silent() {
                    if state {
                        bump(&self.stats.state_silenced);
                    }
                    continue;
                }
                let reply = match request {
                    Err(e) => {
                        bump(&self.stats.bad_requests);
                        tracing::warn!(error = %e, "simulated table controller: request skipped");
                        continue;
                    }
                    Ok(Request::Actidyn(cmds)) => self.answer_actidyn(cmds).await,
                    Ok(Request::Acutrol(c)) => self.answer_acutrol(c).await,
                };
                let corrupted_before = TableServerStats::get(&self.stats.corrupted);
                let encoded = reply.is_some();
                match reply.and_then(|b| self.faulted_reply(b)) {
                    Some(bytes) => {
                        stream.write_all(&bytes).await?;
                        stream.flush().await?;
                        bump(&self.stats.replies);
                        if state {
                            let damaged =
                                TableServerStats::get(&self.stats.corrupted) != corrupted_before;
                            bump(if damaged {
                                &self.stats.state_corrupted
                            } else {
                                &self.stats.state_replies
                            });
                            if !damaged {
                                let now = self.clock.now().as_nanos() as u64;
                                self.stats.last_state_reply_ns.store(now, Ordering::Relaxed);
                            }
                        }
                    }
                    None if state && encoded => bump(&self.stats.state_dropped),
                    None => {}
                }
            }
        }
    }

    /// Run the watchdog while no stream is being served; never returns.
    async fn idle_watchdog(&mut self) {
        loop {
            self.watchdog_sleep().await;
            self.check_watchdog().await;
        }
    }
}

enum Request {
    Actidyn(Vec<actidyn::Command>),
    Acutrol(acutrol::Command),
}

/// Serve `table` on one stream in `dialect` until the peer closes it (a TCP-like stream:
/// [`Fault::Disconnect`] closes it). Shorthand for [`TableController::serve`].
pub async fn serve_table<S, T>(
    stream: S,
    table: T,
    dialect: Dialect,
    faults: FaultSwitch,
    clock: Arc<dyn Clock>,
) -> io::Result<()>
where
    S: AsyncRead + AsyncWrite + Unpin,
    T: RateTable,
{
    let mut ctl = TableController::new(table, clock, TableServeOptions::new(dialect, faults));
    ctl.serve(stream, PortKind::Tcp).await.map(|_| ())
}

/// Serve on a pseudo-terminal until the pty fails. The driver opens `pty.path` (read it before
/// moving the pty in).
pub async fn serve_table_pty<T: RateTable>(
    mut pty: Pty,
    mut ctl: TableController<T>,
) -> io::Result<()> {
    loop {
        // The pty holds its slave end open, so the master never sees the driver hang up.
        ctl.serve(&mut pty.server, PortKind::Serial).await?;
    }
}

/// Serve on a TCP listener, one connection at a time, accepting the next after each
/// disconnection. The watchdog keeps running between connections. Never returns unless
/// accepting fails.
pub async fn serve_table_tcp<T: RateTable>(
    listener: TcpListener,
    mut ctl: TableController<T>,
) -> io::Result<()> {
    loop {
        let accepted = tokio::select! {
            r = listener.accept() => r,
            () = ctl.idle_watchdog() => continue,
        };
        let (stream, peer) = accepted?;
        if let Err(e) = stream.set_nodelay(true) {
            tracing::debug!(error = %e, "set_nodelay failed");
        }
        tracing::debug!(%peer, "simulated table controller: connection accepted");
        match ctl.serve(stream, PortKind::Tcp).await {
            Ok(end) => tracing::debug!(?end, %peer, "simulated table controller: connection ended"),
            Err(e) => {
                tracing::debug!(error = %e, %peer, "simulated table controller: connection failed")
            }
        }
    }
}
