//! The calibration's accuracy, proven on simulated recordings with known truth: one scenario
//! run with many seeds, each recording calibrated by the seed's method and by the joint fit,
//! and the errors against the simulator's true model summarised.
//!
//! Per coefficient: the RMS error over seeds of both methods and their ratio; the fraction of
//! seeds whose stated 95 % interval (±1.96σ) covers the truth; and the thermal error removed
//! over each run.

use std::io::Cursor;
use std::path::Path;
use std::sync::Mutex;

use anyhow::Context as _;
use bench_physics::ModelKey;
use serde::Serialize;

use bench_recording::Recording;
use bench_report::calibrate::{calibrate_recording, CalibrateSettings};

use crate::simulate::{capabilities, run_plan, SimOptions};

/// The coefficients compared.
pub const COEFFICIENTS: [ModelKey; 4] = ModelKey::CALIBRATED;

/// One seed's result.
#[derive(Debug, Clone, Serialize)]
pub struct SeedResult {
    /// Simulator seed.
    pub seed: u64,
    /// Joint fit: (value, σ) per coefficient, in [`COEFFICIENTS`] order.
    pub joint: Vec<(f64, f64)>,
    /// Joint fit's σ under the noise model per coefficient: for GLS the Cramér–Rao bound.
    pub joint_noise_model_sigma: Vec<f64>,
    /// Joint fit's block-bootstrap σ per coefficient (of the whitened residuals for GLS).
    pub joint_bootstrap_sigma: Vec<f64>,
    /// OLS value per coefficient on the same data, for comparison.
    pub ols: Vec<f64>,
    /// Seed method: value per coefficient (NaN for the scale factor, which it does not fit).
    pub seed_method: Vec<f64>,
    /// True values.
    pub truth: Vec<f64>,
    /// Thermal error removed by the joint calibration (fraction).
    pub joint_removed: f64,
    /// Thermal error removed by the seed calibration (fraction).
    pub seed_removed: f64,
    /// Thermal lag used by the joint fit, s.
    pub lag_s: f64,
}

/// Summary of one coefficient over the seeds.
#[derive(Debug, Clone, Serialize)]
pub struct CoefficientSummary {
    /// `bench.gyro_model` key.
    pub key: String,
    /// RMS of (joint − truth).
    pub joint_rms_error: f64,
    /// RMS of (seed − truth); NaN where the seed method does not estimate it.
    pub seed_rms_error: f64,
    /// seed RMS / joint RMS.
    pub improvement: f64,
    /// Fraction of seeds with |joint − truth| ≤ 1.96σ.
    pub coverage_95: f64,
    /// RMS of the stated σ.
    pub rms_sigma: f64,
    /// RMS of the noise-model σ (for GLS the Cramér–Rao bound under the fitted noise model).
    pub rms_noise_model_sigma: f64,
    /// RMS of (OLS − truth) on the same data.
    pub ols_rms_error: f64,
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct MonteCarlo {
    /// Scenario file.
    pub scenario: String,
    /// Per seed.
    pub seeds: Vec<SeedResult>,
    /// Per coefficient.
    pub coefficients: Vec<CoefficientSummary>,
    /// Thermal error removed by the joint calibration: (min, median, max) over seeds.
    pub joint_removed: (f64, f64, f64),
    /// Same for the seed method.
    pub seed_removed: (f64, f64, f64),
}

/// Run `scenario` with seeds `first_seed..first_seed + count` on `jobs` threads, calibrate
/// each recording in memory, and summarise.
pub fn run(
    scenario: &Path,
    first_seed: u64,
    count: u64,
    jobs: usize,
    settings: &CalibrateSettings,
    on_seed: impl FnMut(&SeedResult) + Send,
) -> anyhow::Result<MonteCarlo> {
    let plan = crate::scenario::load(scenario, &capabilities())?;
    let seeds =
        parallel_seeds(first_seed, count, jobs, |seed| one_seed(&plan, seed, settings), on_seed)?;
    Ok(summarise(scenario.display().to_string(), seeds))
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
) -> anyhow::Result<SeedResult> {
    let opts = SimOptions { seed, ..SimOptions::default() };
    let (report, cursor) = run_plan(plan, Cursor::new(Vec::new()), &opts, None)?;
    anyhow::ensure!(report.completed(), "run {}", report.outcome);
    let rec = Recording::from_bytes(cursor.get_ref())?;
    let out = calibrate_recording(&rec, settings)?;
    let truth = out.truth.as_ref().context("the recording has no bench.gyro_model")?;
    let joint = out.calibration.joint.as_ref().map_err(|e| anyhow::anyhow!("joint fit: {e}"))?;
    let seed_cal =
        out.calibration.seed.as_ref().map_err(|e| anyhow::anyhow!("seed method: {e}"))?;
    let est = [joint.bias, joint.scale_factor_error, joint.temp_coeff, joint.temp_rate_coeff];
    Ok(SeedResult {
        seed,
        joint: est.iter().map(|e| (e.value, e.std_err)).collect(),
        joint_noise_model_sigma: est.iter().map(|e| e.noise_model_std_err).collect(),
        joint_bootstrap_sigma: est.iter().map(|e| e.bootstrap_std_err).collect(),
        ols: est.iter().map(|e| e.ols_value).collect(),
        seed_method: vec![
            seed_cal.bias_rad_s,
            f64::NAN,
            seed_cal.temp_coeff,
            seed_cal.temp_rate_coeff.unwrap_or(f64::NAN),
        ],
        truth: COEFFICIENTS.iter().map(|k| truth.model.get(*k)).collect(),
        joint_removed: truth.joint_removal.map_or(f64::NAN, |r| r.removed()),
        seed_removed: truth.seed_removal.map_or(f64::NAN, |r| r.removed()),
        lag_s: match &out.calibration.lag {
            Some(Ok(l)) => l.used_s,
            _ => 0.0,
        },
    })
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    (s / n as f64).sqrt()
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
pub fn summarise(scenario: String, seeds: Vec<SeedResult>) -> MonteCarlo {
    let coefficients = COEFFICIENTS
        .iter()
        .enumerate()
        .map(|(j, key)| {
            let joint_rms_error = rms(seeds.iter().map(|r| r.joint[j].0 - r.truth[j]));
            let seed_rms_error = rms(seeds.iter().map(|r| r.seed_method[j] - r.truth[j]));
            let covered = seeds
                .iter()
                .filter(|r| (r.joint[j].0 - r.truth[j]).abs() <= 1.959_964 * r.joint[j].1)
                .count();
            CoefficientSummary {
                key: key.key().to_owned(),
                joint_rms_error,
                seed_rms_error,
                improvement: seed_rms_error / joint_rms_error,
                coverage_95: covered as f64 / seeds.len() as f64,
                rms_sigma: rms(seeds.iter().map(|r| r.joint[j].1)),
                rms_noise_model_sigma: rms(seeds.iter().map(|r| r.joint_noise_model_sigma[j])),
                ols_rms_error: rms(seeds.iter().map(|r| r.ols[j] - r.truth[j])),
            }
        })
        .collect();
    MonteCarlo {
        scenario,
        joint_removed: spread(seeds.iter().map(|r| r.joint_removed).collect()),
        seed_removed: spread(seeds.iter().map(|r| r.seed_removed).collect()),
        coefficients,
        seeds,
    }
}
