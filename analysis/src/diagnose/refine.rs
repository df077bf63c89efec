//! A grid parameter refitted and refined below its grid, and its σ.

use super::*;

/// A continuous grid parameter refined between its best grid value's neighbours, placed by
/// `spacing`, the best fit kept, the Wald profile extended. A periodic bias's period evenly in frequency; a time
/// constant evenly in its logarithm.
#[allow(clippy::too_many_arguments)]
pub(super) fn refine_between(
    prep: &Prepared,
    id: EffectId,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
    fitted: &mut Fitted,
    profile: &mut Vec<(f64, f64)>,
    spacing: Spacing,
) {
    let Spacing { count, warp, unwarp } = spacing;
    let g = grid(prep, id);
    let Some(k) = g.iter().position(|&v| v == fitted.p) else { return };
    let w0 = warp(fitted.p);
    let mut values = Vec::new();
    for nb in [k.checked_sub(1), Some(k + 1)].into_iter().flatten() {
        let Some(&pn) = g.get(nb) else { continue };
        let w1 = warp(pn);
        values.extend((1..=count).map(|j| unwarp(w0 + (w1 - w0) * j as f64 / (count + 1) as f64)));
    }
    let tries =
        columns::par_map(prep.threads, &values, |&p| (p, candidate_columns(prep, id, p, model)));
    keep_best(prep.threads, proj, y, noise, tries.into_iter(), fitted, profile);
}

/// How [`refine_between`] places its values: `count` on each side, evenly in `warp` of the
/// parameter (`unwarp` its inverse).
#[derive(Clone, Copy)]
pub(super) struct Spacing {
    pub(super) count: usize,
    pub(super) warp: fn(f64) -> f64,
    pub(super) unwarp: fn(f64) -> f64,
}

impl Spacing {
    /// `count` values on each side, evenly in frequency (a period).
    pub(super) fn by_frequency(count: usize) -> Self {
        Spacing { count, warp: |p| 1.0 / p, unwarp: |f| 1.0 / f }
    }

    /// `count` values on each side, evenly in the logarithm: the time constants, in the final
    /// fit only (the grid's steps, a factor 1.5, are wider than a time constant's σ on a long
    /// run; in the search a lag's τ refined by least squares moves to where its Wald is lower
    /// under correlated noise).
    pub(super) fn by_logarithm(count: usize) -> Self {
        Spacing { count, warp: f64::ln, unwarp: f64::exp }
    }
}

/// Test each `(value, columns)` of `tries`: its Wald statistic joins the profile, and the best
/// fit (least squares) replaces `fitted`.
pub(super) fn keep_best(
    threads: usize,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    tries: impl Iterator<Item = (f64, Vec<Vec<f64>>)>,
    fitted: &mut Fitted,
    profile: &mut Vec<(f64, f64)>,
) {
    let tries: Vec<(f64, Vec<Vec<f64>>)> = tries.collect();
    let tests = columns::par_map(threads, &tries, |(_, cols)| proj.test(cols, y, noise));
    for ((p, cols), t) in tries.into_iter().zip(tests) {
        if let Some(t) = t {
            profile.push((p, t.wald));
            if t.delta_rss > fitted.test.delta_rss {
                *fitted = Fitted { p, cols, test: t };
            }
        }
    }
    profile.sort_by(|a, b| a.0.total_cmp(&b.0));
}

/// A gridded effect's best grid value refined below the grid's spacing (bias step, periodic
/// bias); nothing for the others.
#[allow(clippy::too_many_arguments)]
pub(super) fn refine(
    prep: &Prepared,
    id: EffectId,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
    fitted: &mut Fitted,
    profile: &mut Vec<(f64, f64)>,
) {
    match id.effect().refinement() {
        Refinement::BinStarts => refine_step(prep, id, proj, y, noise, model, fitted, profile),
        Refinement::EvenInFrequency { each_side } => {
            let spacing = Spacing::by_frequency(each_side);
            refine_between(prep, id, proj, y, noise, model, fitted, profile, spacing);
        }
        Refinement::None | Refinement::FinalEvenInLog { .. } => {}
    }
}

/// An instant (a bias step's) refined from its grid position to the bin: every bin start
/// between the neighbouring grid positions is tried, the best fit kept, the Wald profile
/// extended.
#[allow(clippy::too_many_arguments)]
pub(super) fn refine_step(
    prep: &Prepared,
    id: EffectId,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
    fitted: &mut Fitted,
    profile: &mut Vec<(f64, f64)>,
) {
    let g = grid(prep, id);
    let Some(k) = g.iter().position(|&v| v == fitted.p) else { return };
    let lo = if k == 0 { fitted.p } else { g[k - 1] };
    let hi = if k + 1 == g.len() { fitted.p } else { g[k + 1] };
    let best = fitted.p;
    let values: Vec<f64> =
        prep.bins.iter().map(|b| b.start_s).filter(|&p| p > lo && p < hi && p != best).collect();
    let tries = values.into_iter().map(|p| (p, regressor_columns(prep, id, p, model)));
    keep_best(prep.threads, proj, y, noise, tries, fitted, profile);
}

