//! `rate_squared`: output proportional to the square of the input rate.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// `c·Ω_in²`.
pub struct RateSquared;

impl LinearEffect for RateSquared {
    fn key(&self) -> &'static str {
        "rate_squared"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "output error ∝ rate² (scale-factor asymmetry / nonlinearity), the same for \
         both directions"
    }
    fn shape(&self) -> &'static str {
        "Ω_in² (the same either direction)"
    }
    fn formula(&self) -> &'static str {
        "`c·Ω_in²`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::finite("coeff_s_per_rad", "s/rad", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.input_rad_s * s.input_rad_s;
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::RateShape
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "bias", when: "a run at one |rate| without rests" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "coeff_s_per_rad", unit: "s/rad", index: 0 }]
    }
}
