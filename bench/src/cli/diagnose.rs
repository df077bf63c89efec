//! `bench diagnose RECORDING`: where the recording departs from the simulation of the same
//! run, the physics that explains it, and the updated model.

use std::path::PathBuf;
use std::process::ExitCode;

use super::exit::Exit;

use super::say::say;
use anyhow::Context as _;
use bench_analysis::diagnose::{DiagnoseOptions, Verdict};
use bench_physics::ModelKey;
use bench_recording::model_file::{
    CalibrationFile, HeldEntry, ModelKeys, Source, Uncertainty, HOLDABLE_KEYS,
};
use bench_report::diagnose::{diagnose_run, json, report};
use bench_report::display;

/// Arguments of `bench diagnose`.
#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Recording (MCAP, per the recording contract).
    pub recording: PathBuf,
    /// Nominal model: a model TOML file, or a recording (MCAP) whose `bench.gyro_model` and
    /// effects are taken (e.g. the simulation of the run: `--model sim.mcap`); default: the
    /// recording's own `bench.gyro_model`.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Directory for `model.toml` (the updated model), `report.html` and the PNG figures.
    #[arg(long, short, default_value = "diagnosis")]
    pub out: PathBuf,
    /// Also write the machine-readable result here (docs/diagnose.md).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Bin length, s.
    #[arg(long, default_value_t = 10.0)]
    pub bin_s: f64,
    /// Family-wise probability of a false finding over every effect and grid point tried.
    #[arg(long, default_value_t = 0.01)]
    pub alpha: f64,
    /// Skip the HTML/PNG report.
    #[arg(long)]
    pub no_report: bool,
    /// Write a scenario that would separate the terms this recording cannot tell apart
    /// (validated against the simulated bench), with the predicted separation: the run is
    /// simulated under the diagnosed model and diagnosed (docs/diagnose.md).
    #[arg(long, value_name = "FILE")]
    pub suggest_scenario: Option<PathBuf>,
    /// With `--suggest-scenario`: the bench's limits the suggestion keeps within (a bench
    /// config; default: the simulated bench's).
    #[arg(long, value_name = "BENCH.toml", requires = "suggest_scenario")]
    pub bench: Option<PathBuf>,
    /// No progress bar and no timing line.
    #[arg(long, short)]
    pub quiet: bool,
    /// Only the residual scan (docs/diagnose.md, Speed): every candidate's regressors over its
    /// grid tested against the refitted nominal design, each one's best grid value and Wald
    /// statistic printed with the time to read, prepare and scan (`--json`: the same as JSON);
    /// no search, model or report.
    #[arg(long, conflicts_with_all = ["suggest_scenario"])]
    pub scan_only: bool,
    /// With `--scan-only`: write the scan's inputs to this directory (`.npy` arrays and
    /// `scan.json`) for `scripts/diagnose_numpy.py`.
    #[arg(long, value_name = "DIR", requires = "scan_only")]
    pub scan_inputs: Option<PathBuf>,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// The family check and rate dependence of each finding, the effects not named for their
/// family's sake, and the verdict's identifiability caveats.
fn print_checks(d: &bench_analysis::diagnose::Diagnosis) {
    for f in &d.findings {
        let Some(c) = &f.family else { continue };
        let strongest = c.strongest.as_ref().map_or(String::new(), |m| {
            format!("; strongest: {} (Wald {:.1}, threshold {:.1})", m.name, m.wald, m.threshold)
        });
        say!(
            "  {} family check ({}, {} members): {}{strongest}; size moves {:.1}σ (limit {:.2}) \
             when it is freed",
            f.effect.key(),
            c.family,
            c.members,
            if c.passed { "passed" } else { "FAILED — not named" },
            c.size_change_z,
            c.size_change_limit
        );
        if let Some(r) = &f.rate_dependence {
            say!(
                "  {} at {} cycles/rev belongs to the {}: rate-independent Wald {:.1}, \
                 ∝ table rate Wald {:.1} (threshold {:.1}, each with the other in)",
                f.effect.key(),
                r.cycles_per_rev,
                match r.verdict() {
                    "gyro" => "gyro",
                    "table" => "table's rate ripple",
                    "both" => "gyro and the table's rate ripple both",
                    _ => "gyro or the table: this run cannot tell",
                },
                r.gyro_wald,
                r.ripple_wald,
                r.threshold
            );
        }
    }
    for c in d.identifiability().iter().filter(|c| c.effect_accepted) {
        say!(
            "  {} and {} are nearly collinear on this recording (ρ = {:.3}, σ ×{:.1})",
            c.effect.key(),
            c.with_name(),
            c.rho,
            c.sigma_inflation
        );
    }
    for c in bench_report::diagnose::verdict_caveats(d) {
        say!("caveat: {c}");
    }
}

