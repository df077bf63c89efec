//! The coil's lag behind the chamber air, for a gyro without its own temperature sensor: a
//! coefficient of the nominal model (`thermal_time_constant`), profiled here before the search,
//! again beside what the search found, and judged as every slow effect's rival.
//!
//! Without a sensor the model temperature is the chamber air through the model's first-order
//! lag ([`Native::build`]). A lab's model states that lag from a datasheet or an earlier run;
//! the coil's own may be twice or a third of it. The error is then no effect of its own: the
//! thermal terms follow the air early or late, `k_dt·dT/dt` leaves a transient of `τ`'s size
//! after every ramp's start and end (a ramp of 2 °C/min under the writer's k_dt: ≈ 1e-7 rad/s,
//! ten times the flicker), and on a 1 h run a transient decaying over 500–1000 s has the shape
//! of a bias step, a drift or a quadratic in temperature. Measured on the lab writer's random
//! nulls (seeds 17, 20, 26, 30, 36, 59 of `scripts/lab_diagnose_study.py random --hours
//! 0.75,1.5`: every false finding and two false unexplained, all on gyros without a sensor,
//! coil lags 499–1085 s against the lab's 300 s): with the true lag given, all six are clean.
//!
//! So the lag is refitted with the nominal parameters it acts through: the base design (bias,
//! scale factor, k_t, k_dt) is projected out at each τ of a log grid and the least-squares
//! residual profiled ([`profile`]); its minimum is refined by a parabola. The update is taken
//! only when the data determine it: the change it makes to the model, the base projected out,
//! tested as one column against the model lag's residual under the run's noise model (the
//! bins' covariance, flicker and reference lines included) at χ²₁(1 − α), as a term is. Its σ
//! is the linearised least-squares σ of τ under the same covariance. Otherwise the lab's lag is
//! held, as any coefficient the run does not determine.
//!
//! A lag profiled before the search takes part of any effect the run holds (a scale factor
//! varying with temperature, a rate²), and the transient that the wrong lag then leaves is
//! named as a bias step, a slow periodic bias or a drift. So the lag is profiled again with
//! the search's effects and nuisance terms fitted along at every τ, its change tested from the
//! lab's lag again; when that moves it, the search runs again at the new lag (at most
//! [`MAX_REPROFILES`] times). On the lab writer's study seeds 119, 151, 218 and 255 (effect
//! class, gyros without a sensor, coil lags 455–1050 s) the first profile gave 853, 781, 30
//! and 30 s and a step, a drift, a periodic bias or a step was named beside the concealed
//! effect; profiled beside the effects the lag moves (546 s, or back to the lab's 300 s when
//! it is no longer determined: seed 255's first move had Wald 534, beside the effects 1.4) and
//! nothing else is named.
//!
//! On a short run whose coil never settles the lag still trades against a slow effect: each
//! accepted effect has the lag as a rival ([`rival`], judged in [`super::nuisance`]): the lag
//! refitted without the effect, its move passing the lag's own test while the effect at the
//! moved lag keeps at most one test's quantile, is "not told apart: E or the coil's thermal
//! lag". A kink in k_t, outside the library, is judged the same way with the lag refitted
//! beside it ([`kink_rival`]).
//!
//! Beside the lag, an accepted effect whose regressor reads the coil's temperature (a scale
//! factor vs T, a quadratic in T, hysteresis) is built again at every lag tried ([`Beside`]):
//! held as it was built at the lag in use it stands for the wrong coil everywhere else, and the
//! profile cannot move to the lag the data hold. The lab writer's study seed 205 (a scale
//! factor vs T of 1.44 ppm/°C, 2.7e-7 rad/s at 23 °/min and 28 °C from T0, twice the k_t term;
//! the coil 1038 s behind the air): with the column held, the profile stays at 251–327 s
//! (± 74–131 s), the scale factor comes out at half its value and a periodic bias is named
//! beside it.

use super::*;

/// What the lag's profile fits beside the thermal terms: columns that do not depend on the
/// lag (nuisance terms, effects of time, table or angle), and the accepted effects whose
/// regressors read the coil's temperature ([`candidates::reads_temperature`]), rebuilt at each
/// lag tried.
#[derive(Debug, Clone, Default)]
pub(super) struct Beside<'a> {
    /// Columns the same at every lag (bin means).
    pub(super) fixed: Vec<&'a [f64]>,
    /// Effects (id, grid value) built at each lag.
    pub(super) thermal: Vec<(EffectId, f64)>,
}

