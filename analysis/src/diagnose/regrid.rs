//! The search again with the accepted effects' grid values refitted from several starts.

use super::*;

/// The starts of [`refit_search`] that move accepted time constant `i`: each of its grid values
/// against the rest of the model, as the unit vector its column adds to the rest. A
/// candidate's residual sum of squares at each start then comes from inner products with the
/// candidate's columns projected off the rest once (ordinary least squares, as the grid
/// values are chosen), not from a new fit per start.
pub(super) struct StartSet {
    pub(super) i: usize,
    pub(super) rest: Projector,
    /// The residual of the rest, and its sum of squares.
    pub(super) r_rest: Vec<f64>,
    pub(super) rr: f64,
    pub(super) values: Vec<StartValue>,
}

/// One grid value of a [`StartSet`].
pub(super) struct StartValue {
    pub(super) value: f64,
    pub(super) cols: Vec<Vec<f64>>,
    /// The unit vector the column adds to the rest, and its inner product with the rest's
    /// residual.
    pub(super) unit: Vec<f64>,
    pub(super) c: f64,
}

/// A start [`StartSet::best`] chose: accepted effect `i` at `value`, its columns `cols`.
pub(super) struct Start {
    pub(super) i: usize,
    pub(super) value: f64,
    pub(super) cols: Vec<Vec<f64>>,
}

impl StartSet {
    pub(super) fn new(
        i: usize,
        rest: Projector,
        grid: Vec<f64>,
        cached: &[Vec<Vec<f64>>],
        y: &[f64],
    ) -> Option<StartSet> {
        let r_rest = rest.residual(y, y.len());
        let rr = r_rest.iter().map(|v| v * v).sum();
        let values = grid
            .into_iter()
            .zip(cached)
            .filter(|(_, cols)| cols.len() == 1)
            .filter_map(|(v, cols)| {
                let w = rest.orthogonalise(cols).pop()?;
                let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
                (norm > 0.0 && norm.is_finite()).then(|| {
                    let unit: Vec<f64> = w.iter().map(|x| x / norm).collect();
                    let c = dot(&unit, &r_rest);
                    StartValue { value: v, cols: cols.clone(), unit, c }
                })
            })
            .collect::<Vec<_>>();
        (!values.is_empty()).then_some(StartSet { i, rest, r_rest, rr, values })
    }

