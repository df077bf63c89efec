//! `once_per_revolution`: output periodic once per table revolution.

use super::{
    sin_cos, Columns, EffectSample, Family, LinearEffect, Order, Owner, Param, Procedure, Reported,
    Rival, Role,
};

/// `a·sin(θ + φ)`, θ the table angle.
pub struct OncePerRevolution;

impl LinearEffect for OncePerRevolution {
    fn key(&self) -> &'static str {
        "once_per_revolution"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "output periodic once per table revolution: a tilted sensing axis picking up \
         the horizontal Earth rate, or magnetic (Faraday) sensitivity"
    }
    fn shape(&self) -> &'static str {
        "table angle, 1 cycle/rev"
    }
    fn formula(&self) -> &'static str {
        "`a·sin(θ + φ)`, θ the table angle"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("amplitude_rad_s", "rad/s", Role::Amplitude),
            Param::finite("phase_rad", "rad", Role::Phase),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        2
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        sin_cos(s.angle_mid_rad, out);
    }
    fn columns(&self) -> Columns {
        Columns::Angle(Order::One)
    }
    fn family(&self) -> Family {
        Family::AngleHarmonics
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "angle_harmonic", when: "arcs short of a full turn" },
            Rival {
                with: "periodic_bias",
                when: "slow turns, each revolution about as long as the period",
            },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::Amplitude { name: "amplitude_rad_s", unit: "rad/s" },
            Reported::Fixed { name: "cycles_per_rev", value: 1.0, unit: "1" },
            Reported::Phase,
        ]
    }
}
