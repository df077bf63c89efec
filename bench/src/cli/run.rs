//! `bench run SCENARIO`: run a scenario and record it.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use super::exit::Exit;
use std::sync::Arc;

use super::say::{asked, say};
use anyhow::Context as _;
use bench::bench_config::{BenchConfig, BenchSource, ReplayBenchConfig};
use bench::plan::RunPlan;
use bench::runner::{run_info, stop_on_signals, wall_epoch_ns, Bench, Pace, RunOptions, RunReport};
use bench::scenario::{Capabilities, LoadError};
use bench_drivers::{Clock, SystemClock};
use bench_recording::TomlAttachment;

/// Arguments of `bench run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Scenario file (TOML).
    pub scenario: PathBuf,
    /// Recording to write (default: the scenario's file name with `.mcap`, in the current
    /// directory; if that exists, the first free `NAME-2.mcap`, `NAME-3.mcap`, …). An existing
    /// file given here is refused unless `--force`.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Overwrite the `--out` file if it exists.
    #[arg(long)]
    pub force: bool,
    /// Serial number of the unit under test (`bench.station` `unit_serial`; overrides the
    /// scenario's `[station]`).
    #[arg(long)]
    pub unit_serial: Option<String>,
    /// Who runs the test (`bench.station` `operator`).
    #[arg(long)]
    pub operator: Option<String>,
    /// Which test station (`bench.station` `station`).
    #[arg(long)]
    pub station: Option<String>,
    /// Seed of the simulator's random streams; the same seed gives the same recording
    /// (simulated bench only).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Bench config (TOML): real drivers, simulators behind virtual ports, or a `[replay]` of
    /// a recording; a config without drivers is the embedded simulated bench at its site with
    /// its `[simulation]` settings; `replay:REC.mcap` replays a recording in virtual time.
    /// Without it the embedded simulated bench runs in virtual time.
    #[arg(long, short)]
    pub bench: Option<PathBuf>,
    /// Show the streams live in Foxglove (WebSocket server; open ws://127.0.0.1:8765).
    #[arg(long)]
    pub live: bool,
    /// Address of the live view's server (only loopback unless you say otherwise).
    #[arg(long, default_value = "127.0.0.1:8765", requires = "live")]
    pub live_addr: std::net::SocketAddr,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Also write the run's report as JSON here (`-` for stdout, then alone on it): the
    /// recording, its outcome (and the fault's name when it aborted), bench and wall time,
    /// gyro samples.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Gyro model from a calibration file (`bench calibrate`'s `calibration.toml`): the
    /// nominal model recorded in `bench.gyro_model` and, on the simulated bench, the model
    /// the simulated gyro follows (replacing `[gyro.model]` and `[simulation.truth]`).
    #[arg(long)]
    pub gyro_model: Option<PathBuf>,
    /// Kill-safety: the recording is flushed so that a SIGKILL or crash loses at most this
    /// many seconds of bench time in a paced run, of wall-clock work in a virtual-time run
    /// (`bench recover` restores the rest). Overrides the
    /// scenario's `[recording] flush_interval`; default 1 s.
    #[arg(long, value_name = "SECONDS")]
    pub flush_interval_s: Option<f64>,
    /// Run the embedded simulated bench in real time × this factor on tokio, as a real bench
    /// runs (signals abort to the safe state), instead of in virtual time.
    #[arg(long, value_name = "FACTOR")]
    pub time_scale: Option<f64>,
    /// Print `bench time T s (log time N ns)` on stderr each time the run passes a multiple
    /// of this many seconds of bench time (for logs and supervisors).
    #[arg(long, value_name = "SECONDS")]
    pub time_marks_s: Option<f64>,
}

impl RunArgs {
    /// `--flush-interval-s` and `--time-marks-s` as durations, checked.
    fn recording_options(&self) -> anyhow::Result<(Option<Duration>, Option<Duration>)> {
        let seconds = |name: &str, v: f64| -> anyhow::Result<Duration> {
            anyhow::ensure!(
                v.is_finite() && v > 0.0 && v <= 3600.0,
                "{name} must be a number of seconds in (0, 3600], got {v}"
            );
            Ok(Duration::from_secs_f64(v))
        };
        let flush = self.flush_interval_s.map(|v| seconds("--flush-interval-s", v)).transpose()?;
        let marks = self.time_marks_s.map(|v| seconds("--time-marks-s", v)).transpose()?;
        Ok((flush, marks))
    }
}

