//! `thermal_lag`: the fibre coil's temperature lags the one the model uses.

use super::{
    Columns, Effect, EffectSample, Family, Grid, Owner, Param, Procedure, Refinement, Reported,
    Rival, Role,
};

/// The bias terms follow the temperature through a first-order lag.
pub struct ThermalLag;

impl Effect for ThermalLag {
    fn key(&self) -> &'static str {
        "thermal_lag"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "the fibre coil's temperature lags the measured temperature by a first-order \
         time constant, so the thermal bias follows the temperature late"
    }
    fn shape(&self) -> &'static str {
        "the thermal terms through a lag"
    }
    fn formula(&self) -> &'static str {
        "the thermal terms driven by `T_c`, the sensor temperature through a lag τ"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::positive("time_constant_s", "s", Role::Grid)];
        P
    }
    fn linear_count(&self) -> usize {
        0
    }
    fn regressors(&self, _s: &EffectSample, _p: f64, _out: &mut [f64]) {
        // Applied to the temperature (`lag_temperature`), not added to the output.
    }
    fn columns(&self) -> Columns {
        Columns::ThermalLag
    }
    fn grid(&self) -> Grid {
        Grid::TimeConstants(&[30., 60., 120., 240., 400., 600., 900., 1400., 2000., 3000.])
    }
    fn refinement(&self) -> Refinement {
        Refinement::FinalEvenInLog { each_side: 5 }
    }
    fn family(&self) -> Family {
        Family::Temperature
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "thermal_hysteresis", when: "every ramp at one |dT/dt|" },
            Rival { with: "temp_rate_coeff", when: "every ramp at one |dT/dt|" },
            // The lagged term settles after a ramp starts as a warm-up decays after power-on:
            // one exponential each, alike where the run's first ramp comes early.
            Rival {
                with: "warm_up",
                when: "one settling after the first ramp, early in the run (a lag's response \
                       to it decays as a warm-up does)",
            },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::ThermalRamps
    }
    fn reported(&self) -> &'static [Reported] {
        &[
            Reported::GridValue { name: "time_constant_s", unit: "s" },
            Reported::Linear { name: "gain", unit: "1", index: 0 },
        ]
    }
}
