//! The effect search as a whole (module docs, step 4): rounds of [`search`] that accept the
//! best candidate the held-out blocks confirm (or a confirmed pair), refit the earlier effects'
//! grid values and drop those the newcomer explains; then the family check of every accepted
//! effect, and the search again around the structure it did not confirm.

use super::*;

/// Candidates' grid columns by effect (they depend on the run only: computed once).
pub(super) type ColumnCache = std::collections::BTreeMap<EffectId, Vec<Vec<Vec<f64>>>>;

/// The state of the search: the model so far, what was tried and what waits.
pub(super) struct Search<'a> {
    pub(super) ctx: SearchCtx<'a>,
    /// Every bin (the projectors' rows).
    all: Vec<usize>,
    /// The nominal residual, bin means (Earth's rate moved into the prediction once found).
    pub(super) y: Vec<f64>,
    /// The noise model of the refitted nominal residual.
    pub(super) noise: BinNoise,
    /// Candidates still to test.
    candidates: Vec<EffectId>,
    /// Every candidate of the search, as it began.
    pub(super) tested: Vec<EffectId>,
    /// Candidates the held-out blocks did not confirm: they wait until the model changes.
    on_hold: Vec<EffectId>,
    /// The nominal parameters' columns, then nuisance blocks ([`Downgraded`]).
    pub(super) base_design: Vec<Vec<f64>>,
    /// The effects in the model, in the order they joined.
    pub(super) accepted: Vec<Accepted>,
    /// The model's design: the base design and the accepted effects' columns.
    pub(super) design: Vec<Vec<f64>>,
    pub(super) proj: Projector,
    /// The residual after the model.
    pub(super) r: Vec<f64>,
    pub(super) findings: Vec<Finding>,
    rejected: Vec<Finding>,
    pub(super) earth_found: bool,
    pub(super) column_cache: ColumnCache,
    /// Each candidate's threshold, set when it is first tested (for a grid: from the scan of
    /// the noise model, [`scan`]).
    thresholds: std::collections::BTreeMap<EffectId, f64>,
    /// Structure that a candidate fitted but its family check did not confirm ([`family`]).
    pub(super) downgraded: Vec<Downgraded>,
    /// The family-wise level split over the candidates.
    level: f64,
    /// Rivals the data preferred to an accepted effect ([`check_families`]): searched first,
    /// alone, in the next round.
    preferred: Vec<EffectId>,
}

impl<'a> Search<'a> {
    /// The search's start from the refitted nominal model `base`.
    pub(super) fn new(
        prep: &'a Prepared,
        model: &'a GyroModel,
        effects: &Effects,
        latitude_known: bool,
        opts: &'a DiagnoseOptions,
        base: &BaseFit,
    ) -> Self {
        let candidates: Vec<EffectId> = EffectId::ALL
            .into_iter()
            .filter(|&id| !effects.has(id))
            .filter(|&id| !is_earth(id) || (!model.earth_rate && latitude_known))
            .filter(|&id| {
                id.effect().columns() != Columns::ThermalLag
                    || model.temp_coeff != 0.0
                    || model.temp_rate_coeff != 0.0
            })
            .collect();
        let m_candidates = candidates.len().max(1) as f64;
        Self {
            ctx: SearchCtx { prep, model, opts, m_candidates },
            all: (0..prep.bins.len()).collect(),
            y: base.y.clone(),
            noise: base.noise.clone(),
            tested: candidates.clone(),
            candidates,
            on_hold: Vec::new(),
            base_design: prep.base.clone(),
            accepted: Vec::new(),
            design: prep.base.clone(),
            proj: base.proj.clone(),
            r: base.r.clone(),
            findings: Vec::new(),
            rejected: Vec::new(),
            earth_found: false,
            column_cache: ColumnCache::new(),
            thresholds: std::collections::BTreeMap::new(),
            downgraded: Vec::new(),
            level: opts.alpha / m_candidates,
            preferred: Vec::new(),
        }
    }

    /// The search, then the family check of every accepted effect in the final model; an
    /// effect that fails becomes nuisance structure and the search runs again around it.
    pub(super) fn run(&mut self) -> Result<(), AnalysisError> {
        let opts = self.ctx.opts;
        for _pass in 0..3 {
            // Each round accepts an effect or puts one on hold: the bound is never reached
            // first.
            for _round in 0..(opts.max_effects + 1) * (EffectId::ALL.len() + 1) {
                if self.findings.len() >= opts.max_effects || !self.round()? {
                    break;
                }
            }
            let changed = self.families();
            self.rebuild()?;
            if !changed {
                break;
            }
        }
        Ok(())
    }

