//! `rate_ripple`: the table's rate ripples N times per revolution.

use super::{
    Columns, Effect, EffectSample, Family, Grid, Owner, Param, Procedure, Refinement, Reported,
    Rival, Role,
};

/// `ε·Ω_t·sin(N·θ + φ)`, Ω_t the table's rate along the sensing axis: the table's own motion,
/// below its angle readout's resolution.
pub struct RateRipple;

impl Effect for RateRipple {
    fn key(&self) -> &'static str {
        "rate_ripple"
    }
    fn owner(&self) -> Owner {
        Owner::Table
    }
    fn description(&self) -> &'static str {
        "the table's rate ripples N times per revolution (torque-motor cogging, encoder \
         errors) by less than its angle readout resolves: the gyro sees ε·Ω·sin(Nθ + φ) \
         that the recorded table motion does not show"
    }
    fn shape(&self) -> &'static str {
        "table rate ripple (∝ rate)"
    }
    fn formula(&self) -> &'static str {
        "`ε·Ω_t·sin(N·θ + φ)`, Ω_t the table's rate along the sensing axis"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("relative_amplitude", "1", Role::Amplitude),
            Param::positive("cycles_per_rev", "1", Role::Grid),
            Param::finite("phase_rad", "rad", Role::Phase),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        2
    }
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]) {
        let (sin, cos) = (p * s.angle_mid_rad).sin_cos();
        out[0] = s.table_rate_rad_s * sin;
        out[1] = s.table_rate_rad_s * cos;
    }
    fn columns(&self) -> Columns {
        Columns::Ripple
    }
    fn grid(&self) -> Grid {
        Grid::CyclesPerRev { from: 2, to: 64 }
    }
    fn refinement(&self) -> Refinement {
        Refinement::None
    }
    fn family(&self) -> Family {
        Family::RippleOrders
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "angle_harmonic", when: "one table rate" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::Amplitude { name: "relative_amplitude", unit: "1" },
            Reported::GridValue { name: "cycles_per_rev", unit: "1" },
            Reported::Phase,
        ]
    }
}