/// The kill-safety bound of a run: `--flush-interval-s` over the scenario's `[recording]
/// flush_interval`; `None`: the default ([`bench::runner::DEFAULT_FLUSH_INTERVAL`]).
fn flush_interval_of(cli: Option<Duration>, plan: &RunPlan) -> Option<Duration> {
    cli.or(plan.flush_interval)
}

/// Apply `--unit-serial`, `--operator`, `--station` over the scenario's `[station]`.
fn apply_station(plan: &mut RunPlan, args: &RunArgs) {
    for (key, v) in [
        ("unit_serial", &args.unit_serial),
        ("operator", &args.operator),
        ("station", &args.station),
    ] {
        if let Some(v) = v {
            plan.station.info.insert(key.to_string(), v.clone());
        }
    }
}

/// Apply `--gyro-model` to a loaded plan.
fn apply_gyro_model(plan: &mut RunPlan, path: Option<&Path>) -> anyhow::Result<()> {
    if let Some(path) = path {
        let file = bench_recording::model_file::CalibrationFile::load(path)?;
        let model = file.model();
        plan.gyro.model = model.clone();
        plan.gyro.model_given = true;
        plan.gyro.effects = file.effects;
        plan.sim.truth = model;
        plan.sim.truth_effects = file.effects;
    }
    Ok(())
}

/// Load and validate; print every problem. `None` when invalid (already reported).
fn load_plan(path: &Path, caps: &Capabilities) -> anyhow::Result<Option<RunPlan>> {
    match bench::scenario::load(path, caps) {
        Ok(p) => Ok(Some(p)),
        Err(LoadError::Invalid(errors)) => {
            for e in errors.iter() {
                eprintln!("{e}");
            }
            eprintln!("{}: {} error(s); nothing was run", path.display(), errors.len());
            Ok(None)
        }
        Err(e) => Err(e.into()),
    }
}

/// Run on the embedded simulated bench, or on the bench a config describes.
pub fn run(args: RunArgs, verbose: u8) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.scenario, &[super::kind::Kind::Scenario])?;
    if let Some(b) = &args.bench {
        super::kind::expect(b, &[super::kind::Kind::BenchConfig])?;
    }
    if let Some(m) = &args.gyro_model {
        super::kind::expect(m, &[super::kind::Kind::Model])?;
    }
    args.recording_options()?;
    if let Some(scale) = args.time_scale {
        anyhow::ensure!(
            scale.is_finite() && scale > 0.0,
            "--time-scale must be a positive number, got {scale}"
        );
    }
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.out.as_deref())?;
    outputs.file(args.json.as_deref())?;
    let out = match &args.out {
        Some(out) => out.clone(),
        None => {
            let stem = args.scenario.file_stem().map(|s| s.to_os_string()).unwrap_or_default();
            let default = PathBuf::from(stem).with_extension("mcap");
            if args.force {
                default
            } else {
                fresh_name(&default)
            }
        }
    };
    let progress = !args.quiet && bench::progress::stderr_is_styled();
    let report = match &args.bench {
        None => run_simulated(&args, &out, progress, verbose, None)?,
        Some(spec) => {
            let source = match BenchSource::load(spec) {
                Ok(source) => source,
                Err(e) => {
                    return super::validate::config_invalid(&e).map_or_else(|| Err(e.into()), Ok)
                }
            };
            match source {
                BenchSource::Replay(_) | BenchSource::Devices(_)
                    if args.time_scale.is_some()
                        && !matches!(&source, BenchSource::Devices(c) if c.is_simulated()) =>
                {
                    anyhow::bail!(
                        "--time-scale runs the embedded simulated bench in real time; this \
                         bench config names devices or a replay (their time scale is the \
                         config's `[bench] time_scale` or `[replay] speed`)"
                    )
                }
                BenchSource::Replay(replay) => {
                    run_on_replay(&args, &replay, &out, progress, verbose)?
                }
                BenchSource::Devices(config) if config.is_simulated() => {
                    run_simulated(&args, &out, progress, verbose, Some(&config))?
                }
                BenchSource::Devices(config) => {
                    run_on_bench(&args, spec, *config, &out, progress, verbose)?
                }
            }
        }
    };
    let Some(report) = report else {
        return Ok(Exit::Invalid.into());
    };
    let to_stdout = args.json.as_deref() == Some(Path::new("-"));
    if !to_stdout {
        say!(
            "{}: {} — {} of bench time in {:.2} s wall ({:.0}× real time), {} gyro samples, \
             peak RSS {}",
            out.display(),
            report.outcome,
            bench::progress::hms(report.bench_time.as_secs_f64()),
            report.wall_time.as_secs_f64(),
            report.speed(),
            report.gyro_samples,
            bench::process::peak_rss_mib().map_or("n/a".to_string(), |m| format!("{m:.1} MB")),
        );
    }
    if let Some(path) = &args.json {
        let v = serde_json::json!({
            "recording": out.display().to_string(),
            "completed": report.completed(),
            "outcome": report.outcome.to_string(),
            "fault": report.fault.as_ref().map(|f| f.message.clone()),
            "bench_time_s": report.bench_time.as_secs_f64(),
            "wall_time_s": report.wall_time.as_secs_f64(),
            "gyro_samples": report.gyro_samples,
            "peak_rss_mb": bench::process::peak_rss_mib(),
        });
        let text = serde_json::to_string_pretty(&v)?;
        if to_stdout {
            asked!("{text}");
        } else {
            std::fs::write(path, text)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    Ok(if report.completed() { Exit::Success } else { Exit::Aborted }.into())
}

/// `path` if it does not exist, else the first of `STEM-2.EXT`, `STEM-3.EXT`, … that does not
/// (said on stderr).
pub fn fresh_name(path: &Path) -> PathBuf {
    if !path.exists() {
        return path.to_path_buf();
    }
    let stem = path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned());
    for k in 2u32.. {
        let name = match &ext {
            Some(e) => format!("{stem}-{k}.{e}"),
            None => format!("{stem}-{k}"),
        };
        let candidate = path.with_file_name(name);
        if !candidate.exists() {
            eprintln!("{} exists: recording to {} instead", path.display(), candidate.display());
            return candidate;
        }
    }
    path.to_path_buf()
}