    /// The design, its projector and the residual from the accepted effects.
    pub(super) fn rebuild(&mut self) -> Result<(), AnalysisError> {
        self.design = model_design(&self.base_design, &self.accepted, None);
        self.proj = Projector::new(&self.design, &self.all)?;
        self.r = self.proj.residual(&self.y, self.all.len());
        Ok(())
    }

    /// One round: the best candidate (or, when none passes, the best after the accepted
    /// effects' grid values are refitted), judged on the held-out blocks, alone or with a
    /// partner. Returns whether the search goes on.
    fn round(&mut self) -> Result<bool, AnalysisError> {
        // A rival the data preferred to an accepted effect takes that effect's turn: searched
        // first, alone (among every candidate, another shape that fits part of the same
        // signal could take it, and the effect's place would go to neither).
        let preferred = std::mem::take(&mut self.preferred);
        let (mut best, mut tried) = (None, Vec::new());
        for pool in [&preferred[..], &self.candidates[..]] {
            (best, tried) = search(
                &self.ctx,
                pool,
                &self.proj,
                &self.y,
                &self.r,
                &self.noise,
                &mut self.column_cache,
                &mut self.thresholds,
            );
            if best.is_some() {
                break;
            }
        }
        if best.is_none() {
            best = self.regrid_search()?;
        }
        let Some((_, mut f, mut fitted)) = best else {
            self.rejected.extend(tried);
            return Ok(false);
        };
        let hz = if is_earth(f.effect) {
            f64::INFINITY
        } else if f.holdout_z.is_finite() {
            // Judged already (with the accepted effects' grid values fitted again).
            f.holdout_z
        } else {
            let (prep, opts) = (self.ctx.prep, self.ctx.opts);
            let (y, noise) = (&self.y, &self.noise);
            holdout_z(&self.design, &fitted.cols, y, &prep.bins, noise, opts.holdout_block_s)
        };
        f.holdout_z = hz;
        self.candidates.retain(|&c| c != f.effect);
        let mut partner = None;
        if hz <= HOLDOUT_Z {
            partner = self.partner(&mut f, &mut fitted)?;
            if partner.is_none() {
                f.rejected_because =
                    Some(format!("held-out blocks do not confirm it (z = {hz:.1})"));
                self.on_hold.push(f.effect);
                self.rejected.push(f);
                self.rejected.extend(tried);
                return Ok(true);
            }
        }
        let f_id = f.effect;
        self.accept(f, fitted, partner, tried);
        self.drop_explained(f_id)?;
        self.rebuild()?;
        Ok(true)
    }

    /// The search again over every candidate, on hold or not, with the accepted effects' grid
    /// values refitted ([`refit_search`]); the refitted values are kept when one passes.
    fn regrid_search(&mut self) -> Result<Option<(f64, Finding, Fitted)>, AnalysisError> {
        let pool: Vec<EffectId> = self.candidates.iter().chain(&self.on_hold).copied().collect();
        let Some((found, refitted)) = refit_search(
            &self.ctx,
            &pool,
            &self.accepted,
            &self.base_design,
            &self.y,
            &self.noise,
            &self.column_cache,
            &self.thresholds,
        ) else {
            return Ok(None);
        };
        for (a, (p, cols)) in self.accepted.iter_mut().zip(refitted) {
            a.p = p;
            a.cols = cols;
        }
        self.rebuild()?;
        self.on_hold.retain(|&c| c != found.1.effect);
        Ok(Some(found))
    }

