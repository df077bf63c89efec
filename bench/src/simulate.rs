//! The embedded default bench: run a plan against the in-process simulators in virtual time
//! and record it to MCAP.

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;
use std::sync::Arc;

use anyhow::Context as _;
use bench_drivers::clock::VirtualClock;
use bench_drivers::Clock;
use bench_physics::effects::{Effects, RateRipple};
use bench_recording::RunInfo;
use bench_sim::{SimBench, SimConfig};

use crate::plan::RunPlan;
use crate::run::{ConsoleLayer, Devices};
use crate::runner::{gyro_model_metadata, run_info, run_virtual, RunOptions, RunReport};
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
    /// Kill-safety bound of the recording, bench time (default `None`:
    /// [`crate::runner::DEFAULT_FLUSH_INTERVAL`]); [`SimOptions::IN_MEMORY`] for runs into
    /// memory, which a kill loses whole anyway.
    pub flush_interval: Option<std::time::Duration>,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self { seed: 1, epoch_ns: SIM_EPOCH_NS, progress: false, live: None, flush_interval: None }
    }
}

impl SimOptions {
    /// A flush interval for runs recorded into memory (the studies): long, so chunks fill
    /// and the run is not held to the recorder thread.
    pub const IN_MEMORY: Option<std::time::Duration> = Some(std::time::Duration::from_secs(3600));

    /// The runner's options for these, with a terminal log layer.
    pub fn run_options(&self, console: Option<ConsoleLayer>) -> RunOptions {
        RunOptions {
            progress: self.progress,
            live: self.live.clone(),
            console,
            flush_interval: self.flush_interval,
            ..Default::default()
        }
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
        axis_up: plan.site.axis_up(),
        initial_temp_c: plan.sim.initial_temp_c,
        ..SimConfig::default()
    }
}

/// The effects a simulated run records in `bench.gyro_model` (the contract's "model the
/// simulator used"): the nominal effects (what the lab believes, `[gyro.model.effects]`) and,
/// when the simulated table ripples and the nominal effects say nothing of it, the table's own
/// ripple as `rate_ripple` — physics the simulator simulates, so a diagnosis takes it as
/// nominal. The truth's own effects (`[simulation.truth.effects]`, a concealed `rate_ripple`
/// included) stay concealed.
pub fn recorded_effects(plan: &RunPlan, config: &SimConfig) -> Effects {
    let mut effects = plan.gyro.effects;
    let table = &config.table;
    if effects.rate_ripple.is_none() && table.ripple_rel > 0.0 && table.ripple_cycles_per_rev > 0 {
        effects.rate_ripple = Some(RateRipple {
            relative_amplitude: table.ripple_rel,
            cycles_per_rev: f64::from(table.ripple_cycles_per_rev),
            phase_rad: table.ripple_phase_rad,
        });
    }
    effects
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
    let recorded = recorded_effects(plan, &config);
    let sim = SimBench::new(config, shared.clone())
        .context("the scenario asks for a simulator configuration it cannot run")?;
    let (table, chamber, gyro) = sim.into_parts();
    let devices =
        Devices { table: Box::new(table), chamber: Box::new(chamber), gyro: Box::new(gyro) };
    let mut info = run_info(plan, opts.epoch_ns);
    info.gyro_model = gyro_model_metadata(&plan.sim.truth, &recorded);
    info.gyro_model_role = bench_recording::ModelRole::Simulation;
    run_virtual(plan, devices, &clock, info, writer, opts.run_options(console))
}

/// The simulated bench's devices for `plan` on `clock`, and the run info of a simulated run
/// (the truth model recorded, role `simulation`).
fn sim_devices(
    plan: &RunPlan,
    config: SimConfig,
    clock: Arc<dyn Clock>,
    epoch_ns: u64,
) -> anyhow::Result<(Devices, RunInfo)> {
    let recorded = recorded_effects(plan, &config);
    let sim = SimBench::new(config, clock)
        .context("the scenario asks for a simulator configuration it cannot run")?;
    let (table, chamber, gyro) = sim.into_parts();
    let devices =
        Devices { table: Box::new(table), chamber: Box::new(chamber), gyro: Box::new(gyro) };
    let mut info = run_info(plan, epoch_ns);
    info.gyro_model = gyro_model_metadata(&plan.sim.truth, &recorded);
    info.gyro_model_role = bench_recording::ModelRole::Simulation;
    Ok((devices, info))
}

/// [`run_plan`] with the runner's options given whole (flush interval, time marks, policy).
pub fn run_plan_opts<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    writer: W,
    seed: u64,
    epoch_ns: u64,
    opts: RunOptions,
) -> anyhow::Result<(RunReport, W)> {
    let clock = VirtualClock::new();
    let (devices, info) =
        sim_devices(plan, sim_config(plan, seed), Arc::new(clock.clone()), epoch_ns)?;
    run_virtual(plan, devices, &clock, info, writer, opts)
}

/// The simulated bench in real time × `time_scale` on the current tokio runtime, as a bench
/// with real devices runs (bench time zero at [`SIM_EPOCH_NS`]).
pub async fn run_plan_realtime<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    writer: W,
    seed: u64,
    time_scale: f64,
    opts: RunOptions,
) -> anyhow::Result<(RunReport, W)> {
    let clock = bench_drivers::SystemClock::new(time_scale);
    let (devices, info) =
        sim_devices(plan, sim_config(plan, seed), Arc::new(clock.clone()), SIM_EPOCH_NS)?;
    crate::runner::run_realtime(plan, devices, clock, info, writer, opts).await
}
