//! The gyro's error model, with the parameter names and units of `bench.gyro_model` in the
//! recording format (`recording/FORMAT.md`).
//!
//! Output of the gyro, averaged over a sample interval:
//!
//! ```text
//! V = Ω_in·(1 + scale_factor_error) + bias + temp_coeff·(T − T0) + temp_rate_coeff·dT/dt + noise
//! Ω_in = table rate + earth_rate · Ω_E · sin(latitude)      (sensing axis up)
//! ```
//!
//! with T the gyro's own temperature, following chamber air through a first-order lag of
//! `thermal_time_constant`, and noise = white (ARW) + bias instability.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::units::{DEG_PER_H, DEG_PER_SQRT_H};

/// Nominal gyro error model; every field is in the contract's unit (SI, temperatures in °C).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroModel {
    /// Constant zero offset V0, rad/s.
    pub bias: f64,
    /// k_sf − 1, dimensionless.
    pub scale_factor_error: f64,
    /// T0 of the thermal terms, °C.
    pub reference_temperature: f64,
    /// Slope of bias with temperature (T − T0), rad/s per °C.
    pub temp_coeff: f64,
    /// Slope of bias with dT/dt, rad/s per (°C/s).
    pub temp_rate_coeff: f64,
    /// Angle random walk (white rate noise density), rad/√s.
    pub arw: f64,
    /// Flicker floor of the Allan deviation (the ADEV value at its minimum, not IEEE 952's B,
    /// which is this divided by √(2 ln 2 / π) ≈ 0.664), rad/s.
    pub bias_instability: f64,
    /// Whether the model includes Earth's rotation.
    pub earth_rate: bool,
    /// First-order lag from chamber air to gyro temperature, s; 0 = gyro at air temperature.
    pub thermal_time_constant: f64,
}

/// A key of `bench.gyro_model`: the one list of the model's parameters, their contract names
/// and their fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ModelKey {
    /// `bias`, rad/s.
    Bias,
    /// `scale_factor_error`, 1.
    ScaleFactorError,
    /// `reference_temperature`, °C.
    ReferenceTemperature,
    /// `temp_coeff`, rad/s per °C.
    TempCoeff,
    /// `temp_rate_coeff`, rad/s per (°C/s).
    TempRateCoeff,
    /// `arw`, rad/√s.
    Arw,
    /// `bias_instability`, rad/s.
    BiasInstability,
    /// `earth_rate`, 1 or 0.
    EarthRate,
    /// `thermal_time_constant`, s.
    ThermalTimeConstant,
}

impl ModelKey {
    /// Every key, in contract order.
    pub const ALL: [ModelKey; 9] = [
        ModelKey::Bias,
        ModelKey::ScaleFactorError,
        ModelKey::ReferenceTemperature,
        ModelKey::TempCoeff,
        ModelKey::TempRateCoeff,
        ModelKey::Arw,
        ModelKey::BiasInstability,
        ModelKey::EarthRate,
        ModelKey::ThermalTimeConstant,
    ];

    /// The four coefficients a thermal calibration fits, in the order every report lists them.
    pub const CALIBRATED: [ModelKey; 4] =
        [ModelKey::Bias, ModelKey::ScaleFactorError, ModelKey::TempCoeff, ModelKey::TempRateCoeff];

