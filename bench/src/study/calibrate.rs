//! The calibration's accuracy, proven on simulated recordings with known truth: one scenario
//! run with many seeds — as bench records it, or with a lab's traits applied ([`super::lab`]) —
//! each recording calibrated, and every estimator's errors against the simulator's true model
//! summarised: the seed's plateau method, OLS, the rate-domain GLS and the angle-domain GLS.
//!
//! Per estimator and coefficient: the RMS error over seeds, the RMS stated σ, the fraction of
//! seeds whose stated 95 % interval (±1.96σ) covers the truth and the mean z-score; and the
//! thermal error removed over each run.

use std::path::Path;
use std::sync::Mutex;

use anyhow::Context as _;
use bench_physics::ModelKey;
use serde::Serialize;

use bench_recording::Recording;
use bench_report::calibrate::{calibrate_recording, CalibrateSettings};

use super::lab::LabTraits;
use crate::runner::simulate_in_memory;
use crate::simulate::capabilities;

/// The coefficients compared.
pub const COEFFICIENTS: [ModelKey; 4] = ModelKey::CALIBRATED;

/// The estimators compared, in the order of [`SeedResult::estimates`].
pub const ESTIMATORS: [&str; 4] = ["seed_method", "ols", "rate_gls", "angle_gls"];

/// One seed's result.
#[derive(Debug, Clone, Serialize)]
pub struct SeedResult {
    /// Simulator seed.
    pub seed: u64,
    /// True values per coefficient, in [`COEFFICIENTS`] order.
    pub truth: Vec<f64>,
    /// Per estimator ([`ESTIMATORS`]), per coefficient: (value, stated σ); NaN where the
    /// estimator does not give it (the seed method's scale factor and σ; OLS's σ is its
    /// standard error under the noise model).
    pub estimates: Vec<Vec<(f64, f64)>>,
    /// Whitened residual RMS of the rate-domain and angle-domain fits.
    pub whitened_rms: (f64, f64),
    /// Thermal error removed by the rate-domain calibration (fraction).
    pub joint_removed: f64,
    /// Thermal error removed by the seed calibration (fraction).
    pub seed_removed: f64,
    /// Thermal lag used, s.
    pub lag_s: f64,
    /// The checks `bench calibrate` failed on this seed's fit (empty: judged sound).
    pub fit_failed: Vec<String>,
}

/// One estimator's accuracy on one coefficient over the seeds.
#[derive(Debug, Clone, Serialize)]
pub struct EstimatorSummary {
    /// Estimator ([`ESTIMATORS`]).
    pub estimator: String,
    /// RMS of (value − truth).
    pub rms_error: f64,
    /// RMS of the stated σ (NaN without one).
    pub rms_sigma: f64,
    /// Fraction of seeds with |value − truth| ≤ 1.96σ (NaN without σ).
    pub coverage_95: f64,
    /// Mean of (value − truth)/σ: a bias shows here.
    pub mean_z: f64,
}

/// Summary of one coefficient over the seeds.
#[derive(Debug, Clone, Serialize)]
pub struct CoefficientSummary {
    /// `bench.gyro_model` key.
    pub key: String,
    /// Per estimator, in [`ESTIMATORS`] order.
    pub estimators: Vec<EstimatorSummary>,
}

