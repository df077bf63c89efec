//! Diagnosis: where a recording departs from the simulation of the same run, which physics
//! the model left out, and how much better the fit gets with it.
//!
//! 1. **Simulate the run**: the nominal model ([`bench_physics::GyroModel`] plus any
//!    [`Effects`] it already has) is driven by the recording's own table motion, temperatures,
//!    time and latitude, and its prediction is subtracted from the gyro: the residual. All of
//!    it is done on bin means ([`series`]).
//! 2. **Refit the nominal parameters** (bias, scale factor, temperature and temperature-rate
//!    coefficients) as corrections; they are jointly significant when their Wald statistic
//!    under the noise model exceeds χ²_p(1 − α).
//! 3. **Noise model**: the overlapping Allan deviation of the residual (short τ from the
//!    native samples on settled table segments, long τ from the bins) fitted with white +
//!    flicker ([`crate::calibrate::fit_noise_spec_all_points`]: no point left out); every test below
//!    uses its covariance ([`noise`]), so slow bias wander is not mistaken for structure.
//! 4. **Explain**: each effect of the library ([`bench_physics::effects`]) is tried as extra
//!    regressors (nonlinear parameters by grid search, linear ones by projection), scored by a
//!    Wald statistic with the noise model's covariance ([`fit`]). An effect is accepted when
//!    (a) its Wald statistic passes its threshold at `α / effects`: χ²_k, or for a grid the
//!    tail of W at the grid's least-squares peak under the noise model ([`scan`]), (b) its
//!    ΔBIC = W − (k + q)·ln n_eff is positive, n_eff the noise model's effective number of
//!    independent bins, and (c) the shape fitted on alternate time blocks (sized to the term)
//!    predicts the held-out blocks (combined z > 3). The passing candidate with the largest
//!    ΔBIC joins the model; when its held-out check fails, the best partner is tried with it
//!    (two missing effects spoil each other's hold-out). Each time an effect joins, the
//!    earlier ones' grid values are refitted and any that is no longer significant is dropped.
//!    The search repeats until nothing passes.
//! 5. **Locate and report what is left**: residual by step, direction, heating/cooling,
//!    temperature band and table angle; blocks whose mean departs from the noise model are
//!    `unexplained`, with the signal they correlate with best.
//!
//! The stages, one module each: [`types`] (settings and results), [`prepare`] (step 1 and the
//! noise model), [`candidates`] (each effect's regressors and grid, from its registry entry),
//! [`search`] (one round of step 4), [`stepwise`] (the rounds: hold-out, partners, drops, the
//! family check), [`refine`] and [`regrid`] (grid values below the grid and refitted),
//! [`holdout`], [`nuisance`] (structure a family check did not confirm), [`rivals`] (an
//! effect the recording cannot tell from a declared rival), [`final_fit`],
//! [`locate`] (step 5), [`identify`]; [`residual_scan`] is the first round alone, timed.

mod candidates;
mod coil_lag;
mod columns;
pub mod family;
mod final_fit;
pub mod fit;
mod hinge;
mod holdout;
pub mod identify;
mod locate;
pub mod noise;
mod nuisance;
mod prepare;
mod refine;
mod regrid;
mod residual_scan;
mod rivals;
pub mod scan;
mod scatter;
mod search;
pub mod series;
mod stepwise;
mod types;

pub use columns::default_threads;
pub use residual_scan::{residual_scan, residual_scan_effects, ResidualScan, ScanBest, ScanInputs};
pub use types::*;

use candidates::*;
use final_fit::*;
use holdout::*;
use locate::*;
use nuisance::*;
use prepare::*;
use refine::*;
use regrid::*;
use search::*;
use stepwise::*;

use bench_physics::allan::{chi2_quantile, normal_quantile, AdevPoint};
use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::effects::{
    lag_temperature, Columns, EffectId, EffectSample, Effects, Grid, Order, Refinement, Reported,
    Role, HYSTERESIS_THRESHOLD_C_S,
};
use bench_physics::{GyroModel, ModelKey};

use crate::calibrate::{fit_noise_spec_all_points, pooled_adev};
use crate::error::AnalysisError;
use crate::joint_fit::NoiseSpec;
use crate::windows::RecordWindow;

use crate::steady::{TableMotion, TableSegment};
pub use family::{FamilyCheck, FamilyMember, RateDependence};
use fit::Projector;
pub use identify::Collinearity;
use noise::BinNoise;
use series::{bin_mean, make_bins, Bin, Native, RunSeries};

