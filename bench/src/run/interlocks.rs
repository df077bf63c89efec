//! Run-time interlocks: every reading is checked against the plan's [`Interlocks`] as it
//! arrives; a violation aborts the run to its safe state with a named fault
//! ([`FaultCause::Interlock`]) whose name leads the recorded `outcome`.
//!
//! Two families: thresholds on the measured values (`table_overspeed`, `rate_disagreement`,
//! the chamber temperatures, `setpoint_not_tracked`, `gyro_status`), and the devices' own
//! fault reports (`table_drive_fault`, `table_interlock_open`, `table_mode_lost`,
//! `chamber_alarm`, `chamber_door_open`, `gyro_bit_fail`), which trip on the first reading
//! that shows them: a record window with the table's drive off is bad data, never a completed
//! step.

use std::time::Duration;

use bench_drivers::{ChamberReading, GyroSample, TableMode, TableReading};
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
/// The gyro flagged its samples invalid for longer than `gyro_status_for` (a built-in-test
/// failure is [`GYRO_BIT_FAIL`], at once).
pub const GYRO_STATUS: &str = "gyro_status";
/// A stream had no good reading for longer than the policy's `stale_after`.
pub const STREAM_STALE: &str = "stream_stale";
/// The table controller reports a drive alarm, or its drive is off while bench has commanded
/// it (an amplifier fault, a lost keep-alive, an emergency stop).
pub const TABLE_DRIVE_FAULT: &str = "table_drive_fault";
/// The table controller reports its interlock open.
pub const TABLE_INTERLOCK_OPEN: &str = "table_interlock_open";
/// The table's axis is not in the mode bench commanded (rate mode for a spin, stopped after a
/// stop), its drive on.
pub const TABLE_MODE_LOST: &str = "table_mode_lost";
/// The chamber controller reports an alarm (its register map's alarm bits).
pub const CHAMBER_ALARM: &str = "chamber_alarm";
/// The chamber door is open (its register map's door bits).
pub const CHAMBER_DOOR_OPEN: &str = "chamber_door_open";
/// The gyro reports a built-in-test failure.
pub const GYRO_BIT_FAIL: &str = "gyro_bit_fail";

/// The interlocks that are the devices' own fault reports, each tripped by the first reading
/// that shows it.
pub const DEVICE_REPORTS: [&str; 6] = [
    TABLE_DRIVE_FAULT,
    TABLE_INTERLOCK_OPEN,
    TABLE_MODE_LOST,
    CHAMBER_ALARM,
    CHAMBER_DOOR_OPEN,
    GYRO_BIT_FAIL,
];

/// A status word as `0x3 (drive off, alarm)`.
fn bits(word: u32, names: &[(u32, &str)]) -> String {
    let set: Vec<&str> = names.iter().filter(|(b, _)| word & b != 0).map(|(_, n)| *n).collect();
    format!("0x{word:x} ({})", set.join(", "))
}

fn table_bits(word: u32) -> String {
    use status::table::*;
    bits(
        word,
        &[
            (DRIVE_OFF, "drive off"),
            (ALARM, "alarm"),
            (INTERLOCK, "interlock"),
            (SLEWING, "slewing"),
        ],
    )
}

fn mode_name(m: TableMode) -> &'static str {
    match m {
        TableMode::Off => "off",
        TableMode::Rate => "rate",
        TableMode::Position => "position",
        TableMode::Stopped => "stopped",
    }
}

/// The monitor's memory between readings.
#[derive(Debug, Default)]
pub(crate) struct Monitor {
    /// The table mode bench last commanded (`None` before its first command).
    commanded_mode: Option<TableMode>,
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
    /// Bench commanded the table into `mode` (called with the table held, so that every
    /// reading checked after it was taken after the command).
    pub(crate) fn table_commanded(&mut self, mode: TableMode) {
        self.commanded_mode = Some(mode);
    }

    /// The table controller's own fault reports.
    fn table_reports(&self, r: &TableReading) -> Option<Fault> {
        use status::table::{ALARM, INTERLOCK};
        if r.status & INTERLOCK != 0 {
            return Some(trip(
                TABLE_INTERLOCK_OPEN,
                format!(
                    "the table controller reports its interlock open (status {})",
                    table_bits(r.status)
                ),
            ));
        }
        if r.status & ALARM != 0 {
            return Some(trip(
                TABLE_DRIVE_FAULT,
                format!(
                    "the table controller reports a drive alarm (mode {}, status {})",
                    mode_name(r.mode),
                    table_bits(r.status)
                ),
            ));
        }
        let commanded = self.commanded_mode?;
        if r.mode == TableMode::Off {
            return Some(trip(
                TABLE_DRIVE_FAULT,
                format!(
                    "the table's drive is off (mode {}, status {}) with {} mode commanded",
                    mode_name(r.mode),
                    table_bits(r.status),
                    mode_name(commanded)
                ),
            ));
        }
        (r.mode != commanded).then(|| {
            trip(
                TABLE_MODE_LOST,
                format!(
                    "the table is in {} mode, {} mode commanded",
                    mode_name(r.mode),
                    mode_name(commanded)
                ),
            )
        })
    }

