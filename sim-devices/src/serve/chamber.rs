//! A chamber controller served over Modbus RTU (on a pseudo-terminal) or Modbus TCP (on
//! 127.0.0.1, an OS-chosen port), backed by any [`Chamber`] (normally [`crate::SimChamber`])
//! through the same [`RegisterMap`] the driver uses.
//!
//! Framing and CRC are tokio-modbus's server (`rtu-server`, `tcp-server`). The register bank:
//!
//! - reads of the process value and working set point call [`Chamber::read`] and encode the
//!   values with the map's encoding;
//! - a write completing the set point calls [`Chamber::set_target`] with the rate from the
//!   rate-limit register (if the map has one; 0 = no limit, units `rate_units`), so the
//!   controller ramps; reading the set point back gives the words written (or the chamber's
//!   target before any write);
//! - the rate-limit register, the map's `on_connect` and EEPROM registers and
//!   `extra_registers` are plain read/write words (F4 presets add 606 = decimals, 0 = 5270, 901 = 1);
//! - any other address answers exception 2 (illegal data address); a write to the process value
//!   or working set point, too; a set point the chamber refuses answers exception 3.
//!
//! Every accepted write is logged ([`ServedChamber::writes`]) so tests can check the words a
//! driver wrote, byte for byte. Requests to another unit id get no reply, as on a real bus.
//!
//! # Faults ([`FaultSwitch`])
//!
//! | fault | RTU | TCP |
//! |---|---|---|
//! | `Silence` | no reply | no reply |
//! | `ModbusException { code }` | every request answered with the exception | same |
//! | `Corrupt { every }` | last byte (CRC high byte) of every n-th reply flipped | transaction id low byte of every n-th reply flipped (TCP itself would catch real corruption; this models a confused gateway) |
//! | `Disconnect { seconds }` | requests dropped for `seconds` of bench time | the connection is closed once (at the next request); the fault then clears itself |
//! | `ChamberOvershoot { overshoot_c }` | see below | same |
//!
//! tokio-modbus's RTU server cannot be made to send a bad CRC, so the RTU server sits behind a
//! byte-forwarding proxy: the driver's pty ↔ proxy task ↔ a second pty pair ↔ tokio-modbus. The
//! proxy applies `Corrupt` and `Disconnect`; it counts each chunk read from the server as one
//! reply (tokio-modbus writes a reply in one write).
//!
//! **Overshoot model** (a fault of the served controller, not of the physics): while
//! `ChamberOvershoot { overshoot_c: A }` is on, a set-point write at bench time `t0` that moves
//! the target by sign `s` makes the served process value `PV + s·A·(u/τ)·e^{1−u/τ}`, `u = t − t0`,
//! `τ = overshoot_time_constant_s`: it rises to `A` above the physics at `u = τ` and decays
//! after. Switching the fault off removes it at once.

use std::collections::HashMap;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll};
use std::time::Duration;

use bench_drivers::protocol::modbus_map::RateUnits;
use bench_drivers::protocol::modbus_map::{Preset, RegisterMap};
use bench_drivers::transport::{Endpoint, Parity, SerialSettings};
use bench_drivers::{BenchTime, Chamber, Clock, ErrorKind};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::net::TcpStream;
use tokio::task::JoinHandle;
use tokio_modbus::{ExceptionCode, Request, Response, SlaveRequest};

use crate::faults::{Fault, FaultCounter, FaultSwitch};
use crate::ports::{loopback_listener, Pty};

/// How to serve a chamber.
#[derive(Debug, Clone)]
pub struct ChamberServeOptions {
    /// Register map served (the driver must use the same).
    pub map: RegisterMap,
    /// Unit id answered (default 1).
    pub unit_id: u8,
    /// Implied decimals of int16 values (default 1; ignored for floats).
    pub decimals: u8,
    /// Further plain registers and their initial words.
    pub extra_registers: Vec<(u16, u16)>,
    /// Units of the rate-limit register (default per minute).
    pub rate_units: RateUnits,
    /// Faults to apply.
    pub faults: FaultSwitch,
    /// Time constant of the overshoot fault, bench s (default 60).
    pub overshoot_time_constant_s: f64,
}

