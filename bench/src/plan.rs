//! A validated run: what the scenario parser produces and the orchestrator executes.
//!
//! Everything here is SI (s, rad, rad/s, rad/s²) except temperatures (°C). Loops of the
//! scenario are already expanded; every value has been checked against the devices'
//! capabilities.

use std::time::Duration;

use bench_physics::effects::Effects;
use bench_physics::GyroModel;

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
    /// The steps, loops expanded, in execution order.
    pub steps: Vec<PlannedStep>,
}

/// Gyro settings.
#[derive(Debug, Clone, PartialEq)]
pub struct GyroSetup {
    /// Output rate, Hz.
    pub sample_rate_hz: f64,
    /// The nominal error model written to `bench.gyro_model`.
    pub model: GyroModel,
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

impl RunPlan {
    /// Nominal bench time the plan needs, assuming every wait condition is met as soon as the
    /// physics allows is unknown in advance; this sums the fixed durations and the ramp times
    /// implied by chamber steps, for progress/ETA estimates only.
    pub fn estimated_duration(&self) -> Duration {
        let mut total = 0.0f64;
        let mut setpoint = self.sim.initial_temp_c;
        let mut ramp_end = 0.0f64;
        for s in &self.steps {
            match &s.action {
                Action::Chamber { target_c, ramp_c_s } => {
                    let d = (target_c - setpoint).abs();
                    ramp_end = total + ramp_c_s.map_or(0.0, |r| if r > 0.0 { d / r } else { 0.0 });
                    setpoint = *target_c;
                }
                Action::Wait { duration } => total += duration.as_secs_f64(),
                Action::WaitTemperature { hold, .. } => {
                    total = total.max(ramp_end) + hold.as_secs_f64();
                }
                Action::WaitRampEnd { .. } => total = total.max(ramp_end),
                Action::Record { duration, until_ramp_end } => {
                    if *until_ramp_end {
                        total = total.max(ramp_end);
                    } else {
                        total += duration.as_secs_f64();
                    }
                }
                Action::Table { .. } | Action::TableStop { .. } => {}
            }
        }
        Duration::from_secs_f64(total.max(0.0))
    }
}
