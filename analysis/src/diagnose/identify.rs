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
    /// The other term: a nominal parameter's key or an accepted effect's key; or a set of them
    /// that together hold the effect where no single one does ([`Self::with_name`]).
    pub with: Vec<String>,
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

impl Collinearity {
    /// The other term's name, a set's as `a + b`.
    pub fn with_name(&self) -> String {
        self.with.join(" + ")
    }
}

/// A term of the final model: its name and its columns' indices in the design.
pub(super) struct Term {
    pub name: String,
    pub cols: Vec<usize>,
}

/// The linear parameter whose size is bounded (the first size the effect reports), and its
/// unit.
fn bounded_parameter(id: EffectId) -> (&'static str, &'static str) {
    id.effect().reported().iter().find(|r| r.is_size()).map_or(("", ""), |r| (r.name(), r.unit()))
}

/// 95 % upper bound of a term's size: `|θ| + 1.96σ`, or a sinusoid's amplitude `+ 2.45σ`
/// (√χ²₂(0.95)).
fn bound(t: &TermTest) -> f64 {
    let (size, sigma) = t.size();
    let z = if t.theta.len() == 2 { 2.45 } else { 1.96 };
    size + z * sigma
}

/// The summed variances of a term's coefficients (noise model).
pub(super) fn trace(t: &TermTest) -> f64 {
    (0..t.theta.len()).map(|a| t.cov[(a, a)]).sum()
}

/// Most terms in a set that together hold an effect no single term does (beyond it, the
/// confusion is the whole model's, and a set says little).
const MAX_SET: usize = 3;