impl ChamberServeOptions {
    /// Options for a preset: unit 1, 1 decimal; the Watlow F4 also serves its decimals register
    /// 606 = 1, model register 0 = 5270 and the units register its map checks (901 = 1, °C).
    pub fn preset(p: Preset) -> Self {
        let map = RegisterMap::preset(p);
        let mut extra = Vec::new();
        if let Some(reg) = map.decimals_register() {
            extra.push((reg, 1));
        }
        if p == Preset::WatlowF4 {
            extra.push((0, 5270));
        }
        if let Some(c) = map.celsius_check {
            extra.push((c.register, c.value));
        }
        Self { extra_registers: extra, ..Self::new(map) }
    }

    /// Options for any map, with the defaults above.
    pub fn new(map: RegisterMap) -> Self {
        Self {
            map,
            unit_id: 1,
            decimals: 1,
            extra_registers: Vec::new(),
            rate_units: RateUnits::PerMinute,
            faults: FaultSwitch::new(),
            overshoot_time_constant_s: 60.0,
        }
    }
}

/// One accepted register write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WriteRecord {
    /// First register.
    pub register: u16,
    /// Words written.
    pub words: Vec<u16>,
    /// Function code (6 single, 16 multiple).
    pub function: u8,
}

#[derive(Debug, Clone, Copy)]
struct Overshoot {
    t0: BenchTime,
    sign: f64,
}

struct State {
    chamber: Box<dyn Chamber>,
    bank: HashMap<u16, u16>,
    overshoot: Option<Overshoot>,
}

/// What the RTU server's line carried, seen by its proxy (one request at a time on the bus,
/// so each reply is paired with the request before it). Counters only grow.
#[derive(Debug, Default)]
pub struct ChamberWireStats {
    /// Complete state reads answered intact: the process value and then (if the map has one)
    /// the working set point, both replies undamaged — one driver poll, the samples this
    /// controller sent.
    pub state_replies: AtomicU64,
    /// Replies to a state read damaged by [`Fault::Corrupt`].
    pub state_corrupted: AtomicU64,
    /// State read requests swallowed by a [`Fault::Disconnect`].
    pub state_dropped: AtomicU64,
    /// Replies to a state read that were Modbus exceptions.
    pub state_exceptions: AtomicU64,
    /// Replies of any kind damaged by [`Fault::Corrupt`].
    pub corrupted: AtomicU64,
    /// Bench time of the last complete state read answered intact, ns (0: none yet).
    pub last_state_reply_ns: AtomicU64,
}

impl ChamberWireStats {
    /// Read one counter.
    pub fn get(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
    }
}

fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::Relaxed);
}

/// Which state register a request reads, for [`ChamberWireStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StateRead {
    ProcessValue,
    WorkingSetPoint,
    Other,
}

struct Shared {
    wire: Arc<ChamberWireStats>,
    opts: ChamberServeOptions,
    clock: Arc<dyn Clock>,
    state: tokio::sync::Mutex<State>,
    writes: Mutex<Vec<WriteRecord>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn range(start: u16, count: u16) -> std::ops::Range<u32> {
    u32::from(start)..u32::from(start) + u32::from(count)
}

impl Shared {
    fn wc(&self) -> u16 {
        self.opts.map.encoding.word_count()
    }

    fn encode(&self, v: f64) -> Result<Vec<u16>, ExceptionCode> {
        self.opts
            .map
            .encoding
            .encode(v, self.opts.decimals)
            .map_err(|_| ExceptionCode::ServerDeviceFailure)
    }

    fn words_of(&self, bank: &HashMap<u16, u16>, start: u16) -> Option<Vec<u16>> {
        range(start, self.wc())
            .map(|a| u16::try_from(a).ok().and_then(|a| bank.get(&a).copied()))
            .collect()
    }

    fn overshoot_c(&self, st: &State) -> f64 {
        let (Some(o), Some(Fault::ChamberOvershoot { overshoot_c })) =
            (st.overshoot, self.opts.faults.find(|f| matches!(f, Fault::ChamberOvershoot { .. })))
        else {
            return 0.0;
        };
        let tau = self.opts.overshoot_time_constant_s;
        let u = self.clock.now().saturating_sub(o.t0).as_secs_f64() / tau;
        o.sign * overshoot_c * u * (1.0 - u).exp()
    }

