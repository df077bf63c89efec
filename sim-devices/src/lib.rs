//! Simulators of the bench devices: an in-process simulated bench whose rate table, climatic
//! chamber and FOG share one physics world ([`bench_physics`]).
//!
//! The world is evaluated in closed form at the bench time each device call asks about (the
//! clock's `now`, or the gyro's sample instant), so a simulated run costs a few hundred
//! nanoseconds per device call whatever the time step, and gives the same samples for the same
//! seed and commands however the calls interleave.
//!
//! ```
//! use std::sync::Arc;
//! use bench_drivers::clock::{run_virtual, VirtualClock};
//! use bench_drivers::{Gyro, RateTable};
//! use bench_physics::units::{DEG, DEG_PER_MIN};
//! use bench_sim::{SimBench, SimConfig};
//!
//! let clock = VirtualClock::new();
//! let mut bench = SimBench::new(SimConfig::default(), Arc::new(clock.clone())).expect("valid config");
//! let mean = run_virtual(&clock, |_| async move {
//!     bench.table.set_rate(10.0 * DEG_PER_MIN, 1.0 * DEG).await.expect("accepted");
//!     let mut sum = 0.0;
//!     for _ in 0..200 {
//!         sum += bench.gyro.next_sample().await.expect("sample").rate_rad_s;
//!     }
//!     sum / 200.0
//! })
//! .expect("no deadlock");
//! assert!((mean - 10.0 * DEG_PER_MIN).abs() < 1e-4);
//! ```

mod config;
mod devices;
pub mod faults;
pub mod ports;
pub mod serve;
mod world;

use std::sync::{Arc, Mutex};

use bench_drivers::Clock;

pub use config::{default_infos, GyroParams, SimConfig, SimConfigError, SimInfos};
pub use devices::{SimChamber, SimGyro, SimTable};
pub use world::Truth;

/// A simulated bench: three devices sharing one physics world.
pub struct SimBench {
    /// The rate table.
    pub table: SimTable,
    /// The climatic chamber.
    pub chamber: SimChamber,
    /// The gyro.
    pub gyro: SimGyro,
    /// The simulation's truth.
    pub truth: Truth,
}

impl SimBench {
    /// Build the bench from `config` (checked with [`SimConfig::validate`]) on `clock`. The
    /// world starts at bench time 0: table at rest at angle 0, chamber and gyro at
    /// `initial_temp_c`, target = set point = that temperature.
    pub fn new(config: SimConfig, clock: Arc<dyn Clock>) -> Result<Self, SimConfigError> {
        config.validate()?;
        let infos = config.infos();
        let world = Arc::new(Mutex::new(world::World::new(&config)));
        Ok(Self {
            table: SimTable { world: world.clone(), clock: clock.clone(), info: infos.table },
            chamber: SimChamber { world: world.clone(), clock: clock.clone(), info: infos.chamber },
            gyro: SimGyro {
                world: world.clone(),
                clock,
                info: infos.gyro,
                rate_hz: config.gyro_sample_rate_hz,
                base_ns: 0,
                since_base: 0,
                seq: 0,
            },
            truth: Truth { world },
        })
    }

    /// The three devices, for moving into the orchestrator.
    pub fn into_parts(self) -> (SimTable, SimChamber, SimGyro) {
        (self.table, self.chamber, self.gyro)
    }
}
