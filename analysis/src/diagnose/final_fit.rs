//! The final fit: the nominal parameters and the effects' coefficients together, and the
//! effects' parameters as a diagnosis reports them.

use super::*;

/// What the final fit gives.
pub(super) struct FinalFit {
    pub(super) parameter_updates: Vec<ParameterUpdate>,
    /// The nominal model with the refitted parameters.
    pub(super) model: GyroModel,
    /// The nominal effects with the accepted ones.
    pub(super) effects: Effects,
    /// Each accepted effect's contribution to the bins.
    pub(super) contributions: Vec<(EffectId, Vec<f64>)>,
}

/// σ of a parameter with the effects and nuisance terms in, over its σ in the refit without
/// them, beyond which they carry more than [`crate::information::CONFOUNDED`] of its
/// information (`1/√(1 − ρ²)`: 10 for ρ² = 0.99).
pub(super) fn confounded_ratio() -> f64 {
    1.0 / (1.0 - crate::information::CONFOUNDED).sqrt()
}

/// Which nominal parameters the final model does not determine, with the reason: those whose
/// σ with the effects and nuisance terms in (`with`) exceeds [`confounded_ratio`] times their σ
/// in the parameter refit without them (`without`), or that the final design drops (NaN) while
/// the refit determines them. Such a parameter is held at its nominal value and the rest are
/// refitted without it: an estimate traded between the parameter and the terms is noise of
/// any size (a 40-minute file once wrote a bias of 2.4e-3 ± 1.8e-3 rad/s into model.toml),
/// never a measurement.
pub(super) fn held_parameters(with: &[f64], without: &[f64]) -> Vec<Option<String>> {
    with.iter()
        .zip(without)
        .map(|(&w, &b)| {
            if !b.is_finite() || b <= 0.0 {
                return None;
            }
            if !w.is_finite() {
                return Some(
                    "held at the nominal value: the effects and unexplained structure in the \
                     model span it"
                        .into(),
                );
            }
            let ratio = w / b;
            (ratio > confounded_ratio()).then(|| {
                let times =
                    if ratio >= 1e3 { format!("{ratio:.2e}") } else { format!("{ratio:.1}") };
                format!(
                    "held at the nominal value: the effects and unexplained structure in the \
                     model carry {:.1} % of its information (σ {times}× the refit's without \
                     them)",
                    100.0 * (1.0 - 1.0 / (ratio * ratio))
                )
            })
        })
        .collect()
}

/// Parameters and effects' coefficients fitted together on the search's final model; each
/// accepted effect's finding gets its final parameters. `refit` is the parameter refit's
/// projector (the nominal design alone), against which a parameter is held. `lag`: the coil's
/// lag profile (fitted, or held at the lab's where the run does not determine it): what its
/// uncertainty costs each coefficient is in their covariance ([`coil_lag::lag_shift`]).
pub(super) fn final_fit(
    search: &mut Search<'_>,
    effects: &Effects,
    refit: &Projector,
    lag: Option<&coil_lag::CoilLag>,
) -> Result<FinalFit, AnalysisError> {
    let model = search.ctx.model;
    let n = search.y.len();
    let all: Vec<usize> = (0..n).collect();
    let sigmas = |proj: &Projector| -> Vec<f64> {
        let cov = proj.covariance(&search.noise);
        (0..ModelKey::CALIBRATED.len())
            .map(|j| {
                proj.kept.iter().position(|&c| c == j).map_or(f64::NAN, |c| cov[(c, c)].sqrt())
            })
            .collect()
    };
    let with_terms = sigmas(&search.proj);
    let held = held_parameters(&with_terms, &sigmas(refit));
    let mut proj = search.proj.clone();
    if held.iter().any(Option::is_some) {
        // The rest refitted with the held ones out of the design (a zero column is not kept).
        let mut design = model_design(&search.base_design, &search.accepted, None);
        for (j, h) in held.iter().enumerate() {
            if h.is_some() {
                design[j] = vec![0.0; n];
            }
        }
        proj = Projector::new(&design, &all)?;
    }
    let beta = proj.beta(&search.y);
    let mut cov = proj.covariance(&search.noise);
    if let Some(lag) = lag {
        let zeroed: Vec<bool> = held.iter().map(Option::is_some).collect();
        let (prep, base, accepted) = (search.ctx.prep, &search.base_design, &search.accepted);
        if let Some(shift) = coil_lag::lag_shift(prep, model, lag, base, &zeroed, accepted)? {
            let s = nalgebra::DVector::from_iterator(
                proj.kept.len(),
                proj.kept.iter().map(|&c| shift.get(c).copied().unwrap_or(0.0)),
            );
            cov += &s * s.transpose();
        }
    }
    let coef = |j: usize| -> (f64, f64) {
        proj.kept
            .iter()
            .position(|&c| c == j)
            .map_or((0.0, f64::NAN), |c| (beta[c], cov[(c, c)].sqrt()))
    };
    let mut parameter_updates = Vec::new();
    let mut updated = model.clone();
    for (j, key) in ModelKey::CALIBRATED.into_iter().enumerate() {
        let nominal = model.get(key);
        let held = held[j].clone();
        let (fitted, sigma) = match held {
            Some(_) => (nominal, with_terms[j]),
            None => {
                let (d, s) = coef(j);
                (nominal + d, s)
            }
        };
        parameter_updates.push(ParameterUpdate { key, nominal, fitted, sigma, held });
        updated.set(key, fitted);
    }
    // Effects' final coefficients (refitted jointly) into the findings and the model.
    let mut new_effects = *effects;
    if search.earth_found {
        apply_effect(&mut new_effects, EffectId::EarthRate, f64::NAN, &[]);
    }
    let mut col = search.base_design.len();
    let mut contributions = Vec::new();
    for i in 0..search.accepted.len() {
        let a = &search.accepted[i];
        let k = a.cols.len();
        let th: Vec<(f64, f64)> = (0..k).map(|j| coef(col + j)).collect();
        col += k;
        let mut contribution = vec![0.0; n];
        for (c, (v, _)) in a.cols.iter().zip(&th) {
            for i in 0..n {
                contribution[i] += c[i] * v;
            }
        }
        contributions.push((a.id, contribution));
        let cov_block = nalgebra::DMatrix::from_fn(k, k, |x, z| {
            let ia = proj.kept.iter().position(|&c| c == col - k + x);
            let ib = proj.kept.iter().position(|&c| c == col - k + z);
            match (ia, ib) {
                (Some(ia), Some(ib)) => cov[(ia, ib)],
                _ => 0.0,
            }
        });
        final_parameters(search, i, &th, cov_block);
        let a = &search.accepted[i];
        apply_effect(&mut new_effects, a.id, a.p, &th);
    }
    Ok(FinalFit { parameter_updates, model: updated, effects: new_effects, contributions })
}

