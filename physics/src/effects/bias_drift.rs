//! `bias_drift`: the bias trending linearly in time (IEEE Std 952's drift term: ageing, a
//! slow settling far longer than the run).

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// `D·t`.
pub struct BiasDrift;

impl LinearEffect for BiasDrift {
    fn key(&self) -> &'static str {
        "bias_drift"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "the bias trending linearly in time (ageing, a settling much slower than the run), \
         IEEE Std 952's drift"
    }
    fn shape(&self) -> &'static str {
        "a linear trend in time"
    }
    fn formula(&self) -> &'static str {
        "`D·t`, t from power-on"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::finite("slope_rad_s2", "rad/s²", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.t_s;
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::None
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "warm_up", when: "a decay much slower than the run" },
            Rival { with: "bias_step", when: "a short run, or a step near its middle" },
            Rival { with: "temp_coeff", when: "one monotonic temperature ramp" },
            Rival {
                with: "temperature_quadratic",
                when: "each temperature visited once, in one pass (a trend in time is then a \
                       curve in temperature)",
            },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::LongerRun
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "slope_rad_s2", unit: "rad/s²", index: 0 }]
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EffectId, EffectSample, Effects};

    #[test]
    fn the_drift_is_its_slope_times_the_time_since_power_on() {
        let e = Effects::default().with(EffectId::BiasDrift, &[2e-10]).expect("one parameter");
        let s = |t_s: f64| EffectSample { t_s, input_rad_s: 0.003, ..EffectSample::default() };
        assert_eq!(e.value(&s(0.0), 1.001), 0.0);
        assert!((e.value(&s(3600.0), 1.001) - 7.2e-7).abs() < 1e-21);
    }
}
