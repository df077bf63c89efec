//! The step sequencer: runs the plan's steps in order, brackets each with step events, and
//! puts the bench into its safe state at the end.

use std::time::Duration;

use bench_drivers::TableMode;
use futures::channel::mpsc;
use futures::StreamExt;

use super::{Ctx, Event, Fault, FaultCause, StepEvent};
use crate::plan::{Action, PlannedStep, RunPlan, TempSource};

/// Measured table rate counts as settled within this fraction of the command…
const SETTLE_REL: f64 = 1e-3;
/// …or this absolute rate, rad/s (≈ 0.2 °/h), whichever is larger.
const SETTLE_ABS_RAD_S: f64 = 1e-6;
/// Margin on temperature-band edges for binary rounding of decimal readings, °C.
const BAND_EDGE_C: f64 = 1e-9;
/// The chamber's working set point has reached its target within this, °C.
const RAMP_END_TOL_C: f64 = 0.05;

fn step_event(ctx: &Ctx, step: &PlannedStep, event: StepEvent) {
    ctx.send(Event::Step {
        t: ctx.clock.now(),
        index: step.index,
        name: step.name.clone(),
        event,
        label: step.label.clone(),
    });
}

/// Run every step; the first failure (or a fault from a device task, the stop signal or the
/// recorder) aborts, and is returned.
pub(super) async fn run_steps(
    plan: &RunPlan,
    ctx: &Ctx,
    mut fault_rx: mpsc::UnboundedReceiver<()>,
) -> Option<Fault> {
    let poll = Duration::from_secs_f64(1.0 / plan.chamber_poll_hz.max(plan.table_poll_hz));
    for step in &plan.steps {
        ctx.live.set_step(step.index);
        step_event(ctx, step, StepEvent::Start);
        tracing::info!(
            "step {} {}{}",
            step.index,
            step.name,
            if step.label.is_empty() { String::new() } else { format!(" [{}]", step.label) }
        );
        let action = run_action(&step.action, ctx, poll);
        futures::pin_mut!(action);
        let result = match futures::future::select(action, fault_rx.next()).await {
            futures::future::Either::Left((r, _)) => r,
            futures::future::Either::Right(_) => Err(ctx.fault().unwrap_or_else(|| {
                Fault::new(FaultCause::Start, "fault signalled without a cause")
            })),
        };
        match result {
            Ok(()) => step_event(ctx, step, StepEvent::End),
            Err(fault) => {
                step_event(ctx, step, StepEvent::Abort);
                return Some(fault.context(format!(
                    "step {} ({}) at {}",
                    step.index,
                    step_title(&step.name, &step.label),
                    step.origin
                )));
            }
        }
    }
    None
}

/// A step as the abort names it: its label when that starts with the action's name ("record cw
/// ramp", not "record record cw ramp"), else the action's name and the label.
fn step_title(name: &str, label: &str) -> String {
    if label.is_empty() {
        name.to_owned()
    } else if label.split_whitespace().next() == Some(name) {
        label.to_owned()
    } else {
        format!("{name} {label}")
    }
}

/// A device's refusal of a command as a fault.
fn refused(device: &'static str, what: String) -> impl FnOnce(bench_drivers::DeviceError) -> Fault {
    move |e| Fault::new(FaultCause::Device { device, kind: e.kind() }, format!("{what}: {e}"))
}

