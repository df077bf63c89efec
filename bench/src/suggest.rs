//! The experiment that separates what a recording could not: `bench diagnose …
//! --suggest-scenario FILE`, built on the procedure design ([`crate::design`]).
//!
//! A diagnosis lists the pairs of terms its recording cannot tell apart
//! ([`bench_analysis::diagnose::identify`]). Each kind of confusion has a procedure that breaks
//! it, within the bench's limits and the recording's devices:
//!
//! - **thermal** (a hysteresis, coil lag, quadratic or scale-factor-vs-temperature term against
//!   the temperature coefficients): a designed sweep procedure ([`crate::design::search`]) with
//!   holds at both ends — the run of the chamber time given whose Cramér–Rao σ of `k_dt` is
//!   smallest when a lag (at the recording's τ) is fitted beside it, since a lag's `τ·dT/dt` is
//!   what a steady ramp cannot tell from `k_dt`; the holds and the turns of the sweeps are where
//!   the two part. It has no soak step (the sweeps start with `wait = "ramp end"`), so a gyro
//!   without a sensor is never soaked on it;
//! - **per revolution** (angle harmonics, the table's rate ripple, against each other or the
//!   parameters): two full revolutions per direction at 10 °/min and at 30 °/min (or the
//!   bench's fastest, if slower), at constant temperature — soaked on the gyro's sensor, or on
//!   the chamber's air for a gyro without one: full turns make the harmonics orthogonal, and
//!   two rates tell a term of the gyro (independent of rate) from the table's ripple (∝ rate);
//! - **rate²** (against the bias and scale factor, on a run at one |rate|): the same two rates,
//!   at which `Ω²` is no longer a constant.
//!
//! The scenario is validated against the bench's capabilities before it is written.
//! [`predict`] simulates it under the diagnosed model (with the recording's devices: no gyro
//! sensor, none on the simulated gyro) and diagnoses the result: the σ and collinearity of each
//! confounded pair there, against the recording's. [`offer`] tries chamber times from the
//! recording's own up to three times it and offers the first run that lowers both σ and ρ of
//! every pair it is meant to separate — or none, saying so.

use std::fmt::Write as _;

use anyhow::Context as _;
use bench_analysis::diagnose::{Collinearity, DiagnoseOptions, Diagnosis};
use bench_physics::effects::{EffectId, Procedure};
use bench_physics::GyroModel;

use crate::design::{self, Goal, Grid, Limits, ScenarioSetup, Subject};
use crate::runner::{run, Bench, RunOptions, IN_MEMORY_FLUSH_INTERVAL};
use crate::scenario::Capabilities;
use crate::simulate::{capabilities, sim_config};

/// What the suggestion is for: a confounded pair and how it separates.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The pair on the recording.
    pub before: Collinearity,
    /// The same pair on the simulated suggestion (`None` when that run no longer has the term).
    pub after: Option<Collinearity>,
}

impl Target {
    /// Both σ and ρ of the pair lower on the suggested run than on the recording.
    pub fn lowered(&self) -> bool {
        self.after.as_ref().is_some_and(|a| a.sigma < self.before.sigma && a.rho < self.before.rho)
    }
}

/// A suggested scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Suggestion {
    /// Scenario TOML, validated against the bench's capabilities.
    pub text: String,
    /// Why, one line each.
    pub why: Vec<String>,
    /// The pairs it separates, with the predicted separation once [`predict`] ran.
    pub targets: Vec<Target>,
    /// Chamber time of the run, s (its nominal timeline).
    pub duration_s: f64,
    /// The recording's gyro has its own temperature sensor (the simulated prediction's gyro
    /// has one only then).
    pub gyro_sensor: bool,
    /// Chamber times of the shorter runs [`offer`] tried first, which did not lower every
    /// target, s.
    pub shorter_tried_s: Vec<f64>,
}

impl Suggestion {
    /// Every target's σ and ρ lower on the suggested run ([`Target::lowered`]).
    pub fn lowers_all(&self) -> bool {
        !self.targets.is_empty() && self.targets.iter().all(Target::lowered)
    }
}

/// What the suggestion needs of the recording beyond its diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingFacts {
    /// Recording's name (for the description).
    pub name: String,
    /// Site latitude, degrees.
    pub latitude_deg: f64,
    /// Lowest and highest model temperature of the run, °C.
    pub temp_range_c: (f64, f64),
    /// The gyro has its own temperature sensor (without one: the chamber's air is the soak
    /// source, and the simulated prediction's gyro has none either).
    pub gyro_sensor: bool,
    /// The recording's duration, s: the first chamber time a thermal design is given.
    pub duration_s: f64,
}

