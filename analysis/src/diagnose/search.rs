//! One round of the effect search: every candidate fitted over its grid, tested and scored.

use super::*;

/// What a candidate search needs that does not change between rounds.
pub(super) struct SearchCtx<'a> {
    pub(super) prep: &'a Prepared,
    pub(super) model: &'a GyroModel,
    pub(super) opts: &'a DiagnoseOptions,
    /// Number of candidates (the Bonferroni factor over effects).
    pub(super) m_candidates: f64,
}

/// One round of the search: every candidate fitted at its best grid value against `proj`, and
/// judged. Returns the best that passes its threshold and ΔBIC (score, finding, fit), and the
/// findings of the others.
#[allow(clippy::too_many_arguments)]
pub(super) fn search(
    ctx: &SearchCtx<'_>,
    candidates: &[EffectId],
    proj: &Projector,
    y: &[f64],
    r: &[f64],
    noise: &BinNoise,
    cache: &mut std::collections::BTreeMap<EffectId, Vec<Vec<Vec<f64>>>>,
    thresholds: &mut std::collections::BTreeMap<EffectId, f64>,
) -> (Option<(f64, Finding, Fitted)>, Vec<Finding>) {
    let n_eff = noise.n_eff();
    let mut best: Option<(f64, Finding, Fitted)> = None;
    let mut tried: Vec<Finding> = Vec::new();
    // Every candidate's grid columns not computed yet, computed together (in parallel; the
    // sinusoids' whole grids by rotation, [`columns`]).
    let missing: Vec<(EffectId, f64)> = candidates
        .iter()
        .filter(|id| !cache.contains_key(id))
        .flat_map(|&id| grid(ctx.prep, id).into_iter().map(move |p| (id, p)))
        .collect();
    ctx.prep.prefill_sinusoids(&missing);
    let computed = columns::par_map(ctx.prep.threads, &missing, |&(id, p)| {
        candidate_columns(ctx.prep, id, p, ctx.model)
    });
    for (&(id, _), cols) in missing.iter().zip(computed) {
        cache.entry(id).or_default().push(cols);
    }
    for &id in candidates {
        let g = grid(ctx.prep, id);
        let m_grid = g.len() as f64;
        let mut top: Option<Fitted> = None;
        let mut profile: Vec<(f64, f64)> = Vec::new();
        let cached = cache.entry(id).or_insert_with(|| {
            g.iter().map(|&p| candidate_columns(ctx.prep, id, p, ctx.model)).collect()
        });
        let tests: Vec<Option<fit::TermTest>> = if is_earth(id) {
            // Earth's rate is a constant: it can only show as the bias correction
            // being Earth's rate. Test that shift (bias column, current design).
            g.iter().map(|_| earth_test(proj, y, noise, ctx.prep.earth)).collect()
        } else {
            columns::par_map(ctx.prep.threads, cached, |cols| proj.test(cols, y, noise))
        };
        for ((&p, cols), t) in g.iter().zip(cached.iter()).zip(tests) {
            let cols = cols.clone();
            let Some(t) = t else { continue };
            profile.push((p, t.wald));
            // The grid value is chosen by fit (least squares), the term judged by W there.
            if top.as_ref().is_none_or(|b| t.delta_rss > b.test.delta_rss) {
                top = Some(Fitted { p, cols, test: t });
            }
        }
        let Some(mut fitted) = top else { continue };
        // Judged at the grid (what the scan threshold is for), reported at the refined fit.
        let wald_grid = fitted.test.wald;
        refine(ctx.prep, id, proj, y, noise, ctx.model, &mut fitted, &mut profile);
        let Fitted { p, cols, test: t } = fitted;
        let k = cols.len() as f64;
        let q = if m_grid > 1.0 { 1.0 } else { 0.0 };
        let thr = *thresholds.entry(id).or_insert_with(|| {
            let level = ctx.opts.alpha / ctx.m_candidates;
            let single: Vec<Vec<f64>> =
                cached.iter().filter(|c| c.len() == 1).map(|c| c[0].clone()).collect();
            let scanned = if m_grid > 1.0 && single.len() == cached.len() {
                scan::peak_wald_quantile(proj, &single, noise, level, SCAN_SEED + id as u64)
            } else {
                None
            };
            // Never below one test's threshold (the draws' own scatter could put it there).
            scanned.map_or_else(
                || chi2_quantile(1.0 - level / m_grid, k),
                |q| q.max(chi2_quantile(1.0 - level, k)),
            )
        });
        let dbic = t.wald - (k + q) * n_eff.ln();
        let mut f = new_finding(ctx.prep, id, p, &cols, &t, &profile, thr, dbic, r);
        if is_earth(id) {
            // Consistency with Earth's rate is part of its test. The bias shift holds Earth's
            // rate plus what the model's own bias is off by (a lab's always is, by more than
            // the shift's σ): Earth's rate is named when the shift agrees with it or lies
            // nearer it than zero — of the two explanations, the one that leaves the model's
            // bias the smaller error.
            let theta = t.theta[0];
            let z_diff = (theta - 1.0) / t.sigma(0).max(1e-300);
            if z_diff.abs() > 3.0 && (theta - 1.0).abs() >= theta.abs() {
                f.rejected_because = Some(format!(
                    "bias shift is not Earth's rate (z = {z_diff:.1}; {:.3} of it, nearer zero)",
                    theta
                ));
                tried.push(f);
                continue;
            }
            f.remark = Some(earth_remark(ctx.prep.earth, theta));
        }
        if wald_grid <= thr {
            f.rejected_because = Some(format!("Wald {wald_grid:.1} ≤ threshold {thr:.1}"));
            tried.push(f);
            continue;
        }
        if dbic <= 0.0 {
            f.rejected_because = Some(format!("ΔBIC {dbic:.1} ≤ 0"));
            tried.push(f);
            continue;
        }
        let score = dbic;
        if best.as_ref().is_none_or(|(s, ..)| score > *s) {
            if let Some((_, prev, _)) = best.take() {
                tried.push(prev);
            }
            best = Some((score, f, Fitted { p, cols, test: t }));
        } else {
            tried.push(f);
        }
    }
    (best, tried)
}

