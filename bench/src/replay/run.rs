//! A scenario against a recording: the plan adjusted to the recording and the run's info. The
//! run itself is [`crate::runner::run`] with [`crate::runner::Bench::Replay`], in virtual time
//! (as fast as the CPU allows) or in real time at a chosen speed.

use bench_recording::RunInfo;

use super::ReplayData;
use crate::plan::RunPlan;
use crate::runner::run_info;

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
