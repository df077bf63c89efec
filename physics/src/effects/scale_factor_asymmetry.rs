//! `scale_factor_asymmetry`: the scale factor differs between clockwise and counter-clockwise
//! input (IEEE Std 952's scale-factor asymmetry).

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// `a·|Ω_in|`: the scale factor `1 + s + a` for positive input, `1 + s − a` for negative.
pub struct ScaleFactorAsymmetry;

impl LinearEffect for ScaleFactorAsymmetry {
    fn key(&self) -> &'static str {
        "scale_factor_asymmetry"
    }
    fn owner(&self) -> Owner {
        Owner::Gyro
    }
    fn description(&self) -> &'static str {
        "the scale factor differing between positive and negative input rates (CW against \
         CCW): an error linear in speed, the same sign either direction"
    }
    fn shape(&self) -> &'static str {
        "|Ω_in| (linear in speed, either direction)"
    }
    fn formula(&self) -> &'static str {
        "`a·sgn(Ω_in)·Ω_in`: scale factor `1 + s ± a` for ±Ω_in"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::finite("asymmetry", "1", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        1
    }
    fn regressors(&self, s: &EffectSample, out: &mut [f64]) {
        out[0] = s.input_rad_s.abs();
    }
    fn columns(&self) -> Columns {
        Columns::PerSample
    }
    fn family(&self) -> Family {
        Family::RateShape
    }
    fn rivals(&self) -> &'static [Rival] {
        &[
            Rival { with: "rate_squared", when: "turns at one |rate| (with rests or not)" },
            Rival { with: "bias", when: "a run at one |rate| without rests" },
        ]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "asymmetry", unit: "1", index: 0 }]
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EffectId, EffectSample, Effects};

    #[test]
    fn the_asymmetry_adds_to_the_scale_factor_one_way_and_takes_away_the_other() {
        let e = Effects::default().with(EffectId::ScaleFactorAsymmetry, &[3e-5]).expect("one");
        let at = |w: f64| e.value(&EffectSample { input_rad_s: w, ..EffectSample::default() }, 1.0);
        // (1 + a)·Ω for Ω > 0, (1 − a)·Ω for Ω < 0: the error a·|Ω| either way.
        assert!((at(0.002) - 6e-8).abs() < 1e-22);
        assert!((at(-0.002) - 6e-8).abs() < 1e-22);
        assert_eq!(at(0.0), 0.0);
    }
}
