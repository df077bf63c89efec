//! A validated run: what the scenario parser produces and the orchestrator executes.
//!
//! Everything here is SI (s, rad, rad/s, rad/s²) except temperatures (°C). Loops of the
//! scenario are already expanded; every value has been checked against the devices'
//! capabilities.

use std::time::Duration;

use bench_physics::chamber::{ChamberModel, ChamberParams};
use bench_physics::effects::Effects;
use bench_physics::gyro::GyroSampler;
use bench_physics::table::{RateTableModel, TableParams};
use bench_physics::units::quantise;
use bench_physics::GyroModel;

/// Run-time interlock thresholds (`[interlocks]`): each violation aborts the run with a named
/// fault (`bench::run::interlocks`). Defaults derive from the devices' capabilities and the
/// gyro's ratings.
#[derive(Debug, Clone, PartialEq)]
pub struct Interlocks {
    /// `table_overspeed` above this measured |rate|, rad/s (default: the lesser of the table's
    /// maximum rate and the gyro's input range).
    pub table_max_rate_rad_s: f64,
    /// `rate_disagreement`: how far the rate may leave its command once reached, rad/s
    /// (default 0.1 °/s).
    pub rate_tolerance_rad_s: f64,
    /// … for how long (default 5 s).
    pub rate_disagreement_for: Duration,
    /// `chamber_over_temperature` above this air temperature, °C (default: the gyro's
    /// operating maximum + 5 °C, at most the chamber's maximum).
    pub chamber_max_temp_c: f64,
    /// `chamber_under_temperature` below this, °C (default: the gyro's operating minimum −
    /// 5 °C, at least the chamber's minimum).
    pub chamber_min_temp_c: f64,
    /// `setpoint_not_tracked`: how far the air may be from the working set point, °C
    /// (default 10 °C).
    pub setpoint_tolerance_c: f64,
    /// … for how long (default 30 min).
    pub setpoint_not_tracked_for: Duration,
    /// `gyro_status`: how long the gyro may flag its samples invalid or failing built-in test
    /// (default 5 s).
    pub gyro_status_for: Duration,
}

impl Interlocks {
    /// The defaults for devices with these capabilities.
    pub fn defaults(caps: &crate::scenario::Capabilities) -> Self {
        let deg = bench_physics::units::DEG;
        let (glo, ghi) = caps.gyro.capabilities.operating_temp_c;
        let c = &caps.chamber.capabilities;
        Self {
            table_max_rate_rad_s: caps
                .table
                .capabilities
                .max_rate_rad_s
                .min(caps.gyro.capabilities.max_rate_rad_s),
            rate_tolerance_rad_s: 0.1 * deg,
            rate_disagreement_for: Duration::from_secs(5),
            chamber_max_temp_c: (ghi + 5.0).min(c.max_temp_c),
            chamber_min_temp_c: (glo - 5.0).max(c.min_temp_c),
            setpoint_tolerance_c: 10.0,
            setpoint_not_tracked_for: Duration::from_secs(1800),
            gyro_status_for: Duration::from_secs(5),
        }
    }
}

/// A validated, fully expanded scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPlan {
    /// Scenario name (`bench.scenario` `name`).
    pub name: String,
    /// The whole scenario file text (`bench.scenario` `text`).
    pub text: String,
    /// Where the scenario was read from, for messages.
    pub source: String,
    /// The bench site.
    pub site: bench_recording::Site,
    /// Gyro settings.
    pub gyro: GyroSetup,
    /// Polling rates of the table and chamber, Hz (contract default 20).
    pub table_poll_hz: f64,
    /// Chamber polling rate, Hz.
    pub chamber_poll_hz: f64,
    /// Settings that only the simulated bench uses.
    pub sim: SimSetup,
    /// What to do when the run ends or aborts: table decelerates at this rate, rad/s².
    pub safe_decel_rad_s2: f64,
    /// Chamber set point of the safe state, °C.
    pub safe_temp_c: f64,
    /// `[safe] chamber_hold`: the chamber keeps its set point in the safe state (no command).
    pub safe_chamber_hold: bool,
    /// Run-time interlock thresholds (`[interlocks]`).
    pub interlocks: Interlocks,
    /// The unit under test, operator, station and acceptance limits (`bench.station`,
    /// `bench.acceptance`).
    pub station: Station,
    /// `[recording] flush_interval`: kill-safety, the most bench time of data a SIGKILL or
    /// crash may lose (`bench run --flush-interval-s` overrides it); `None`: the default, 1 s.
    pub flush_interval: Option<std::time::Duration>,
    /// The steps, loops expanded, in execution order.
    pub steps: Vec<PlannedStep>,
}

