//! The experiment that separates what a recording could not: `bench diagnose …
//! --suggest-scenario FILE`.
//!
//! A diagnosis lists the pairs of terms its recording cannot tell apart
//! ([`bench_analysis::diagnose::identify`]). Each kind of confusion has a procedure that breaks
//! it, built from the recording's own temperature range, site and diagnosed gyro model:
//!
//! - **thermal** (a hysteresis, coil lag, quadratic or scale-factor-vs-temperature term against
//!   the temperature coefficients): ramps at two rates (0.5 and 2 °C/min) across the range, each
//!   followed by a 40 min hold at constant temperature, in both directions of rotation. A hold
//!   keeps the hysteresis state and the lagged temperature apart from dT/dt = 0; two rates make
//!   the lag's `τ·dT/dt` differ from a fixed `k_dt`;
//! - **per revolution** (angle harmonics, the table's rate ripple, against each other or the
//!   parameters): two full revolutions per direction at 10 °/min and at 30 °/min, at constant
//!   temperature: full turns make the harmonics orthogonal, and two rates tell a term of the
//!   gyro (independent of rate) from the table's ripple (∝ rate);
//! - **rate²** (against the bias and scale factor, on a run at one |rate|): the same two rates,
//!   at which `Ω²` is no longer a constant.
//!
//! The scenario is validated against the simulated bench (and so stays within its
//! capabilities) before it is written. [`predict`] simulates it under the diagnosed model and
//! diagnoses the result: the σ and collinearity of each confounded effect there, against the
//! recording's.

use std::fmt::Write as _;

use anyhow::Context as _;
use bench_analysis::diagnose::{Collinearity, DiagnoseOptions, Diagnosis};
use bench_physics::effects::{EffectId, Procedure};
use bench_physics::GyroModel;

use crate::runner::simulate_in_memory;
use crate::simulate::capabilities;

/// What the suggestion is for: a confounded pair and how it separates.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The pair on the recording.
    pub before: Collinearity,
    /// The same pair on the simulated suggestion (`None` when that run no longer has the term).
    pub after: Option<Collinearity>,
}

/// A suggested scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Suggestion {
    /// Scenario TOML, validated against the simulated bench.
    pub text: String,
    /// Why, one line each.
    pub why: Vec<String>,
    /// The pairs it separates, with the predicted separation once [`predict`] ran.
    pub targets: Vec<Target>,
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
}

/// Terms that full turns at two rates separate: the angle's and the rate's (the effect's
/// [`bench_physics::effects::Effect::separated_by`]).
fn is_angle(id: EffectId) -> bool {
    id.effect().separated_by() == Procedure::TurnsAtTwoRates
}

/// A scenario that separates the diagnosis's confounded pairs (module docs), or `None` when
/// the diagnosis found none.
pub fn suggest(d: &Diagnosis, facts: &RecordingFacts) -> anyhow::Result<Option<Suggestion>> {
    suggest_for(d.identifiability(), &d.model, facts)
}

