//! Runs in real (or scaled) time on tokio: real devices behind drivers, or simulators behind
//! virtual ports. The orchestrator is the same as for the simulated bench; only the clock and
//! the executor differ.

use std::io::{Seek, Write};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use bench_drivers::clock::TokioSpawner;
use bench_drivers::{Clock, SystemClock};

use crate::plan::RunPlan;
use crate::record::{Recorder, RunInfo};
use crate::run::threaded::ThreadedSink;
use crate::run::{
    execute, ConsoleLayer, Devices, ExecOptions, FaultPolicy, Live, Outcome, StopSignal,
};
use crate::simulate::RunReport;

/// Options of a real-time run.
#[derive(Default)]
pub struct RealtimeOptions {
    /// Show a progress bar on a terminal.
    pub progress: bool,
    /// Abort request (Ctrl-C).
    pub stop: Option<StopSignal>,
    /// Terminal log layer.
    pub console: Option<ConsoleLayer>,
    /// Limits of the fault handling.
    pub policy: FaultPolicy,
    /// Also show the streams in a Foxglove live view.
    pub live: Option<Arc<crate::live_view::LiveView>>,
}

/// Run `plan` on `devices` with `clock` on the current tokio runtime, recording into `writer`
/// with `info`. Events reach the file through the recorder thread one by one, so a crash loses
/// at most the current chunk's unflushed tail (the recorder flushes every few seconds and at
/// every step end).
pub async fn run_plan_realtime<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    devices: Devices,
    clock: SystemClock,
    writer: W,
    info: RunInfo,
    opts: RealtimeOptions,
) -> anyhow::Result<(RunReport, W)> {
    let epoch_ns = info.epoch_ns;
    let recorder = Recorder::new(writer, info).context("cannot start the recording")?;
    let sink = ThreadedSink::new(recorder, 1).context("cannot start the recorder thread")?;
    let sink = crate::live_view::LiveTee::new(sink, opts.live.clone(), epoch_ns);
    let live = Arc::new(Live::default());
    let progress = opts.progress.then(|| {
        crate::progress::Progress::start(live.clone(), plan.estimated_duration(), plan.steps.len())
    });
    let shared: Arc<dyn Clock> = Arc::new(clock);
    let wall = Instant::now();
    let result = execute(
        plan,
        devices,
        shared,
        sink,
        TokioSpawner,
        live.clone(),
        ExecOptions { console: opts.console, stop: opts.stop, policy: opts.policy },
    )
    .await;
    let wall_time = wall.elapsed();
    drop(progress);
    let (recorder, thread_error) = result.sink.into_inner().finish()?;
    let outcome = match result.record_error.or(thread_error) {
        Some(e) => Outcome::Aborted(format!("recording failed: {e}")),
        None => result.outcome,
    };
    let writer = recorder.finish(&outcome).context("cannot finish the recording")?;
    Ok((
        RunReport {
            outcome: outcome.to_string(),
            bench_time: result.duration,
            wall_time,
            gyro_samples: live.snapshot().gyro_samples,
        },
        writer,
    ))
}
