//! The family check of accepted effects; structure it does not confirm kept as nuisance terms.

use super::*;

/// Structure that a candidate fitted and its family check did not confirm: reported as
/// [`Unexplained`], its columns (the effect's and its significant relatives') kept at the end
/// of the base design as nuisance terms, in the order the blocks were added.
pub(super) struct Downgraded {
    pub(super) unexplained: Unexplained,
    /// How many columns of the base design are this block's.
    pub(super) cols: usize,
}

/// Nuisance blocks that the model's later effects explain leave the design and the report: a
/// block that failed its family check beside a bent effect (a warm-up's τ shortened by a bias
/// step not yet found) may hold nothing once the step is in. Each block is tested against the
/// rest of the design and the accepted effects; one whose joint Wald is at most one test's χ²
/// quantile at the effects' level (a lower bar than any search threshold, so a block leaves
/// only when nothing of it is left) goes. `prefix` is the number of base columns before the
/// blocks. Returns whether any left.
pub(super) fn recheck_downgraded(
    prefix: usize,
    base_design: &mut Vec<Vec<f64>>,
    downgraded: &mut Vec<Downgraded>,
    accepted: &[Accepted],
    y: &[f64],
    noise: &BinNoise,
    level: f64,
) -> bool {
    let all: Vec<usize> = (0..y.len()).collect();
    let mut changed = false;
    let mut i = 0;
    while i < downgraded.len() {
        let start = prefix + downgraded[..i].iter().map(|d| d.cols).sum::<usize>();
        let k = downgraded[i].cols;
        let block = &base_design[start..start + k];
        let others: Vec<Vec<f64>> = base_design[..start]
            .iter()
            .chain(&base_design[start + k..])
            .chain(accepted.iter().flat_map(|a| &a.cols))
            .cloned()
            .collect();
        let thr = chi2_quantile(1.0 - level, k as f64);
        let held = Projector::new(&others, &all)
            .ok()
            .and_then(|p| p.test(block, y, noise))
            .is_some_and(|t| t.wald > thr);
        if held {
            i += 1;
        } else {
            base_design.drain(start..start + k);
            downgraded.remove(i);
            changed = true;
        }
    }
    changed
}

/// What [`check_families`] updates.
pub(super) struct FamilyState<'a> {
    pub(super) accepted: &'a mut Vec<Accepted>,
    pub(super) base_design: &'a mut Vec<Vec<f64>>,
    pub(super) findings: &'a mut Vec<Finding>,
    pub(super) rejected: &'a mut Vec<Finding>,
    pub(super) downgraded: &'a mut Vec<Downgraded>,
    pub(super) thresholds: &'a std::collections::BTreeMap<EffectId, f64>,
    /// The search's candidates ([`rivals`]).
    pub(super) tested: &'a [EffectId],
    /// The rivals preferred: the search makes each a candidate again and searches it first in
    /// the next round.
    pub(super) preferred: &'a mut Vec<EffectId>,
    /// The search's candidate columns, for the rivals' grids.
    pub(super) cache: &'a ColumnCache,
    /// The coil lag's test as a rival ([`lag_confounded`]): [`coil_lag::threshold`] at the
    /// diagnosis's α, as the lag's profile is judged.
    pub(super) lag_threshold: f64,
}