impl<'a> Beside<'a> {
    /// A model past the calibrated parameters: the nuisance blocks of `base_design` and the
    /// `accepted` effects but `skip`, those that read the coil's temperature to be rebuilt.
    pub(super) fn of(
        base_design: &'a [Vec<f64>],
        accepted: &'a [Accepted],
        skip: Option<usize>,
    ) -> Self {
        let nuisance = base_design.get(ModelKey::CALIBRATED.len()..).unwrap_or_default();
        let mut out =
            Self { fixed: nuisance.iter().map(Vec::as_slice).collect(), thermal: Vec::new() };
        for (_, a) in accepted.iter().enumerate().filter(|(j, _)| Some(*j) != skip) {
            out.push((a.id, a.p, &a.cols));
        }
        out
    }

    /// An effect (id, grid value, columns at the lag in use) beside: rebuilt at each lag where
    /// it reads the coil's temperature, as it is otherwise.
    pub(super) fn push(&mut self, (id, p, cols): (EffectId, f64, &'a [Vec<f64>])) {
        if candidates::reads_temperature(id, p) {
            self.thermal.push((id, p));
        } else {
            self.fixed.extend(cols.iter().map(Vec::as_slice));
        }
    }

    /// Nothing beside.
    pub(super) fn is_empty(&self) -> bool {
        self.fixed.is_empty() && self.thermal.is_empty()
    }
}

/// How many times the lag is profiled again beside what the search found (`diagnose`): each
/// time it moves the search runs again at the new lag.
pub(super) const MAX_REPROFILES: usize = 2;

/// The test the lag's move passes to be taken (and, as an effect's rival, to explain the
/// residual): χ²₁(1 − α), as a term is judged.
pub(super) fn threshold(alpha: f64) -> f64 {
    chi2_quantile(1.0 - alpha, 1.0)
}

/// The lag the profile reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CoilLag {
    /// The model's lag, s.
    pub(super) nominal_s: f64,
    /// The profile's minimum, s.
    pub(super) fitted_s: f64,
    /// Its 1σ under the noise model, s.
    pub(super) sigma_s: f64,
    /// Wald statistic of the change from the model's lag to the fitted one ([`profile`]).
    pub(super) wald: f64,
    /// χ²₁(1 − α).
    pub(super) threshold: f64,
}

impl CoilLag {
    /// Whether the run tells the coil's lag from the model's.
    pub(super) fn significant(&self) -> bool {
        self.wald > self.threshold
    }
}

/// The profile's problem: the nominal residual with the model's thermal terms added back, the
/// bins it is fitted on and the thermal columns at any lag.
struct Setup<'a> {
    prep: &'a Prepared,
    y: Vec<f64>,
    rows: Vec<usize>,
}

impl<'a> Setup<'a> {
    /// `None` where the gyro has its own sensor, the nominal effects already lag the
    /// temperature, or too few bins are left.
    fn new(prep: &'a Prepared, model: &GyroModel) -> Option<Self> {
        if !prep.lag_free {
            return None;
        }
        let n = prep.bins.len();
        // The nominal residual with the model's thermal terms added back: they lie in the
        // base's span at the model's lag, and at any other lag the base refits them.
        let y: Vec<f64> = (0..n)
            .map(|i| {
                prep.y[i] - prep.pred[i]
                    + model.temp_coeff * prep.base[2][i]
                    + model.temp_rate_coeff * prep.base[3][i]
            })
            .collect();
        // Bins that hold a rate change carry the time offset and the reference lines' ends:
        // left out of the profile (they do not depend on the lag).
        let rows: Vec<usize> = (0..n).filter(|&i| !prep.bins[i].transition).collect();
        (rows.len() >= 20).then_some(Self { prep, y, rows })
    }

    fn n(&self) -> usize {
        self.prep.bins.len()
    }

    /// The model temperature's and its rate's bin means through a lag of `tau` (through the
    /// run's memo: the profiles and rivals read the same grid).
    fn thermal(&self, tau: f64) -> Result<std::sync::Arc<[Vec<f64>; 2]>, AnalysisError> {
        Ok(self.at_lag(tau, &[])?.0)
    }

