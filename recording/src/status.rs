//! Status words recorded in the `status` fields of the recording (0 = ok / valid).

/// Gyro sample status bits (`/gyro/rate` `status`).
pub mod gyro {
    /// The device flagged the sample invalid.
    pub const INVALID: u32 = 1 << 0;
    /// The device's sample counter skipped: samples were lost before this one.
    pub const SEQ_GAP: u32 = 1 << 1;
    /// The device reports a built-in-test failure.
    pub const BIT_FAIL: u32 = 1 << 2;
    /// The sample was received after a corrupt frame was skipped.
    pub const AFTER_CORRUPT: u32 = 1 << 3;
}

/// Rate-table status bits (`/table/state` `status`).
pub mod table {
    /// Drive is off.
    pub const DRIVE_OFF: u32 = 1 << 0;
    /// Controller reports an alarm.
    pub const ALARM: u32 = 1 << 1;
    /// Interlock open.
    pub const INTERLOCK: u32 = 1 << 2;
    /// Rate not yet settled on the command (accelerating).
    pub const SLEWING: u32 = 1 << 3;
}

/// Chamber status bits (`/chamber/state` `status`).
pub mod chamber {
    /// Controller reports an alarm (sensor break, over-temperature).
    pub const ALARM: u32 = 1 << 0;
    /// Working set point is ramping toward the target.
    pub const RAMPING: u32 = 1 << 1;
    /// Heating or cooling output is saturated.
    pub const SATURATED: u32 = 1 << 2;
}