    /// The grid value of the time constant where the candidate (each of its grid columns
    /// `grid_cols`, at its best) leaves the least sum of squares: (that sum, (i, value, columns)).
    pub(super) fn best(&self, threads: usize, grid_cols: &[Vec<Vec<f64>>]) -> Option<(f64, Start)> {
        let per_column = columns::par_map(threads, grid_cols, |cols| {
            let gb = self.rest.orthogonalise(cols);
            let k = gb.len();
            let gtg = nalgebra::DMatrix::from_fn(k, k, |a, b| dot(&gb[a], &gb[b]));
            let gtr = nalgebra::DVector::from_fn(k, |a, _| dot(&gb[a], &self.r_rest));
            self.values
                .iter()
                .map(|sv| {
                    let a = nalgebra::DVector::from_fn(k, |j, _| dot(&gb[j], &sv.unit));
                    let m = &gtg - &a * a.transpose();
                    let g = &gtr - &a * sv.c;
                    let drss = m.try_inverse().map_or(0.0, |mi| (g.transpose() * mi * &g)[(0, 0)]);
                    self.rr - sv.c * sv.c - drss.max(0.0)
                })
                .collect::<Vec<f64>>()
        });
        let (j, left) = (0..self.values.len())
            .map(|j| (j, per_column.iter().map(|v| v[j]).fold(f64::INFINITY, f64::min)))
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        let sv = &self.values[j];
        Some((left, Start { i: self.i, value: sv.value, cols: sv.cols.clone() }))
    }
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// What [`refit_search`] found: the candidate (score, finding, fit) and the accepted effects'
/// grid values and columns fitted again with it in.
pub(super) type Refitted = ((f64, Finding, Fitted), Vec<(f64, Vec<Vec<f64>>)>);

/// The search's step with the accepted effects' grid values fitted again. The search judges a
/// candidate at the accepted effects' grid values, which the model's earlier terms may have
/// bent (a warm-up's τ shortened to take part of a bias step the model does not hold yet): the
/// true effect then stays under its threshold while a wrong term that fits the bent model's
/// leftovers passes. Here each candidate is fitted with the accepted effects' grid values
/// fitted again (in turn, twice) and judged by what it adds to the model as it stands: its Wald
/// scaled by the drop of the residual sum of squares from the current model's (never from the
/// bent one's: freeing the grid values buys the candidate nothing the current model could take
/// by itself). It must pass its search threshold, ΔBIC and the held-out blocks. Only a
/// candidate that moves some grid value is tried (otherwise this is the search's own test).
/// The alternation starts from the best of several models (below), each time constant at
/// each of its grid values.
/// Returns the best by ΔBIC.
#[allow(clippy::too_many_arguments)]
pub(super) fn refit_search(
    ctx: &SearchCtx<'_>,
    candidates: &[EffectId],
    accepted: &[Accepted],
    base_design: &[Vec<f64>],
    y: &[f64],
    noise: &BinNoise,
    cache: &std::collections::BTreeMap<EffectId, Vec<Vec<Vec<f64>>>>,
    thresholds: &std::collections::BTreeMap<EffectId, f64>,
) -> Option<Refitted> {
    let prep = ctx.prep;
    let n = prep.bins.len();
    let all: Vec<usize> = (0..n).collect();
    let gridded: Vec<usize> =
        (0..accepted.len()).filter(|&i| grid(prep, accepted[i].id).len() > 1).collect();
    if gridded.is_empty() {
        return None;
    }
    let design_of = |acc: &[(f64, Vec<Vec<f64>>)], skip: Option<usize>, extra: &[Vec<f64>]| {
        base_design
            .iter()
            .chain(acc.iter().enumerate().filter(|(i, _)| Some(*i) != skip).flat_map(|(_, a)| &a.1))
            .chain(extra)
            .cloned()
            .collect::<Vec<Vec<f64>>>()
    };
    let rss = |pr: &Projector| pr.residual(y, n).iter().map(|v| v * v).sum::<f64>();
    let current: Vec<(f64, Vec<Vec<f64>>)> =
        accepted.iter().map(|a| (a.p, a.cols.clone())).collect();
    let now = Projector::new(&design_of(&current, None, &[]), &all).ok()?;
    let rss_now = rss(&now);
    // Where the alternation starts: the model as it stands, or with one accepted time
    // constant (warm-up, lag) at another of its grid values. A time constant trades against
    // every slow term, so a hidden step pulls it far (900 → 367 s on the lab writer's warm-up
    // + step, seed 8), and from the bent value the candidate's best is elsewhere (the step at
    // 11 310 s instead of 2748 s); the grids are short (9–10 values).
    let start_sets: Vec<StartSet> = gridded
        .iter()
        .filter(|&&i| matches!(accepted[i].id.effect().grid(), Grid::TimeConstants(_)))
        .filter_map(|&i| {
            let rest = Projector::new(&design_of(&current, Some(i), &[]), &all).ok()?;
            StartSet::new(i, rest, grid(prep, accepted[i].id), cache.get(&accepted[i].id)?, y)
        })
        .collect();
    let n_eff = noise.n_eff();
    let mut best: Option<Refitted> = None;
    for &id in candidates {
        let Some(&thr) = thresholds.get(&id) else { continue };
        if is_earth(id) {
            continue;
        }
        let gridded_r = grid(prep, id).len() > 1;
        let fit_r = |pr: &Projector| -> Option<(Fitted, Vec<(f64, f64)>)> {
            if gridded_r {
                return refit_grid_profile(prep, id, pr, y, noise, ctx.model, cache);
            }
            let cols = cache.get(&id)?.first()?.clone();
            let test = pr.test(&cols, y, noise)?;
            Some((Fitted { p: f64::NAN, cols, test }, Vec::new()))
        };
        // The start: the model where the candidate at its best grid value leaves the least.
        let mut acc = current.clone();
        let Some(grid_cols) = cache.get(&id) else { continue };
        if let Some(st) = start_sets
            .iter()
            .filter_map(|set| set.best(prep.threads, grid_cols))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|x| x.1)
        {
            acc[st.i] = (st.value, st.cols);
        }
        let Ok(pr) = Projector::new(&design_of(&acc, None, &[]), &all) else { continue };
        let Some(mut cand) = fit_r(&pr) else { continue };
        for _ in 0..2 {
            for &i in &gridded {
                let Ok(pd) = Projector::new(&design_of(&acc, Some(i), &cand.0.cols), &all) else {
                    continue;
                };
                if let Some(g) = refit_grid(prep, accepted[i].id, &pd, y, noise, ctx.model, cache) {
                    acc[i] = (g.p, g.cols);
                }
            }
            let Ok(pa) = Projector::new(&design_of(&acc, None, &[]), &all) else { break };
            if let Some(c) = fit_r(&pa) {
                cand = c;
            }
        }
        if acc.iter().zip(&current).all(|(a, c)| a.0 == c.0) {
            continue;
        }
        let d = design_of(&acc, None, &[]);
        let Ok(pa) = Projector::new(&d, &all) else { continue };
        let (Fitted { p, cols, .. }, profile) = cand;
        let Some(t) = pa.test(&cols, y, noise) else { continue };
        let r_bent = pa.residual(y, n);
        let rss_with = r_bent.iter().map(|v| v * v).sum::<f64>() - t.delta_rss;
        let gain = rss_now - rss_with;
        if !(t.delta_rss > 0.0 && gain > 0.0) {
            continue;
        }
        let wald = t.wald * (gain / t.delta_rss).min(1.0);
        let q = if gridded_r { 1.0 } else { 0.0 };
        let dbic = wald - (cols.len() as f64 + q) * n_eff.ln();
        if wald <= thr || dbic <= 0.0 || best.as_ref().is_some_and(|b| b.0 .0 >= dbic) {
            continue;
        }
        let hz = holdout_z(&d, &cols, y, &prep.bins, noise, ctx.opts.holdout_block_s);
        if hz <= HOLDOUT_Z {
            continue;
        }
        let mut f = new_finding(prep, id, p, &cols, &t, &profile, thr, dbic, &r_bent);
        f.wald = wald;
        f.holdout_z = hz;
        best = Some(((dbic, f, Fitted { p, cols, test: t }), acc));
    }
    best
}
