//! Run-time interlocks: every reading is checked against the plan's [`Interlocks`] as it
//! arrives; a violation aborts the run to its safe state with a named fault
//! ([`FaultCause::Interlock`]) whose name leads the recorded `outcome`.

use std::time::Duration;

use bench_drivers::{ChamberReading, GyroSample, TableReading};
use bench_recording::status;

use super::{Fault, FaultCause};
use crate::plan::Interlocks;

/// The table's measured rate exceeds `table_max_rate`.
pub const TABLE_OVERSPEED: &str = "table_overspeed";
/// A commanded rate was not reached in time (the step's settle time).
pub const TABLE_STALL: &str = "table_stall";
/// After reaching its command, the table's rate left it by more than `rate_tolerance` for
/// longer than `rate_disagreement_for`.
pub const RATE_DISAGREEMENT: &str = "rate_disagreement";
/// The chamber air is above `chamber_max_temp`.
pub const CHAMBER_OVER_TEMPERATURE: &str = "chamber_over_temperature";
/// The chamber air is below `chamber_min_temp`.
pub const CHAMBER_UNDER_TEMPERATURE: &str = "chamber_under_temperature";
/// The chamber air stayed further than `setpoint_tolerance` from its working set point for
/// longer than `setpoint_not_tracked_for`.
pub const SETPOINT_NOT_TRACKED: &str = "setpoint_not_tracked";
/// The gyro flagged its samples invalid or failing built-in test for longer than
/// `gyro_status_for`.
pub const GYRO_STATUS: &str = "gyro_status";
/// A stream had no good reading for longer than the policy's `stale_after`.
pub const STREAM_STALE: &str = "stream_stale";

/// Gyro status bits that are the gyro's own error reports (not link errors the driver or the
/// recorder flags).
const GYRO_ERROR_BITS: u32 = status::gyro::INVALID | status::gyro::BIT_FAIL;

/// The monitor's memory between readings.
#[derive(Debug, Default)]
pub(crate) struct Monitor {
    last_command_rad_s: Option<f64>,
    reached: bool,
    disagree_since: Option<Duration>,
    untracked_since: Option<Duration>,
    gyro_bad_since: Option<Duration>,
}

fn trip(name: &'static str, message: String) -> Fault {
    Fault::new(FaultCause::Interlock { name }, format!("{name}: {message}"))
}

/// How long `since` has lasted at `t`, starting it if need be.
fn lasting(since: &mut Option<Duration>, t: Duration) -> Duration {
    t.saturating_sub(*since.get_or_insert(t))
}

impl Monitor {
    pub(crate) fn table(
        &mut self,
        lim: &Interlocks,
        t: Duration,
        r: &TableReading,
    ) -> Option<Fault> {
        let deg = bench_physics::units::DEG;
        if r.rate_rad_s.abs() > lim.table_max_rate_rad_s {
            return Some(trip(
                TABLE_OVERSPEED,
                format!(
                    "table rate {:.4} °/s exceeds the limit {:.4} °/s",
                    r.rate_rad_s / deg,
                    lim.table_max_rate_rad_s / deg
                ),
            ));
        }
        if self.last_command_rad_s != Some(r.rate_command_rad_s) {
            self.last_command_rad_s = Some(r.rate_command_rad_s);
            self.reached = false;
            self.disagree_since = None;
        }
        let off = (r.rate_rad_s - r.rate_command_rad_s).abs();
        if off <= lim.rate_tolerance_rad_s {
            self.reached = true;
            self.disagree_since = None;
        } else if self.reached {
            let d = lasting(&mut self.disagree_since, t);
            if d >= lim.rate_disagreement_for {
                return Some(trip(
                    RATE_DISAGREEMENT,
                    format!(
                        "table rate {:.4} °/s differs from its command {:.4} °/s by more than \
                         {:.4} °/s for {:.1} s",
                        r.rate_rad_s / deg,
                        r.rate_command_rad_s / deg,
                        lim.rate_tolerance_rad_s / deg,
                        d.as_secs_f64()
                    ),
                ));
            }
        }
        None
    }

    pub(crate) fn chamber(
        &mut self,
        lim: &Interlocks,
        t: Duration,
        r: &ChamberReading,
    ) -> Option<Fault> {
        let air = r.temperature_c;
        if air > lim.chamber_max_temp_c {
            return Some(trip(
                CHAMBER_OVER_TEMPERATURE,
                format!("chamber air {air:.2} °C above the limit {} °C", lim.chamber_max_temp_c),
            ));
        }
        if air < lim.chamber_min_temp_c {
            return Some(trip(
                CHAMBER_UNDER_TEMPERATURE,
                format!("chamber air {air:.2} °C below the limit {} °C", lim.chamber_min_temp_c),
            ));
        }
        if (air - r.setpoint_c).abs() > lim.setpoint_tolerance_c {
            let d = lasting(&mut self.untracked_since, t);
            if d >= lim.setpoint_not_tracked_for {
                return Some(trip(
                    SETPOINT_NOT_TRACKED,
                    format!(
                        "chamber air {air:.2} °C further than {} °C from its set point {:.2} °C \
                         for {:.0} s",
                        lim.setpoint_tolerance_c,
                        r.setpoint_c,
                        d.as_secs_f64()
                    ),
                ));
            }
        } else {
            self.untracked_since = None;
        }
        None
    }

    pub(crate) fn gyro(&mut self, lim: &Interlocks, t: Duration, s: &GyroSample) -> Option<Fault> {
        if s.status & GYRO_ERROR_BITS != 0 {
            let d = lasting(&mut self.gyro_bad_since, t);
            if d >= lim.gyro_status_for {
                return Some(trip(
                    GYRO_STATUS,
                    format!(
                        "the gyro has flagged its samples (status 0x{:x}) for {:.1} s",
                        s.status,
                        d.as_secs_f64()
                    ),
                ));
            }
        } else {
            self.gyro_bad_since = None;
        }
        None
    }
}