/// The `i`-th accepted effect's finding gets its parameters from its final coefficients `th`
/// (value, σ) and their covariance `cov_block`. Its grid value's σ against the final model: a
/// continuous one's by linearisation, a discrete one's from its profile (the search's profile
/// was taken against the model of its round, where the value may differ), else the search's.
fn final_parameters(
    search: &mut Search<'_>,
    i: usize,
    th: &[(f64, f64)],
    cov_block: nalgebra::DMatrix<f64>,
) {
    let (prep, model) = (search.ctx.prep, search.ctx.model);
    let a = &search.accepted[i];
    let (id, p) = (a.id, a.p);
    let Some(f) = search.findings.iter_mut().find(|f| f.effect == id) else { return };
    let theta: Vec<f64> = th.iter().map(|x| x.0).collect();
    let t = fit::TermTest { theta: theta.clone(), cov: cov_block, wald: f.wald, delta_rss: 0.0 };
    let others = model_design(&search.base_design, &search.accepted, Some(i));
    let all: Vec<usize> = (0..search.y.len()).collect();
    let po = Projector::new(&others, &all).ok();
    let (y, noise) = (&search.y, &search.noise);
    let linear = po
        .as_ref()
        .and_then(|po| grid_sigma_linearised(prep, id, p, &a.cols, &theta, po, y, noise, model));
    let fresh = match (linear, &po) {
        (None, Some(po)) => refit_grid_profile(prep, id, po, y, noise, model, &search.column_cache)
            .map(|(_, profile)| profile),
        _ => None,
    };
    let grid_name = grid_parameter(id);
    let searched = f.parameters.iter().find(|q| Some(q.name) == grid_name).map(|q| q.sigma);
    let at_value = [(p, f.wald)];
    f.parameters = effect_parameters(id, p, &t, fresh.as_deref().unwrap_or(&at_value), prep);
    let sigma = linear.or(if fresh.is_none() { searched } else { None });
    if let (Some(s), Some(q)) = (sigma, f.parameters.iter_mut().find(|q| Some(q.name) == grid_name))
    {
        q.sigma = s;
    }
}

