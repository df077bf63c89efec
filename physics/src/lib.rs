//! Physics of the FOG thermal-calibration bench.
//!
//! One place for every physical model bench uses, shared by the simulators (`bench-sim`) and the
//! analysis: units, Earth rate, the gyro error model and output, noise processes, rate-table and
//! chamber dynamics, first-order lags and the Allan deviation. Pure: no I/O, deterministic for
//! a seed.
//!
//! ```
//! use bench_physics::units::DEG_PER_MIN;
//! let seed_table_rate_rad_s = 10.0 * DEG_PER_MIN;
//! assert!((seed_table_rate_rad_s - 2.9089e-3).abs() < 1e-7);
//! ```

pub mod allan;
pub mod chamber;
pub mod earth;
pub mod effects;
pub mod gyro;
pub mod gyro_model;
pub mod lag;
pub mod noise;
pub mod table;
pub mod units;

pub use gyro_model::{GyroModel, ModelKey};