/// The embedded simulated bench in virtual time; with a bench config that names no drivers,
/// at its site and with its `[simulation.effects]` over the scenario's truth effects.
fn run_simulated(
    args: &RunArgs,
    out: &Path,
    progress: bool,
    verbose: u8,
    config: Option<&BenchConfig>,
) -> anyhow::Result<Option<RunReport>> {
    let Some(mut plan) = load_plan(&args.scenario, &bench::simulate::capabilities())? else {
        return Ok(None);
    };
    apply_gyro_model(&mut plan, args.gyro_model.as_deref())?;
    if let Some(config) = config {
        apply_sim_config(&mut plan, config);
        plan.station = plan.station.overridden_by(&config.station());
    }
    apply_station(&mut plan, args);
    let rt = runtime()?;
    let _entered = rt.enter();
    let (flush_interval, time_marks) = args.recording_options()?;
    let file = std::fs::File::create(out)
        .with_context(|| format!("cannot create recording {}", out.display()))?;
    let opts = RunOptions {
        pace: args.time_scale.map_or(Pace::Virtual, Pace::RealTime),
        progress,
        live: start_live(&rt, args)?,
        console: Some(super::console_layer(verbose)),
        // A real-time run is stopped by the operator as a real bench is.
        stop: args.time_scale.map(|_| stop_on_signals()),
        policy: config.map(|c| c.bench.policy()).unwrap_or_default(),
        flush_interval: flush_interval_of(flush_interval, &plan),
        time_marks,
    };
    let bench = Bench::Simulated(bench::simulate::sim_config(&plan, args.seed));
    let (report, writer) = bench::runner::run(&plan, bench, std::io::BufWriter::new(file), opts)?;
    finish_file(writer, out, args.time_scale.is_some())?;
    Ok(Some(report))
}

/// A bench config's site and `[simulation.effects]` applied to a plan for the simulated bench:
/// the site replaces the scenario's, each effect replaces or adds to the truth effects.
pub fn apply_sim_config(plan: &mut RunPlan, config: &BenchConfig) {
    if let Some(site) = config.site() {
        plan.site = site;
    }
    plan.sim.truth_effects = plan.sim.truth_effects.overridden_by(&config.sim_effects());
}

/// Flush the recording to disk; a `paced` run's (real or scaled time), which closed a chunk at
/// every flush, is then compacted into full chunks (`bench_recording::recover::compact_file`).
fn finish_file(
    writer: std::io::BufWriter<std::fs::File>,
    out: &Path,
    paced: bool,
) -> anyhow::Result<()> {
    writer
        .into_inner()
        .map_err(|e| e.into_error())
        .and_then(|f| f.sync_all())
        .with_context(|| format!("cannot write recording {}", out.display()))?;
    if paced {
        match bench_recording::recover::compact_file(out) {
            Ok(_) => {}
            Err(e) => tracing::warn!("{}: left in small chunks: {e}", out.display()),
        }
    }
    Ok(())
}

