//! The embedded default bench: run a plan against the in-process simulators in virtual time
//! and record it to MCAP.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use bench_drivers::clock::{run_virtual, VirtualClock};
use bench_drivers::Clock;
use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use bench_sim::{SimBench, SimConfig};

use crate::live_view::LiveTee;
use crate::plan::RunPlan;
use crate::record::{Axis, Recorder, RunInfo, Site};
use crate::run::threaded::ThreadedSink;
use crate::run::{execute, ConsoleLayer, Devices, ExecOptions, Live, Outcome};
use crate::scenario::Capabilities;

/// Bench time zero of simulated runs: 2026-01-01T00:00:00Z, fixed so that a run is a pure
/// function of scenario and seed.
pub const SIM_EPOCH_NS: u64 = 1_767_225_600_000_000_000;

/// Options of a simulated run.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// Seed of every random stream of the simulator (default 1).
    pub seed: u64,
    /// Unix time of bench time zero, ns (default [`SIM_EPOCH_NS`]).
    pub epoch_ns: u64,
    /// Show a progress bar on a terminal (default false).
    pub progress: bool,
    /// Also show the streams in a Foxglove live view (default none).
    pub live: Option<Arc<crate::live_view::LiveView>>,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self { seed: 1, epoch_ns: SIM_EPOCH_NS, progress: false, live: None }
    }
}

/// What a simulated run did.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReport {
    /// `completed` or `aborted: <reason>`.
    pub outcome: String,
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
}

/// The simulated bench's capabilities, for validating scenarios.
pub fn capabilities() -> Capabilities {
    let i = bench_sim::default_infos();
    Capabilities { table: i.table, chamber: i.chamber, gyro: i.gyro }
}

/// The simulator configuration a plan asks for.
pub fn sim_config(plan: &RunPlan, seed: u64) -> SimConfig {
    SimConfig {
        seed,
        gyro_model: plan.sim.truth.clone(),
        gyro_effects: plan.sim.truth_effects,
        gyro_sample_rate_hz: plan.gyro.sample_rate_hz,
        latitude_deg: plan.site.latitude_deg,
        axis_up: plan.site.axis_up,
        initial_temp_c: plan.sim.initial_temp_c,
        ..SimConfig::default()
    }
}

/// `bench.*` metadata of a run of `plan`.
pub fn run_info(plan: &RunPlan, epoch_ns: u64) -> RunInfo {
    let site = Site {
        latitude_deg: plan.site.latitude_deg,
        longitude_deg: plan.site.longitude_deg,
        height_m: plan.site.height_m,
        axis: Some(if plan.site.axis_up { Axis::Up } else { Axis::Down }),
    };
    let mut info = RunInfo::new(
        epoch_ns,
        &plan.name,
        &plan.text,
        site,
        gyro_model_metadata(&plan.gyro.model, &plan.gyro.effects),
    );
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

/// Load the scenario at `scenario`, validate it against the simulated bench, run it and write
/// the recording to `out`.
pub fn run_scenario_file(
    scenario: &Path,
    out: &Path,
    opts: &SimOptions,
) -> anyhow::Result<RunReport> {
    let plan = crate::scenario::load(scenario, &capabilities())?;
    let file =
        File::create(out).with_context(|| format!("cannot create recording {}", out.display()))?;
    let (report, writer) = run_plan(&plan, BufWriter::new(file), opts, None)?;
    writer
        .into_inner()
        .map_err(|e| e.into_error())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("cannot write recording {}", out.display()))?;
    Ok(report)
}

/// Run `plan` on the simulated bench in virtual time, recording into `writer`; returns the
/// report and the finished writer. `console` is an optional terminal log layer.
pub fn run_plan<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    writer: W,
    opts: &SimOptions,
    console: Option<ConsoleLayer>,
) -> anyhow::Result<(RunReport, W)> {
    run_plan_with(plan, sim_config(plan, opts.seed), writer, opts, console)
}

/// [`run_plan`] with a simulator configuration of the caller's (e.g. with sensor noise off).
pub fn run_plan_with<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    config: SimConfig,
    writer: W,
    opts: &SimOptions,
    console: Option<ConsoleLayer>,
) -> anyhow::Result<(RunReport, W)> {
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let sim = SimBench::new(config, shared.clone())
        .context("the scenario asks for a simulator configuration it cannot run")?;
    let (table, chamber, gyro) = sim.into_parts();
    let devices =
        Devices { table: Box::new(table), chamber: Box::new(chamber), gyro: Box::new(gyro) };
    // The contract's `bench.gyro_model` is "the model the simulator used": the truth's base
    // keys, plus the nominal effects (what the lab believes). The truth's own effects stay
    // concealed.
    let mut info = run_info(plan, opts.epoch_ns);
    info.gyro_model = gyro_model_metadata(&plan.sim.truth, &plan.gyro.effects);
    run_devices_virtual(plan, devices, &clock, info, writer, opts, console)
}

/// Run `plan` on `devices` whose clock is `clock`, in virtual time, recording into `writer`
/// with `info` (the simulated bench and replays in virtual time). `opts.seed` is not used.
pub fn run_devices_virtual<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    devices: Devices,
    clock: &VirtualClock,
    info: RunInfo,
    writer: W,
    opts: &SimOptions,
    console: Option<ConsoleLayer>,
) -> anyhow::Result<(RunReport, W)> {
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let epoch_ns = info.epoch_ns;
    let recorder = Recorder::new(writer, info).context("cannot start the recording")?;
    // Serialising and compressing run on the second core; batches amortise the hand-over.
    let recorder = ThreadedSink::new(recorder, 4096).context("cannot start the recorder thread")?;
    let recorder = LiveTee::new(recorder, opts.live.clone(), epoch_ns);
    let live = Arc::new(Live::default());
    let progress = opts.progress.then(|| {
        crate::progress::Progress::start(live.clone(), plan.estimated_duration(), plan.steps.len())
    });
    let wall = Instant::now();
    let result = run_virtual(clock, |spawner| {
        execute(
            plan,
            devices,
            shared.clone(),
            recorder,
            spawner,
            live.clone(),
            ExecOptions { console, ..Default::default() },
        )
    })
    .context("simulated run stalled")?;
    let wall_time = wall.elapsed();
    drop(progress);
    let (recorder, thread_error) = result.sink.into_inner().finish()?;
    let outcome = match result.record_error.or(thread_error) {
        Some(e) => Outcome::Aborted(format!("recording failed: {e}")),
        None => result.outcome,
    };
    let writer = recorder.finish(&outcome).context("cannot finish the recording")?;
    let report = RunReport {
        outcome: outcome.to_string(),
        bench_time: result.duration,
        wall_time,
        gyro_samples: live.snapshot().gyro_samples,
    };
    Ok((report, writer))
}
