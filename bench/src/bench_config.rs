//! Bench configuration: which driver and transport reaches each device, and where the bench
//! stands. Documented in `docs/bench-config.md`.
//!
//! ```toml
//! [site]
//! latitude_deg = 43.56
//!
//! [table]
//! dialect = "actidyn"
//! endpoint = { tcp = { addr = "192.168.10.20:62000" } }
//!
//! [chamber]
//! protocol = "modbus"          # the default, the only protocol so far
//! endpoint = { serial = { path = "/dev/ttyUSB0", baud = 9600 } }
//! unit_id = 1
//! map = "watlow_f4t"
//!
//! [gyro]
//! driver = "can"
//! transport = { kind = "slcan", serial = { path = "/dev/ttyACM0", baud = 115200 } }
//! ```
//!
//! A config without `[table]`, `[chamber]` and `[gyro]` describes the embedded simulated
//! bench: `bench run --bench` then runs the in-process simulators in virtual time, at the
//! config's site and with its `[simulation]` settings (effects beyond the gyro's model, which
//! the recording conceals). `bench sim serve --bench` takes the same settings.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use bench_drivers::real::chamber::{ModbusChamber, ModbusChamberConfig};
use bench_drivers::real::gyro_can::{CanGyro, CanGyroConfig};
use bench_drivers::real::gyro_kvh::{Dsp3000Config, Dsp3000Gyro, Kvh1750Config, Kvh1750Gyro};
use bench_drivers::real::table::{RateTableDriver, TableDriverConfig};
use bench_drivers::{Chamber, Clock, DeviceError, Gyro};
use bench_physics::effects::Effects;
use serde::{Deserialize, Serialize};

use crate::run::{Devices, FaultPolicy};
use crate::scenario::Capabilities;
use bench_recording::{Axis, Site};

/// A bench configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchConfig {
    /// Where the bench stands; overrides the scenario's `[site]` (the lab knows where it is).
    #[serde(default)]
    pub site: Option<SiteConfig>,
    /// Settings of bench itself.
    #[serde(default)]
    pub bench: BenchSettings,
    /// The rate table's driver; absent (with `chamber` and `gyro`) for the embedded simulated
    /// bench.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<TableDriverConfig>,
    /// The chamber's driver, by protocol.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chamber: Option<ChamberConfig>,
    /// The gyro's driver.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro: Option<GyroConfig>,
    /// Settings of the simulated bench (embedded, or served by `bench sim serve --bench`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<SimulationSettings>,
    /// The test station (`bench.station`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub station: Option<StationConfig>,
    /// Acceptance limits on |coefficient|, SI, per coefficient key (`bench.acceptance`).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub acceptance: std::collections::BTreeMap<String, f64>,
    /// The lab's own limits, for `bench validate --bench` without connecting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits: Option<LimitsConfig>,
}

/// `[station]`: which test station and who runs it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StationConfig {
    /// The station's name.
    #[serde(default)]
    pub station: Option<String>,
    /// The operator.
    #[serde(default)]
    pub operator: Option<String>,
}

/// `[limits]`: the lab devices' limits, units in the key names; each absent key is the
/// simulated bench's.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsConfig {
    /// Largest table rate, °/s.
    #[serde(default)]
    pub table_max_rate_deg_s: Option<f64>,
    /// Largest table acceleration, °/s².
    #[serde(default)]
    pub table_max_accel_deg_s2: Option<f64>,
    /// Lowest chamber temperature, °C.
    #[serde(default)]
    pub chamber_min_temp_c: Option<f64>,
    /// Highest chamber temperature, °C.
    #[serde(default)]
    pub chamber_max_temp_c: Option<f64>,
    /// Fastest heating ramp, °C/min.
    #[serde(default)]
    pub chamber_max_heat_rate_c_min: Option<f64>,
    /// Fastest cooling ramp, °C/min.
    #[serde(default)]
    pub chamber_max_cool_rate_c_min: Option<f64>,
    /// The gyro's output rates, Hz.
    #[serde(default)]
    pub gyro_sample_rates_hz: Option<Vec<f64>>,
    /// The gyro's lowest operating temperature, °C.
    #[serde(default)]
    pub gyro_min_temp_c: Option<f64>,
    /// The gyro's highest operating temperature, °C.
    #[serde(default)]
    pub gyro_max_temp_c: Option<f64>,
    /// Whether the gyro reports its temperature.
    #[serde(default)]
    pub gyro_has_temperature: Option<bool>,
}

impl LimitsConfig {
    /// Every value that is not a usable limit: (problem, key).
    fn problems(&self) -> Vec<(String, &'static str)> {
        let mut out = Vec::new();
        for (key, v) in [
            ("table_max_rate_deg_s", self.table_max_rate_deg_s),
            ("table_max_accel_deg_s2", self.table_max_accel_deg_s2),
            ("chamber_max_heat_rate_c_min", self.chamber_max_heat_rate_c_min),
            ("chamber_max_cool_rate_c_min", self.chamber_max_cool_rate_c_min),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    out.push((format!("must be a positive number, got {v}"), key));
                }
            }
        }
        for (key, v) in [
            ("chamber_min_temp_c", self.chamber_min_temp_c),
            ("chamber_max_temp_c", self.chamber_max_temp_c),
            ("gyro_min_temp_c", self.gyro_min_temp_c),
            ("gyro_max_temp_c", self.gyro_max_temp_c),
        ] {
            if let Some(v) = v {
                if !v.is_finite() || v < -273.15 {
                    out.push((format!("must be a temperature above -273.15 °C, got {v}"), key));
                }
            }
        }
        if let (Some(lo), Some(hi)) = (self.chamber_min_temp_c, self.chamber_max_temp_c) {
            if lo >= hi {
                out.push((
                    format!("must be above chamber_min_temp_c ({lo}), got {hi}"),
                    "chamber_max_temp_c",
                ));
            }
        }
        if let Some(r) = &self.gyro_sample_rates_hz {
            if r.is_empty() || r.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                out.push(("must list positive rates".to_string(), "gyro_sample_rates_hz"));
            }
        }
        out
    }
}

