//! Replay devices: a recording played back through the [`RateTable`], [`Chamber`] and [`Gyro`]
//! traits, so the orchestrator, the recorder, the analysis and the wire servers run on recorded
//! data (`bench run SCENARIO --bench replay:REC.mcap`, `bench replay REC.mcap --serve`).
//!
//! Time: a recording's messages are placed on the bench-time axis relative to the run's start
//! epoch (`bench.run` `started` when the file has it, else the earliest message of the four
//! required channels). On a [`bench_drivers::VirtualClock`] a replay runs as fast as the CPU
//! allows; on a [`bench_drivers::SystemClock`] with scale X it runs at X × real time.
//!
//! - The gyro hands out each recorded sample when the clock reaches its log time.
//! - The table and the chamber answer a read with the last recorded reading at or before the
//!   clock's time (the first one before the recording starts).
//! - Commands are accepted and compared with the recording: a table command that disagrees with
//!   the next recorded `rate_command`, or a chamber target that the recorded working set point
//!   does not move toward, is logged as a warning and counted ([`ReplayChecks`]). The readings
//!   stay what was recorded.
//! - Past the end of the recording, [`AtEnd::Error`] makes reads fail with a non-transient
//!   error (a run aborts: "recording ended"); [`AtEnd::Hold`] keeps the last reading and stops
//!   the gyro (what a served replay does).
//!
//! ```no_run
//! use std::sync::Arc;
//! use bench::replay::{ReplayData, ReplayOptions};
//! let data = Arc::new(ReplayData::load("run.mcap".as_ref())?);
//! let clock: Arc<dyn bench_drivers::Clock> = Arc::new(bench_drivers::VirtualClock::new());
//! let bench = data.devices(clock, ReplayOptions::default());
//! println!("replaying {} gyro samples", data.gyro.len());
//! # Ok::<(), bench::replay::ReplayError>(())
//! ```

mod run;

pub use run::prepare;

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use bench_drivers::{
    Chamber, ChamberCapabilities, ChamberReading, Clock, DeviceError, DeviceInfo, DeviceResult,
    ErrorKind, Gyro, GyroCapabilities, GyroSample, HeldClock, RateTable, TableCapabilities,
    TableMode, TableReading,
};

use crate::run::Devices;
use crate::scenario::Capabilities;
use bench_recording::schema::META_GYRO_MODEL;
use bench_recording::{ChamberMsg, GyroMsg, Recording, RecordingError, Site, Stamped, TableMsg};

/// A recorded table command counts as agreeing within this fraction of the command…
const COMMAND_REL: f64 = 1e-6;
/// …or this absolute rate, rad/s.
const COMMAND_ABS_RAD_S: f64 = 1e-9;
/// A chamber target is checked against the recorded working set point over this window.
const SETPOINT_CHECK_WINDOW: Duration = Duration::from_secs(120);
/// The working set point has reached a target within this, °C.
const SETPOINT_TOL_C: f64 = 0.05;

/// Chamber ramp rates a replay accepts, °C/s (whatever the recorded chamber could do).
pub const REPLAY_MAX_RAMP_C_S: f64 = 10.0;

/// One recorded stream on the bench-time axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Track<T> {
    /// Bench time of each message (log time − start epoch), non-decreasing.
    pub t: Vec<Duration>,
    /// Device time stamps (publish time − start epoch) where they differ from the log time.
    pub device_time: Vec<Option<Duration>>,
    /// The message bodies.
    pub msg: Vec<T>,
    /// Median interval between messages (zero for fewer than two).
    median_period: Duration,
}

impl<T: Clone> Track<T> {
    fn new(stamped: &[Stamped<T>], epoch_ns: u64) -> Self {
        let mut v: Vec<&Stamped<T>> = stamped.iter().collect();
        // The contract orders each channel by log time; a file that does not is sorted (stable,
        // so equal times keep file order).
        v.sort_by_key(|m| m.log_time_ns);
        let rel = |ns: u64| Duration::from_nanos(ns.saturating_sub(epoch_ns));
        let t: Vec<Duration> = v.iter().map(|m| rel(m.log_time_ns)).collect();
        let mut d: Vec<Duration> = t
            .windows(2)
            .filter_map(|w| match w {
                [a, b] => Some(b.saturating_sub(*a)),
                _ => None,
            })
            .collect();
        let mid = d.len() / 2;
        let median_period =
            if d.is_empty() { Duration::ZERO } else { *d.select_nth_unstable(mid).1 };
        Self {
            t,
            median_period,
            device_time: v
                .iter()
                .map(|m| (m.publish_time_ns != m.log_time_ns).then(|| rel(m.publish_time_ns)))
                .collect(),
            msg: v.iter().map(|m| m.msg.clone()).collect(),
        }
    }
}

