//! Running a scenario against a recording: in virtual time (as fast as the CPU allows) or in
//! real time at a chosen speed.

use std::io::{Seek, Write};
use std::sync::Arc;

use bench_drivers::clock::VirtualClock;
use bench_drivers::{Clock, SystemClock};
use bench_recording::RunInfo;

use super::{ReplayChecks, ReplayData, ReplayOptions};
use crate::plan::RunPlan;
use crate::runner::{run_info, wall_epoch_ns, RunOptions, RunReport};

/// Adjust `plan` to the recording: the site is where the data was taken (`bench.site`; a
/// different scenario latitude is logged). Returns the run info: the recording's start epoch
/// (virtual time) or `epoch_ns`, and its `bench.gyro_model` when it has one.
pub fn prepare(plan: &mut RunPlan, data: &ReplayData, epoch_ns: u64) -> RunInfo {
    if let Some(site) = data.site {
        if site.latitude_deg != plan.site.latitude_deg {
            tracing::warn!(
                "replay: the recording's latitude {}° overrides the scenario's {}°",
                site.latitude_deg,
                plan.site.latitude_deg
            );
        }
        plan.site = site;
    }
    let mut info = run_info(plan, epoch_ns);
    if let Some(model) = &data.gyro_model {
        info.gyro_model = model.clone();
    }
    info.gyro_model_role = data.gyro_model_role;
    info
}

/// What a replayed run did, with the command checks.
pub struct ReplayReport {
    /// The run's report.
    pub run: RunReport,
    /// How the commands compared with the recording.
    pub checks: Arc<ReplayChecks>,
}

/// Run `plan` (already validated against [`ReplayData::capabilities`]) on the replay of `data`
/// in virtual time, recording into `writer` with the recording's start epoch, so that the
/// re-recorded device streams carry the original's log times.
pub fn run_virtual<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    data: &Arc<ReplayData>,
    writer: W,
    opts: RunOptions,
) -> anyhow::Result<(ReplayReport, W)> {
    let mut plan = plan.clone();
    let info = prepare(&mut plan, data, data.epoch_ns);
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let (devices, checks) = data.devices(shared, ReplayOptions::default()).into_devices();
    let (run, writer) = crate::runner::run_virtual(&plan, devices, &clock, info, writer, opts)?;
    Ok((ReplayReport { run, checks }, writer))
}

/// Run `plan` on the replay of `data` in real time × `speed` on the current tokio runtime; log
/// times start at the wall clock's now.
pub async fn run_realtime<W: Write + Seek + Send + 'static>(
    plan: &RunPlan,
    data: &Arc<ReplayData>,
    speed: f64,
    writer: W,
    opts: RunOptions,
) -> anyhow::Result<(ReplayReport, W)> {
    let mut plan = plan.clone();
    let info = prepare(&mut plan, data, wall_epoch_ns());
    let clock = SystemClock::new(speed);
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let (devices, checks) = data.devices(shared, ReplayOptions::default()).into_devices();
    let (run, writer) =
        crate::runner::run_realtime(&plan, devices, clock, info, writer, opts).await?;
    Ok((ReplayReport { run, checks }, writer))
}
