//! `bench diagnose` on the independent lab writer's null recording (every lab trait, no effect
//! beyond the model): what it holds beyond the model is the lab's stamping — the table's host
//! stamps 12 ms behind its samples, the gyro's 3 ms — so the gyro's time tags are early against
//! the table's by 9 ms. The diagnosis must name that, and nothing else: no other effect, no
//! unexplained window.

use bench_physics::effects::EffectId;
use bench_recording::Recording;
use bench_report::diagnose::diagnose_recording;
use bench_tests::{lab_fixture, lab_truth};
use serde_json::Value;

#[test]
fn a_lab_null_recording_names_only_the_stamping_offset_between_gyro_and_table() {
    // Measured −9.38 ms against the writer's −9.01 ms. The 0.374 ms is the table's angle
    // readout, not the stamps: at 10 °/min read at 10 Hz in 1″ steps every reading advances
    // exactly 60 steps, so each segment's readings carry one constant rounding offset (CCW
    // −0.426″, CW +0.023″ on this procedure, whatever the seed), and at every reversal the
    // 0.449″ between them reads as (0.449″)/(2·10 °/min) = 0.374 ms of offset (noise-free:
    // −9.3789 ms measured, −9.0052 − 0.3737 predicted). The σ now carries it (0.34 ms).
    only_the_stamping_offset("lab-null", 1, &[]);
}

/// The short procedure (~1.7 h, eight 720 s segments): the same stamping offset, and nothing
/// else. Its term lives in the nine bins that hold a start, reversal or stop, 720 s apart; the
/// held-out check's 60 s blocks (a quarter of that support, at least six bins) put all nine in
/// one set when counted on the clock (720 s is 12 blocks), so the offset went unconfirmed and
/// other terms took its spikes (angle harmonics, |Ω_in|, a bias step, unexplained windows).
#[test]
fn a_short_lab_null_recording_names_only_the_stamping_offset() {
    let path = lab_fixture("lab-null", 7, &[("procedure.length", "short")]);
    let truth = truth_of(&path);
    assert_eq!(truth["procedure"]["table_commands"].as_array().map(Vec::len), Some(9));
    let delta_s = stamping_offset_s(&truth);

    let rec = Recording::load(&path).expect("reads");
    let out = diagnose_recording(&rec, None, &Default::default()).expect("diagnoses");
    let d = &out.diagnosis;
    assert_eq!(accepted(d), [EffectId::TimeOffset], "{:?}", d.findings);
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let f = d.findings.iter().find(|f| f.accepted).expect("the finding");
    let (offset, sigma) = param(f, "offset_s");
    // Measured −9.36 ms against the writer's −9.01 ms (the 5 h file: −9.38 ms).
    assert!((offset - delta_s).abs() < 5e-4, "offset {offset} ± {sigma} vs {delta_s}");
    assert!(f.holdout_z > 3.0, "held-out z {}", f.holdout_z);
}

/// A table stamped by its host (no device time) with 10 ms of jitter: the steady lines' ends
/// are then known to ~1e-6 rad, several times the gyro's own noise over a 10 s bin that holds a
/// rate change. With only the gyro's noise in the bins' covariance, those bins' scatter was
/// taken for a bias at every rate change (seeds 2 and 3: `|dΩ/dt|` / speeding-up with Wald
/// 42.5 / 47.7 > 13.0, the offset reported unexplained). With the lines' errors in it
/// (`diagnose::noise::ReferenceLines`) the offset is named alone. The readout's rounding keeps
/// its phase (60 steps a reading), read off the angles: with the old test on the stamps'
/// duration, seed 3's σ lost the readout's 0.34 ms and missed the truth by 6.8σ.
#[test]
fn a_table_stamped_by_its_host_leaves_only_the_stamping_offset() {
    for seed in [2, 3] {
        let sets = [
            ("procedure.length", "short"),
            ("traits.table_device_time", "false"),
            ("traits.jitter_s.table", "0.01"),
        ];
        only_the_stamping_offset("lab-null", seed, &sets);
    }
}

/// The writer's null seed 17: one gyro frame lost in the 10 s bin that holds the reversal at
/// 7319 s (199 samples). The bin's gyro mean is over the covered 9.95 s; its reference was the
/// lines' increment over all 10 s, a whitened residual of 41σ there, and the time offset's
/// family check took it for a bias at every rate change (`|dΩ/dt|`, Wald 124 > 13: seed 45
/// alike, 139): the offset reported unexplained, the 2 seeds in 50 the writer's null study
/// missed. The reference now takes the hole's increment out (`series::make_bins`).
#[test]
fn a_lost_frame_in_a_reversal_bin_is_not_a_bias_at_the_rate_changes() {
    let f = only_the_stamping_offset("lab-null", 17, &[]);
    let family = f.family.as_ref().expect("a family check");
    let strongest = family.strongest.as_ref().expect("members");
    assert!(strongest.wald < strongest.threshold, "{family:?}");
}

/// The randomised study's null seed 3 (writer seed 12, a lab's traits): 0.87 h, one rate of
/// 8.87 °/min, the table read at 2 Hz in 1″ steps. The table rests before its start and after
/// its stop, where every reading is one value of the 1″ grid: each rest line's angle is known
/// only to ±0.5″ (σ = q/√12 = 1.4e-6 rad, 1.4e-7 rad/s over the 10 s bin that holds the start),
/// while the readings' scatter about it is 0. With that left out of the bins' covariance the
/// start bin (−9.6e-8 rad/s, five times a steady bin's scatter) read as "dΩ/dt while speeding
/// up only" (Wald 23.3 > 13.4) and the offset was reported unexplained — 12 of the study's 60
/// nulls. The reference lines now carry the rounding that does not average down
/// (`diagnose::noise::rounding_variance`): here the turning line's ten phases leave it
/// q/(10√12), so the rounding is each line's own, not the motion's.
#[test]
fn a_table_at_rest_read_in_steps_is_not_a_bias_while_speeding_up() {
    let sets = [
        (
            "procedure.legs",
            r#"[{"hold_s": 589.3090131408301}, {"to_c": -16.0, "rate_c_min": 2.907}, {"hold_s": 227}, {"to_c": 5.0, "rate_c_min": 0.804}]"#,
        ),
        ("procedure.rates_deg_min", "[8.87]"),
        ("procedure.rate_deg_min", "8.87"),
        ("procedure.segment_s", "813"),
        ("procedure.first_direction", "ccw"),
        ("gyro.sample_rate_hz", "20.0"),
        ("gyro.thermal_time_constant", "293"),
        ("traits.chamber_rate_hz", "2.0"),
        ("traits.table_rate_hz", "2.0"),
        (
            "traits.chamber_cycling",
            r#"{"enabled": true, "amplitude_c": 0.018, "period_s": 236, "shape": "sine", "duty": 0.401, "phase_s": 587.5}"#,
        ),
    ];
    let f = only_the_stamping_offset("lab-null", 12, &sets);
    let family = f.family.as_ref().expect("a family check");
    let strongest = family.strongest.as_ref().expect("members");
    assert!(strongest.wald < strongest.threshold, "{family:?}");
}

