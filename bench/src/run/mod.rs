//! The orchestrator: device pollers, the step sequencer and the recorder, running as tasks on
//! one shared [`Clock`].
//!
//! ```text
//!  gyro task ──┐                      ┌─> /gyro/rate
//!  table poller ├─> Event channel ──> recorder task ─> /table/state, /chamber/state,
//!  chamber poller┘        ^                           /bench/step, /log  (MCAP)
//!  sequencer ─────────────┘ (step events; commands devices through their mutexes)
//! ```
//!
//! The same code runs on the virtual-time executor (simulated bench, as fast as the CPU allows)
//! and on tokio in real time (real devices): it only sleeps through the clock and spawns through
//! a [`futures::task::Spawn`].

pub mod interlocks;
pub mod live;
pub mod logging;
mod sequencer;
pub mod threaded;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bench_drivers::{
    Chamber, ChamberReading, Clock, DeviceError, DeviceResult, ErrorKind, Gyro, GyroSample,
    RateTable, TableReading,
};
use futures::channel::mpsc;
use futures::future::{AbortHandle, Abortable};
use futures::lock::Mutex as AsyncMutex;
use futures::task::{Spawn, SpawnExt};
use futures::StreamExt;
use tracing::instrument::WithSubscriber;
use tracing_subscriber::layer::SubscriberExt;

use crate::plan::RunPlan;
use bench_recording::{ChamberMsg, GyroMsg, TableMsg};
pub use bench_recording::{LogLevel, Outcome, StepEvent};
pub use live::{Live, Snapshot, Stream};

/// Everything a run records, in the order it happened per source.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A gyro sample received at bench time `t`.
    Gyro(Duration, GyroSample),
    /// A table reading taken at `t`.
    Table(Duration, TableReading),
    /// A chamber reading taken at `t`.
    Chamber(Duration, ChamberReading),
    /// A step started, ended or aborted.
    Step {
        /// Bench time.
        t: Duration,
        /// Step index in the plan.
        index: usize,
        /// Step kind.
        name: String,
        /// `start`, `end` or `abort`.
        event: StepEvent,
        /// Step label.
        label: String,
    },
    /// A log message (foxglove.Log).
    Log {
        /// Bench time.
        t: Duration,
        /// Severity.
        level: LogLevel,
        /// Text.
        message: String,
        /// Source (tracing target).
        name: String,
        /// Source file.
        file: String,
        /// Source line.
        line: u32,
    },
}

/// Where a run's events go: the MCAP recorder, or memory in tests. Errors stop the run (it
/// aborts to a safe state); the sink keeps what it already has.
pub trait EventSink: Send + 'static {
    /// Record one event.
    fn record(&mut self, event: &Event) -> anyhow::Result<()>;
}

/// The devices of one run.
pub struct Devices {
    /// Rate table.
    pub table: Box<dyn RateTable>,
    /// Climatic chamber.
    pub chamber: Box<dyn Chamber>,
    /// Gyro.
    pub gyro: Box<dyn Gyro>,
}

/// Result of [`execute`].
pub struct RunResult<S> {
    /// What stopped the run early; `None` when every step completed.
    pub fault: Option<Fault>,
    /// The sink, with everything recorded, to be finished by the caller.
    pub sink: S,
    /// Bench time at the end.
    pub duration: Duration,
    /// What the table's wire link coped with over the run (a real driver's; `None` otherwise).
    pub table_link: Option<bench_drivers::real::link::LinkCounters>,
}

impl<S> RunResult<S> {
    /// How the run ended (`bench.run` `outcome`).
    pub fn outcome(&self) -> Outcome {
        outcome_of(self.fault.as_ref())
    }
}

/// `completed` without a fault, `aborted: <message>` with one.
pub fn outcome_of(fault: Option<&Fault>) -> Outcome {
    match fault {
        None => Outcome::Completed,
        Some(f) => Outcome::Aborted(f.message.clone()),
    }
}