/// Real time on tokio: connect every device (failing before anything moves), validate the
/// scenario against what they report, run with Ctrl-C aborting to the safe state.
fn run_on_bench(
    args: &RunArgs,
    config_path: &Path,
    config: BenchConfig,
    out: &Path,
    progress: bool,
    verbose: u8,
) -> anyhow::Result<Option<RunReport>> {
    if config.sim_effects().any() {
        tracing::warn!(
            "{}: [simulation.effects] ignored: the devices are reached through drivers (give \
             the config to `bench sim serve --bench` to simulate them)",
            config_path.display()
        );
    }
    let config_text = std::fs::read_to_string(config_path)
        .with_context(|| format!("cannot read {}", config_path.display()))?;
    let rt = runtime()?;
    let _entered = rt.enter();
    let live = start_live(&rt, args)?;
    let (flush_interval, time_marks) = args.recording_options()?;
    let clock = SystemClock::new(config.bench.time_scale);
    // Bench time zero is now: log times are wall-clock times (scaled around this instant for
    // simulators behind virtual ports).
    let epoch_ns = wall_epoch_ns();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let (devices, caps) = rt.block_on(config.connect(shared))?;
    let Some(mut plan) = load_plan(&args.scenario, &caps)? else {
        return Ok(None);
    };
    apply_gyro_model(&mut plan, args.gyro_model.as_deref())?;
    plan.station = plan.station.overridden_by(&config.station());
    apply_station(&mut plan, args);
    if let Some(site) = config.site() {
        if site.latitude_deg != plan.site.latitude_deg {
            tracing::warn!(
                "bench config latitude {}° overrides the scenario's {}°",
                site.latitude_deg,
                plan.site.latitude_deg
            );
        }
        plan.site = site;
    }
    let mut info = run_info(&plan, epoch_ns);
    // Real drivers: the gyro is the lab's, so its model is what the lab gave (nominal), or
    // none; the scenario's defaults are not this gyro's.
    if !plan.gyro.model_given {
        info.gyro_model.clear();
    }
    info.config = Some(TomlAttachment {
        name: config_path
            .file_name()
            .map_or("bench.toml".into(), |n| n.to_string_lossy().into_owned()),
        text: config_text,
    });
    let file = std::fs::File::create(out)
        .with_context(|| format!("cannot create recording {}", out.display()))?;
    let (report, writer) = bench::runner::run(
        &plan,
        Bench::Connected { devices, clock, info: Box::new(info) },
        std::io::BufWriter::new(file),
        RunOptions {
            pace: Pace::RealTime(config.bench.time_scale),
            progress,
            stop: Some(stop_on_signals()),
            console: Some(super::console_layer(verbose)),
            policy: config.bench.policy(),
            live,
            flush_interval: flush_interval_of(flush_interval, &plan),
            time_marks,
        },
    )?;
    finish_file(writer, out, true)?;
    Ok(Some(report))
}

/// Against a recording: the scenario is validated against what the replay offers, then run in
/// virtual time (no `speed`) or in real time × `speed`. Commands that disagree with the
/// recording are counted and reported.
fn run_on_replay(
    args: &RunArgs,
    config: &ReplayBenchConfig,
    out: &Path,
    progress: bool,
    verbose: u8,
) -> anyhow::Result<Option<RunReport>> {
    let rec = &config.replay.recording;
    let data = Arc::new(bench::replay::ReplayData::load(rec)?);
    let Some(mut plan) = load_plan(&args.scenario, &data.capabilities())? else {
        return Ok(None);
    };
    apply_gyro_model(&mut plan, args.gyro_model.as_deref())?;
    apply_station(&mut plan, args);
    let file = std::fs::File::create(out)
        .with_context(|| format!("cannot create recording {}", out.display()))?;
    let writer = std::io::BufWriter::new(file);
    let rt = runtime()?;
    let _entered = rt.enter();
    let opts = RunOptions {
        pace: config.replay.speed.map_or(Pace::Virtual, Pace::RealTime),
        progress,
        live: start_live(&rt, args)?,
        console: Some(super::console_layer(verbose)),
        stop: config.replay.speed.map(|_| stop_on_signals()),
        policy: config.bench.policy(),
        flush_interval: flush_interval_of(args.recording_options()?.0, &plan),
        time_marks: args.recording_options()?.1,
    };
    let paced = matches!(opts.pace, Pace::RealTime(_));
    let (report, writer) = bench::runner::run(&plan, Bench::Replay(data), writer, opts)?;
    finish_file(writer, out, paced)?;
    if let Some(c) = report.replay {
        say!(
            "replay of {}: {} table command(s), {} disagreeing with the recording; {} chamber \
             target(s), {} disagreeing",
            rec.display(),
            c.table_commands,
            c.table_mismatches,
            c.chamber_targets,
            c.chamber_mismatches
        );
    }
    Ok(Some(report))
}

