//! `bench diagnose` on recordings of the simulated bench: a run whose truth is the nominal
//! model gives no finding; the files it writes load back.

use std::path::PathBuf;

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_analysis::diagnose::{DiagnoseOptions, Diagnosis, Verdict};
use bench_recording::Recording;
use bench_report::diagnose::{diagnose_recording, json};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn simulate_text(text: &str, seed: u64) -> Recording {
    let plan = bench::scenario::parse(text, "test.toml", &capabilities()).expect("valid");
    let (report, bytes) = simulate_in_memory(&plan, seed).expect("runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    Recording::from_bytes(&bytes).expect("reads back")
}

fn scenario(name: &str) -> String {
    std::fs::read_to_string(workspace().join("scenarios").join(name)).expect("scenario")
}

/// The gyro's truth is the nominal model; the simulated table ripples (1e-5 of the rate at 16
/// cycles per revolution, below its 1″ readout) and the recording says so: its
/// `bench.gyro_model` holds the ripple as `effect.rate_ripple.*`, physics the simulator
/// simulated. Nothing is missing; against a nominal model without the ripple, the ripple is
/// all there is to find.
#[test]
fn a_run_whose_gyro_truth_is_the_nominal_model_has_nothing_missing() {
    let rec = simulate_text(&scenario("thermal-short.toml"), 21);
    let started = std::time::Instant::now();
    let out = diagnose_recording(&rec, None, &DiagnoseOptions::default()).expect("diagnoses");
    eprintln!("diagnosed in {:.2} s", started.elapsed().as_secs_f64());
    let d = &out.diagnosis;
    let ripple = bench_physics::effects::EffectId::RateRipple;
    assert!(out.nominal.1.has(ripple), "the table's ripple is recorded as nominal");
    assert!(d.findings.iter().all(|f| !f.accepted), "{:?}", d.findings);
    assert_ne!(d.verdict, Verdict::MissingPhysics);
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let j = json::to_json(&out, "null.mcap");
    assert_eq!(j["version"], 1);
    assert_eq!(j["verdict"], d.verdict.key());

    // The same run against its model without the ripple (the analysis takes the effects it is
    // given; `diagnose_recording` would take the table's ripple from the recording): the ripple
    // is found.
    let (model, mut effects, _) = out.nominal.clone();
    effects.clear(ripple);
    let opts = DiagnoseOptions::default();
    let diagnosis = bench_analysis::diagnose::diagnose(&out.data.series, &model, &effects, &opts)
        .expect("diagnoses");
    let out = bench_report::diagnose::DiagnoseOutcome {
        nominal: (model, effects, "no ripple".to_string()),
        diagnosis,
        resimulated: None,
        ..out
    };
    let d = &out.diagnosis;
    let found: Vec<_> = d.findings.iter().filter(|f| f.accepted).collect();
    let keys: Vec<_> = found.iter().map(|f| f.effect.key()).collect();
    assert_eq!(keys, ["rate_ripple"]);
    let p = |name: &str| {
        let q = found[0].parameters.iter().find(|q| q.name == name).expect("parameter");
        (q.value, q.sigma)
    };
    assert_eq!(p("cycles_per_rev").0, 16.0);
    let (eps, s) = p("relative_amplitude");
    assert!((eps - 1e-5).abs() < 3.0 * s, "ε {eps} ± {s}");
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let j = json::to_json(&out, "null.mcap");
    assert_eq!(j["verdict"], "missing_physics");
    assert!(j["parameter_updates"]["bias"]["sigma"].as_f64().is_some_and(|s| s > 0.0));
    assert_eq!(j["findings"].as_array().map(Vec::len), Some(1));
}

/// The shipped demo recordings say what recordings/README.md says they say.
#[test]
fn the_demo_recordings_diagnose_as_documented() {
    // Every demo's simulated table ripples at 16 cycles per revolution; the recordings carry
    // that ripple as nominal physics (`effect.rate_ripple.*`), so it is not a finding.
    let cases: [(&str, &[&str], Verdict); 3] = [
        ("demo-null.mcap", &[], Verdict::Consistent),
        ("demo-once-per-revolution.mcap", &["once_per_revolution"], Verdict::MissingPhysics),
        ("demo-warm-up-and-step.mcap", &["bias_step", "warm_up"], Verdict::MissingPhysics),
    ];
    for (file, want, verdict) in cases {
        let bytes = std::fs::read(workspace().join("recordings").join(file)).expect("demo file");
        let rec = Recording::from_bytes(&bytes).expect("reads");
        let out = diagnose_recording(&rec, None, &DiagnoseOptions::default()).expect("diagnoses");
        let d = &out.diagnosis;
        let mut found: Vec<_> =
            d.findings.iter().filter(|f| f.accepted).map(|f| f.effect.key()).collect();
        found.sort_unstable();
        assert_eq!(found, want, "{file}");
        assert_eq!(d.verdict, verdict, "{file}");
    }
}

/// A concealed warm-up (3e-7 rad/s, τ 600 s) and bias step (1e-7 rad/s at 3000 s), seed 1:
/// the warm-up is named first with τ bent to 400 s, then rate² (Wald 19.8) and a scale factor
/// vs T (14.9) take the step between them, each passing its own family check, and the step is
/// left at Wald 7.9 < 14.7 judged at the bent τ. Judged with the warm-up's τ fitted again
/// beside it, the step passes (Wald 17.6 > 14.7) and joins, and the two wrong terms hold
/// nothing once it is in (Wald 0.9 and 1.7): they leave, "explained by bias_step". (The build
/// before took the pair out by checking pairs of accepted effects against the library.)
#[test]
fn a_step_two_other_terms_took_between_them_is_named_and_they_are_not() {
    let d = &warm_up_and_step(1);
    assert_eq!(accepted_keys(d), ["bias_step", "warm_up"], "{:?}", d.findings);
    let step = d.findings.iter().find(|f| f.effect.key() == "bias_step").expect("the step");
    let p = |name: &str| {
        let q = step.parameters.iter().find(|q| q.name == name).expect("parameter");
        (q.value, q.sigma)
    };
    let (size, s) = p("step_rad_s");
    assert!((size - 1e-7).abs() < 3.0 * s, "step {size} ± {s}");
    let (at, s) = p("time_s");
    assert!((at - 3000.0).abs() < 3.0 * s.max(10.0), "at {at} ± {s}");
    // The two wrong terms: a rate shape (on this one-|rate| procedure Ω² and |Ω| — rate² and
    // the scale-factor asymmetry — are one shape, and the library tries either) and a scale
    // factor vs T.
    let wrong = |keys: &[&str]| {
        d.findings
            .iter()
            .find(|f| keys.contains(&f.effect.key()))
            .unwrap_or_else(|| panic!("one of {keys:?} among the findings: {:?}", d.findings))
    };
    for t in
        [wrong(&["rate_squared", "scale_factor_asymmetry"]), wrong(&["scale_factor_temperature"])]
    {
        let why = t.rejected_because.as_deref().unwrap_or_default();
        assert!(why.starts_with("explained by bias_step"), "{}: {why}", t.effect.key());
    }
}

/// The same warm-up + step at seeds 10, 13 and 20. The warm-up is named first with τ bent to
/// 240 s (it takes part of the step through the refitted temperature coefficients), and the
/// step's Wald with the bent warm-up in stays under its threshold. The leftovers of the bent
/// model then passed for a 4/rev harmonic (seed 13, Wald 33.0 > 23.3), a time offset (seed
/// 20, 12.9 > 11.4) or a scale factor vs T and a time offset beside a 20 cycles/rev
/// nuisance block reported unexplained (seed 10). With the warm-up's τ fitted again beside
/// it, the step adds 17.4–27.0 of Wald to the model as it stands (thresholds 14.5–14.7); once
/// it is in, the wrong terms
/// and the nuisance block hold nothing. Every parameter within 3σ, τ's σ by linearisation.
#[test]
fn a_step_a_bent_warm_up_hid_is_found_by_fitting_the_warm_up_again() {
    for seed in [10, 13, 20] {
        let d = &warm_up_and_step(seed);
        assert_eq!(accepted_keys(d), ["bias_step", "warm_up"], "seed {seed}: {:?}", d.findings);
        assert!(d.unexplained.is_empty(), "seed {seed}: {:?}", d.unexplained);
        for (key, name, truth) in [
            ("warm_up", "amplitude_rad_s", 3e-7),
            ("warm_up", "time_constant_s", 600.0),
            ("bias_step", "step_rad_s", 1e-7),
            ("bias_step", "time_s", 3000.0),
        ] {
            let f = d.findings.iter().find(|f| f.effect.key() == key).expect(key);
            let q = f.parameters.iter().find(|q| q.name == name).expect(name);
            assert!(
                (q.value - truth).abs() <= 3.0 * q.sigma,
                "seed {seed}: {key}.{name} {} ± {} vs {truth}",
                q.value,
                q.sigma
            );
        }
    }
}

/// `diagnose-demo.toml` with a concealed warm-up (3e-7 rad/s, τ 600 s) and bias step (1e-7 rad/s
/// at 3000 s), simulated at `seed` and diagnosed.
fn warm_up_and_step(seed: u64) -> Diagnosis {
    let text = format!(
        "{}\n[simulation.truth.effects]\nwarm_up = {{ amplitude_rad_s = 3e-7, time_constant_s = \
         600 }}\nbias_step = {{ time_s = 3000, step_rad_s = 1e-7 }}\n",
        scenario("diagnose-demo.toml")
    );
    let rec = simulate_text(&text, seed);
    diagnose_recording(&rec, None, &DiagnoseOptions::default()).expect("diagnoses").diagnosis
}

/// The effects a diagnosis names, sorted.
fn accepted_keys(d: &Diagnosis) -> Vec<&'static str> {
    let mut found: Vec<&str> =
        d.findings.iter().filter(|f| f.accepted).map(|f| f.effect.key()).collect();
    found.sort_unstable();
    found
}
