//! `warm_up`: bias settling exponentially after power-on.

use super::{
    Columns, Effect, EffectSample, Family, Grid, Owner, Param, Procedure, Refinement, Reported,
    Rival, Role,
};

/// `A·e^{−(t − t_on)/τ}`.
pub struct WarmUp;

impl Effect for WarmUp {
    fn key(&self) -> &'static str {
        "warm_up"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "bias settling exponentially after power-on as the source and electronics warm"
    }
    fn shape(&self) -> &'static str {
        "a decay after power-on"
    }
    fn formula(&self) -> &'static str {
        "`A·e^{−(t − t_on)/τ}`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("amplitude_rad_s", "rad/s", Role::Coefficient(0)),
            Param::positive("time_constant_s", "s", Role::Grid),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]) {
        out[0] = if p > 0.0 { (-s.t_s / p).exp() } else { 0.0 };
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn grid(&self) -> Grid {
        Grid::TimeConstants(&[60., 120., 240., 400., 600., 900., 1400., 2000., 3000.])
    }
    fn refinement(&self) -> Refinement {
        Refinement::FinalEvenInLog { each_side: 5 }
    }
    fn family(&self) -> Family {
        Family::Decay
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "bias_step", when: "a step early in the run" },
            Rival {
                with: "scale_factor_asymmetry",
                when: "each table rate in its own part of the run (a decay in time moves one \
                       |rate|'s level against the others)",
            },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::LongerRun
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::Linear { name: "amplitude_rad_s", unit: "rad/s", index: 0 },
            Reported::GridValue { name: "time_constant_s", unit: "s" },
        ]
    }
}
