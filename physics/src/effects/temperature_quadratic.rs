//! `temperature_quadratic`: bias quadratic in temperature.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// Bias quadratic in temperature: `c₂·(T − T0)²`.
pub struct TemperatureQuadratic;

impl LinearEffect for TemperatureQuadratic {
    fn key(&self) -> &'static str {
        "temperature_quadratic"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "bias curves with temperature: a term in (T − T0)² beside the linear one"
    }
    fn shape(&self) -> &'static str {
        "(T − T0)²"
    }
    fn formula(&self) -> &'static str {
        "`c₂·(T − T0)²`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] =
            &[Param::finite("coeff_rad_s_per_c2", "rad/s/°C²", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.temp_minus_ref_c * s.temp_minus_ref_c;
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::Temperature
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "temp_coeff", when: "a narrow temperature span" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::ThermalRamps
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "coeff_rad_s_per_c2", unit: "rad/s/°C²", index: 0 }]
    }
}