impl<T> Track<T> {
    /// Number of messages.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the stream is empty.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Index of the last message at or before `now`; `None` before the first.
    pub fn at(&self, now: Duration) -> Option<usize> {
        self.t.partition_point(|t| *t <= now).checked_sub(1)
    }

    /// Bench time of the last message.
    pub fn end(&self) -> Option<Duration> {
        self.t.last().copied()
    }

    /// Median interval between messages (zero for fewer than two).
    pub fn median_period(&self) -> Duration {
        self.median_period
    }
}

/// A recording prepared for replay: the three device streams on the bench-time axis, with the
/// run's start epoch and the metadata a re-run needs.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayData {
    /// Where it came from (for device descriptions and messages).
    pub source: String,
    /// Bench time zero of the recording, ns since the Unix epoch.
    pub epoch_ns: u64,
    /// `/gyro/rate`.
    pub gyro: Track<GyroMsg>,
    /// `/table/state`.
    pub table: Track<TableMsg>,
    /// `/chamber/state`.
    pub chamber: Track<ChamberMsg>,
    /// `bench.site`, if recorded with a latitude (checked as every reader checks it).
    pub site: Option<Site>,
    /// `bench.gyro_model` entries, if recorded.
    pub gyro_model: Option<BTreeMap<String, String>>,
    /// What they are to the recorded data.
    pub gyro_model_role: bench_recording::ModelRole,
    /// Whether the file ended normally (a cut file replays up to its cut).
    pub complete: bool,
}

/// Why a recording cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file could not be read.
    #[error("cannot read {recording}: {source}")]
    Read {
        /// The recording.
        recording: String,
        /// Where and why reading failed.
        #[source]
        source: RecordingError,
    },
    /// `bench.site` is not as the contract says.
    #[error("{recording}: {source}")]
    Site {
        /// The recording.
        recording: String,
        /// The metadata record and key.
        #[source]
        source: bench_recording::MetadataError,
    },
    /// A required device stream has no message.
    #[error("{recording}: channel {topic} has no message: nothing to replay for the {device}")]
    Empty {
        /// The recording.
        recording: String,
        /// Topic.
        topic: &'static str,
        /// Device.
        device: &'static str,
    },
}

impl ReplayData {
    /// Read a recording file (any conforming MCAP: with or without summary, any compression).
    pub fn load(path: &Path) -> Result<Self, ReplayError> {
        let rec = Recording::load(path).map_err(|source| ReplayError::Read {
            recording: path.display().to_string(),
            source,
        })?;
        Self::from_recording(&rec, &path.display().to_string())
    }

    /// Prepare a loaded recording; `source` names it in messages.
    pub fn from_recording(rec: &Recording, source: &str) -> Result<Self, ReplayError> {
        use bench_recording::schema::{TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_TABLE};
        for (empty, topic, device) in [
            (rec.gyro.is_empty(), TOPIC_GYRO, "gyro"),
            (rec.table.is_empty(), TOPIC_TABLE, "rate table"),
            (rec.chamber.is_empty(), TOPIC_CHAMBER, "chamber"),
        ] {
            if empty {
                return Err(ReplayError::Empty { recording: source.to_string(), topic, device });
            }
        }
        // Bench time zero of the replay is the recording's time zero.
        let epoch_ns = rec.time_zero_ns().unwrap_or(0);
        Ok(Self {
            source: source.to_string(),
            epoch_ns,
            gyro: Track::new(&rec.gyro, epoch_ns),
            table: Track::new(&rec.table, epoch_ns),
            chamber: Track::new(&rec.chamber, epoch_ns),
            site: rec
                .site()
                .map_err(|e| ReplayError::Site { recording: source.to_string(), source: e })?,
            gyro_model: rec.metadata(META_GYRO_MODEL).cloned(),
            gyro_model_role: rec.gyro_model_role(),
            complete: rec.complete,
        })
    }