    /// The contract's name.
    pub const fn key(self) -> &'static str {
        match self {
            ModelKey::Bias => "bias",
            ModelKey::ScaleFactorError => "scale_factor_error",
            ModelKey::ReferenceTemperature => "reference_temperature",
            ModelKey::TempCoeff => "temp_coeff",
            ModelKey::TempRateCoeff => "temp_rate_coeff",
            ModelKey::Arw => "arw",
            ModelKey::BiasInstability => "bias_instability",
            ModelKey::EarthRate => "earth_rate",
            ModelKey::ThermalTimeConstant => "thermal_time_constant",
        }
    }

    /// The key named `name` in the contract.
    pub fn from_key(name: &str) -> Option<ModelKey> {
        ModelKey::ALL.into_iter().find(|k| k.key() == name)
    }

    /// The contract's (SI) unit, for people.
    pub fn unit(self) -> &'static str {
        match self {
            ModelKey::Bias | ModelKey::BiasInstability => "rad/s",
            ModelKey::ScaleFactorError | ModelKey::EarthRate => "1",
            ModelKey::ReferenceTemperature => "°C",
            ModelKey::TempCoeff => "rad/s/°C",
            ModelKey::TempRateCoeff => "rad/s/(°C/s)",
            ModelKey::Arw => "rad/√s",
            ModelKey::ThermalTimeConstant => "s",
        }
    }

    /// Whether the parameter can only be zero or positive.
    pub fn non_negative(self) -> bool {
        matches!(self, ModelKey::Arw | ModelKey::BiasInstability | ModelKey::ThermalTimeConstant)
    }

    /// The keys a calibration may hold (not determined by the procedure, so not written as
    /// measured): the coefficients it fits, [`ModelKey::CALIBRATED`].
    pub const HOLDABLE: [ModelKey; 4] = ModelKey::CALIBRATED;

    /// The keys an acceptance limit may name (`[acceptance]`, `bench.acceptance`): the
    /// calibrated coefficients and the two noise terms.
    pub const LIMITED: [ModelKey; 6] = [
        ModelKey::Bias,
        ModelKey::ScaleFactorError,
        ModelKey::TempCoeff,
        ModelKey::TempRateCoeff,
        ModelKey::Arw,
        ModelKey::BiasInstability,
    ];

    /// The name in files whose keys carry their SI unit: the calibration file's `[gyro_model]`
    /// and `[uncertainty]`, `[acceptance]` and `bench.acceptance` (`bias_rad_s`, …).
    pub const fn file_key(self) -> &'static str {
        match self {
            ModelKey::Bias => "bias_rad_s",
            ModelKey::ScaleFactorError => "scale_factor_error",
            ModelKey::ReferenceTemperature => "reference_temperature_c",
            ModelKey::TempCoeff => "temp_coeff_rad_s_per_c",
            ModelKey::TempRateCoeff => "temp_rate_coeff_rad_s_per_c_s",
            ModelKey::Arw => "arw_rad_per_sqrt_s",
            ModelKey::BiasInstability => "bias_instability_rad_s",
            ModelKey::EarthRate => "earth_rate",
            ModelKey::ThermalTimeConstant => "thermal_time_constant_s",
        }
    }

    /// The key whose [`ModelKey::file_key`] is `name`.
    pub fn from_file_key(name: &str) -> Option<ModelKey> {
        ModelKey::ALL.into_iter().find(|k| k.file_key() == name)
    }

    /// The one range check of a value of this key, wherever a model comes from (model file,
    /// scenario, simulator config): every value finite, the scale factor `1 + error` positive,
    /// the noise terms and the lag not negative (`earth_rate` is a flag: any value). `Err`
    /// says what is required.
    pub fn check(self, value: f64) -> Result<(), &'static str> {
        match self {
            ModelKey::EarthRate => Ok(()),
            _ if !value.is_finite() => Err(self.requirement()),
            ModelKey::ScaleFactorError if value <= -1.0 => Err(self.requirement()),
            k if k.non_negative() && value < 0.0 => Err(self.requirement()),
            _ => Ok(()),
        }
    }

    /// What [`ModelKey::check`] requires, in words.
    pub fn requirement(self) -> &'static str {
        match self {
            ModelKey::EarthRate => "must be true or false",
            ModelKey::ScaleFactorError => "must be finite and above -1",
            k if k.non_negative() => "must be finite and not negative",
            _ => "must be finite",
        }
    }
}

/// [`ModelKey::file_key`] (`file`) or [`ModelKey::key`] of each of `keys`.
const fn names<const N: usize>(keys: [ModelKey; N], file: bool) -> [&'static str; N] {
    let mut out = [""; N];
    let mut i = 0;
    while i < N {
        out[i] = if file { keys[i].file_key() } else { keys[i].key() };
        i += 1;
    }
    out
}

const fn file_keys<const N: usize>(keys: [ModelKey; N]) -> [&'static str; N] {
    names(keys, true)
}

/// File keys of every key, in contract order (the calibration file's `[gyro_model]`).
pub const MODEL_FILE_KEYS: [&str; 9] = file_keys(ModelKey::ALL);

/// Keys of `[acceptance]` / `bench.acceptance` ([`ModelKey::LIMITED`]): SI, units in the names.
pub const ACCEPTANCE_KEYS: [&str; 6] = file_keys(ModelKey::LIMITED);

/// File keys of the coefficients a calibration may hold ([`ModelKey::HOLDABLE`]).
pub const HOLDABLE_KEYS: [&str; 4] = file_keys(ModelKey::HOLDABLE);

/// Names of `bench.gyro_model`'s keys, in contract order.
pub const GYRO_MODEL_KEYS: [&str; 9] = names(ModelKey::ALL, false);