    async fn read(&self, addr: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        let mut st = self.state.lock().await;
        let r = st.chamber.read().await.map_err(|_| ExceptionCode::ServerDeviceFailure)?;
        let map = &self.opts.map;
        let pv = self.encode(r.temperature_c + self.overshoot_c(&st))?;
        let wsp = self.encode(r.setpoint_c)?;
        let sp = match self.words_of(&st.bank, map.set_point) {
            Some(w) => w,
            None => self.encode(r.target_c)?,
        };
        let field = |start: u16, words: &[u16], a: u32| -> Option<u16> {
            let i = a.checked_sub(u32::from(start))?;
            words.get(usize::try_from(i).ok()?).copied()
        };
        range(addr, count)
            .map(|a| {
                field(map.process_value, &pv, a)
                    .or_else(|| map.working_set_point.and_then(|w| field(w, &wsp, a)))
                    .or_else(|| field(map.set_point, &sp, a))
                    .or_else(|| u16::try_from(a).ok().and_then(|a| st.bank.get(&a).copied()))
                    .ok_or(ExceptionCode::IllegalDataAddress)
            })
            .collect()
    }

    async fn write(&self, addr: u16, words: &[u16], function: u8) -> Result<(), ExceptionCode> {
        let map = &self.opts.map;
        let wc = u32::from(self.wc());
        let mut st = self.state.lock().await;
        let sp = u32::from(map.set_point)..u32::from(map.set_point) + wc;
        let count = u16::try_from(words.len()).map_err(|_| ExceptionCode::IllegalDataValue)?;
        let mut bank = st.bank.clone();
        let mut touches_sp = false;
        for (a, w) in range(addr, count).zip(words) {
            let a16 = u16::try_from(a).map_err(|_| ExceptionCode::IllegalDataAddress)?;
            if sp.contains(&a) {
                touches_sp = true;
            } else if !st.bank.contains_key(&a16) {
                return Err(ExceptionCode::IllegalDataAddress);
            }
            bank.insert(a16, *w);
        }
        if touches_sp {
            if let Some(sp_words) = self.words_of(&bank, map.set_point) {
                let target = map
                    .encoding
                    .decode(&sp_words, self.opts.decimals)
                    .map_err(|_| ExceptionCode::IllegalDataValue)?;
                let ramp = match map.ramp_rate.and_then(|r| self.words_of(&bank, r)) {
                    Some(w) => {
                        let per_unit = map
                            .encoding
                            .decode(&w, self.opts.decimals)
                            .map_err(|_| ExceptionCode::IllegalDataValue)?;
                        (per_unit > 0.0).then(|| per_unit / self.opts.rate_units.seconds())
                    }
                    None => None,
                };
                let before = st.chamber.read().await.map(|r| r.target_c).unwrap_or(target);
                st.chamber.set_target(target, ramp).await.map_err(|e| match e.kind() {
                    ErrorKind::OutOfRange => ExceptionCode::IllegalDataValue,
                    _ => ExceptionCode::ServerDeviceFailure,
                })?;
                let on = self.opts.faults.find(|f| matches!(f, Fault::ChamberOvershoot { .. }));
                st.overshoot = on.map(|_| Overshoot {
                    t0: self.clock.now(),
                    sign: if target >= before { 1.0 } else { -1.0 },
                });
            }
        }
        st.bank = bank;
        lock(&self.writes).push(WriteRecord { register: addr, words: words.to_vec(), function });
        Ok(())
    }

    async fn handle(&self, req: SlaveRequest<'static>) -> Result<Option<Response>, ExceptionCode> {
        if req.slave != self.opts.unit_id || self.opts.faults.silent() {
            return Ok(None);
        }
        if let Some(Fault::ModbusException { code }) =
            self.opts.faults.find(|f| matches!(f, Fault::ModbusException { .. }))
        {
            return Err(ExceptionCode::new(code));
        }
        match req.request {
            Request::ReadHoldingRegisters(addr, count) => {
                Ok(Some(Response::ReadHoldingRegisters(self.read(addr, count).await?)))
            }
            Request::WriteSingleRegister(addr, word) => {
                self.write(addr, &[word], 6).await?;
                Ok(Some(Response::WriteSingleRegister(addr, word)))
            }
            Request::WriteMultipleRegisters(addr, words) => {
                self.write(addr, &words, 16).await?;
                let n = u16::try_from(words.len()).unwrap_or(u16::MAX);
                Ok(Some(Response::WriteMultipleRegisters(addr, n)))
            }
            _ => Err(ExceptionCode::IllegalFunction),
        }
    }
}

/// The tokio-modbus service over the register bank.
#[derive(Clone)]
struct ChamberService(Arc<Shared>);

type BoxFut<T> = Pin<Box<dyn Future<Output = T> + Send>>;

impl tokio_modbus::server::Service for ChamberService {
    type Request = SlaveRequest<'static>;
    type Response = Option<Response>;
    type Exception = ExceptionCode;
    type Future = BoxFut<Result<Option<Response>, ExceptionCode>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        let shared = self.0.clone();
        Box::pin(async move { shared.handle(req).await })
    }
}