/// Rows of the located-mismatch table printed; the rest are counted on one line.
const LOCATED_ROWS: usize = 10;

/// Where the refit residual sits, step by step: the windows by |z|, largest first, at most
/// [`LOCATED_ROWS`] of them, each with its time from the recording's time zero, temperature,
/// mean residual ± 1σ and, when effects were found, how much of it they account for.
fn print_located(o: &bench_report::diagnose::DiagnoseOutcome) {
    let l = bench_report::diagnose::located::located(o);
    if l.windows.is_empty() {
        return;
    }
    let departing = l.windows.iter().filter(|w| l.departs(w)).count();
    say!(
        "located: the residual after the parameter refit by step; {departing} of {} depart from \
         the noise model (|z| > {:.2}, α {} over the steps, marked *)",
        l.windows.len(),
        l.z_threshold,
        l.alpha
    );
    // The effects found, summed over each window: one effect is named in the header, several
    // by the largest in each row.
    let found: Vec<&str> =
        o.diagnosis.series.contributions.iter().map(|(id, _)| id.key()).collect();
    let effects = match found.as_slice() {
        [] => String::new(),
        [one] => format!(" {one} there |"),
        _ => " effects found there |".into(),
    };
    say!("| step | time | temperature | residual ± 1σ | z |{effects}");
    say!("| --- | --- | --- | --- | --- |{}", if found.is_empty() { "" } else { " --- |" });
    let by_z = l.by_z();
    for w in by_z.iter().take(LOCATED_ROWS) {
        let explained = match w.explained {
            Some((v, name)) => {
                let v = display::si_value(display::RATE, v, 2);
                if found.len() > 1 {
                    format!(" {v} (largest {name}) |")
                } else {
                    format!(" {v} |")
                }
            }
            None => String::new(),
        };
        say!(
            "| {} | {}–{} | {} | {} | {:.1}{} |{explained}",
            w.name,
            display::hms(w.start_s),
            display::hms(w.end_s),
            w.temp_c.text(),
            display::si_value_sigma(display::RATE, w.mean, w.sigma),
            w.z(),
            if l.departs(w) { " *" } else { "" },
        );
    }
    if let Some(next) = by_z.get(LOCATED_ROWS) {
        say!(
            "… {} more (|z| ≤ {:.1}: `--json` lists every step under location.steps)",
            by_z.len() - LOCATED_ROWS,
            next.z().abs()
        );
    }
}

/// `--suggest-scenario`: write the separating scenario and print the predicted separation —
/// only when it lowers σ and ρ of every pair it is meant to separate.
fn suggest_scenario(
    out: &bench_report::diagnose::DiagnoseOutcome,
    name: &str,
    path: &std::path::Path,
    bench: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    let d = &out.diagnosis;
    let temps = &d.series.temp_c;
    let lo = temps.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = temps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let latitude_deg = match out.data.series.latitude_deg {
        Some(latitude_deg) => latitude_deg,
        None => {
            say!("the recording has no site: the suggestion assumes latitude 45°");
            45.0
        }
    };
    let time = &d.series.time_s;
    let facts = bench::suggest::RecordingFacts {
        name: name.to_string(),
        latitude_deg,
        temp_range_c: (lo, hi),
        gyro_sensor: out.data.gyro_sensor(),
        duration_s: time.last().zip(time.first()).map_or(0.0, |(b, a)| b - a),
    };
    let caps = super::design::bench_capabilities(bench)?;
    use bench::suggest::Offer;
    let s = match bench::suggest::offer(d, &facts, &caps, 1)? {
        Offer::Nothing => {
            say!("no terms are confounded on this recording: no scenario suggested");
            return Ok(());
        }
        Offer::Lowers(s) | Offer::DoesNotLower(s) => s,
    };
    let offered = s.lowers_all();
    for w in &s.why {
        say!("{}: {w}", if offered { "suggested" } else { "tried" });
    }
    for t in &s.targets {
        let unit = display::for_si(t.before.unit);
        let sigma = |c: &bench_analysis::diagnose::Collinearity| {
            format!("σ {} (ρ = {:.3})", display::si_value(unit, c.sigma, 2), c.rho)
        };
        let by = match &t.after {
            Some(a) if t.lowered() => format!(": σ × {:.2}", a.sigma / t.before.sigma),
            Some(_) => " (not separated by it)".into(),
            None => String::new(),
        };
        say!(
            "  {} vs {}: {} on this recording ({}) → {} on the suggested run ({}){by}",
            t.before.effect.key(),
            t.before.with_name(),
            sigma(&t.before),
            bench::suggest::hm(facts.duration_s),
            t.after.as_ref().map_or("not testable".into(), sigma),
            bench::suggest::hm(s.duration_s),
        );
    }
    if !offered {
        say!(
            "no scenario suggested: the best run tried ({} of chamber time, up to {}× this \
             recording's) does not lower σ and ρ of every pair above",
            bench::suggest::hm(s.duration_s),
            bench::suggest::BUDGETS[bench::suggest::BUDGETS.len() - 1]
        );
        return Ok(());
    }
    if !s.shorter_tried_s.is_empty() {
        let tried: Vec<String> = s.shorter_tried_s.iter().map(|&t| bench::suggest::hm(t)).collect();
        say!("  (shorter runs tried first did not lower every pair: {})", tried.join(", "));
    }
    std::fs::write(path, &s.text).with_context(|| format!("cannot write {}", path.display()))?;
    say!(
        "wrote {} ({} of chamber time; `bench validate` passes{}; run it with `bench run`)",
        path.display(),
        bench::suggest::hm(s.duration_s),
        if bench.is_some() { " against the bench given" } else { "" }
    );
    Ok(())
}