/// `[simulation]`: settings that only a simulated bench uses.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSettings {
    /// `[simulation.effects]`: effects beyond the gyro's model that the simulated gyro shows,
    /// each replacing or adding to the scenario's truth effects (concealed: not recorded).
    #[serde(default)]
    pub effects: Effects,
}

/// `[bench]`: settings of the controller itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BenchSettings {
    /// Bench time per wall time (default 1). Only for simulators behind virtual ports, which
    /// run faster than real time (`bench sim serve --time-scale`): both sides must agree.
    pub time_scale: f64,
    /// Consecutive failed reads of one device (each after the driver's own retries) before the
    /// run aborts (default 5).
    pub max_consecutive_errors: u32,
    /// A stream with no good reading for this long, in bench seconds, aborts the run
    /// (default 30).
    pub stale_after_s: f64,
    /// How long each safe-state command may take, bench seconds (default 10).
    pub safe_state_timeout_s: f64,
}

impl Default for BenchSettings {
    fn default() -> Self {
        let p = FaultPolicy::default();
        Self {
            time_scale: 1.0,
            max_consecutive_errors: p.max_consecutive_errors,
            stale_after_s: p.stale_after.as_secs_f64(),
            safe_state_timeout_s: p.safe_state_timeout.as_secs_f64(),
        }
    }
}

impl BenchSettings {
    /// The orchestrator's fault policy these settings give.
    pub fn policy(&self) -> FaultPolicy {
        FaultPolicy {
            max_consecutive_errors: self.max_consecutive_errors,
            stale_after: std::time::Duration::from_secs_f64(self.stale_after_s),
            safe_state_timeout: std::time::Duration::from_secs_f64(self.safe_state_timeout_s),
        }
    }
}

/// `[site]` of a bench config.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteConfig {
    /// Geodetic latitude, degrees north.
    pub latitude_deg: f64,
    /// Longitude, degrees east.
    #[serde(default)]
    pub longitude_deg: Option<f64>,
    /// Height, m.
    #[serde(default)]
    pub height_m: Option<f64>,
    /// `up` (default) or `down`: where the gyro's sensing axis points.
    #[serde(default = "default_axis")]
    pub axis: String,
}

fn default_axis() -> String {
    "up".into()
}

/// The gyro's driver, chosen by `driver`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "snake_case")]
pub enum GyroConfig {
    /// bench's CAN frame set over SLCAN or socketcan.
    Can(CanGyroConfig),
    /// KVH 1750/1775 format A over serial.
    Kvh1750(Kvh1750Config),
    /// KVH DSP-3000 over serial.
    Dsp3000(Dsp3000Config),
}

/// The chamber's driver, chosen by `protocol`: one variant per protocol, each with its own
/// settings, beside the others as the gyro's drivers are ([`GyroConfig`]). `protocol` may be
/// left out for `modbus`, the only one so far (configs written before there was a choice name
/// none).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "protocol", rename_all = "snake_case")]
pub enum ChamberConfig {
    /// A controller over Modbus RTU or TCP (Watlow F4/F4T, Eurotherm 3216, a custom map).
    Modbus(ModbusChamberConfig),
}

impl ChamberConfig {
    /// The driver's own checks of its settings (what `connect` would refuse): (key, problem)
    /// with the key to locate it at (`None`: the section).
    pub fn problems(&self) -> Vec<(Option<&'static str>, String)> {
        match self {
            ChamberConfig::Modbus(c) => {
                let mut out: Vec<(Option<&'static str>, String)> = c
                    .given_twice()
                    .into_iter()
                    .map(|(s, ms)| {
                        (
                            Some(ms),
                            format!("`{s}` and the older `{ms}` give the same setting: keep `{s}`"),
                        )
                    })
                    .collect();
                if out.is_empty() {
                    if let Err(e) = c.validate() {
                        out.push((None, e.message().to_owned()));
                    } else if let Err(e) = c.map.map().validate() {
                        out.push((Some("map"), format!("map: {e}")));
                    }
                }
                out
            }
        }
    }

    /// Connect to the chamber (failing if it cannot be reached or does not answer as
    /// expected).
    pub async fn connect(&self, clock: Arc<dyn Clock>) -> Result<Box<dyn Chamber>, DeviceError> {
        match self {
            ChamberConfig::Modbus(c) => {
                Ok(Box::new(ModbusChamber::connect(c.clone(), clock).await?))
            }
        }
    }
}

/// A protocol's name in `[chamber] protocol`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ChamberProtocol {
    Modbus,
}

impl<'de> Deserialize<'de> for ChamberConfig {
    /// `protocol` (default `modbus`) picks the variant; every other key is the variant's, read
    /// straight from the file so that each error keeps its line and column.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = ChamberConfig;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a [chamber] table")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> Result<ChamberConfig, A::Error> {
                let mut keys = WithoutProtocol { inner: map, protocol: None };
                let c = ModbusChamberConfig::deserialize(
                    serde::de::value::MapAccessDeserializer::new(&mut keys),
                )?;
                match keys.protocol.unwrap_or(ChamberProtocol::Modbus) {
                    ChamberProtocol::Modbus => Ok(ChamberConfig::Modbus(c)),
                }
            }
        }
        d.deserialize_map(V)
    }
}

/// A table's keys without `protocol`, which is kept aside.
struct WithoutProtocol<A> {
    inner: A,
    protocol: Option<ChamberProtocol>,
}

/// A key: `protocol`, or another read by `seed` (taken only then, so the next key can use it).
struct KeySeed<'s, K>(&'s mut Option<K>);

enum Key<T> {
    Protocol,
    Other(T),
}