impl Default for GyroModel {
    /// The seed's gyro (`docs/seed-method.md`), made concrete:
    ///
    /// - residual bias and scale factor zero (the seed assumes them calibrated out);
    /// - noise giving 0.002 °/h Allan deviation at 100 s at constant temperature: ARW
    ///   1e-4 °/√h (6e-4 °/h at 100 s) and a flicker floor of √(0.002² − 0.0006²) ≈ 0.00191 °/h;
    /// - thermal drift of 0.1 °/h across the working range: 0.1 °/h over 100 °C for the
    ///   temperature term, and 0.1 °/h at the seed's largest dT/dt (0.033 °C/s) for the
    ///   temperature-rate term (the seed finds the rate term dominant);
    /// - T0 = 20 °C (room), Earth rate on, 300 s thermal lag from air to the sensing coil.
    fn default() -> Self {
        let arw = 1e-4 * DEG_PER_SQRT_H;
        let floor_deg_h = (0.002f64.powi(2) - 0.0006f64.powi(2)).sqrt();
        Self {
            bias: 0.0,
            scale_factor_error: 0.0,
            reference_temperature: 20.0,
            temp_coeff: 0.1 * DEG_PER_H / 100.0,
            temp_rate_coeff: 0.1 * DEG_PER_H / 0.033,
            arw,
            bias_instability: floor_deg_h * DEG_PER_H,
            earth_rate: true,
            thermal_time_constant: 300.0,
        }
    }
}

/// A `bench.gyro_model` entry that is not a number.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("bench.gyro_model key `{key}`: expected a decimal number, got `{value}`")]
pub struct ModelKeyError {
    /// The key.
    pub key: String,
    /// What was there.
    pub value: String,
}

impl GyroModel {
    /// Every value checked ([`ModelKey::check`]), in contract order: the first key out of
    /// range, with what it requires.
    pub fn validate(&self) -> Result<(), (ModelKey, &'static str)> {
        ModelKey::ALL.into_iter().try_for_each(|k| k.check(self.get(k)).map_err(|why| (k, why)))
    }

    /// The model with every term zero (what a metadata record with no keys means).
    pub fn zero() -> Self {
        Self {
            bias: 0.0,
            scale_factor_error: 0.0,
            reference_temperature: 0.0,
            temp_coeff: 0.0,
            temp_rate_coeff: 0.0,
            arw: 0.0,
            bias_instability: 0.0,
            earth_rate: false,
            thermal_time_constant: 0.0,
        }
    }

    /// The value of `key` (`earth_rate` as 1 or 0).
    pub fn get(&self, key: ModelKey) -> f64 {
        match key {
            ModelKey::Bias => self.bias,
            ModelKey::ScaleFactorError => self.scale_factor_error,
            ModelKey::ReferenceTemperature => self.reference_temperature,
            ModelKey::TempCoeff => self.temp_coeff,
            ModelKey::TempRateCoeff => self.temp_rate_coeff,
            ModelKey::Arw => self.arw,
            ModelKey::BiasInstability => self.bias_instability,
            ModelKey::EarthRate => f64::from(u8::from(self.earth_rate)),
            ModelKey::ThermalTimeConstant => self.thermal_time_constant,
        }
    }

    /// Set `key` to `value` (`earth_rate`: any non-zero value is on).
    pub fn set(&mut self, key: ModelKey, value: f64) {
        match key {
            ModelKey::Bias => self.bias = value,
            ModelKey::ScaleFactorError => self.scale_factor_error = value,
            ModelKey::ReferenceTemperature => self.reference_temperature = value,
            ModelKey::TempCoeff => self.temp_coeff = value,
            ModelKey::TempRateCoeff => self.temp_rate_coeff = value,
            ModelKey::Arw => self.arw = value,
            ModelKey::BiasInstability => self.bias_instability = value,
            ModelKey::EarthRate => self.earth_rate = value != 0.0,
            ModelKey::ThermalTimeConstant => self.thermal_time_constant = value,
        }
    }