    /// The thermal bin means ([`Self::thermal`]) and the columns of the temperature-reading
    /// `effects` (id, grid value) with the coil `tau` behind the air, through the run's memos:
    /// the coil's temperature is computed once for whatever they lack.
    #[allow(clippy::type_complexity)]
    fn at_lag(
        &self,
        tau: f64,
        effects: &[(EffectId, f64)],
    ) -> Result<(std::sync::Arc<[Vec<f64>; 2]>, Vec<std::sync::Arc<Vec<Vec<f64>>>>), AnalysisError>
    {
        let thermal = self
            .prep
            .lag_thermal
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&tau.to_bits())
            .cloned();
        let mut cols: Vec<Option<std::sync::Arc<Vec<Vec<f64>>>>> = {
            let memo = self.prep.lag_effects.lock().unwrap_or_else(|e| e.into_inner());
            effects
                .iter()
                .map(|&(id, p)| memo.get(&(tau.to_bits(), id, p.to_bits())).cloned())
                .collect()
        };
        if let (Some(th), true) = (&thermal, cols.iter().all(Option::is_some)) {
            return Ok((th.clone(), cols.into_iter().flatten().collect()));
        }
        let (nat, bins, t0) = (&self.prep.native, &self.prep.bins, self.prep.t0);
        let (temp, rate) = series::coil_temperature(&nat.t, &nat.air_c, tau)?;
        let thermal = match thermal {
            Some(th) => th,
            None => {
                let th = std::sync::Arc::new([
                    bin_mean(bins, &nat.dt, |k| temp[k] - t0),
                    bin_mean(bins, &nat.dt, |k| rate[k]),
                ]);
                let mut memo = self.prep.lag_thermal.lock().unwrap_or_else(|e| e.into_inner());
                memo.insert(tau.to_bits(), th.clone());
                th
            }
        };
        if cols.iter().any(Option::is_none) {
            let hysteresis = bench_physics::effects::HysteresisState::series(HYST_C_S, &rate);
            let mut memo = self.prep.lag_effects.lock().unwrap_or_else(|e| e.into_inner());
            for (slot, &(id, p)) in cols.iter_mut().zip(effects) {
                if slot.is_none() {
                    let c = std::sync::Arc::new(candidates::per_sample_columns_at(
                        self.prep,
                        id,
                        p,
                        &temp,
                        &hysteresis,
                    ));
                    memo.insert((tau.to_bits(), id, p.to_bits()), c.clone());
                    *slot = Some(c);
                }
            }
        }
        Ok((thermal, cols.into_iter().flatten().collect()))
    }

    /// Effect `id`'s columns with the coil `tau` behind the air: rebuilt there where it reads
    /// the coil's temperature, its columns at the lag in use (`cols`) otherwise.
    fn effect_columns_at<'c>(
        &self,
        tau: f64,
        (id, p, cols): (EffectId, f64, &'c [Vec<f64>]),
    ) -> Result<std::borrow::Cow<'c, [Vec<f64>]>, AnalysisError> {
        Ok(if candidates::reads_temperature(id, p) {
            std::borrow::Cow::Owned(self.at_lag(tau, &[(id, p)])?.1[0].to_vec())
        } else {
            std::borrow::Cow::Borrowed(cols)
        })
    }

    /// The base design at lag `tau`, then `beside` (its temperature-reading effects at `tau`).
    fn design(&self, tau: f64, beside: &Beside) -> Result<Vec<Vec<f64>>, AnalysisError> {
        let (th, effects) = self.at_lag(tau, &beside.thermal)?;
        let base = &self.prep.base;
        let mut d = vec![base[0].clone(), base[1].clone(), th[0].clone(), th[1].clone()];
        d.extend(beside.fixed.iter().map(|c| c.to_vec()));
        d.extend(effects.iter().flat_map(|e| e.iter().cloned()));
        Ok(d)
    }

    fn projector(&self, tau: f64, beside: &Beside) -> Result<Projector, AnalysisError> {
        Projector::new(&self.design(tau, beside)?, &self.rows)
    }

    /// The least-squares lag with `beside` fitted along: the minimum of the residual over a
    /// log grid (30..4000 s, ×1.25, and `nominal`), refined by a parabola in ln τ.
    fn best(&self, beside: &Beside, nominal: f64) -> Result<f64, AnalysisError> {
        let n = self.n();
        self.best_by(nominal, |tau| {
            let r = self.projector(tau, beside)?.residual(&self.y, n);
            Ok(r.iter().map(|x| x * x).sum())
        })
    }

    /// The lag that minimises `rss` ([`Self::best`]'s grid and refinement).
    fn best_by(
        &self,
        nominal: f64,
        rss: impl Fn(f64) -> Result<f64, AnalysisError>,
    ) -> Result<f64, AnalysisError> {
        let mut grid: Vec<f64> = std::iter::successors(Some(30.0), |t| Some(t * 1.25))
            .take_while(|t| *t <= 4000.0)
            .collect();
        if nominal > 0.0 {
            grid.push(nominal);
            grid.sort_by(f64::total_cmp);
        }
        let prof: Vec<(f64, f64)> =
            grid.iter().map(|&t| rss(t).map(|v| (t, v))).collect::<Result<_, _>>()?;
        let k =
            prof.iter().enumerate().min_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).map_or(0, |(i, _)| i);
        let mut best = prof[k].0;
        if k > 0 && k + 1 < prof.len() {
            // The parabola's vertex in ln τ through the minimum and its neighbours.
            let (x0, x1, x2) = (prof[k - 1].0.ln(), prof[k].0.ln(), prof[k + 1].0.ln());
            let (y0, y1, y2) = (prof[k - 1].1, prof[k].1, prof[k + 1].1);
            let den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
            if den.abs() > 0.0 {
                let v = x1
                    - 0.5 * ((x1 - x0).powi(2) * (y1 - y2) - (x1 - x2).powi(2) * (y1 - y0)) / den;
                if v.is_finite() && v > x0 && v < x2 && rss(v.exp())? < prof[k].1 {
                    best = v.exp();
                }
            }
        }
        Ok(best)
    }

    /// The fitted k_t and k_dt at lag `tau` with `beside`.
    fn thermal_coeffs(&self, at: &Projector) -> (f64, f64) {
        let beta = at.beta(&self.y);
        let coef = |j: usize| at.kept.iter().position(|&c| c == j).map_or(0.0, |c| beta[c]);
        (coef(2), coef(3))
    }

    /// The Wald statistic of moving the lag from `from` to `to` with `beside` fitted along:
    /// the change it makes to the model (at `to`'s k_t, k_dt), `from`'s design projected out,
    /// as one column against `from`'s residual under `noise` — a term's test; a linearised
    /// `((τ̂ − τ₀)/σ)²` would understate a long lag, whose response saturates.
    fn change_wald(
        &self,
        from: f64,
        to: f64,
        beside: &Beside,
        noise: &BinNoise,
    ) -> Result<f64, AnalysisError> {
        if from <= 0.0 {
            return Ok(f64::INFINITY);
        }
        let n = self.n();
        let at_to = self.projector(to, beside)?;
        let (kt, kdt) = self.thermal_coeffs(&at_to);
        let at_from = self.projector(from, beside)?;
        let ((th0, e0), (th1, e1)) =
            (self.at_lag(from, &beside.thermal)?, self.at_lag(to, &beside.thermal)?);
        let ([t0m, r0m], [t1m, r1m]) = (&*th0, &*th1);
        let mut u: Vec<f64> =
            (0..n).map(|i| kt * (t1m[i] - t0m[i]) + kdt * (r1m[i] - r0m[i])).collect();
        // The temperature-reading effects beside move with the lag too: their columns' change
        // at `to`'s coefficients.
        let beta = at_to.beta(&self.y);
        let first = 4 + beside.fixed.len();
        let changes = e0.iter().zip(&e1).flat_map(|(c0, c1)| c0.iter().zip(c1.iter()));
        for (j, (c0, c1)) in changes.enumerate() {
            let Some(b) = at_to.kept.iter().position(|&c| c == first + j).map(|c| beta[c]) else {
                continue;
            };
            u.iter_mut().zip(c0.iter().zip(c1)).for_each(|(x, (a, z))| *x += b * (z - a));
        }
        let u = at_from.residual(&u, n);
        let r0 = at_from.residual(&self.y, n);
        let uu = noise.quad(&u, &u);
        let ur: f64 = u.iter().zip(&r0).map(|(a, b)| a * b).sum();
        Ok(if uu > 0.0 { ur * ur / uu } else { 0.0 })
    }
}