    /// Another missing effect may be what spoils the held-out blocks (a warm-up judged against
    /// blocks that also hold an unmodelled later step): the best partner fitted with `f` in the
    /// model, the two grid values fitted in turn, and both taken when the held-out blocks
    /// confirm each with the other in (`f` and `fitted` updated then).
    fn partner(
        &mut self,
        f: &mut Finding,
        fitted: &mut Fitted,
    ) -> Result<Option<(Finding, Fitted)>, AnalysisError> {
        if is_earth(f.effect) || self.findings.len() + 2 > self.ctx.opts.max_effects {
            return Ok(None);
        }
        let (prep, model, all) = (self.ctx.prep, self.ctx.model, &self.all);
        let (y, noise, design) = (&self.y, &self.noise, &self.design);
        let mut d2 = design.clone();
        d2.extend(fitted.cols.iter().cloned());
        let proj2 = Projector::new(&d2, all)?;
        let r2 = proj2.residual(y, all.len());
        let others: Vec<EffectId> = self
            .candidates
            .iter()
            .chain(&self.on_hold)
            .copied()
            .filter(|&c| !is_earth(c))
            .collect();
        let (best2, _) = search(
            &self.ctx,
            &others,
            &proj2,
            y,
            &r2,
            noise,
            &mut self.column_cache,
            &mut self.thresholds,
        );
        let Some((_, mut f2, mut fitted2)) = best2 else { return Ok(None) };
        let cache = &self.column_cache;
        // The two grid values fitted in turn, each with the other in the model.
        let mut top = Fitted { p: fitted.p, cols: fitted.cols.clone(), test: fitted.test.clone() };
        let mut d3 = design.clone();
        for _ in 0..2 {
            d3 = design.clone();
            d3.extend(fitted2.cols.iter().cloned());
            let p3 = Projector::new(&d3, all)?;
            if let Some(g1) = refit_grid(prep, f.effect, &p3, y, noise, model, cache) {
                top = g1;
            }
            let mut d4 = design.clone();
            d4.extend(top.cols.iter().cloned());
            let p4 = Projector::new(&d4, all)?;
            if let Some(g2) = refit_grid(prep, f2.effect, &p4, y, noise, model, cache) {
                fitted2 = g2;
            }
        }
        let mut d2 = design.clone();
        d2.extend(top.cols.iter().cloned());
        let block = self.ctx.opts.holdout_block_s;
        let hz1 = holdout_z(&d3, &top.cols, y, &prep.bins, noise, block);
        let hz2 = holdout_z(&d2, &fitted2.cols, y, &prep.bins, noise, block);
        if !(hz1 > HOLDOUT_Z && hz2 > HOLDOUT_Z) {
            return Ok(None);
        }
        f.holdout_z = hz1;
        f2.holdout_z = hz2;
        f2.accepted = true;
        self.candidates.retain(|&c| c != f2.effect);
        self.on_hold.retain(|&c| c != f2.effect);
        *fitted = top;
        Ok(Some((f2, fitted2)))
    }

    /// `f` (and its partner) into the model; the candidates on hold are tried again. Earth's
    /// rate, a constant the bias column spans, moves into the prediction (through the scale
    /// factor) rather than the design, so the bias correction is re-estimated.
    fn accept(
        &mut self,
        mut f: Finding,
        fitted: Fitted,
        partner: Option<(Finding, Fitted)>,
        tried: Vec<Finding>,
    ) {
        self.candidates.append(&mut self.on_hold);
        f.accepted = true;
        let f_id = f.effect;
        self.findings.push(f);
        let findings = &self.findings;
        self.rejected
            .extend(tried.into_iter().filter(|t| !findings.iter().any(|a| a.effect == t.effect)));
        if is_earth(f_id) {
            let prep = self.ctx.prep;
            let scale = 1.0 + self.ctx.model.scale_factor_error;
            for v in &mut self.y {
                *v -= scale * prep.earth;
            }
            if let Some(input) = self.base_design.get_mut(1) {
                for v in input.iter_mut() {
                    *v += prep.earth;
                }
            }
            self.earth_found = true;
        } else {
            let Fitted { p, cols, test } = fitted;
            self.accepted.push(Accepted { id: f_id, p, cols, test });
        }
        if let Some((f2, fitted2)) = partner {
            let Fitted { p, cols, test } = fitted2;
            self.accepted.push(Accepted { id: f2.effect, p, cols, test });
            self.findings.push(f2);
        }
    }

