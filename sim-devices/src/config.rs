//! Configuration of the simulated bench and the capabilities it reports.

use bench_drivers::{ChamberCapabilities, DeviceInfo, GyroCapabilities, TableCapabilities};
use bench_physics::chamber::ChamberParams;
use bench_physics::effects::{EffectId, Effects};
use bench_physics::table::TableParams;
use bench_physics::units::DEG;
use bench_physics::GyroModel;
use serde::{Deserialize, Serialize};

/// The simulated gyro's interface (what it can do, not its error model).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroParams {
    /// Output rates it can be set to, Hz (default 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000,
    /// 2000).
    pub sample_rates_hz: Vec<f64>,
    /// Input range, rad/s (default 500 °/s); larger true rates saturate the output and flag the
    /// sample invalid.
    pub max_rate_rad_s: f64,
    /// Operating temperature range, °C (default −40..+60).
    pub operating_temp_c: (f64, f64),
    /// Whether samples carry the internal temperature (default true).
    pub has_temperature: bool,
}

impl Default for GyroParams {
    fn default() -> Self {
        Self {
            sample_rates_hz: vec![
                1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0,
            ],
            max_rate_rad_s: 500.0 * DEG,
            operating_temp_c: (-40.0, 60.0),
            has_temperature: true,
        }
    }
}

/// Everything the simulated bench needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// Seed of every random stream (gyro noise, table and chamber readout noise).
    pub seed: u64,
    /// The gyro's true error model (default: [`GyroModel::default`], the seed's gyro).
    pub gyro_model: GyroModel,
    /// Effects beyond the model that the simulated gyro also shows (default: none); a
    /// recording keeps them out of `bench.gyro_model`, so they are concealed.
    pub gyro_effects: Effects,
    /// Gyro output rate, Hz (default 20); must be one of `gyro.sample_rates_hz`.
    pub gyro_sample_rate_hz: f64,
    /// Latitude of the bench, degrees north (default 59.94, St Petersburg).
    pub latitude_deg: f64,
    /// The gyro's sensing axis points up (default true).
    pub axis_up: bool,
    /// Chamber air, set point and gyro temperature at the start, °C (default 20).
    pub initial_temp_c: f64,
    /// Rate table (default: ST1300 class, see [`TableParams`]).
    pub table: TableParams,
    /// Climatic chamber (default: ST1300 chamber, see [`ChamberParams`]).
    pub chamber: ChamberParams,
    /// Gyro interface.
    pub gyro: GyroParams,
}

impl SimConfig {
    /// The simulated table and the gyro's effects as the simulator runs them: a `rate_ripple`
    /// effect is the table's ripple (it replaces the table's own; the gyro sees it through the
    /// table's true motion), so it leaves the gyro's effects and sets `table.ripple_*`.
    pub fn table_and_gyro_effects(&self) -> (TableParams, Effects) {
        let mut table = self.table.clone();
        let effects = self.gyro_effects.without(EffectId::RateRipple);
        if let Some(&[rel, cycles_per_rev, phase_rad]) = self.gyro_effects.get(EffectId::RateRipple)
        {
            // ε·sin(x + φ) with ε < 0 is |ε|·sin(x + φ + π).
            let (eps, phase) =
                if rel < 0.0 { (-rel, phase_rad + std::f64::consts::PI) } else { (rel, phase_rad) };
            table.ripple_rel = eps;
            // Whole and in range: checked by `validate`.
            table.ripple_cycles_per_rev = cycles_per_rev.round().clamp(0.0, 65_535.0) as u32;
            table.ripple_phase_rad = phase;
        }
        (table, effects)
    }