/// Profile the coil's lag on `prep` (prepared with `model`'s lag, `noise_spec` its noise
/// model), with the columns `beside` (effects and nuisance terms found at that lag, bin means)
/// fitted along at every lag; the change is tested from `from_s` (the lab's lag). `None` where
/// the gyro has its own sensor, the nominal effects already lag the temperature, or the
/// profile is flat.
#[allow(clippy::too_many_arguments)]
pub(super) fn profile(
    prep: &Prepared,
    noise_spec: NoiseSpec,
    model: &GyroModel,
    alpha: f64,
    beside: &Beside,
    from_s: f64,
) -> Result<Option<CoilLag>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let n = setup.n();
    let best = setup.best(beside, from_s)?;
    // σ of τ: the model's response to τ (at the fitted k_t, k_dt), the design projected out,
    // its least-squares coefficient's variance under the noise model.
    let at = setup.projector(best, beside)?;
    let (kt, kdt) = setup.thermal_coeffs(&at);
    let h = 0.02 * best;
    let (plus, minus) = (setup.thermal(best + h)?, setup.thermal(best - h)?);
    let ([tp, rp], [tmn, rmn]) = (&*plus, &*minus);
    let d: Vec<f64> =
        (0..n).map(|i| (kt * (tp[i] - tmn[i]) + kdt * (rp[i] - rmn[i])) / (2.0 * h)).collect();
    let c = at.residual(&d, n);
    let cc: f64 = c.iter().map(|x| x * x).sum();
    if cc.is_nan() || cc <= 0.0 {
        return Ok(None);
    }
    let noise = BinNoise::new(&prep.bins, noise_spec).with_reference(prep.reference.clone());
    let sigma = noise.quad(&c, &c).sqrt() / cc;
    let wald = setup.change_wald(from_s, best, beside, &noise)?;
    Ok(Some(CoilLag {
        nominal_s: from_s,
        fitted_s: best,
        sigma_s: sigma,
        wald,
        threshold: threshold(alpha),
    }))
}

