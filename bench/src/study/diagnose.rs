//! The diagnosis over many simulated seeds: how often it claims physics that is not there
//! (false discoveries on runs whose truth is the nominal model, or differs from it only in
//! parameter values), and how often it names, and recovers, an effect that is there.
//!
//! The scenario's `[simulation.truth.effects]` are the concealed truth: the recording's
//! `bench.gyro_model` holds only the nominal model, and the diagnosis runs against that.

use std::path::Path;
use std::time::Instant;

use anyhow::Context as _;

use bench_analysis::diagnose::{DiagnoseOptions, Verdict};
use bench_physics::effects::{EffectId, Effects};
use bench_physics::GyroModel;

use crate::runner::simulate_in_memory;
use crate::simulate::{capabilities, sim_config};
use crate::study::calibrate::parallel_seeds;
use bench_recording::Recording;

/// One seed's diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct SeedDiagnosis {
    /// Seed.
    pub seed: u64,
    /// Verdict.
    pub verdict: Verdict,
    /// Effects accepted.
    pub found: Vec<EffectId>,
    /// Whether structure was reported as unexplained.
    pub unexplained: bool,
    /// Per truth effect: each fitted parameter's |error|/σ (NaN when not found).
    pub z: Vec<(EffectId, &'static str, f64)>,
    /// Residual RMS after the refit and after the effects, rad/s.
    pub rms: (f64, f64),
    /// Wall time of the diagnosis alone, s.
    pub seconds: f64,
}

/// The study's summary.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseStudy {
    /// The concealed truth.
    pub truth: Effects,
    /// Per seed.
    pub seeds: Vec<SeedDiagnosis>,
}

impl DiagnoseStudy {
    /// Seeds naming an effect that is not in the truth, or reporting unexplained structure
    /// when the truth has no effect: the false-discovery rate.
    pub fn false_discovery_rate(&self) -> f64 {
        let truth = self.truth.ids();
        let bad = self
            .seeds
            .iter()
            .filter(|s| {
                s.found.iter().any(|e| !truth.contains(e)) || (truth.is_empty() && s.unexplained)
            })
            .count();
        bad as f64 / self.seeds.len().max(1) as f64
    }

    /// Seeds naming an effect that is not in the truth (unexplained windows aside).
    pub fn false_finding_rate(&self) -> f64 {
        let truth = self.truth.ids();
        let bad = self.seeds.iter().filter(|s| s.found.iter().any(|e| !truth.contains(e))).count();
        bad as f64 / self.seeds.len().max(1) as f64
    }

    /// Seeds reporting unexplained structure, whatever they found.
    pub fn unexplained_rate(&self) -> f64 {
        let bad = self.seeds.iter().filter(|s| s.unexplained).count();
        bad as f64 / self.seeds.len().max(1) as f64
    }

    /// Seeds naming exactly the truth's effects.
    pub fn exact_rate(&self) -> f64 {
        let mut truth = self.truth.ids();
        truth.sort();
        let ok = self
            .seeds
            .iter()
            .filter(|s| {
                let mut f = s.found.clone();
                f.sort();
                f == truth
            })
            .count();
        ok as f64 / self.seeds.len().max(1) as f64
    }

    /// Fraction of seeds with each verdict: consistent, parameters only, missing physics.
    pub fn verdict_rates(&self) -> [f64; 3] {
        let n = self.seeds.len().max(1) as f64;
        let rate = |v: Verdict| self.seeds.iter().filter(|s| s.verdict == v).count() as f64 / n;
        [rate(Verdict::Consistent), rate(Verdict::ParametersOnly), rate(Verdict::MissingPhysics)]
    }

    /// Fraction of fitted truth parameters within 3σ, over seeds that found their effect.
    pub fn within_3_sigma(&self) -> f64 {
        let z: Vec<f64> = self
            .seeds
            .iter()
            .flat_map(|s| s.z.iter().map(|x| x.2))
            .filter(|z| z.is_finite())
            .collect();
        z.iter().filter(|z| **z <= 3.0).count() as f64 / z.len().max(1) as f64
    }

