//! The one way to run a plan and record it, whatever the bench: [`run`] takes the plan, the
//! [`Bench`] (the embedded simulators, a replayed recording, or devices already connected) and
//! a [`Pace`] (virtual time, as fast as the CPU allows, or real time × a scale on tokio). Every
//! run starts the recording the same way (recorder thread, live view, progress), runs
//! [`crate::run::execute`], and ends with the same typed [`RunReport`].
//! [`simulate_in_memory`] is the studies' and tests' short form: the simulated bench in
//! virtual time into memory.

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
use bench_sim::{SimBench, SimConfig};

use crate::live_view::{LiveTee, LiveView};
use crate::plan::RunPlan;
use crate::replay::ReplayData;
use crate::run::threaded::ThreadedSink;
use crate::run::{
    execute, outcome_of, ConsoleLayer, Devices, ExecOptions, Fault, FaultCause, FaultPolicy, Live,
    RunResult, StopSignal, Stopper,
};
use crate::simulate::{recorded_effects, sim_config, SIM_EPOCH_NS};

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
    /// On a replay: how the run's commands compared with the recording's.
    pub replay: Option<ReplayCounts>,
    /// What the table's wire link coped with (a real driver's; `None` otherwise).
    pub table_link: Option<bench_drivers::real::link::LinkCounters>,
}

/// How a replayed run's commands compared with the recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReplayCounts {
    /// Table rate commands sent.
    pub table_commands: u64,
    /// Of them, commands that disagree with the recorded `rate_command`.
    pub table_mismatches: u64,
    /// Chamber targets sent.
    pub chamber_targets: u64,
    /// Of them, targets that disagree with the recorded set point.
    pub chamber_mismatches: u64,
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

/// How fast a run goes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Pace {
    /// Virtual time, as fast as the CPU allows: a deterministic discrete-event executor (the
    /// simulated bench and replays).
    #[default]
    Virtual,
    /// Real time × this scale on tokio, as a bench with real devices runs (1 for real
    /// devices; any positive scale for simulators and replays).
    RealTime(f64),
}

/// Where a run's devices come from.
// One value per run, moved once: the size of the simulated variant does not matter.
#[allow(clippy::large_enum_variant)]
pub enum Bench {
    /// The embedded simulated bench with this configuration (seed, truth, …: usually
    /// [`crate::simulate::sim_config`]); the recording keeps its truth in `bench.gyro_model`
    /// (role `simulation`). Bench time zero: [`SIM_EPOCH_NS`].
    Simulated(SimConfig),
    /// A recording replayed: its devices answer as recorded; the scenario's commands are
    /// checked against the recorded ones ([`RunReport::replay`]). In virtual time the log
    /// times are the recording's, in real time the wall clock's.
    Replay(Arc<ReplayData>),
    /// Devices already connected on `clock` (real drivers, or simulators behind virtual ports),
    /// recorded with `info`: always real time at the clock's scale.
    Connected {
        /// The devices.
        devices: Devices,
        /// Their clock.
        clock: SystemClock,
        /// The recording's `bench.*` metadata (see [`run_info`]).
        info: Box<RunInfo>,
    },
}

/// Options of a run, whatever its bench.
#[derive(Default)]
pub struct RunOptions {
    /// Virtual or real time (ignored by [`Bench::Connected`], which is real time).
    pub pace: Pace,
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
    /// Kill-safety: what a kill (SIGKILL) mid-run may lose at most — of bench time in a paced
    /// run (real or scaled time), of wall-clock work in a virtual-time run (a deterministic
    /// function of scenario and seed: run it again); `None`: [`DEFAULT_FLUSH_INTERVAL`]. See
    /// [`recorder_options`].
    pub flush_interval: Option<Duration>,
    /// Print a time mark on stderr every this much bench time (`bench run --time-marks-s`).
    pub time_marks: Option<Duration>,
}

