//! `angle_harmonic`: output periodic k ≥ 2 times per table revolution.

use super::{
    sin_cos, Columns, Effect, EffectSample, Family, Grid, Order, Owner, Param, Procedure,
    Refinement, Reported, Rival, Role,
};

/// `a·sin(k·θ + φ)`, k ≥ 2 cycles per revolution, independent of the rate (the gyro's, not
/// the table's rate).
pub struct AngleHarmonic;

impl Effect for AngleHarmonic {
    fn key(&self) -> &'static str {
        "angle_harmonic"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "output periodic k ≥ 2 times per table revolution whatever the rate: the \
         gyro's own angle-dependent error (an asymmetric mount or magnetic shield, a \
         field gradient across the table) rather than the table's rate ripple"
    }
    fn shape(&self) -> &'static str {
        "table angle, k cycles/rev"
    }
    fn formula(&self) -> &'static str {
        "`a·sin(k·θ + φ)`, k ≥ 2 cycles per revolution, independent of the rate"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("amplitude_rad_s", "rad/s", Role::Amplitude),
            Param::positive("cycles_per_rev", "1", Role::Grid),
            Param::finite("phase_rad", "rad", Role::Phase),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        2
    }
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]) {
        sin_cos(p * s.angle_mid_rad, out);
    }
    fn columns(&self) -> Columns {
        Columns::Angle(Order::Grid)
    }
    fn grid(&self) -> Grid {
        Grid::Harmonics
    }
    fn refinement(&self) -> Refinement {
        Refinement::None
    }
    fn family(&self) -> Family {
        Family::AngleHarmonics
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "once_per_revolution", when: "arcs short of a full turn" },
            Rival { with: "rate_ripple", when: "one table rate" },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::Amplitude { name: "amplitude_rad_s", unit: "rad/s" },
            Reported::GridValue { name: "cycles_per_rev", unit: "1" },
            Reported::Phase,
        ]
    }
}