/// Null seed 17 of `scripts/lab_diagnose_study.py random --hours 0.75,1.5` (writer seed 68):
/// a gyro without its own sensor whose coil lags the air by 985 s, the lab's model saying
/// 300 s; 1.4 h at 10 Hz, three rates with rests. With the model's lag the thermal terms
/// followed the air too early and left a transient decaying over ~1000 s after the ramp's
/// end: named a `bias_step` at 2953 s (Wald 33.5 > 17.8). The diagnosis now refits the coil's
/// lag with the nominal parameters (`diagnose::coil_lag`): the offset alone is named, and the
/// lag is a parameter update within 3σ of the writer's.
#[test]
fn a_coil_lag_other_than_the_models_is_a_parameter_not_a_bias_step() {
    let sets = [
        (
            "procedure.legs",
            r#"[{"hold_s": 621.4416664898283}, {"to_c": -27.0, "rate_c_min": 2.062}, {"hold_s": 2312}, {"to_c": 2.0, "rate_c_min": 2.007}]"#,
        ),
        ("procedure.rates_deg_min", "[4.65, 12.38, 25.5]"),
        ("procedure.rate_deg_min", "4.65"),
        ("procedure.segment_s", "829"),
        ("procedure.first_direction", "ccw"),
        ("procedure.stop_s", "259"),
        ("gyro.sample_rate_hz", "10.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "985"),
        ("traits.chamber_rate_hz", "2.0"),
        ("traits.table_rate_hz", "20.0"),
        (
            "traits.chamber_cycling",
            r#"{"enabled": true, "amplitude_c": 0.0491, "period_s": 254, "shape": "sine", "duty": 0.475, "phase_s": 158.7}"#,
        ),
    ];
    let path = lab_fixture("lab-null", 68, &sets);
    let truth = truth_of(&path);
    assert_eq!(truth["config"]["gyro"]["sensor"], Value::Bool(false));
    let rec = Recording::load(&path).expect("reads");
    let out = diagnose_recording(&rec, None, &Default::default()).expect("diagnoses");
    let d = &out.diagnosis;
    assert_eq!(accepted(d), [EffectId::TimeOffset], "{:?}", d.findings);
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let lag = coil_lag(d);
    assert_eq!(lag.nominal, 300.0);
    assert!((lag.fitted - 985.0).abs() < 3.0 * lag.sigma, "{lag:?}");
}

/// Diagnose the writer's `preset` at `seed` with `sets`: only the stamping offset is named,
/// within 3σ of the writer's realised one (σ below 0.5 ms), nothing unexplained. The finding.
fn only_the_stamping_offset(
    preset: &str,
    seed: u64,
    sets: &[(&str, &str)],
) -> bench_analysis::diagnose::Finding {
    let path = lab_fixture(preset, seed, sets);
    let delta_s = stamping_offset_s(&truth_of(&path));
    let rec = Recording::load(&path).expect("reads");
    let out = diagnose_recording(&rec, None, &Default::default()).expect("diagnoses");
    let d = out.diagnosis;
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "seed {seed}: {:?}", d.findings);
    assert!(d.unexplained.is_empty(), "seed {seed}: {:?}", d.unexplained);
    let f = d.findings.into_iter().find(|f| f.accepted).expect("the finding");
    let (offset, sigma) = param(&f, "offset_s");
    assert!(
        (offset - delta_s).abs() < 3.0 * sigma && sigma < 5e-4,
        "seed {seed}: offset {offset} ± {sigma} vs {delta_s}"
    );
    f
}

/// The writer's truth of a fixture.
/// The writer's realised stamping offset of the gyro against the table, s (δ > 0 when the
/// gyro is late), checked to be its 9 ms trait.
fn stamping_offset_s(truth: &Value) -> f64 {
    let realised = &truth["traits"]["realised_stamp_offset_s"];
    let mean = |ch: &str| realised[ch]["mean"].as_f64().expect("realised stamp offset");
    let delta_s = mean("gyro") - mean("table");
    assert!((delta_s + 0.009).abs() < 1e-4, "the writer's traits: {delta_s}");
    delta_s
}

fn truth_of(path: &std::path::Path) -> Value {
    serde_json::from_slice(&std::fs::read(lab_truth(path)).expect("truth")).expect("truth JSON")
}

fn diagnose(preset: &str) -> (bench_analysis::diagnose::Diagnosis, Value) {
    diagnose_with(preset, 1, &[])
}

/// The writer's `preset` at `seed` with `sets` ([`lab_fixture`]), diagnosed against its own
/// model; with its truth.
fn diagnose_with(
    preset: &str,
    seed: u64,
    sets: &[(&str, &str)],
) -> (bench_analysis::diagnose::Diagnosis, Value) {
    let path = lab_fixture(preset, seed, sets);
    let truth = truth_of(&path);
    let rec = Recording::load(&path).expect("reads");
    let out = diagnose_recording(&rec, None, &Default::default()).expect("diagnoses");
    (out.diagnosis, truth)
}

fn accepted(d: &bench_analysis::diagnose::Diagnosis) -> Vec<EffectId> {
    d.findings.iter().filter(|f| f.accepted).map(|f| f.effect).collect()
}

/// The effects `d` names, in key order, asserted to be `want` (in key order too).
fn assert_named(d: &bench_analysis::diagnose::Diagnosis, want: &[EffectId]) {
    let mut named = accepted(d);
    named.sort_by_key(|id| id.key());
    assert_eq!(named, want, "{:?} {:?}", d.findings, d.unexplained);
}

/// The coil's lag as `d` refitted it.
fn coil_lag(d: &bench_analysis::diagnose::Diagnosis) -> &bench_analysis::diagnose::ParameterUpdate {
    d.parameter_updates
        .iter()
        .find(|u| u.key == bench_physics::ModelKey::ThermalTimeConstant && u.held.is_none())
        .expect("the coil's lag refitted")
}

fn param(f: &bench_analysis::diagnose::Finding, name: &str) -> (f64, f64) {
    let p = f.parameters.iter().find(|p| p.name == name).expect(name);
    (p.value, p.sigma)
}

/// What `--suggest-scenario` needs to know of the recording `d` diagnosed.
fn facts(name: &str, d: &bench_analysis::diagnose::Diagnosis) -> bench::suggest::RecordingFacts {
    let temps = &d.series.temp_c;
    bench::suggest::RecordingFacts {
        name: name.into(),
        latitude_deg: 43.56,
        temp_range_c: (
            temps.iter().copied().fold(f64::INFINITY, f64::min),
            temps.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ),
        gyro_sensor: true,
        duration_s: d.series.time_s.last().copied().unwrap_or(0.0),
    }
}

/// The suggested scenario simulated with `effects` (TOML of `[simulation.truth.effects]`)
/// concealed, and diagnosed.
fn diagnose_suggestion_with(
    s: &bench::suggest::Suggestion,
    effects: &str,
) -> bench_analysis::diagnose::Diagnosis {
    let text = format!("{}\n[simulation.truth.effects]\n{effects}\n", s.text);
    let plan = bench::scenario::parse(&text, "suggested", &bench::simulate::capabilities())
        .expect("validates");
    let (report, bytes) = bench::runner::simulate_in_memory(&plan, 3).expect("runs");
    assert!(report.completed(), "{}", report.outcome);
    let run = Recording::from_bytes(&bytes).expect("reads");
    diagnose_recording(&run, None, &Default::default()).expect("diagnoses").diagnosis
}