/// [`suggest`] for the confounded `pairs` of a recording diagnosed to `model`.
fn suggest_for(
    pairs: Vec<Collinearity>,
    model: &GyroModel,
    facts: &RecordingFacts,
) -> anyhow::Result<Option<Suggestion>> {
    if pairs.is_empty() {
        return Ok(None);
    }
    let angle = pairs.iter().any(|c| is_angle(c.effect));
    let thermal = pairs.iter().any(|c| !is_angle(c.effect));
    let (lo, hi) = facts.temp_range_c;
    // At least 20 °C of range, within the gyro's −40..60 °C.
    let lo = lo.floor().clamp(-40.0, 40.0);
    let hi = hi.ceil().clamp(lo + 20.0, 60.0);
    let t0 = model.reference_temperature;
    let mut why = Vec::new();
    let mut steps = String::new();
    let mut step = |label: &str, body: &str| {
        let _ = writeln!(steps, "[[step]]\nlabel = \"{label}\"\n{body}\n");
    };
    // To `t` °C, then the gyro itself soaked there.
    let soak = |step: &mut dyn FnMut(&str, &str), t: f64| {
        step(&format!("to {t}C"), &format!("chamber = \"{t} °C\""));
        step(
            &format!("soak {t}C"),
            &format!(
                "wait_temperature = \"{t} °C\"\nsource = \"gyro\"\nband = \"0.3 °C\"\n\
                 hold = \"10 min\"\ntimeout = \"4 h\""
            ),
        );
    };
    if thermal {
        why.push(format!(
            "thermal: ramps at 0.5 and 2 °C/min between {lo} and {hi} °C, each followed by a \
             40 min hold, in both directions: holds keep a hysteresis or a lagged temperature \
             apart from dT/dt = 0, and two rates make a lag's τ·dT/dt differ from k_dt"
        ));
        soak(&mut step, lo);
        for (dir, up, down) in [("cw", 0.5, 2.0), ("ccw", 2.0, 0.5)] {
            step(
                &format!("spin {dir}"),
                &format!("spin = \"10 °/min\"\ndirection = \"{dir}\"\naccel = \"1 °/s²\""),
            );
            step(&format!("settle {dir}"), "wait = \"2 min\"");
            for (from, to, rate) in [(lo, hi, up), (hi, lo, down)] {
                step(
                    &format!("ramp {from}C to {to}C at {rate} C/min"),
                    &format!("chamber = \"{to} °C\"\nramp = \"{rate} °C/min\""),
                );
                step(
                    &format!("record {dir} ramp {from}C to {to}C"),
                    "record = \"ramp end\"\ntimeout = \"4 h\"",
                );
                step(&format!("record {dir} hold {to}C"), "record = \"40 min\"");
            }
            step(&format!("stop {dir}"), "stop = \"table\"");
        }
    }
    if angle {
        why.push(format!(
            "per revolution: two full revolutions per direction at 10 °/min and at 30 °/min at \
             {t0} °C: full turns make the angle harmonics orthogonal, and two rates tell a term \
             of the gyro (independent of rate) from the table's rate ripple (∝ rate), and a \
             rate² term from the bias"
        ));
        soak(&mut step, t0);
        for (rate, minutes) in [(10.0, 72), (30.0, 24)] {
            for dir in ["cw", "ccw"] {
                step(
                    &format!("spin {dir} {rate} deg/min"),
                    &format!("spin = \"{rate} °/min\"\ndirection = \"{dir}\"\naccel = \"1 °/s²\""),
                );
                step(&format!("settle {dir} {rate}"), "wait = \"1 min\"");
                step(
                    &format!("record {dir} {rate} deg/min, 2 revolutions"),
                    &format!("record = \"{minutes} min\""),
                );
            }
        }
        step("stop", "stop = \"table\"");
    }
    let pairs_text: Vec<String> = pairs
        .iter()
        .map(|c| format!("{} vs {} (ρ = {:.3})", c.effect.key(), c.with_name(), c.rho))
        .collect();
    let mut model_toml = String::new();
    for (k, v) in model.to_metadata() {
        let value = if k == "earth_rate" { (v == "1" || v == "true").to_string() } else { v };
        let _ = writeln!(model_toml, "{k} = {value}");
    }
    let text = format!(
        "# Suggested by `bench diagnose {name} --suggest-scenario`: a run that separates what \
         that recording\n# could not ({pairs}).\n{why}\n\n[scenario]\nname = \"separate-{slug}\"\n\
         description = \"Separates {pairs} (bench diagnose of {name}).\"\n\n[site]\n\
         latitude_deg = {lat}\naxis = \"up\"\n\n[gyro]\nsample_rate = \"20 Hz\"\n\n\
         # The diagnosed model of {name}.\n[gyro.model]\n{model_toml}\n[simulation]\n\
         initial_temp = \"{t0} °C\"\n\n[safe]\ndecel = \"10 °/s²\"\ntemperature = \"{t0} °C\"\n\n\
         {steps}",
        name = facts.name,
        pairs = pairs_text.join(", "),
        why = why.iter().map(|w| format!("# {w}")).collect::<Vec<_>>().join("\n"),
        slug = pairs.first().map_or("terms", |c| c.effect.key()),
        lat = facts.latitude_deg,
    );
    crate::scenario::parse(&text, "suggested scenario", &capabilities())
        .map_err(|e| anyhow::anyhow!("the suggested scenario does not validate: {e}"))?;
    let targets = pairs.into_iter().map(|before| Target { before, after: None }).collect();
    Ok(Some(Suggestion { text, why, targets }))
}

/// Simulate `s` under its scenario's model (the diagnosed one, `seed`) and diagnose the run
/// against that model: each target's σ and ρ there.
pub fn predict(s: &mut Suggestion, seed: u64) -> anyhow::Result<()> {
    let plan = crate::scenario::parse(&s.text, "suggested scenario", &capabilities())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let (report, bytes) = simulate_in_memory(&plan, seed)?;
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
        RecordingFacts { name: "r.mcap".into(), latitude_deg: 43.6, temp_range_c: (-5.0, 45.0) }
    }

    /// Steps of the suggested scenario that spin at `rate` °/min, and that ramp the chamber.
    fn counts(text: &str, rate: &str) -> (usize, usize) {
        let spins = text.matches(&format!("spin = \"{rate} °/min\"")).count();
        let ramps = text.matches("ramp = \"").count();
        (spins, ramps)
    }

    #[test]
    fn a_rate_squared_term_gets_two_rates_and_no_thermal_ramps() {
        let model = GyroModel::default();
        let s = suggest_for(vec![pair(EffectId::RateSquared, "bias")], &model, &facts())
            .expect("validates")
            .expect("a suggestion");
        // Full turns each way at 10 and at 30 °/min, at constant temperature.
        assert_eq!(counts(&s.text, "30"), (2, 0), "{}", s.text);
        assert_eq!(counts(&s.text, "10").0, 2, "{}", s.text);
        assert!(s.why.iter().any(|w| w.contains("rate² term from the bias")), "{:?}", s.why);
        assert_eq!(s.targets.len(), 1);
    }

    #[test]
    fn a_thermal_term_gets_ramps_at_two_rates_and_no_second_table_rate() {
        let model = GyroModel::default();
        let s = suggest_for(vec![pair(EffectId::ThermalLag, "temp_rate_coeff")], &model, &facts())
            .expect("validates")
            .expect("a suggestion");
        let (spins30, ramps) = counts(&s.text, "30");
        assert_eq!(spins30, 0, "{}", s.text);
        // Up and down at 0.5 and 2 °C/min, in each direction of rotation.
        assert_eq!(ramps, 4, "{}", s.text);
        assert!(s.text.contains("ramp = \"0.5 °C/min\"") && s.text.contains("ramp = \"2 °C/min\""));
        // Over the recording's range (−5..45 °C).
        assert!(s.text.contains("chamber = \"-5 °C\"") && s.text.contains("chamber = \"45 °C\""));
    }

    #[test]
    fn nothing_confounded_suggests_nothing() {
        assert!(suggest_for(Vec::new(), &GyroModel::default(), &facts()).expect("ok").is_none());
    }
}