impl<'de, K: serde::de::DeserializeSeed<'de>> serde::de::DeserializeSeed<'de> for KeySeed<'_, K> {
    type Value = Key<K::Value>;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        struct V<'s, K>(&'s mut Option<K>);
        impl<'de, K: serde::de::DeserializeSeed<'de>> serde::de::Visitor<'de> for V<'_, K> {
            type Value = Key<K::Value>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a key")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Self::Value, E> {
                if v == "protocol" {
                    return Ok(Key::Protocol);
                }
                let seed = self.0.take().ok_or_else(|| E::custom("key read twice"))?;
                seed.deserialize(serde::de::value::StrDeserializer::<E>::new(v)).map(Key::Other)
            }
        }
        d.deserialize_identifier(V(self.0))
    }
}

impl<'de, A: serde::de::MapAccess<'de>> serde::de::MapAccess<'de> for WithoutProtocol<A> {
    type Error = A::Error;
    fn next_key_seed<K: serde::de::DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, A::Error> {
        let mut seed = Some(seed);
        loop {
            match self.inner.next_key_seed(KeySeed(&mut seed))? {
                None => return Ok(None),
                Some(Key::Other(k)) => return Ok(Some(k)),
                // Checked where it stands: an unknown protocol is an error at its value.
                Some(Key::Protocol) => self.protocol = Some(self.inner.next_value()?),
            }
        }
    }
    fn next_value_seed<V: serde::de::DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, A::Error> {
        self.inner.next_value_seed(seed)
    }
}

/// A bench config that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read bench config {}: {source}", path.display())]
    Io {
        /// Path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file is not a valid bench config.
    #[error("{file}:{line}:{column}: {message}")]
    Invalid {
        /// File name.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Several problems, each located.
    #[error("{}", .0.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"))]
    Several(Vec<ConfigError>),
    /// `connect` on a config without drivers (the embedded simulated bench).
    #[error(
        "the bench config names no drivers ([table], [chamber], [gyro]): it describes the \
         embedded simulated bench"
    )]
    NoDrivers,
    /// A device could not be reached or did not answer as expected.
    #[error("{device}: {source}")]
    Connect {
        /// Which device.
        device: &'static str,
        /// What was tried and what came back.
        source: DeviceError,
    },
}