    /// Bench time of the last device message.
    pub fn duration(&self) -> Duration {
        [self.gyro.end(), self.table.end(), self.chamber.end()]
            .into_iter()
            .flatten()
            .max()
            .unwrap_or_default()
    }

    /// The recorded gyro output rate, Hz (from the median sample interval, rounded to 1 µHz).
    pub fn gyro_rate_hz(&self) -> f64 {
        let p = self.gyro.median_period().as_secs_f64();
        if p > 0.0 {
            ((1.0 / p) * 1e6).round() / 1e6
        } else {
            20.0
        }
    }

    /// Whether the recorded gyro reports a temperature.
    pub fn gyro_has_temperature(&self) -> bool {
        self.gyro.msg.iter().any(|m| m.temperature_c.is_some())
    }

    /// What the replayed devices report: the simulated bench's limits, with chamber ramps up to
    /// [`REPLAY_MAX_RAMP_C_S`] (a replay does not execute commands: it checks them against the
    /// recording), and the recorded gyro's rate and temperature sensor.
    pub fn capabilities(&self) -> Capabilities {
        let mut infos = bench_sim::default_infos();
        let ch = &mut infos.chamber.capabilities;
        ch.max_heat_rate_c_s = ch.max_heat_rate_c_s.max(REPLAY_MAX_RAMP_C_S);
        ch.max_cool_rate_c_s = ch.max_cool_rate_c_s.max(REPLAY_MAX_RAMP_C_S);
        let mut gyro = infos.gyro.capabilities;
        gyro.sample_rates_hz = vec![self.gyro_rate_hz()];
        gyro.has_temperature = self.gyro_has_temperature();
        fn info<C>(source: &str, capabilities: C) -> DeviceInfo<C> {
            DeviceInfo {
                model: format!("replay of {source}"),
                driver: "replay".to_string(),
                capabilities,
            }
        }
        Capabilities {
            table: info(&self.source, infos.table.capabilities),
            chamber: info(&self.source, infos.chamber.capabilities),
            gyro: info(&self.source, gyro),
        }
    }

    /// The three replay devices on `clock`, and the counters of their command checks.
    pub fn devices(self: &Arc<Self>, clock: Arc<dyn Clock>, opts: ReplayOptions) -> ReplayBench {
        let checks = Arc::new(ReplayChecks::default());
        let caps = self.capabilities();
        ReplayBench {
            table: ReplayTable {
                data: self.clone(),
                clock: clock.clone(),
                info: caps.table,
                at_end: opts.at_end,
                checks: checks.clone(),
                commanded: None,
            },
            chamber: ReplayChamber {
                data: self.clone(),
                clock: clock.clone(),
                info: caps.chamber,
                at_end: opts.at_end,
                checks: checks.clone(),
                target_c: None,
            },
            gyro: ReplayGyro {
                data: self.clone(),
                clock,
                rate_hz: self.gyro_rate_hz(),
                info: caps.gyro,
                at_end: opts.at_end,
                next: 0,
                checks: checks.clone(),
            },
            checks,
        }
    }
}

impl ReplayData {
    /// Serve this replay's devices over the simulators' wire protocols (`bench replay
    /// --serve`), on `clock`: held at the last reading past the end, and the table and chamber
    /// start `clock` at their first request ([`StartOnRequest`]).
    pub async fn serve(
        self: &Arc<Self>,
        clock: &HeldClock,
    ) -> Result<bench_sim::serve::bench::ServedBench, bench_sim::serve::bench::ServeError> {
        let shared: Arc<dyn Clock> = Arc::new(clock.clone());
        let bench = self.devices(shared.clone(), ReplayOptions { at_end: AtEnd::Hold });
        bench_sim::serve::bench::serve_devices(
            StartOnRequest::new(bench.table, clock.clone()),
            StartOnRequest::new(bench.chamber, clock.clone()),
            bench.gyro,
            self.gyro_rate_hz(),
            shared,
        )
        .await
    }
}