/// A running chamber server; stops when dropped.
pub struct ServedChamber {
    /// What a driver opens (pty path at 9600 baud, or `127.0.0.1:port`).
    pub endpoint: Endpoint,
    shared: Arc<Shared>,
    tasks: Vec<JoinHandle<()>>,
}

impl ServedChamber {
    /// Every accepted register write so far, in order.
    pub fn writes(&self) -> Vec<WriteRecord> {
        lock(&self.shared.writes).clone()
    }

    /// The faults this server applies.
    pub fn faults(&self) -> &FaultSwitch {
        &self.shared.opts.faults
    }

    /// What the line carried (RTU only: counted by the proxy; zero on TCP).
    pub fn wire_stats(&self) -> Arc<ChamberWireStats> {
        self.shared.wire.clone()
    }
}

impl Drop for ServedChamber {
    fn drop(&mut self) {
        self.tasks.iter().for_each(JoinHandle::abort);
    }
}

fn shared(
    chamber: Box<dyn Chamber>,
    clock: Arc<dyn Clock>,
    opts: ChamberServeOptions,
) -> Arc<Shared> {
    let mut bank: HashMap<u16, u16> = opts.extra_registers.iter().copied().collect();
    let map = &opts.map;
    let plain =
        map.on_connect.iter().map(|w| w.register).chain(map.eeprom_registers.iter().copied());
    for r in plain {
        bank.entry(r).or_insert(0);
    }
    if let Some(r) = map.ramp_rate {
        for a in range(r, map.encoding.word_count()) {
            if let Ok(a) = u16::try_from(a) {
                bank.entry(a).or_insert(0);
            }
        }
    }
    Arc::new(Shared {
        wire: Arc::default(),
        clock,
        state: tokio::sync::Mutex::new(State { chamber, bank, overshoot: None }),
        writes: Mutex::new(Vec::new()),
        opts,
    })
}

/// Serve `chamber` over Modbus TCP on 127.0.0.1 (OS-chosen port). Ready on return: the
/// listener is bound, so a driver may connect at once.
pub async fn serve_chamber_tcp(
    chamber: Box<dyn Chamber>,
    clock: Arc<dyn Clock>,
    opts: ChamberServeOptions,
) -> io::Result<ServedChamber> {
    let listener = loopback_listener().await?;
    let addr = listener.local_addr()?;
    let shared = shared(chamber, clock, opts);
    let service = ChamberService(shared.clone());
    let faults = shared.opts.faults.clone();
    let counter = Arc::new(Mutex::new(FaultCounter::default()));
    let task = tokio::spawn(async move {
        let server = tokio_modbus::server::tcp::Server::new(listener);
        let on_connected = move |stream: TcpStream, _peer| {
            let service = service.clone();
            let faults = faults.clone();
            let counter = counter.clone();
            async move {
                stream.set_nodelay(true)?;
                Ok(Some((service, FaultyTcp::new(stream, faults, counter))))
            }
        };
        let on_error = |e: io::Error| tracing::debug!(error = %e, "modbus tcp connection ended");
        if let Err(e) = server.serve(&on_connected, on_error).await {
            tracing::warn!(error = %e, "modbus tcp server stopped");
        }
    });
    Ok(ServedChamber {
        endpoint: Endpoint::Tcp { addr: addr.to_string() },
        shared,
        tasks: vec![task],
    })
}