/// A two-worker tokio runtime.
pub(crate) fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")
}

/// The live view, if `--live`: started on `rt`, its address printed.
fn start_live(
    rt: &tokio::runtime::Runtime,
    args: &RunArgs,
) -> anyhow::Result<Option<Arc<bench::live_view::LiveView>>> {
    super::start_live(rt, args.live, args.live_addr)
}

#[cfg(test)]
mod tests {
    use bench_physics::effects::{EffectId, Effects};
    use bench_physics::GyroModel;
    use bench_recording::model_file::{write_model_file, Source, Uncertainty};

    use super::*;

    fn plan() -> RunPlan {
        let text = "[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 10\n\
                    [simulation.truth.effects]\nrate_squared = { coeff_s_per_rad = 1e-3 }\n\
                    [[step]]\nwait = \"1 s\"\n";
        bench::scenario::parse(text, "t.toml", &bench::simulate::capabilities()).expect("valid")
    }

    #[test]
    fn the_command_line_flush_interval_overrides_the_scenarios() {
        let text = "[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 10\n\
                    [recording]\nflush_interval = \"5 s\"\n[[step]]\nwait = \"1 s\"\n";
        let p = bench::scenario::parse(text, "t.toml", &bench::simulate::capabilities())
            .expect("valid");
        assert_eq!(flush_interval_of(None, &p), Some(Duration::from_secs(5)));
        let cli = Some(Duration::from_millis(500));
        assert_eq!(flush_interval_of(cli, &p), cli);
        assert_eq!(flush_interval_of(None, &plan()), None, "neither: the runner's default");
        let args =
            <RunArgs as clap::FromArgMatches>::from_arg_matches(
                &<RunArgs as clap::Args>::augment_args(clap::Command::new("run"))
                    .get_matches_from(["run", "s.toml", "--flush-interval-s", "0.5"]),
            )
            .expect("args");
        assert_eq!(args.recording_options().expect("valid").0, cli);
    }

    #[test]
    fn a_model_file_with_effects_replaces_the_nominal_and_the_truth_effects() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("m.toml");
        let model = GyroModel { bias: 3e-8, ..GyroModel::default() };
        let effects = Effects::default().with(EffectId::WarmUp, &[1e-7, 900.0]).expect("fits");
        write_model_file(&path, &model, &effects, &Source::default(), &Uncertainty::default())
            .expect("writes");
        let mut p = plan();
        assert!(p.sim.truth_effects.has(EffectId::RateSquared));
        apply_gyro_model(&mut p, Some(&path)).expect("applies");
        assert_eq!(p.gyro.model, model);
        assert_eq!(p.gyro.effects, effects);
        assert_eq!(p.sim.truth_effects, effects);
        // Recorded as effect keys of bench.gyro_model.
        let meta = bench::runner::run_info(&p, 0).gyro_model;
        assert_eq!(meta.get("effect.warm_up.time_constant_s").map(String::as_str), Some("9e2"));
    }

    #[test]
    fn a_simulated_bench_config_adds_its_site_and_concealed_effects() {
        let config = BenchConfig::parse(
            "[site]\nlatitude_deg = 45.5\n[simulation.effects]\nwarm_up = { amplitude_rad_s = \
             1e-7, time_constant_s = 60 }\n",
            "sim.toml",
        )
        .expect("valid");
        let mut p = plan();
        apply_sim_config(&mut p, &config);
        assert_eq!(p.site.latitude_deg, 45.5);
        assert_eq!(p.sim.truth_effects.get(EffectId::RateSquared), Some(&[1e-3][..]));
        assert_eq!(p.sim.truth_effects.get(EffectId::WarmUp), Some(&[1e-7, 60.0][..]));
        assert!(!p.gyro.effects.any(), "concealed: not the nominal model's");
        let meta = bench::runner::run_info(&p, 0).gyro_model;
        assert!(meta.keys().all(|k| !k.starts_with("effect.")), "{meta:?}");
        let sim = bench::simulate::sim_config(&p, 1);
        assert_eq!(sim.gyro_effects, p.sim.truth_effects);
    }
}