/// Every pair of `effects` (id, accepted, grid value, columns; an accepted effect's columns are in
/// `design` too, at the indices of its [`Term`]) with the `terms` of the final `design`: the
/// pairs that reach [`COLLINEAR_RHO`] are the ones reported.
///
/// Two more cases are measured, because a pair alone misses them:
/// - **an effect the design spans** (its regressors a combination of the model's to 1e-9: a
///   rate² term on a run at one |rate| is a bias plus a scale factor): no σ exists with the
///   model as it is, so each term whose removal frees the effect is paired with it at `ρ = 1`,
///   with an infinite σ and bound (any size is absorbed); if no single term does, the pairs of
///   terms that do;
/// - **a set of terms** that together hold an effect no single one does: when every pair stays
///   below [`COLLINEAR_RHO`], terms are added greedily (the one that raises `ρ` most) until the
///   set reaches it, at most [`MAX_SET`] of them ([`Collinearity::with`] lists them).
///
/// `sets` asks for the collinearity of an effect with a given set of terms as well (a
/// recording's set, measured again on a suggested run).
pub(super) fn collinear_pairs(
    design: &[Vec<f64>],
    terms: &[Term],
    effects: &[(EffectId, bool, f64, Vec<Vec<f64>>)],
    y: &[f64],
    noise: &BinNoise,
    sets: &[(EffectId, Vec<String>)],
) -> Vec<Collinearity> {
    let all: Vec<usize> = (0..noise.len()).collect();
    let mut out = Vec::new();
    for (id, accepted, p, cols) in effects {
        let own = terms.iter().find(|t| t.name == id.key()).map(|t| t.cols.clone());
        let without_own: Vec<usize> =
            (0..design.len()).filter(|j| own.as_ref().is_none_or(|o| !o.contains(j))).collect();
        // The effect's test against the design without its own columns and those of `skip`.
        let test_without = |skip: &[&Term]| -> Option<TermTest> {
            let kept: Vec<Vec<f64>> = without_own
                .iter()
                .filter(|j| !skip.iter().any(|t| t.cols.contains(j)))
                .map(|&j| design[j].clone())
                .collect();
            Projector::new(&kept, &all).ok()?.test(cols, y, noise)
        };
        let others: Vec<&Term> = terms.iter().filter(|t| t.name != id.key()).collect();
        let (parameter, unit) = bounded_parameter(*id);
        let entry =
            |with: &[&Term], rho: f64, inflation: f64, sigma: f64, bound: f64| Collinearity {
                effect: *id,
                effect_accepted: *accepted,
                grid_value: *p,
                with: with.iter().map(|t| t.name.clone()).collect(),
                rho,
                sigma_inflation: inflation,
                sigma,
                bound,
                parameter,
                unit,
            };
        let Some(t_full) = test_without(&[]) else {
            // Spanned by the design: the terms (or pairs of terms) whose removal frees it.
            let singles: Vec<&Term> =
                others.iter().copied().filter(|t| test_without(&[t]).is_some()).collect();
            let freeing: Vec<Vec<&Term>> = if singles.is_empty() {
                let mut v = Vec::new();
                for (a, ta) in others.iter().enumerate() {
                    for tb in &others[a + 1..] {
                        if test_without(&[ta, tb]).is_some() {
                            v.push(vec![*ta, *tb]);
                        }
                    }
                }
                v
            } else {
                singles.into_iter().map(|t| vec![t]).collect()
            };
            for set in freeing {
                let inf = f64::INFINITY;
                out.push(entry(&set, 1.0, inf, inf, inf));
            }
            continue;
        };
        let vf = trace(&t_full);
        if vf.is_nan() || vf <= 0.0 {
            continue;
        }
        // ρ of the effect with the set `skip` (given the rest), and the σ ratio.
        let rho_with = |skip: &[&Term]| -> Option<(f64, f64)> {
            let vm = trace(&test_without(skip)?);
            if vm.is_nan() || vm <= 0.0 {
                return None;
            }
            let vif = (vf / vm).max(1.0);
            Some(((1.0 - 1.0 / vif).sqrt(), vif.sqrt()))
        };
        let bound_full = bound(&t_full);
        let mut best_single = 0.0f64;
        for term in &others {
            let Some((rho, inflation)) = rho_with(&[term]) else { continue };
            best_single = best_single.max(rho);
            out.push(entry(&[term], rho, inflation, vf.sqrt(), bound_full));
        }
        let mut pushed: Vec<Vec<String>> = Vec::new();
        // A set, when no single term holds the effect but the whole model might.
        if best_single < COLLINEAR_RHO
            && others.len() >= 2
            && rho_with(&others).is_some_and(|(rho, _)| rho >= COLLINEAR_RHO)
        {
            let mut set: Vec<&Term> = Vec::new();
            let mut reached = None;
            while set.len() < MAX_SET {
                let step = others
                    .iter()
                    .filter(|t| !set.iter().any(|s| s.name == t.name))
                    .filter_map(|t| {
                        let mut s = set.clone();
                        s.push(t);
                        rho_with(&s).map(|r| (*t, r))
                    })
                    .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0));
                let Some((t, r)) = step else { break };
                set.push(t);
                if r.0 >= COLLINEAR_RHO {
                    reached = Some(r);
                    break;
                }
            }
            if let (Some((rho, inflation)), true) = (reached, set.len() >= 2) {
                let e = entry(&set, rho, inflation, vf.sqrt(), bound_full);
                pushed.push(e.with.clone());
                out.push(e);
            }
        }
        // Sets asked for.
        for (_, names) in sets.iter().filter(|(e, n)| e == id && !pushed.contains(n)) {
            let set: Vec<&Term> =
                others.iter().copied().filter(|t| names.contains(&t.name)).collect();
            if set.len() < 2 {
                continue;
            }
            if let Some((rho, inflation)) = rho_with(&set) {
                out.push(entry(&set, rho, inflation, vf.sqrt(), bound_full));
            }
        }
    }
    out.sort_by(|a, b| b.rho.total_cmp(&a.rho));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::series::test_bins;
    use crate::joint_fit::NoiseSpec;

    const N: usize = 400;

    fn noise() -> BinNoise {
        let bins = test_bins(N);
        BinNoise::new(&bins, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 })
    }

    /// Mutually orthogonal zero-mean columns: sinusoids of distinct whole numbers of cycles.
    fn wave(cycles: f64) -> Vec<f64> {
        (0..N)
            .map(|i| (std::f64::consts::TAU * cycles * (i as f64 + 0.5) / N as f64).sin())
            .collect()
    }

    fn term(name: &str, j: usize) -> Term {
        Term { name: name.into(), cols: vec![j] }
    }

    fn add(a: &[f64], b: &[f64], k: f64) -> Vec<f64> {
        a.iter().zip(b).map(|(x, y)| x + k * y).collect()
    }

    #[test]
    fn an_effect_the_model_spans_is_paired_with_the_terms_that_free_it_at_rho_one() {
        // A table that turns at one |rate| the whole run: a rate² column is a constant, which is
        // the bias; the scale factor (±1) has nothing to do with it.
        let bias = vec![1.0; N];
        let sf: Vec<f64> = (0..N).map(|i| if (i / 40) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let rate2 = vec![8.5e-6; N];
        let y = wave(3.0);
        let pairs = collinear_pairs(
            &[bias, sf],
            &[term("bias", 0), term("scale_factor_error", 1)],
            &[(EffectId::RateSquared, false, f64::NAN, vec![rate2])],
            &y,
            &noise(),
            &[],
        );
        assert_eq!(pairs.len(), 1, "{pairs:?}");
        let c = &pairs[0];
        assert_eq!((c.with_name().as_str(), c.rho), ("bias", 1.0), "{c:?}");
        assert!(c.bound.is_infinite() && c.sigma.is_infinite(), "{c:?}");
    }

    #[test]
    fn two_terms_that_together_hold_an_effect_are_named_as_a_set() {
        // x1 and x2 share the direction u; the effect is u plus a little of its own. Either term
        // alone, the other still takes u (each pair's ρ is low); without both, nothing does.
        let (u, a, b, w) = (wave(1.0), wave(2.0), wave(3.0), wave(4.0));
        let x1 = add(&u, &a, 0.05);
        let x2 = add(&u, &b, 0.05);
        let e = add(&u, &w, 0.1);
        let y = wave(5.0);
        let run = |sets: &[(EffectId, Vec<String>)]| {
            collinear_pairs(
                &[vec![1.0; N], x1.clone(), x2.clone()],
                &[term("bias", 0), term("temp_coeff", 1), term("temp_rate_coeff", 2)],
                &[(EffectId::ThermalLag, false, 400.0, vec![e.clone()])],
                &y,
                &noise(),
                sets,
            )
        };
        let pairs = run(&[]);
        let single = |name: &str| pairs.iter().find(|c| c.with == [name]).expect(name).rho;
        assert!(single("temp_coeff") < 0.7 && single("temp_rate_coeff") < 0.7, "{pairs:?}");
        let set = pairs.iter().find(|c| c.with.len() > 1).expect("a set");
        assert_eq!(set.with_name(), set.with.join(" + "));
        let mut names: Vec<&str> = set.with.iter().map(String::as_str).collect();
        names.sort_unstable();
        assert_eq!(names, ["temp_coeff", "temp_rate_coeff"], "{set:?}");
        // ‖e‖² = 1.01 over what the design leaves of it (≈ 0.01): ρ ≈ 0.995.
        assert!(set.rho > 0.99 && set.rho < 1.0, "{set:?}");
        // A set asked for is measured even when below the threshold: here the set with the bias.
        let asked = run(&[(EffectId::ThermalLag, vec!["bias".into(), "temp_coeff".into()])]);
        let c =
            asked.iter().find(|c| c.with_name() == "bias + temp_coeff").expect("the set asked for");
        assert!(c.rho < COLLINEAR_RHO, "{c:?}");
    }
}
