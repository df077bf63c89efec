//! The nominal model's effects beyond its base terms, sample by sample: physics a recording
//! already states (its `bench.gyro_model` `effect.*` keys — a simulated run records its table's
//! rate ripple there) and that a calibration of the base terms takes as known.
//!
//! A rate ripple of 1e-5 of the table's rate at 16 cycles per revolution has a 135 s period at
//! 10 °/min: over 3-minute plateaus it does not average out, and left in the data it moved the
//! temperature coefficient of `scenarios/seed.toml` by ≈ 5 % in noise-free simulations.

use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::effects::{lag_temperature, EffectId, EffectSample, Effects, HysteresisState};
use bench_physics::GyroModel;

use crate::diagnose::series::Native;

/// `effects` of `model` (Earth's rate left out: the calibration removes it through the site)
/// at every sample of `native` (the run's per-sample arrays), rad/s. `axis_up` and
/// `latitude_deg` are the site's.
pub fn effects_per_sample(
    native: &Native,
    model: &GyroModel,
    effects: &Effects,
    axis_up: bool,
    latitude_deg: Option<f64>,
) -> Vec<f64> {
    let effects = effects.without(EffectId::EarthRate);
    if !effects.any() {
        return vec![0.0; native.t.len()];
    }
    let (temp, temp_rate) = effect_temperature(native, &effects);
    let hysteresis = HysteresisState::series(effects.hysteresis_threshold_c_s(), &temp_rate);
    let axis = if axis_up { 1.0 } else { -1.0 };
    let earth = latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, axis_up));
    let earth_in = if model.earth_rate { earth } else { 0.0 };
    let scale = 1.0 + model.scale_factor_error;
    (0..native.t.len())
        .map(|k| {
            let s = EffectSample {
                t_s: native.t[k],
                input_rad_s: axis * native.table_rate_rad_s[k] + earth_in,
                table_rate_rad_s: axis * native.table_rate_rad_s[k],
                temp_minus_ref_c: temp[k] - model.reference_temperature,
                angle_mid_rad: native.angle_mid_rad[k],
                hysteresis: hysteresis[k],
                earth_rad_s: earth,
            };
            effects.value(&s, scale)
        })
        .collect()
}

/// The temperature the effects see at every sample of `native`, and its rate (°C, °C/s): the
/// model temperature, or with an effect's thermal lag, the lagged one (rate from the lag's own
/// equation, dT/dt = (T_in − T)/τ).
pub fn effect_temperature(native: &Native, effects: &Effects) -> (Vec<f64>, Vec<f64>) {
    if !effects.has(EffectId::ThermalLag) {
        return (native.temp_c.clone(), native.temp_rate_c_s.clone());
    }
    let tau = effects.lag_s();
    let lagged = lag_temperature(&native.t, &native.temp_c, tau);
    let rate = native.temp_c.iter().zip(&lagged).map(|(a, b)| (a - b) / tau).collect();
    (lagged, rate)
}