/// The family check ([`family`]) of each accepted effect in `ids` against the rest of the
/// model, then its declared rivals ([`rivals`]): its result goes into the finding; an effect
/// that fails either leaves the findings for the rejected, becomes [`Unexplained`] structure
/// ("not told apart: E or R" for a rival), and its columns with the significant members' (or
/// the rival's) stay in the design as nuisance terms. Returns whether any effect failed.
pub(super) fn check_families(
    prep: &Prepared,
    model: &GyroModel,
    ids: &[EffectId],
    st: &mut FamilyState<'_>,
    y: &[f64],
    noise: &BinNoise,
    level: f64,
) -> bool {
    let n = prep.bins.len();
    let all: Vec<usize> = (0..n).collect();
    let mut changed = false;
    for &id in ids {
        let Some(i) = st.accepted.iter().position(|a| a.id == id) else { continue };
        let others = model_design(st.base_design, st.accepted, Some(i));
        let (p, cols) = (st.accepted[i].p, st.accepted[i].cols.clone());
        // Structure found to be unexplained since may hold this effect's part too.
        let thr = st.thresholds.get(&id).copied().unwrap_or(0.0);
        let still = Projector::new(&others, &all).ok().and_then(|po| po.test(&cols, y, noise));
        if still.as_ref().is_none_or(|t| t.wald <= thr) {
            changed = true;
            st.accepted.remove(i);
            if let Some(pos) = st.findings.iter().position(|f| f.effect == id) {
                let mut f = st.findings.remove(pos);
                f.accepted = false;
                let w = still.map_or(0.0, |t| t.wald);
                f.rejected_because = Some(format!(
                    "explained by the unexplained structure once that is in the model \
                     (Wald {w:.1} ≤ {thr:.1})"
                ));
                st.rejected.push(f);
            }
            continue;
        }
        let Some(g) =
            family::gate(prep, id, p, &cols, &others, st.base_design, y, noise, level, model)
        else {
            continue;
        };
        let k = match id.effect().columns() {
            Columns::Angle(Order::One) => Some(1.0),
            Columns::Angle(Order::Grid) | Columns::Ripple => Some(p),
            _ => None,
        };
        let rd = k.and_then(|k| family::rate_dependence(prep, k, &others, y, noise, level));
        let Some(pos) = st.findings.iter().position(|f| f.effect == id) else { continue };
        st.findings[pos].family = Some(g.check.clone());
        st.findings[pos].rate_dependence = rd;
        // The rest of the model past the calibrated parameters, for the coil lag's profiles.
        let beside = coil_lag::Beside::of(st.base_design, st.accepted, Some(i));
        let rival = if g.check.passed {
            let ctx = rivals::RivalCtx {
                prep,
                model,
                tested: st.tested,
                accepted: st.accepted,
                base_design: st.base_design,
                index: i,
                level,
                cache: st.cache,
                thresholds: st.thresholds,
                beside: &beside,
                lag_threshold: st.lag_threshold,
            };
            rivals::judge_rivals(&ctx, (id, p), &cols, &others, y, noise)
        } else {
            None
        };
        let rival = match rival {
            Some(rivals::RivalVerdict::Prefer(r, e_beside, r_beside)) => {
                // The rival explains what the effect did and more: the effect leaves, the
                // rival is searched for again.
                changed = true;
                st.accepted.remove(i);
                let mut f = st.findings.remove(pos);
                f.accepted = false;
                f.rejected_because = Some(format!(
                    "its rival {} explains the data better: with it in the model {} keeps \
                     Wald {:.1} ≤ {:.1}, beside {} it keeps Wald {:.1} > {:.1}",
                    r.key(),
                    id.key(),
                    e_beside.value,
                    e_beside.threshold,
                    id.key(),
                    r_beside.value,
                    r_beside.threshold
                ));
                st.rejected.push(f);
                st.preferred.push(r);
                continue;
            }
            Some(rivals::RivalVerdict::NotToldApart(n)) => Some(n),
            None => None,
        };
        let lag = || {
            lag_confounded(
                prep,
                model,
                (id, p, &cols),
                &beside,
                noise,
                level,
                st.lag_threshold,
                st.cache,
            )
        };
        // Told apart from its relatives and rivals, the effect must still be told from the
        // nominal parameters refitted beside it. A rival that matched it only with the coil's
        // lag moved gives way to the lag itself where the lag alone explains the effect: the
        // simpler alternative (the lab writer's study seed 243: a step from the coil's
        // transient is the lag's, not a drift's).
        let confounded = if !g.check.passed || is_earth(id) {
            None
        } else if let Some(r) = &rival {
            r.at_lag_s.and_then(|_| lag())
        } else {
            parameter_confounded(id, &cols, &others, &all, y, noise).or_else(lag).or_else(|| {
                kink_confounded(prep, model, (id, p, &cols), &beside, noise, level, st.cache)
            })
        };
        // The rival's columns stay beside the effect's as nuisance terms either way.
        let rival_cols = rival.as_ref().map(|r| r.cols.clone());
        let rival = if confounded.is_some() { None } else { rival };
        if g.check.passed && rival.is_none() && confounded.is_none() {
            continue;
        }
        changed = true;
        st.accepted.remove(i);
        let mut f = st.findings.remove(pos);
        f.accepted = false;
        f.rejected_because = Some(match (&rival, &confounded) {
            (Some(r), _) => r.words(id),
            (None, Some(words)) => words.clone(),
            (None, None) => format!("not named: {}", g.check.reason()),
        });
        // The nuisance blocks beside the effect: its significant relatives, or the rival.
        let extra: Vec<Vec<f64>> = match rival_cols {
            Some(c) => c,
            None => g.nuisance.iter().flat_map(|m| m.cols.iter().cloned()).collect(),
        };
        // What the effect and its significant relatives hold together, as unexplained.
        let mut design = others.clone();
        design.extend(cols.iter().cloned());
        design.extend(extra.iter().cloned());
        // Fitted values are stable where a split of coefficients between near-collinear
        // columns is not: the contribution is what the extra columns add to the fit.
        let fitted_gain = |d: &[Vec<f64>]| Projector::new(d, &all).map(|pd| pd.residual(y, n));
        let contribution = match (fitted_gain(&others), fitted_gain(&design)) {
            (Ok(r_o), Ok(r_d)) => r_o.iter().zip(&r_d).map(|(a, b)| a - b).collect(),
            _ => vec![0.0; n],
        };
        let effect_size = f
            .parameters
            .iter()
            .find(|q| q.unit == "rad/s")
            .map_or(String::new(), |q| format!(" of {}", family::deg_h(q.value)));
        let correlates_with = match (&rival, &g.check.strongest) {
            (Some(r), _) => r.words(id),
            (None, _) if confounded.is_some() => confounded.clone().unwrap_or_default(),
            (None, Some(m)) if m.wald > m.threshold => format!(
                "{}, {} (Wald {:.1} > {:.1}), beside a {}-like term{effect_size}",
                m.name,
                family::deg_h(m.size_rad_s),
                m.wald,
                m.threshold,
                id.key()
            ),
            (None, Some(m)) => format!(
                "a {}-like term{effect_size} whose size moves {:.1}σ (> {:.2}) when {} is freed",
                id.key(),
                g.check.size_change_z,
                g.check.size_change_limit,
                m.name
            ),
            (None, None) => format!("a {}-like term{effect_size}", id.key()),
        };
        let sel: Vec<f64> = contribution.iter().copied().filter(|v| *v != 0.0).collect();
        let before = st.base_design.len();
        st.base_design.extend(cols);
        st.base_design.extend(extra);
        st.downgraded.push(Downgraded {
            unexplained: Unexplained {
                windows_s: windows_of(&prep.bins, &contribution),
                correlates_with,
                rms: rms(&sel),
            },
            cols: st.base_design.len() - before,
        });
        st.rejected.push(f);
    }
    changed
}