/// Effect `id`'s Wald statistic, its columns `cols` tested against a design `at` for a residual
/// `y` under `noise`: an effect with a grid is fitted again over it ([`refit_grid`]; its value
/// was chosen without that design), judged as one test. 0 where nothing of it is left.
pub(super) fn effect_wald<'a>(
    prep: &'a Prepared,
    id: EffectId,
    model: &'a GyroModel,
    cache: &'a ColumnCache,
    noise: &'a BinNoise,
) -> impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64 + 'a {
    let gridded = grid(prep, id).len() > 1;
    move |at: &Projector, y: &[f64], cols: &[Vec<f64>]| {
        if gridded {
            refit_grid(prep, id, at, y, noise, model, cache).map_or(0.0, |f| f.test.wald)
        } else {
            at.test(cols, y, noise).map_or(0.0, |t| t.wald)
        }
    }
}

/// A gridded effect's best grid value (least squares) against `proj`, refined below the grid
/// ([`refine`]); `None` for an effect without a grid or not yet tried.
pub(super) fn refit_grid(
    prep: &Prepared,
    id: EffectId,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
    cache: &std::collections::BTreeMap<EffectId, Vec<Vec<Vec<f64>>>>,
) -> Option<Fitted> {
    refit_grid_profile(prep, id, proj, y, noise, model, cache).map(|(f, _)| f)
}

/// [`refit_grid`] with the Wald profile over the grid (and its refinement).
pub(super) fn refit_grid_profile(
    prep: &Prepared,
    id: EffectId,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
    cache: &std::collections::BTreeMap<EffectId, Vec<Vec<Vec<f64>>>>,
) -> Option<(Fitted, Vec<(f64, f64)>)> {
    let g = grid(prep, id);
    if g.len() < 2 {
        return None;
    }
    let cached = cache.get(&id).map(Vec::as_slice);
    let (mut fitted, mut profile) = best_on_grid(prep, id, &g, cached, proj, y, noise, model)?;
    refine(prep, id, proj, y, noise, model, &mut fitted, &mut profile);
    Some((fitted, profile))
}

/// Effect `id`'s best value among grid values `g` against `proj` (least squares), with the
/// Wald profile over them; not refined. The columns are `cached` (the search's, in `g`'s
/// order) where given; otherwise (a rival judged beside an accepted effect, or on a grid wider
/// than its search's) computed here, through the run's memo.
#[allow(clippy::too_many_arguments)]
pub(super) fn best_on_grid(
    prep: &Prepared,
    id: EffectId,
    g: &[f64],
    cached: Option<&[Vec<Vec<f64>>]>,
    proj: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
) -> Option<(Fitted, Vec<(f64, f64)>)> {
    let computed: Vec<Vec<Vec<f64>>>;
    let cached = match cached {
        Some(c) => c,
        None => {
            prep.prefill_sinusoids(&g.iter().map(|&p| (id, p)).collect::<Vec<_>>());
            computed =
                columns::par_map(prep.threads, g, |&p| candidate_columns(prep, id, p, model));
            &computed
        }
    };
    let mut top: Option<Fitted> = None;
    let mut profile = Vec::new();
    let tests = columns::par_map(prep.threads, cached, |cols| proj.test(cols, y, noise));
    for ((&p, cols), t) in g.iter().zip(cached).zip(tests) {
        if let Some(t) = t {
            profile.push((p, t.wald));
            if top.as_ref().is_none_or(|b| t.delta_rss > b.test.delta_rss) {
                top = Some(Fitted { p, cols: cols.clone(), test: t });
            }
        }
    }
    Some((top?, profile))
}

/// The 1σ of a continuous grid parameter (a warm-up's or a lag's time constant, a periodic
/// bias's period) by linearisation: the model's derivative with respect to it (the fitted
/// coefficients `theta` times the columns' derivatives, by central differences) fitted beside
/// the effect's columns against `others`, its coefficient's noise-model σ. The Wald profile's
/// width is not this σ where the noise is correlated (a flicker floor makes the fitted time
/// constant scatter several times wider than the profile's Wald ≥ peak − 1 interval). `None`
/// for a discrete parameter (a step's bin, a harmonic's k).
#[allow(clippy::too_many_arguments)]
pub(super) fn grid_sigma_linearised(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    cols: &[Vec<f64>],
    theta: &[f64],
    others: &Projector,
    y: &[f64],
    noise: &BinNoise,
    model: &GyroModel,
) -> Option<f64> {
    if !id.effect().grid().is_continuous() {
        return None;
    }
    let h = 1e-3 * p;
    let up = candidate_columns(prep, id, p + h, model);
    let down = candidate_columns(prep, id, p - h, model);
    let n = prep.bins.len();
    let deriv: Vec<f64> = (0..n)
        .map(|i| {
            theta.iter().zip(up.iter().zip(&down)).map(|(a, (u, d))| a * (u[i] - d[i])).sum::<f64>()
                / (2.0 * h)
        })
        .collect();
    let mut with: Vec<Vec<f64>> = cols.to_vec();
    with.push(deriv);
    let t = others.test(&with, y, noise)?;
    let s = t.sigma(cols.len());
    s.is_finite().then_some(s)
}
