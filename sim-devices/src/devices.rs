//! The three simulated devices.

use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use bench_drivers::{
    Chamber, ChamberCapabilities, ChamberReading, Clock, DeviceError, DeviceInfo, DeviceResult,
    ErrorKind, Gyro, GyroCapabilities, GyroSample, RateTable, TableCapabilities, TableMode,
    TableReading,
};
use bench_physics::gyro::GyroSampler;
use bench_physics::table::AxisMode;
use bench_recording::status;

use crate::world::{lock, SharedWorld};

/// Simulated rate table.
#[derive(Clone)]
pub struct SimTable {
    pub(crate) world: SharedWorld,
    pub(crate) clock: Arc<dyn Clock>,
    pub(crate) info: DeviceInfo<TableCapabilities>,
}

/// Simulated climatic chamber.
#[derive(Clone)]
pub struct SimChamber {
    pub(crate) world: SharedWorld,
    pub(crate) clock: Arc<dyn Clock>,
    pub(crate) info: DeviceInfo<ChamberCapabilities>,
}

/// Simulated FOG. Sample `k` (k = 1, 2, …) is the mean over `((k−1)/fs, k/fs]` and is returned
/// at bench time `k/fs` with `seq = k − 1`.
#[derive(Clone)]
pub struct SimGyro {
    pub(crate) world: SharedWorld,
    pub(crate) clock: Arc<dyn Clock>,
    pub(crate) info: DeviceInfo<GyroCapabilities>,
    pub(crate) rate_hz: f64,
    /// Start of the current sample schedule (changes with the sample rate), ns.
    pub(crate) base_ns: u64,
    /// Samples taken since `base_ns`.
    pub(crate) since_base: u64,
    pub(crate) seq: u64,
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

fn out_of_range(e: impl std::error::Error) -> DeviceError {
    DeviceError::new(ErrorKind::OutOfRange, e.to_string())
}

#[async_trait]
impl RateTable for SimTable {
    fn info(&self) -> &DeviceInfo<TableCapabilities> {
        &self.info
    }

    async fn set_rate(&mut self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<()> {
        let now = secs(self.clock.now());
        let mut w = lock(&self.world);
        let t = w.command_time(now);
        w.table.command_rate(t, rate_rad_s, accel_rad_s2).map_err(out_of_range)
    }

    async fn stop(&mut self, decel_rad_s2: f64) -> DeviceResult<()> {
        let now = secs(self.clock.now());
        let mut w = lock(&self.world);
        let t = w.command_time(now);
        w.table.stop(t, decel_rad_s2).map_err(out_of_range)
    }

    async fn read(&mut self) -> DeviceResult<TableReading> {
        let now = self.clock.now();
        let mut guard = lock(&self.world);
        let w = &mut *guard;
        let t = w.seen(secs(now));
        let st = w.table.state(t);
        let r = w.table.readout(&st, &mut w.table_rng);
        Ok(TableReading {
            angle_rad: r.angle_rad,
            rate_rad_s: r.rate_rad_s,
            rate_command_rad_s: st.rate_command_rad_s,
            mode: match st.mode {
                AxisMode::Rate => TableMode::Rate,
                AxisMode::Stopped => TableMode::Stopped,
            },
            status: if st.slewing { status::table::SLEWING } else { 0 },
            device_time: Some(now),
        })
    }
}

#[async_trait]
impl Chamber for SimChamber {
    fn info(&self) -> &DeviceInfo<ChamberCapabilities> {
        &self.info
    }

    async fn set_target(&mut self, target_c: f64, ramp_c_s: Option<f64>) -> DeviceResult<()> {
        let now = secs(self.clock.now());
        let mut w = lock(&self.world);
        let t = w.command_time(now);
        let used = w.chamber.set_target(t, target_c, ramp_c_s).map_err(out_of_range)?;
        if let Some(r) = ramp_c_s {
            if used < r {
                tracing::debug!(
                    requested_c_s = r,
                    used_c_s = used,
                    "chamber ramp limited to capability"
                );
            }
        }
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<ChamberReading> {
        let now = self.clock.now();
        let mut guard = lock(&self.world);
        let w = &mut *guard;
        let t = w.seen(secs(now));
        let st = w.chamber.state(t);
        let r = w.chamber.readout(&st, &mut w.chamber_rng);
        let mut s = 0;
        if st.ramping {
            s |= status::chamber::RAMPING;
        }
        if st.saturated {
            s |= status::chamber::SATURATED;
        }
        Ok(ChamberReading {
            temperature_c: r.temperature_c,
            setpoint_c: r.setpoint_c,
            target_c: r.target_c,
            status: s,
            device_time: Some(now),
        })
    }
}

impl SimGyro {
    /// Bench time of the `j`-th sample of the current schedule.
    fn instant(&self, j: u64) -> Duration {
        let offset_ns = (j as f64 * 1e9 / self.rate_hz).round();
        Duration::from_nanos(self.base_ns.saturating_add(offset_ns as u64))
    }
}

#[async_trait]
impl Gyro for SimGyro {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        &self.info
    }

    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let t = self.instant(self.since_base + 1);
        if self.clock.now() < t {
            self.clock.sleep_until(t).await;
        }
        // Nothing above changed any state, so dropping the future while it slept lost nothing.
        let sample = lock(&self.world).gyro_sample(secs(t));
        let mut st = 0;
        // A consumer too far behind the others gets an invalid placeholder for the samples the
        // world no longer remembers, then catches up.
        let (terms, temp) = sample.unwrap_or_else(|| {
            st |= status::gyro::INVALID;
            (Default::default(), f64::NAN)
        });
        let mut rate = terms.total();
        let max = self.info.capabilities.max_rate_rad_s;
        if !rate.is_finite() {
            rate = 0.0;
            st |= status::gyro::INVALID;
        } else if rate.abs() > max {
            rate = rate.clamp(-max, max);
            st |= status::gyro::INVALID;
        }
        let seq = self.seq;
        self.seq += 1;
        self.since_base += 1;
        Ok(GyroSample {
            rate_rad_s: rate,
            temperature_c: self
                .info
                .capabilities
                .has_temperature
                .then(|| GyroSampler::temperature_readout(temp))
                .filter(|t| t.is_finite()),
            seq,
            status: st,
            device_time: Some(t),
        })
    }

    fn sample_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// Any of the listed rates; the new schedule starts at the last sample's time.
    async fn set_sample_rate(&mut self, hz: f64) -> DeviceResult<()> {
        let caps = &self.info.capabilities;
        if !caps.sample_rates_hz.iter().any(|r| (r - hz).abs() < 1e-9) {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!("sample rate {hz} Hz is not one of {:?} Hz", caps.sample_rates_hz),
            ));
        }
        let last = self.instant(self.since_base);
        self.base_ns = u64::try_from(last.as_nanos()).unwrap_or(u64::MAX);
        self.since_base = 0;
        self.rate_hz = hz;
        lock(&self.world).gyro.set_sample_interval(1.0 / hz);
        Ok(())
    }
}