/// Default of [`RunOptions::flush_interval`]: 1 s.
pub const DEFAULT_FLUSH_INTERVAL: Duration = Duration::from_secs(1);

/// A kill-safety bound for runs recorded into memory (the studies): long, so the recorder
/// never flushes early (a kill loses such a run whole anyway).
pub const IN_MEMORY_FLUSH_INTERVAL: Duration = Duration::from_secs(3600);

/// The recorder's options for a kill-safety bound `loss`.
///
/// - Paced (real or scaled time): the recorder flushes every ¾ of `loss` of bench time and at
///   every step end, and events reach it one by one. Each flush closes a chunk; the file is
///   compacted into full chunks when the run ends (`bench run` does it).
/// - Virtual time: chunks close only when full (1 MiB), which takes milliseconds; the recorder
///   also flushes every ¾ of `loss` of wall-clock time, and the run hands events over at
///   least every ⅛ of it ([`ThreadedSink::hold_limit`]), two batches of 4096 at most waiting
///   for the writer. The run never waits for the writer beyond that.
///
/// Returns the options and the hold limit for the hand-over (virtual time only).
pub fn recorder_options(loss: Duration, paced: bool) -> (RecorderOptions, Option<Duration>) {
    let flush = loss * 3 / 4;
    if paced {
        (RecorderOptions { flush_interval: Some(flush), ..RecorderOptions::default() }, None)
    } else {
        let options = RecorderOptions {
            flush_interval: None,
            flush_wall: Some(flush),
            flush_on_step_end: false,
            ..RecorderOptions::default()
        };
        (options, Some(loss / 8))
    }
}

/// The recording side of a run: started before the devices move, finished after.
struct Session<W: Write + Seek + Send + 'static> {
    sink: LiveTee<ThreadedSink<Recorder<W>>>,
    live: Arc<Live>,
    progress: Option<crate::progress::Progress>,
    wall: Instant,
}

/// Start the recording of `plan` into `writer` with `info`. `batch`: events per hand-over to
/// the recorder thread (large in virtual time, where it amortises, bounded by the hold limit;
/// 1 in real time, so a crash loses no more than the recorder's unflushed tail).
fn start<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    info: RunInfo,
    writer: W,
    opts: &RunOptions,
    batch: usize,
) -> anyhow::Result<Session<W>> {
    let epoch_ns = info.epoch_ns;
    let loss = opts.flush_interval.unwrap_or(DEFAULT_FLUSH_INTERVAL);
    let (options, hold) = recorder_options(loss, batch == 1);
    let recorder =
        Recorder::with_options(writer, info, options).context("cannot start the recording")?;
    // Serialising and compressing run on the second core.
    let mut sink =
        ThreadedSink::new(recorder, batch).context("cannot start the recorder thread")?;
    if let Some(hold) = hold {
        sink = sink.hold_limit(hold);
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
        replay: None,
        table_link: result.table_link,
    };
    Ok((report, writer))
}

