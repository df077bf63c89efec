//! The physics world the three simulated devices share.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use bench_physics::chamber::{ChamberModel, ThermalState};
use bench_physics::gyro::{GyroSampler, GyroTerms, Mounting};
use bench_physics::table::{RateTableModel, TableState};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::SimConfig;

/// ChaCha8 stream of the gyro noise.
pub(crate) const STREAM_GYRO: u64 = 1;
/// ChaCha8 stream of the table's rate readout noise.
pub(crate) const STREAM_TABLE: u64 = 2;
/// ChaCha8 stream of the chamber's sensor noise.
pub(crate) const STREAM_CHAMBER: u64 = 3;

/// Table, chamber (with the gyro's temperature as its payload) and gyro, evaluated in closed
/// form at whatever time a device asks about. Each random stream belongs to one device and
/// advances once per reading of that device, so results do not depend on how calls of
/// different devices interleave.
pub(crate) struct World {
    pub(crate) table: RateTableModel,
    pub(crate) table_rng: ChaCha8Rng,
    pub(crate) chamber: ChamberModel,
    pub(crate) chamber_rng: ChaCha8Rng,
    pub(crate) gyro: GyroSampler,
    /// Recent gyro samples by end time (ns): one physical output that several consumers (the
    /// SLCAN and KVH outputs of `bench sim serve`) read at their own pace.
    gyro_recent: std::collections::VecDeque<(u64, GyroTerms, f64)>,
    /// Latest time anything was evaluated at, s: commands never start before it.
    last_t_s: f64,
}

fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

impl World {
    pub(crate) fn new(cfg: &SimConfig) -> Self {
        let m = &cfg.gyro_model;
        let mounting = Mounting { latitude_deg: cfg.latitude_deg, axis_up: cfg.axis_up };
        let (table, effects) = cfg.table_and_gyro_effects();
        Self {
            table: RateTableModel::new(table),
            table_rng: rng(cfg.seed, STREAM_TABLE),
            chamber: ChamberModel::new(
                cfg.chamber.clone(),
                cfg.initial_temp_c,
                m.thermal_time_constant,
            ),
            chamber_rng: rng(cfg.seed, STREAM_CHAMBER),
            gyro: GyroSampler::new(
                m.clone(),
                1.0 / cfg.gyro_sample_rate_hz,
                cfg.seed,
                STREAM_GYRO,
                mounting,
                cfg.initial_temp_c,
            )
            .with_effects(effects),
            gyro_recent: std::collections::VecDeque::with_capacity(GYRO_RECENT),
            last_t_s: 0.0,
        }
    }

    /// Note an evaluation at `t_s`; returns `t_s`.
    #[inline]
    pub(crate) fn seen(&mut self, t_s: f64) -> f64 {
        if t_s > self.last_t_s {
            self.last_t_s = t_s;
        }
        t_s
    }

    /// Time for a command given now: never before anything already evaluated.
    pub(crate) fn command_time(&mut self, now_s: f64) -> f64 {
        self.seen(now_s.max(self.last_t_s))
    }

    /// The gyro sample ending at `t_s` and the gyro's true temperature then. Each sample is
    /// computed once, in order; asking again for a recent one returns the same values. `None`
    /// for a sample too old to be remembered (a consumer more than [`GYRO_RECENT`] samples
    /// behind the others).
    #[inline]
    pub(crate) fn gyro_sample(&mut self, t_s: f64) -> Option<(GyroTerms, f64)> {
        let key = (t_s * 1e9).round() as u64;
        match self.gyro_recent.back() {
            Some(&(last, ..)) if key <= last => {
                return self
                    .gyro_recent
                    .iter()
                    .rev()
                    .find(|(k, ..)| *k == key)
                    .map(|&(_, terms, temp)| (terms, temp));
            }
            _ => {}
        }
        self.seen(t_s);
        // A gyro whose time tags are late by δ reports at t the motion up to t − δ.
        let angle = self.table.true_angle(t_s - self.gyro.effects().offset_s());
        let temp = self.chamber.state(t_s).payload_c;
        let terms = self.gyro.sample(t_s, angle, temp);
        if self.gyro_recent.len() == GYRO_RECENT {
            self.gyro_recent.pop_front();
        }
        self.gyro_recent.push_back((key, terms, temp));
        Some((terms, temp))
    }
}

/// How many recent gyro samples the world remembers for consumers that lag behind.
pub(crate) const GYRO_RECENT: usize = 8192;

/// Shared handle on the world.
pub(crate) type SharedWorld = Arc<Mutex<World>>;

pub(crate) fn lock(w: &SharedWorld) -> MutexGuard<'_, World> {
    // A poisoned lock means a panic elsewhere while holding it; every update of the world is a
    // single assignment of fully computed values, so its state is still consistent.
    w.lock().unwrap_or_else(|p| p.into_inner())
}

/// Read-only view of the simulation's truth, for tests and for recording what the devices do
/// not report (the true table angle, the gyro's true temperature).
#[derive(Clone)]
pub struct Truth {
    pub(crate) world: SharedWorld,
}

impl Truth {
    /// The table's true state at bench time `t`.
    pub fn table(&self, t: Duration) -> TableState {
        lock(&self.world).table.state(t.as_secs_f64())
    }

    /// The chamber's true thermal state at bench time `t`; `payload_c` is the gyro's true
    /// temperature.
    pub fn thermal(&self, t: Duration) -> ThermalState {
        lock(&self.world).chamber.state(t.as_secs_f64())
    }
}
