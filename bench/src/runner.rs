//! One way to run a plan and record it, whatever the bench: the embedded simulators and replays
//! in virtual time ([`run_virtual`]), real devices or simulators behind virtual ports and
//! replays in real (or scaled) time on tokio ([`run_realtime`]). Both start the recording the
//! same way (recorder thread, live view, progress), run [`crate::run::execute`], and end with the
//! same typed [`RunReport`].

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use bench_drivers::clock::{run_virtual as run_on_virtual_executor, TokioSpawner, VirtualClock};
use bench_drivers::{Clock, SystemClock};
use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use bench_recording::{Outcome, Recorder, RecorderOptions, RunInfo};

use crate::live_view::{LiveTee, LiveView};
use crate::plan::RunPlan;
use crate::run::threaded::ThreadedSink;
use crate::run::{
    execute, outcome_of, ConsoleLayer, Devices, ExecOptions, Fault, FaultCause, FaultPolicy, Live,
    RunResult, StopSignal, Stopper,
};

/// What a run did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// How it ended (`bench.run` `outcome`).
    pub outcome: Outcome,
    /// What stopped it early, typed; `None` when it completed.
    pub fault: Option<Fault>,
    /// Bench time covered.
    pub bench_time: Duration,
    /// Wall-clock time taken.
    pub wall_time: Duration,
    /// Gyro samples recorded.
    pub gyro_samples: u64,
}

impl RunReport {
    /// Bench time per wall time.
    pub fn speed(&self) -> f64 {
        self.bench_time.as_secs_f64() / self.wall_time.as_secs_f64().max(1e-9)
    }

    /// Whether every step completed.
    pub fn completed(&self) -> bool {
        self.fault.is_none()
    }
}

/// Options of a run, whatever its bench.
#[derive(Default)]
pub struct RunOptions {
    /// Show a progress bar on a terminal.
    pub progress: bool,
    /// Also show the streams in a Foxglove live view.
    pub live: Option<Arc<LiveView>>,
    /// Terminal log layer (every event also goes to `/log`).
    pub console: Option<ConsoleLayer>,
    /// External abort request (Ctrl-C).
    pub stop: Option<StopSignal>,
    /// Limits of the fault handling.
    pub policy: FaultPolicy,
    /// Kill-safety: at most this much bench time of data is lost if the process is killed
    /// (SIGKILL) mid-run; `None`: [`DEFAULT_FLUSH_INTERVAL`]. See [`kill_safe_split`].
    pub flush_interval: Option<Duration>,
    /// Print a time mark on stderr every this much bench time (`bench run --time-marks-s`).
    pub time_marks: Option<Duration>,
}

/// Default of [`RunOptions::flush_interval`]: 1 s of bench time.
pub const DEFAULT_FLUSH_INTERVAL: Duration = Duration::from_secs(1);

/// How a kill-safety bound `loss` of bench time is split: the recorder flushes every ¾ of
/// it, and in virtual time the run may run ahead of the recorder thread by at most ¼ of it
/// (in real time the hand-over is immediate, one event at a time). Returns (flush interval,
/// lag limit).
pub fn kill_safe_split(loss: Duration) -> (Duration, Duration) {
    let flush = loss * 3 / 4;
    (flush, loss - flush)
}

/// The recording side of a run: started before the devices move, finished after.
struct Session<W: Write + Seek + Send + 'static> {
    sink: LiveTee<ThreadedSink<Recorder<W>>>,
    live: Arc<Live>,
    progress: Option<crate::progress::Progress>,
    wall: Instant,
}

/// Start the recording of `plan` into `writer` with `info`. `batch`: events per hand-over to
/// the recorder thread (large in virtual time, where it amortises, bounded by the lag limit;
/// 1 in real time, so a crash loses no more than the recorder's unflushed tail).
fn start<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    info: RunInfo,
    writer: W,
    opts: &RunOptions,
    batch: usize,
) -> anyhow::Result<Session<W>> {
    let epoch_ns = info.epoch_ns;
    let (flush, lag) = kill_safe_split(opts.flush_interval.unwrap_or(DEFAULT_FLUSH_INTERVAL));
    let options = RecorderOptions { flush_interval: Some(flush), ..RecorderOptions::default() };
    let recorder =
        Recorder::with_options(writer, info, options).context("cannot start the recording")?;
    // Serialising and compressing run on the second core.
    let mut sink =
        ThreadedSink::new(recorder, batch).context("cannot start the recorder thread")?;
    if batch > 1 {
        sink = sink.lag_limit(lag);
    }
    if let Some(every) = opts.time_marks {
        sink = sink.time_marks(every, epoch_ns);
    }
    let sink = LiveTee::new(sink, opts.live.clone(), epoch_ns);
    let live = Arc::new(Live::default());
    let progress = opts.progress.then(|| crate::progress::Progress::start(live.clone(), plan));
    Ok(Session { sink, live, progress, wall: Instant::now() })
}