/// A table or chamber that starts a [`HeldClock`] at its first request (a read or a command):
/// a served replay (`bench replay --serve`) then begins when a client first asks for something,
/// not when the server started, so a bench that connects late misses nothing.
#[derive(Clone)]
pub struct StartOnRequest<D> {
    device: D,
    clock: HeldClock,
}

impl<D> StartOnRequest<D> {
    /// Wrap `device`; its first request starts `clock`.
    pub fn new(device: D, clock: HeldClock) -> Self {
        Self { device, clock }
    }

    fn request(&self, what: &str) {
        if self.clock.start() {
            tracing::info!("replay started by the first request ({what})");
        }
    }
}

#[async_trait]
impl<T: RateTable + Sync> RateTable for StartOnRequest<T> {
    fn info(&self) -> &DeviceInfo<TableCapabilities> {
        self.device.info()
    }
    async fn set_rate(&mut self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<()> {
        self.request("table command");
        self.device.set_rate(rate_rad_s, accel_rad_s2).await
    }
    async fn stop(&mut self, decel_rad_s2: f64) -> DeviceResult<()> {
        self.request("table stop");
        self.device.stop(decel_rad_s2).await
    }
    async fn read(&mut self) -> DeviceResult<TableReading> {
        self.request("table read");
        self.device.read().await
    }
    async fn service(&mut self) -> DeviceResult<()> {
        self.device.service().await
    }
}

#[async_trait]
impl<C: Chamber + Sync> Chamber for StartOnRequest<C> {
    fn info(&self) -> &DeviceInfo<ChamberCapabilities> {
        self.device.info()
    }
    async fn set_target(&mut self, target_c: f64, ramp_c_s: Option<f64>) -> DeviceResult<()> {
        self.request("chamber set point");
        self.device.set_target(target_c, ramp_c_s).await
    }
    async fn read(&mut self) -> DeviceResult<ChamberReading> {
        self.request("chamber read");
        self.device.read().await
    }
    async fn service(&mut self) -> DeviceResult<()> {
        self.device.service().await
    }
}

/// What a replay device does once the clock passes the end of its stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AtEnd {
    /// Reads fail with a non-transient error naming the end (a run aborts). The gyro fails one
    /// and a half sample periods after its last sample, the table and chamber two poll periods
    /// after theirs, so a run that ends with the recording does not see it.
    #[default]
    Error,
    /// Keep reporting the last reading; the gyro stops streaming (served replays).
    Hold,
}

/// Options of the replay devices.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReplayOptions {
    /// Behaviour past the end of the recording.
    pub at_end: AtEnd,
}

/// How the commands sent to the replay devices compared with the recording.
#[derive(Debug, Default)]
pub struct ReplayChecks {
    /// Table commands (set rate, stop) received.
    pub table_commands: AtomicU64,
    /// …of which disagreed with the recorded `rate_command`.
    pub table_mismatches: AtomicU64,
    /// Chamber targets received.
    pub chamber_commands: AtomicU64,
    /// …of which the recorded working set point did not move toward.
    pub chamber_mismatches: AtomicU64,
    /// Gyro samples handed out.
    pub gyro_samples: AtomicU64,
}

impl ReplayChecks {
    /// (table commands, table mismatches, chamber commands, chamber mismatches).
    pub fn counts(&self) -> (u64, u64, u64, u64) {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        (
            g(&self.table_commands),
            g(&self.table_mismatches),
            g(&self.chamber_commands),
            g(&self.chamber_mismatches),
        )
    }
}

/// The three replay devices of one recording.
pub struct ReplayBench {
    /// Rate table.
    pub table: ReplayTable,
    /// Chamber.
    pub chamber: ReplayChamber,
    /// Gyro.
    pub gyro: ReplayGyro,
    /// Command checks shared by the three.
    pub checks: Arc<ReplayChecks>,
}

impl ReplayBench {
    /// As the orchestrator's devices; the checks stay readable through the returned handle.
    pub fn into_devices(self) -> (Devices, Arc<ReplayChecks>) {
        (
            Devices {
                table: Box::new(self.table),
                chamber: Box::new(self.chamber),
                gyro: Box::new(self.gyro),
            },
            self.checks,
        )
    }
}

fn ended(data: &ReplayData, topic: &str, end: Duration) -> DeviceError {
    DeviceError::new(
        ErrorKind::Other,
        format!(
            "replay: the recording {} ends at {:.3} s of bench time ({topic})",
            data.source,
            end.as_secs_f64()
        ),
    )
}