    /// Median wall time of one diagnosis, s.
    pub fn median_seconds(&self) -> f64 {
        let mut t: Vec<f64> = self.seeds.iter().map(|s| s.seconds).collect();
        t.sort_by(f64::total_cmp);
        t.get(t.len() / 2).copied().unwrap_or(f64::NAN)
    }
}

/// Simulate `scenario` with seeds `first..first + count` on `jobs` threads and diagnose each
/// recording in memory against `nominal`, or else its own `bench.gyro_model` (a nominal model
/// that differs from the scenario's truth only in parameter values makes a parameters-only
/// study). With `lab`, each recording first gets a lab's traits ([`super::lab`]). With `keep`,
/// each recording as analysed is written there as `seed-N.mcap`, for a failing seed to be
/// looked at with `bench diagnose`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    scenario: &Path,
    first: u64,
    count: u64,
    jobs: usize,
    opts: &DiagnoseOptions,
    nominal: Option<(GyroModel, Effects, String)>,
    lab: Option<&super::lab::LabTraits>,
    keep: Option<&Path>,
    on_seed: impl FnMut(&SeedDiagnosis) + Send,
) -> anyhow::Result<DiagnoseStudy> {
    let plan = crate::scenario::load(scenario, &capabilities())?;
    // What a diagnosis should find: every effect the simulated gyro's output shows (the
    // table's ripple included) that the nominal model does not already hold (a simulated run
    // records its table's ripple as nominal).
    let config = sim_config(&plan, first);
    let nominal_effects = match &nominal {
        Some((_, effects, _)) => *effects,
        None => crate::simulate::recorded_effects(&plan, &config),
    };
    let mut truth = config.seen_effects();
    for id in truth.ids() {
        if nominal_effects.param_values(id).is_some()
            && nominal_effects.param_values(id) == truth.param_values(id)
        {
            truth.clear(id);
        }
    }
    // A lab's traits stamp the gyro and the table with different latencies: the recording
    // then truly holds a time offset of the gyro against the table (δ > 0: gyro late), which a
    // diagnosis should name.
    if let Some(l) = lab {
        let delta_s = l.latency_s[0] - l.latency_s[1];
        if delta_s != 0.0 && !truth.has(EffectId::TimeOffset) {
            // One value, the offset's one parameter.
            let _ = truth.set(EffectId::TimeOffset, &[delta_s]);
        }
    }
    let seeds = parallel_seeds(
        first,
        count,
        jobs,
        |seed| {
            let (report, mut bytes) = simulate_in_memory(&plan, seed)?;
            anyhow::ensure!(report.completed(), "run {}", report.outcome);
            if let Some(traits) = lab {
                bytes = super::lab::apply_to_bytes(&Recording::from_bytes(&bytes)?, traits, seed)?;
            }
            if let Some(dir) = keep {
                let path = dir.join(format!("seed-{seed}.mcap"));
                std::fs::write(&path, &bytes)
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
            let rec = Recording::from_bytes(&bytes)?;
            let started = Instant::now();
            let out = bench_report::diagnose::diagnose_recording(&rec, nominal.clone(), opts)?;
            let seconds = started.elapsed().as_secs_f64();
            let d = &out.diagnosis;
            let mut z = Vec::new();
            for id in truth.ids() {
                let want = truth.param_values(id).unwrap_or_default();
                for (name, value) in id.param_names().into_iter().zip(want) {
                    let got = d
                        .findings
                        .iter()
                        .find(|f| f.accepted && f.effect == id)
                        .and_then(|f| f.parameters.iter().find(|p| p.name == name));
                    let zz = got.map_or(f64::NAN, |p| (p.value - value).abs() / p.sigma);
                    z.push((id, name, zz));
                }
            }
            Ok(SeedDiagnosis {
                seed,
                verdict: d.verdict,
                found: d.findings.iter().filter(|f| f.accepted).map(|f| f.effect).collect(),
                unexplained: !d.unexplained.is_empty(),
                z,
                rms: (d.rms.before, d.rms.after),
                seconds,
            })
        },
        on_seed,
    )?;
    Ok(DiagnoseStudy { truth, seeds })
}