/// Run `plan` on `bench` at `opts.pace`, recording into `writer`; returns the report and the
/// finished writer. Blocks: a real-time run goes on the current tokio runtime (enter the one
/// the devices were connected on, and call it from outside async code, e.g. in
/// `spawn_blocking`), or on a runtime of its own when there is none.
pub fn run<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    bench: Bench,
    writer: W,
    opts: RunOptions,
) -> anyhow::Result<(RunReport, W)> {
    match (bench, opts.pace) {
        (Bench::Connected { devices, clock, info }, _) => {
            on_tokio(run_realtime(plan, devices, clock, *info, writer, opts))
        }
        (Bench::Simulated(config), Pace::Virtual) => {
            let clock = VirtualClock::new();
            let (devices, info) = simulated(plan, config, Arc::new(clock.clone()))?;
            run_virtual(plan, devices, &clock, info, writer, opts)
        }
        (Bench::Simulated(config), Pace::RealTime(scale)) => {
            let clock = SystemClock::new(scale);
            let (devices, info) = simulated(plan, config, Arc::new(clock.clone()))?;
            on_tokio(run_realtime(plan, devices, clock, info, writer, opts))
        }
        (Bench::Replay(data), pace) => {
            let mut plan = plan.clone();
            let (report, writer, checks) = match pace {
                Pace::Virtual => {
                    let info = crate::replay::prepare(&mut plan, &data, data.epoch_ns);
                    let clock = VirtualClock::new();
                    let (devices, checks) =
                        data.devices(Arc::new(clock.clone()), Default::default()).into_devices();
                    let (report, writer) = run_virtual(&plan, devices, &clock, info, writer, opts)?;
                    (report, writer, checks)
                }
                Pace::RealTime(speed) => {
                    let info = crate::replay::prepare(&mut plan, &data, wall_epoch_ns());
                    let clock = SystemClock::new(speed);
                    let (devices, checks) =
                        data.devices(Arc::new(clock.clone()), Default::default()).into_devices();
                    let (report, writer) =
                        on_tokio(run_realtime(&plan, devices, clock, info, writer, opts))?;
                    (report, writer, checks)
                }
            };
            let (table_commands, table_mismatches, chamber_targets, chamber_mismatches) =
                checks.counts();
            let replay = Some(ReplayCounts {
                table_commands,
                table_mismatches,
                chamber_targets,
                chamber_mismatches,
            });
            Ok((RunReport { replay, ..report }, writer))
        }
    }
}

/// The simulated bench in virtual time into memory, as the studies and tests run it: seed
/// `seed`, the plan's simulator configuration ([`crate::simulate::sim_config`]), a long flush
/// interval. Returns the report and the recording's bytes.
pub fn simulate_in_memory(plan: &RunPlan, seed: u64) -> anyhow::Result<(RunReport, Vec<u8>)> {
    let opts =
        RunOptions { flush_interval: Some(IN_MEMORY_FLUSH_INTERVAL), ..RunOptions::default() };
    let bench = Bench::Simulated(sim_config(plan, seed));
    let (report, cursor) = run(plan, bench, std::io::Cursor::new(Vec::new()), opts)?;
    Ok((report, cursor.into_inner()))
}

/// The simulated bench's devices for `plan` with `config` on `clock`, and the run info of a
/// simulated run: the truth model recorded, role `simulation`, bench time zero
/// [`SIM_EPOCH_NS`].
fn simulated(
    plan: &RunPlan,
    config: SimConfig,
    clock: Arc<dyn Clock>,
) -> anyhow::Result<(Devices, RunInfo)> {
    let recorded = recorded_effects(plan, &config);
    let sim = SimBench::new(config, clock)
        .context("the scenario asks for a simulator configuration it cannot run")?;
    let (table, chamber, gyro) = sim.into_parts();
    let devices =
        Devices { table: Box::new(table), chamber: Box::new(chamber), gyro: Box::new(gyro) };
    let mut info = run_info(plan, SIM_EPOCH_NS);
    info.gyro_model = gyro_model_metadata(&plan.sim.truth, &recorded);
    info.gyro_model_role = bench_recording::ModelRole::Simulation;
    Ok((devices, info))
}

/// `fut` run to its end on the current tokio runtime, or on a two-worker runtime of its own
/// when there is none.
fn on_tokio<T>(fut: impl std::future::Future<Output = anyhow::Result<T>>) -> anyhow::Result<T> {
    match tokio::runtime::Handle::try_current() {
        Ok(handle) => handle.block_on(fut),
        Err(_) => tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .context("cannot start the tokio runtime")?
            .block_on(fut),
    }
}

/// Run `plan` on `devices` whose clock is `clock`, in virtual time (the simulated bench and
/// replays), recording into `writer` with `info`.
fn run_virtual<W: Write + Seek + Send + 'static>(
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
async fn run_realtime<W: Write + Seek + Send + 'static>(
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