/// Terms that full turns at two rates separate: the angle's and the rate's (the effect's
/// [`bench_physics::effects::Effect::separated_by`]).
fn is_angle(id: EffectId) -> bool {
    id.effect().separated_by() == Procedure::TurnsAtTwoRates
}

/// A scenario that separates the diagnosis's confounded pairs (module docs) on the simulated
/// bench, its thermal part designed for the recording's own duration; `None` when the
/// diagnosis found none. Not yet predicted ([`predict`]); [`offer`] does both.
pub fn suggest(d: &Diagnosis, facts: &RecordingFacts) -> anyhow::Result<Option<Suggestion>> {
    suggest_for(d.identifiability(), &d.model, facts, &capabilities(), facts.duration_s)
}

/// The outcome of [`offer`].
#[derive(Debug, Clone, PartialEq)]
pub enum Offer {
    /// The diagnosis found nothing confounded.
    Nothing,
    /// A run that lowers σ and ρ of every pair it is meant to separate (predicted).
    Lowers(Suggestion),
    /// The best run tried (the longest) does not: not offered.
    DoesNotLower(Suggestion),
}

/// Chamber times tried, as multiples of the recording's duration.
pub const BUDGETS: [f64; 3] = [1.0, 2.0, 3.0];

/// The suggestion offered (module docs): designed within `caps` for the recording's duration,
/// then twice and three times it, each simulated under the diagnosed model (`seed`) and
/// diagnosed; the first that lowers σ and ρ of every target is offered.
pub fn offer(
    d: &Diagnosis,
    facts: &RecordingFacts,
    caps: &Capabilities,
    seed: u64,
) -> anyhow::Result<Offer> {
    let pairs = d.identifiability();
    let mut last: Option<Suggestion> = None;
    for k in BUDGETS {
        // At least 2 h: the shortest sweeps with holds.
        let budget_s = (k * facts.duration_s).max(7200.0);
        let Some(mut s) = suggest_for(pairs.clone(), &d.model, facts, caps, budget_s)? else {
            return Ok(Offer::Nothing);
        };
        predict(&mut s, seed)?;
        if let Some(l) = &last {
            s.shorter_tried_s = l.shorter_tried_s.clone();
            s.shorter_tried_s.push(l.duration_s);
        }
        if s.lowers_all() {
            return Ok(Offer::Lowers(s));
        }
        let angle_only = pairs.iter().all(|c| is_angle(c.effect));
        last = Some(s);
        // The per-revolution run does not depend on the chamber time.
        if angle_only {
            break;
        }
    }
    Ok(last.map_or(Offer::Nothing, Offer::DoesNotLower))
}

/// The grid a thermal suggestion searches: sweeps with holds at both ends (a lag parts from
/// `k_dt` only where the ramp starts and stops), at the bench's slowest table rate up to
/// 10 °/min (the table does not matter to thermal terms).
fn thermal_grid(limits: &Limits) -> Grid {
    Grid {
        ramps_c_min: vec![0.5, 1.0, 2.0, 3.0],
        table_deg_min: vec![design::fastest_allowed(&[10.0], limits.max_table_deg_min, 1.0)],
        reversal_min: vec![10.0, 20.0],
        hold_min: vec![20.0, 40.0],
        max_legs: 16,
        dt_s: 10.0,
    }
}