impl BenchConfig {
    /// Read and parse a bench config file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, &path.display().to_string())
    }

    /// Parse bench config `text`; errors name `file:line:column`. A file that is not valid
    /// TOML or has a wrong key stops at that first error (the TOML reader's); every problem
    /// of the values is listed ([`ConfigError::Several`]).
    pub fn parse(text: &str, file: &str) -> Result<Self, ConfigError> {
        let cfg: Self = toml::from_str(text).map_err(|e| toml_error(text, file, &e))?;
        let mut errors = Vec::new();
        let mut located = Vec::new();
        let mut bad = |path: &[&str], message: String| {
            let at = bench_recording::toml_doc::value_span(text, path).map_or(0, |s| s.start);
            let (line, column) = bench_recording::toml_doc::line_col(text, at);
            errors.push(ConfigError::Invalid { file: file.to_string(), line, column, message });
        };
        if !(cfg.bench.time_scale.is_finite() && cfg.bench.time_scale > 0.0) {
            bad(
                &["bench", "time_scale"],
                format!(
                    "[bench] time_scale must be a positive number, got {}",
                    cfg.bench.time_scale
                ),
            );
        }
        let b = &cfg.bench;
        for (key, v) in
            [("stale_after_s", b.stale_after_s), ("safe_state_timeout_s", b.safe_state_timeout_s)]
        {
            if !(v.is_finite() && v > 0.0 && v < 1e9) {
                bad(
                    &["bench", key],
                    format!("[bench] {key} must be a positive number of seconds, got {v}"),
                );
            }
        }
        if b.max_consecutive_errors == 0 {
            bad(
                &["bench", "max_consecutive_errors"],
                "[bench] max_consecutive_errors must be at least 1".into(),
            );
        }
        let given = [cfg.table.is_some(), cfg.chamber.is_some(), cfg.gyro.is_some()];
        if given.contains(&true) && given.contains(&false) {
            let missing: Vec<&str> = ["[table]", "[chamber]", "[gyro]"]
                .into_iter()
                .zip(given)
                .filter(|(_, g)| !g)
                .map(|(n, _)| n)
                .collect();
            bad(
                &[],
                format!(
                    "give all three device sections [table], [chamber], [gyro] (real drivers), \
                     or none (the embedded simulated bench); missing: {}",
                    missing.join(", ")
                ),
            );
        }
        // The drivers' own checks of their settings, which `connect` makes: a config that
        // would not connect for its values is refused here, at its section.
        if let Some(t) = &cfg.table {
            if let Err(e) = t.validate() {
                bad(&["table"], format!("[table] {}", e.message()));
            }
        }
        for (key, problem) in cfg.chamber.iter().flat_map(ChamberConfig::problems) {
            let path: &[&str] = match key {
                Some(k) => &["chamber", k],
                None => &["chamber"],
            };
            bad(path, format!("[chamber] {problem}"));
        }
        let kvh = match &cfg.gyro {
            Some(GyroConfig::Can(g)) => {
                if let Err(e) = g.validate() {
                    bad(&["gyro"], format!("[gyro] {}", e.message()));
                }
                Vec::new()
            }
            Some(GyroConfig::Kvh1750(g)) => g.problems(),
            Some(GyroConfig::Dsp3000(g)) => g.problems(),
            None => Vec::new(),
        };
        // KVH gyros: every problem at its key (the section when the key is a default).
        for (key, message) in kvh {
            let path: &[&str] =
                if bench_recording::toml_doc::value_span(text, &["gyro", key]).is_some() {
                    &["gyro", key]
                } else {
                    &["gyro"]
                };
            bad(path, format!("[gyro] {message}"));
        }
        if let Some(sim) = &cfg.simulation {
            if let Err((line, column, message)) = bench_recording::effects_toml::check_located(
                &sim.effects,
                text,
                &["simulation", "effects"],
            ) {
                located.push(ConfigError::Invalid {
                    file: file.to_string(),
                    line,
                    column,
                    message,
                });
            }
        }
        if let (Some(site), Some(s)) = (&cfg.site, cfg.site()) {
            for (key, problem) in s.problems() {
                bad(&["site", key], format!("[site] {problem}"));
            }
            if let Err(problem) = Axis::parse(&site.axis) {
                bad(&["site", "axis"], format!("[site] {problem}"));
            }
        }
        for (key, v) in &cfg.acceptance {
            if !crate::plan::ACCEPTANCE_KEYS.contains(&key.as_str()) {
                bad(
                    &["acceptance", key],
                    format!(
                        "[acceptance] unknown coefficient `{key}`; allowed: {}",
                        crate::plan::ACCEPTANCE_KEYS.join(", ")
                    ),
                );
            } else if !(v.is_finite() && *v > 0.0) {
                bad(
                    &["acceptance", key],
                    format!("[acceptance] {key} is a limit on |coefficient|: it must be positive, got {v}"),
                );
            }
        }
        if let Some(l) = &cfg.limits {
            for (problem, path) in l.problems() {
                bad(&["limits", path], format!("[limits] {path} {problem}"));
            }
        }
        errors.extend(located);
        match errors.len() {
            0 => Ok(cfg),
            1 => Err(errors.remove(0)),
            _ => Err(ConfigError::Several(errors)),
        }
    }

    /// The test-station metadata this config gives (`[station]`, `[acceptance]`).
    pub fn station(&self) -> crate::plan::Station {
        let mut s = crate::plan::Station::default();
        if let Some(st) = &self.station {
            for (k, v) in [("station", &st.station), ("operator", &st.operator)] {
                if let Some(v) = v {
                    s.info.insert(k.to_string(), v.clone());
                }
            }
        }
        s.acceptance = self.acceptance.clone();
        s
    }

    /// The capabilities to validate a scenario against without connecting: the simulated
    /// bench's, each replaced by the config's `[limits]` where it gives one; with whether any
    /// limit was given.
    pub fn limits(&self) -> (Capabilities, bool) {
        let mut caps = crate::simulate::capabilities();
        let Some(l) = &self.limits else { return (caps, false) };
        let t = &mut caps.table.capabilities;
        let c = &mut caps.chamber.capabilities;
        let g = &mut caps.gyro.capabilities;
        let deg = bench_physics::units::DEG;
        let set = |v: Option<f64>, to: &mut f64, factor: f64| {
            if let Some(v) = v {
                *to = v * factor;
            }
        };
        set(l.table_max_rate_deg_s, &mut t.max_rate_rad_s, deg);
        set(l.table_max_accel_deg_s2, &mut t.max_accel_rad_s2, deg);
        set(l.chamber_min_temp_c, &mut c.min_temp_c, 1.0);
        set(l.chamber_max_temp_c, &mut c.max_temp_c, 1.0);
        set(l.chamber_max_heat_rate_c_min, &mut c.max_heat_rate_c_s, 1.0 / 60.0);
        set(l.chamber_max_cool_rate_c_min, &mut c.max_cool_rate_c_s, 1.0 / 60.0);
        if let Some(r) = &l.gyro_sample_rates_hz {
            g.sample_rates_hz = r.clone();
        }
        if let (Some(lo), Some(hi)) = (l.gyro_min_temp_c, l.gyro_max_temp_c) {
            g.operating_temp_c = (lo, hi);
        } else {
            set(l.gyro_min_temp_c, &mut g.operating_temp_c.0, 1.0);
            set(l.gyro_max_temp_c, &mut g.operating_temp_c.1, 1.0);
        }
        if let Some(h) = l.gyro_has_temperature {
            g.has_temperature = h;
        }
        (caps, true)
    }

    /// Whether the config describes the embedded simulated bench (no device sections).
    pub fn is_simulated(&self) -> bool {
        self.table.is_none() && self.chamber.is_none() && self.gyro.is_none()
    }

    /// The `[simulation.effects]` (none without the section).
    pub fn sim_effects(&self) -> Effects {
        self.simulation.as_ref().map(|s| s.effects).unwrap_or_default()
    }

    /// The site as the plan holds it.
    pub fn site(&self) -> Option<Site> {
        self.site.as_ref().map(|s| Site {
            latitude_deg: s.latitude_deg,
            longitude_deg: s.longitude_deg,
            height_m: s.height_m,
            axis: Some(if s.axis == "down" { Axis::Down } else { Axis::Up }),
        })
    }

    /// Connect to every device, one after the other, failing on the first that cannot be
    /// reached (nothing has moved yet). Returns the devices and their capabilities.
    pub async fn connect(
        &self,
        clock: Arc<dyn Clock>,
    ) -> Result<(Devices, Capabilities), ConfigError> {
        let (Some(table), Some(chamber), Some(gyro)) = (&self.table, &self.chamber, &self.gyro)
        else {
            return Err(ConfigError::NoDrivers);
        };
        let table = RateTableDriver::connect_with_clock(table.clone(), clock.clone())
            .await
            .map_err(|source| ConfigError::Connect { device: "rate table", source })?;
        let chamber = chamber
            .connect(clock.clone())
            .await
            .map_err(|source| ConfigError::Connect { device: "chamber", source })?;
        let gyro: Box<dyn Gyro> = match gyro {
            GyroConfig::Can(c) => Box::new(
                CanGyro::open(c, clock.clone())
                    .await
                    .map_err(|source| ConfigError::Connect { device: "gyro (CAN)", source })?,
            ),
            GyroConfig::Kvh1750(c) => Box::new(
                Kvh1750Gyro::open(c, clock.clone())
                    .map_err(|source| ConfigError::Connect { device: "gyro (KVH 1750)", source })?,
            ),
            GyroConfig::Dsp3000(c) => {
                Box::new(Dsp3000Gyro::open(c, clock.clone()).map_err(|source| {
                    ConfigError::Connect { device: "gyro (KVH DSP-3000)", source }
                })?)
            }
        };
        use bench_drivers::RateTable;
        let caps = Capabilities {
            table: table.info().clone(),
            chamber: chamber.info().clone(),
            gyro: gyro.info().clone(),
        };
        Ok((Devices { table: Box::new(table), chamber, gyro }, caps))
    }
}