    /// Every effect beyond the gyro model that the simulated gyro's output shows: the gyro's
    /// effects, and the table's ripple as `rate_ripple` (what a diagnosis should find).
    pub fn seen_effects(&self) -> Effects {
        let (table, mut effects) = self.table_and_gyro_effects();
        if table.ripple_rel > 0.0 && table.ripple_cycles_per_rev > 0 {
            let ripple =
                [table.ripple_rel, f64::from(table.ripple_cycles_per_rev), table.ripple_phase_rad];
            // Three values, the ripple's three parameters.
            let _ = effects.set(EffectId::RateRipple, &ripple);
        }
        effects
    }
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            gyro_model: GyroModel::default(),
            gyro_effects: Effects::default(),
            gyro_sample_rate_hz: 20.0,
            latitude_deg: 59.94,
            axis_up: true,
            initial_temp_c: 20.0,
            table: TableParams::default(),
            chamber: ChamberParams::default(),
            gyro: GyroParams::default(),
        }
    }
}

/// A configuration the simulator cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("simulator config: `{field}` {problem}")]
pub struct SimConfigError {
    /// The offending field.
    pub field: &'static str,
    /// What is wrong with it.
    pub problem: String,
}

fn err(field: &'static str, problem: impl Into<String>) -> SimConfigError {
    SimConfigError { field, problem: problem.into() }
}

fn positive(field: &'static str, v: f64) -> Result<(), SimConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be a positive number, got {v}")))
    }
}

fn non_negative(field: &'static str, v: f64) -> Result<(), SimConfigError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(err(field, format!("must be a number ≥ 0, got {v}")))
    }
}

/// The three devices' descriptions.
#[derive(Debug, Clone, PartialEq)]
pub struct SimInfos {
    /// Rate table.
    pub table: DeviceInfo<TableCapabilities>,
    /// Chamber.
    pub chamber: DeviceInfo<ChamberCapabilities>,
    /// Gyro.
    pub gyro: DeviceInfo<GyroCapabilities>,
}

/// Descriptions of the devices of a default [`SimConfig`], without building a simulator.
pub fn default_infos() -> SimInfos {
    SimConfig::default().infos()
}

impl SimConfig {
    /// Check the configuration: every parameter finite and in range, the gyro rate one of the
    /// listed rates, the initial temperature inside the chamber's range.
    pub fn validate(&self) -> Result<(), SimConfigError> {
        let rates = &self.gyro.sample_rates_hz;
        if rates.is_empty() || rates.iter().any(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(err("gyro.sample_rates_hz", "must list positive rates"));
        }
        if !rates.iter().any(|r| (r - self.gyro_sample_rate_hz).abs() < 1e-9) {
            return Err(err(
                "gyro_sample_rate_hz",
                format!("{} Hz is not one of the gyro's rates {rates:?}", self.gyro_sample_rate_hz),
            ));
        }
        bench_recording::SiteNumber::LATITUDE_DEG
            .check(self.latitude_deg)
            .map_err(|e| err("latitude_deg", e))?;
        let c = &self.chamber;
        if !(c.min_temp_c.is_finite() && c.max_temp_c.is_finite() && c.min_temp_c < c.max_temp_c) {
            return Err(err("chamber.min_temp_c", "range must be finite with min < max"));
        }
        if !(self.initial_temp_c >= c.min_temp_c && self.initial_temp_c <= c.max_temp_c) {
            return Err(err(
                "initial_temp_c",
                format!(
                    "{} °C is outside the chamber's {}..{} °C",
                    self.initial_temp_c, c.min_temp_c, c.max_temp_c
                ),
            ));
        }
        self.gyro_effects.validate().map_err(|e| err("gyro_effects", e))?;
        if let Some(&[_, n, _]) = self.gyro_effects.get(EffectId::RateRipple) {
            if n.fract() != 0.0 || !(1.0..=f64::from(u16::MAX)).contains(&n) {
                return Err(err(
                    "gyro_effects",
                    format!(
                        "`rate_ripple.cycles_per_rev` must be a whole number of cycles per \
                         revolution for the simulated table, got {n}"
                    ),
                ));
            }
        }
        positive("chamber.max_heat_rate_c_s", c.max_heat_rate_c_s)?;
        positive("chamber.max_cool_rate_c_s", c.max_cool_rate_c_s)?;
        positive("chamber.air_heat_slew_c_s", c.air_heat_slew_c_s)?;
        positive("chamber.air_cool_slew_c_s", c.air_cool_slew_c_s)?;
        non_negative("chamber.air_time_constant_s", c.air_time_constant_s)?;
        non_negative("chamber.resolution_c", c.resolution_c)?;
        non_negative("chamber.sensor_noise_c", c.sensor_noise_c)?;
        let t = &self.table;
        positive("table.max_rate_rad_s", t.max_rate_rad_s)?;
        positive("table.max_accel_rad_s2", t.max_accel_rad_s2)?;
        non_negative("table.position_resolution_rad", t.position_resolution_rad)?;
        non_negative("table.ripple_rel", t.ripple_rel)?;
        non_negative("table.rate_noise_rad_s", t.rate_noise_rad_s)?;
        positive("gyro.max_rate_rad_s", self.gyro.max_rate_rad_s)?;
        // The one validation of a gyro model (`ModelKey::check`).
        self.gyro_model.validate().map_err(|(key, why)| {
            err("gyro_model", format!("`{}` {why}, got {}", key.key(), self.gyro_model.get(key)))
        })?;
        Ok(())
    }