/// Hysteresis threshold used for the candidate (the library's default).
const HYST_C_S: f64 = HYSTERESIS_THRESHOLD_C_S;
/// z the held-out blocks must reach to confirm an effect.
const HOLDOUT_Z: f64 = 3.0;
/// Least share of a term's energy a set of blocks must hold to be fitted on in the hold-out.
const HOLDOUT_MIN_SHARE: f64 = 0.2;
/// Seed of the scan-threshold draws ([`scan`]): fixed, so a diagnosis is reproducible.
const SCAN_SEED: u64 = 0x5eed_d1a6;

/// Whether effect `id` is Earth's rate (tested as the bias correction, not as a regressor).
fn is_earth(id: EffectId) -> bool {
    id.effect().columns() == Columns::EarthRate
}

/// A candidate fitted at its best grid value.
struct Fitted {
    /// Grid value (NaN for none).
    p: f64,
    /// Its columns.
    cols: Vec<Vec<f64>>,
    /// The test.
    test: fit::TermTest,
}

/// An effect in the model.
struct Accepted {
    id: EffectId,
    /// Its grid value (NaN for none).
    p: f64,
    /// Its columns.
    cols: Vec<Vec<f64>>,
    /// Its last test.
    test: fit::TermTest,
}

/// The model's design: the base columns, then each accepted effect's but `skip`'s, in order.
fn model_design(base: &[Vec<f64>], accepted: &[Accepted], skip: Option<usize>) -> Vec<Vec<f64>> {
    model_design_but(base, accepted, skip.as_slice())
}

/// The model's design without the accepted effects at positions `skip`.
fn model_design_but(base: &[Vec<f64>], accepted: &[Accepted], skip: &[usize]) -> Vec<Vec<f64>> {
    let kept = accepted.iter().enumerate().filter(|(j, _)| !skip.contains(j));
    base.iter().chain(kept.flat_map(|(_, a)| &a.cols)).cloned().collect()
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// The nominal parameters refitted as corrections (module docs, steps 2 and 3).
struct BaseFit {
    /// The nominal residual, bin means.
    y: Vec<f64>,
    /// The projector of the nominal parameters' columns.
    proj: Projector,
    /// The residual after the refit.
    r: Vec<f64>,
    /// The noise model of `r`.
    noise_spec: NoiseSpec,
    noise: BinNoise,
    /// The corrections' joint Wald test.
    wald: WaldTest,
}

impl BaseFit {
    /// The refit on `prep` under its noise model `noise_spec` ([`noise_model`] of `prep`).
    fn new(prep: &Prepared, noise_spec: NoiseSpec, alpha: f64) -> Result<Self, AnalysisError> {
        let n = prep.bins.len();
        let all: Vec<usize> = (0..n).collect();
        let y: Vec<f64> = prep.y.iter().zip(&prep.pred).map(|(a, b)| a - b).collect();
        let proj = Projector::new(&prep.base, &all)?;
        let r = proj.residual(&y, n);
        let noise = BinNoise::new(&prep.bins, noise_spec)
            .with_reference(prep.reference.clone())
            .with_white_scale(&prep.bins, &prep.scatter.scale);
        let beta0 = proj.beta(&y);
        let cov0 = proj.covariance(&noise);
        let p0 = beta0.len();
        let params_wald = nalgebra::DVector::from_vec(beta0);
        let value = cov0
            .try_inverse()
            .map_or(0.0, |ci| (params_wald.transpose() * ci * &params_wald)[(0, 0)]);
        let threshold = if p0 > 0 { chi2_quantile(1.0 - alpha, p0 as f64) } else { f64::INFINITY };
        Ok(Self { y, proj, r, noise_spec, noise, wald: WaldTest { value, threshold } })
    }
}

/// The options a diagnosis refuses.
fn check_options(opts: &DiagnoseOptions) -> Result<(), AnalysisError> {
    if !(opts.bin_s.is_finite() && opts.bin_s > 0.0) {
        return Err(AnalysisError::InvalidParameter {
            name: "bin_s",
            value: opts.bin_s,
            why: "must be a positive number of seconds",
        });
    }
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(AnalysisError::InvalidParameter {
            name: "alpha",
            value: opts.alpha,
            why: "must be a probability in (0, 1)",
        });
    }
    Ok(())
}

