//! Identifiability: which terms this recording cannot tell apart.
//!
//! Two terms whose regressors are nearly collinear under the noise model trade places freely:
//! a heating/cooling hysteresis on a profile whose ramps all run at 1 °C/min is almost
//! `k_dt·dT/dt`, so the refit of `k_dt` absorbs it and the search never sees it. For a term
//! `E` (an effect of the library, accepted or not) and a term `X` of the final model (a nominal
//! parameter or an accepted effect), the collinearity is measured by the variance inflation of
//! `E`'s coefficients when `X` joins the design, with the noise model's covariance (the
//! sandwich of [`super::fit`], so "whitened"): `VIF = var(θ_E | model) / var(θ_E | model
//! without X)` and `ρ = √(1 − 1/VIF)`, the multiple correlation of `E` with `X` given the rest.
//! A pair with `ρ ≥ 0.9` is reported, with the largest size of `E` that the data cannot rule
//! out (95 %: `|θ| + 1.96σ`, or for a sinusoid the amplitude plus `2.45σ`) with `X` in the
//! model.

use bench_physics::effects::EffectId;

use super::fit::{Projector, TermTest};
use super::noise::BinNoise;

/// Collinearity at and above which a pair is reported.
pub const COLLINEAR_RHO: f64 = 0.9;

/// A pair of terms that this recording cannot separate well.
#[derive(Debug, Clone, PartialEq)]
pub struct Collinearity {
    /// The effect (its key).
    pub effect: EffectId,
    /// Whether the effect is in the updated model.
    pub effect_accepted: bool,
    /// The effect's grid value (time constant, period, cycles per revolution…; NaN for none).
    pub grid_value: f64,
    /// The other term: a nominal parameter's key or an accepted effect's key.
    pub with: String,
    /// ρ, 0..1 (module docs).
    pub rho: f64,
    /// The effect's σ with the other term in the model over its σ without (√VIF).
    pub sigma_inflation: f64,
    /// The effect's σ with the other term in the model (its coefficients' summed variances,
    /// square-rooted), in `unit`.
    pub sigma: f64,
    /// The largest size of the effect the data cannot rule out with the other term in, 95 %.
    pub bound: f64,
    /// Which parameter `bound` is of (`half_width_rad_s`, `amplitude_rad_s`, …) and its unit.
    pub parameter: &'static str,
    /// Unit of `bound`.
    pub unit: &'static str,
}

/// A term of the final model: its name and its columns' indices in the design.
pub(super) struct Term {
    pub name: String,
    pub cols: Vec<usize>,
}

/// The linear parameter whose size is bounded, and its unit.
fn bounded_parameter(id: EffectId) -> (&'static str, &'static str) {
    match id {
        EffectId::EarthRate => ("rate_rad_s", "rad/s"),
        EffectId::ThermalLag => ("gain", "1"),
        EffectId::TemperatureQuadratic => ("coeff_rad_s_per_c2", "rad/s/°C²"),
        EffectId::ScaleFactorTemperature => ("coeff_per_c", "1/°C"),
        EffectId::ThermalHysteresis => ("half_width_rad_s", "rad/s"),
        EffectId::TimeOffset => ("offset_s", "s"),
        EffectId::RateSquared => ("coeff_s_per_rad", "s/rad"),
        EffectId::RateRipple => ("relative_amplitude", "1"),
        EffectId::BiasStep => ("step_rad_s", "rad/s"),
        EffectId::OncePerRevolution
        | EffectId::AngleHarmonic
        | EffectId::WarmUp
        | EffectId::PeriodicBias => ("amplitude_rad_s", "rad/s"),
    }
}

/// 95 % upper bound of a term's size: `|θ| + 1.96σ`, or a sinusoid's amplitude `+ 2.45σ`
/// (√χ²₂(0.95)).
fn bound(t: &TermTest) -> f64 {
    let (size, sigma) = t.size();
    let z = if t.theta.len() == 2 { 2.45 } else { 1.96 };
    size + z * sigma
}

fn trace(t: &TermTest) -> f64 {
    (0..t.theta.len()).map(|a| t.cov[(a, a)]).sum()
}

/// Every pair of `effects` (id, accepted, grid value, columns; an accepted effect's columns are in
/// `design` too, at the indices of its [`Term`]) with the `terms` of the final `design`: the
/// pairs that reach [`COLLINEAR_RHO`] are the ones reported.
pub(super) fn collinear_pairs(
    design: &[Vec<f64>],
    terms: &[Term],
    effects: &[(EffectId, bool, f64, Vec<Vec<f64>>)],
    y: &[f64],
    noise: &BinNoise,
) -> Vec<Collinearity> {
    let all: Vec<usize> = (0..noise.len()).collect();
    let mut out = Vec::new();
    for (id, accepted, p, cols) in effects {
        let own = terms.iter().find(|t| t.name == id.key()).map(|t| t.cols.clone());
        let without_own: Vec<usize> =
            (0..design.len()).filter(|j| own.as_ref().is_none_or(|o| !o.contains(j))).collect();
        let pick = |skip: &[usize]| -> Vec<Vec<f64>> {
            without_own.iter().filter(|j| !skip.contains(j)).map(|&j| design[j].clone()).collect()
        };
        let Ok(p_full) = Projector::new(&pick(&[]), &all) else { continue };
        let Some(t_full) = p_full.test(cols, y, noise) else { continue };
        for term in terms {
            if term.name == id.key() {
                continue;
            }
            let Ok(p_minus) = Projector::new(&pick(&term.cols), &all) else { continue };
            let Some(t_minus) = p_minus.test(cols, y, noise) else { continue };
            let (vf, vm) = (trace(&t_full), trace(&t_minus));
            if !(vf > 0.0 && vm > 0.0) {
                continue;
            }
            let vif = (vf / vm).max(1.0);
            let rho = (1.0 - 1.0 / vif).sqrt();
            let (parameter, unit) = bounded_parameter(*id);
            out.push(Collinearity {
                effect: *id,
                effect_accepted: *accepted,
                grid_value: *p,
                with: term.name.clone(),
                rho,
                sigma_inflation: vif.sqrt(),
                sigma: vf.sqrt(),
                bound: bound(&t_full),
                parameter,
                unit,
            });
        }
    }
    out.sort_by(|a, b| b.rho.total_cmp(&a.rho));
    out
}