    /// The devices' descriptions (model, driver `sim`, capabilities), for validating a scenario
    /// before any simulator exists.
    pub fn infos(&self) -> SimInfos {
        SimInfos {
            table: DeviceInfo {
                model: "Actidyn ST1300 rate table (simulated)".into(),
                driver: "sim".into(),
                capabilities: TableCapabilities {
                    max_rate_rad_s: self.table.max_rate_rad_s,
                    max_accel_rad_s2: self.table.max_accel_rad_s2,
                    position_resolution_rad: self.table.position_resolution_rad,
                },
            },
            chamber: DeviceInfo {
                model: "ST1300 climatic chamber (simulated)".into(),
                driver: "sim".into(),
                capabilities: ChamberCapabilities {
                    min_temp_c: self.chamber.min_temp_c,
                    max_temp_c: self.chamber.max_temp_c,
                    max_heat_rate_c_s: self.chamber.max_heat_rate_c_s,
                    max_cool_rate_c_s: self.chamber.max_cool_rate_c_s,
                    temp_resolution_c: self.chamber.resolution_c,
                },
            },
            gyro: DeviceInfo {
                model: "FOG (simulated)".into(),
                driver: "sim".into(),
                capabilities: GyroCapabilities {
                    sample_rates_hz: self.gyro.sample_rates_hz.clone(),
                    max_rate_rad_s: self.gyro.max_rate_rad_s,
                    operating_temp_c: self.gyro.operating_temp_c,
                    has_temperature: self.gyro.has_temperature,
                },
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::effects::EffectId;

    #[test]
    fn a_rate_ripple_effect_becomes_the_tables_ripple() {
        let cfg = SimConfig::default();
        // The default table ripples; the gyro adds nothing of its own.
        let seen = cfg.seen_effects();
        let r = seen.get(EffectId::RateRipple).expect("the table's ripple is seen");
        assert_eq!(r, &[1e-5, 16.0, 0.0][..]);

        let mut cfg = SimConfig::default();
        cfg.gyro_effects.set(EffectId::RateRipple, &[-2e-5, 8.0, 0.5]).expect("fits");
        assert!(cfg.validate().is_ok());
        let (table, effects) = cfg.table_and_gyro_effects();
        assert!(!effects.has(EffectId::RateRipple), "not added a second time through the gyro");
        assert_eq!((table.ripple_rel, table.ripple_cycles_per_rev), (2e-5, 8));
        assert!((table.ripple_phase_rad - (0.5 + std::f64::consts::PI)).abs() < 1e-15);

        cfg.gyro_effects.set(EffectId::RateRipple, &[-2e-5, 2.5, 0.5]).expect("fits");
        let e = cfg.validate().expect_err("half a cycle");
        assert!(e.to_string().contains("whole number"), "{e}");
    }
}
