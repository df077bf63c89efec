//! Single-axis rate table.

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

use crate::{DeviceInfo, DeviceResult};

/// What a rate table can do. Scenarios are validated against it before anything moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableCapabilities {
    /// Largest rate magnitude the table accepts, rad/s.
    pub max_rate_rad_s: f64,
    /// Largest acceleration magnitude the table accepts, rad/s².
    pub max_accel_rad_s2: f64,
    /// Resolution of the position readout, rad (ST1300: 1″ = 4.8481e-6 rad).
    pub position_resolution_rad: f64,
}

/// Operating mode of the table's axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TableMode {
    /// Drive off.
    Off,
    /// Rate mode: the axis follows a commanded rate.
    Rate,
    /// Position mode.
    Position,
    /// Decelerating to rest / held at rest.
    Stopped,
}

/// One reading of the table's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableReading {
    /// Axis angle, rad, unwrapped (keeps counting past 2π), positive counter-clockwise seen
    /// from above.
    pub angle_rad: f64,
    /// Measured rate, rad/s, positive counter-clockwise.
    pub rate_rad_s: f64,
    /// Commanded rate, rad/s.
    pub rate_command_rad_s: f64,
    /// Axis mode.
    pub mode: TableMode,
    /// Status word, 0 = ok; bits in [`bench_recording::status::table`].
    pub status: u32,
    /// The controller's own time stamp of the reading, if it has one (bench-time scale).
    pub device_time: Option<std::time::Duration>,
}

/// A single-axis rate table.
///
/// Calls are async and may take a round trip on the wire; dropping a future cancels the
/// operation from bench's side (the table may already have received the command). Drivers apply
/// their own reply timeouts and report them as [`crate::ErrorKind::Timeout`].
#[async_trait]
pub trait RateTable: Send {
    /// Model and capabilities.
    fn info(&self) -> &DeviceInfo<TableCapabilities>;

    /// Enter rate mode and slew to `rate_rad_s` (positive counter-clockwise seen from above)
    /// with acceleration magnitude `accel_rad_s2`. Returns once the command is accepted, not when
    /// the rate is reached.
    async fn set_rate(&mut self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<()>;

    /// Decelerate to rest at `decel_rad_s2` and hold. Used for the safe state.
    async fn stop(&mut self, decel_rad_s2: f64) -> DeviceResult<()>;

    /// Read angle, rate, command and status.
    async fn read(&mut self) -> DeviceResult<TableReading>;

    /// Periodic housekeeping the controller needs (for example the Actidyn alarm-clear
    /// keep-alive). Called by the poller at its rate; default: nothing to do.
    async fn service(&mut self) -> DeviceResult<()> {
        Ok(())
    }

    /// What the link to the controller has coped with so far (late, stale and corrupt replies,
    /// retries); `None` for a table without a wire link (the simulator, a replay).
    fn link_counters(&self) -> Option<crate::real::link::LinkCounters> {
        None
    }
}