    pub(crate) fn table(
        &mut self,
        lim: &Interlocks,
        t: Duration,
        r: &TableReading,
    ) -> Option<Fault> {
        if let Some(fault) = self.table_reports(r) {
            return Some(fault);
        }
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
        use status::chamber::{ALARM, DOOR_OPEN};
        if r.status & DOOR_OPEN != 0 {
            return Some(trip(
                CHAMBER_DOOR_OPEN,
                format!("the chamber controller reports its door open (status 0x{:x})", r.status),
            ));
        }
        if r.status & ALARM != 0 {
            return Some(trip(
                CHAMBER_ALARM,
                format!(
                    "the chamber controller reports an alarm (status 0x{:x}, air {:.2} °C)",
                    r.status, r.temperature_c
                ),
            ));
        }
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
        if s.status & status::gyro::BIT_FAIL != 0 {
            return Some(trip(
                GYRO_BIT_FAIL,
                format!(
                    "the gyro reports a built-in-test failure (status 0x{:x}, sample {})",
                    s.status, s.seq
                ),
            ));
        }
        if s.status & status::gyro::INVALID != 0 {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn reading(mode: TableMode, status: u32) -> TableReading {
        TableReading {
            angle_rad: 0.0,
            rate_rad_s: 0.0,
            rate_command_rad_s: 0.0,
            mode,
            status,
            device_time: None,
        }
    }

    fn name(f: Option<Fault>) -> Option<&'static str> {
        f.map(|f| match f.cause {
            FaultCause::Interlock { name } => name,
            other => panic!("not an interlock: {other:?}"),
        })
    }

    #[test]
    fn a_drive_off_is_a_fault_only_once_bench_has_commanded_the_table() {
        let mut m = Monitor::default();
        // Before the first command the drive may be off (the controller's state at connect).
        assert_eq!(m.table_reports(&reading(TableMode::Off, status::table::DRIVE_OFF)), None);
        assert_eq!(m.table_reports(&reading(TableMode::Stopped, 0)), None);
        m.table_commanded(TableMode::Rate);
        assert_eq!(m.table_reports(&reading(TableMode::Rate, status::table::SLEWING)), None);
        let off = m.table_reports(&reading(TableMode::Off, status::table::DRIVE_OFF));
        assert_eq!(name(off), Some(TABLE_DRIVE_FAULT));
        assert_eq!(name(m.table_reports(&reading(TableMode::Stopped, 0))), Some(TABLE_MODE_LOST));
        m.table_commanded(TableMode::Stopped);
        assert_eq!(m.table_reports(&reading(TableMode::Stopped, 0)), None);
        assert_eq!(name(m.table_reports(&reading(TableMode::Rate, 0))), Some(TABLE_MODE_LOST));
    }

    #[test]
    fn alarm_and_interlock_bits_trip_whatever_was_commanded() {
        let m = Monitor::default();
        let alarm = m.table_reports(&reading(TableMode::Stopped, status::table::ALARM));
        assert_eq!(name(alarm), Some(TABLE_DRIVE_FAULT));
        let both = status::table::ALARM | status::table::INTERLOCK;
        let f = m.table_reports(&reading(TableMode::Off, both)).expect("trips");
        assert_eq!(f.message, "table_interlock_open: the table controller reports its interlock open (status 0x6 (alarm, interlock))");
    }

    #[test]
    fn gyro_bit_failure_trips_at_once_and_invalid_samples_after_their_time() {
        let lim = Interlocks {
            table_max_rate_rad_s: 1.0,
            rate_tolerance_rad_s: 1e-3,
            rate_disagreement_for: Duration::from_secs(5),
            chamber_max_temp_c: 60.0,
            chamber_min_temp_c: -40.0,
            setpoint_tolerance_c: 10.0,
            setpoint_not_tracked_for: Duration::from_secs(1800),
            gyro_status_for: Duration::from_secs(5),
        };
        let s = |status| GyroSample {
            rate_rad_s: 0.0,
            temperature_c: None,
            seq: 7,
            status,
            device_time: None,
        };
        let mut m = Monitor::default();
        let t = Duration::from_secs(10);
        let bit = m.gyro(&lim, t, &s(status::gyro::BIT_FAIL));
        assert_eq!(name(bit), Some(GYRO_BIT_FAIL));
        assert_eq!(m.gyro(&lim, t, &s(status::gyro::INVALID)), None);
        let later = m.gyro(&lim, t + Duration::from_secs(5), &s(status::gyro::INVALID));
        assert_eq!(name(later), Some(GYRO_STATUS));
    }
}
