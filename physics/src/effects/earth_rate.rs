//! `earth_rate`: Earth's rotation along the sensing axis that the nominal model leaves out.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival,
};

/// Earth's rotation that the nominal model leaves out: on or off, no parameter.
pub struct EarthRate;

impl LinearEffect for EarthRate {
    fn key(&self) -> &'static str {
        "earth_rate"
    }
    fn owner(&self) -> Owner {
        Owner::Site
    }
    fn description(&self) -> &'static str {
        "Earth's rotation along the sensing axis (Ω_E·sin latitude), left out of the model"
    }
    fn shape(&self) -> &'static str {
        "Earth's rate (a constant)"
    }
    fn formula(&self) -> &'static str {
        "`(1 + s)·Ω_E·sin(lat)` where the model leaves Earth out"
    }
    fn params(&self) -> &'static [Param] {
        &[]
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.earth_rad_s;
    }
    fn columns(&self) -> Columns {
        Columns::EarthRate
    }
    fn family(&self) -> Family {
        Family::None
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "bias", when: "always at one site with the axis one way up" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::AxisTurnedOver
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::EarthRate, Reported::Latitude]
    }
}