/// The effect's parameters in its own terms from the linear fit `t` at grid value `p`, with a
/// grid parameter's σ from the Wald profile (the span where W stays within 1 of its peak).
pub(super) fn effect_parameters(
    id: EffectId,
    p: f64,
    t: &fit::TermTest,
    profile: &[(f64, f64)],
    prep: &Prepared,
) -> Vec<EffectParameter> {
    let lin =
        |name, unit, a: usize| EffectParameter { name, value: t.theta[a], sigma: t.sigma(a), unit };
    let grid_sigma = || {
        let peak = profile.iter().map(|x| x.1).fold(f64::NEG_INFINITY, f64::max);
        let inside: Vec<f64> = profile.iter().filter(|x| x.1 >= peak - 1.0).map(|x| x.0).collect();
        let (lo, hi) = inside
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        // Half the width of the interval, at least half the local grid spacing.
        let spacing = profile
            .windows(2)
            .filter(|w| w[0].0 <= p && w[1].0 >= p)
            .map(|w| w[1].0 - w[0].0)
            .fold(f64::INFINITY, f64::min);
        let spacing = if spacing.is_finite() { spacing } else { 0.0 };
        (0.5 * (hi - lo)).max(0.5 * spacing)
    };
    let ap = || amplitude_phase(t);
    id.effect()
        .reported()
        .iter()
        .map(|r| match *r {
            Reported::Linear { name, unit, index } => {
                let mut q = lin(name, unit, index);
                if id.effect().columns() == Columns::TimeOffset {
                    // The readout's share (not in the noise model of the gyro's bins).
                    q.sigma = q.sigma.hypot(prep.readout_offset_sigma_s);
                }
                q
            }
            Reported::Amplitude { name, unit } => EffectParameter { name, unit, ..ap()[0] },
            Reported::Phase => ap()[1].clone(),
            Reported::GridValue { name, unit } => {
                EffectParameter { name, value: p, sigma: grid_sigma(), unit }
            }
            Reported::Fixed { name, value, unit } => {
                EffectParameter { name, value, sigma: 0.0, unit }
            }
            Reported::EarthRate | Reported::Latitude => {
                let rate = t.theta[0] * prep.earth;
                let s = t.sigma(0) * prep.earth.abs();
                if *r == Reported::EarthRate {
                    return EffectParameter {
                        name: r.name(),
                        value: rate,
                        sigma: s,
                        unit: r.unit(),
                    };
                }
                let e = bench_physics::earth::EARTH_RATE_RAD_S;
                let sin = (rate / e * prep.axis).clamp(-1.0, 1.0);
                let lat = sin.asin().to_degrees();
                let dlat =
                    s / (e * lat.to_radians().cos().abs().max(1e-6)) * 180.0 / std::f64::consts::PI;
                EffectParameter { name: r.name(), value: lat, sigma: dlat, unit: r.unit() }
            }
        })
        .collect()
}

/// The name of effect `id`'s reported grid parameter, if it has one.
pub(super) fn grid_parameter(id: EffectId) -> Option<&'static str> {
    id.effect().reported().iter().find(|r| r.is_grid()).map(|r| r.name())
}

/// Amplitude and phase of `a·sin(x + φ)` from the coefficients of `sin x` and `cos x`, with
/// their σ by the delta method.
pub(super) fn amplitude_phase(t: &fit::TermTest) -> Vec<EffectParameter> {
    let (a, b) = (t.theta[0], t.theta[1]);
    let (amp, amp_sigma) = t.size();
    let phase = b.atan2(a);
    // Delta method.
    let (va, vb, cab) = (t.cov[(0, 0)], t.cov[(1, 1)], t.cov[(0, 1)]);
    let ph_var = if amp > 0.0 {
        (b * b * va + a * a * vb - 2.0 * a * b * cab) / amp.powi(4)
    } else {
        f64::INFINITY
    };
    vec![
        EffectParameter { name: "amplitude_rad_s", value: amp, sigma: amp_sigma, unit: "rad/s" },
        EffectParameter {
            name: "phase_rad",
            value: phase,
            sigma: ph_var.max(0.0).sqrt(),
            unit: "rad",
        },
    ]
}

/// Put an accepted effect with its fitted parameters into `e`: its grid value `p` and its
/// coefficients `th` (value, σ) in the roles of its parameters.
pub(super) fn apply_effect(e: &mut Effects, id: EffectId, p: f64, th: &[(f64, f64)]) {
    let v = |a: usize| th.get(a).map_or(0.0, |x| x.0);
    // `a·sin x + b·cos x` as amplitude and phase of `A·sin(x + φ)`.
    let (amp, phase) = (v(0).hypot(v(1)), v(1).atan2(v(0)));
    let values: Vec<f64> = id
        .params()
        .iter()
        .map(|q| match q.role {
            Role::Coefficient(k) => v(k),
            Role::Amplitude => amp,
            Role::Phase => phase,
            Role::Grid => p,
            Role::Setting(value) => value,
        })
        .collect();
    // One value per parameter: the count always fits.
    let _ = e.set(id, &values);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_parameter_the_terms_take_over_is_held_and_the_others_are_not() {
        // The bias 8e4 times less certain with the terms in (the 40-minute file's), the scale
        // factor 1.5 times, the temperature term just inside ρ² = 0.99, the last dropped.
        let with = [364.0, 3.0, 9.9, f64::NAN];
        let without = [0.0044, 2.0, 1.0, 1.0];
        let held = held_parameters(&with, &without);
        assert!(held[0].as_deref().is_some_and(|r| r.contains("100.0 %")), "{held:?}");
        assert_eq!(held[1..3], [None, None]);
        assert!(held[3].as_deref().is_some_and(|r| r.contains("span it")), "{held:?}");
        assert!((confounded_ratio() - 10.0).abs() < 1e-9);
        // A parameter the refit does not determine either is not this rule's to hold.
        assert_eq!(held_parameters(&[f64::NAN], &[f64::NAN]), [None]);
    }
}