    /// Stepwise: with the newcomer `f_id` in, each earlier effect's grid value is fitted again
    /// and an effect the others now explain is dropped.
    fn drop_explained(&mut self, f_id: EffectId) -> Result<(), AnalysisError> {
        if !(self.accepted.len() >= 2 || (self.earth_found && !self.accepted.is_empty())) {
            return Ok(());
        }
        let (prep, model) = (self.ctx.prep, self.ctx.model);
        let mut i = 0;
        while i < self.accepted.len() {
            let others = model_design(&self.base_design, &self.accepted, Some(i));
            let proj_o = Projector::new(&others, &self.all)?;
            let id = self.accepted[i].id;
            let (y, noise) = (&self.y, &self.noise);
            if let Some(fitted) = refit_grid(prep, id, &proj_o, y, noise, model, &self.column_cache)
            {
                self.accepted[i].p = fitted.p;
                self.accepted[i].cols = fitted.cols;
            }
            let thr = self.thresholds.get(&id).copied().unwrap_or(0.0);
            match proj_o.test(&self.accepted[i].cols, y, noise) {
                Some(t) if t.wald > thr => {
                    self.accepted[i].test = t;
                    i += 1;
                }
                t => {
                    self.accepted.remove(i);
                    if let Some(pos) = self.findings.iter().position(|f| f.effect == id) {
                        let mut dropped = self.findings.remove(pos);
                        dropped.accepted = false;
                        let w = t.map_or(0.0, |t| t.wald);
                        dropped.rejected_because = Some(format!(
                            "explained by {} once that is in the model (Wald {w:.1} ≤ {thr:.1})",
                            f_id.key()
                        ));
                        self.rejected.push(dropped);
                    }
                }
            }
        }
        Ok(())
    }

    /// The family check of every accepted effect ([`check_families`]), then the nuisance
    /// blocks checked again ([`recheck_downgraded`]). Returns whether the model changed.
    fn families(&mut self) -> bool {
        let (prep, model) = (self.ctx.prep, self.ctx.model);
        let ids: Vec<EffectId> = self.accepted.iter().map(|a| a.id).collect();
        let mut state = FamilyState {
            accepted: &mut self.accepted,
            base_design: &mut self.base_design,
            findings: &mut self.findings,
            rejected: &mut self.rejected,
            downgraded: &mut self.downgraded,
            thresholds: &self.thresholds,
            tested: &self.tested,
            preferred: &mut self.preferred,
            cache: &self.column_cache,
            lag_threshold: coil_lag::threshold(self.ctx.opts.alpha),
        };
        let (y, noise, level) = (&self.y, &self.noise, self.level);
        let changed = check_families(prep, model, &ids, &mut state, y, noise, level);
        // A preferred rival's next turn: a candidate again, off hold (the two lists stay apart,
        // so no pool holds it twice), and searched first ([`Search::round`]).
        for &r in &self.preferred {
            self.on_hold.retain(|&c| c != r);
            if !self.candidates.contains(&r) {
                self.candidates.push(r);
            }
        }
        if changed {
            return true;
        }
        recheck_downgraded(
            prep.base.len(),
            &mut self.base_design,
            &mut self.downgraded,
            &self.accepted,
            y,
            noise,
            level,
        )
    }

    /// A time constant refined below its grid against the final model. The search compares
    /// grid values only: refined by least squares, a lag's τ moves to where its Wald is lower
    /// under the correlated noise, and a bias step then outscores it.
    pub(super) fn refine_time_constants(&mut self) -> Result<(), AnalysisError> {
        let (prep, model) = (self.ctx.prep, self.ctx.model);
        for i in 0..self.accepted.len() {
            let id = self.accepted[i].id;
            let Refinement::FinalEvenInLog { each_side } = id.effect().refinement() else {
                continue;
            };
            let others = model_design(&self.base_design, &self.accepted, Some(i));
            let Ok(po) = Projector::new(&others, &self.all) else { continue };
            let (p, cols) = (self.accepted[i].p, self.accepted[i].cols.clone());
            let (y, noise) = (&self.y, &self.noise);
            let Some(test) = po.test(&cols, y, noise) else { continue };
            let mut fitted = Fitted { p, cols, test };
            let mut profile = Vec::new();
            let spacing = Spacing::by_logarithm(each_side);
            refine_between(prep, id, &po, y, noise, model, &mut fitted, &mut profile, spacing);
            self.accepted[i].p = fitted.p;
            self.accepted[i].cols = fitted.cols;
        }
        self.rebuild()
    }

    /// The rejected candidates, the last rejection of each effect not in the model, by
    /// Wald over threshold, largest first.
    pub(super) fn rejections(&mut self) -> Vec<Finding> {
        let mut seen = std::collections::BTreeSet::new();
        let findings = &self.findings;
        let mut rej: Vec<Finding> = std::mem::take(&mut self.rejected)
            .into_iter()
            .rev()
            .filter(|f| !findings.iter().any(|a| a.effect == f.effect) && seen.insert(f.effect))
            .collect();
        rej.sort_by(|a, b| (b.wald / b.threshold).total_cmp(&(a.wald / a.threshold)));
        rej
    }
}
