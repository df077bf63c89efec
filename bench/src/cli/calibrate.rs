//! `bench calibrate RECORDING`: the gyro's thermal calibration from a recording.

use std::path::PathBuf;
use std::process::ExitCode;

use super::exit::Exit;

use super::say::say;
use anyhow::Context as _;
use bench_analysis::joint_fit::Estimator;
use bench_physics::ModelKey;
use bench_recording::model_file::{
    CalibrationFile, CovarianceSection, HeldEntry, ModelKeys, Source, Uncertainty, HOLDABLE_KEYS,
};
use bench_report::calibrate::{
    calibrate_run, held, json, report, CalibrateSettings, CalibrationOutcome, Prior,
};
use bench_report::display::{self, coefficient_unit};

/// Arguments of `bench calibrate`.
#[derive(clap::Args, Debug)]
pub struct CalibrateArgs {
    /// Recording (MCAP, per the recording contract).
    pub recording: PathBuf,
    /// Directory for `calibration.toml`, `report.html` and the PNG figures.
    #[arg(long, short, default_value = "calibration")]
    pub out: PathBuf,
    /// Also write the machine-readable result here (docs/calibrate.md).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Reference temperature T0 of the coefficients, °C (default: the recording model's, else 20).
    #[arg(long)]
    pub reference_temperature_c: Option<f64>,
    /// Block-bootstrap replicates (default 400).
    #[arg(long)]
    pub replicates: Option<usize>,
    /// Do not estimate the thermal lag (only done for a gyro without its own sensor).
    #[arg(long)]
    pub no_lag: bool,
    /// Skip the HTML/PNG report.
    #[arg(long)]
    pub no_report: bool,
    /// No progress bar and no timing line.
    #[arg(long, short)]
    pub quiet: bool,
    /// Write `calibration.toml` even when the fit is poor (it then says so in its method).
    #[arg(long)]
    pub keep_poor_fit: bool,
    /// What a coefficient is expected to be before the data, `KEY=VALUE±SIGMA` (or `+-`; SI
    /// units, keys bias, scale_factor_error, temp_coeff, temp_rate_coeff): the size the run must
    /// resolve, and the value held when the run does not determine it (else the recording's
    /// nominal model). Repeatable.
    #[arg(long = "prior", value_name = "KEY=VALUE±SIGMA")]
    pub priors: Vec<Prior>,
    /// Apply the calibration to this second recording of the same gyro and report it there
    /// too, as `bench verify` does (in the report, the JSON and the exit code).
    #[arg(long, value_name = "RECORDING")]
    pub verify: Option<PathBuf>,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Calibrate and write the outputs.
pub fn run(args: CalibrateArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    let settings = CalibrateSettings {
        reference_temperature_c: args.reference_temperature_c,
        replicates: args.replicates,
        no_lag: args.no_lag,
        priors: args.priors.clone(),
    };
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.dir(&args.out)?;
    outputs.file(args.json.as_deref())?;
    let started = std::time::Instant::now();
    // Read as a stream, the gyro's samples reduced to the thermal model's rate as they pass;
    // then the arrays, with only the notes on the file kept.
    let streamed = super::read_recording_stream(&args.recording, args.quiet)?;
    let context = super::analysis_context(&streamed.rec, "calibrate", &args.recording);
    let notes: Vec<String> =
        streamed.rec.cut_note().into_iter().chain(streamed.rec.damage_note()).collect();
    let run = bench_report::load::load_streamed(streamed)
        .map_err(bench_report::calibrate::CalibrateError::from)
        .with_context(|| context.clone())?;
    super::note_reduction(&run, args.quiet);
    let working = bench::progress::Working::new(
        &format!("calibrating {}", args.recording.display()),
        !args.quiet && bench::progress::stderr_is_styled(),
    );
    let mut out = calibrate_run(run, &settings).with_context(|| context.clone())?;
    drop(working);
    let name = args
        .recording
        .file_name()
        .map_or_else(|| args.recording.display().to_string(), |n| n.to_string_lossy().into_owned());
    let cal = &out.calibration;
    for m in &cal.missing {
        eprintln!("note: {m}");
    }
    outputs.prepare()?;

    say!(
        "{name}: {} record windows, T0 = {} °C",
        cal.windows.len(),
        cal.options.joint.reference_temperature_c
    );
    if let Ok(a) = &cal.allan {
        say!(
            "noise: N = {} °/√h, B = {} °/h (floor {} °/h), K {} {} °/h/√h",
            display::sig(a.fit.arw_deg_per_sqrt_h().value, 3),
            display::sig(a.fit.bias_instability_deg_per_h().value, 3),
            display::sig(display::RATE.of(a.fit.flicker_floor().value), 3),
            if a.fit.rate_random_walk.upper_bound { "≤" } else { "=" },
            display::sig(a.fit.rate_random_walk_deg_per_h_per_sqrt_h().value, 3),
        );
    }
    if let Ok(j) = &cal.joint {
        say!(
            "joint fit: {}{}",
            j.estimator.as_str().to_uppercase(),
            if j.whitened_residual_rms.is_finite() {
                format!(" (whitened residual RMS {:.3})", j.whitened_residual_rms)
            } else {
                String::new()
            }
        );
    }
    if let Some(Ok(a)) = &cal.angle {
        say!(
            "angle-domain fit: GLS on {} angle misclosures over {} stretches (whitened residual \
             RMS {:.3})",
            a.readings,
            a.stretches,
            a.whitened_residual_rms
        );
    }
    let poor = out.quality.poor();
    if poor {
        eprintln!(
            "FIT POOR: the model does not fit these data, so the coefficients below and their σ \
             are not sound:"
        );
        for l in out.quality.lines() {
            eprintln!("  - {l}");
        }
        eprintln!(
            "  `bench diagnose {}` looks for the physics the model leaves out.",
            args.recording.display()
        );
    } else if out.quality.checks.is_empty() || !out.quality.block_threshold.is_finite() {
        say!("fit: not checked (the joint fit gave nothing to check)");
    } else {
        say!(
            "fit: {} ({} checks passed; no residual block beyond {:.2}σ)",
            if cal.incomplete() { "the coefficients estimated fit" } else { "sound" },
            out.quality.checks.len(),
            out.quality.block_threshold
        );
    }
    for l in held::lines(cal) {
        eprintln!("{l}");
    }
    if cal.incomplete() && !poor {
        eprintln!(
            "calibration INCOMPLETE: {} held at the value above, not estimated; \
             calibration.toml says so in [held]",
            held::held(cal).iter().map(|(k, _)| k.key()).collect::<Vec<_>>().join(", ")
        );
    }
    let model_label = if out.truth.is_some() { "simulator's truth" } else { "recording's model" };
    if poor {
        say!("(poor fit: values for inspection only)");
    }
    say!("| coefficient | rate domain ± 1σ | angle domain ± 1σ | seed method | {model_label} |");
    say!("| --- | --- | --- | --- | --- |");
    let seed = cal.seed.as_ref().ok();
    let joint = cal.joint.as_ref().ok();
    let angle = cal.angle.as_ref().and_then(|a| a.as_ref().ok());
    let recorded = out.data.run.model.as_ref().map(|m| &m.model);
    for (j, key) in ModelKey::CALIBRATED.into_iter().enumerate() {
        let Some(unit) = coefficient_unit(key) else { continue };
        let pm = |v: Option<(f64, f64)>| {
            v.map_or("—".to_owned(), |(v, s)| display::si_value_sigma(unit, v, s))
        };
        // A value with no σ to the decimals of the rate-domain σ, for comparison.
        let sigma_si = joint.and_then(|f| f.estimate(key)).map_or(f64::NAN, |e| e.std_err);
        let one = |v: Option<f64>| {
            v.map_or("—".to_owned(), |v| {
                display::value_like(unit.of(v), unit.of(sigma_si), unit.name)
            })
        };
        let est = joint.and_then(|f| f.estimate(key));
        let (rate, ang) = match est.filter(|e| e.held) {
            Some(e) => (
                format!("HELD at {} — not estimated", display::si_value(unit, e.value, 4)),
                "held".into(),
            ),
            None => (
                pm(est.map(|e| (e.value, e.std_err))),
                pm(angle.map(|a| a.estimates()[j]).map(|e| (e.value, e.std_err))),
            ),
        };
        say!(
            "| {} | {rate} | {ang} | {} | {} |",
            key.key(),
            one(seed.and_then(|s| s.coefficient(key))),
            one(recorded.map(|m| m.get(key))),
        );
    }
    if let Some(t) = &out.truth {
        if let (Some(j), Some(s)) = (t.joint_removal, t.seed_removal) {
            say!(
                "thermal error removed over the run: joint {:.1} %, seed method {:.1} %",
                100.0 * j.removed(),
                100.0 * s.removed()
            );
        }
    }

    if let Some(c) = &out.compensation {
        for l in bench_report::verify::summary_lines(c) {
            say!("this run: {l}");
        }
    }
    if let Some(path) = &args.verify {
        if let Some(model_file) =
            out.model.as_ref().map(|m| calibration_file(&out, m, &name, false))
        {
            let vrec = super::load_recording(path, args.quiet)?;
            let v = bench_report::verify::verify_recording(&vrec, &model_file)
                .with_context(|| format!("cannot verify on {}", path.display()))?;
            say!("verification on {}: {}", path.display(), v.verdict.text());
            for l in bench_report::verify::summary_lines(&v.compensation) {
                say!("verification: {l}");
            }
            let vname = path
                .file_name()
                .map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
            out.verification = Some((vname, Box::new(v)));
        }
    }

    let acceptance = bench_report::acceptance::judge_calibration(&out);
    if let Some(a) = &acceptance {
        print_acceptance(a);
    }
    let failed =
        acceptance.as_ref().is_some_and(|a| a.result == bench_report::acceptance::Judgement::Fail);

    if let Some(model) = out.model.as_ref().filter(|_| !poor || args.keep_poor_fit) {
        let file = calibration_file(&out, model, &name, poor);
        let path = args.out.join("calibration.toml");
        file.save(&path)?;
        say!("wrote {}", path.display());
    } else if out.model.is_some() {
        eprintln!(
            "no calibration file: the fit is poor (see above); --keep-poor-fit writes it anyway"
        );
    } else {
        eprintln!("no calibration file: the joint fit failed (see the notes above)");
        for note in &notes {
            eprintln!("  {note}: `bench recover` keeps the intact part in a new indexed file");
        }
    }
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&json::to_json(&out, &name))?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        say!("wrote {}", path.display());
    }
    if !args.no_report {
        let files = report::write_report(&out, &name, &args.out)?;
        say!("wrote {} and {} PNG figures", files.html.display(), files.pngs.len());
    }
    if !args.quiet {
        eprintln!("done in {:.2} s", started.elapsed().as_secs_f64());
    }
    let exit = match (&out.model, poor) {
        (None, _) => Exit::Incomplete,
        (Some(_), true) => Exit::FitPoor,
        (Some(_), false) if failed => Exit::AcceptanceFailed,
        (Some(_), false) if cal.incomplete() => Exit::Incomplete,
        (Some(_), false) => {
            out.verification.as_ref().map_or(Exit::Success, |(_, v)| super::verify::exit_of(v))
        }
    };
    Ok(exit.into())
}