    /// As `bench.gyro_model` metadata: every key, numbers as decimal text (shortest
    /// round-tripping form), `earth_rate` as 1 or 0.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        ModelKey::ALL
            .into_iter()
            .map(|k| {
                let text = match k {
                    ModelKey::EarthRate => if self.earth_rate { "1" } else { "0" }.to_string(),
                    _ => format!("{:e}", self.get(k)),
                };
                (k.key().to_string(), text)
            })
            .collect()
    }

    /// From `bench.gyro_model` metadata: absent keys are zero; keys this model does not know
    /// are returned beside it, to be kept and reported.
    pub fn from_metadata(
        meta: &BTreeMap<String, String>,
    ) -> Result<(Self, BTreeMap<String, String>), ModelKeyError> {
        let mut m = Self::zero();
        let mut extra = BTreeMap::new();
        for (k, v) in meta {
            match ModelKey::from_key(k) {
                Some(key) => {
                    let x = v
                        .trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| ModelKeyError { key: k.clone(), value: v.clone() })?;
                    m.set(key, x);
                }
                None => {
                    extra.insert(k.clone(), v.clone());
                }
            }
        }
        Ok((m, extra))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_round_trips_exactly() {
        let m = GyroModel::default();
        let (back, extra) = GyroModel::from_metadata(&m.to_metadata()).expect("parses");
        assert_eq!(back, m);
        assert!(extra.is_empty());
        assert_eq!(m.to_metadata().len(), GYRO_MODEL_KEYS.len());
    }

    #[test]
    fn absent_keys_are_zero_and_unknown_keys_are_kept() {
        let mut meta = BTreeMap::new();
        meta.insert("bias".to_string(), "1.5e-8".to_string());
        meta.insert("g_sensitivity".to_string(), "3e-9".to_string());
        let (m, extra) = GyroModel::from_metadata(&meta).expect("parses");
        assert_eq!(m.bias, 1.5e-8);
        assert_eq!(m.temp_coeff, 0.0);
        assert!(!m.earth_rate);
        assert_eq!(extra.get("g_sensitivity").map(String::as_str), Some("3e-9"));
    }

    #[test]
    fn non_numeric_value_is_an_error_naming_the_key() {
        let mut meta = BTreeMap::new();
        meta.insert("arw".to_string(), "lots".to_string());
        let e = GyroModel::from_metadata(&meta).expect_err("rejects");
        assert!(e.to_string().contains("`arw`") && e.to_string().contains("lots"));
    }

    #[test]
    fn every_key_names_its_field() {
        for (i, k) in ModelKey::ALL.into_iter().enumerate() {
            assert_eq!(GYRO_MODEL_KEYS[i], k.key());
            assert_eq!(ModelKey::from_key(k.key()), Some(k));
            let mut m = GyroModel::zero();
            m.set(k, 1.0);
            assert_eq!(m.get(k), 1.0, "{}", k.key());
            let changed: Vec<ModelKey> =
                ModelKey::ALL.into_iter().filter(|o| m.get(*o) != 0.0).collect();
            assert_eq!(changed, [k], "{}", k.key());
        }
        assert_eq!(ModelKey::from_key("g_sensitivity"), None);
    }

    #[test]
    fn file_keys_name_every_key_once_and_the_lists_derive_from_the_table() {
        for k in ModelKey::ALL {
            assert_eq!(ModelKey::from_file_key(k.file_key()), Some(k));
            assert!(k.file_key().starts_with(k.key()), "{}", k.file_key());
        }
        assert_eq!(ACCEPTANCE_KEYS[0], "bias_rad_s");
        assert_eq!(ACCEPTANCE_KEYS[5], "bias_instability_rad_s");
        assert_eq!(HOLDABLE_KEYS, ModelKey::CALIBRATED.map(ModelKey::file_key));
        assert_eq!(ModelKey::from_file_key("bias"), None);
    }

    #[test]
    fn one_validation_for_every_source_of_a_model() {
        assert_eq!(GyroModel::default().validate(), Ok(()));
        assert_eq!(GyroModel::zero().validate(), Ok(()));
        let bad = |key: ModelKey, v: f64| {
            let mut m = GyroModel::default();
            m.set(key, v);
            m.validate().map_err(|(k, _)| k)
        };
        assert_eq!(bad(ModelKey::ScaleFactorError, -1.0), Err(ModelKey::ScaleFactorError));
        assert_eq!(bad(ModelKey::ScaleFactorError, -0.999), Ok(()));
        assert_eq!(bad(ModelKey::Bias, -1.0), Ok(()));
        assert_eq!(bad(ModelKey::Bias, f64::NAN), Err(ModelKey::Bias));
        assert_eq!(bad(ModelKey::Arw, -1e-9), Err(ModelKey::Arw));
        assert_eq!(
            bad(ModelKey::ThermalTimeConstant, f64::INFINITY),
            Err(ModelKey::ThermalTimeConstant)
        );
        assert_eq!(bad(ModelKey::TempRateCoeff, -3.0), Ok(()));
        assert_eq!(ModelKey::ScaleFactorError.check(-2.0), Err("must be finite and above -1"));
        assert_eq!(ModelKey::BiasInstability.check(-1.0), Err("must be finite and not negative"));
    }

    #[test]
    fn default_noise_gives_0_002_deg_h_at_100_s() {
        let m = GyroModel::default();
        let adev_100 = ((m.arw / 10.0).powi(2) + m.bias_instability.powi(2)).sqrt();
        assert!((adev_100 / DEG_PER_H - 0.002).abs() < 1e-9);
    }
}
