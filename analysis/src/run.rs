//! A whole run as arrays: what the analyses read from a recording, times in seconds from the
//! recording's time zero.

/// How a step's span ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepEnd {
    /// Its `end` event.
    End,
    /// Its `abort` event.
    Abort,
    /// No event: the recording stops first (a file cut short); the span runs to the last gyro
    /// sample.
    Missing,
}

/// A step of the run: a span of time with its label (for locating structure).
#[derive(Debug, Clone, PartialEq)]
pub struct StepSpan {
    /// Step index in the scenario.
    pub index: u64,
    /// Step name (`record`, `wait_temperature`, …).
    pub name: String,
    /// Label (may be empty).
    pub label: String,
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// How it ended.
    pub ended: StepEnd,
}

/// Everything the analyses read from a recording, as arrays (times in s from the recording's
/// time zero).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunSeries {
    /// Gyro sample times (end of each sample interval), s; valid samples only, increasing.
    pub gyro_time_s: Vec<f64>,
    /// Gyro output, rad/s.
    pub gyro_rate_rad_s: Vec<f64>,
    /// Where the loader averaged the gyro in blocks, the full-rate Allan variance's sums below
    /// the block, one entry per sample above ([`crate::allan_sub`]); `None` at full rate.
    pub gyro_sub_block: Option<crate::allan_sub::SubBlockSums>,
    /// The gyro's own temperature, °C, if it reports one.
    pub gyro_temp_c: Option<Vec<f64>>,
    /// Table sample times, s.
    pub table_time_s: Vec<f64>,
    /// Table angle, rad (unwrapped, positive counter-clockwise).
    pub table_angle_rad: Vec<f64>,
    /// Commanded table rate, rad/s.
    pub table_rate_command_rad_s: Vec<f64>,
    /// Chamber sample times, s.
    pub chamber_time_s: Vec<f64>,
    /// Chamber air temperature, °C.
    pub chamber_temp_c: Vec<f64>,
    /// The scenario's steps.
    pub steps: Vec<StepSpan>,
    /// Site latitude, degrees north, if the recording has one.
    pub latitude_deg: Option<f64>,
    /// Sensing axis up (along the table's counter-clockwise axis).
    pub axis_up: bool,
}