/// Finish the recording with the run's outcome (a recorder failure found only now aborts it).
fn finish<W: Write + Seek + Send + 'static>(
    live: &Live,
    wall: Instant,
    result: RunResult<LiveTee<ThreadedSink<Recorder<W>>>>,
) -> anyhow::Result<(RunReport, W)> {
    let wall_time = wall.elapsed();
    let (recorder, thread_error) = result.sink.into_inner().finish()?;
    let fault = result.fault.or_else(|| {
        thread_error.map(|e| Fault::new(FaultCause::Recording, format!("recording failed: {e}")))
    });
    let outcome = outcome_of(fault.as_ref());
    let writer = recorder.finish(&outcome).context("cannot finish the recording")?;
    let report = RunReport {
        outcome,
        fault,
        bench_time: result.duration,
        wall_time,
        gyro_samples: live.snapshot().gyro_samples,
    };
    Ok((report, writer))
}

/// Run `plan` on `devices` whose clock is `clock`, in virtual time (the simulated bench and
/// replays), recording into `writer` with `info`.
pub fn run_virtual<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    devices: Devices,
    clock: &VirtualClock,
    info: RunInfo,
    writer: W,
    opts: RunOptions,
) -> anyhow::Result<(RunReport, W)> {
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let Session { sink, live, progress, wall } = start(plan, info, writer, &opts, 4096)?;
    let RunOptions { console, stop, policy, .. } = opts;
    let result = run_on_virtual_executor(clock, |spawner| {
        execute(
            plan,
            devices,
            shared.clone(),
            sink,
            spawner,
            live.clone(),
            ExecOptions { console, stop, policy },
        )
    })
    .context("simulated run stalled")?;
    drop(progress);
    finish(&live, wall, result)
}

/// Run `plan` on `devices` with `clock` on the current tokio runtime, in real time (or scaled,
/// for simulators and replays), recording into `writer` with `info`. Events reach the file
/// through the recorder thread one by one, so a crash loses at most the recorder's unflushed
/// tail (it flushes every ¾ of [`RunOptions::flush_interval`] of bench time and at every
/// step end).
pub async fn run_realtime<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    devices: Devices,
    clock: SystemClock,
    info: RunInfo,
    writer: W,
    opts: RunOptions,
) -> anyhow::Result<(RunReport, W)> {
    let Session { sink, live, progress, wall } = start(plan, info, writer, &opts, 1)?;
    let RunOptions { console, stop, policy, .. } = opts;
    let shared: Arc<dyn Clock> = Arc::new(clock);
    let result = execute(
        plan,
        devices,
        shared,
        sink,
        TokioSpawner,
        live.clone(),
        ExecOptions { console, stop, policy },
    )
    .await;
    drop(progress);
    finish(&live, wall, result)
}

/// A stop signal raised by the operator, listened for on the current tokio runtime: the first
/// Ctrl-C (SIGINT) or SIGTERM aborts the run to its safe state; a second one stops at once (the
/// safe-state commands are still sent, each waited for at most
/// [`crate::run::HURRIED_SAFE_STATE_TIMEOUT`]).
pub fn stop_on_signals() -> StopSignal {
    let (stopper, stop) = Stopper::new();
    tokio::spawn(async move {
        #[cfg(unix)]
        let mut term =
            tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).ok();
        let mut first = true;
        loop {
            #[cfg(unix)]
            let sigterm = async {
                match term.as_mut() {
                    Some(t) => t.recv().await,
                    None => futures::future::pending().await,
                }
            };
            #[cfg(not(unix))]
            let sigterm = futures::future::pending::<Option<()>>();
            let what = tokio::select! {
                r = tokio::signal::ctrl_c() => match r {
                    Ok(()) => "Ctrl-C",
                    Err(_) => return,
                },
                Some(()) = sigterm => "SIGTERM",
            };
            if first {
                stopper.stop(format!("interrupted by the operator ({what})"));
                first = false;
            } else {
                stopper.stop_now();
            }
        }
    });
    stop
}

/// Now, in ns since the Unix epoch: bench time zero of a run in real time.
pub fn wall_epoch_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// `bench.*` metadata of a run of `plan`: its site, its scenario (attached under the scenario
/// file's name) and its nominal gyro model.
pub fn run_info(plan: &RunPlan, epoch_ns: u64) -> RunInfo {
    let mut info = RunInfo::new(
        epoch_ns,
        &plan.name,
        &plan.text,
        plan.site,
        gyro_model_metadata(&plan.gyro.model, &plan.gyro.effects),
    );
    info.station = plan.station.info.clone();
    info.acceptance = plan.station.acceptance_metadata();
    info.scenario_attachment = Path::new(&plan.source)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .or(info.scenario_attachment);
    info
}

/// `bench.gyro_model` metadata: the contract's keys of `model` and the `effect.*` keys of
/// `effects` (extra keys, which the contract allows).
pub fn gyro_model_metadata(model: &GyroModel, effects: &Effects) -> BTreeMap<String, String> {
    let mut meta = model.to_metadata();
    meta.extend(effects.to_metadata());
    meta
}