/// Serve `chamber` over Modbus RTU on a new pseudo-terminal (the endpoint's path). Ready on
/// return: bytes a driver writes wait in the pty until the server reads them.
pub fn serve_chamber_rtu(
    chamber: Box<dyn Chamber>,
    clock: Arc<dyn Clock>,
    opts: ChamberServeOptions,
) -> io::Result<ServedChamber> {
    let outer = Pty::new()?;
    let (server_end, proxy_end) = tokio_serial::SerialStream::pair().map_err(io::Error::other)?;
    let endpoint = Endpoint::Serial(SerialSettings {
        path: outer.path.clone(),
        baud: 9600,
        parity: Parity::None,
        data_bits: 8,
        stop_bits: 1,
    });
    let shared = shared(chamber, clock.clone(), opts);
    let service = ChamberService(shared.clone());
    let server = tokio::spawn(async move {
        let server = tokio_modbus::server::rtu::Server::new(server_end);
        if let Err(e) = server.serve_forever(service).await {
            tracing::warn!(error = %e, "modbus rtu server stopped");
        }
    });
    let proxy = tokio::spawn(rtu_proxy(outer, proxy_end, shared.clone(), clock));
    Ok(ServedChamber { endpoint, shared, tasks: vec![server, proxy] })
}

/// Forwards bytes between the driver's pty and the RTU server's, applying `Corrupt` (replies)
/// and `Disconnect` (requests dropped for a while), and counting state reads
/// ([`ChamberWireStats`]).
async fn rtu_proxy(
    mut outer: Pty,
    mut inner: tokio_serial::SerialStream,
    shared: Arc<Shared>,
    clock: Arc<dyn Clock>,
) {
    let faults = shared.opts.faults.clone();
    let wire = shared.wire.clone();
    let map = &shared.opts.map;
    let mut req = [0u8; 512];
    let mut rep = [0u8; 512];
    let mut counter = FaultCounter::default();
    let mut dead_until: Option<Duration> = None;
    // What each forwarded request reads, oldest first (the server answers in order); the
    // replies not yet parsed into frames; whether the process value of the poll in progress
    // came back intact.
    let mut pending: std::collections::VecDeque<StateRead> = Default::default();
    let mut replies: Vec<u8> = Vec::new();
    let mut pv_ok = false;
    let classify = |frame: &[u8]| match (frame.get(1), frame.get(2), frame.get(3)) {
        (Some(3 | 4), Some(&hi), Some(&lo)) => {
            let addr = u16::from_be_bytes([hi, lo]);
            if addr == map.process_value {
                StateRead::ProcessValue
            } else if Some(addr) == map.working_set_point {
                StateRead::WorkingSetPoint
            } else {
                StateRead::Other
            }
        }
        _ => StateRead::Other,
    };
    loop {
        tokio::select! {
            r = outer.server.read(&mut req) => {
                let Ok(n) = r else { break };
                let bytes = req.get(..n).unwrap_or_default();
                if let Some(f @ Fault::Disconnect { seconds }) =
                    faults.find(|f| matches!(f, Fault::Disconnect { .. }))
                {
                    faults.remove(&f);
                    let secs = if seconds.is_finite() { seconds.max(0.0) } else { 0.0 };
                    dead_until = Some(clock.now() + Duration::from_secs_f64(secs));
                }
                let dead = dead_until.is_some_and(|t| clock.now() < t);
                let mut rest = bytes;
                while let Some(len) = rtu_request_len(rest) {
                    let (frame, tail) = rest.split_at(len.min(rest.len()));
                    let kind = classify(frame);
                    if dead {
                        if kind != StateRead::Other {
                            bump(&wire.state_dropped);
                        }
                    } else {
                        pending.push_back(kind);
                    }
                    rest = tail;
                }
                if dead {
                    continue;
                }
                if inner.write_all(bytes).await.is_err() {
                    break;
                }
            }
            r = inner.read(&mut rep) => {
                let Ok(n) = r else { break };
                let Some(bytes) = rep.get_mut(..n) else { break };
                let mut damaged_at = None;
                if let Some(Fault::Corrupt { every }) =
                    faults.find(|f| matches!(f, Fault::Corrupt { .. }))
                {
                    if counter.tick(every) {
                        if let Some(last) = bytes.last_mut() {
                            *last ^= 0xFF;
                            bump(&wire.corrupted);
                            damaged_at = Some(replies.len() + n - 1);
                        }
                    }
                }
                replies.extend_from_slice(bytes);
                // Every complete reply frame, paired with the request it answers.
                let mut start = 0;
                while let Some(len) = replies.get(start..).and_then(rtu_reply_len) {
                    let end = start + len;
                    if end > replies.len() {
                        break;
                    }
                    let damaged = damaged_at.is_some_and(|d| (start..end).contains(&d));
                    let exception = replies.get(start + 1).is_some_and(|fc| fc & 0x80 != 0);
                    let state = pending.pop_front().unwrap_or(StateRead::Other);
                    if state != StateRead::Other {
                        if damaged {
                            bump(&wire.state_corrupted);
                        } else if exception {
                            bump(&wire.state_exceptions);
                        }
                    }
                    let intact = !damaged && !exception;
                    let complete = |wire: &ChamberWireStats| {
                        bump(&wire.state_replies);
                        let now = clock.now().as_nanos() as u64;
                        wire.last_state_reply_ns.store(now, Ordering::Relaxed);
                    };
                    match state {
                        StateRead::ProcessValue if intact && map.working_set_point.is_none() => {
                            complete(&wire);
                        }
                        StateRead::ProcessValue => pv_ok = intact,
                        // A damaged working set point is read again by the driver within
                        // the same poll: the process value stays good.
                        StateRead::WorkingSetPoint if intact => {
                            if pv_ok {
                                complete(&wire);
                            }
                            pv_ok = false;
                        }
                        StateRead::WorkingSetPoint => {}
                        StateRead::Other => pv_ok = false,
                    }
                    start = end;
                }
                replies.drain(..start.min(replies.len()));
                if outer.server.write_all(bytes).await.is_err() {
                    break;
                }
            }
        }
    }
    tracing::debug!("modbus rtu proxy stopped");
}