async fn run_action(action: &Action, ctx: &Ctx, poll: Duration) -> Result<(), Fault> {
    let clock = &ctx.clock;
    match *action {
        Action::Chamber { target_c, ramp_c_s } => {
            ctx.chamber
                .lock()
                .await
                .set_target(target_c, ramp_c_s)
                .await
                .map_err(refused("chamber", format!("chamber refused set point {target_c} °C")))?;
            ctx.live.set_commanded_target(target_c);
        }
        Action::Table { rate_rad_s, accel_rad_s2, settle } => {
            {
                let mut table = ctx.table.lock().await;
                table
                    .set_rate(rate_rad_s, accel_rad_s2)
                    .await
                    .map_err(refused("table", format!("table refused rate {rate_rad_s} rad/s")))?;
                ctx.table_commanded(TableMode::Rate);
            }
            if settle {
                wait_table_rate(ctx, rate_rad_s, accel_rad_s2, poll).await?;
            }
        }
        Action::TableStop { decel_rad_s2 } => {
            {
                let mut table = ctx.table.lock().await;
                table
                    .stop(decel_rad_s2)
                    .await
                    .map_err(refused("table", "table refused stop".to_string()))?;
                ctx.table_commanded(TableMode::Stopped);
            }
            wait_table_rate(ctx, 0.0, decel_rad_s2, poll).await?;
        }
        Action::Wait { duration } => clock.sleep(duration).await,
        Action::WaitTemperature { source, target_c, band_c, hold, timeout } => {
            let start = clock.now();
            let mut in_band_since: Option<Duration> = None;
            loop {
                let snap = ctx.live.snapshot();
                let temp = match source {
                    TempSource::Air => snap.air_temp_c,
                    TempSource::Gyro if snap.gyro_temp_c.is_finite() => snap.gyro_temp_c,
                    TempSource::Gyro => snap.air_temp_c,
                };
                let now = clock.now();
                // Readings are decimal (0.1 °C): 39.8 is "within 0.2 of 40" however the wire's
                // decoding rounded it in binary, so the edge gets a margin far below any
                // resolution.
                if (temp - target_c).abs() <= band_c + BAND_EDGE_C {
                    let since = *in_band_since.get_or_insert(now);
                    if now - since >= hold {
                        return Ok(());
                    }
                } else {
                    in_band_since = None;
                }
                if now - start >= timeout {
                    return Err(Fault::new(
                        FaultCause::StepTimeout,
                        format!(
                            "temperature {temp:.2} °C not within {target_c} ± {band_c} °C for {} \
                             s after {} s",
                            hold.as_secs_f64(),
                            timeout.as_secs_f64()
                        ),
                    ));
                }
                clock.sleep(poll).await;
            }
        }
        Action::WaitRampEnd { timeout } => wait_ramp_end(ctx, timeout, poll).await?,
        Action::Record { duration, until_ramp_end } => {
            if until_ramp_end {
                wait_ramp_end(ctx, duration, poll).await?;
            } else {
                clock.sleep(duration).await;
            }
        }
    }
    Ok(())
}

async fn wait_ramp_end(ctx: &Ctx, timeout: Duration, poll: Duration) -> Result<(), Fault> {
    let start = ctx.clock.now();
    loop {
        let s = ctx.live.snapshot();
        // Judged against the target bench commanded (the readings may predate the command);
        // without a command, against the controller's own target.
        let target =
            if s.commanded_target_c.is_finite() { s.commanded_target_c } else { s.target_c };
        if (s.setpoint_c - target).abs() <= RAMP_END_TOL_C {
            return Ok(());
        }
        if ctx.clock.now() - start >= timeout {
            return Err(Fault::new(
                FaultCause::StepTimeout,
                format!(
                    "chamber ramp not finished after {} s (working set point {:.2} °C, target \
                     {:.2} °C)",
                    timeout.as_secs_f64(),
                    s.setpoint_c,
                    target
                ),
            ));
        }
        ctx.clock.sleep(poll).await;
    }
}

async fn wait_table_rate(
    ctx: &Ctx,
    rate_rad_s: f64,
    accel_rad_s2: f64,
    poll: Duration,
) -> Result<(), Fault> {
    let start = ctx.clock.now();
    let tol = (rate_rad_s.abs() * SETTLE_REL).max(SETTLE_ABS_RAD_S);
    let span = (rate_rad_s - ctx.live.snapshot().table_rate_rad_s).abs();
    let slew_s = if accel_rad_s2 > 0.0 && span.is_finite() { span / accel_rad_s2 } else { 0.0 };
    let timeout = Duration::from_secs_f64(2.0 * slew_s + 10.0);
    // Only readings taken after the command count.
    ctx.clock.sleep(poll).await;
    loop {
        let s = ctx.live.snapshot();
        if (s.table_rate_rad_s - rate_rad_s).abs() <= tol {
            return Ok(());
        }
        if ctx.clock.now() - start >= timeout {
            let name = super::interlocks::TABLE_STALL;
            return Err(Fault::new(
                FaultCause::Interlock { name },
                format!(
                    "{name}: table rate {:.6e} rad/s did not settle on {rate_rad_s:.6e} rad/s within {:.1} s",
                    s.table_rate_rad_s,
                    timeout.as_secs_f64()
                ),
            ));
        }
        ctx.clock.sleep(poll).await;
    }
}

