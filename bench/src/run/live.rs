//! Latest values of a run, shared between the pollers, the sequencer and the progress display.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Lock-free latest values (f64 stored as bits). Written by the pollers, read by the sequencer's
/// wait conditions and by the progress display thread.
#[derive(Debug)]
pub struct Live {
    bench_time_ns: AtomicU64,
    table_rate_rad_s: AtomicU64,
    table_command_rad_s: AtomicU64,
    air_temp_c: AtomicU64,
    setpoint_c: AtomicU64,
    target_c: AtomicU64,
    commanded_target_c: AtomicU64,
    gyro_temp_c: AtomicU64,
    gyro_rate_rad_s: AtomicU64,
    step: AtomicUsize,
    gyro_samples: AtomicU64,
    /// Bench time (ns) of the latest good reading of each stream, by [`Stream`].
    fresh_ns: [AtomicU64; 3],
}

/// The device streams the watchdog looks after.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stream {
    /// `/gyro/rate`.
    Gyro = 0,
    /// `/table/state`.
    Table = 1,
    /// `/chamber/state`.
    Chamber = 2,
}

impl Stream {
    /// Every stream.
    pub const ALL: [Stream; 3] = [Stream::Gyro, Stream::Table, Stream::Chamber];
    /// Device name for messages.
    pub fn device(self) -> &'static str {
        match self {
            Stream::Gyro => "gyro",
            Stream::Table => "rate table",
            Stream::Chamber => "chamber",
        }
    }
}

fn load(a: &AtomicU64) -> f64 {
    f64::from_bits(a.load(Ordering::Relaxed))
}
fn store(a: &AtomicU64, v: f64) {
    a.store(v.to_bits(), Ordering::Relaxed)
}

impl Default for Live {
    fn default() -> Self {
        let nan = || AtomicU64::new(f64::NAN.to_bits());
        Self {
            bench_time_ns: AtomicU64::new(0),
            table_rate_rad_s: nan(),
            table_command_rad_s: nan(),
            air_temp_c: nan(),
            setpoint_c: nan(),
            target_c: nan(),
            commanded_target_c: nan(),
            gyro_temp_c: nan(),
            gyro_rate_rad_s: nan(),
            step: AtomicUsize::new(0),
            gyro_samples: AtomicU64::new(0),
            fresh_ns: [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)],
        }
    }
}

/// A consistent-enough copy of the latest values (NaN where nothing was read yet).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    /// Bench time of the latest reading, s.
    pub bench_time_s: f64,
    /// Measured table rate, rad/s.
    pub table_rate_rad_s: f64,
    /// Commanded table rate, rad/s.
    pub table_command_rad_s: f64,
    /// Chamber air temperature, °C.
    pub air_temp_c: f64,
    /// Working set point, °C.
    pub setpoint_c: f64,
    /// Target set point the controller reports, °C.
    pub target_c: f64,
    /// Last target set point bench commanded, °C (NaN before the first command).
    pub commanded_target_c: f64,
    /// Gyro internal temperature, °C.
    pub gyro_temp_c: f64,
    /// Latest gyro rate, rad/s.
    pub gyro_rate_rad_s: f64,
    /// Index of the running step.
    pub step: usize,
    /// Gyro samples received so far.
    pub gyro_samples: u64,
}

impl Live {
    /// Note the bench time of a reading.
    pub fn set_time(&self, t: std::time::Duration) {
        self.bench_time_ns.fetch_max(t.as_nanos() as u64, Ordering::Relaxed);
    }
    /// Record a table reading.
    pub fn set_table(&self, rate_rad_s: f64, command_rad_s: f64) {
        store(&self.table_rate_rad_s, rate_rad_s);
        store(&self.table_command_rad_s, command_rad_s);
    }
    /// Record a chamber reading.
    pub fn set_chamber(&self, air_c: f64, setpoint_c: f64, target_c: f64) {
        store(&self.air_temp_c, air_c);
        store(&self.setpoint_c, setpoint_c);
        store(&self.target_c, target_c);
    }
    /// Note the chamber target bench commanded.
    pub fn set_commanded_target(&self, target_c: f64) {
        store(&self.commanded_target_c, target_c);
    }
    /// Record a gyro sample.
    pub fn set_gyro(&self, rate_rad_s: f64, temp_c: Option<f64>) {
        store(&self.gyro_rate_rad_s, rate_rad_s);
        if let Some(t) = temp_c {
            store(&self.gyro_temp_c, t);
        }
        self.gyro_samples.fetch_add(1, Ordering::Relaxed);
    }
    /// Note a good reading of `stream` at bench time `t`.
    pub fn set_fresh(&self, stream: Stream, t: std::time::Duration) {
        self.fresh_ns[stream as usize].fetch_max(t.as_nanos() as u64, Ordering::Relaxed);
    }
    /// Bench time of the latest good reading of `stream`.
    pub fn fresh(&self, stream: Stream) -> std::time::Duration {
        std::time::Duration::from_nanos(self.fresh_ns[stream as usize].load(Ordering::Relaxed))
    }
    /// Note the running step.
    pub fn set_step(&self, index: usize) {
        self.step.store(index, Ordering::Relaxed);
    }
    /// Copy out the latest values.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            bench_time_s: self.bench_time_ns.load(Ordering::Relaxed) as f64 * 1e-9,
            table_rate_rad_s: load(&self.table_rate_rad_s),
            table_command_rad_s: load(&self.table_command_rad_s),
            air_temp_c: load(&self.air_temp_c),
            setpoint_c: load(&self.setpoint_c),
            target_c: load(&self.target_c),
            commanded_target_c: load(&self.commanded_target_c),
            gyro_temp_c: load(&self.gyro_temp_c),
            gyro_rate_rad_s: load(&self.gyro_rate_rad_s),
            step: self.step.load(Ordering::Relaxed),
            gyro_samples: self.gyro_samples.load(Ordering::Relaxed),
        }
    }
}
