//! Single-axis gyro (FOG): a stream of rate samples.

use async_trait::async_trait;
use serde::{Deserialize, Serialize};

use crate::{DeviceError, DeviceInfo, DeviceResult};

/// What a gyro can do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GyroCapabilities {
    /// Output rates the gyro can be set to, Hz.
    pub sample_rates_hz: Vec<f64>,
    /// Input range (largest rate magnitude measured), rad/s.
    pub max_rate_rad_s: f64,
    /// Operating temperature range, °C (seed FOG: -40..+60).
    pub operating_temp_c: (f64, f64),
    /// Whether samples carry the gyro's internal temperature.
    pub has_temperature: bool,
}

/// One gyro sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSample {
    /// Mean angular rate about the sensing axis over the sample interval, rad/s.
    pub rate_rad_s: f64,
    /// The gyro's internal temperature, °C, if it has a sensor.
    pub temperature_c: Option<f64>,
    /// The device's own sample counter (wraps at the device's width).
    pub seq: u64,
    /// Status word, 0 = valid; bits in [`bench_recording::status::gyro`].
    pub status: u32,
    /// The device's own time stamp, if it has one.
    pub device_time: Option<std::time::Duration>,
}

/// A gyro streaming samples at a configured rate.
#[async_trait]
pub trait Gyro: Send {
    /// Model and capabilities.
    fn info(&self) -> &DeviceInfo<GyroCapabilities>;

    /// Wait for the next sample. Cancel-safe: dropping the future loses no sample that the
    /// next call would have returned.
    async fn next_sample(&mut self) -> DeviceResult<GyroSample>;

    /// Current output rate, Hz.
    fn sample_rate_hz(&self) -> f64;

    /// Set the output rate, Hz. Default: only the current rate is accepted.
    async fn set_sample_rate(&mut self, hz: f64) -> DeviceResult<()> {
        if (hz - self.sample_rate_hz()).abs() < 1e-9 {
            Ok(())
        } else {
            Err(DeviceError::unsupported("changing the sample rate"))
        }
    }
}