/// Index of the reading to report at `now`, or the end-of-recording error.
fn reading_index<T>(
    data: &ReplayData,
    track: &Track<T>,
    topic: &str,
    now: Duration,
    at_end: AtEnd,
) -> DeviceResult<usize> {
    let end = track.end().unwrap_or_default();
    if at_end == AtEnd::Error && now > end + 2 * track.median_period().max(Duration::from_millis(1))
    {
        return Err(ended(data, topic, end));
    }
    Ok(track.at(now).unwrap_or(0))
}

/// The rate table of a recording.
#[derive(Clone)]
pub struct ReplayTable {
    data: Arc<ReplayData>,
    clock: Arc<dyn Clock>,
    info: DeviceInfo<TableCapabilities>,
    at_end: AtEnd,
    checks: Arc<ReplayChecks>,
    /// The mode last commanded: a recording holds no mode, so the replayed axis is in the mode
    /// it was put in (until then: off where the recording's status says so, stopped where it
    /// shows no motion and no command, else in rate mode). A recorded drive alarm stays in the
    /// replayed status.
    commanded: Option<TableMode>,
}

impl ReplayTable {
    /// Compare a command with the first recorded reading after now.
    fn check(&self, rate_rad_s: f64, what: &str) {
        self.checks.table_commands.fetch_add(1, Ordering::Relaxed);
        let now = self.clock.now();
        let track = &self.data.table;
        let next = track.t.partition_point(|t| *t <= now);
        let Some(rec) = track.msg.get(next) else {
            return;
        };
        let tol = (rate_rad_s.abs() * COMMAND_REL).max(COMMAND_ABS_RAD_S);
        if (rec.rate_command_rad_s - rate_rad_s).abs() > tol {
            self.checks.table_mismatches.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(
                "replay: table {what} {rate_rad_s:.6e} rad/s at {:.3} s, but the recording's \
                 rate_command is {:.6e} rad/s (reporting the recording)",
                now.as_secs_f64(),
                rec.rate_command_rad_s
            );
        }
    }
}

#[async_trait]
impl RateTable for ReplayTable {
    fn info(&self) -> &DeviceInfo<TableCapabilities> {
        &self.info
    }

    async fn set_rate(&mut self, rate_rad_s: f64, _accel_rad_s2: f64) -> DeviceResult<()> {
        self.check(rate_rad_s, "commanded");
        self.commanded = Some(TableMode::Rate);
        Ok(())
    }

    async fn stop(&mut self, _decel_rad_s2: f64) -> DeviceResult<()> {
        self.check(0.0, "stop: commanded");
        self.commanded = Some(TableMode::Stopped);
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<TableReading> {
        let track = &self.data.table;
        let i = reading_index(&self.data, track, "/table/state", self.clock.now(), self.at_end)?;
        let (Some(m), Some(dt)) = (track.msg.get(i), track.device_time.get(i)) else {
            return Err(ended(&self.data, "/table/state", Duration::ZERO));
        };
        let mode = if let Some(mode) = self.commanded {
            mode
        } else if m.status & bench_recording::status::table::DRIVE_OFF != 0 {
            TableMode::Off
        } else if m.rate_command_rad_s == 0.0 && m.rate_rad_s == 0.0 {
            TableMode::Stopped
        } else {
            TableMode::Rate
        };
        Ok(TableReading {
            angle_rad: m.angle_rad,
            rate_rad_s: m.rate_rad_s,
            rate_command_rad_s: m.rate_command_rad_s,
            mode,
            status: m.status,
            device_time: *dt,
        })
    }
}

/// The chamber of a recording.
#[derive(Clone)]
pub struct ReplayChamber {
    data: Arc<ReplayData>,
    clock: Arc<dyn Clock>,
    info: DeviceInfo<ChamberCapabilities>,
    at_end: AtEnd,
    checks: Arc<ReplayChecks>,
    target_c: Option<f64>,
}

#[async_trait]
impl Chamber for ReplayChamber {
    fn info(&self) -> &DeviceInfo<ChamberCapabilities> {
        &self.info
    }