/// How often a pending safe-state command (or the tail) looks for a second stop request, bench
/// time.
const HURRY_POLL: Duration = Duration::from_millis(50);

/// Sleep `d` of bench time, or less if a second stop request comes.
pub(super) async fn sleep_unless_hurried(ctx: &Ctx, d: Duration) {
    let end = ctx.clock.now() + d;
    while !ctx.hurried() {
        let now = ctx.clock.now();
        if now >= end {
            return;
        }
        ctx.clock.sleep(HURRY_POLL.min(end - now)).await;
    }
}

/// Wait for a safe-state command at most the policy's timeout, or
/// [`super::HURRIED_SAFE_STATE_TIMEOUT`] once a second stop request has come. `None`: timed
/// out.
async fn bounded<T>(ctx: &Ctx, fut: impl std::future::Future<Output = T>) -> Option<T> {
    let clock = ctx.clock.as_ref();
    let deadline = clock.now() + ctx.policy.safe_state_timeout;
    let mut hurried_deadline = None;
    futures::pin_mut!(fut);
    loop {
        let tick = clock.sleep(HURRY_POLL);
        futures::pin_mut!(tick);
        match futures::future::select(fut.as_mut(), tick).await {
            futures::future::Either::Left((r, _)) => return Some(r),
            futures::future::Either::Right(_) => {
                let now = clock.now();
                if ctx.hurried() {
                    let d =
                        *hurried_deadline.get_or_insert(now + super::HURRIED_SAFE_STATE_TIMEOUT);
                    if now >= d {
                        return None;
                    }
                }
                if now >= deadline {
                    return None;
                }
            }
        }
    }
}

/// Table to rest and chamber to the safe set point, both at once, each bounded by the policy's
/// timeout (cut short by a second stop request). Errors are logged: the run is ending either
/// way. A device that never answers cannot hang the teardown.
pub(super) async fn safe_state(plan: &RunPlan, ctx: &Ctx) {
    let limit = ctx.policy.safe_state_timeout;
    let table = bounded(ctx, async {
        let mut t = ctx.table.lock().await;
        let stopped = t.stop(plan.safe_decel_rad_s2).await;
        if stopped.is_ok() {
            ctx.table_commanded(TableMode::Stopped);
        }
        stopped
    });
    let chamber = bounded(ctx, async {
        if plan.safe_chamber_hold {
            return Ok(());
        }
        let mut c = ctx.chamber.lock().await;
        c.set_target(plan.safe_temp_c, None).await
    });
    let (table, chamber) = futures::join!(table, chamber);
    match table {
        Some(Ok(())) => tracing::info!("safe state: table decelerating to rest"),
        Some(Err(e)) => tracing::error!("safe state: table stop failed: {e}"),
        None => tracing::error!("safe state: table stop not answered {}", late(ctx, limit)),
    }
    match chamber {
        Some(Ok(())) if plan.safe_chamber_hold => {
            tracing::info!("safe state: chamber holds its set point ([safe] chamber_hold)")
        }
        Some(Ok(())) => tracing::info!("safe state: chamber set point {} °C", plan.safe_temp_c),
        Some(Err(e)) => tracing::error!("safe state: chamber set point failed: {e}"),
        None => {
            tracing::error!("safe state: chamber set point not answered {}", late(ctx, limit))
        }
    }
}

fn late(ctx: &Ctx, limit: Duration) -> String {
    if ctx.hurried() {
        "before the second interrupt's deadline; given up".to_string()
    } else {
        format!("within {} s; given up", limit.as_secs_f64())
    }
}