/// Issue 14, items 1 and 2: a bias at 2 (or 3) cycles per revolution on 120° arcs, where
/// `sin θ` takes up most of `sin 2θ`, is named by its harmonic with its amplitude and phase
/// within 3σ, judged the gyro's (not the table's rate ripple), and its family check passes:
/// never `once_per_revolution`.
#[test]
fn a_bias_at_two_or_three_cycles_per_revolution_is_named_by_its_harmonic() {
    for (preset, key, k) in
        [("effect-2rev", "twice_per_rev", 2.0), ("effect-3rev", "three_per_rev", 3.0)]
    {
        let (d, truth) = diagnose(preset);
        let found = accepted(&d);
        assert_eq!(
            found,
            [EffectId::TimeOffset, EffectId::AngleHarmonic],
            "{preset}: {:?}",
            d.findings
        );
        assert!(d.unexplained.is_empty(), "{preset}: {:?}", d.unexplained);
        let f = d.findings.iter().find(|f| f.effect == EffectId::AngleHarmonic).expect("found");
        let t = &truth["effects"][key]["parameters"];
        let (amp, phase) = (t["amplitude"].as_f64().expect("a"), t["phase"].as_f64().expect("φ"));
        assert_eq!(param(f, "cycles_per_rev").0, k, "{preset}");
        let (a, sa) = param(f, "amplitude_rad_s");
        assert!((a - amp).abs() < 3.0 * sa, "{preset}: amplitude {a} ± {sa} vs {amp}");
        let (p, sp) = param(f, "phase_rad");
        assert!((p - phase).abs() < 3.0 * sp, "{preset}: phase {p} ± {sp} vs {phase}");
        let c = f.family.as_ref().expect("family checked");
        assert!(c.passed && c.members >= 10, "{preset}: {c:?}");
        let r = f.rate_dependence.as_ref().expect("rate dependence");
        assert_eq!(r.verdict(), "gyro", "{preset}: {r:?}");
        assert!(r.gyro_wald > 10.0 * r.threshold && r.ripple_wald < r.threshold, "{r:?}");
        assert!(!found.contains(&EffectId::OncePerRevolution));
    }
}

/// Issue 14, item 1: a 900 s sawtooth is no sinusoid. The periodic bias that fits its
/// fundamental leaves its harmonics in the residual, so it is not named: the structure is
/// reported unexplained, with the harmonic that shows it (450 s), and no other effect (a
/// rate ripple or angle harmonic at an alias of a higher harmonic) is named for what is left.
#[test]
fn a_sawtooth_is_reported_unexplained_with_its_harmonic_not_named_a_sinusoid() {
    let (d, _) = diagnose("effect-sawtooth");
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let periodic = d.findings.iter().find(|f| f.effect == EffectId::PeriodicBias).expect("tried");
    let c = periodic.family.as_ref().expect("family checked");
    assert!(!c.passed, "{c:?}");
    let m = c.strongest.as_ref().expect("member");
    assert!(m.name.contains("(P/2)") && m.wald > 5.0 * m.threshold, "{m:?}");
    let (p, sp) = param(periodic, "period_s");
    assert!((p - 900.0).abs() < 3.0 * sp.max(1.0), "period {p} ± {sp}");
    assert_eq!(d.unexplained.len(), 1, "{:?}", d.unexplained);
    let u = &d.unexplained[0];
    assert!(u.correlates_with.starts_with("time, period 450 s (P/2)"), "{}", u.correlates_with);
    assert!(u.correlates_with.contains("periodic_bias-like"), "{}", u.correlates_with);
}

/// Issue 14, item 2: a rate ripple of the table (3e-5 of the rate at 12 cycles/rev) is told
/// apart from a bias of the gyro at the same harmonic: the rate-proportional term carries it.
/// It is named with its size and phase within 3σ and nothing is left: the table's own ripple
/// fit (from the angle readings) no longer leaks one 12-cycle ripple into every harmonic of
/// 120° arcs (it took 8.4e-5 at 12 cycles and 4.6e-5 at 24 out of the reference, which left
/// 5.5e-5 in anti-phase and a 24-cycle residual of Wald 9424).
#[test]
fn a_table_rate_ripple_is_told_apart_from_a_gyro_harmonic() {
    let (d, truth) = diagnose("effect-ripple");
    assert_eq!(accepted(&d), [EffectId::TimeOffset, EffectId::RateRipple], "{:?}", d.findings);
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let f = d.findings.iter().find(|f| f.effect == EffectId::RateRipple).expect("tried");
    assert_eq!(param(f, "cycles_per_rev").0, 12.0);
    let t = &truth["effects"]["rate_ripple"]["parameters"];
    let (eps, phase) =
        (t["relative_amplitude"].as_f64().expect("ε"), t["phase"].as_f64().expect("φ"));
    let (e, se) = param(f, "relative_amplitude");
    assert!((e - eps).abs() < 3.0 * se, "ε {e} ± {se} vs {eps}");
    let (p, sp) = param(f, "phase_rad");
    assert!((p - phase).abs() < 3.0 * sp, "phase {p} ± {sp} vs {phase}");
    let r = f.rate_dependence.as_ref().expect("rate dependence");
    assert_eq!(r.verdict(), "table", "{r:?}");
    assert!(r.ripple_wald > 100.0 * r.threshold && r.gyro_wald < r.threshold, "{r:?}");
    assert!(!accepted(&d).contains(&EffectId::AngleHarmonic), "{:?}", d.findings);
}

/// A rate² term on the lab writer's procedure (one |rate|, 10 °/min) is known only from the
/// table's rests (120 s before the first spin-up, 60 s after the stop): while the table turns,
/// `Ω²` is a constant the bias takes. So is `|Ω|`, a scale-factor asymmetry: on this design the
/// two are the same two levels, and the diagnosis says so — "not told apart", with the run
/// that separates them — instead of naming one (before the asymmetry joined the library it was
/// named rate², right by luck: the writer's asymmetry was named rate² the same way).
#[test]
fn a_rate_squared_term_on_one_rate_is_not_told_from_an_asymmetry() {
    let (d, _) = diagnose("effect-rate-squared");
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let told: Vec<&str> = d
        .unexplained
        .iter()
        .map(|u| u.correlates_with.as_str())
        .filter(|c| c.starts_with("not told apart"))
        .collect();
    assert_eq!(told.len(), 1, "{:?}", d.unexplained);
    assert!(
        told[0].contains("rate_squared") && told[0].contains("scale_factor_asymmetry"),
        "{told:?}"
    );
    assert!(told[0].contains("the run that separates them: full revolutions"), "{told:?}");
}

/// Issue 26: a bias drifting linearly in time (the writer's 1e-10 rad/s², 0.074 °/h per hour,
/// on the short procedure) was named a warm-up plus a bias step; it is `bias_drift`, alone
/// beside the lab's stamping offset, its slope within 3σ.
#[test]
fn a_linear_bias_drift_is_named_with_its_slope() {
    let (d, truth) = diagnose_with("short-lab-null", 2, &[("effects.bias_drift.enabled", "true")]);
    assert_eq!(accepted(&d), [EffectId::TimeOffset, EffectId::BiasDrift], "{:?}", d.findings);
    let f = d.findings.iter().find(|f| f.effect == EffectId::BiasDrift).expect("found");
    let want = truth["effects"]["bias_drift"]["parameters"]["slope"].as_f64().expect("slope");
    let (v, s) = param(f, "slope_rad_s2");
    assert!((v - want).abs() <= 3.0 * s && s < 0.2 * want, "{v} ± {s} vs {want}");
}

/// Issue 26: a lab's model that leaves Earth's rate out, and whose bias is off by the writer's
/// 0.03 °/h as well (far more than the shift's σ): the bias shift is named Earth's rate, with
/// the comparison against Ω_E·sin(latitude) at the writer's site (43.56°).
#[test]
fn earth_rate_left_out_of_the_model_is_named_with_the_comparison() {
    let (d, _) = diagnose_with("short-lab-null", 5, &[("nominal_earth_rate", "false")]);
    let f = d.findings.iter().find(|f| f.effect == EffectId::EarthRate).expect("Earth's rate");
    let remark = f.remark.as_deref().expect("the comparison");
    assert!(remark.contains("15.04 °/h × sin 43.6°"), "{remark}");
    assert!(remark.contains("of the model's own bias"), "{remark}");
    let (lat, s) = param(f, "latitude_deg");
    assert!((lat - 43.56).abs() < 0.5 && s > 0.0, "{lat} ± {s}");
}

