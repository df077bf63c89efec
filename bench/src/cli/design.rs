//! `bench design`: the shortest chamber run that reaches the σ asked for, or the smallest σ in
//! a time budget, written as a scenario ([`bench::design`], docs/design.md).

use std::path::PathBuf;
use std::process::ExitCode;

use super::exit::{Exit, UsageError};
use super::say::say;
use anyhow::Context as _;
use bench::bench_config::BenchSource;
use bench::design::{self, Goal, Grid, Limits, Prediction, Procedure, ScenarioSetup, Subject};
use bench::scenario::Capabilities;
use bench_physics::units::DEG_PER_H;
use bench_physics::{GyroModel, ModelKey};
use bench_report::display::{coefficient_unit, sig};

/// The seed's full-range procedure: the default reference of `--hours`.
const THERMAL_FULL: &str = include_str!("../../../scenarios/thermal-full.toml");

/// Arguments of `bench design`.
#[derive(clap::Args, Debug)]
pub struct DesignArgs {
    /// Target σ per coefficient, e.g. `k_t=2e-10,k_dt=1e-6,sf=2ppm` (names: bias, sf, k_t,
    /// k_dt or the contract keys; a bare number is SI, or give the display unit: °/h, ppm,
    /// °/h/°C, °/h/(°C/min)). The design reaches all of them in the least chamber time.
    #[arg(long, value_name = "KEY=SIGMA,…", conflicts_with = "like")]
    pub sigma: Option<String>,
    /// Reach the σ this scenario reaches on the gyro (its predicted σ per coefficient).
    #[arg(long, value_name = "SCENARIO")]
    pub like: Option<PathBuf>,
    /// Chamber-time budget, hours: the smallest σ (relative to `--sigma`, `--like`, or by
    /// default the seed's `thermal-full` procedure) that fits.
    #[arg(long)]
    pub hours: Option<f64>,
    /// The gyro: a model TOML file (or a recording's `bench.gyro_model`); default: the seed's
    /// gyro.
    #[arg(long, conflicts_with = "from")]
    pub model: Option<PathBuf>,
    /// The gyro, its devices (temperature sensor or none) and its site from a recording.
    #[arg(long, value_name = "REC.mcap")]
    pub from: Option<PathBuf>,
    /// The bench's limits (a bench config's `[limits]`; default: the simulated bench's).
    #[arg(long, short)]
    pub bench: Option<PathBuf>,
    /// The gyro has no temperature sensor: its lag from the chamber air is fitted.
    #[arg(long)]
    pub no_sensor: bool,
    /// Site latitude, degrees (default: the recording's with `--from`, else 59.94, the
    /// seed's).
    #[arg(long, allow_hyphen_values = true)]
    pub latitude: Option<f64>,
    /// Scenario TOML to write.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Targets `KEY=SIGMA,…`, SI, per coefficient.
pub fn parse_targets(text: &str) -> Result<[Option<f64>; 4], String> {
    let mut out = [None; 4];
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (k, v) = part.split_once('=').ok_or_else(|| format!("`{part}`: expected KEY=SIGMA"))?;
        let j = design::coefficient(k).ok_or_else(|| {
            format!("`{}`: not a calibrated coefficient ({})", k.trim(), design::SHORT.join(", "))
        })?;
        let v = v.trim();
        let unit = coefficient_unit(ModelKey::CALIBRATED[j]).expect("a calibrated coefficient");
        let split =
            v.find(|c: char| !(c.is_ascii_digit() || "+-.eE".contains(c))).unwrap_or(v.len());
        let (num, u) = (v[..split].trim(), v[split..].trim());
        let x: f64 = num
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite() && *x > 0.0)
            .ok_or_else(|| format!("`{part}`: σ must be a positive number"))?;
        let si = if u.is_empty() {
            x
        } else if u == unit.name || u.replace("deg", "°") == unit.name {
            x / unit.per_si
        } else {
            return Err(format!(
                "`{part}`: unit `{u}` for {}: give SI or {}",
                design::SHORT[j],
                unit.name
            ));
        };
        out[j] = Some(si);
    }
    if out.iter().all(Option::is_none) {
        return Err("no target given".into());
    }
    Ok(out)
}

