//! `thermal_hysteresis`: the bias remembers whether the gyro last heated or cooled.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// Default hysteresis threshold: 0.1 °C/min.
pub const HYSTERESIS_THRESHOLD_C_S: f64 = 0.1 / 60.0;

/// Heating/cooling hysteresis of the bias: `h·m`, m the [`super::HysteresisState`].
pub struct ThermalHysteresis;

impl LinearEffect for ThermalHysteresis {
    fn key(&self) -> &'static str {
        "thermal_hysteresis"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "bias differs after heating and after cooling (stress in the coil potting \
         relaxes with the direction of the last temperature change)"
    }
    fn shape(&self) -> &'static str {
        "heating vs cooling (hysteresis)"
    }
    fn formula(&self) -> &'static str {
        "`h·m`, m = +1 after heating, −1 after cooling, 0 before either"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("half_width_rad_s", "rad/s", Role::Coefficient(0)),
            Param::positive("threshold_c_s", "°C/s", Role::Setting(HYSTERESIS_THRESHOLD_C_S)),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.hysteresis;
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::Temperature
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "thermal_lag", when: "every ramp at one |dT/dt|" },
            Rival { with: "temp_rate_coeff", when: "every ramp at one |dT/dt|" },
            // One switch between heating and cooling is one jump of the bias: a step.
            Rival { with: "bias_step", when: "one switch between heating and cooling" },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::ThermalRamps
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "half_width_rad_s", unit: "rad/s", index: 0 }]
    }
}