/// The writer's warm-up (3e-7 rad/s, τ 900 s) with a bias step (1e-7 rad/s) three time
/// constants in, at 2748 s, seed 1. The previous build named the warm-up and missed the step:
/// judged at the warm-up's grid value the step stayed under its threshold. Fitted with the
/// warm-up's τ fitted again beside it, and judged by what it adds to the model as it stands,
/// it is named; both effects' parameters within 3σ of the writer's.
#[test]
fn a_bias_step_after_a_warm_up_is_named_with_the_warm_up_fitted_again() {
    let (d, truth) = diagnose("effect-warmup-step");
    let mut got = accepted(&d);
    got.sort();
    assert_eq!(
        got,
        [EffectId::TimeOffset, EffectId::WarmUp, EffectId::BiasStep],
        "{:?}",
        d.findings
    );
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let fx = &truth["effects"];
    let num = |v: &Value| v.as_f64().expect("a number");
    for (id, name, want) in [
        (EffectId::WarmUp, "amplitude_rad_s", num(&fx["warm_up"]["parameters"]["amplitude"])),
        (EffectId::WarmUp, "time_constant_s", num(&fx["warm_up"]["parameters"]["time_constant_s"])),
        (EffectId::BiasStep, "step_rad_s", num(&fx["bias_step"]["parameters"]["step"])),
        (EffectId::BiasStep, "time_s", num(&fx["bias_step"]["time_s"])),
    ] {
        let f = d.findings.iter().find(|f| f.effect == id).expect("found");
        let (v, s) = param(f, name);
        assert!((v - want).abs() <= 3.0 * s, "{}.{name}: {v} ± {s} vs {want}", id.key());
    }
}

/// Issue 14, item 3: the writer's temperature-gradient term `c·(T_air − T_gyro)` is exactly
/// `c·τ·dT/dt` for a first-order coil: the refit of `temp_rate_coeff` takes it (to the writer's
/// effective coefficient within 3σ), and the diagnosis says that a thermal lag — the library's
/// term of that shape — cannot be told apart from `temp_rate_coeff` here, with its bound.
#[test]
fn a_term_collinear_with_a_parameter_is_stated_with_its_bound() {
    let (d, truth) = diagnose("effect-gradient");
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let eff = truth["effects"]["temperature_gradient"]["effective_temp_rate_coeff"]
        .as_f64()
        .expect("effective k_dt");
    let u = d
        .parameter_updates
        .iter()
        .find(|u| u.key == bench_physics::ModelKey::TempRateCoeff)
        .expect("k_dt");
    assert!((u.fitted - eff).abs() < 3.0 * u.sigma, "k_dt {} ± {} vs {eff}", u.fitted, u.sigma);
    let pairs = d.identifiability();
    let c = pairs
        .iter()
        .find(|c| c.effect == EffectId::ThermalLag && c.with == ["temp_rate_coeff"])
        .unwrap_or_else(|| panic!("{:?}", d.identifiability()));
    assert!(c.rho >= 0.9 && c.rho < 1.0 && !c.effect_accepted, "{c:?}");
    assert!(c.bound > 0.0 && c.sigma_inflation > 2.0, "{c:?}");
    let caveats = bench_report::diagnose::verdict_caveats(&d);
    assert!(
        caveats
            .iter()
            .any(|s| s.starts_with("thermal_lag cannot be told apart from temp_rate_coeff")),
        "{caveats:?}"
    );
    // Nothing on the null file is that collinear but the same pair.
    let (null, _) = diagnose("lab-null");
    assert!(
        null.identifiability().iter().all(|c| c.effect == EffectId::ThermalLag),
        "{:?}",
        null.identifiability()
    );
}

/// Issue 14, item 4: the experiment that separates them. On the gradient file the diagnosis
/// cannot tell a coil lag from `temp_rate_coeff`; the suggested scenario (ramps at two rates,
/// holds after each) validates against the simulated bench, its predicted separation is better
/// (σ and ρ of the lag at the recording's τ, simulated under the diagnosed model), and a
/// simulation of it with a concealed 400 s coil lag has the lag named, τ and gain within 3σ.
#[test]
fn the_suggested_scenario_separates_a_lag_from_temp_rate_coeff() {
    let (d, _) = diagnose("effect-gradient");
    let mut s =
        bench::suggest::suggest(&d, &facts("gradient.mcap", &d)).expect("builds").expect("one");
    bench::suggest::predict(&mut s, 1).expect("predicts");
    let t = s
        .targets
        .iter()
        .find(|t| t.before.effect == EffectId::ThermalLag && t.before.with == ["temp_rate_coeff"])
        .expect("the lag is a target");
    let after = t.after.as_ref().expect("judged on the suggestion");
    assert!(after.rho < t.before.rho && after.sigma < t.before.sigma, "{t:?}");

    // The proof: the suggestion simulated with a concealed lag names it.
    let d = diagnose_suggestion_with(&s, "thermal_lag = { time_constant_s = 400 }");
    let f = d
        .findings
        .iter()
        .find(|f| f.accepted && f.effect == EffectId::ThermalLag)
        .unwrap_or_else(|| panic!("{:?}", d.findings));
    let (tau, s_tau) = param(f, "time_constant_s");
    let (gain, s_gain) = param(f, "gain");
    assert!((tau - 400.0).abs() <= 3.0 * s_tau, "τ {tau} ± {s_tau}");
    assert!((gain - 1.0).abs() <= 3.0 * s_gain, "gain {gain} ± {s_gain}");
}

/// Issue 31: `--suggest-scenario` on a 5 h recording of a gyro without its own sensor whose
/// coil lag the diagnosis cannot tell from `temp_rate_coeff + temp_coeff` (lab writer's
/// `lab-nosensor`, seed 2: ρ 0.924). Main offered an 11 h 54 min run soaking on
/// `source = "gyro"`, its own prediction "not testable". The suggestion is now a designed
/// sweep run with no soak on a sensor the gyro lacks; it is offered only because, simulated
/// with a gyro without a sensor and diagnosed, it lowers σ and ρ of the pair; it is at most
/// three times the recording's length and it validates.
#[test]
fn the_suggestion_for_a_gyro_without_a_sensor_lowers_what_it_separates_and_soaks_on_no_sensor() {
    use bench::suggest::{offer, Offer};
    let path = lab_fixture("lab-nosensor", 2, &[]);
    let rec = Recording::load(&path).expect("reads");
    let out = diagnose_recording(&rec, None, &Default::default()).expect("diagnoses");
    assert!(!out.data.gyro_sensor());
    let d = &out.diagnosis;
    let facts = bench::suggest::RecordingFacts { gyro_sensor: false, ..facts("nosensor.mcap", d) };
    let s = match offer(d, &facts, &bench::simulate::capabilities(), 1).expect("offers") {
        Offer::Lowers(s) => s,
        other => panic!("{other:?}"),
    };
    let t = s
        .targets
        .iter()
        .find(|t| t.before.effect == EffectId::ThermalLag)
        .unwrap_or_else(|| panic!("{:?}", s.targets));
    let after = t.after.as_ref().expect("judged on the suggestion");
    assert!(after.sigma < t.before.sigma && after.rho < t.before.rho, "{t:?}");
    assert!(!s.text.contains("source = \"gyro\""), "{}", s.text);
    assert!(!s.gyro_sensor);
    assert!(
        s.duration_s <= 3.0 * facts.duration_s + 1.0,
        "{} vs {}",
        s.duration_s,
        facts.duration_s
    );
    bench::scenario::parse(&s.text, "suggested", &bench::simulate::capabilities())
        .expect("bench validate passes");
}