/// What the coil's lag's uncertainty costs each coefficient of the final model (`final_fit`):
/// every coefficient is fitted at the lag in use (`model`'s: the profile's minimum where the run
/// determines the lag, else the lab's, held), and is conditional on it. The final design
/// (`base_design` with its `zeroed` columns out, then the `accepted` effects; the thermal
/// columns and the effects that read the coil's temperature built at each lag) is fitted with
/// the lag moved one profile σ down and up in ln τ (the profile's σ relative to its minimum,
/// `lag`): half the change of each column's coefficient, indexed by design column (0 where a
/// fit drops it). Added to the covariance as `s·sᵀ`, it is the coefficients' variance with the
/// lag free as far as the run holds it. `None` where the lag is not profiled or its σ is not
/// finite.
///
/// The lab writer's study seeds 23, 205 and 218 (gyros without a sensor, a scale factor vs T,
/// coils 776–1058 s behind the air, the lab's 300 s): the lag fitted at 1414 ± 789 s and
/// 859 ± 540 s, or held (profile 538 ± 350 s, Wald 3.6): the scale factor's coefficient came
/// out 3.6σ, 4.0σ and 11σ from the truth with the σ of the lag in use alone.
pub(super) fn lag_shift(
    prep: &Prepared,
    model: &GyroModel,
    lag: &CoilLag,
    base_design: &[Vec<f64>],
    zeroed: &[bool],
    accepted: &[Accepted],
) -> Result<Option<Vec<f64>>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let (center, rel) = (model.thermal_time_constant, lag.sigma_s / lag.fitted_s);
    if !(rel.is_finite() && rel > 0.0 && center > 0.0 && base_design.len() >= 4) {
        return Ok(None);
    }
    let all: Vec<usize> = (0..setup.n()).collect();
    let beta_at = |tau: f64| -> Result<Vec<f64>, AnalysisError> {
        let th = setup.thermal(tau)?;
        let mut d = base_design.to_vec();
        d[2].clone_from(&th[0]);
        d[3].clone_from(&th[1]);
        for (col, z) in d.iter_mut().zip(zeroed) {
            if *z {
                col.iter_mut().for_each(|x| *x = 0.0);
            }
        }
        for a in accepted {
            d.extend(setup.effect_columns_at(tau, (a.id, a.p, &a.cols))?.iter().cloned());
        }
        let at = Projector::new(&d, &all)?;
        let b = at.beta(&setup.y);
        let mut out = vec![f64::NAN; d.len()];
        for (c, &col) in at.kept.iter().enumerate() {
            out[col] = b[c];
        }
        Ok(out)
    };
    let (up, down) = (beta_at(center * rel.exp())?, beta_at(center / rel.exp())?);
    Ok(Some(
        up.iter()
            .zip(&down)
            .map(|(u, d)| if u.is_finite() && d.is_finite() { 0.5 * (u - d) } else { 0.0 })
            .collect(),
    ))
}

