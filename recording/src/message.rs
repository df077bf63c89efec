//! One type per channel of the contract, used both to write and to read, plus the step event,
//! the run's outcome and the log level. Field names on the wire are the contract's; in Rust they
//! carry their units.

use std::fmt;

use serde::{Deserialize, Serialize};

/// `/gyro/rate` body (`bench.GyroSample`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GyroMsg {
    /// Mean angular rate about the sensing axis over the sample interval ending at `log_time`,
    /// rad/s.
    #[serde(rename = "rate")]
    pub rate_rad_s: f64,
    /// The gyro's internal temperature, °C; `None` (JSON `null`) if it has no sensor.
    #[serde(rename = "temperature", default)]
    pub temperature_c: Option<f64>,
    /// The device's own sample counter.
    pub seq: u64,
    /// Status bits, 0 = valid ([`crate::status::gyro`]).
    pub status: u32,
}

/// `/table/state` body (`bench.TableState`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TableMsg {
    /// Axis angle, rad, unwrapped (keeps counting past 2π), positive counter-clockwise seen from
    /// above.
    #[serde(rename = "angle")]
    pub angle_rad: f64,
    /// Measured rate, rad/s.
    #[serde(rename = "rate")]
    pub rate_rad_s: f64,
    /// Commanded rate, rad/s.
    #[serde(rename = "rate_command")]
    pub rate_command_rad_s: f64,
    /// Status bits, 0 = ok ([`crate::status::table`]).
    pub status: u32,
}

/// `/chamber/state` body (`bench.ChamberState`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ChamberMsg {
    /// Chamber air temperature (the controller's process value), °C.
    #[serde(rename = "temperature")]
    pub temperature_c: f64,
    /// The controller's working set point, °C.
    #[serde(rename = "setpoint")]
    pub setpoint_c: f64,
    /// Status bits, 0 = ok ([`crate::status::chamber`]).
    pub status: u32,
}

/// `/bench/step` body (`bench.Step`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct StepMsg {
    /// Step index in the scenario.
    pub index: u64,
    /// Step name (`record`, `wait_temperature`, …).
    pub name: String,
    /// Start, end or abort.
    pub event: StepEvent,
    /// Label; one starting with `record` marks a window whose data a calibration uses.
    pub label: String,
}

impl StepMsg {
    /// Whether the step's label marks a calibration window (starts with `record`).
    pub fn is_record(&self) -> bool {
        is_record_label(&self.label)
    }
}

/// A step whose label starts with this marks data a calibration uses.
pub const RECORD_LABEL_PREFIX: &str = "record";

/// Whether a step's `label` marks a calibration window (starts with [`RECORD_LABEL_PREFIX`]).
pub fn is_record_label(label: &str) -> bool {
    label.starts_with(RECORD_LABEL_PREFIX)
}

/// A step event (`bench.Step` `event`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StepEvent {
    /// The step started.
    Start,
    /// The step ended normally.
    End,
    /// The step was aborted.
    Abort,
}

impl StepEvent {
    /// `start`, `end` or `abort`.
    pub fn as_str(self) -> &'static str {
        match self {
            StepEvent::Start => "start",
            StepEvent::End => "end",
            StepEvent::Abort => "abort",
        }
    }
}

/// How the run ended (`bench.run` `outcome`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// `completed`.
    Completed,
    /// `aborted: <reason>`.
    Aborted(String),
}

impl Outcome {
    /// Parse the contract's text; `None` for anything else.
    pub fn parse(text: &str) -> Option<Self> {
        if text == "completed" {
            Some(Outcome::Completed)
        } else {
            text.strip_prefix("aborted:").map(|r| Outcome::Aborted(r.trim_start().to_string()))
        }
    }
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Outcome::Completed => f.write_str("completed"),
            Outcome::Aborted(reason) => write!(f, "aborted: {reason}"),
        }
    }
}

/// Log level of `foxglove.Log` (written as its number).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum LogLevel {
    /// 1.
    Debug = 1,
    /// 2.
    Info = 2,
    /// 3.
    Warning = 3,
    /// 4.
    Error = 4,
    /// 5.
    Fatal = 5,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodies_use_the_contracts_field_names_in_its_order() {
        let g = GyroMsg { rate_rad_s: 1e-5, temperature_c: None, seq: 3, status: 0 };
        assert_eq!(
            serde_json::to_string(&g).ok().as_deref(),
            Some(r#"{"rate":0.00001,"temperature":null,"seq":3,"status":0}"#)
        );
        let t = TableMsg { angle_rad: 1.5, rate_rad_s: -0.1, rate_command_rad_s: -0.1, status: 8 };
        assert_eq!(
            serde_json::to_string(&t).ok().as_deref(),
            Some(r#"{"angle":1.5,"rate":-0.1,"rate_command":-0.1,"status":8}"#)
        );
        let c = ChamberMsg { temperature_c: 20.5, setpoint_c: 21.0, status: 2 };
        assert_eq!(
            serde_json::to_string(&c).ok().as_deref(),
            Some(r#"{"temperature":20.5,"setpoint":21.0,"status":2}"#)
        );
        let s =
            StepMsg { index: 4, name: "record".into(), event: StepEvent::End, label: "x".into() };
        assert_eq!(
            serde_json::to_string(&s).ok().as_deref(),
            Some(r#"{"index":4,"name":"record","event":"end","label":"x"}"#)
        );
    }

    #[test]
    fn outcomes_read_back_from_their_text() {
        for o in [Outcome::Completed, Outcome::Aborted("table stalled".into())] {
            assert_eq!(Outcome::parse(&o.to_string()), Some(o));
        }
        assert_eq!(Outcome::parse("finished"), None);
    }
}

/// What a recording's `bench.gyro_model` is to its data (`bench.run` key `gyro_model_role`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModelRole {
    /// A simulator produced the gyro's output from this model: it is the data's truth.
    Simulation,
    /// The model the lab believes in (a datasheet, an earlier calibration), or none given:
    /// a starting point, not the truth. A recording that does not say is read as this.
    #[default]
    Nominal,
}

impl ModelRole {
    /// Text in `bench.run`.
    pub fn key(self) -> &'static str {
        match self {
            ModelRole::Simulation => "simulation",
            ModelRole::Nominal => "nominal",
        }
    }

    /// The role `bench.run`'s text names; anything but `simulation` is nominal.
    pub fn from_key(text: Option<&str>) -> ModelRole {
        match text {
            Some("simulation") => ModelRole::Simulation,
            _ => ModelRole::Nominal,
        }
    }
}