/// `[replay]`: the devices are a recording played back ([`crate::replay`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayConfig {
    /// The recording (MCAP); a relative path is taken from the config file's directory.
    pub recording: PathBuf,
    /// Absent: virtual time (as fast as the CPU allows). A positive number: real time × that
    /// factor (1 = as recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
}

/// A bench config whose devices are a recording: `[replay]` and optionally `[bench]`. The site
/// is the recording's `bench.site`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReplayBenchConfig {
    /// Which recording and how fast.
    pub replay: ReplayConfig,
    /// Fault-handling settings (`time_scale` is not used: see `speed`).
    #[serde(default)]
    pub bench: BenchSettings,
}

/// What `bench run --bench` names: devices to connect to, or a recording to replay.
#[derive(Debug, Clone, PartialEq)]
pub enum BenchSource {
    /// `[table]`, `[chamber]`, `[gyro]`: real drivers or served simulators; none of them: the
    /// embedded simulated bench ([`BenchConfig::is_simulated`]).
    Devices(Box<BenchConfig>),
    /// `[replay]` or `replay:PATH`.
    Replay(ReplayBenchConfig),
}

/// Prefix of a `--bench` argument that names a recording to replay in virtual time.
pub const REPLAY_PREFIX: &str = "replay:";

impl BenchSource {
    /// `replay:PATH` (a recording, replayed in virtual time), or a bench config file with
    /// either device sections or a `[replay]` section.
    pub fn load(spec: &Path) -> Result<Self, ConfigError> {
        if let Some(rec) = spec.to_str().and_then(|s| s.strip_prefix(REPLAY_PREFIX)) {
            return Ok(Self::Replay(ReplayBenchConfig {
                replay: ReplayConfig { recording: PathBuf::from(rec), speed: None },
                bench: BenchSettings::default(),
            }));
        }
        let text = read_text(spec)?;
        let file = spec.display().to_string();
        let mut source = Self::parse(&text, &file)?;
        if let Self::Replay(r) = &mut source {
            if r.replay.recording.is_relative() {
                if let Some(dir) = spec.parent() {
                    r.replay.recording = dir.join(&r.replay.recording);
                }
            }
            // A recording that cannot be opened is the config's error, at its key.
            if let Err(e) = std::fs::File::open(&r.replay.recording) {
                let at = bench_recording::toml_doc::value_span(&text, &["replay", "recording"])
                    .map_or(0, |s| s.start);
                let (line, column) = bench_recording::toml_doc::line_col(&text, at);
                return Err(ConfigError::Invalid {
                    file,
                    line,
                    column,
                    message: format!("[replay] recording {}: {e}", r.replay.recording.display()),
                });
            }
        }
        Ok(source)
    }

    /// Parse config `text`: a `[replay]` section makes it a replay (no device sections
    /// allowed beside it); errors name `file:line:column`.
    pub fn parse(text: &str, file: &str) -> Result<Self, ConfigError> {
        let is_replay =
            text.parse::<toml::Table>().map(|t| t.contains_key("replay")).unwrap_or(false);
        if !is_replay {
            return BenchConfig::parse(text, file).map(|c| Self::Devices(Box::new(c)));
        }
        let cfg: ReplayBenchConfig =
            toml::from_str(text).map_err(|e| toml_error(text, file, &e))?;
        let at_key = |key: &str| {
            let (line, column) = text
                .find(&format!("{key} "))
                .or_else(|| text.find(key))
                .map_or((1, 1), |at| bench_recording::toml_doc::line_col(text, at));
            (line, column)
        };
        if let Some(speed) = cfg.replay.speed {
            if !(speed.is_finite() && speed > 0.0) {
                let (line, column) = at_key("speed");
                return Err(ConfigError::Invalid {
                    file: file.to_string(),
                    line,
                    column,
                    message: format!(
                        "[replay] speed must be a positive number (× real time), got {speed}; \
                         leave it out for virtual time"
                    ),
                });
            }
        }
        // The fault-handling settings are checked as for a device bench.
        let b = &cfg.bench;
        for (key, v) in
            [("stale_after_s", b.stale_after_s), ("safe_state_timeout_s", b.safe_state_timeout_s)]
        {
            if !(v.is_finite() && v > 0.0 && v < 1e9) {
                let (line, column) = at_key(key);
                return Err(ConfigError::Invalid {
                    file: file.to_string(),
                    line,
                    column,
                    message: format!("[bench] {key} must be a positive number of seconds, got {v}"),
                });
            }
        }
        Ok(Self::Replay(cfg))
    }
}

/// Wall time a served simulator's stream may stay silent before it is stale, s.
pub const SERVED_STALE_WALL_S: f64 = 5.0;

/// Wall time without a gyro sample before the served gyro's driver counts a timeout, s.
pub const SERVED_GYRO_WATCHDOG_WALL_S: f64 = 0.25;