impl CoefficientSummary {
    /// The summary of estimator `name`.
    pub fn of(&self, name: &str) -> Option<&EstimatorSummary> {
        self.estimators.iter().find(|e| e.estimator == name)
    }
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct MonteCarlo {
    /// Scenario file.
    pub scenario: String,
    /// Whether a lab's traits were applied to each recording ([`super::lab::LabTraits::lab`]).
    pub lab: bool,
    /// Per seed.
    pub seeds: Vec<SeedResult>,
    /// Per coefficient.
    pub coefficients: Vec<CoefficientSummary>,
    /// Thermal error removed by the rate-domain calibration: (min, median, max) over seeds.
    pub joint_removed: (f64, f64, f64),
    /// Same for the seed method.
    pub seed_removed: (f64, f64, f64),
    /// Seeds whose fit `bench calibrate` judged poor.
    pub fits_poor: usize,
}

/// Run `scenario` with seeds `first_seed..first_seed + count` on `jobs` threads, calibrate
/// each recording in memory, and summarise.
/// With `lab`, each recording first gets a lab's traits ([`super::lab`]).
pub fn run(
    scenario: &Path,
    first_seed: u64,
    count: u64,
    jobs: usize,
    settings: &CalibrateSettings,
    lab: Option<LabTraits>,
    on_seed: impl FnMut(&SeedResult) + Send,
) -> anyhow::Result<MonteCarlo> {
    let plan = crate::scenario::load(scenario, &capabilities())?;
    let seeds = parallel_seeds(
        first_seed,
        count,
        jobs,
        |seed| one_seed(&plan, seed, settings, lab.as_ref()),
        on_seed,
    )?;
    Ok(summarise(scenario.display().to_string(), lab.is_some(), seeds))
}

/// Run `work` for seeds `first..first + count` on `jobs` threads, calling `on_done` as each
/// finishes; results in seed order. The first error stops the study and is returned.
pub fn parallel_seeds<R: Send>(
    first: u64,
    count: u64,
    jobs: usize,
    work: impl Fn(u64) -> anyhow::Result<R> + Sync,
    mut on_done: impl FnMut(&R) + Send,
) -> anyhow::Result<Vec<R>> {
    let next = Mutex::new(first);
    let results = Mutex::new(Vec::new());
    let report = Mutex::new(&mut on_done);
    let end = first + count;
    std::thread::scope(|s| -> anyhow::Result<()> {
        let handles: Vec<_> = (0..jobs.max(1))
            .map(|_| {
                s.spawn(|| -> anyhow::Result<()> {
                    loop {
                        let seed = {
                            let mut n = next.lock().map_err(|_| anyhow::anyhow!("poisoned"))?;
                            if *n >= end {
                                return Ok(());
                            }
                            *n += 1;
                            *n - 1
                        };
                        let r = work(seed).with_context(|| format!("seed {seed}"))?;
                        if let Ok(mut f) = report.lock() {
                            (*f)(&r);
                        }
                        results.lock().map_err(|_| anyhow::anyhow!("poisoned"))?.push((seed, r));
                    }
                })
            })
            .collect();
        for h in handles {
            h.join().map_err(|_| anyhow::anyhow!("a Monte Carlo worker panicked"))??;
        }
        Ok(())
    })?;
    let mut out = results.into_inner().map_err(|_| anyhow::anyhow!("poisoned"))?;
    out.sort_by_key(|(seed, _)| *seed);
    Ok(out.into_iter().map(|(_, r)| r).collect())
}

fn one_seed(
    plan: &crate::plan::RunPlan,
    seed: u64,
    settings: &CalibrateSettings,
    lab: Option<&LabTraits>,
) -> anyhow::Result<SeedResult> {
    let (report, bytes) = simulate_in_memory(plan, seed)?;
    anyhow::ensure!(report.completed(), "run {}", report.outcome);
    let mut rec = Recording::from_bytes(&bytes)?;
    if let Some(traits) = lab {
        rec = super::lab::apply(&rec, traits, seed)?;
    }
    let out = calibrate_recording(&rec, settings)?;
    let truth = out.truth.as_ref().context("the recording has no bench.gyro_model")?;
    let cal = &out.calibration;
    let joint = cal.joint.as_ref().map_err(|e| anyhow::anyhow!("joint fit: {e}"))?;
    let nan = (f64::NAN, f64::NAN);
    let seed_est: Vec<(f64, f64)> = COEFFICIENTS
        .iter()
        .map(|k| {
            cal.seed.as_ref().ok().and_then(|s| s.coefficient(*k)).map_or(nan, |v| (v, f64::NAN))
        })
        .collect();
    let by_key = |f: &dyn Fn(ModelKey) -> Option<(f64, f64)>| -> Vec<(f64, f64)> {
        COEFFICIENTS.iter().map(|k| f(*k).unwrap_or(nan)).collect()
    };
    let ols = by_key(&|k| {
        joint.estimate(k).filter(|e| !e.held).map(|e| (e.ols_value, e.ols_noise_model_std_err))
    });
    let rate = by_key(&|k| joint.estimate(k).filter(|e| !e.held).map(|e| (e.value, e.std_err)));
    let angle = cal.angle.as_ref().and_then(|a| a.as_ref().ok());
    let angle_est = by_key(&|k| {
        let j = COEFFICIENTS.iter().position(|c| *c == k)?;
        angle.map(|a| (a.estimates()[j].value, a.estimates()[j].std_err))
    });
    Ok(SeedResult {
        seed,
        truth: COEFFICIENTS.iter().map(|k| truth.model.get(*k)).collect(),
        estimates: vec![seed_est, ols, rate, angle_est],
        whitened_rms: (
            joint.whitened_residual_rms,
            angle.map_or(f64::NAN, |a| a.whitened_residual_rms),
        ),
        joint_removed: truth.joint_removal.map_or(f64::NAN, |r| r.removed()),
        seed_removed: truth.seed_removal.map_or(f64::NAN, |r| r.removed()),
        lag_s: match &cal.lag {
            Some(Ok(l)) => l.used_s,
            _ => 0.0,
        },
        fit_failed: out
            .quality
            .checks
            .iter()
            .filter(|c| !c.passed)
            .map(|c| c.key.to_owned())
            .collect(),
    })
}

fn spread(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    v.sort_by(f64::total_cmp);
    (v[0], v[v.len() / 2], v[v.len() - 1])
}

/// Summarise per-seed results.
pub fn summarise(scenario: String, lab: bool, seeds: Vec<SeedResult>) -> MonteCarlo {
    let coefficients = COEFFICIENTS
        .iter()
        .enumerate()
        .map(|(j, key)| CoefficientSummary {
            key: key.key().to_owned(),
            estimators: ESTIMATORS
                .iter()
                .enumerate()
                .map(|(e, name)| {
                    let pairs: Vec<(f64, f64, f64)> = seeds
                        .iter()
                        .map(|r| (r.estimates[e][j].0, r.estimates[e][j].1, r.truth[j]))
                        .filter(|(v, _, _)| v.is_finite())
                        .collect();
                    let with_sigma: Vec<f64> = pairs
                        .iter()
                        .filter(|(_, s, _)| s.is_finite() && *s > 0.0)
                        .map(|(v, s, t)| (v - t) / s)
                        .collect();
                    let n = with_sigma.len() as f64;
                    EstimatorSummary {
                        estimator: (*name).to_owned(),
                        rms_error: bench_analysis::stats::rms(pairs.iter().map(|(v, _, t)| v - t)),
                        rms_sigma: bench_analysis::stats::rms(
                            pairs.iter().map(|(_, s, _)| *s).filter(|s| s.is_finite()),
                        ),
                        coverage_95: with_sigma.iter().filter(|z| z.abs() <= 1.959_964).count()
                            as f64
                            / n,
                        mean_z: with_sigma.iter().sum::<f64>() / n,
                    }
                })
                .collect(),
        })
        .collect();
    MonteCarlo {
        scenario,
        lab,
        joint_removed: spread(seeds.iter().map(|r| r.joint_removed).collect()),
        seed_removed: spread(seeds.iter().map(|r| r.seed_removed).collect()),
        fits_poor: seeds.iter().filter(|r| !r.fit_failed.is_empty()).count(),
        coefficients,
        seeds,
    }
}
