//! `bias_step`: a sudden bias jump at one instant.

use super::{
    Columns, Effect, EffectSample, Family, Grid, Owner, Param, Procedure, Refinement, Reported,
    Rival, Role,
};

/// `b·H(t − t_s)`.
pub struct BiasStep;

impl Effect for BiasStep {
    fn key(&self) -> &'static str {
        "bias_step"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "a sudden bias jump at one instant (mode hop, shock, reset)"
    }
    fn shape(&self) -> &'static str {
        "a bias step"
    }
    fn formula(&self) -> &'static str {
        "`b·H(t − t_s)`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("time_s", "s", Role::Grid),
            Param::finite("step_rad_s", "rad/s", Role::Coefficient(0)),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]) {
        out[0] = if s.t_s >= p { 1.0 } else { 0.0 };
    }
    fn columns(&self) -> Columns {
        Columns::AtBinStart
    }
    fn grid(&self) -> Grid {
        Grid::BinStarts { positions: 100 }
    }
    fn refinement(&self) -> Refinement {
        Refinement::BinStarts
    }
    fn family(&self) -> Family {
        Family::Step
    }
    fn rivals(&self) -> &'static [Rival] {
        &[Rival { with: "warm_up", when: "a step early in the run" }]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::LongerRun
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::GridValue { name: "time_s", unit: "s" },
            Reported::Linear { name: "step_rad_s", unit: "rad/s", index: 0 },
        ]
    }
}