/// What kind of thing stopped a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultCause {
    /// A device failed; its error's kind decides nothing more here (the run is over).
    Device {
        /// `rate table`, `chamber` or `gyro`.
        device: &'static str,
        /// The device error's kind.
        kind: ErrorKind,
    },
    /// A device stream had no good reading for longer than the policy allows.
    Stale {
        /// `rate table`, `chamber` or `gyro`.
        device: &'static str,
    },
    /// A step's condition was not met within its time (temperature or ramp end not reached).
    StepTimeout,
    /// A run-time interlock tripped (`[interlocks]`); `name` is one of the names in
    /// [`interlocks`] and leads the fault's message: a threshold (`table_overspeed`,
    /// `table_stall`, `rate_disagreement`, `chamber_over_temperature`,
    /// `chamber_under_temperature`, `setpoint_not_tracked`, `gyro_status`) or a device's own
    /// fault report, tripped by the first reading that shows it (`table_drive_fault`,
    /// `table_interlock_open`, `table_mode_lost`, `chamber_alarm`, `chamber_door_open`,
    /// `gyro_bit_fail`).
    Interlock {
        /// The interlock's name.
        name: &'static str,
    },
    /// The operator (or a signal) asked the run to stop.
    Operator,
    /// The recording could not be written.
    Recording,
    /// The run's tasks could not be started.
    Start,
}

/// Why a run stopped early: its cause and the message recorded in `outcome`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// The cause.
    pub cause: FaultCause,
    /// What happened, for people (becomes `aborted: <message>`).
    pub message: String,
}

impl Fault {
    /// A fault of `cause` with `message`.
    pub fn new(cause: FaultCause, message: impl Into<String>) -> Self {
        Self { cause, message: message.into() }
    }

    /// The same fault with `context` before its message (`context: message`).
    pub fn context(self, context: impl std::fmt::Display) -> Self {
        Self { message: format!("{context}: {}", self.message), ..self }
    }
}

/// Limits of the fault handling.
#[derive(Debug, Clone)]
pub struct FaultPolicy {
    /// Consecutive transient errors (timeouts, CRC) of one device before the run aborts.
    pub max_consecutive_errors: u32,
    /// How long a safe-state command may take before it is given up, bench time.
    pub safe_state_timeout: Duration,
    /// A stream with no good reading for this long is stale: the run aborts.
    pub stale_after: Duration,
}

impl Default for FaultPolicy {
    fn default() -> Self {
        Self {
            max_consecutive_errors: 5,
            safe_state_timeout: Duration::from_secs(10),
            stale_after: Duration::from_secs(30),
        }
    }
}

/// A terminal (or other) tracing layer for a run's log events.
pub type ConsoleLayer =
    Box<dyn tracing_subscriber::Layer<tracing_subscriber::Registry> + Send + Sync>;

/// Asks a running [`execute`] to abort (e.g. on Ctrl-C): the current step ends with an `abort`
/// event, the bench goes to its safe state and the fault is [`FaultCause::Operator`]. A second
/// request (or [`Stopper::stop_now`]) stops at once: the safe-state commands are still sent,
/// but each is waited for at most [`HURRIED_SAFE_STATE_TIMEOUT`], and the tail of recording
/// after them is skipped.
#[derive(Clone, Debug)]
pub struct Stopper(mpsc::UnboundedSender<StopRequest>);

/// What a [`Stopper`] asks.
#[derive(Debug, Clone, PartialEq)]
enum StopRequest {
    /// Abort to the safe state with this reason.
    Abort(String),
    /// Stop now (a second interrupt).
    Now,
}

impl Stopper {
    /// A stopper and the signal to hand to [`ExecOptions::stop`].
    pub fn new() -> (Self, StopSignal) {
        let (tx, rx) = mpsc::unbounded();
        (Self(tx), StopSignal(rx))
    }

    /// Abort the run with `reason` (ignored once the run has ended). A second call stops at
    /// once, as [`Stopper::stop_now`].
    pub fn stop(&self, reason: impl Into<String>) {
        let _ = self.0.unbounded_send(StopRequest::Abort(reason.into()));
    }

    /// Stop at once: abort if not yet aborting, and cut the safe state short (the commands
    /// are still sent).
    pub fn stop_now(&self) {
        let _ = self.0.unbounded_send(StopRequest::Now);
    }
}