/// [`suggest`] for the confounded `pairs` of a recording diagnosed to `model`, within `caps`,
/// its thermal part designed for `budget_s` of chamber time.
fn suggest_for(
    pairs: Vec<Collinearity>,
    model: &GyroModel,
    facts: &RecordingFacts,
    caps: &Capabilities,
    budget_s: f64,
) -> anyhow::Result<Option<Suggestion>> {
    if pairs.is_empty() {
        return Ok(None);
    }
    let angle = pairs.iter().any(|c| is_angle(c.effect));
    let thermal = pairs.iter().any(|c| !is_angle(c.effect));
    let mut limits = Limits::of(caps);
    limits.gyro_sensor = limits.gyro_sensor && facts.gyro_sensor;
    let t0 = model.reference_temperature.clamp(limits.range_c.0, limits.range_c.1);
    let setup = ScenarioSetup {
        latitude_deg: facts.latitude_deg,
        axis_up: true,
        sample_rate_hz: 20.0,
        model: model.clone(),
    };
    let pairs_text: Vec<String> = pairs
        .iter()
        .map(|c| format!("{} vs {} (ρ = {:.3})", c.effect.key(), c.with_name(), c.rho))
        .collect();
    let pairs_text = pairs_text.join(", ");
    let mut why = Vec::new();
    let mut duration_s = 0.0;
    let header = format!(
        "Suggested by `bench diagnose {} --suggest-scenario`: a run that separates what that \
         recording\ncould not ({pairs_text}).",
        facts.name
    );
    // The per-revolution turns: the bench's fastest up to 30 °/min and a third of it.
    let fast = limits.max_table_deg_min.min(30.0).floor().max(1.0);
    let slow = if fast >= 30.0 { 10.0 } else { (fast / 3.0 * 10.0).floor() / 10.0 };
    let angle_why = format!(
        "per revolution: two full revolutions per direction at {slow} °/min and at {fast} \
         °/min at {t0} °C (soaked on the {}): full turns make the angle harmonics orthogonal, \
         and two rates tell a term of the gyro (independent of rate) from the table's rate \
         ripple (∝ rate), and a rate² term from the bias",
        if limits.gyro_sensor { "gyro's sensor" } else { "chamber's air: the gyro has no sensor" }
    );
    let mut text = if thermal {
        // The lag the pair was judged at (else the model's, else 600 s): fitted beside k_dt.
        let tau = pairs
            .iter()
            .find(|c| c.effect == EffectId::ThermalLag && c.grid_value.is_finite())
            .map(|c| c.grid_value)
            .or((model.thermal_time_constant > 0.0).then_some(model.thermal_time_constant))
            .unwrap_or(600.0);
        let mut lagged = model.clone();
        lagged.thermal_time_constant = tau;
        let subject = Subject { model: lagged, latitude_deg: facts.latitude_deg, initial_c: t0 };
        let lag_limits = Limits { gyro_sensor: false, ..limits };
        let goal =
            Goal::Budget { hours: budget_s / 3600.0, reference: [None, None, None, Some(1.0)] };
        let found = design::search(&subject, &lag_limits, &thermal_grid(&limits), goal)
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "no sweep procedure with holds fits {:.1} h within the bench's limits",
                    budget_s / 3600.0
                )
            })?;
        let p = found.procedure;
        let tl = p.timeline().context("the designed procedure has no timeline")?;
        duration_s = tl.duration_s;
        why.push(format!(
            "thermal: {} sweeps {}..{} °C at ±{} °C/min with {} min holds at both ends, table \
             ±{} °/min reversed every {} min (bench design: the smallest σ of k_dt with a \
             {tau:.0} s lag fitted beside it within {}): a hold and each turn of the sweep keep \
             a lagged temperature apart from dT/dt, where a steady ramp makes τ·dT/dt a copy \
             of k_dt",
            p.legs,
            p.range_c.0,
            p.range_c.1,
            p.ramp_c_min,
            p.hold_min,
            p.table_deg_min,
            p.reversal_min,
            hm(budget_s)
        ));
        if angle {
            why.push(angle_why.clone());
        }
        let header = format!("{header}\n{}", why.join("\n"));
        tl.scenario(&p, &format!("separate-{}", slug(&pairs)), &header, &setup)
    } else {
        why.push(angle_why.clone());
        header_only(
            &pairs,
            &pairs_text,
            &format!("{header}\n{}", why.join("\n")),
            facts,
            &setup,
            t0,
        )
    };
    if angle {
        let source = if limits.gyro_sensor { "gyro" } else { "air" };
        let mut steps = String::new();
        let mut step = |label: &str, body: &str| {
            let _ = writeln!(steps, "[[step]]\nlabel = \"{label}\"\n{body}\n");
        };
        step(&format!("to {t0}C"), &format!("chamber = \"{t0} °C\""));
        step(
            &format!("soak {t0}C"),
            &format!(
                "wait_temperature = \"{t0} °C\"\nsource = \"{source}\"\nband = \"0.3 °C\"\n\
                 hold = \"10 min\"\ntimeout = \"4 h\""
            ),
        );
        // The soak: the move at the chamber's fastest, ten minutes held and the gyro's
        // settling: 30 min allowed.
        duration_s += 1800.0;
        for rate in [slow, fast] {
            let minutes = 720.0 / rate;
            for dir in ["cw", "ccw"] {
                step(
                    &format!("spin {dir} {rate} deg/min"),
                    &format!(
                        "spin = \"{rate} °/min\"\ndirection = \"{dir}\"\naccel = \"{} °/s²\"",
                        limits.accel_deg_s2
                    ),
                );
                step(&format!("settle {dir} {rate}"), "wait = \"1 min\"");
                step(
                    &format!("record {dir} {rate} deg/min, 2 revolutions"),
                    &format!("record = \"{minutes} min\""),
                );
                duration_s += (minutes + 1.0) * 60.0;
            }
        }
        step("stop", "stop = \"table\"");
        text.push_str(&steps);
    }
    crate::scenario::parse(&text, "suggested scenario", caps)
        .map_err(|e| anyhow::anyhow!("the suggested scenario does not validate: {e}"))?;
    let targets = pairs.into_iter().map(|before| Target { before, after: None }).collect();
    Ok(Some(Suggestion {
        text,
        why,
        targets,
        duration_s,
        gyro_sensor: limits.gyro_sensor,
        shorter_tried_s: Vec::new(),
    }))
}