/// The bench config that reaches a served simulated bench (`bench sim serve`): the table's
/// Actidyn port, the chamber's Modbus RTU port and the gyro's SLCAN adapter, at the served
/// time scale and the simulator's latitude. A loaded host's scheduling is wall time, which a
/// time scale multiplies: streams go stale after 30 s of bench time or
/// [`SERVED_STALE_WALL_S`] of wall time, and the gyro's watchdog waits 10 sample periods or
/// [`SERVED_GYRO_WATCHDOG_WALL_S`], whichever is longer.
pub fn for_served_bench(
    endpoints: &bench_sim::serve::bench::ServedEndpoints,
    time_scale: f64,
    latitude_deg: f64,
    axis_up: bool,
) -> BenchConfig {
    use bench_drivers::protocol::Dialect;
    use bench_drivers::real::chamber::MapChoice;
    let mut gyro = CanGyroConfig::slcan(endpoints.gyro_slcan.path.clone());
    gyro.sample_rate_hz = endpoints.gyro_rate_hz;
    gyro.watchdog_periods = gyro
        .watchdog_periods
        .max((SERVED_GYRO_WATCHDOG_WALL_S * time_scale * gyro.sample_rate_hz).ceil());
    BenchConfig {
        site: Some(SiteConfig {
            latitude_deg,
            longitude_deg: None,
            height_m: None,
            axis: if axis_up { "up" } else { "down" }.into(),
        }),
        bench: BenchSettings {
            time_scale,
            // Staleness is a link's silence, which the host's scheduling sets in wall time: at
            // 60× real time the default 30 s of bench time is half a second of a loaded host.
            stale_after_s: BenchSettings::default()
                .stale_after_s
                .max(SERVED_STALE_WALL_S * time_scale),
            ..BenchSettings::default()
        },
        table: Some(TableDriverConfig::new(endpoints.table_actidyn_pty.clone(), Dialect::Actidyn)),
        chamber: Some(ChamberConfig::Modbus(ModbusChamberConfig::new(
            endpoints.chamber_rtu.clone(),
            MapChoice::Preset(endpoints.chamber_preset),
        ))),
        gyro: Some(GyroConfig::Can(gyro)),
        simulation: None,
        station: None,
        acceptance: Default::default(),
        limits: None,
    }
}

impl BenchConfig {
    /// As TOML text (the format [`BenchConfig::load`] reads).
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }
}

/// The text of the config file at `path`; bytes that are not UTF-8 are an error at their line
/// and column.
fn read_text(path: &Path) -> Result<String, ConfigError> {
    let bytes = std::fs::read(path)
        .map_err(|source| ConfigError::Io { path: path.to_path_buf(), source })?;
    bench_recording::toml_doc::utf8_text(bytes).map_err(|(_, line, column, message)| {
        ConfigError::Invalid { file: path.display().to_string(), line, column, message }
    })
}