    async fn set_target(&mut self, target_c: f64, _ramp_c_s: Option<f64>) -> DeviceResult<()> {
        self.checks.chamber_commands.fetch_add(1, Ordering::Relaxed);
        self.target_c = Some(target_c);
        let now = self.clock.now();
        let track = &self.data.chamber;
        let from = track.at(now).unwrap_or(0);
        let Some(sp0) = track.msg.get(from).map(|m| m.setpoint_c) else {
            return Ok(());
        };
        let gap0 = (sp0 - target_c).abs();
        if gap0 <= SETPOINT_TOL_C {
            return Ok(());
        }
        let until = track.t.partition_point(|t| *t <= now + SETPOINT_CHECK_WINDOW);
        let later = track.msg.get(from + 1..until).unwrap_or_default();
        if !later.is_empty() && !later.iter().any(|m| (m.setpoint_c - target_c).abs() < gap0) {
            self.checks.chamber_mismatches.fetch_add(1, Ordering::Relaxed);
            tracing::warn!(
                "replay: chamber target {target_c} °C at {:.3} s, but the recording's set point \
                 stays at {sp0} °C or moves away over the next {} s (reporting the recording)",
                now.as_secs_f64(),
                SETPOINT_CHECK_WINDOW.as_secs()
            );
        }
        Ok(())
    }

    async fn read(&mut self) -> DeviceResult<ChamberReading> {
        let track = &self.data.chamber;
        let i = reading_index(&self.data, track, "/chamber/state", self.clock.now(), self.at_end)?;
        let (Some(m), Some(dt)) = (track.msg.get(i), track.device_time.get(i)) else {
            return Err(ended(&self.data, "/chamber/state", Duration::ZERO));
        };
        Ok(ChamberReading {
            temperature_c: m.temperature_c,
            setpoint_c: m.setpoint_c,
            target_c: self.target_c.unwrap_or(m.setpoint_c),
            status: m.status,
            device_time: *dt,
        })
    }
}

/// The gyro of a recording: each sample when the clock reaches its log time.
#[derive(Clone)]
pub struct ReplayGyro {
    data: Arc<ReplayData>,
    clock: Arc<dyn Clock>,
    rate_hz: f64,
    info: DeviceInfo<GyroCapabilities>,
    at_end: AtEnd,
    next: usize,
    checks: Arc<ReplayChecks>,
}

impl ReplayGyro {
    /// Skip to the first sample after bench time `t` (used by servers that start late).
    pub fn seek(&mut self, t: Duration) {
        self.next = self.data.gyro.t.partition_point(|s| *s <= t);
    }
}

#[async_trait]
impl Gyro for ReplayGyro {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        &self.info
    }

    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let track = &self.data.gyro;
        let (Some(t), Some(m), Some(dt)) =
            (track.t.get(self.next), track.msg.get(self.next), track.device_time.get(self.next))
        else {
            let end = track.end().unwrap_or_default();
            return match self.at_end {
                AtEnd::Error => {
                    let period = Duration::from_secs_f64(1.5 / self.rate_hz.max(1e-3));
                    self.clock.sleep_until(end + period).await;
                    Err(ended(&self.data, "/gyro/rate", end))
                }
                AtEnd::Hold => {
                    futures::future::pending::<()>().await;
                    Err(ended(&self.data, "/gyro/rate", end))
                }
            };
        };
        // Cancel-safe: the index moves only once the sample is handed out.
        self.clock.sleep_until(*t).await;
        self.next += 1;
        self.checks.gyro_samples.fetch_add(1, Ordering::Relaxed);
        Ok(GyroSample {
            rate_rad_s: m.rate_rad_s,
            temperature_c: m.temperature_c,
            seq: m.seq,
            status: m.status,
            device_time: *dt,
        })
    }

    fn sample_rate_hz(&self) -> f64 {
        self.rate_hz
    }

    async fn set_sample_rate(&mut self, hz: f64) -> DeviceResult<()> {
        if (hz - self.rate_hz).abs() <= 1e-6 * self.rate_hz.max(1.0) {
            Ok(())
        } else {
            Err(DeviceError::new(
                ErrorKind::Unsupported,
                format!("replay: the recording's gyro ran at {} Hz, not {hz} Hz", self.rate_hz),
            ))
        }
    }
}

#[cfg(test)]
mod tests;