/// Keys of `[station]` / `bench.station`.
pub const STATION_KEYS: &[&str] = &["unit_serial", "operator", "station"];

/// Keys of `[acceptance]` / `bench.acceptance`: the coefficients a calibration reports, SI,
/// units in the names (those of the model file; [`bench_physics::ModelKey::LIMITED`]).
pub const ACCEPTANCE_KEYS: &[&str] = &bench_physics::gyro_model::ACCEPTANCE_KEYS;

/// Test-station metadata of a run: what a test record says about the unit and its test.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Station {
    /// `unit_serial`, `operator`, `station` as given ([`STATION_KEYS`]).
    pub info: std::collections::BTreeMap<String, String>,
    /// Acceptance limit on |coefficient| per [`ACCEPTANCE_KEYS`] key, SI.
    pub acceptance: std::collections::BTreeMap<String, f64>,
}

impl Station {
    /// `bench.acceptance` entries: each limit as decimal text (shortest exact form).
    pub fn acceptance_metadata(&self) -> std::collections::BTreeMap<String, String> {
        self.acceptance.iter().map(|(k, v)| (k.clone(), format!("{v:e}"))).collect()
    }

    /// `other`'s entries over these (a bench config's or the command line's over the
    /// scenario's).
    pub fn overridden_by(&self, other: &Station) -> Station {
        let mut s = self.clone();
        s.info.extend(other.info.iter().map(|(k, v)| (k.clone(), v.clone())));
        s.acceptance.extend(other.acceptance.iter().map(|(k, v)| (k.clone(), *v)));
        s
    }
}

/// Gyro settings.
#[derive(Debug, Clone, PartialEq)]
pub struct GyroSetup {
    /// Output rate, Hz.
    pub sample_rate_hz: f64,
    /// The nominal error model written to `bench.gyro_model`.
    pub model: GyroModel,
    /// Whether the lab gave the model (`[gyro.model]` or `--gyro-model`): a run on real
    /// drivers records only a given model, never the defaults as if they were the gyro's.
    pub model_given: bool,
    /// Effects beyond the model that the lab believes in (`[gyro.model.effects]`, or a model
    /// file's `[effects]`): written to `bench.gyro_model` as `effect.*` keys, and the starting
    /// point of the simulator's [`SimSetup::truth_effects`].
    pub effects: Effects,
}

/// Settings of the in-process simulated bench.
#[derive(Debug, Clone, PartialEq)]
pub struct SimSetup {
    /// Chamber air (and gyro) temperature at the start, °C.
    pub initial_temp_c: f64,
    /// The simulator's true gyro model (defaults to the nominal one).
    pub truth: GyroModel,
    /// Effects the simulated gyro shows: [`GyroSetup::effects`], each effect named in
    /// `[simulation.truth.effects]` replacing, adding or (with `false`) removing one. Never
    /// written to the recording beyond what `GyroSetup::effects` already says: concealed.
    pub truth_effects: Effects,
}

/// One step of the plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedStep {
    /// Position in the expanded plan, from 0.
    pub index: usize,
    /// Step kind, e.g. `chamber`, `table`, `wait_temperature`, `record`.
    pub name: String,
    /// Label; a label starting with `record` marks a calibration window.
    pub label: String,
    /// Where the step is in the scenario file (`file:line:column`), for messages.
    pub origin: String,
    /// What the step does.
    pub action: Action,
}

/// Which temperature a condition watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TempSource {
    /// Chamber air (the controller's process value).
    Air,
    /// The gyro's internal sensor (falls back to air if the gyro has none).
    Gyro,
}