/// The calibration file of `out`: the model, the 1σ of what was estimated, `[held]` for what
/// the run does not determine (never among the measured values) and the covariance of what was
/// estimated.
fn calibration_file(
    out: &CalibrationOutcome,
    model: &bench_physics::GyroModel,
    recording: &str,
    poor: bool,
) -> CalibrationFile {
    let cal = &out.calibration;
    let j = cal.joint.as_ref().ok();
    let sigma = |k: ModelKey| j.and_then(|j| j.estimate(k)).filter(|e| !e.held).map(|e| e.std_err);
    let mut file = CalibrationFile::new(
        model,
        &Default::default(),
        Source {
            recording: recording.to_owned(),
            software: format!("bench {}", env!("CARGO_PKG_VERSION")),
            method: match j.map(|j| j.estimator) {
                Some(Estimator::Gls) => {
                    "joint generalised least squares under the Allan noise model \
                     (docs/calibrate.md)"
                }
                _ => "joint least squares (docs/calibrate.md)",
            }
            .to_owned()
                + if poor { "; FIT POOR: kept on request, not sound" } else { "" }
                + if cal.incomplete() { "; INCOMPLETE: see [held]" } else { "" },
        },
        Uncertainty {
            bias_rad_s: sigma(ModelKey::Bias),
            scale_factor_error: sigma(ModelKey::ScaleFactorError),
            temp_coeff_rad_s_per_c: sigma(ModelKey::TempCoeff),
            temp_rate_coeff_rad_s_per_c_s: sigma(ModelKey::TempRateCoeff),
        },
    );
    file.gyro_model = ModelKeys::from(model);
    for (k, h) in held::held(cal) {
        let Some((_, name)) = HOLDABLE_KEYS.iter().find(|(hk, _)| *hk == k) else { continue };
        let hj = held::held_json(h);
        file.held.insert(
            (*name).to_owned(),
            HeldEntry {
                value: h.value,
                sigma: hj.sigma,
                source: hj.source.to_owned(),
                reason: hj.reason,
                determination: hj.determination,
            },
        );
    }
    let est: Vec<usize> = (0..4).filter(|&i| cal.held[i].is_none()).collect();
    file.covariance = j
        .map(|j| CovarianceSection {
            keys: est.iter().map(|&i| HOLDABLE_KEYS[i].1.to_owned()).collect(),
            matrix: est
                .iter()
                .map(|&a| est.iter().map(|&b| j.covariance[a][b]).collect())
                .collect(),
        })
        .filter(|c| c.matrix.iter().flatten().all(|v| v.is_finite()));
    file
}

