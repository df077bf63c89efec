//! The sim-vs-real workflow: `bench model real.mcap -o m.toml`, `bench run … --gyro-model m.toml
//! --out sim.mcap`, `bench diagnose real.mcap --model sim.mcap`. The simulated recording's
//! model carries the simulated table's ripple (`effect.rate_ripple`, 16 cycles/rev: the
//! table's own motion, which the simulator records as nominal); applied to the real table it
//! was taken for physics the real gyro lacks (`periodic_bias` at 130.9 s on two lab files, the
//! nominal fit worse). The table's motion and the clocks are the diagnosed recording's own
//! ([`bench_physics::effects::Effects::on_the_bench_of`]): a model from elsewhere gives the
//! same names as the file's own. Every preset: `scripts/lab_model_elsewhere.sh`.

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_analysis::diagnose::Diagnosis;
use bench_physics::effects::{EffectId, Effects};
use bench_physics::GyroModel;
use bench_recording::Recording;
use bench_report::diagnose::diagnose_recording;
use bench_report::load::recorded_model;
use bench_tests::lab_fixture;

/// A short simulated run whose gyro is `model` with `effects` (as `bench run --gyro-model`),
/// read back: its recorded model is what `--model sim.mcap` loads.
fn simulated_with(model: &GyroModel, effects: Effects) -> Recording {
    let text =
        "[scenario]\nname = \"short\"\n[site]\nlatitude_deg = 59.94\n\n[[step]]\nwait = \"10 s\"\n";
    let mut plan = bench::scenario::parse(text, "sim.toml", &capabilities()).expect("valid");
    plan.gyro.model = model.clone();
    plan.gyro.model_given = true;
    plan.gyro.effects = effects;
    plan.sim.truth = model.clone();
    plan.sim.truth_effects = effects;
    let (_, bytes) = simulate_in_memory(&plan, 3).expect("runs");
    Recording::from_bytes(&bytes).expect("reads back")
}

fn names(d: &Diagnosis) -> Vec<&'static str> {
    d.findings.iter().filter(|f| f.accepted).map(|f| f.effect.key()).collect()
}

/// `preset` (seed 1, the short procedure) diagnosed against its own model and against the
/// model of a simulation of it: the same names.
fn same_names_with_the_simulations_model(preset: &str) {
    let path = lab_fixture(preset, 1, &[("procedure.length", "short")]);
    let real = Recording::load(&path).expect("reads");
    let own = recorded_model(&real).expect("loads").expect("a recorded model");
    let sim = simulated_with(&own.model, own.effects);
    let from_sim = recorded_model(&sim).expect("loads").expect("a recorded model");
    assert!(
        from_sim.effects.has(EffectId::RateRipple),
        "the simulation records its table's ripple: {:?}",
        from_sim.effects
    );
    let opts = Default::default();
    let alone = diagnose_recording(&real, None, &opts).expect("diagnoses");
    let nominal = Some((from_sim.model, from_sim.effects, "sim.mcap".to_string()));
    let against_sim = diagnose_recording(&real, nominal, &opts).expect("diagnoses");
    assert_eq!(against_sim.nominal.1, own.effects, "{preset}: the real bench's own effects");
    let (a, b) = (&alone.diagnosis, &against_sim.diagnosis);
    assert_eq!(names(b), names(a), "{preset}: {:?}\nvs {:?}", b.findings, a.findings);
    assert_eq!(b.unexplained.len(), a.unexplained.len(), "{preset}: {:?}", b.unexplained);
    assert_eq!(b.rms.nominal, a.rms.nominal, "{preset}: the same nominal residual");
}

#[test]
fn a_lab_null_recording_gives_the_same_names_against_a_simulations_model() {
    same_names_with_the_simulations_model("lab-null");
}

#[test]
fn a_warm_up_and_step_give_the_same_names_against_a_simulations_model() {
    same_names_with_the_simulations_model("effect-warmup-step");
}

#[test]
fn a_periodic_bias_gives_the_same_names_against_a_simulations_model() {
    same_names_with_the_simulations_model("effect-periodic");
}