/// Whether the coil's lag, refitted without effect `id` ([`coil_lag::rival`]), explains what
/// the effect holds, on a gyro without its own sensor: the lag's move from the lag in use
/// passes its test (χ²₁ at the diagnosis's α, as the lag's profile is judged) and at the moved
/// lag the effect keeps at most one test's quantile of its degrees of freedom (an effect with a
/// grid fitted again there), while at the lag in use it passed it on the same bins. A short run
/// whose coil never settles trades the lag against a step, a slow periodic bias or a drift
/// (study seed 243: a bias step of Wald 26.8 at the lab's 300 s keeps 1.4 at the 1467 s the data
/// give without it; the coil's true lag was 1132 s). Returns the words for the report.
#[allow(clippy::too_many_arguments)]
fn lag_confounded(
    prep: &Prepared,
    model: &GyroModel,
    (id, p, cols): (EffectId, f64, &[Vec<f64>]),
    beside: &coil_lag::Beside,
    noise: &BinNoise,
    level: f64,
    lag_threshold: f64,
    cache: &ColumnCache,
) -> Option<String> {
    // A further lag on top of the coil's is the same physics: the lag's own update.
    if id == EffectId::ThermalLag {
        return None;
    }
    let test = refine::effect_wald(prep, id, model, cache, noise);
    let rv = coil_lag::rival(prep, model, (id, p, cols), beside, noise, test).ok()??;
    let thr_e = chi2_quantile(1.0 - level, cols.len() as f64);
    if !(rv.lag > lag_threshold && rv.effect_there <= thr_e && rv.effect_here > thr_e) {
        return None;
    }
    Some(format!(
        "not told apart: {} or the coil's thermal lag (alike on a gyro without its own \
         temperature sensor whose coil does not settle: the lag refitted without {}, {:.0} s for \
         the {:.0} s in use, explains the residual, Wald {:.1} > {:.1}, and at that lag {} keeps \
         Wald {:.1} ≤ {:.1}); the run that separates them: a gyro with its own temperature \
         sensor, or holds of several coil lags at each temperature",
        id.key(),
        id.key(),
        rv.tau_s,
        rv.from_s,
        rv.lag,
        lag_threshold,
        id.key(),
        rv.effect_there,
        thr_e
    ))
}