/// The coil's lag as the rival of an accepted effect ([`super::nuisance`]): the lag refitted
/// without the effect.
pub(super) struct LagRival {
    /// The lag in use, s.
    pub from_s: f64,
    /// The lag refitted without the effect, s.
    pub tau_s: f64,
    /// The move's Wald statistic from the lag in use.
    pub lag: f64,
    /// The effect's Wald statistic at the lag in use, on the profile's bins.
    pub effect_here: f64,
    /// The effect's Wald statistic at the refitted lag.
    pub effect_there: f64,
}

/// [`LagRival`] of an effect `id` at grid value `p` with columns `cols` (bin means, prepared
/// at `model`'s lag): `beside` the rest of the model past the calibrated parameters,
/// `test(projector, y, cols)` the effect's Wald statistic with its columns `cols` against a
/// design for the profile's residual `y` — at the refitted lag the columns of an effect that
/// reads the coil's temperature are that lag's. `None` where the lag is not profiled.
pub(super) fn rival(
    prep: &Prepared,
    model: &GyroModel,
    (id, p, cols): (EffectId, f64, &[Vec<f64>]),
    beside: &Beside,
    noise: &BinNoise,
    test: impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64,
) -> Result<Option<LagRival>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let from_s = model.thermal_time_constant;
    let tau_s = setup.best(beside, from_s)?;
    let lag = setup.change_wald(from_s, tau_s, beside, noise)?;
    let effect_here = test(&setup.projector(from_s, beside)?, &setup.y, cols);
    let there = setup.effect_columns_at(tau_s, (id, p, cols))?;
    let effect_there = test(&setup.projector(tau_s, beside)?, &setup.y, &there);
    Ok(Some(LagRival { from_s, tau_s, lag, effect_here, effect_there }))
}

/// An effect and a declared rival judged at the coil lag the rival's model holds
/// ([`effect_at_rivals_lag`]).
pub(super) struct AtRivalsLag {
    /// The lag profiled beside the rest of the model and the rival, s.
    pub tau_s: f64,
    /// The rival's Wald statistic there, without the effect.
    pub rival: f64,
    /// The effect's Wald statistic there, beside the rival.
    pub effect: f64,
}

