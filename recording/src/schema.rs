//! Topics, schema names and JSON Schema documents of recording format version 1
//! (`FORMAT.md`). Shared by the writer ([`crate::writer`]) and the reader
//! ([`crate::reader`]).

/// Value of `format_version` in the `bench.run` metadata record.
pub const FORMAT_VERSION: &str = "1";
/// Message encoding of every channel bench writes.
pub const MESSAGE_ENCODING: &str = "json";
/// Schema encoding of every schema bench writes.
pub const SCHEMA_ENCODING: &str = "jsonschema";

/// Gyro samples.
pub const TOPIC_GYRO: &str = "/gyro/rate";
/// Rate-table state.
pub const TOPIC_TABLE: &str = "/table/state";
/// Chamber state.
pub const TOPIC_CHAMBER: &str = "/chamber/state";
/// Step events.
pub const TOPIC_STEP: &str = "/bench/step";
/// Log messages (optional channel).
pub const TOPIC_LOG: &str = "/log";

/// Schema name of [`TOPIC_GYRO`].
pub const SCHEMA_GYRO: &str = "bench.GyroSample";
/// Schema name of [`TOPIC_TABLE`].
pub const SCHEMA_TABLE: &str = "bench.TableState";
/// Schema name of [`TOPIC_CHAMBER`].
pub const SCHEMA_CHAMBER: &str = "bench.ChamberState";
/// Schema name of [`TOPIC_STEP`].
pub const SCHEMA_STEP: &str = "bench.Step";
/// Schema name of [`TOPIC_LOG`] (Foxglove's well-known log schema).
pub const SCHEMA_LOG: &str = "foxglove.Log";

/// Metadata record with format version, start time, software and outcome.
pub const META_RUN: &str = "bench.run";
/// `bench.run` key saying what `bench.gyro_model` is to the data ([`crate::ModelRole`]).
pub const RUN_KEY_MODEL_ROLE: &str = "gyro_model_role";
/// Metadata record describing the bench's site.
pub const META_SITE: &str = "bench.site";
/// Metadata record with the scenario's name and text.
pub const META_SCENARIO: &str = "bench.scenario";
/// Metadata record with the nominal gyro error model.
pub const META_GYRO_MODEL: &str = "bench.gyro_model";
/// Metadata record (optional): the unit under test, operator and test station.
pub const META_STATION: &str = "bench.station";
/// Metadata record (optional): acceptance limits per coefficient.
pub const META_ACCEPTANCE: &str = "bench.acceptance";

/// Media type of the scenario and configuration attachments.
pub const MEDIA_TYPE_TOML: &str = "application/toml";

/// JSON Schema of `bench.GyroSample`.
pub const GYRO_SCHEMA_JSON: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "bench.GyroSample",
  "description": "One gyro sample: mean angular rate about the sensing axis over the sample interval ending at log_time.",
  "type": "object",
  "properties": {
    "rate": { "type": "number", "description": "Mean angular rate about the sensing axis, rad/s" },
    "temperature": { "type": ["number", "null"], "description": "Gyro internal temperature, C; null if the gyro has no sensor" },
    "seq": { "type": "integer", "minimum": 0, "description": "The device's own sample counter" },
    "status": { "type": "integer", "minimum": 0, "description": "Status bits, 0 = valid (bit 0 invalid, bit 1 counter gap, bit 2 built-in-test failure, bit 3 after a corrupt frame)" }
  },
  "required": ["rate", "temperature", "seq", "status"]
}"#;

/// JSON Schema of `bench.TableState`.
pub const TABLE_SCHEMA_JSON: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "bench.TableState",
  "description": "One reading of the rate table's axis.",
  "type": "object",
  "properties": {
    "angle": { "type": "number", "description": "Axis angle, rad, unwrapped, positive counter-clockwise seen from above" },
    "rate": { "type": "number", "description": "Measured axis rate, rad/s" },
    "rate_command": { "type": "number", "description": "Commanded axis rate, rad/s" },
    "status": { "type": "integer", "minimum": 0, "description": "Status bits, 0 = ok (bit 0 drive off, bit 1 alarm, bit 2 interlock, bit 3 slewing)" }
  },
  "required": ["angle", "rate", "rate_command", "status"]
}"#;

/// JSON Schema of `bench.ChamberState`.
pub const CHAMBER_SCHEMA_JSON: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "bench.ChamberState",
  "description": "One reading of the climatic chamber's controller.",
  "type": "object",
  "properties": {
    "temperature": { "type": "number", "description": "Chamber air temperature (process value), C" },
    "setpoint": { "type": "number", "description": "The controller's working set point, C" },
    "status": { "type": "integer", "minimum": 0, "description": "Status bits, 0 = ok (bit 0 alarm, bit 1 ramping, bit 2 output saturated)" }
  },
  "required": ["temperature", "setpoint", "status"]
}"#;

/// JSON Schema of `bench.Step`.
pub const STEP_SCHEMA_JSON: &str = r#"{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "bench.Step",
  "description": "Start, end or abort of a scenario step. A label starting with 'record' marks data a calibration uses.",
  "type": "object",
  "properties": {
    "index": { "type": "integer", "minimum": 0, "description": "Index of the step in the scenario" },
    "name": { "type": "string", "description": "Name of the step" },
    "event": { "type": "string", "enum": ["start", "end", "abort"] },
    "label": { "type": "string", "description": "Label of the step, may be empty" }
  },
  "required": ["index", "name", "event", "label"]
}"#;

/// JSON Schema of `foxglove.Log`, as published by Foxglove (foxglove-sdk
/// `schemas/jsonschema/Log.json`).
pub const LOG_SCHEMA_JSON: &str = r#"{
  "title": "foxglove.Log",
  "description": "A log message",
  "$comment": "Generated by https://github.com/foxglove/foxglove-sdk",
  "type": "object",
  "properties": {
    "timestamp": {
      "type": "object",
      "title": "time",
      "properties": {
        "sec": { "type": "integer", "minimum": 0 },
        "nsec": { "type": "integer", "minimum": 0, "maximum": 999999999 }
      },
      "description": "Timestamp of log message"
    },
    "level": {
      "title": "foxglove.LogLevel",
      "description": "Log level",
      "oneOf": [
        { "title": "UNKNOWN", "const": 0 },
        { "title": "DEBUG", "const": 1 },
        { "title": "INFO", "const": 2 },
        { "title": "WARNING", "const": 3 },
        { "title": "ERROR", "const": 4 },
        { "title": "FATAL", "const": 5 }
      ]
    },
    "message": { "type": "string", "description": "Log message" },
    "name": { "type": "string", "description": "Process or node name" },
    "file": { "type": "string", "description": "Filename" },
    "line": { "type": "integer", "minimum": 0, "maximum": 4294967295, "description": "Line number in the file" }
  }
}"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_are_json_objects_titled_with_their_schema_name() {
        for (name, doc) in [
            (SCHEMA_GYRO, GYRO_SCHEMA_JSON),
            (SCHEMA_TABLE, TABLE_SCHEMA_JSON),
            (SCHEMA_CHAMBER, CHAMBER_SCHEMA_JSON),
            (SCHEMA_STEP, STEP_SCHEMA_JSON),
            (SCHEMA_LOG, LOG_SCHEMA_JSON),
        ] {
            let v: serde_json::Value = serde_json::from_str(doc).expect("schema parses");
            assert_eq!(v["title"], name);
            assert_eq!(v["type"], "object");
            assert!(v["properties"].is_object());
        }
    }
}