/// A TOML parse or shape error of `file`, at its line and column.
fn toml_error(text: &str, file: &str, e: &toml::de::Error) -> ConfigError {
    let (line, column) = bench_recording::toml_doc::line_col(text, e.span().map_or(0, |s| s.start));
    ConfigError::Invalid {
        file: file.to_string(),
        line,
        column,
        message: e.message().trim().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[site]
latitude_deg = 43.56

[table]
dialect = "actidyn"
endpoint = { tcp = { addr = "127.0.0.1:62000" } }

[chamber]
endpoint = { serial = { path = "/dev/ttyUSB0", baud = 9600 } }
unit_id = 1
map = "watlow_f4t"

[gyro]
driver = "can"
transport = { kind = "slcan", serial = { path = "/dev/ttyACM0", baud = 115200 } }
"#;

    #[test]
    fn a_lab_config_parses_with_defaults() {
        let c = BenchConfig::parse(GOOD, "lab.toml").expect("valid");
        assert_eq!(c.bench.time_scale, 1.0);
        assert_eq!(c.bench.policy().stale_after, std::time::Duration::from_secs(30));
        assert_eq!(c.bench.policy().max_consecutive_errors, 5);
        assert_eq!(c.site().map(|s| (s.latitude_deg, s.axis_up())), Some((43.56, true)));
        assert!(matches!(c.gyro, Some(GyroConfig::Can(_))));
        assert!(matches!(&c.chamber, Some(ChamberConfig::Modbus(m)) if m.unit_id == 1));
        assert!(!c.is_simulated());
        assert_eq!(c.sim_effects(), Effects::default());
    }

    #[test]
    fn the_chamber_is_chosen_by_protocol_modbus_by_default() {
        let modbus = |c: &BenchConfig| match &c.chamber {
            Some(ChamberConfig::Modbus(m)) => m.clone(),
            None => panic!("no chamber"),
        };
        let plain = BenchConfig::parse(GOOD, "lab.toml").expect("valid");
        let text = GOOD.replace("[chamber]\n", "[chamber]\nprotocol = \"modbus\"\n");
        let named = BenchConfig::parse(&text, "lab.toml").expect("valid");
        assert_eq!(modbus(&named), modbus(&plain));
        // Written out, it names its protocol and reads back the same.
        let again = plain.to_toml().expect("serialises");
        assert!(again.contains("protocol = \"modbus\""), "{again}");
        assert_eq!(BenchConfig::parse(&again, "again.toml").expect("valid"), plain);
        // An unknown protocol is an error at its value.
        let text = GOOD.replace("[chamber]\n", "[chamber]\nprotocol = \"profibus\"\n");
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("unknown").to_string();
        assert!(e.starts_with("lab.toml:10:12: unknown variant `profibus`"), "{e}");
        assert!(e.contains("`modbus`"), "{e}");
    }

    #[test]
    fn chamber_times_in_seconds_or_the_older_ms_but_never_both() {
        let modbus = |c: &BenchConfig| match &c.chamber {
            Some(ChamberConfig::Modbus(m)) => m.clone(),
            None => panic!("no chamber"),
        };
        let with = |extra: &str| GOOD.replace("unit_id = 1\n", &format!("unit_id = 1\n{extra}"));
        let s = BenchConfig::parse(
            &with("retry_backoff_s = 0.02\nrequest_timeout_s = 0.5\n"),
            "s.toml",
        )
        .expect("seconds");
        let ms = BenchConfig::parse(
            &with("retry_backoff_ms = 20\nrequest_timeout_ms = 500\n"),
            "ms.toml",
        )
        .expect("the older milliseconds, still read");
        assert_eq!(modbus(&s).retry_policy(), modbus(&ms).retry_policy());
        assert_eq!(modbus(&s).request_timeout(), modbus(&ms).request_timeout());
        let e = BenchConfig::parse(
            &with("retry_backoff_s = 0.02\nretry_backoff_ms = 20\n"),
            "both.toml",
        )
        .expect_err("both forms")
        .to_string();
        // Located at the older key's value.
        assert!(
            e.starts_with(
                "both.toml:13:20: [chamber] `retry_backoff_s` and the older `retry_backoff_ms`"
            ),
            "{e}"
        );
    }

    #[test]
    fn unknown_key_is_located() {
        let text = GOOD.replace("unit_id = 1", "unit_id = 1\nbaudrate = 9600");
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("rejected").to_string();
        assert!(e.starts_with("lab.toml:12:1: unknown field `baudrate`"), "{e}");
    }

    #[test]
    fn unknown_gyro_driver_names_the_allowed_ones() {
        let text = GOOD.replace("driver = \"can\"", "driver = \"imu\"");
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("rejected").to_string();
        assert!(e.starts_with("lab.toml:15:10: unknown variant `imu`"), "{e}");
        assert!(e.contains("`can`") && e.contains("`kvh1750`") && e.contains("`dsp3000`"), "{e}");
    }

    #[test]
    fn kvh_gyro_settings_are_checked_at_their_keys() {
        let head = GOOD.split("[gyro]").next().unwrap_or_default();
        // Lines of `head`: the gyro section starts after them.
        let at = head.lines().count() + 1;
        let text = format!(
            "{head}[gyro]\ndriver = \"kvh1750\"\nserial = {{ path = \"\", baud = 0 }}\n\
             sample_rate_hz = -5\nwatchdog_periods = 0.5\nmax_rate_deg_s = 0\n\
             operating_temp_c = [60.0, -40.0]\n"
        );
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("rejected").to_string();
        for (line, col, what) in [
            (at + 2, 10, "[gyro] serial.path is empty"),
            (at + 2, 10, "[gyro] serial.baud must be > 0"),
            (at + 3, 18, "[gyro] sample_rate_hz = -5 must be > 0"),
            (at + 4, 20, "[gyro] watchdog_periods = 0.5 must be ≥ 1"),
            (at + 5, 18, "[gyro] max_rate_deg_s = 0 must be > 0"),
            (at + 6, 20, "[gyro] operating_temp_c = [60, -40] must be [min, max] °C"),
        ] {
            assert!(
                e.contains(&format!("lab.toml:{line}:{col}: {what}")),
                "{what} at {line}:{col} in\n{e}"
            );
        }
        // DSP-3000: a given output rate is checked; the defaults are valid.
        let dsp = |extra: &str| {
            format!(
                "{head}[gyro]\ndriver = \"dsp3000\"\nserial = {{ path = \"/dev/ttyUSB1\", \
                 baud = 38400 }}\n{extra}"
            )
        };
        assert!(BenchConfig::parse(&dsp(""), "lab.toml").is_ok());
        let e = BenchConfig::parse(&dsp("sample_rate_hz = 0\n"), "lab.toml")
            .expect_err("rejected")
            .to_string();
        assert!(
            e.starts_with(&format!(
                "lab.toml:{}:18: [gyro] sample_rate_hz = 0 must be > 0",
                at + 3
            )),
            "{e}"
        );
    }

    #[test]
    fn bad_time_scale_and_latitude_are_rejected() {
        let text = format!("[bench]\ntime_scale = 0\n{GOOD}");
        let e = BenchConfig::parse(&text, "x.toml").expect_err("rejected").to_string();
        assert!(e.contains("time_scale must be a positive number, got 0"), "{e}");
        let text = format!("[bench]\nstale_after_s = -1\n{GOOD}");
        let e = BenchConfig::parse(&text, "x.toml").expect_err("rejected").to_string();
        assert!(e.contains("stale_after_s must be a positive number of seconds, got -1"), "{e}");
        let text = GOOD.replace("43.56", "95.0");
        let e = BenchConfig::parse(&text, "x.toml").expect_err("rejected").to_string();
        assert!(e.contains("latitude_deg 95 is outside -90..90"), "{e}");
    }

    #[test]
    fn a_replay_section_or_prefix_names_a_recording() {
        let c = BenchSource::parse("[replay]\nrecording = \"run.mcap\"\nspeed = 10\n", "r.toml")
            .expect("valid");
        let BenchSource::Replay(r) = c else { panic!("not a replay") };
        assert_eq!((r.replay.recording, r.replay.speed), (PathBuf::from("run.mcap"), Some(10.0)));
        let c = BenchSource::load(Path::new("replay:/tmp/x.mcap")).expect("valid");
        let BenchSource::Replay(r) = c else { panic!("not a replay") };
        assert_eq!((r.replay.recording, r.replay.speed), (PathBuf::from("/tmp/x.mcap"), None));
        assert!(matches!(BenchSource::parse(GOOD, "lab.toml"), Ok(BenchSource::Devices(_))));
    }

    #[test]
    fn replay_config_errors_are_located() {
        let text = "[replay]\nrecording = \"run.mcap\"\n\n[table]\ndialect = \"actidyn\"\n";
        let e = BenchSource::parse(text, "r.toml").expect_err("rejected").to_string();
        assert!(
            e.starts_with("r.toml:4:2: unknown field `table`, expected `replay` or `bench`"),
            "{e}"
        );
        let e = BenchSource::parse("[replay]\nrecordin = \"a\"\n", "r.toml")
            .expect_err("rejected")
            .to_string();
        assert!(e.starts_with("r.toml:2:1: unknown field `recordin`"), "{e}");
        let e = BenchSource::parse("[replay]\nrecording = \"a\"\nspeed = -2\n", "r.toml")
            .expect_err("rejected")
            .to_string();
        assert!(e.starts_with("r.toml:3:1: [replay] speed must be a positive number"), "{e}");
    }

    const SIM: &str = r#"[site]
latitude_deg = 45.0

[simulation.effects]
earth_rate = true
bias_step = { time_s = 100, step_rad_s = 1e-6 }

[simulation.effects.warm_up]
amplitude_rad_s = 1e-7
time_constant_s = 900
"#;

    #[test]
    fn a_config_without_drivers_is_the_simulated_bench_with_its_effects() {
        use bench_physics::effects::EffectId;
        let c = BenchConfig::parse(SIM, "sim.toml").expect("valid");
        assert!(c.is_simulated());
        let e = c.sim_effects();
        assert!(e.has(EffectId::EarthRate));
        assert_eq!(e.get(EffectId::BiasStep), Some(&[100.0, 1e-6][..]));
        assert_eq!(e.get(EffectId::WarmUp), Some(&[1e-7, 900.0][..]));
        assert_eq!(e.ids().len(), 3);
        // Written back, it reads the same.
        let text = c.to_toml().expect("serialises");
        assert_eq!(BenchConfig::parse(&text, "back.toml").expect("valid"), c);
        // A lab config may carry [simulation] too.
        let both = format!("{GOOD}\n{}", SIM.replace("[site]\nlatitude_deg = 45.0\n", ""));
        let c = BenchConfig::parse(&both, "lab.toml").expect("valid");
        assert!(!c.is_simulated() && c.sim_effects().has(EffectId::EarthRate));
    }

    #[test]
    fn bad_effects_in_the_bench_config_are_located() {
        let e = |text: String| BenchConfig::parse(&text, "sim.toml").expect_err("rejected");
        let msg = e(SIM.replace("time_constant_s = 900", "time_constant_s = 0")).to_string();
        assert_eq!(
            msg,
            "sim.toml:10:19: [simulation.effects] warm_up.time_constant_s = 0: must be greater \
             than zero"
        );
        let msg = e(SIM.replace("step_rad_s = 1e-6", "step_rad_s = nan")).to_string();
        assert_eq!(
            msg,
            "sim.toml:6:42: [simulation.effects] bias_step.step_rad_s = NaN: must be a finite \
             number"
        );
        let msg = e(SIM.replace("bias_step =", "bias_stop =")).to_string();
        assert!(
            msg.starts_with("sim.toml:6:1: unknown field `bias_stop`, expected one of"),
            "{msg}"
        );
        assert!(msg.contains("`bias_step`") && msg.contains("`rate_squared`"), "{msg}");
        let msg = e(SIM.replace("time_s = 100, ", "")).to_string();
        assert!(msg.starts_with("sim.toml:6:13: missing field `time_s`"), "{msg}");
        let msg = e(SIM.replace("amplitude_rad_s = 1e-7", "amplitude_rad_s = \"big\"")).to_string();
        assert!(msg.starts_with("sim.toml:9:19: invalid type: string"), "{msg}");
        let msg = e(SIM.replace("earth_rate = true", "earth_rate = true\ncolour = 1")).to_string();
        assert!(msg.starts_with("sim.toml:6:1: unknown field `colour`"), "{msg}");
    }

    #[test]
    fn drivers_are_all_or_none() {
        let text = GOOD.replace("[gyro]\ndriver = \"can\"\n", "[nothing]\n");
        let text = text.replace("[nothing]\ntransport = { kind = \"slcan\", serial = { path = \"/dev/ttyACM0\", baud = 115200 } }\n", "");
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("rejected").to_string();
        assert!(e.ends_with("missing: [gyro]"), "{e}");
    }

    #[test]
    fn the_drivers_own_checks_are_made_when_the_config_is_read() {
        // Found by scripts/bad_inputs.py: `bench validate --bench` accepted a gyro sample rate
        // of -20 Hz that `bench run` refused only when it connected.
        let text = GOOD.replace("baud = 115200 } }", "baud = 115200 } }\nsample_rate_hz = -20.0");
        let e = BenchConfig::parse(&text, "lab.toml").expect_err("negative rate").to_string();
        assert!(e.contains(": [gyro] sample_rate_hz = -20"), "{e}");
        // At the [gyro] section.
        let line: usize = e.split(':').nth(1).and_then(|l| l.parse().ok()).unwrap_or(0);
        assert!((14..=17).contains(&line), "{e}");
    }

    #[test]
    fn unreadable_text_and_a_missing_replay_recording_are_located() {
        // Found by scripts/bad_inputs.py: both named the file but no place in the config.
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("lab.toml");
        std::fs::write(&path, b"[site]\nlatitude_deg = 45.0\naxis = \"\xFFup\"\n").expect("write");
        let e = BenchSource::load(&path).expect_err("not UTF-8").to_string();
        assert!(e.starts_with(&format!("{}:3:9: not UTF-8", path.display())), "{e}");
        std::fs::write(&path, "[replay]\nrecording = \"gone.mcap\"\n").expect("write");
        let e = BenchSource::load(&path).expect_err("no recording");
        assert!(matches!(e, ConfigError::Invalid { line: 2, column: 13, .. }), "{e}");
        assert!(e.to_string().contains("[replay] recording"), "{e}");
    }

    #[tokio::test]
    async fn a_config_without_drivers_cannot_connect() {
        let c = BenchConfig::parse(SIM, "sim.toml").expect("valid");
        let clock: Arc<dyn Clock> = Arc::new(bench_drivers::SystemClock::new(1.0));
        let e = c.connect(clock).await.err().expect("no drivers");
        assert!(matches!(e, ConfigError::NoDrivers), "{e}");
    }

    #[tokio::test]
    async fn a_closed_port_fails_before_anything_moves_naming_what_was_tried() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.expect("bind");
        let addr = listener.local_addr().expect("addr");
        drop(listener);
        let text = GOOD.replace("127.0.0.1:62000", &addr.to_string());
        let c = BenchConfig::parse(&text, "lab.toml").expect("valid");
        let clock: Arc<dyn Clock> = Arc::new(bench_drivers::SystemClock::new(1.0));
        let e = c.connect(clock).await.err().expect("nothing listens").to_string();
        assert!(e.starts_with("rate table:"), "{e}");
        assert!(e.contains(&addr.to_string()), "{e}");
    }
}