/// The pass/fail lines: the unit, each limit, the result.
fn print_acceptance(a: &bench_report::acceptance::Acceptance) {
    let who: Vec<String> = ["unit_serial", "operator", "station"]
        .iter()
        .filter_map(|k| a.station.get(*k).map(|v| format!("{} {v}", k.replace('_', " "))))
        .collect();
    if !who.is_empty() {
        say!("{}", who.join(", "));
    }
    for p in &a.problems {
        eprintln!("note: {p}");
    }
    for c in &a.checks {
        let u = bench_report::acceptance::limit_unit(&c.key);
        let shown = match (c.value, c.interval) {
            (Some(v), Some((lo, hi))) => {
                let v = match c.sigma {
                    Some(s) => display::si_value_sigma(u, v, s),
                    None => display::si_value(u, v, 4),
                };
                format!(
                    "{v} (|·| within {}..{} at ≈95 %)",
                    display::sig(u.of(lo), 4),
                    display::si_value(u, hi, 4)
                )
            }
            _ => "not estimated".to_string(),
        };
        say!(
            "acceptance {}: {shown} vs limit {}: {}",
            c.key,
            display::si_value(u, c.limit, 4),
            c.judgement.key()
        );
    }
    say!("acceptance: {}", a.result.key().to_uppercase());
}