/// Issue 14, "never a wrong name": on 120° arcs a 5e-8 rad/s once-per-revolution bias and a
/// twice-per-revolution one explain each other (seed 8 fitted `angle_harmonic` k = 2 at
/// 2.0e-8 ± 0.24e-8 rad/s before the rival check). The diagnosis now names neither: the
/// per-revolution structure is unexplained, with the harmonic it cannot be told apart from.
#[test]
fn per_revolution_harmonics_that_cannot_be_told_apart_are_not_named() {
    let (d, _) = diagnose_with("effect-1rev", 8, &[]);
    let found = accepted(&d);
    assert!(!found.contains(&EffectId::AngleHarmonic), "{:?}", d.findings);
    let named_1rev = found.contains(&EffectId::OncePerRevolution);
    let told = d.unexplained.iter().any(|u| u.correlates_with.contains("not told apart"));
    assert!(named_1rev || told, "{:?} / {:?}", d.findings, d.unexplained);
}

/// Issue 14 item 4 for the per-revolution template: where 120° arcs left a 1/rev bias "not
/// told apart", the suggested scenario (full turns at two rates) simulated with that bias
/// concealed names it, amplitude and phase within 3σ.
#[test]
fn the_suggested_scenario_names_a_once_per_revolution_bias_the_arcs_could_not() {
    let (d, _) = diagnose_with("effect-1rev", 8, &[]);
    let s = bench::suggest::suggest(&d, &facts("1rev.mcap", &d)).expect("builds").expect("one");
    assert!(s.text.contains("full revolutions"), "{}", s.text);
    let (amplitude, phase) = (5e-8, 0.7);
    let d = diagnose_suggestion_with(
        &s,
        &format!("once_per_revolution = {{ amplitude_rad_s = {amplitude}, phase_rad = {phase} }}"),
    );
    let f = d
        .findings
        .iter()
        .find(|f| f.accepted && f.effect == EffectId::OncePerRevolution)
        .unwrap_or_else(|| panic!("{:?} / {:?}", d.findings, d.unexplained));
    let (a, s_a) = param(f, "amplitude_rad_s");
    let (p, s_p) = param(f, "phase_rad");
    assert!((a - amplitude).abs() <= 3.0 * s_a, "amplitude {a} ± {s_a}");
    let dp =
        (p - phase + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    assert!(dp.abs() <= 3.0 * s_p, "phase {p} ± {s_p}");
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
}

/// Issue 26, physics outside the library: a kink in k_t (the writer's `kt_kink`, 2e-8 rad/s
/// per °C above 40 °C, on the short procedure's 0..50 °C) is half a V in temperature, and
/// `(T − T0)²` takes most of it: main names `temperature_quadratic` (ΔBIC 37). The
/// temperature family now holds the hinges `max(0, T − T_k)` at the recording's temperature
/// deciles (`diagnose::hinge`); the hinge near the knot explains the data better than the
/// quadratic, each against its own threshold, and the quadratic beside it keeps nothing: the
/// quadratic is not named, and the structure is reported unexplained as a change of k_t.
#[test]
fn a_kink_in_k_t_is_not_named_a_temperature_quadratic() {
    let sets = [
        ("effects.kt_kink.enabled", "true"),
        ("effects.kt_kink.temp_c", "40"),
        ("effects.kt_kink.coeff", "2e-8"),
    ];
    let (d, _) = diagnose_with("short-lab-null", 1, &sets);
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let kink = d.unexplained.iter().find(|u| u.correlates_with.starts_with("k_t changes near"));
    assert!(kink.is_some(), "{:?}", d.unexplained);
}

/// Issue 26, physics outside the library: a burst of white noise four times the gyro's for
/// 900 s from the middle of the short procedure (the writer's `noise_burst`). The previous
/// build said nothing of it. Each 60 s window's scatter is now tested against the rest of the
/// run's (`diagnose::scatter`): the burst is reported unexplained with its factor and its
/// span, its bins are deweighted by their own scatter, and only the lab's stamping offset is
/// named.
#[test]
fn a_burst_of_noise_is_reported_unexplained_with_its_factor_and_span() {
    let (d, truth) = diagnose_with("short-lab-null", 1, &[("effects.noise_burst.enabled", "true")]);
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let burst: Vec<_> =
        d.unexplained.iter().filter(|u| u.correlates_with.starts_with("noise ")).collect();
    assert_eq!(burst.len(), 1, "{:?}", d.unexplained);
    let (a, b) = burst[0].windows_s[0];
    let start = 0.5 * truth["duration_s"].as_f64().expect("duration");
    assert!((a - start).abs() < 90.0 && (b - (start + 900.0)).abs() < 90.0, "{a}..{b} vs {start}");
    let factor: f64 = burst[0].correlates_with["noise ".len()..]
        .split('×')
        .next()
        .and_then(|x| x.parse().ok())
        .expect("the factor");
    assert!((factor - 4.0).abs() < 0.6, "{}", burst[0].correlates_with);
    assert_eq!(d.unexplained.len(), 1, "{:?}", d.unexplained);
}

/// Issue 26: a warm-up whose time constant is a third of the run (the randomised study's
/// effect seed 26: τ 1923 s, −0.033 °/h, in 1.4 h of ramps at three table rates, a 20 Hz gyro,
/// a lab's traits) is a decay the run cannot tell from a linear drift. It was named
/// `bias_drift`: the declared rivals with a grid (warm-up, step) were looked up among columns
/// never computed and skipped. Now "not told apart: bias_drift or warm_up", with the run that
/// separates them, and neither named.
#[test]
fn a_warm_up_as_slow_as_the_run_is_not_told_apart_from_a_drift() {
    let legs = r#"[{"hold_s":658.7643059951172},{"to_c":-21.0,"rate_c_min":2.214},{"to_c":29.0,"rate_c_min":1.479},{"hold_s":526},{"to_c":17.0,"rate_c_min":1.045}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[20.16,21.55,3.02]"),
        ("procedure.rate_deg_min", "20.16"),
        ("procedure.segment_s", "568"),
        ("procedure.first_direction", "cw"),
        ("gyro.sample_rate_hz", "20.0"),
        ("gyro.sensor", "true"),
        ("gyro.thermal_time_constant", "709"),
        ("traits.chamber_rate_hz", "10.0"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0178"),
        ("traits.chamber_cycling.period_s", "257"),
        ("traits.chamber_cycling.shape", "triangle"),
        ("traits.chamber_cycling.duty", "0.528"),
        ("traits.chamber_cycling.phase_s", "262.9"),
        ("traits.table_rate_hz", "10.0"),
        ("effects.warm_up.enabled", "true"),
        ("effects.warm_up.amplitude", "-1.616048267451e-07"),
        ("effects.warm_up.time_constant_s", "1923"),
    ];
    let (d, _) = diagnose_with("lab-null", 105, &sets);
    assert_eq!(accepted(&d), [EffectId::TimeOffset], "{:?}", d.findings);
    let apart = d
        .unexplained
        .iter()
        .find(|u| u.correlates_with.contains("not told apart: bias_drift or warm_up"))
        .unwrap_or_else(|| panic!("{:?}", d.unexplained));
    assert!(apart.correlates_with.contains("a longer run"), "{}", apart.correlates_with);
}

/// Issue 26: on one ramp from 20 to −10 °C and a long plateau (the randomised study's effect
/// seed 80: a bias step, a gyro without its own sensor) a temperature quadratic is almost
/// `temp_coeff` (ρ = 0.996). It was named beside the step with 0.0000007 ± 0.0000045
/// °/h/°C². Now the step is named, the quadratic is "not told apart" from `temp_coeff`, and
/// `temp_coeff` is held at the nominal model's value, never written as measured.
#[test]
fn an_effect_a_parameter_takes_over_is_not_named_and_the_parameter_is_held() {
    let legs = r#"[{"hold_s":587.915814560916},{"to_c":-10.0,"rate_c_min":3.912},{"hold_s":3387}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[22.58]"),
        ("procedure.rate_deg_min", "22.58"),
        ("procedure.segment_s", "795"),
        ("procedure.first_direction", "ccw"),
        ("gyro.sample_rate_hz", "20.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "237"),
        ("effects.bias_step.enabled", "true"),
        ("effects.bias_step.step", "1.304161739139859e-07"),
        ("effects.bias_step.time_fraction", "0.725"),
    ];
    let (d, truth) = diagnose_with("lab-clean", 321, &sets);
    assert_eq!(accepted(&d), [EffectId::BiasStep], "{:?}", d.findings);
    let f = d.findings.iter().find(|f| f.effect == EffectId::BiasStep).expect("the step");
    let (v, s) = param(f, "step_rad_s");
    let want = truth["effects"]["bias_step"]["parameters"]["step"].as_f64().expect("step");
    assert!((v - want).abs() <= 3.0 * s, "step {v} ± {s} vs {want}");
    assert!(
        d.unexplained.iter().any(|u| u
            .correlates_with
            .contains("not told apart: temperature_quadratic or temp_coeff")),
        "{:?}",
        d.unexplained
    );
    let kt = d
        .parameter_updates
        .iter()
        .find(|u| u.key == bench_physics::ModelKey::TempCoeff)
        .expect("k_t");
    assert!(kt.held.is_some() && kt.fitted == kt.nominal, "{kt:?}");
}

/// Issue 26: a periodic bias of 1.5 cycles in the run (the randomised study's effect seed 32:
/// 0.017 °/h at 2171 s in 0.9 h, one ramp and a long plateau, a 100 Hz gyro without its own
/// sensor) is searched from four cycles only, and a bias step was named for it. A sinusoid
/// that slow is now every slow shape's rival, fitted down to 1.5 cycles: beside it the step
/// keeps Wald 1.7, and since a period under four cycles is never named (nor searched for
/// again), neither is named — "not told apart", and nothing else named for what is left (a
/// rate² and a scale-factor asymmetry were, when the step gave way to a periodic bias the
/// search could not find).
#[test]
fn a_periodic_bias_of_one_and_a_half_cycles_is_not_named_a_bias_step() {
    let legs = r#"[{"hold_s":671.7260370087192},{"to_c":-9.0,"rate_c_min":3.35},{"hold_s":2046}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[19.1,19.69]"),
        ("procedure.rate_deg_min", "19.1"),
        ("procedure.segment_s", "336"),
        ("gyro.sample_rate_hz", "100.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "555"),
        ("effects.periodic_bias.enabled", "true"),
        ("effects.periodic_bias.amplitude", "8.166734142144225e-08"),
        ("effects.periodic_bias.period_s", "2171"),
    ];
    let (d, _) = diagnose_with("lab-clean", 129, &sets);
    assert!(accepted(&d).is_empty(), "{:?}", d.findings);
    let apart: Vec<_> = d
        .unexplained
        .iter()
        .filter(|u| u.correlates_with.starts_with("not told apart: bias_step or periodic_bias"))
        .collect();
    assert_eq!(apart.len(), 1, "{:?}", d.unexplained);
    assert!(apart[0].correlates_with.contains("a few cycles in the run"), "{:?}", apart[0]);
}

/// Study seed 84 (`scripts/lab_diagnose_study.py random --classes effect --hours 0.75,1.5`, the
/// lab writer's seed 337): a 200 Hz gyro, one hold, a ramp to −40 °C and a 47-minute hold in
/// 1.26 h at one table rate (19.37 °/min), a periodic bias of 2101 s concealed — 2.2 cycles,
/// under the four a period is searched for with. bench named a bias step, a scale factor vs
/// temperature, a periodic bias at 704 s and a once-per-revolution term (the writer's true
/// model named the same): the periodic bias was in the model already at 704 s, and a rival in
/// the model was never judged. Judged at its best value in place of its 704 s instance, the
/// periodic bias explains what the once-per-revolution term holds (one revolution lasts
/// 1115 s) and, once in, the step, the scale factor and the 704 s cycle too: nothing is named.
#[test]
fn a_rival_in_the_model_at_another_value_is_judged_at_its_best_one() {
    let legs =
        r#"[{"hold_s":783.5700169064482},{"to_c":-40.0,"rate_c_min":3.789},{"hold_s":2812}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[19.37]"),
        ("procedure.rate_deg_min", "19.37"),
        ("procedure.segment_s", "833"),
        ("procedure.stop_s", "259"),
        ("gyro.sample_rate_hz", "200.0"),
        ("gyro.thermal_time_constant", "1012"),
        ("effects.periodic_bias.enabled", "true"),
        ("effects.periodic_bias.amplitude", "9.084036482751955e-08"),
        ("effects.periodic_bias.period_s", "2101"),
    ];
    let (d, _) = diagnose_with("lab-clean", 337, &sets);
    assert_named(&d, &[]);
    let apart: Vec<_> = d
        .unexplained
        .iter()
        .filter(|u| u.correlates_with.starts_with("not told apart: "))
        .collect();
    assert_eq!(apart.len(), 1, "{:?}", d.unexplained);
    assert!(apart[0].correlates_with.contains(" or periodic_bias "), "{:?}", apart[0]);
}