/// Diagnose and write the outputs. Exit code 0 for `consistent`, 6 for `parameters_only`,
/// 7 for `missing_physics` ([`Exit`]).
pub fn run(args: DiagnoseArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    if let Some(m) = &args.model {
        use super::kind::{expect, Kind};
        expect(m, &[Kind::Model, Kind::Recording])?;
    }
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.json.as_deref())?;
    match &args.scan_inputs {
        Some(dir) => outputs.dir(dir)?,
        None if !args.scan_only => outputs.dir(&args.out)?,
        None => {}
    }
    outputs.file(args.suggest_scenario.as_deref())?;
    let started = std::time::Instant::now();
    let nominal = args.model.as_deref().map(super::model::load_nominal).transpose()?;
    let opts = DiagnoseOptions {
        bin_s: args.bin_s,
        alpha: args.alpha,
        threads: threads_from_env(),
        ..Default::default()
    };
    if args.scan_only {
        // The scan's benchmark: every sample, as the scan's speed is quoted.
        let rec = super::load_recording(&args.recording, args.quiet)?;
        return scan_only(&args, nominal, &opts, &rec, started, outputs);
    }
    // Read as a stream, the gyro's samples reduced to the thermal model's rate as they pass.
    let streamed = super::read_recording_stream(&args.recording, args.quiet)?;
    let working = bench::progress::Working::new(
        &format!("diagnosing {}", args.recording.display()),
        !args.quiet && bench::progress::stderr_is_styled(),
    );
    let context = super::analysis_context(&streamed.rec, "diagnose", &args.recording);
    let data = bench_report::load::load_streamed(streamed)
        .map_err(bench_report::diagnose::DiagnoseError::from)
        .with_context(|| context.clone())?;
    super::note_reduction(&data, args.quiet);
    let out = diagnose_run(data, nominal, &opts).with_context(|| context.clone())?;
    drop(working);
    let name = args
        .recording
        .file_name()
        .map_or_else(|| args.recording.display().to_string(), |n| n.to_string_lossy().into_owned());
    let d = &out.diagnosis;
    say!("{name}: verdict {} (nominal model: {})", d.verdict.key(), out.nominal.2);
    let rms = |v: f64| display::si_value(display::RATE, v, 3);
    say!(
        "residual RMS of {} bins: nominal {}, parameters refitted {}, with effects {}",
        display::si_value(display::SECONDS, opts.bin_s, 3),
        rms(d.rms.nominal),
        rms(d.rms.before),
        rms(d.rms.after)
    );
    say!("| parameter | nominal | fitted ± 1σ | z |");
    say!("| --- | --- | --- | --- |");
    for u in &d.parameter_updates {
        let unit = display::model_key_unit(u.key);
        if u.held.is_some() {
            say!(
                "| {} | {} | held (σ would be {}) | — |",
                u.key.key(),
                display::value_like(unit.of(u.nominal), unit.of(u.sigma), unit.name),
                display::si_value(unit, u.sigma, 2)
            );
            continue;
        }
        say!(
            "| {} | {} | {} | {} |",
            u.key.key(),
            display::value_like(unit.of(u.nominal), unit.of(u.sigma), unit.name),
            display::si_value_sigma(unit, u.fitted, u.sigma),
            display::sig((u.fitted - u.nominal) / u.sigma, 2)
        );
    }
    for u in d.parameter_updates.iter().filter(|u| u.held.is_some()) {
        say!("held {}: {}", u.key.key(), u.held.as_deref().unwrap_or_default());
    }
    for f in d.findings.iter().filter(|f| f.accepted) {
        let params: Vec<String> = f
            .parameters
            .iter()
            .map(|p| {
                format!(
                    "{} = {}",
                    display::parameter_name(p.name),
                    display::si_value_sigma(display::for_si(p.unit), p.value, p.sigma)
                )
            })
            .collect();
        say!(
            "found {}: {} (ΔBIC {}, RMS {} → {}) — {}",
            f.effect.key(),
            params.join(", "),
            display::sig(f.delta_bic, 3),
            rms(f.rms_before),
            rms(f.rms_after),
            f.remark.as_deref().unwrap_or(f.effect.description())
        );
    }
    print_checks(d);
    print_located(&out);
    for u in &d.unexplained {
        let windows: Vec<String> = u
            .windows_s
            .iter()
            .map(|(a, b)| {
                format!("{}–{}", display::sig(*a, 5), display::si_value(display::SECONDS, *b, 5))
            })
            .collect();
        say!(
            "unexplained: {} window(s) ({}), RMS {}, correlates with {}",
            u.windows_s.len(),
            windows.join(", "),
            rms(u.rms),
            u.correlates_with
        );
    }
    if let Some(r) = &out.resimulated {
        say!(
            "re-simulated with the updated model: residual RMS {}, verdict {}",
            rms(r.rms.nominal),
            r.verdict.key()
        );
    }
    outputs.prepare()?;
    let sigma = |key: ModelKey| {
        d.parameter_updates
            .iter()
            .find(|u| u.key == key && u.held.is_none())
            .map(|u| u.sigma)
            .filter(|s| s.is_finite())
    };
    // A parameter the final model does not determine: its nominal value, under [held].
    let held = d
        .parameter_updates
        .iter()
        .filter_map(|u| {
            let reason = u.held.clone()?;
            let (_, name) = HOLDABLE_KEYS.iter().find(|(k, _)| *k == u.key)?;
            let entry = HeldEntry {
                value: u.nominal,
                sigma: None,
                source: "nominal".into(),
                reason,
                determination: "a run whose procedure separates it from the effects found \
                                (`bench diagnose --suggest-scenario`)"
                    .into(),
            };
            Some(((*name).to_owned(), entry))
        })
        .collect();
    let file = CalibrationFile {
        source: Source {
            recording: name.clone(),
            software: format!("bench {}", env!("CARGO_PKG_VERSION")),
            method: "diagnose: nominal model refitted, effects added (docs/diagnose.md)".into(),
        },
        gyro_model: ModelKeys::from(&d.model),
        uncertainty: Uncertainty {
            bias_rad_s: sigma(ModelKey::Bias),
            scale_factor_error: sigma(ModelKey::ScaleFactorError),
            temp_coeff_rad_s_per_c: sigma(ModelKey::TempCoeff),
            temp_rate_coeff_rad_s_per_c_s: sigma(ModelKey::TempRateCoeff),
        },
        // The gyro's effects: the table's motion and the clocks are the recording's bench's.
        effects: d.effects.travelling(),
        held,
        covariance: None,
    };
    let path = args.out.join("model.toml");
    file.save(&path)?;
    say!("wrote {}", path.display());
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&json::to_json(&out, &name))?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
        say!("wrote {}", path.display());
    }
    if let Some(path) = &args.suggest_scenario {
        suggest_scenario(&out, &name, path, args.bench.as_deref())?;
    }
    if !args.no_report {
        let files = report::write_report(&out, &name, &args.out)?;
        say!("wrote {} and {} PNG figures", files.html.display(), files.pngs.len());
    }
    if !args.quiet {
        eprintln!("done in {:.2} s", started.elapsed().as_secs_f64());
    }
    Ok(match d.verdict {
        Verdict::Consistent => Exit::Success.into(),
        Verdict::ParametersOnly => Exit::ParametersOnly.into(),
        Verdict::MissingPhysics => Exit::MissingPhysics.into(),
    })
}

