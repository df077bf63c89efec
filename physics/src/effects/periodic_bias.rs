//! `periodic_bias`: bias oscillating in time with a period of its own.

use super::{
    Columns, Effect, EffectSample, Family, Grid, Owner, Param, Procedure, Refinement, Reported,
    Rival, Role,
};

/// `a·sin(2π·t/P + φ)`.
pub struct PeriodicBias;

impl Effect for PeriodicBias {
    fn key(&self) -> &'static str {
        "periodic_bias"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "bias oscillating in time with a period unrelated to the table or the test \
         profile: environment cycling (lab air conditioning, the chamber's compressor, \
         nearby equipment) reaching the gyro or its electronics"
    }
    fn shape(&self) -> &'static str {
        "a sinusoid in time"
    }
    fn formula(&self) -> &'static str {
        "`a·sin(2π·t/P + φ)`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[
            Param::finite("amplitude_rad_s", "rad/s", Role::Amplitude),
            Param::positive("period_s", "s", Role::Grid),
            Param::finite("phase_rad", "rad", Role::Phase),
        ];
        P
    }
    fn linear_count(&self) -> usize {
        2
    }
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]) {
        let (sin, cos) =
            if p > 0.0 { (std::f64::consts::TAU * s.t_s / p).sin_cos() } else { (0.0, 0.0) };
        out[0] = sin;
        out[1] = cos;
    }
    fn columns(&self) -> Columns {
        Columns::Periodic
    }
    fn grid(&self) -> Grid {
        Grid::Periods { min_s: 120.0, min_cycles: 4.0, most: 300 }
    }
    /// Under four cycles in the run a sinusoid is too free a shape to search for (it takes a
    /// warm-up and a later step between them, and the search names what is left), but a slow
    /// shape found is not named where such a sinusoid explains the residual as well.
    fn rival_grid(&self) -> Grid {
        Grid::Periods { min_s: 120.0, min_cycles: 1.5, most: 300 }
    }
    fn refinement(&self) -> Refinement {
        Refinement::EvenInFrequency { each_side: 8 }
    }
    fn family(&self) -> Family {
        Family::PeriodShape
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "bias_step", when: "a few cycles in the run" },
            Rival { with: "bias_drift", when: "a few cycles in the run" },
            Rival { with: "warm_up", when: "a few cycles in the run" },
            Rival { with: "temperature_quadratic", when: "a few cycles in the run" },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::LongerRun
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::Amplitude { name: "amplitude_rad_s", unit: "rad/s" },
            Reported::GridValue { name: "period_s", unit: "s" },
            Reported::Phase,
        ]
    }
}