/// Diagnose `run` against the nominal `model` with its `effects` (module docs).
pub fn diagnose(
    run: &RunSeries,
    model: &GyroModel,
    effects: &Effects,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, AnalysisError> {
    check_options(opts)?;
    let mut prep = prepare(run, model, effects, opts)?;
    let mut noise_spec = noise_model(&prep)?;
    // A gyro without its own sensor: the coil's lag refitted where the run determines it
    // ([`coil_lag`]), and everything after prepared with it.
    let nominal_lag_s = model.thermal_time_constant;
    // The last profile taken: where it does not move the lag, the lag is held at the lab's.
    let mut profiled = coil_lag::profile(
        &prep,
        noise_spec,
        model,
        opts.alpha,
        &coil_lag::Beside::default(),
        nominal_lag_s,
    )?;
    let mut lag = profiled.filter(|l| l.significant());
    let mut lagged = model.clone();
    let mut passes = 0;
    let (base, mut search) = loop {
        let tau = lag.map_or(nominal_lag_s, |l| l.fitted_s);
        if lagged.thermal_time_constant != tau {
            lagged.thermal_time_constant = tau;
            prep = prepare(run, &lagged, effects, opts)?;
            noise_spec = noise_model(&prep)?;
        }
        let base = BaseFit::new(&prep, noise_spec, opts.alpha)?;
        let mut search =
            Search::new(&prep, &lagged, effects, run.latitude_deg.is_some(), opts, &base);
        search.run()?;
        // The lag again with what the search found beside it ([`coil_lag`]: a lag profiled
        // without an effect the run holds takes part of it, and what the lag then leaves
        // is named as slow shapes): when it moves, the search runs again at the new lag.
        let beside = (passes < coil_lag::MAX_REPROFILES)
            .then(|| coil_lag::Beside::of(&search.base_design, &search.accepted, None))
            .filter(|b| !b.is_empty());
        if let Some(beside) = beside {
            if let Some(l) =
                coil_lag::profile(&prep, noise_spec, &lagged, opts.alpha, &beside, nominal_lag_s)?
            {
                profiled = Some(l);
                let again = l.significant().then_some(l);
                let moved = again.map_or(nominal_lag_s, |l| l.fitted_s);
                if (moved / tau - 1.0).abs() > 0.01 {
                    passes += 1;
                    lag = again;
                    continue;
                }
            }
        }
        break (base, search);
    };
    let location = locate(&prep, run, &base.r, &base.noise, &base.proj, &base.y);
    let rejections = search.rejections();
    search.refine_time_constants()?;
    let held_lag = profiled.filter(|l| lag.is_none() && !l.significant());
    let mut fit = final_fit(&mut search, effects, &base.proj, lag.or(held_lag).as_ref())?;
    if let Some(l) = lag {
        fit.parameter_updates.push(ParameterUpdate {
            key: ModelKey::ThermalTimeConstant,
            nominal: l.nominal_s,
            fitted: l.fitted_s,
            sigma: l.sigma_s,
            held: None,
        });
    } else if let Some(l) = held_lag {
        fit.parameter_updates.push(ParameterUpdate {
            key: ModelKey::ThermalTimeConstant,
            nominal: l.nominal_s,
            fitted: l.nominal_s,
            sigma: l.sigma_s,
            held: Some(format!(
                "held at the nominal value: the run does not determine the coil's lag (its \
                 profile's minimum {:.0} ± {:.0} s moves the model by Wald {:.1} ≤ {:.1}); the \
                 fitted parameters' and effects' σ include a 1σ move of it",
                l.fitted_s, l.sigma_s, l.wald, l.threshold
            )),
        });
    }
    let collinearity = identifiability(&search);
    let mut unexplained = unexplained(&prep, &search.r, &search.noise, opts);
    unexplained
        .splice(0..0, std::mem::take(&mut search.downgraded).into_iter().map(|d| d.unexplained));
    // Windows whose own scatter exceeds the model's ([`scatter`]), first.
    unexplained.splice(0..0, prep.scatter.unexplained());
    let verdict = if !search.findings.is_empty() || !unexplained.is_empty() {
        Verdict::MissingPhysics
    } else if base.wald.value > base.wald.threshold || lag.is_some() {
        Verdict::ParametersOnly
    } else {
        Verdict::Consistent
    };
    let n_eff = search.noise.n_eff();
    let rms = ResidualRms { nominal: rms(&search.y), before: rms(&base.r), after: rms(&search.r) };
    let bic = bic(&search, &base, n_eff);
    let series = series(&prep, &search, &base, fit.contributions);
    let mut findings = std::mem::take(&mut search.findings);
    findings.extend(rejections.into_iter().take(5));
    Ok(Diagnosis {
        verdict,
        parameter_updates: fit.parameter_updates,
        parameters_wald: base.wald,
        findings,
        unexplained,
        location,
        noise_before: base.noise_spec,
        noise_after: search.noise.spec(),
        n_eff,
        n_bins: prep.bins.len(),
        rms,
        adev_before: bin_adev(&prep.bins, &base.r),
        adev_after: bin_adev(&prep.bins, &search.r),
        bic,
        model: fit.model,
        effects: fit.effects,
        series,
        collinearity,
    })
}

/// The Bayesian information criterion before and after the effects, under the noise model.
fn bic(search: &Search<'_>, base: &BaseFit, n_eff: f64) -> Bic {
    let sig2 = search.noise.mean_bin_variance();
    let before =
        base.r.iter().map(|x| x * x).sum::<f64>() / sig2 + base.proj.kept.len() as f64 * n_eff.ln();
    let q_total: usize = search
        .accepted
        .iter()
        // One nonlinear parameter per effect searched over a grid (the search's `q`).
        .map(|a| usize::from(grid(search.ctx.prep, a.id).len() > 1))
        .sum();
    let after = search.r.iter().map(|x| x * x).sum::<f64>() / sig2
        + (search.proj.kept.len() + q_total) as f64 * n_eff.ln();
    Bic { before, after }
}

/// The residuals and the signals they are read against, per bin.
fn series(
    prep: &Prepared,
    search: &Search<'_>,
    base: &BaseFit,
    contributions: Vec<(EffectId, Vec<f64>)>,
) -> Series {
    let dt = &prep.native.dt;
    Series {
        time_s: prep.bins.iter().map(Bin::centre_s).collect(),
        residual_nominal: search.y.clone(),
        residual_before: base.r.clone(),
        residual_after: search.r.clone(),
        temp_c: bin_mean(&prep.bins, dt, |k| prep.temp[k]),
        temp_rate_c_s: bin_mean(&prep.bins, dt, |k| prep.temp_rate[k]),
        table_rate_rad_s: prep.bins.iter().map(|b| b.table_rate_rad_s).collect(),
        angle_rad: bin_mean(&prep.bins, dt, |k| prep.native.angle_mid_rad[k]),
        contributions,
    }
}

/// Identifiability of every effect against the final model's terms ([`identify`]).
fn identifiability(search: &Search<'_>) -> Vec<Collinearity> {
    let (prep, model, opts) = (search.ctx.prep, search.ctx.model, search.ctx.opts);
    let (y, noise) = (&search.y, &search.noise);
    let mut terms: Vec<identify::Term> = ModelKey::CALIBRATED
        .iter()
        .enumerate()
        .map(|(j, k)| identify::Term { name: k.key().to_string(), cols: vec![j] })
        .collect();
    let mut at = search.base_design.len();
    for a in &search.accepted {
        terms.push(identify::Term {
            name: a.id.key().to_string(),
            cols: (at..at + a.cols.len()).collect(),
        });
        at += a.cols.len();
    }
    let effect_cols: Vec<(EffectId, bool, f64, Vec<Vec<f64>>)> = search
        .tested
        .iter()
        .filter(|&&id| !is_earth(id))
        .filter_map(|&id| {
            if let Some(a) = search.accepted.iter().find(|a| a.id == id) {
                return Some((id, true, a.p, a.cols.clone()));
            }
            if let Some(&(_, p)) = opts.identify_at.iter().find(|x| x.0 == id) {
                return Some((id, false, p, candidate_columns(prep, id, p, model)));
            }
            let cache = &search.column_cache;
            let (p, cols) = match refit_grid(prep, id, &search.proj, y, noise, model, cache) {
                Some(f) => (f.p, f.cols),
                None if grid(prep, id).len() == 1 => {
                    (f64::NAN, candidate_columns(prep, id, f64::NAN, model))
                }
                None => return None,
            };
            Some((id, false, p, cols))
        })
        .collect();
    identify::collinear_pairs(&search.design, &terms, &effect_cols, y, noise, &opts.identify_with)
}