/// What a step does.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Move the chamber's set point to `target_c` at `ramp_c_s` (°C/s), or at full speed.
    /// Returns at once: the ramp runs concurrently with later steps.
    Chamber {
        /// Target set point, °C.
        target_c: f64,
        /// Ramp rate magnitude, °C/s; `None` = as fast as the controller goes.
        ramp_c_s: Option<f64>,
    },
    /// Spin the table at `rate_rad_s` (positive counter-clockwise seen from above; CW is
    /// negative) with acceleration `accel_rad_s2`. If `settle`, the step ends when the measured
    /// rate is within tolerance of the command; otherwise at once.
    Table {
        /// Commanded rate, rad/s.
        rate_rad_s: f64,
        /// Acceleration magnitude, rad/s².
        accel_rad_s2: f64,
        /// Wait until the rate is reached.
        settle: bool,
    },
    /// Decelerate the table to rest at `decel_rad_s2` and wait until it is at rest.
    TableStop {
        /// Deceleration magnitude, rad/s².
        decel_rad_s2: f64,
    },
    /// Wait a fixed time.
    Wait {
        /// How long.
        duration: Duration,
    },
    /// Wait until a temperature stays within `band_c` of `target_c` for `hold`; fail the run
    /// after `timeout`.
    WaitTemperature {
        /// Which temperature.
        source: TempSource,
        /// Target, °C.
        target_c: f64,
        /// Half-width of the band, °C.
        band_c: f64,
        /// How long it must stay in the band.
        hold: Duration,
        /// Give up (abort the run) after this long.
        timeout: Duration,
    },
    /// Wait until the chamber's working set point has reached its target (end of a ramp);
    /// fail after `timeout`.
    WaitRampEnd {
        /// Give up after this long.
        timeout: Duration,
    },
    /// A record window: data between its start and end events is for calibration. Lasts
    /// `duration`, or until the current chamber ramp ends if `until_ramp_end` (then
    /// `duration` is the timeout).
    Record {
        /// Length (or timeout when `until_ramp_end`).
        duration: Duration,
        /// End with the chamber ramp instead of after `duration`.
        until_ramp_end: bool,
    },
}

/// How the plan is expected to unfold in bench time: [`RunPlan::estimate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Expected bench time at each step's start, s (one per step).
    pub step_start_s: Vec<f64>,
    /// Expected bench time at each step's end, s.
    pub step_end_s: Vec<f64>,
    /// Expected bench time of the whole run (safe state and its tail included).
    pub total: Duration,
    /// The first step whose condition the physics says is not met within its timeout (the
    /// run would abort there), if any.
    pub timeout_step: Option<usize>,
}

impl Estimate {
    /// Expected bench time still to go when step `step` has run for `in_step_s`, s: the rest of
    /// this step (at least nothing, when it overruns its estimate) and every later step.
    pub fn remaining_s(&self, step: usize, in_step_s: f64) -> f64 {
        let total = self.total.as_secs_f64();
        match (self.step_start_s.get(step), self.step_end_s.get(step)) {
            (Some(&start), Some(&end)) => {
                let left_in_step = (end - start - in_step_s.max(0.0)).max(0.0);
                left_in_step + (total - end).max(0.0)
            }
            _ => 0.0,
        }
    }
}

/// The sequencer's rules that the estimate follows (`run::sequencer`): a settled table rate is
/// within 1e-3 of the command or 1e-6 rad/s; a ramp has ended when the displayed working set
/// point is within 0.05 °C of the target; a temperature band edge gets 1e-9 °C.
const SETTLE_REL: f64 = 1e-3;
const SETTLE_ABS_RAD_S: f64 = 1e-6;
const RAMP_END_TOL_C: f64 = 0.05;
const BAND_EDGE_C: f64 = 1e-9;
/// Bench time recorded after the safe-state commands (`run::SAFE_STATE_TAIL`).
const SAFE_STATE_TAIL_S: f64 = 1.0;

impl RunPlan {
    /// Expected bench time of the run, for `bench validate` and the progress display:
    /// [`Self::estimate`] on the simulated bench's chamber and table.
    pub fn estimated_duration(&self) -> Duration {
        self.estimate().total
    }

    /// How the plan unfolds on the simulated bench's chamber ([`ChamberParams::default`]) and
    /// table ([`TableParams::default`]): [`Self::estimate_with`].
    pub fn estimate(&self) -> Estimate {
        self.estimate_with(&ChamberParams::default(), &TableParams::default())
    }