/// A σ in the coefficient's display unit.
fn show(j: usize, x: f64) -> String {
    let u = coefficient_unit(ModelKey::CALIBRATED[j]).expect("a calibrated coefficient");
    if x.is_finite() {
        format!("{} {}", sig(x * u.per_si, 3), u.name).trim_end().to_owned()
    } else {
        "not determined".into()
    }
}

/// Hours and minutes.
fn hm(s: f64) -> String {
    let m = (s / 60.0).round() as u64;
    format!("{} h {:02} min", m / 60, m % 60)
}

/// The bench's capabilities.
fn capabilities(args: &DesignArgs) -> anyhow::Result<Capabilities> {
    bench_capabilities(args.bench.as_deref())
}

/// The capabilities of the bench `spec` (a bench config), or the simulated bench's.
pub fn bench_capabilities(spec: Option<&std::path::Path>) -> anyhow::Result<Capabilities> {
    let Some(spec) = spec else { return Ok(bench::simulate::capabilities()) };
    match BenchSource::load(spec)? {
        BenchSource::Devices(config) => Ok(config.limits().0),
        BenchSource::Replay(r) => {
            Ok(bench::replay::ReplayData::load(&r.replay.recording)?.capabilities())
        }
    }
}

/// The gyro, whether it has a sensor, the latitude and what the gyro is, for messages.
fn subject(args: &DesignArgs) -> anyhow::Result<(GyroModel, Option<bool>, Option<f64>, String)> {
    if let Some(path) = &args.from {
        let rec = bench_recording::Recording::load(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let run = bench_report::load::load(&rec)?;
        let model = run.model.as_ref().map(|m| m.model.clone()).ok_or_else(|| {
            anyhow::anyhow!(
                "{} has no bench.gyro_model: give the gyro with --model",
                path.display()
            )
        })?;
        let sensor = run.gyro_sensor();
        let latitude = run.series.latitude_deg;
        drop(run);
        // The recording's nominal model may not be its gyro: the noise (and a gyro without a
        // sensor's lag) are the ones the calibration measures on the recording.
        let measured = measured(&rec, &model, sensor);
        return Ok((
            measured,
            Some(sensor),
            latitude,
            format!(
                "{} (noise{} measured on it by the calibration; its nominal model says ARW {} \
                 °/√h, flicker floor {} °/h)",
                path.display(),
                if sensor { "" } else { " and lag" },
                sig(model.arw * 60.0 / (std::f64::consts::PI / 180.0), 3),
                sig(model.bias_instability / DEG_PER_H, 3)
            ),
        ));
    }
    match &args.model {
        Some(path) => {
            let (m, _, what) = super::model::load_nominal(path)?;
            Ok((m, None, None, what))
        }
        None => Ok((GyroModel::default(), None, None, "the seed's gyro (default model)".into())),
    }
}

/// `model` with the noise the calibration measures on `rec` (white noise and flicker floor of
/// its fitted noise model) and, for a gyro without a sensor, the lag it fits; `model`'s own
/// where the calibration measures none.
fn measured(rec: &bench_recording::Recording, model: &GyroModel, sensor: bool) -> GyroModel {
    let mut m = model.clone();
    let settings = bench_report::calibrate::CalibrateSettings::default();
    let Ok(out) = bench_report::calibrate::calibrate_recording(rec, &settings) else {
        say!("the calibration of the recording failed: the design uses its nominal model's noise");
        return m;
    };
    match out.calibration.noise_model {
        Some(n) => {
            m.arw = n.arw;
            m.bias_instability = n.flicker_floor;
        }
        None => say!("no noise model measured on the recording: its nominal model's noise is used"),
    }
    if !sensor {
        if let Some(Ok(l)) = &out.calibration.lag {
            m.thermal_time_constant = l.used_s;
        }
    }
    m
}

/// Print a prediction against a reference.
fn print_sigma(title: &str, p: &Prediction, reference: Option<(&str, &[Option<f64>; 4])>) {
    say!("{title} ({} of chamber time):", hm(p.duration_s));
    for j in 0..4 {
        let against = match reference {
            Some((name, r)) => r[j].map_or(String::new(), |r| {
                format!("   ({} {name}: {:.2}×)", show(j, r), p.sigma[j] / r)
            }),
            None => String::new(),
        };
        say!("  σ({:<4}) {:>24}{against}", design::SHORT[j], show(j, p.sigma[j]));
    }
}

/// Run `bench design`.
pub fn run(args: DesignArgs) -> anyhow::Result<ExitCode> {
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.out.as_deref())?;
    if args.sigma.is_none() && args.like.is_none() && args.hours.is_none() {
        return Err(UsageError(
            "give --sigma, --like or --hours: what the design is to reach".into(),
        )
        .into());
    }
    if let Some(h) = args.hours {
        if !(h.is_finite() && h > 0.0) {
            return Err(
                UsageError(format!("--hours {h}: must be a positive number of hours")).into()
            );
        }
    }
    let targets = args
        .sigma
        .as_deref()
        .map(parse_targets)
        .transpose()
        .map_err(|e| UsageError(format!("--sigma: {e}")))?;
    let caps = capabilities(&args)?;
    let (model, sensor, rec_lat, what) = subject(&args)?;
    let mut limits = Limits::of(&caps);
    limits.gyro_sensor = limits.gyro_sensor && !args.no_sensor && sensor.unwrap_or(true);
    let latitude_deg = args.latitude.or(rec_lat).unwrap_or(59.94);
    let lag_fitted = !limits.gyro_sensor;
    say!(
        "gyro: {what}; noise: ARW {} °/√h, flicker floor {} °/h (every σ below rests on it); {}",
        sig(model.arw * 60.0 / (std::f64::consts::PI / 180.0), 3),
        sig(model.bias_instability / DEG_PER_H, 3),
        if lag_fitted {
            format!(
                "no temperature sensor: the chamber air through a fitted lag ({:.0} s nominal)",
                model.thermal_time_constant
            )
        } else {
            "its own temperature sensor".into()
        }
    );
    say!(
        "bench: {:.0}..{:.0} °C, ramps ≤ {} °C/min, table ≤ {} °/min at {} °/s²",
        limits.range_c.0,
        limits.range_c.1,
        sig(limits.max_ramp_c_min, 3),
        sig(limits.max_table_deg_min, 3),
        sig(limits.accel_deg_s2, 3)
    );
    // The reference: a scenario's predicted σ.
    let reference = |text: &str, name: &str| -> anyhow::Result<Prediction> {
        let plan = bench::scenario::parse(text, name, &bench::simulate::capabilities())
            .map_err(anyhow::Error::from)?;
        design::predict_plan(&plan, &model, lag_fitted)
            .with_context(|| format!("cannot predict the σ of {name}"))
    };
    let like = match &args.like {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let name = path.display().to_string();
            let p = reference(&text, &name)?;
            print_sigma(&format!("{name} predicted"), &p, None);
            Some((name, p))
        }
        None => None,
    };
    let goal = match (args.hours, targets, &like) {
        (Some(hours), Some(t), _) => Goal::Budget { hours, reference: t },
        (Some(hours), None, Some((_, p))) => Goal::Budget { hours, reference: p.sigma.map(Some) },
        (Some(hours), None, None) => {
            let p = reference(THERMAL_FULL, "thermal-full")?;
            print_sigma("thermal-full predicted", &p, None);
            Goal::Budget { hours, reference: p.sigma.map(Some) }
        }
        (None, Some(t), _) => Goal::Targets(t),
        (None, None, Some((_, p))) => Goal::Targets(p.sigma.map(Some)),
        (None, None, None) => unreachable!("checked above"),
    };
    let subject = Subject { model: model.clone(), latitude_deg, initial_c: 20.0 };
    let started = std::time::Instant::now();
    let Some(found) = design::search(&subject, &limits, &Grid::default(), goal) else {
        eprintln!(
            "error: no procedure within the bench's limits reaches the targets in {} sweeps \
             or fewer ({}); loosen a target, give more hours, or a quieter gyro",
            Grid::default().max_legs,
            match goal {
                Goal::Budget { hours, .. } => format!("budget {hours} h"),
                Goal::Targets(_) => "least time".into(),
            }
        );
        let best = best_effort(&subject, &limits);
        if let Some(b) = best {
            print_sigma("the most this bench reaches (the bound)", &b, None);
        }
        return Ok(Exit::DesignUnreachable.into());
    };
    let p: Procedure = found.procedure;
    let reference_sigma: [Option<f64>; 4] = match goal {
        Goal::Targets(t) => t,
        Goal::Budget { reference, .. } => reference,
    };
    // The prediction on the simulated run of the scenario written (the calibration's own
    // windows), one sweep more while it misses a target.
    let setup =
        ScenarioSetup { latitude_deg, axis_up: true, sample_rate_hz: 20.0, model: model.clone() };
    let mut legs = p.legs;
    let (text, simulated) = loop {
        let q = Procedure { legs, ..p };
        let tl = q.timeline().context("the designed procedure has no timeline")?;
        let header = format!(
            "Designed by `bench design` for {what}.\nWhat it varies: sweep rate, table rate, reversal \
             period, holds, number of sweeps (docs/design.md).\n{} sweeps {}..{} °C at ±{} °C/min; \
             table ±{} °/min reversed every {} min; holds {} min; {} of chamber time.",
            q.legs,
            q.range_c.0,
            q.range_c.1,
            q.ramp_c_min,
            q.table_deg_min,
            q.reversal_min,
            q.hold_min,
            hm(tl.duration_s)
        );
        let text = tl.scenario(&q, "designed", &header, &setup);
        let plan = bench::scenario::parse(&text, "designed scenario", &caps)
            .map_err(|e| anyhow::anyhow!("the designed scenario does not validate: {e}"))?;
        let sim = design::predict_plan(&plan, &model, lag_fitted)?;
        let ok = match goal {
            Goal::Targets(t) => sim.worst_ratio(&t) <= 1.0,
            Goal::Budget { .. } => true,
        };
        if ok || legs >= p.legs + 3 {
            break (text, sim);
        }
        legs += 1;
    };
    say!(
        "searched {} candidates in {:.1} s: {} sweeps {}..{} °C at ±{} °C/min, table ±{} °/min \
         reversed every {} min, holds {} min",
        found.evaluated,
        started.elapsed().as_secs_f64(),
        legs,
        p.range_c.0,
        p.range_c.1,
        p.ramp_c_min,
        p.table_deg_min,
        p.reversal_min,
        p.hold_min
    );
    let label = match (&like, args.hours, targets) {
        (_, _, Some(_)) => "target",
        (Some(_), _, _) => "like",
        _ => "thermal-full",
    };
    print_sigma(
        "designed, predicted (Cramér–Rao bound)",
        &simulated,
        Some((label, &reference_sigma)),
    );
    match &args.out {
        Some(path) => {
            outputs.prepare()?;
            std::fs::write(path, &text)
                .with_context(|| format!("cannot write {}", path.display()))?;
            say!("wrote {}", path.display());
        }
        None => say!("(no --out: the scenario was not written)"),
    }
    // The simulated run is the calibration's own design matrix: a miss there is a miss.
    if let Goal::Targets(t) = goal {
        let missed: Vec<String> = (0..4)
            .filter_map(|j| {
                let r = simulated.sigma[j] / t[j]?;
                (r > 1.0).then(|| format!("{} by {:.0} %", design::SHORT[j], 100.0 * (r - 1.0)))
            })
            .collect();
        if !missed.is_empty() {
            eprintln!(
                "error: on its simulated run the design misses the target of {} (the nominal \
                 timeline's prediction met it); loosen the target or give --hours",
                missed.join(", ")
            );
            return Ok(Exit::DesignUnreachable.into());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The smallest σ this bench reaches in the grid's longest procedure, for the message when
/// nothing reaches the targets.
fn best_effort(subject: &Subject, limits: &Limits) -> Option<Prediction> {
    let g = Grid::default();
    let p = Procedure {
        range_c: limits.range_c,
        ramp_c_min: design::fastest_allowed(&g.ramps_c_min, limits.max_ramp_c_min, 0.5),
        legs: g.max_legs,
        table_deg_min: design::fastest_allowed(&g.table_deg_min, limits.max_table_deg_min, 1.0),
        reversal_min: 10.0,
        hold_min: 0.0,
        accel_deg_s2: limits.accel_deg_s2,
        initial_c: subject.initial_c.clamp(limits.range_c.0, limits.range_c.1),
        transit_c_min: limits.max_ramp_c_min,
    };
    design::predict_procedure(&p, &subject.model, subject.latitude_deg, !limits.gyro_sensor, g.dt_s)
}