/// The scenario's name: after the first pair's effect.
fn slug(pairs: &[Collinearity]) -> &'static str {
    pairs.first().map_or("terms", |c| c.effect.key())
}

/// Hours and minutes.
pub fn hm(s: f64) -> String {
    let m = (s / 60.0).round() as u64;
    format!("{} h {:02} min", m / 60, m % 60)
}

/// The scenario's header and settings without steps (a suggestion with no thermal part).
fn header_only(
    pairs: &[Collinearity],
    pairs_text: &str,
    comment: &str,
    facts: &RecordingFacts,
    setup: &ScenarioSetup,
    t0: f64,
) -> String {
    let mut model_toml = String::new();
    for (k, v) in setup.model.to_metadata() {
        let value = if k == "earth_rate" { (v == "1" || v == "true").to_string() } else { v };
        let _ = writeln!(model_toml, "{k} = {value}");
    }
    let comment: String = comment.lines().map(|l| format!("# {l}\n")).collect();
    format!(
        "{comment}\n[scenario]\nname = \"separate-{slug}\"\n\
         description = \"Separates {pairs_text} (bench diagnose of {name}).\"\n\n[site]\n\
         latitude_deg = {lat}\naxis = \"up\"\n\n[gyro]\nsample_rate = \"20 Hz\"\n\n\
         # The diagnosed model of {name}.\n[gyro.model]\n{model_toml}\n[simulation]\n\
         initial_temp = \"{t0} °C\"\n\n[safe]\ndecel = \"10 °/s²\"\ntemperature = \"{t0} °C\"\n\n",
        name = facts.name,
        slug = slug(pairs),
        lat = facts.latitude_deg,
    )
}