/// Study seed 243 (`scripts/lab_diagnose_study.py random --classes effect --hours 0.75,1.5`,
/// the lab writer's seed 973): a gyro without its own sensor whose coil lags the air by 1132 s
/// (the lab's model says 300 s), one hold and two ramps in 1.3 h, a scale-factor asymmetry
/// concealed. The coil never settles, and the lab's lag is not told from another: at 300 s a
/// bias step passed (Wald 26.8) and was named; refitted without the step the lag moves to
/// about 1470 s (its move's Wald 22.7 > 6.6) and the step keeps Wald 1.4. So neither is named:
/// "not told apart: bias_step or the coil's thermal lag", beside the asymmetry's own rivalry
/// with a rate² on turns at one |rate|.
#[test]
fn a_bias_step_the_coils_lag_explains_as_well_is_not_named() {
    let legs = r#"[{"hold_s":552.5772745261374},{"to_c":-22.0,"rate_c_min":3.029},{"hold_s":2139},{"to_c":39.0,"rate_c_min":3.301}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[25.97,26.44,14.0]"),
        ("procedure.rate_deg_min", "25.97"),
        ("procedure.segment_s", "686"),
        ("procedure.stop_s", "215"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "1132"),
        ("traits.chamber_rate_hz", "20.0"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0484"),
        ("traits.chamber_cycling.period_s", "121"),
        ("traits.chamber_cycling.duty", "0.633"),
        ("traits.chamber_cycling.phase_s", "558.7"),
        ("traits.table_rate_hz", "20.0"),
        ("effects.sf_asymmetry.enabled", "true"),
        ("effects.sf_asymmetry.coeff", "1.6074807995215954e-05"),
    ];
    let (d, _) = diagnose_with("lab-null", 973, &sets);
    assert_eq!(accepted(&d), vec![EffectId::TimeOffset], "{:?}", d.findings);
    let apart =
        |start: &str| d.unexplained.iter().filter(|u| u.correlates_with.starts_with(start)).count();
    assert_eq!(
        apart("not told apart: bias_step or the coil's thermal lag"),
        1,
        "{:?}",
        d.unexplained
    );
}