/// Length of the Modbus RTU request frame at the start of `b` (functions 3, 4, 6, 16), if
/// known from the bytes there.
fn rtu_request_len(b: &[u8]) -> Option<usize> {
    match b.get(1)? {
        3 | 4 | 6 => Some(8),
        16 => Some(9 + usize::from(*b.get(6)?)),
        _ => (!b.is_empty()).then_some(b.len()),
    }
}

/// Length of the Modbus RTU reply frame at the start of `b`, if known from the bytes there.
fn rtu_reply_len(b: &[u8]) -> Option<usize> {
    let fc = *b.get(1)?;
    if fc & 0x80 != 0 {
        return Some(5);
    }
    match fc {
        3 | 4 => Some(5 + usize::from(*b.get(2)?)),
        6 | 16 => Some(8),
        _ => Some(b.len()),
    }
}

/// A server-side TCP stream applying `Disconnect` (EOF at the next request) and `Corrupt`.
struct FaultyTcp {
    inner: TcpStream,
    faults: FaultSwitch,
    /// Shared by the server's connections: "every n-th reply" of the device.
    counter: Arc<Mutex<FaultCounter>>,
    corrupt_this: Option<bool>,
}

impl FaultyTcp {
    fn new(inner: TcpStream, faults: FaultSwitch, counter: Arc<Mutex<FaultCounter>>) -> Self {
        Self { inner, faults, counter, corrupt_this: None }
    }
}

impl AsyncRead for FaultyTcp {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let r = Pin::new(&mut self.inner).poll_read(cx, buf);
        if r.is_ready() {
            if let Some(f) = self.faults.find(|f| matches!(f, Fault::Disconnect { .. })) {
                self.faults.remove(&f);
                buf.clear();
                return Poll::Ready(Ok(()));
            }
        }
        r
    }
}

impl AsyncWrite for FaultyTcp {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let corrupt = match self.corrupt_this {
            Some(c) => c,
            None => {
                let c = match self.faults.find(|f| matches!(f, Fault::Corrupt { .. })) {
                    Some(Fault::Corrupt { every }) => lock(&self.counter).tick(every),
                    _ => false,
                };
                self.corrupt_this = Some(c);
                c
            }
        };
        let r = if corrupt {
            let mut v = buf.to_vec();
            if let Some(b) = v.get_mut(1) {
                *b ^= 0xFF;
            }
            Pin::new(&mut self.inner).poll_write(cx, &v)
        } else {
            Pin::new(&mut self.inner).poll_write(cx, buf)
        };
        if r.is_ready() {
            self.corrupt_this = None;
        }
        r
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}