/// The diagnosis's threads: `BENCH_DIAGNOSE_THREADS` (1: serial) or the machine's
/// parallelism, at most 8 ([`bench_analysis::diagnose::default_threads`]).
pub(crate) fn threads_from_env() -> usize {
    std::env::var("BENCH_DIAGNOSE_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&t| t >= 1)
        .unwrap_or_else(bench_analysis::diagnose::default_threads)
}

/// `--scan-only`: the residual scan alone, timed ([`bench_analysis::diagnose::residual_scan`]).
fn scan_only(
    args: &DiagnoseArgs,
    nominal: Option<(bench_physics::GyroModel, bench_physics::effects::Effects, String)>,
    opts: &DiagnoseOptions,
    rec: &bench_recording::Recording,
    started: std::time::Instant,
    mut outputs: super::outputs::Outputs,
) -> anyhow::Result<ExitCode> {
    let read_s = started.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let data = bench_report::load::load(rec)
        .with_context(|| super::analysis_context(rec, "load", &args.recording))?;
    let load_s = t.elapsed().as_secs_f64();
    let (model, effects, source) = match nominal {
        Some(n) => n,
        None => {
            let m = data.model.clone().context("the recording holds no bench.gyro_model")?;
            (m.model, m.effects, "bench.gyro_model".into())
        }
    };
    let cpu0 = bench::process::cpu_time_s();
    let scan = bench_analysis::diagnose::residual_scan(&data.series, &model, &effects, opts)
        .with_context(|| super::analysis_context(rec, "scan", &args.recording))?;
    let cpu_s = bench::process::cpu_time_s().zip(cpu0).map(|(b, a)| b - a);
    let best: Vec<serde_json::Value> = scan
        .best
        .iter()
        .map(|b| {
            serde_json::json!({
                "effect": b.effect.key(), "grid_values": b.grid_values,
                "value": if b.value.is_finite() { Some(b.value) } else { None },
                "wald": b.wald, "delta_rss": b.delta_rss,
            })
        })
        .collect();
    let threads = opts.threads;
    let out = serde_json::json!({
        "recording": args.recording.display().to_string(), "nominal_model": source,
        "samples": scan.samples, "bins": scan.bins, "threads": threads,
        "time_s": {"read": read_s, "load": load_s, "prepare": scan.prepare_s, "scan": scan.scan_s},
        "cpu_s_prepare_and_scan": cpu_s,
        "best": best,
    });
    if !args.quiet {
        say!(
            "residual scan of {}: {} samples, {} bins, {threads} thread(s)",
            args.recording.display(),
            scan.samples,
            scan.bins
        );
        say!("| effect | grid values | best value | Wald | ΔRSS (rad/s)² |");
        say!("| --- | --- | --- | --- | --- |");
        for b in &scan.best {
            say!(
                "| {} | {} | {} | {:.3} | {:.6e} |",
                b.effect.key(),
                b.grid_values,
                if b.value.is_finite() { display::sig(b.value, 6) } else { "—".into() },
                b.wald,
                b.delta_rss
            );
        }
        say!(
            "time: read {read_s:.3} s, load {load_s:.3} s, prepare {:.3} s, scan {:.3} s \
             (CPU of prepare and scan, every thread: {})",
            scan.prepare_s,
            scan.scan_s,
            cpu_s.map_or("unknown".into(), |c| format!("{c:.2} s"))
        );
    }
    outputs.prepare()?;
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&out)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(dir) = &args.scan_inputs {
        for (name, values) in &scan.inputs.arrays {
            let path = dir.join(format!("{name}.npy"));
            std::fs::write(&path, bench_report::npy::npy_f64(values))
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        let scalars: serde_json::Map<String, serde_json::Value> =
            scan.inputs.scalars.iter().map(|(k, v)| ((*k).to_string(), (*v).into())).collect();
        let grids: serde_json::Map<String, serde_json::Value> = scan
            .inputs
            .grids
            .iter()
            .map(|(id, g)| {
                let g: Vec<Option<f64>> = g.iter().map(|v| v.is_finite().then_some(*v)).collect();
                (id.key().to_string(), serde_json::json!(g))
            })
            .collect();
        let meta = serde_json::json!({"scalars": scalars, "grids": grids, "result": out});
        let path = dir.join("scan.json");
        std::fs::write(&path, serde_json::to_string_pretty(&meta)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(Exit::Success.into())
}
