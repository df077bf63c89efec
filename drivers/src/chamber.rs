//! Climatic chamber (temperature controller).

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

use crate::{DeviceInfo, DeviceResult};

/// What a chamber can do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChamberCapabilities {
    /// Lowest set point, °C (ST1300 chamber: -55).
    pub min_temp_c: f64,
    /// Highest set point, °C (ST1300 chamber: +185).
    pub max_temp_c: f64,
    /// Fastest heating ramp of the set point, °C/s.
    pub max_heat_rate_c_s: f64,
    /// Fastest cooling ramp of the set point, °C/s (a positive number).
    pub max_cool_rate_c_s: f64,
    /// Resolution of the process value, °C.
    pub temp_resolution_c: f64,
}

/// One reading of the chamber controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChamberReading {
    /// Chamber air temperature (the controller's process value), °C.
    pub temperature_c: f64,
    /// The controller's working set point (ramps toward the target), °C.
    pub setpoint_c: f64,
    /// The target set point the working set point ramps to, °C.
    pub target_c: f64,
    /// Status word, 0 = ok; bits in [`bench_recording::status::chamber`].
    pub status: u32,
    /// The controller's own time stamp, if it has one.
    pub device_time: Option<std::time::Duration>,
}

/// A climatic chamber.
#[async_trait]
pub trait Chamber: Send {
    /// Model and capabilities.
    fn info(&self) -> &DeviceInfo<ChamberCapabilities>;

    /// Move the working set point to `target_c`: at `ramp_c_s` (°C/s, magnitude) if given,
    /// else as fast as the controller goes. Returns once accepted; the ramp runs on. A driver
    /// whose controller has no ramp function steps the set point itself in [`Chamber::service`].
    async fn set_target(&mut self, target_c: f64, ramp_c_s: Option<f64>) -> DeviceResult<()>;

    /// Read air temperature, working set point and status.
    async fn read(&mut self) -> DeviceResult<ChamberReading>;

    /// Periodic housekeeping (set-point stepping for controllers without a ramp). Called by the
    /// poller at its rate; default: nothing to do.
    async fn service(&mut self) -> DeviceResult<()> {
        Ok(())
    }
}