/// Effect `e` and its declared rival `r` (each: id, grid value, columns at the lag in use) at
/// the rival's own lag ([`super::rivals`]): the lag profiled with `beside` — the rest of the
/// model past the calibrated parameters, without either — and the rival; where that moves it
/// from the lag in use by more than the lag's own test (`lag_threshold`), the rival's Wald
/// statistic there without the effect and the effect's beside the rival (`test_e`, `test_r` as
/// in [`rival`]; an effect that reads the coil's temperature with that lag's columns); a rival
/// with a grid (`refit_r`: its best columns against a design, `None` for none) fitted on it
/// again at each lag. `None` where the lag is not profiled or the rival leaves it where it is.
///
/// A rival whose model holds another lag must be judged there: the lab writer's study seed 242
/// (a rate² on a sensor-less gyro, turns at 28.3, 28.5 and 6.5 °/min, the coil 741 s behind
/// the air): at the lag the search settled on (≈ 300 s) a scale-factor asymmetry fits the
/// residual better than the rate² (ρ = 0.994 between them), is named, and a step and a lag are
/// named beside it; the rate² with the coil's own lag fits better than all three.
#[allow(clippy::too_many_arguments)]
pub(super) fn effect_at_rivals_lag(
    prep: &Prepared,
    model: &GyroModel,
    e: (EffectId, f64, &[Vec<f64>]),
    r: (EffectId, f64, &[Vec<f64>]),
    beside: &Beside,
    noise: &BinNoise,
    lag_threshold: f64,
    (test_e, test_r): (
        impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64,
        impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64,
    ),
    refit_r: impl Fn(&Projector, &[f64]) -> Option<Vec<Vec<f64>>>,
) -> Result<Option<AtRivalsLag>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let from_s = model.thermal_time_constant;
    // A rival with a grid of its own (a step's time, a warm-up's τ, a period) is fitted on it
    // again at every lag tried: its value and the lag are chosen together (a step's time chosen
    // at a lag that has taken the step's transient is not the step's).
    let n = setup.n();
    let refit = |tau: f64| -> Result<Option<Vec<Vec<f64>>>, AnalysisError> {
        Ok(refit_r(&setup.projector(tau, beside)?, &setup.y))
    };
    let r_cols: Vec<Vec<f64>> =
        if candidates::reads_temperature(r.0, r.1) || refit(from_s)?.is_none() {
            r.2.to_vec()
        } else {
            let tau = setup.best_by(from_s, |tau| {
                let Some(cols) = refit(tau)? else { return Ok(f64::INFINITY) };
                let mut with = beside.clone();
                with.fixed.extend(cols.iter().map(Vec::as_slice));
                let res = setup.projector(tau, &with)?.residual(&setup.y, n);
                Ok(res.iter().map(|x| x * x).sum())
            })?;
            refit(tau)?.unwrap_or_else(|| r.2.to_vec())
        };
    let r = (r.0, r.1, r_cols.as_slice());
    let test_r = |_: usize, at: &Projector, y: &[f64], c: &[Vec<f64>]| test_r(at, y, c);
    let found = effect_beside_rivals_at_their_lag(
        prep,
        model,
        e,
        &[r],
        beside,
        noise,
        lag_threshold,
        test_e,
        test_r,
    )?;
    Ok(found.map(|(tau_s, rivals, effect)| AtRivalsLag { tau_s, rival: rivals[0], effect }))
}

/// Effect `e` and declared rivals `rs` that explain it only together (each: id, grid value,
/// columns at the lag in use; [`super::rivals`]) at the lag their model holds: the lag profiled
/// with `beside` and all of `rs` at their grid values; where that moves it from the lag in use
/// by more than the lag's own test, each rival's Wald statistic there beside the others
/// (`test_r(index, …)`) and the effect's beside them all. `None` where the lag is not profiled
/// or stays.
#[allow(clippy::too_many_arguments)]
pub(super) fn effect_beside_rivals_at_their_lag(
    prep: &Prepared,
    model: &GyroModel,
    e: (EffectId, f64, &[Vec<f64>]),
    rs: &[(EffectId, f64, &[Vec<f64>])],
    beside: &Beside,
    noise: &BinNoise,
    lag_threshold: f64,
    test_e: impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64,
    test_r: impl Fn(usize, &Projector, &[f64], &[Vec<f64>]) -> f64,
) -> Result<Option<(f64, Vec<f64>, f64)>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let from_s = model.thermal_time_constant;
    let mut with_r = beside.clone();
    rs.iter().for_each(|&r| with_r.push(r));
    let tau_s = setup.best(&with_r, from_s)?;
    if setup.change_wald(from_s, tau_s, &with_r, noise)? <= lag_threshold {
        return Ok(None);
    }
    // Each one's columns at that lag, each rival beside the others.
    let mut rivals = Vec::with_capacity(rs.len());
    for (j, &r) in rs.iter().enumerate() {
        let mut others = beside.clone();
        rs.iter().enumerate().filter(|(k, _)| *k != j).for_each(|(_, &o)| others.push(o));
        let at = setup.projector(tau_s, &others)?;
        rivals.push(test_r(j, &at, &setup.y, &setup.effect_columns_at(tau_s, r)?));
    }
    let effect =
        test_e(&setup.projector(tau_s, &with_r)?, &setup.y, &setup.effect_columns_at(tau_s, e)?);
    Ok(Some((tau_s, rivals, effect)))
}

/// A kink in k_t with the coil's lag refitted beside it, as the rival of an accepted effect
/// ([`kink_rival`]).
pub(super) struct KinkRival {
    /// The knot, °C.
    pub knot_c: f64,
    /// The lag in use, s.
    pub from_s: f64,
    /// The lag refitted beside the kink, without the effect, s.
    pub tau_s: f64,
    /// The kink's Wald statistic there, without the effect.
    pub kink: f64,
    /// The effect's Wald statistic at the refitted lag, beside the kink.
    pub effect_there: f64,
}