    /// Run the plan's steps through the same physics the simulated bench follows — the
    /// chamber's set-point ramp, air lag and slew limits, the gyro's thermal lag behind the air
    /// (`sim.truth.thermal_time_constant`), the table's acceleration-limited slews — checking
    /// each wait condition as the sequencer does (readings at the polling rate, displayed
    /// temperatures at their resolution), without noise. A wait whose condition is never met
    /// ends at its timeout, where the run would abort.
    pub fn estimate_with(&self, chamber: &ChamberParams, table: &TableParams) -> Estimate {
        let poll_s = 1.0 / self.chamber_poll_hz.max(self.table_poll_hz).max(1e-3);
        let chamber_dt = 1.0 / self.chamber_poll_hz.max(1e-3);
        let gyro_dt = 1.0 / self.gyro.sample_rate_hz.max(1e-3);
        let mut air = ChamberModel::new(
            chamber.clone(),
            self.sim.initial_temp_c,
            self.sim.truth.thermal_time_constant,
        );
        let table_params = TableParams { ripple_rel: 0.0, rate_noise_rad_s: 0.0, ..table.clone() };
        let mut rot = RateTableModel::new(table_params);
        // The latest reading at `t`: the chamber's at its last poll, the gyro's at its last
        // sample; the sequencer sees them one poll later at the latest.
        let last = |t: f64, dt: f64| (t / dt).floor() * dt;
        let mut commanded_target = f64::NAN;
        let mut t = 0.0f64;
        let (mut starts, mut ends) = (Vec::new(), Vec::new());
        let mut timeout_step = None;
        for s in &self.steps {
            starts.push(t);
            let mut timed_out = false;
            match &s.action {
                Action::Chamber { target_c, ramp_c_s } => {
                    if air.set_target(t, *target_c, *ramp_c_s).is_ok() {
                        commanded_target = *target_c;
                    }
                }
                Action::Table { rate_rad_s, accel_rad_s2, settle } => {
                    let _ = rot.command_rate(t, *rate_rad_s, *accel_rad_s2);
                    if *settle {
                        (t, timed_out) = settle_time(&rot, t, *rate_rad_s, *accel_rad_s2, poll_s);
                    }
                }
                Action::TableStop { decel_rad_s2 } => {
                    let _ = rot.stop(t, *decel_rad_s2);
                    (t, timed_out) = settle_time(&rot, t, 0.0, *decel_rad_s2, poll_s);
                }
                Action::Wait { duration } => t += duration.as_secs_f64(),
                Action::WaitTemperature { source, target_c, band_c, hold, timeout } => {
                    let start = t;
                    let mut in_band_since: Option<f64> = None;
                    loop {
                        let temp = match source {
                            TempSource::Air => {
                                quantise(air.state(last(t, chamber_dt)).air_c, chamber.resolution_c)
                            }
                            TempSource::Gyro => GyroSampler::temperature_readout(
                                air.state(last(t, gyro_dt)).payload_c,
                            ),
                        };
                        if (temp - target_c).abs() <= band_c + BAND_EDGE_C {
                            let since = *in_band_since.get_or_insert(t);
                            if t - since >= hold.as_secs_f64() {
                                break;
                            }
                        } else {
                            in_band_since = None;
                        }
                        if t - start >= timeout.as_secs_f64() {
                            timed_out = true;
                            break;
                        }
                        t += poll_s;
                    }
                }
                Action::WaitRampEnd { timeout } => {
                    (t, timed_out) = ramp_end(
                        &mut air,
                        t,
                        commanded_target,
                        timeout,
                        chamber,
                        chamber_dt,
                        poll_s,
                    )
                }
                Action::Record { duration, until_ramp_end } => {
                    if *until_ramp_end {
                        (t, timed_out) = ramp_end(
                            &mut air,
                            t,
                            commanded_target,
                            duration,
                            chamber,
                            chamber_dt,
                            poll_s,
                        );
                    } else {
                        t += duration.as_secs_f64();
                    }
                }
            }
            ends.push(t);
            if timed_out {
                timeout_step = Some(s.index);
                break;
            }
        }
        // Steps after an abort do not run.
        while starts.len() < self.steps.len() {
            starts.push(t);
            ends.push(t);
        }
        Estimate {
            step_start_s: starts,
            step_end_s: ends,
            total: Duration::from_secs_f64((t + SAFE_STATE_TAIL_S).max(0.0)),
            timeout_step,
        }
    }
}