/// Simulate `s` under its scenario's model (the diagnosed one, `seed`) and diagnose the run
/// against that model: each target's σ and ρ there.
pub fn predict(s: &mut Suggestion, seed: u64) -> anyhow::Result<()> {
    let plan = crate::scenario::parse(&s.text, "suggested scenario", &capabilities())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    // The recording's devices: a gyro without a sensor has none on the simulated bench either.
    let mut config = sim_config(&plan, seed);
    config.gyro.has_temperature = s.gyro_sensor;
    let opts =
        RunOptions { flush_interval: Some(IN_MEMORY_FLUSH_INTERVAL), ..RunOptions::default() };
    let (report, cursor) =
        run(&plan, Bench::Simulated(config), std::io::Cursor::new(Vec::new()), opts)?;
    let bytes = cursor.into_inner();
    anyhow::ensure!(report.completed(), "the suggested run did not complete: {}", report.outcome);
    let rec = bench_recording::Recording::from_bytes(&bytes)?;
    let model: GyroModel = plan.gyro.model.clone();
    // Each target judged at the recording's grid value (a lag's τ, a harmonic's k).
    let opts = DiagnoseOptions {
        identify_at: s.targets.iter().map(|t| (t.before.effect, t.before.grid_value)).collect(),
        identify_with: s.targets.iter().map(|t| (t.before.effect, t.before.with.clone())).collect(),
        ..Default::default()
    };
    let out = bench_report::diagnose::diagnose_recording(
        &rec,
        Some((model, plan.gyro.effects, "the suggested scenario's model".into())),
        &opts,
    )
    .context("cannot diagnose the simulated suggestion")?;
    for t in &mut s.targets {
        t.after = out
            .diagnosis
            .collinearity
            .iter()
            .find(|c| c.effect == t.before.effect && c.with == t.before.with)
            .cloned();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(effect: EffectId, with: &str) -> Collinearity {
        Collinearity {
            effect,
            effect_accepted: false,
            grid_value: f64::NAN,
            with: vec![with.into()],
            rho: 0.97,
            sigma_inflation: 4.1,
            sigma: 1e-3,
            bound: 3e-3,
            parameter: "coeff_s_per_rad",
            unit: "s/rad",
        }
    }

    fn facts() -> RecordingFacts {
        RecordingFacts {
            name: "r.mcap".into(),
            latitude_deg: 43.6,
            temp_range_c: (-5.0, 45.0),
            gyro_sensor: true,
            duration_s: 5.0 * 3600.0,
        }
    }

    /// Steps of the suggested scenario that spin at `rate` °/min, and that ramp the chamber.
    fn counts(text: &str, rate: &str) -> (usize, usize) {
        let spins = text.matches(&format!("spin = \"{rate} °/min\"")).count();
        let ramps = text.matches("ramp = \"").count();
        (spins, ramps)
    }

    /// [`suggest_for`] on the simulated bench for the recording's duration.
    fn on_sim(pairs: Vec<Collinearity>, facts: &RecordingFacts) -> Suggestion {
        suggest_for(pairs, &GyroModel::default(), facts, &capabilities(), facts.duration_s)
            .expect("validates")
            .expect("a suggestion")
    }

    #[test]
    fn a_rate_squared_term_gets_two_rates_and_no_thermal_ramps() {
        let s = on_sim(vec![pair(EffectId::RateSquared, "bias")], &facts());
        // Full turns each way at 10 and at 30 °/min, at constant temperature.
        assert_eq!(counts(&s.text, "30"), (2, 0), "{}", s.text);
        assert_eq!(counts(&s.text, "10").0, 2, "{}", s.text);
        assert!(s.why.iter().any(|w| w.contains("rate² term from the bias")), "{:?}", s.why);
        assert!(s.text.contains("source = \"gyro\""), "{}", s.text);
        assert_eq!(s.targets.len(), 1);
    }

    #[test]
    fn a_thermal_term_gets_designed_sweeps_with_holds_within_the_recordings_duration() {
        let s = on_sim(vec![pair(EffectId::ThermalLag, "temp_rate_coeff")], &facts());
        // Sweeps over the bench's range, each followed by a recorded hold; no second table
        // rate; no soak at all.
        assert!(s.text.contains("chamber = \"-40 °C\"") && s.text.contains("chamber = \"60 °C\""));
        assert!(s.text.contains("record cw hold 60C") || s.text.contains("record ccw hold 60C"));
        assert_eq!(counts(&s.text, "30").0, 0, "{}", s.text);
        assert!(!s.text.contains("wait_temperature"), "{}", s.text);
        assert!(s.duration_s <= 5.0 * 3600.0 && s.duration_s > 2.0 * 3600.0, "{}", s.duration_s);
        assert!(s.why[0].contains("lag fitted beside it"), "{:?}", s.why);
    }

    /// Issue 31: a gyro without its own sensor is soaked on the chamber's air, never on
    /// `source = "gyro"` (main offered that), and the bench's limits hold: a table of at most
    /// 20 °/min gets its turns at 20 and 6.6 °/min, not 30.
    #[test]
    fn a_gyro_without_a_sensor_is_soaked_on_the_air_and_a_slow_table_is_respected() {
        let no_sensor = RecordingFacts { gyro_sensor: false, ..facts() };
        let pairs = vec![
            pair(EffectId::ThermalLag, "temp_rate_coeff"),
            pair(EffectId::RateSquared, "bias"),
        ];
        let s = on_sim(pairs.clone(), &no_sensor);
        assert!(!s.text.contains("source = \"gyro\""), "{}", s.text);
        assert!(s.text.contains("source = \"air\""), "{}", s.text);
        assert!(!s.gyro_sensor);
        let mut caps = capabilities();
        caps.table.capabilities.max_rate_rad_s = 20.0 * bench_physics::units::DEG_PER_MIN;
        let s = suggest_for(pairs, &GyroModel::default(), &no_sensor, &caps, 5.0 * 3600.0)
            .expect("validates")
            .expect("a suggestion");
        assert_eq!(counts(&s.text, "30").0, 0, "{}", s.text);
        assert_eq!(counts(&s.text, "20").0, 2, "{}", s.text);
    }

    #[test]
    fn nothing_confounded_suggests_nothing() {
        let f = facts();
        let none = suggest_for(Vec::new(), &GyroModel::default(), &f, &capabilities(), 3600.0);
        assert!(none.expect("ok").is_none());
    }
}
