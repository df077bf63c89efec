//! The gyro's error model, with the parameter names and units of `bench.gyro_model` in the
//! recording contract (`shared/spec/recording.md`).
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

/// Keys of `bench.gyro_model`, in contract order.
pub const GYRO_MODEL_KEYS: [&str; 9] = [
    "bias",
    "scale_factor_error",
    "reference_temperature",
    "temp_coeff",
    "temp_rate_coeff",
    "arw",
    "bias_instability",
    "earth_rate",
    "thermal_time_constant",
];

impl Default for GyroModel {
    /// The seed's gyro (`shared/seed/README.md`), made concrete:
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

    /// As `bench.gyro_model` metadata: every key, numbers as decimal text (shortest
    /// round-tripping form).
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        let mut put = |k: &str, v: f64| {
            m.insert(k.to_string(), format!("{v:e}"));
        };
        put("bias", self.bias);
        put("scale_factor_error", self.scale_factor_error);
        put("reference_temperature", self.reference_temperature);
        put("temp_coeff", self.temp_coeff);
        put("temp_rate_coeff", self.temp_rate_coeff);
        put("arw", self.arw);
        put("bias_instability", self.bias_instability);
        put("thermal_time_constant", self.thermal_time_constant);
        m.insert("earth_rate".into(), if self.earth_rate { "1" } else { "0" }.into());
        m
    }

    /// From `bench.gyro_model` metadata: absent keys are zero; keys this model does not know
    /// are returned beside it, to be kept and reported.
    pub fn from_metadata(
        meta: &BTreeMap<String, String>,
    ) -> Result<(Self, BTreeMap<String, String>), ModelKeyError> {
        let mut m = Self::zero();
        let mut extra = BTreeMap::new();
        for (k, v) in meta {
            let num = || {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| ModelKeyError { key: k.clone(), value: v.clone() })
            };
            match k.as_str() {
                "bias" => m.bias = num()?,
                "scale_factor_error" => m.scale_factor_error = num()?,
                "reference_temperature" => m.reference_temperature = num()?,
                "temp_coeff" => m.temp_coeff = num()?,
                "temp_rate_coeff" => m.temp_rate_coeff = num()?,
                "arw" => m.arw = num()?,
                "bias_instability" => m.bias_instability = num()?,
                "thermal_time_constant" => m.thermal_time_constant = num()?,
                "earth_rate" => m.earth_rate = num()? != 0.0,
                _ => {
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
    fn default_noise_gives_0_002_deg_h_at_100_s() {
        let m = GyroModel::default();
        let adev_100 = ((m.arw / 10.0).powi(2) + m.bias_instability.powi(2)).sqrt();
        assert!((adev_100 / DEG_PER_H - 0.002).abs() < 1e-9);
    }
}