/// When the table's rate settles on `rate_rad_s` (the sequencer's rule: first look one poll
/// after the command, timeout twice the slew plus 10 s); whether it timed out.
fn settle_time(
    table: &RateTableModel,
    t0: f64,
    rate_rad_s: f64,
    accel_rad_s2: f64,
    poll_s: f64,
) -> (f64, bool) {
    let tol = (rate_rad_s.abs() * SETTLE_REL).max(SETTLE_ABS_RAD_S);
    let span = (rate_rad_s - table.state(t0).rate_rad_s).abs();
    let slew_s = if accel_rad_s2 > 0.0 && span.is_finite() { span / accel_rad_s2 } else { 0.0 };
    let timeout = 2.0 * slew_s + 10.0;
    let mut t = t0 + poll_s;
    loop {
        // The reading the sequencer sees was taken at the previous poll.
        if (table.state(t - poll_s).rate_rad_s - rate_rad_s).abs() <= tol {
            return (t, false);
        }
        if t - t0 >= timeout {
            return (t, true);
        }
        t += poll_s;
    }
}

/// When the chamber's displayed working set point reaches `target_c` (else the controller's
/// own target); whether `timeout` ran out first.
fn ramp_end(
    air: &mut ChamberModel,
    t0: f64,
    target_c: f64,
    timeout: &Duration,
    chamber: &ChamberParams,
    chamber_dt: f64,
    poll_s: f64,
) -> (f64, bool) {
    let mut t = t0;
    loop {
        let st = air.state((t / chamber_dt).floor() * chamber_dt);
        let target = if target_c.is_finite() { target_c } else { st.target_c };
        if (quantise(st.setpoint_c, chamber.resolution_c) - target).abs() <= RAMP_END_TOL_C {
            return (t, false);
        }
        if t - t0 >= timeout.as_secs_f64() {
            return (t, true);
        }
        t += poll_s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(steps: &str) -> RunPlan {
        let text = format!("[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 45\n{steps}");
        crate::scenario::parse(&text, "t.toml", &crate::simulate::capabilities()).expect("valid")
    }

    #[test]
    fn a_soak_waits_for_the_gyros_lag_behind_the_air() {
        // The gyro lags the air by 300 s (default model): after a 20 °C step of the chamber it
        // needs ≈ τ_air + τ_gyro·ln(20/0.2) ≈ 120 + 1380 s to come within 0.2 °C, then holds.
        let p = plan(
            "[[step]]\nchamber = \"40 °C\"\n[[step]]\nwait_temperature = \"40 °C\"\n\
             source = \"gyro\"\nband = \"0.2 °C\"\nhold = \"5 min\"\ntimeout = \"3 h\"\n",
        );
        let e = p.estimate();
        assert_eq!(e.timeout_step, None);
        let soak = e.step_end_s[1] - e.step_start_s[1];
        assert!((1500.0..2400.0).contains(&soak), "{soak} s");
        assert!((e.total.as_secs_f64() - e.step_end_s[1] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_condition_never_met_ends_at_its_timeout() {
        let p = plan(
            "[[step]]\nchamber = \"40 °C\"\n[[step]]\nwait_temperature = \"40 °C\"\n\
             source = \"gyro\"\nband = \"0.2 °C\"\nhold = \"1 min\"\ntimeout = \"10 min\"\n\
             [[step]]\nwait = \"1 h\"\n",
        );
        let e = p.estimate();
        assert_eq!(e.timeout_step, Some(1));
        assert!((e.step_end_s[1] - 600.0).abs() < 0.1, "{}", e.step_end_s[1]);
        assert_eq!(e.step_start_s[2], e.step_end_s[1], "the later step does not run");
    }

    #[test]
    fn remaining_time_counts_down_through_the_steps() {
        let p = plan("[[step]]\nwait = \"10 min\"\n[[step]]\nwait = \"20 min\"\n");
        let e = p.estimate();
        assert_eq!(e.remaining_s(0, 0.0), 1801.0);
        assert_eq!(e.remaining_s(1, 600.0), 601.0);
        // A step overrunning its estimate leaves only the later steps.
        assert_eq!(e.remaining_s(0, 900.0), 1201.0);
        assert_eq!(e.remaining_s(5, 0.0), 0.0);
    }
}