/// The receiving end of a [`Stopper`].
#[derive(Debug)]
pub struct StopSignal(mpsc::UnboundedReceiver<StopRequest>);

/// After a second stop request, how long each safe-state command is still waited for, bench
/// time.
pub const HURRIED_SAFE_STATE_TIMEOUT: Duration = Duration::from_secs(1);

/// Options of [`execute`].
#[derive(Default)]
pub struct ExecOptions {
    /// Extra tracing layer (the CLI's terminal output); every event also goes to `/log`.
    pub console: Option<ConsoleLayer>,
    /// External abort request.
    pub stop: Option<StopSignal>,
    /// Limits of the fault handling.
    pub policy: FaultPolicy,
}

/// How long the streams are still recorded after the safe-state commands.
pub const SAFE_STATE_TAIL: Duration = Duration::from_secs(1);

/// Shared state of one run's tasks.
pub(crate) struct Ctx {
    pub clock: Arc<dyn Clock>,
    pub tx: mpsc::UnboundedSender<Event>,
    pub live: Arc<Live>,
    pub table: AsyncMutex<Box<dyn RateTable>>,
    pub chamber: AsyncMutex<Box<dyn Chamber>>,
    /// First fatal fault reported by a poller, the watchdog, the stop signal or the recorder.
    pub fault: Mutex<Option<Fault>>,
    pub fault_notify: mpsc::UnboundedSender<()>,
    pub policy: FaultPolicy,
    /// A second stop request came: the safe state is cut short.
    pub hurry: AtomicBool,
    /// Interlock thresholds and the monitor's state.
    pub interlocks: crate::plan::Interlocks,
    pub monitor: Mutex<interlocks::Monitor>,
}

impl Ctx {
    pub fn send(&self, e: Event) {
        // Fails only once the recorder has gone, i.e. after the run has ended.
        let _ = self.tx.unbounded_send(e);
    }

    pub fn raise_fault(&self, fault: Fault) {
        let mut f = self.fault.lock().unwrap_or_else(|p| p.into_inner());
        if f.is_none() {
            tracing::error!("{}", fault.message);
            *f = Some(fault);
            let _ = self.fault_notify.unbounded_send(());
        }
    }

    /// Check a reading against the interlocks; a violation raises its fault.
    fn check(
        &self,
        f: impl FnOnce(&mut interlocks::Monitor, &crate::plan::Interlocks) -> Option<Fault>,
    ) {
        let fault = {
            let mut m = self.monitor.lock().unwrap_or_else(|p| p.into_inner());
            f(&mut m, &self.interlocks)
        };
        if let Some(fault) = fault {
            self.raise_fault(fault);
        }
    }

    /// Bench commanded the table into `mode`; call it with the table still held.
    pub fn table_commanded(&self, mode: bench_drivers::TableMode) {
        self.monitor.lock().unwrap_or_else(|p| p.into_inner()).table_commanded(mode);
    }

    pub fn hurried(&self) -> bool {
        self.hurry.load(Ordering::SeqCst)
    }