/// The kink in k_t ([`super::hinge`]) that, with the coil's lag refitted beside it, best
/// explains what the rest of the model leaves, as the rival of effect `id` at grid value `p`
/// with columns `cols` (bin means at `model`'s lag): each knot of `knots` (°C) with the lag
/// profiled along it (its hinge built at every lag tried: a kink is in the coil's
/// temperature), the one of least residual kept; then the kink's Wald statistic there without
/// the effect, and the effect's beside the kink at the refitted lag (`test` as in [`rival`]).
/// `None` where the lag is not profiled, there is no knot, or the effect does not pass `thr_e`
/// at the lag in use on the profile's bins (nothing to explain).
///
/// A kink's passage on a gyro whose coil lags far more than the lab's model says reads, at the
/// lag in use, as an effect of time: the lab writer's study (outside class, full length) seed 9,
/// a kink of 6.4e-9 rad/s/°C at 2 °C, no sensor, the coil 1172 s behind the air against the
/// lab's 300 s: a bias step of Wald 44.6 at 2856 s, its family clean, the lag held (its profile
/// without the kink moves the model by Wald 4.2 ≤ 6.6). With the lag and the kink fitted
/// together the kink explains the residual and the step keeps nothing.
#[allow(clippy::too_many_arguments)]
pub(super) fn kink_rival(
    prep: &Prepared,
    model: &GyroModel,
    (id, p, cols): (EffectId, f64, &[Vec<f64>]),
    beside: &Beside,
    noise: &BinNoise,
    knots: &[f64],
    test: impl Fn(&Projector, &[f64], &[Vec<f64>]) -> f64,
    thr_e: f64,
) -> Result<Option<KinkRival>, AnalysisError> {
    let Some(setup) = Setup::new(prep, model) else {
        return Ok(None);
    };
    let (n, from_s) = (setup.n(), model.thermal_time_constant);
    let effect_here = test(&setup.projector(from_s, beside)?, &setup.y, cols);
    if knots.is_empty() || effect_here <= thr_e {
        return Ok(None);
    }
    // Every knot's hinge at a lag, from one pass of the coil's temperature there (the knots'
    // profiles try the same grid of lags).
    type Hinges = std::rc::Rc<Vec<Vec<f64>>>;
    let memo: std::cell::RefCell<std::collections::BTreeMap<u64, Hinges>> = Default::default();
    let hinges_at = |tau: f64| -> Result<Hinges, AnalysisError> {
        if let Some(h) = memo.borrow().get(&tau.to_bits()) {
            return Ok(h.clone());
        }
        let (nat, bins) = (&prep.native, &prep.bins);
        let (temp, _) = series::coil_temperature(&nat.t, &nat.air_c, tau)?;
        let h: Hinges = std::rc::Rc::new(
            knots.iter().map(|tk| bin_mean(bins, &nat.dt, |k| (temp[k] - tk).max(0.0))).collect(),
        );
        memo.borrow_mut().insert(tau.to_bits(), h.clone());
        Ok(h)
    };
    let with_kink = |tau: f64, j: usize| -> Result<Projector, AnalysisError> {
        let mut d = setup.design(tau, beside)?;
        d.push(hinges_at(tau)?[j].clone());
        Projector::new(&d, &setup.rows)
    };
    let rss = |at: &Projector| at.residual(&setup.y, n).iter().map(|x| x * x).sum::<f64>();
    let mut best: Option<(usize, f64, f64)> = None;
    for j in 0..knots.len() {
        let tau = setup.best_by(from_s, |tau| Ok(rss(&with_kink(tau, j)?)))?;
        let r = rss(&with_kink(tau, j)?);
        if best.is_none_or(|(_, _, b)| r < b) {
            best = Some((j, tau, r));
        }
    }
    let Some((j, tau_s, _)) = best else { return Ok(None) };
    let hinge = hinges_at(tau_s)?[j].clone();
    let kink = setup
        .projector(tau_s, beside)?
        .test(std::slice::from_ref(&hinge), &setup.y, noise)
        .map_or(0.0, |t| t.wald);
    let there = setup.effect_columns_at(tau_s, (id, p, cols))?;
    let effect_there = test(&with_kink(tau_s, j)?, &setup.y, &there);
    Ok(Some(KinkRival { knot_c: knots[j], from_s, tau_s, kink, effect_there }))
}