/// Study seed 192 (`lab_diagnose_study.py random --classes effect --hours 0.75,1.5`): a scale
/// factor vs T of 1.09 ppm/°C on a gyro without its own sensor whose coil lags the air by
/// 867 s, where the lab's model says 300 s. As the scale factor's rival the lag is refitted
/// without it; with the scale factor's column held as it was built at 300 s, the refitted lag
/// moved and the stale column kept Wald 10.4 there, so the scale factor was "not told apart"
/// from the lag. Built again at the refitted lag (`coil_lag::Beside`), the column keeps its
/// signal there and the scale factor is named.
#[test]
fn a_scale_factor_vs_temperature_is_judged_at_the_lag_it_is_rivalled_with() {
    let legs = r#"[{"hold_s":780.3787970950315},{"to_c":55.0,"rate_c_min":3.358},{"hold_s":3193}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[11.08,28.23]"),
        ("procedure.rate_deg_min", "11.08"),
        ("procedure.segment_s", "738"),
        ("procedure.stop_s", "84"),
        ("gyro.sample_rate_hz", "50.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "867"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0108"),
        ("traits.chamber_cycling.period_s", "300"),
        ("traits.chamber_cycling.duty", "0.391"),
        ("traits.chamber_cycling.phase_s", "552.6"),
        ("effects.sf_temperature.enabled", "true"),
        ("effects.sf_temperature.coeff_per_c", "1.0934663301855697e-06"),
    ];
    let (d, _) = diagnose_with("lab-null", 769, &sets);
    assert_named(&d, &[EffectId::ScaleFactorTemperature, EffectId::TimeOffset]);
    assert!(
        !d.unexplained.iter().any(|u| u.correlates_with.contains("scale_factor_temperature")),
        "{:?}",
        d.unexplained
    );
}

/// Study seed 242 (`lab_diagnose_study.py random --classes effect --hours 0.75,1.5`): a rate²
/// of −170 ppm/(°/s) on a gyro without its own sensor whose coil lags the air by 741 s (the
/// lab's model: 300 s), turns at 28.3, 28.5 and 6.5 °/min without stops. The rate² and a
/// scale-factor asymmetry are alike there (ρ = 0.994): only the rests at the run's ends tell
/// them apart. At the lag the search kept (≈ 300 s) the asymmetry fitted better, was named,
/// and a bias step and a `thermal_lag` were named beside it; the rate² fits better than all
/// three at the coil's own lag. Judged beside its rival at the lag the rival's model holds
/// (`coil_lag::effect_at_rivals_lag`), the asymmetry is not told apart from the rate², the lag
/// is profiled again beside both, and the rate² alone is named at the coil's lag.
#[test]
fn a_rival_is_judged_at_the_coil_lag_its_own_model_holds() {
    let legs = r#"[{"hold_s":778.5180892533356},{"to_c":-37.0,"rate_c_min":3.469},{"hold_s":2006},{"to_c":10.0,"rate_c_min":2.293}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[28.31,28.51,6.46]"),
        ("procedure.rate_deg_min", "28.31"),
        ("procedure.segment_s", "540"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "741"),
        ("traits.chamber_rate_hz", "10.0"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0195"),
        ("traits.chamber_cycling.period_s", "570"),
        ("traits.chamber_cycling.duty", "0.664"),
        ("traits.chamber_cycling.phase_s", "341.7"),
        ("traits.table_rate_hz", "1.0"),
        ("effects.rate_squared.enabled", "true"),
        ("effects.rate_squared.coeff", "-0.009750502264507499"),
    ];
    let (d, truth) = diagnose_with("lab-null", 969, &sets);
    assert_named(&d, &[EffectId::RateSquared, EffectId::TimeOffset]);
    let f = d.findings.iter().find(|f| f.effect == EffectId::RateSquared).expect("rate²");
    let (v, s) = param(f, "coeff_s_per_rad");
    let want = truth["effects"]["rate_squared"]["coefficient"].as_f64().expect("truth");
    assert!((v - want).abs() <= 3.0 * s, "rate² {v} ± {s}, truth {want}");
    let lag = coil_lag(&d);
    assert!(
        lag.held.is_none() && (lag.fitted - 741.0).abs() <= 3.0 * lag.sigma,
        "lag {} ± {} s, the writer's 741 s",
        lag.fitted,
        lag.sigma
    );
}

/// Study seed 205 (`lab_diagnose_study.py random --classes effect --hours 0.75,1.5`): a scale
/// factor vs T of 1.44 ppm/°C on a gyro without its own sensor whose coil lags the air by
/// 1038 s (the lab's model: 300 s), turns at 12.8 and 23.2 °/min. The lag's move is tested by
/// the change it makes to the model; beside a scale factor vs T that change is the thermal
/// terms' and the scale factor's column's, rebuilt at the new lag. Counting only the thermal
/// terms', the move away from 300 s without the periodic bias the search had named (to ≈ 860
/// s) had Wald 1.0, so the lag could not be the periodic bias's rival, and the periodic bias
/// (702 s) was named beside the scale factor; counted whole, the move has Wald 27.8, the
/// periodic bias keeps Wald 5.2 at the moved lag, and only the scale factor is named.
#[test]
fn the_lags_move_counts_the_temperature_reading_effects_it_moves() {
    let legs = r#"[{"hold_s":450.8037534812619},{"to_c":-1.0,"rate_c_min":2.349},{"hold_s":306},{"to_c":48.0,"rate_c_min":1.292},{"hold_s":307},{"to_c":29.0,"rate_c_min":1.548}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[12.8,23.21]"),
        ("procedure.rate_deg_min", "12.8"),
        ("procedure.segment_s", "440"),
        ("gyro.sample_rate_hz", "10.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "1038"),
        ("effects.sf_temperature.enabled", "true"),
        ("effects.sf_temperature.coeff_per_c", "1.4387724002609778e-06"),
    ];
    let (d, _) = diagnose_with("lab-clean", 821, &sets);
    assert_eq!(
        accepted(&d),
        vec![EffectId::ScaleFactorTemperature],
        "{:?} {:?}",
        d.findings,
        d.unexplained
    );
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    let lag = coil_lag(&d);
    assert!(lag.held.is_none() && lag.fitted > 600.0, "{lag:?}");
    // The coefficient is fitted at the lag found (859 ± 540 s): its σ carries that lag's
    // (1.21 ± 0.057 ppm/°C at the lag alone, 4.0σ from the writer's 1.44).
    sf_within_3_sigma(&d, 1.4387724002609778e-06);
}

/// The scale factor vs T's coefficient within 3σ of the writer's `want`.
fn sf_within_3_sigma(d: &bench_analysis::diagnose::Diagnosis, want: f64) {
    let f = d
        .findings
        .iter()
        .find(|f| f.effect == EffectId::ScaleFactorTemperature && f.accepted)
        .expect("scale factor vs T");
    let (v, s) = param(f, "coeff_per_c");
    assert!((v - want).abs() <= 3.0 * s, "coeff {v:e} ± {s:e} /°C, the writer's {want:e}");
}

/// Study seed 218 (`lab_diagnose_study.py random --classes effect --hours 0.75,1.5`): a scale
/// factor vs T of −1.68 ppm/°C on a gyro without its own sensor (100 Hz) whose coil lags the
/// air by 776 s (the lab's model: 300 s); one ramp from 20 to −35 °C. The run does not
/// determine the lag beside the scale factor (its profile 538 ± 350 s, Wald 3.6 ≤ 6.6): held
/// at 300 s and said so, and the coefficient's σ carries what holding it costs
/// (`coil_lag::lag_shift`). At the held lag alone: −1.20 ± 0.042 ppm/°C, 11σ from the truth.
#[test]
fn a_held_coil_lag_is_said_and_its_uncertainty_is_in_the_effects_sigma() {
    let legs = r#"[{"hold_s":738.7478918392976},{"to_c":-35.0,"rate_c_min":1.758},{"hold_s":570}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[19.45,14.71,21.84]"),
        ("procedure.rate_deg_min", "19.45"),
        ("procedure.segment_s", "402"),
        ("procedure.first_direction", "ccw"),
        ("procedure.stop_s", "102"),
        ("gyro.sample_rate_hz", "100.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "776"),
        ("effects.sf_temperature.enabled", "true"),
        ("effects.sf_temperature.coeff_per_c", "-1.6790536640214528e-06"),
    ];
    let (d, _) = diagnose_with("lab-clean", 873, &sets);
    assert_eq!(accepted(&d), vec![EffectId::ScaleFactorTemperature], "{:?}", d.findings);
    let lag = d
        .parameter_updates
        .iter()
        .find(|u| u.key == bench_physics::ModelKey::ThermalTimeConstant)
        .expect("the coil's lag, held");
    assert!(
        lag.held.as_deref().is_some_and(|r| r.contains("does not determine"))
            && lag.fitted == 300.0
            && lag.sigma > 0.0,
        "{lag:?}"
    );
    sf_within_3_sigma(&d, -1.6790536640214528e-06);
}