    pub fn fault(&self) -> Option<Fault> {
        self.fault.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

/// Counts consecutive errors of one device; a fault once the policy's limit is reached or on
/// the first non-transient error.
struct ErrorBudget {
    device: &'static str,
    consecutive: u32,
}

impl ErrorBudget {
    fn ok(&mut self) {
        self.consecutive = 0;
    }
    fn err(&mut self, ctx: &Ctx, e: &DeviceError) -> bool {
        self.consecutive += 1;
        if !e.kind().is_transient() || self.consecutive >= ctx.policy.max_consecutive_errors {
            ctx.raise_fault(Fault::new(
                FaultCause::Device { device: self.device, kind: e.kind() },
                format!(
                    "{} failed after {} consecutive error(s): {e}",
                    self.device, self.consecutive
                ),
            ));
            true
        } else {
            tracing::warn!("{}: {e} (retrying)", self.device);
            false
        }
    }
}

async fn gyro_task(ctx: Arc<Ctx>, mut gyro: Box<dyn Gyro>) {
    let mut budget = ErrorBudget { device: "gyro", consecutive: 0 };
    loop {
        match gyro.next_sample().await {
            Ok(s) => {
                budget.ok();
                let t = ctx.clock.now();
                ctx.live.set_gyro(s.rate_rad_s, s.temperature_c);
                ctx.live.set_fresh(Stream::Gyro, t);
                ctx.check(|m, lim| m.gyro(lim, t, &s));
                ctx.send(Event::Gyro(t, s));
            }
            Err(e) => {
                if budget.err(&ctx, &e) {
                    return;
                }
            }
        }
    }
}

fn period(hz: f64) -> Duration {
    Duration::from_secs_f64(1.0 / hz)
}

/// A polled reading and the bench time it was taken at: the midpoint of the request's round
/// trip. A polled device (the table's angle, the chamber's process value) does not stamp its
/// answer; it samples somewhere between the request and the reply, and the midpoint is off by
/// at most half the round trip whichever side is slow. The reply's arrival alone would carry
/// the whole round trip, and every delay of the host in reading it, as a late stamp.
async fn read_stamped<R>(
    clock: &dyn Clock,
    read: impl std::future::Future<Output = DeviceResult<R>>,
) -> DeviceResult<(Duration, R)> {
    let sent = clock.now();
    let r = read.await?;
    let received = clock.now();
    Ok((sent + received.saturating_sub(sent) / 2, r))
}

/// One poll of the table or the chamber: the device's housekeeping, then a reading, noted in
/// the live values; the event to record and its bench time.
async fn poll_once(ctx: &Ctx, stream: Stream) -> DeviceResult<(Duration, Event)> {
    match stream {
        Stream::Table => {
            let mut table = ctx.table.lock().await;
            table.service().await?;
            let (t, r) = read_stamped(&*ctx.clock, table.read()).await?;
            ctx.live.set_table(r.rate_rad_s, r.rate_command_rad_s);
            ctx.check(|m, lim| m.table(lim, t, &r));
            Ok((t, Event::Table(t, r)))
        }
        Stream::Chamber => {
            let mut chamber = ctx.chamber.lock().await;
            chamber.service().await?;
            let (t, r) = read_stamped(&*ctx.clock, chamber.read()).await?;
            ctx.live.set_chamber(r.temperature_c, r.setpoint_c, r.target_c);
            ctx.check(|m, lim| m.chamber(lim, t, &r));
            Ok((t, Event::Chamber(t, r)))
        }
        // The gyro streams by itself (`gyro_task`).
        Stream::Gyro => Err(DeviceError::new(ErrorKind::Unsupported, "the gyro is not polled")),
    }
}

/// Polls the table or the chamber at `hz` on the run's clock, from the run's first instant.
async fn poller(ctx: Arc<Ctx>, stream: Stream, hz: f64) {
    let mut budget = ErrorBudget { device: stream.device(), consecutive: 0 };
    let dt = period(hz);
    let t0 = ctx.clock.now();
    let mut k: u32 = 0;
    loop {
        k += 1;
        ctx.clock.sleep_until(t0 + dt * k).await;
        match poll_once(&ctx, stream).await {
            Ok((t, event)) => {
                budget.ok();
                ctx.live.set_time(t);
                ctx.live.set_fresh(stream, t);
                ctx.send(event);
            }
            Err(e) => {
                if budget.err(&ctx, &e) {
                    return;
                }
            }
        }
    }
}

/// Watches every device stream: none may go without a good reading for longer than the
/// policy's `stale_after` (a driver that hangs, or answers with errors that each stay under the
/// retry budget, still goes stale). Checks once per second of bench time.
async fn watchdog_task(ctx: Arc<Ctx>) {
    let start = ctx.clock.now();
    let limit = ctx.policy.stale_after;
    loop {
        ctx.clock.sleep(Duration::from_secs(1)).await;
        let now = ctx.clock.now();
        for s in Stream::ALL {
            let last = ctx.live.fresh(s).max(start);
            if now.saturating_sub(last) > limit {
                ctx.raise_fault(Fault::new(
                    FaultCause::Stale { device: s.device() },
                    format!(
                        "{}: {} data stale: no good reading for {:.1} s (limit {:.1} s)",
                        interlocks::STREAM_STALE,
                        s.device(),
                        (now - last).as_secs_f64(),
                        limit.as_secs_f64()
                    ),
                ));
                return;
            }
        }
    }
}

/// The recorder task: drains the event channel into the sink until every sender is gone.
async fn recorder_task<S: EventSink>(
    mut rx: mpsc::UnboundedReceiver<Event>,
    mut sink: S,
    ctx: Arc<Ctx>,
) -> S {
    while let Some(ev) = rx.next().await {
        if let Err(e) = sink.record(&ev) {
            ctx.raise_fault(Fault::new(FaultCause::Recording, format!("recording failed: {e:#}")));
            // Keep draining so senders never block; nothing more can be written.
            while rx.next().await.is_some() {}
            break;
        }
    }
    sink
}

/// Run `plan` on `devices`, recording every stream into `sink`.
///
/// `console` is an optional extra tracing layer (e.g. the CLI's terminal output); every event
/// of the run also goes to the recording's `/log` channel. Returns when the last step has ended
/// or the run has aborted and the devices were put into their safe state.
pub async fn execute<S: EventSink>(
    plan: &RunPlan,
    devices: Devices,
    clock: Arc<dyn Clock>,
    sink: S,
    spawner: impl Spawn,
    live: Arc<Live>,
    options: ExecOptions,
) -> RunResult<S> {
    let ExecOptions { console, stop, policy } = options;
    let (tx, rx) = mpsc::unbounded();
    let (fault_tx, fault_rx) = mpsc::unbounded();

    let dispatch = tracing::Dispatch::new(
        tracing_subscriber::Registry::default()
            .with(console)
            .with(logging::RecordingLayer::new(tx.clone(), clock.clone())),
    );

    let ctx = Arc::new(Ctx {
        clock: clock.clone(),
        tx,
        live,
        table: AsyncMutex::new(devices.table),
        chamber: AsyncMutex::new(devices.chamber),
        fault: Mutex::new(None),
        fault_notify: fault_tx,
        policy,
        hurry: AtomicBool::new(false),
        interlocks: plan.interlocks.clone(),
        monitor: Mutex::new(interlocks::Monitor::default()),
    });

    let recording = recorder_task(rx, sink, ctx.clone());

    let mut aborts: Vec<AbortHandle> = Vec::new();
    let mut spawn_errors = Vec::new();
    let device_tasks: Vec<futures::future::BoxFuture<'static, ()>> = vec![
        Box::pin(gyro_task(ctx.clone(), devices.gyro)),
        Box::pin(poller(ctx.clone(), Stream::Table, plan.table_poll_hz)),
        Box::pin(poller(ctx.clone(), Stream::Chamber, plan.chamber_poll_hz)),
        Box::pin(watchdog_task(ctx.clone())),
    ];
    let mut device_tasks = device_tasks;
    if let Some(StopSignal(mut rx)) = stop {
        let c = ctx.clone();
        device_tasks.push(Box::pin(async move {
            let mut requests = 0;
            while let Some(request) = rx.next().await {
                requests += 1;
                let now = requests > 1 || request == StopRequest::Now;
                let reason = match request {
                    StopRequest::Abort(reason) if requests == 1 => reason,
                    _ => "stopped at once by the operator".to_string(),
                };
                if now {
                    tracing::warn!(
                        "second interrupt: stopping now; the safe-state commands are still sent"
                    );
                    c.hurry.store(true, Ordering::SeqCst);
                }
                c.raise_fault(Fault::new(FaultCause::Operator, reason));
            }
        }));
    }
    for fut in device_tasks {
        let (h, reg) = AbortHandle::new_pair();
        aborts.push(h);
        let f = Abortable::new(fut.with_subscriber(dispatch.clone()), reg);
        if let Err(e) = spawner.spawn(async move {
            let _ = f.await;
        }) {
            spawn_errors.push(e.to_string());
        }
    }

    // The recorder runs beside the sequencer in this task. It ends when `main` closes the
    // channel, after the safe state, and hands the sink back.
    let main_ctx = ctx.clone();
    let main = async move {
        let ctx = main_ctx;
        let fault = if spawn_errors.is_empty() {
            sequencer::run_steps(plan, &ctx, fault_rx).await
        } else {
            Some(Fault::new(
                FaultCause::Start,
                format!("cannot start device tasks: {}", spawn_errors.join("; ")),
            ))
        };
        match &fault {
            Some(f) => tracing::error!("run aborted: {}", f.message),
            None => tracing::info!("run completed"),
        }
        sequencer::safe_state(plan, &ctx).await;
        // Keep recording briefly so the safe-state commands show in the streams (not after a
        // second stop request).
        sequencer::sleep_unless_hurried(&ctx, SAFE_STATE_TAIL).await;
        let duration = ctx.clock.now();
        aborts.iter().for_each(AbortHandle::abort);
        // The pollers are stopped: the table is free. Its link's tally goes into the log.
        let table_link = ctx.table.lock().await.link_counters();
        if let Some(c) = table_link {
            tracing::info!(
                late = c.late_replies,
                stale = c.stale_replies,
                corrupt = c.corrupt_replies,
                retries = c.retries,
                reconnects = c.reconnects,
                "rate table link: replies that came after their timeout, skipped replies, retries"
            );
        }
        ctx.tx.close_channel();
        (fault, duration, table_link)
    }
    .with_subscriber(dispatch);
    let (sink, (fault, duration, table_link)) = futures::join!(recording, main);
    RunResult { fault, sink, duration, table_link }
}

impl<W: std::io::Write + std::io::Seek + Send + 'static> EventSink
    for bench_recording::Recorder<W>
{
    fn record(&mut self, event: &Event) -> anyhow::Result<()> {
        match event {
            Event::Gyro(t, s) => self.gyro(*t, s.device_time, &gyro_msg(s))?,
            Event::Table(t, r) => self.table(*t, r.device_time, &table_msg(r))?,
            Event::Chamber(t, r) => self.chamber(*t, r.device_time, &chamber_msg(r))?,
            Event::Step { t, index, name, event, label } => {
                self.step(*t, *index as u64, name, *event, label)?
            }
            Event::Log { t, level, message, name, file, line } => {
                self.log(*t, *level, message, name, file, *line)?
            }
        }
        Ok(())
    }
}

/// A gyro sample as recorded (`/gyro/rate`).
pub fn gyro_msg(s: &GyroSample) -> GyroMsg {
    GyroMsg {
        rate_rad_s: s.rate_rad_s,
        temperature_c: s.temperature_c,
        seq: s.seq,
        status: s.status,
    }
}

/// A table reading as recorded (`/table/state`).
pub fn table_msg(r: &TableReading) -> TableMsg {
    TableMsg {
        angle_rad: r.angle_rad,
        rate_rad_s: r.rate_rad_s,
        rate_command_rad_s: r.rate_command_rad_s,
        status: r.status,
    }
}

/// A chamber reading as recorded (`/chamber/state`).
pub fn chamber_msg(r: &ChamberReading) -> ChamberMsg {
    ChamberMsg { temperature_c: r.temperature_c, setpoint_c: r.setpoint_c, status: r.status }
}

#[cfg(test)]
mod stamp_tests {
    use super::*;
    use bench_drivers::clock::run_virtual;
    use bench_drivers::VirtualClock;

    /// A polled reading is stamped at its round trip's midpoint: a reply 0.4 s after a request
    /// sent at 2 s is stamped 2.2 s (its arrival, 2.4 s, is off by the whole trip).
    #[test]
    fn a_polled_reading_is_stamped_at_the_middle_of_its_round_trip() {
        let clock = VirtualClock::new();
        let c = clock.clone();
        let (t, r) = run_virtual(&clock, move |_| async move {
            c.sleep(Duration::from_secs(2)).await;
            let slow = async {
                c.sleep(Duration::from_millis(400)).await;
                Ok::<_, DeviceError>(7)
            };
            read_stamped(&c, slow).await
        })
        .expect("no deadlock")
        .expect("read");
        assert_eq!((t, r), (Duration::from_millis(2200), 7));
    }
}
