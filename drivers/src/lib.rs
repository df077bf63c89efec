//! Device traits for the FOG calibration bench, the clock every part of a run shares, and the
//! error kinds that let the orchestrator decide between retry and abort.
//!
//! A simulator, a real driver and a recording replay all implement the same three traits:
//! [`RateTable`], [`Chamber`] and [`Gyro`]. Units are SI (rad, rad/s, s) except temperatures,
//! which are °C.
//!
//! ```
//! use bench_drivers::{ErrorKind, DeviceError};
//! let e = DeviceError::new(ErrorKind::Timeout, "no reply to `PRV 1,?` within 200 ms");
//! assert!(e.kind().is_transient());
//! ```

pub mod chamber;
pub mod clock;
pub mod error;
pub mod gyro;
pub mod protocol;
pub mod real;
pub mod table;
pub mod transport;

pub use chamber::{Chamber, ChamberCapabilities, ChamberReading};
pub use clock::{BenchTime, Clock, HeldClock, SystemClock, VirtualClock};
pub use error::{DeviceError, DeviceResult, ErrorKind};
pub use gyro::{Gyro, GyroCapabilities, GyroSample};
pub use table::{RateTable, TableCapabilities, TableMode, TableReading};

use serde::{Deserialize, Serialize};

/// What a device is and what it can do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeviceInfo<C> {
    /// Make and model, e.g. `Actidyn ST1300 (simulated)`.
    pub model: String,
    /// Driver and transport, e.g. `sim`, `actidyn/tcp 127.0.0.1:62000`.
    pub driver: String,
    /// Capabilities scenarios are checked against.
    pub capabilities: C,
}
