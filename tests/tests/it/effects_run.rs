//! Effects beyond the nominal model in a simulated run: a concealed truth effect changes the
//! gyro stream but leaves no trace in `bench.gyro_model`; a nominal one is recorded as
//! `effect.*` keys.

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_physics::effects::{EffectId, Effects};
use bench_recording::Recording;

/// Table at rest, chamber held at 20 °C, 200 s.
fn scenario(effects: &str) -> String {
    format!(
        r#"
[scenario]
name = "effects-test"

[site]
latitude_deg = 45.0

{effects}

[[step]]
label = "record rest"
record = "200 s"
"#
    )
}

fn run(effects: &str) -> Recording {
    let plan = bench::scenario::parse(&scenario(effects), "effects.toml", &capabilities())
        .expect("valid scenario");
    let (report, bytes) = simulate_in_memory(&plan, 1).expect("runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    Recording::from_bytes(&bytes).expect("readable")
}

/// Mean gyro rate over samples with `from_s <= t < to_s` (bench seconds from the first sample).
fn mean_rate(rec: &Recording, from_s: f64, to_s: f64) -> f64 {
    let t0 = rec.gyro.first().map_or(0, |g| g.log_time_ns);
    let xs: Vec<f64> = rec
        .gyro
        .iter()
        .filter(|g| {
            let t = (g.log_time_ns - t0) as f64 * 1e-9;
            (from_s..to_s).contains(&t)
        })
        .map(|g| g.msg.rate_rad_s)
        .collect();
    assert!(xs.len() > 1000, "{} samples in {from_s}..{to_s} s", xs.len());
    xs.iter().sum::<f64>() / xs.len() as f64
}

#[test]
fn a_concealed_bias_step_shows_in_the_stream_but_not_in_the_metadata() {
    let plain = run("");
    let hidden =
        run("[simulation.truth.effects]\nbias_step = { time_s = 100, step_rad_s = 1e-6 }\n");
    let meta_plain = plain.metadata("bench.gyro_model").expect("model recorded");
    let meta_hidden = hidden.metadata("bench.gyro_model").expect("model recorded");
    // Concealed: the recorded model is the same, with no effect key but the simulated table's
    // own ripple (physics the simulator simulates, recorded as nominal).
    assert_eq!(meta_hidden, meta_plain);
    assert!(
        meta_hidden
            .keys()
            .filter(|k| k.starts_with("effect."))
            .all(|k| k.starts_with("effect.rate_ripple.")),
        "{meta_hidden:?}"
    );
    // ...but the stream shows the step: 1e-6 rad/s after 100 s, within noise (the mean of
    // 1900 samples at the default ARW scatters by ~4e-9 rad/s).
    let step = mean_rate(&hidden, 101.0, 199.0) - mean_rate(&hidden, 1.0, 99.0);
    assert!((step - 1e-6).abs() < 3e-8, "step {step:e}");
    let none = mean_rate(&plain, 101.0, 199.0) - mean_rate(&plain, 1.0, 99.0);
    assert!(none.abs() < 3e-8, "no step without the effect: {none:e}");
    // Same seed, same noise: before the step the streams agree sample by sample.
    assert_eq!(plain.gyro[10].msg.rate_rad_s, hidden.gyro[10].msg.rate_rad_s);
}

#[test]
fn nominal_effects_are_recorded_as_effect_keys_and_simulated() {
    let rec = run("[gyro.model.effects]\nonce_per_revolution = { amplitude_rad_s = 2e-8, \
                   phase_rad = 0.5 }\nbias_step = { time_s = 100, step_rad_s = 1e-6 }\n");
    let meta = rec.metadata("bench.gyro_model").expect("model recorded");
    assert_eq!(
        meta.get("effect.once_per_revolution.amplitude_rad_s").map(String::as_str),
        Some("2e-8")
    );
    assert_eq!(meta.get("effect.bias_step.step_rad_s").map(String::as_str), Some("1e-6"));
    let expected = Effects::default()
        .with(EffectId::OncePerRevolution, &[2e-8, 0.5])
        .and_then(|e| e.with(EffectId::BiasStep, &[100.0, 1e-6]))
        // The simulated table's own ripple.
        .and_then(|e| e.with(EffectId::RateRipple, &[1e-5, 16.0, 0.0]))
        .expect("counts fit");
    assert_eq!(Effects::from_metadata(meta), Ok(expected));
    // The contract's keys are all still there.
    for key in bench_physics::gyro_model::GYRO_MODEL_KEYS {
        assert!(meta.contains_key(key), "bench.gyro_model lacks {key}");
    }
    // The nominal effects are the simulator's truth too.
    let step = mean_rate(&rec, 101.0, 199.0) - mean_rate(&rec, 1.0, 99.0);
    assert!((step - 1e-6).abs() < 3e-8, "step {step:e}");
}