/// Whether a kink in k_t ([`super::hinge`]) with the coil's lag refitted beside it
/// ([`coil_lag::kink_rival`]) explains what effect `id` holds, on a gyro without its own
/// sensor: the kink's Wald there passes its test (one test at the effect's `level` over the
/// knots, the look-elsewhere its family check gives it), and beside it the effect keeps at
/// most one test's quantile of its degrees of freedom (an effect with a grid fitted again),
/// while at the lag in use it passed it on the same bins. A kink is outside the library: the
/// effect is not named and the structure is reported with the knot ("k_t changes near …").
/// Every effect but a further lag (the lag's own update) is judged: the hinge members of a
/// temperature effect's family are built at the lag in use only. Returns the words.
fn kink_confounded(
    prep: &Prepared,
    model: &GyroModel,
    (id, p, cols): (EffectId, f64, &[Vec<f64>]),
    beside: &coil_lag::Beside,
    noise: &BinNoise,
    level: f64,
    cache: &ColumnCache,
) -> Option<String> {
    if id == EffectId::ThermalLag || !prep.lag_free {
        return None;
    }
    let knots = hinge::knots(prep);
    let test = refine::effect_wald(prep, id, model, cache, noise);
    let thr_e = chi2_quantile(1.0 - level, cols.len() as f64);
    let kr = coil_lag::kink_rival(prep, model, (id, p, cols), beside, noise, &knots, test, thr_e)
        .ok()??;
    let thr_k = chi2_quantile(1.0 - level / knots.len().max(1) as f64, 1.0);
    if !(kr.kink > thr_k && kr.effect_there <= thr_e) {
        return None;
    }
    let tk = kr.knot_c;
    Some(format!(
        "not told apart: {} or k_t changes near {tk:.1} °C (a kink max(0, T − {tk:.1} °C), \
         outside the library) with the coil's thermal lag refitted beside it, {:.0} s for the \
         {:.0} s in use (alike on a gyro without its own temperature sensor whose coil lags the \
         air: the kink there explains the residual, Wald {:.1} > {:.1}, and beside it {} keeps \
         Wald {:.1} ≤ {:.1}); the run that separates them: a gyro with its own temperature \
         sensor, or holds at several temperatures on each side of {tk:.1} °C",
        id.key(),
        kr.tau_s,
        kr.from_s,
        kr.kink,
        thr_k,
        id.key(),
        kr.effect_there,
        thr_e
    ))
}

/// Whether the nominal parameters carry more than [`crate::information::CONFOUNDED`] of effect
/// `id`'s information (columns `cols`; `others` the design without it, the calibrated
/// parameters first): the effect's coefficients' variance with the design over their variance
/// with one parameter's column left out is `VIF = 1/(1 − ρ²)`. Such an effect is not named —
/// its value is whatever the parameter leaves it (a temperature quadratic on a run that holds
/// one ramp and a plateau, ρ = 0.996 with `temp_coeff`, came out 0.0000007 ± 0.0000045
/// °/h/°C² and was named, the parameter then held). Returns the words for the report.
fn parameter_confounded(
    id: EffectId,
    cols: &[Vec<f64>],
    others: &[Vec<f64>],
    all: &[usize],
    y: &[f64],
    noise: &BinNoise,
) -> Option<String> {
    // The effect's coefficients' summed variance against a design, as identifiability reads it.
    let variance = |design: &[Vec<f64>]| {
        Projector::new(design, all).ok()?.test(cols, y, noise).map(|t| identify::trace(&t))
    };
    let full = variance(others);
    for (j, key) in ModelKey::CALIBRATED.into_iter().enumerate() {
        if j >= others.len() || others[j].iter().all(|v| *v == 0.0) {
            continue;
        }
        let mut without = others.to_vec();
        without[j] = vec![0.0; all.len()];
        let Some(apart) = variance(&without).filter(|v| *v > 0.0) else { continue };
        // Spanned by the design with the parameter in (nothing of it left to test): ρ = 1.
        let rho2 = full.map_or(1.0, |f| (1.0 - apart / f).max(0.0));
        if rho2 <= crate::information::CONFOUNDED {
            continue;
        }
        let when = id.rivalry_with(key.key()).unwrap_or("this procedure");
        return Some(format!(
            "not told apart: {} or {} (alike on {when}: ρ = {:.4}, the run holds less than {:.1} \
             % of the effect's information apart from {}); the run that separates them: {}",
            id.key(),
            key.key(),
            rho2.sqrt(),
            100.0 * (1.0 - crate::information::CONFOUNDED),
            key.key(),
            id.effect().separated_by().words()
        ));
    }
    None
}