/// A candidate's finding, not yet judged: its fit `t` of columns `cols` at grid value `p`
/// against residual `r`, with the search's threshold `thr` and ΔBIC.
#[allow(clippy::too_many_arguments)]
pub(super) fn new_finding(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    cols: &[Vec<f64>],
    t: &fit::TermTest,
    profile: &[(f64, f64)],
    thr: f64,
    dbic: f64,
    r: &[f64],
) -> Finding {
    let n = prep.bins.len();
    let rms_before = rms(r);
    let rms_after = ((rms_before * rms_before * n as f64 - t.delta_rss).max(0.0) / n as f64).sqrt();
    let contribution: Vec<f64> =
        (0..n).map(|i| cols.iter().zip(&t.theta).map(|(c, th)| c[i] * th).sum()).collect();
    Finding {
        effect: id,
        parameters: effect_parameters(id, p, t, profile, prep),
        wald: t.wald,
        threshold: thr,
        delta_bic: dbic,
        rms_before,
        rms_after,
        holdout_z: f64::NAN,
        windows_s: windows_of(&prep.bins, &contribution),
        accepted: false,
        rejected_because: None,
        family: None,
        rate_dependence: None,
        remark: None,
    }
}

/// The comparison that names Earth's rate left out of the model: the bias shift `theta·earth`
/// against the site's Earth rate `earth` (rad/s along the axis), as Ω_E·sin(latitude), and
/// what is left for the model's own bias.
pub(super) fn earth_remark(earth: f64, theta: f64) -> String {
    let e = bench_physics::earth::EARTH_RATE_RAD_S;
    let dh = bench_physics::units::DEG_PER_H;
    let lat = (earth.abs() / e).clamp(0.0, 1.0).asin().to_degrees();
    let sign = if earth < 0.0 { "−" } else { "" };
    format!(
        "Earth's rate left out of the model: the bias shift {:.2} °/h = Earth's rate {:.2} °/h \
         = {sign}{:.2} °/h × sin {lat:.1}° (the site's latitude){}",
        theta * earth / dh,
        earth / dh,
        e / dh,
        if (theta - 1.0).abs() * earth.abs() / dh >= 0.005 {
            format!(", plus {:.2} °/h of the model's own bias", (theta - 1.0) * earth / dh)
        } else {
            String::new()
        }
    )
}

/// Earth's rate as the bias correction: θ = bias correction / Earth's rate (1 if the missing
/// term is Earth's rate).
pub(super) fn earth_test(
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    earth: f64,
) -> Option<fit::TermTest> {
    if earth == 0.0 {
        return None;
    }
    let j = proj.kept.iter().position(|&c| c == 0)?;
    let beta = proj.beta(y);
    let w = proj.weights(j, noise.len());
    let var = noise.quad(&w, &w) / (earth * earth);
    let theta = beta[j] / earth;
    Some(fit::TermTest {
        theta: vec![theta],
        cov: nalgebra::DMatrix::from_element(1, 1, var),
        wald: theta * theta / var,
        delta_rss: 0.0,
    })
}