/// Study seed 145 (`lab_diagnose_study.py random --classes effect --hours 0.75,1.5`): a bias
/// step of −0.033 °/h at 1047 s, during a 1.27 °C/min ramp, on a gyro without its own sensor
/// whose coil lags the air by 408 s. The lag's first profile takes the step's transient (1612
/// s, k_t's sign flipped) and what is left was named a 1208 s periodic bias, with no rival
/// told: the step, its time chosen at that lag, left the lag where it was. A rival with a grid
/// of its own is now fitted on it again at every lag tried, its value and the lag chosen
/// together: the step at its own lag leaves the periodic bias nothing, and the two are "not
/// told apart" — no wrong name.
#[test]
fn a_rivals_grid_value_and_the_coils_lag_are_chosen_together() {
    let legs = r#"[{"hold_s":399.18672006623535},{"to_c":49.0,"rate_c_min":1.272},{"hold_s":217},{"to_c":9.0,"rate_c_min":0.769}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[9.49,3.31,29.92]"),
        ("procedure.rate_deg_min", "9.49"),
        ("procedure.segment_s", "817"),
        ("procedure.first_direction", "cw"),
        ("procedure.stop_s", "226"),
        ("gyro.sample_rate_hz", "50.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "408"),
        ("traits.chamber_rate_hz", "2.0"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0152"),
        ("traits.chamber_cycling.period_s", "551"),
        ("traits.chamber_cycling.duty", "0.513"),
        ("traits.chamber_cycling.phase_s", "253.4"),
        ("effects.bias_step.enabled", "true"),
        ("effects.bias_step.step", "-1.606548341606294e-07"),
        ("effects.bias_step.time_fraction", "0.205"),
    ];
    let (d, _) = diagnose_with("lab-null", 581, &sets);
    assert_eq!(accepted(&d), vec![EffectId::TimeOffset], "{:?} {:?}", d.findings, d.unexplained);
    assert!(
        d.unexplained
            .iter()
            .any(|u| u.correlates_with.starts_with("not told apart: periodic_bias or bias_step")),
        "{:?}",
        d.unexplained
    );
}

/// Study seed 9 of the outside class at full length (`scripts/lab_diagnose_study.py random
/// --classes outside --seeds 9`, the lab writer's seed 39): a kink in k_t of 6.4e-9 rad/s/°C at
/// 2 °C on a gyro without its own sensor whose coil lags the air by 1172 s, where the lab's
/// model says 300 s (3.05 h: hold, down to −27 °C, hold, up to −11 °C, hold, up to 57 °C). At
/// the lab's lag, held (its profile without the kink moves the model by Wald 4.2 ≤ 6.6), the
/// kink's passage read as one jump: a bias step of Wald 44.6 at 2856 s was named, its family
/// clean. The kink with the coil's lag refitted beside it (about 1040 s) explains the residual
/// and the step keeps nothing beside it: the step is not named, and the structure is reported
/// as a change of k_t.
#[test]
fn a_kink_that_reads_as_a_step_at_the_lag_in_use_is_judged_with_the_lag_refitted() {
    let legs = r#"[{"hold_s":584.7636977700954},{"to_c":-27.0,"rate_c_min":2.402},{"hold_s":2805},{"to_c":-11.0,"rate_c_min":3.602},{"hold_s":2107},{"to_c":57.0,"rate_c_min":2.698},{"hold_s":2527}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[13.86]"),
        ("procedure.rate_deg_min", "13.86"),
        ("procedure.segment_s", "548"),
        ("gyro.sample_rate_hz", "25.0"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "1172"),
        ("traits.chamber_rate_hz", "10.0"),
        ("traits.chamber_cycling.enabled", "true"),
        ("traits.chamber_cycling.amplitude_c", "0.0347"),
        ("traits.chamber_cycling.period_s", "303"),
        ("traits.chamber_cycling.shape", "sine"),
        ("traits.chamber_cycling.duty", "0.48"),
        ("traits.chamber_cycling.phase_s", "391.3"),
        ("effects.kt_kink.enabled", "true"),
        ("effects.kt_kink.coeff", "6.3912719066005e-09"),
        ("effects.kt_kink.temp_c", "2"),
    ];
    let (d, _) = diagnose_with("lab-null", 39, &sets);
    assert_eq!(accepted(&d), vec![EffectId::TimeOffset], "{:?} {:?}", d.findings, d.unexplained);
    let kink = d.unexplained.iter().find(|u| {
        u.correlates_with.starts_with("not told apart: bias_step or k_t changes near")
            && u.correlates_with.contains("with the coil's thermal lag refitted beside it")
    });
    assert!(kink.is_some(), "{:?}", d.unexplained);
}

/// Study pair 39 (`scripts/lab_diagnose_study.py random --classes pair --hours 0.75,1.5`, the
/// lab writer's seed 158): a thermal hysteresis of half-width 8.0e-8 rad/s and a warm-up of
/// −1.9e-7 rad/s with τ 1339 s on a 1.04 h run of a gyro without its own sensor (the coil 972 s
/// behind the air, the lab's model 300 s): hold, cool 20 → 1 °C, hold, heat to 17 °C. The
/// hysteresis switches at 649 s and 3245 s, and a bias step at 3250 s was named: the
/// hysteresis alone explains the residual but leaves the step significant (one coefficient
/// must fit both switches, and the first sits inside the warm-up). Judged against pairs of its
/// declared rivals, the step keeps nothing beside the hysteresis and a slow trend together:
/// not named, "not told apart" from the pair.
#[test]
fn a_step_two_rivals_explain_together_is_not_named() {
    let legs = r#"[{"hold_s":367.128763640849},{"to_c":1.0,"rate_c_min":0.627},{"hold_s":550},{"to_c":17.0,"rate_c_min":0.928}]"#;
    let sets = [
        ("procedure.legs", legs),
        ("procedure.rates_deg_min", "[8.23,23.65,7.18]"),
        ("procedure.rate_deg_min", "8.23"),
        ("procedure.segment_s", "278"),
        ("gyro.sensor", "false"),
        ("gyro.thermal_time_constant", "972"),
        ("effects.hysteresis.enabled", "true"),
        ("effects.hysteresis.half_width", "8.000824846065901e-08"),
        ("effects.warm_up.enabled", "true"),
        ("effects.warm_up.amplitude", "-1.906160775675658e-07"),
        ("effects.warm_up.time_constant_s", "1339"),
    ];
    let (d, _) = diagnose_with("lab-clean", 158, &sets);
    assert_eq!(accepted(&d), Vec::<EffectId>::new(), "{:?} {:?}", d.findings, d.unexplained);
    let pair = d.unexplained.iter().find(|u| {
        u.correlates_with.starts_with("not told apart: bias_step or thermal_hysteresis with ")
    });
    assert!(pair.is_some(), "{:?}", d.unexplained);
}
