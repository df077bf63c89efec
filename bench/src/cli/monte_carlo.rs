//! `bench monte-carlo SCENARIO`: the calibration's accuracy over many simulated seeds.

use std::path::PathBuf;
use std::process::ExitCode;

use super::say::say;
use anyhow::Context as _;
use bench::study;
use bench_physics::ModelKey;
use bench_report::calibrate::CalibrateSettings;
use bench_report::display::coefficient_unit;

/// Arguments of `bench monte-carlo`.
#[derive(clap::Args, Debug)]
pub struct MonteCarloArgs {
    /// Scenario to simulate (its `[simulation.truth]` is the truth), e.g.
    /// `scenarios/thermal-full.toml` of the bench repository.
    pub scenario: PathBuf,
    /// Number of seeds.
    #[arg(long, default_value_t = 50)]
    pub seeds: u64,
    /// First seed.
    #[arg(long, default_value_t = 1)]
    pub first_seed: u64,
    /// Worker threads (default: available cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Write every seed's result and the summary as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Study `bench diagnose` instead of the calibration: false discoveries on runs whose
    /// truth is the nominal model, recovery of the scenario's concealed effects.
    #[arg(long)]
    pub diagnose: bool,
    /// Apply a lab's traits to every simulated recording before it is analysed (10 Hz table,
    /// 1 Hz chamber, 1″ angle, jittered host stamps with latency, lost and bad gyro frames,
    /// record windows from the reversal).
    #[arg(long)]
    pub lab: bool,
    /// With `--diagnose`: the nominal model (a model TOML file) to diagnose against instead of
    /// each recording's `bench.gyro_model`; coefficients other than the scenario's truth make a
    /// parameters-only study.
    #[arg(long, requires = "diagnose")]
    pub model: Option<PathBuf>,
    /// With `--diagnose`: write each seed's recording, as diagnosed (lab traits applied), to
    /// this directory as `seed-N.mcap`.
    #[arg(long, requires = "diagnose")]
    pub keep: Option<PathBuf>,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Display unit (name, SI value of one unit) of a coefficient named by its key.
fn unit(key: &str) -> (&'static str, f64) {
    ModelKey::from_key(key)
        .and_then(coefficient_unit)
        .map_or(("", 1.0), |u| (u.name, 1.0 / u.per_si))
}

/// The diagnosis study (`--diagnose`).
fn run_diagnose(args: &MonteCarloArgs, jobs: usize) -> anyhow::Result<ExitCode> {
    let started = std::time::Instant::now();
    let nominal = args.model.as_deref().map(super::model::load_nominal).transpose()?;
    let lab = args.lab.then(bench::study::lab::LabTraits::lab);
    let mut outputs = super::outputs::Outputs::new(args.force);
    if let Some(dir) = &args.keep {
        outputs.dir(dir)?;
    }
    outputs.prepare()?;
    let study = study::diagnose::run(
        &args.scenario,
        args.first_seed,
        args.seeds,
        jobs,
        &bench_analysis::diagnose::DiagnoseOptions::default(),
        nominal,
        lab.as_ref(),
        args.keep.as_deref(),
        |s| {
            eprintln!(
                "seed {:>4}: {} found [{}]{} in {:.2} s",
                s.seed,
                s.verdict.key(),
                s.found.iter().map(|e| e.key()).collect::<Vec<_>>().join(", "),
                if s.unexplained { ", unexplained structure" } else { "" },
                s.seconds
            )
        },
    )?;
    let truth: Vec<&str> = study.truth.ids().iter().map(|e| e.key()).collect();
    say!(
        "{} seeds of {}{} in {:.0} s; concealed truth: [{}]",
        study.seeds.len(),
        args.scenario.display(),
        if args.lab { " with a lab's traits" } else { "" },
        started.elapsed().as_secs_f64(),
        truth.join(", ")
    );
    say!("| figure | value |");
    say!("| --- | --- |");
    say!("| false-discovery rate | {:.1} % |", 100.0 * study.false_discovery_rate());
    say!(
        "| … false findings (an effect not in the truth) | {:.1} % |",
        100.0 * study.false_finding_rate()
    );
    say!("| … seeds with unexplained windows | {:.1} % |", 100.0 * study.unexplained_rate());
    say!("| exactly the truth's effects named | {:.1} % |", 100.0 * study.exact_rate());
    let [c, p, m] = study.verdict_rates();
    say!(
        "| verdicts: consistent / parameters_only / missing_physics | {:.0} / {:.0} / {:.0} % |",
        100.0 * c,
        100.0 * p,
        100.0 * m
    );
    if !truth.is_empty() {
        say!("| fitted parameters within 3σ | {:.1} % |", 100.0 * study.within_3_sigma());
    }
    say!("| median diagnosis time | {:.2} s |", study.median_seconds());
    Ok(ExitCode::SUCCESS)
}

/// Run the study and print the accuracy table.
pub fn run(args: MonteCarloArgs) -> anyhow::Result<ExitCode> {
    super::outputs::Outputs::new(args.force).file(args.json.as_deref())?;
    let jobs =
        args.jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if args.diagnose {
        return run_diagnose(&args, jobs);
    }
    let started = std::time::Instant::now();
    let lab = args.lab.then(bench::study::lab::LabTraits::lab);
    let mc = study::calibrate::run(
        &args.scenario,
        args.first_seed,
        args.seeds,
        jobs,
        &CalibrateSettings::default(),
        lab,
        |r| {
            eprintln!(
                "seed {:>4}: thermal error removed {:.1} % (seed method {:.1} %), lag {:.0} s, \
                 whitened RMS {:.3} (rate) {:.3} (angle), fit {}",
                r.seed,
                100.0 * r.joint_removed,
                100.0 * r.seed_removed,
                r.lag_s,
                r.whitened_rms.0,
                r.whitened_rms.1,
                if r.fit_failed.is_empty() {
                    "sound".to_owned()
                } else {
                    format!("POOR ({})", r.fit_failed.join(", "))
                }
            )
        },
    )?;
    say!(
        "{} seeds of {}{} in {:.0} s\n",
        mc.seeds.len(),
        args.scenario.display(),
        if mc.lab { " with a lab's traits" } else { "" },
        started.elapsed().as_secs_f64()
    );
    say!("| coefficient | estimator | RMS error | RMS σ | 95 % coverage | mean z |");
    say!("| --- | --- | --- | --- | --- | --- |");
    for c in &mc.coefficients {
        let (u, s) = unit(&c.key);
        for e in &c.estimators {
            if !e.rms_error.is_finite() {
                continue;
            }
            let pct =
                |x: f64| if x.is_finite() { format!("{:.0} %", 100.0 * x) } else { "—".into() };
            let num = |x: f64| {
                if x.is_finite() {
                    format!("{} {u}", bench_report::display::sig(x / s, 3)).trim_end().to_owned()
                } else {
                    "—".into()
                }
            };
            let z = if e.mean_z.is_finite() { format!("{:+.2}", e.mean_z) } else { "—".into() };
            say!(
                "| {} | {} | {} | {} | {} | {} |",
                c.key,
                e.estimator,
                num(e.rms_error),
                num(e.rms_sigma),
                pct(e.coverage_95),
                z
            );
        }
    }
    let (a, b, c) = mc.joint_removed;
    let (d, e, f) = mc.seed_removed;
    say!(
        "\nthermal error removed (min / median / max): rate-domain GLS {:.1} / {:.1} / {:.1} %, seed \
         method {:.1} / {:.1} / {:.1} %",
        100.0 * a, 100.0 * b, 100.0 * c, 100.0 * d, 100.0 * e, 100.0 * f
    );
    say!(
        "fits judged poor by bench calibrate: {} of {} (on a scenario without concealed physics, \
         its false alarms)",
        mc.fits_poor,
        mc.seeds.len()
    );
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&mc)?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
