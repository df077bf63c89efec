//! `scale_factor_temperature`: scale factor linear in temperature.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// Scale factor linear in temperature: `k_sT·(T − T0)·Ω_in`.
pub struct ScaleFactorTemperature;

impl LinearEffect for ScaleFactorTemperature {
    fn key(&self) -> &'static str {
        "scale_factor_temperature"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "scale factor changes with temperature (source wavelength, coil length): an \
         error ∝ rate × (T − T0) that flips sign with the direction of rotation"
    }
    fn shape(&self) -> &'static str {
        "(T − T0)·Ω_in (scale factor vs T)"
    }
    fn formula(&self) -> &'static str {
        "`k_sT·(T − T0)·Ω_in`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::finite("coeff_per_c", "1/°C", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.temp_minus_ref_c * s.input_rad_s;
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::Temperature
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "temp_coeff", when: "each temperature seen in one direction only" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::ThermalRamps
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "coeff_per_c", unit: "1/°C", index: 0 }]
    }
}
