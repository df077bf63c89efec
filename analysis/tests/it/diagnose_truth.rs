//! Diagnosis against the simulator's own truth (`GyroSampler` with effects switched on), on a
//! 2.6 h procedure: rest, CW/CCW plateaus at 20 and 50 °C, a heating ramp CW and a cooling
//! ramp CCW at 1 °C/min, soaks at rest; table motion with real accelerations read in 1″ steps,
//! gyro temperature in 0.01 °C steps, chamber air in 0.1 °C steps, seed-gyro noise (ARW and
//! bias instability). Each effect is switched on at a few times the noise floor and concealed
//! from the nominal model.

use bench_analysis::diagnose::{diagnose, DiagnoseOptions, Diagnosis, Verdict};
use bench_analysis::run::{RunSeries, StepEnd, StepSpan};
use bench_physics::effects::*;
use bench_physics::gyro::{GyroSampler, Mounting};
use bench_physics::lag::FirstOrderLag;
use bench_physics::table::{RateTableModel, TableParams};
use bench_physics::units::{quantise, DEG_PER_MIN};
use bench_physics::GyroModel;

const DT: f64 = 0.05;
const LAT: f64 = 59.94;
const OMEGA: f64 = 10.0 * DEG_PER_MIN;
const ACCEL: f64 = 0.017_453_292_5; // 1 °/s²

/// These effects on, each with its parameters.
fn on(list: &[(EffectId, &[f64])]) -> Effects {
    let mut e = Effects::default();
    for (id, v) in list {
        e.set(*id, v).expect("count fits");
    }
    e
}

/// label, table rate, air at start, air rate (°C/s), duration (s).
type Step = (&'static str, f64, f64, f64, f64);

fn procedure() -> Vec<Step> {
    let ramp = 1.0 / 60.0;
    vec![
        ("soak 20C", 0.0, 20.0, 0.0, 600.0),
        ("record cw 20C", -OMEGA, 20.0, 0.0, 900.0),
        ("record ccw 20C", OMEGA, 20.0, 0.0, 900.0),
        ("record cw ramp 20C to 50C", -OMEGA, 20.0, ramp, 1800.0),
        ("soak 50C", 0.0, 50.0, 0.0, 900.0),
        ("record ccw 50C", OMEGA, 50.0, 0.0, 600.0),
        ("record cw 50C", -OMEGA, 50.0, 0.0, 600.0),
        ("record ccw ramp 50C to 20C", OMEGA, 50.0, -ramp, 1800.0),
        ("record cw 20C again", -OMEGA, 20.0, 0.0, 600.0),
    ]
}

/// Simulate the procedure with `truth` + `effects` on a table without rate ripple; the gyro's
/// `seed`.
fn simulate(truth: &GyroModel, effects: Effects, seed: u64) -> RunSeries {
    simulate_on(TableParams { ripple_rel: 0.0, ..TableParams::default() }, truth, effects, seed)
}

/// [`simulate`] on a table with `table`'s parameters.
fn simulate_on(table: TableParams, truth: &GyroModel, effects: Effects, seed: u64) -> RunSeries {
    simulate_steps(&procedure(), table, truth, effects, seed)
}

/// [`procedure`] with the 20 and 50 °C plateaus turned at 10 and at 30 °/min: turns at two
/// |rate| with rests (the soaks) between them, the run that tells an error in Ω² from one in |Ω|.
fn procedure_two_rates() -> Vec<Step> {
    let ramp = 1.0 / 60.0;
    let fast = 3.0 * OMEGA;
    vec![
        ("soak 20C", 0.0, 20.0, 0.0, 600.0),
        ("record cw 20C", -OMEGA, 20.0, 0.0, 600.0),
        ("record ccw 20C", OMEGA, 20.0, 0.0, 600.0),
        ("record cw 20C fast", -fast, 20.0, 0.0, 600.0),
        ("record ccw 20C fast", fast, 20.0, 0.0, 600.0),
        ("record cw ramp 20C to 50C", -OMEGA, 20.0, ramp, 1800.0),
        ("soak 50C", 0.0, 50.0, 0.0, 900.0),
        ("record ccw 50C fast", fast, 50.0, 0.0, 600.0),
        ("record cw 50C fast", -fast, 50.0, 0.0, 600.0),
        ("record ccw 50C", OMEGA, 50.0, 0.0, 600.0),
        ("record cw 50C", -OMEGA, 50.0, 0.0, 600.0),
        ("record ccw ramp 50C to 20C", OMEGA, 50.0, -ramp, 1800.0),
        ("record cw 20C again", -OMEGA, 20.0, 0.0, 600.0),
    ]
}

/// The procedure `steps` simulated on a table with `table`'s parameters, with `truth` +
/// `effects` and the gyro's `seed`.
fn simulate_steps(
    steps: &[Step],
    table: TableParams,
    truth: &GyroModel,
    effects: Effects,
    seed: u64,
) -> RunSeries {
    let air0 = steps[0].2;
    let mount = Mounting { latitude_deg: LAT, axis_up: true };
    let mut gyro = GyroSampler::new(truth.clone(), DT, seed, 1, mount, air0).with_effects(effects);
    let mut lag = FirstOrderLag::new(truth.thermal_time_constant, air0);
    let q = table.position_resolution_rad;
    let mut table = RateTableModel::new(table);
    let mut run = RunSeries { latitude_deg: Some(LAT), axis_up: true, ..RunSeries::default() };
    let mut temps = Vec::new();
    let mut t = 0.0f64;
    let mut k = 0usize;
    for (index, &(label, rate, air_start, air_rate, secs)) in steps.iter().enumerate() {
        let start = t;
        table.command_rate(t, rate, ACCEL).expect("command");
        let n = (secs / DT).round() as usize;
        for i in 0..n {
            let u0 = air_start + air_rate * i as f64 * DT;
            let u1 = air_start + air_rate * (i + 1) as f64 * DT;
            let temp = lag.step_linear(u0, u1, DT);
            k += 1;
            t = k as f64 * DT;
            let angle = table.true_angle(t - effects.offset_s());
            let v = gyro.sample(t, angle, temp).total();
            run.gyro_time_s.push(t);
            run.gyro_rate_rad_s.push(v);
            temps.push(GyroSampler::temperature_readout(temp));
            run.table_time_s.push(t);
            run.table_angle_rad.push(quantise(table.true_angle(t), q));
            run.table_rate_command_rad_s.push(rate);
            run.chamber_time_s.push(t);
            run.chamber_temp_c.push(quantise(u1, 0.1));
        }
        run.steps.push(StepSpan {
            index: index as u64,
            name: if label.starts_with("record") { "record" } else { "wait" }.into(),
            label: if label.starts_with("record") { label.into() } else { String::new() },
            start_s: start,
            end_s: t,
            ended: StepEnd::End,
        });
    }
    run.gyro_temp_c = Some(temps);
    run
}

fn nominal() -> GyroModel {
    GyroModel::default()
}

fn check(d: &Diagnosis) -> String {
    let mut s = format!(
        "verdict {:?}, rms {:?}, n_eff {:.0}, params W {:.1}/{:.1}\n",
        d.verdict, d.rms, d.n_eff, d.parameters_wald.value, d.parameters_wald.threshold
    );
    for f in &d.findings {
        s += &format!(
            "  {} accepted={} W={:.1} thr={:.1} dBIC={:.1} hz={:.1} {:?} {:?}\n",
            f.effect.key(),
            f.accepted,
            f.wald,
            f.threshold,
            f.delta_bic,
            f.holdout_z,
            f.parameters.iter().map(|p| (p.name, p.value, p.sigma)).collect::<Vec<_>>(),
            f.rejected_because
        );
    }
    for u in &d.unexplained {
        s += &format!("  unexplained {:?} {} {:e}\n", u.windows_s, u.correlates_with, u.rms);
    }
    s
}

fn accepted(d: &Diagnosis) -> Vec<EffectId> {
    d.findings.iter().filter(|f| f.accepted).map(|f| f.effect).collect()
}

fn param(d: &Diagnosis, id: EffectId, name: &str) -> (f64, f64) {
    let f = d.findings.iter().find(|f| f.effect == id && f.accepted).expect("finding");
    let p = f.parameters.iter().find(|p| p.name == name).expect("parameter");
    (p.value, p.sigma)
}

fn within_3_sigma(d: &Diagnosis, id: EffectId, name: &str, truth: f64) {
    let (v, s) = param(d, id, name);
    assert!(
        (v - truth).abs() <= 3.0 * s,
        "{}: {name} = {v:e} ± {s:e}, truth {truth:e}\n{}",
        id.key(),
        check(d)
    );
}

fn run_with(effects: Effects, seed: u64) -> Diagnosis {
    let run = simulate(&nominal(), effects, seed);
    diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default()).expect("diagnosis")
}

#[test]
fn null_run_has_no_finding() {
    for seed in [1, 2] {
        let d = run_with(Effects::default(), seed);
        assert!(accepted(&d).is_empty(), "seed {seed}: {}", check(&d));
        assert!(d.unexplained.is_empty(), "seed {seed}: {}", check(&d));
        assert_ne!(d.verdict, Verdict::MissingPhysics);
    }
}

#[test]
fn parameters_only_run_is_named_so() {
    let truth = GyroModel { bias: 2e-7, temp_coeff: 2.0 * nominal().temp_coeff, ..nominal() };
    let run = simulate(&truth, Effects::default(), 3);
    let d = diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(d.verdict, Verdict::ParametersOnly, "{}", check(&d));
    let bias = &d.parameter_updates[0];
    assert!((bias.fitted - 2e-7).abs() < 3.0 * bias.sigma, "{bias:?}");
}

/// Turns at 10 and 30 °/min: a revolution lasts 36 or 12 minutes, so a once-per-revolution
/// term is no sinusoid in time.
#[test]
fn once_per_revolution_is_found() {
    let e = on(&[(EffectId::OncePerRevolution, &[3e-8, 0.8])]);
    let table = TableParams { ripple_rel: 0.0, ..TableParams::default() };
    let run = simulate_steps(&procedure_two_rates(), table, &nominal(), e, 4);
    let d = diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(accepted(&d), vec![EffectId::OncePerRevolution], "{}", check(&d));
    within_3_sigma(&d, EffectId::OncePerRevolution, "amplitude_rad_s", 3e-8);
    within_3_sigma(&d, EffectId::OncePerRevolution, "phase_rad", 0.8);
    assert!(d.rms.after < d.rms.before);
}

/// At one table rate (10 °/min, a revolution in 36 minutes, turning most of the run) a
/// once-per-revolution term is nearly a periodic bias of the revolution's period: on this
/// gyro seed it keeps Wald 12.1 beside one, under one test's 14.9. Not named; "not told
/// apart", with the run that separates them (turns at two rates: the test above).
#[test]
fn once_per_revolution_at_one_slow_rate_is_not_told_apart_from_a_periodic_bias() {
    let d = run_with(on(&[(EffectId::OncePerRevolution, &[3e-8, 0.8])]), 4);
    assert!(accepted(&d).is_empty(), "{}", check(&d));
    let apart: Vec<_> = d
        .unexplained
        .iter()
        .filter(|u| {
            u.correlates_with.starts_with("not told apart: once_per_revolution or periodic_bias")
        })
        .collect();
    assert_eq!(apart.len(), 1, "{}", check(&d));
    assert!(apart[0].correlates_with.contains("two table rates"), "{}", apart[0].correlates_with);
}

#[test]
fn warm_up_alone_is_found() {
    let d = run_with(on(&[(EffectId::WarmUp, &[2e-7, 600.0])]), 5);
    assert_eq!(accepted(&d), vec![EffectId::WarmUp], "{}", check(&d));
    assert!(d.rms.after < d.rms.before);
}

#[test]
fn once_per_revolution_and_bias_step_together() {
    let e =
        on(&[(EffectId::OncePerRevolution, &[4e-8, -1.0]), (EffectId::BiasStep, &[5000.0, 1e-7])]);
    let d = run_with(e, 6);
    let mut got = accepted(&d);
    got.sort();
    assert_eq!(got, vec![EffectId::OncePerRevolution, EffectId::BiasStep], "{}", check(&d));
    within_3_sigma(&d, EffectId::BiasStep, "step_rad_s", 1e-7);
    within_3_sigma(&d, EffectId::BiasStep, "time_s", 5000.0);
    within_3_sigma(&d, EffectId::OncePerRevolution, "amplitude_rad_s", 4e-8);
}

#[test]
fn warm_up_and_bias_step_together() {
    // A warm-up judged alone against held-out blocks that also hold an unmodelled step is not
    // confirmed; the pair is (each with the other in the model), both grid values refitted.
    let e = on(&[(EffectId::WarmUp, &[3e-7, 600.0]), (EffectId::BiasStep, &[4000.0, 1e-7])]);
    let d = run_with(e, 12);
    let mut got = accepted(&d);
    got.sort();
    assert_eq!(got, vec![EffectId::WarmUp, EffectId::BiasStep], "{}", check(&d));
    within_3_sigma(&d, EffectId::BiasStep, "step_rad_s", 1e-7);
    within_3_sigma(&d, EffectId::BiasStep, "time_s", 4000.0);
    within_3_sigma(&d, EffectId::WarmUp, "amplitude_rad_s", 3e-7);
}

/// One effect concealed at a few times the noise floor: named alone, its parameter within 3σ,
/// the residual smaller.
fn single(effects: Effects, seed: u64, id: EffectId, name: &str, truth: f64) {
    let d = run_with(effects, seed);
    assert_eq!(accepted(&d), vec![id], "{}", check(&d));
    within_3_sigma(&d, id, name, truth);
    assert!(d.rms.after < d.rms.before, "{}", check(&d));
    assert!(d.bic.after < d.bic.before, "{}", check(&d));
}

/// Over 20..50 °C with T0 = 20 °C, 1.2e-9 rad/s/°C² departs from the best line by up to
/// 1.35e-7 rad/s: beside the kink in k_t that explains it best (a hinge at a knot on the
/// recording's temperatures) the quadratic keeps its Wald, so it is named.
#[test]
fn temperature_quadratic_is_found() {
    let e = on(&[(EffectId::TemperatureQuadratic, &[1.2e-9])]);
    single(e, 7, EffectId::TemperatureQuadratic, "coeff_rad_s_per_c2", 1.2e-9);
}

/// A third of that (4e-10 rad/s/°C², five times the flicker floor) on the same 30 °C: the
/// best hinge alone explains more of it than the quadratic does, and beside the hinge the
/// quadratic keeps nothing. The data cannot say which it is: not named, the structure
/// reported unexplained as the kink beside a quadratic-like term.
#[test]
fn a_weak_temperature_quadratic_is_not_told_from_a_kink_in_k_t() {
    let d = run_with(on(&[(EffectId::TemperatureQuadratic, &[4e-10])]), 7);
    assert!(accepted(&d).is_empty(), "{}", check(&d));
    let kink = d.unexplained.iter().find(|u| u.correlates_with.starts_with("k_t changes near"));
    let why = kink.map(|u| u.correlates_with.as_str()).unwrap_or_default();
    assert!(
        why.contains("not told apart") && why.contains("temperature_quadratic"),
        "{}",
        check(&d)
    );
    assert!(d.rms.after < d.rms.before, "{}", check(&d));
}

#[test]
fn scale_factor_temperature_is_found() {
    let e = on(&[(EffectId::ScaleFactorTemperature, &[1e-6])]);
    single(e, 8, EffectId::ScaleFactorTemperature, "coeff_per_c", 1e-6);
}

/// An error in Ω² on turns at one |rate| (with rests): at two levels of |Ω| (0 and 10 °/min)
/// Ω² and |Ω| (a scale-factor asymmetry) are both a line through them, so the honest answer is
/// "not told apart" with the run that separates them — neither named, both shapes kept as
/// nuisance and reported unexplained.
#[test]
fn rate_squared_on_one_rate_is_not_told_from_an_asymmetry() {
    let d = run_with(on(&[(EffectId::RateSquared, &[1e-2])]), 9);
    assert!(accepted(&d).is_empty(), "{}", check(&d));
    let both = |why: &str| {
        why.starts_with("not told apart: ")
            && why.contains("rate_squared")
            && why.contains("scale_factor_asymmetry")
            && why.contains("two table rates")
    };
    assert!(
        d.unexplained.iter().any(|u| both(&u.correlates_with)),
        "the pair reported unexplained, with the separating run\n{}",
        check(&d)
    );
    assert!(d.rms.after < d.rms.before, "{}", check(&d));
}

/// The same error on [`procedure_two_rates`] (10 and 30 °/min, rests between): Ω² is told from
/// |Ω| and named alone, its coefficient within 3σ.
#[test]
fn rate_squared_is_found_on_turns_at_two_rates() {
    let e = on(&[(EffectId::RateSquared, &[1e-2])]);
    let table = TableParams { ripple_rel: 0.0, ..TableParams::default() };
    let run = simulate_steps(&procedure_two_rates(), table, &nominal(), e, 9);
    let d = diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(accepted(&d), vec![EffectId::RateSquared], "{}", check(&d));
    within_3_sigma(&d, EffectId::RateSquared, "coeff_s_per_rad", 1e-2);
    assert!(d.rms.after < d.rms.before, "{}", check(&d));
    assert!(d.bic.after < d.bic.before, "{}", check(&d));
}

#[test]
fn time_offset_is_found() {
    let e = on(&[(EffectId::TimeOffset, &[2e-4])]);
    single(e, 10, EffectId::TimeOffset, "offset_s", 2e-4);
}

/// Two heating and two cooling ramps: four switches of the hysteresis, which one bias step
/// cannot take. (On [`procedure`]'s one ramp each way the hysteresis is a bias step at the
/// switch to cooling plus a smaller one at the start of heating: "not told apart:
/// thermal_hysteresis or bias_step", seed 11 keeping Wald 11.1 ≤ 11.9 beside the step.)
fn procedure_two_cycles() -> Vec<Step> {
    let ramp = 1.0 / 60.0;
    vec![
        ("soak 20C", 0.0, 20.0, 0.0, 600.0),
        ("record cw ramp 20C to 50C", -OMEGA, 20.0, ramp, 1800.0),
        ("record ccw 50C", OMEGA, 50.0, 0.0, 600.0),
        ("record cw ramp 50C to 20C", -OMEGA, 50.0, -ramp, 1800.0),
        ("record ccw 20C", OMEGA, 20.0, 0.0, 600.0),
        ("record cw ramp 20C to 50C again", -OMEGA, 20.0, ramp, 1800.0),
        ("record ccw 50C again", OMEGA, 50.0, 0.0, 600.0),
        ("record cw ramp 50C to 20C again", -OMEGA, 50.0, -ramp, 1800.0),
        ("record ccw 20C again", OMEGA, 20.0, 0.0, 600.0),
    ]
}

#[test]
fn thermal_hysteresis_is_found() {
    let e = on(&[(EffectId::ThermalHysteresis, &[5e-8, HYSTERESIS_THRESHOLD_C_S])]);
    let table = TableParams { ripple_rel: 0.0, ..TableParams::default() };
    let run = simulate_steps(&procedure_two_cycles(), table, &nominal(), e, 11);
    let d = diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(accepted(&d), vec![EffectId::ThermalHysteresis], "{}", check(&d));
    within_3_sigma(&d, EffectId::ThermalHysteresis, "half_width_rad_s", 5e-8);
    assert!(d.rms.after < d.rms.before, "{}", check(&d));
}

/// On one heating and one cooling ramp the hysteresis is a bias step and a smaller one: the
/// declared rivalry ("one switch between heating and cooling") is judged, and neither is named
/// alone.
#[test]
fn thermal_hysteresis_on_one_ramp_each_way_is_not_told_apart_from_a_bias_step() {
    let d = run_with(on(&[(EffectId::ThermalHysteresis, &[5e-8, HYSTERESIS_THRESHOLD_C_S])]), 11);
    assert!(accepted(&d).is_empty(), "{}", check(&d));
    assert!(
        d.unexplained
            .iter()
            .any(|u| u.correlates_with.contains("not told apart: thermal_hysteresis or bias_step")),
        "{}",
        check(&d)
    );
}

#[test]
fn thermal_lag_is_found() {
    let e = on(&[(EffectId::ThermalLag, &[400.0])]);
    single(e, 12, EffectId::ThermalLag, "time_constant_s", 400.0);
}

#[test]
fn earth_rate_left_out_of_the_model_is_found() {
    // The nominal model leaves Earth out; the gyro senses it.
    let nominal = GyroModel { earth_rate: false, ..nominal() };
    let run = simulate(&GyroModel { earth_rate: true, ..nominal.clone() }, Effects::default(), 13);
    let d = diagnose(&run, &nominal, &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(accepted(&d), vec![EffectId::EarthRate], "{}", check(&d));
    within_3_sigma(&d, EffectId::EarthRate, "latitude_deg", LAT);
    assert!(d.effects.has(EffectId::EarthRate));
}

#[test]
fn table_rate_ripple_below_the_readout_resolution_is_found() {
    // The simulated table's default ripple: 1e-5 of the rate at 16 cycles per revolution, an
    // angle excursion of 0.26″ that its 1″ readout does not show. The gyro sees it.
    let table = TableParams::default();
    assert_eq!((table.ripple_rel, table.ripple_cycles_per_rev), (1e-5, 16));
    let run = simulate_on(table, &nominal(), Effects::default(), 1);
    let d = diagnose(&run, &nominal(), &Effects::default(), &DiagnoseOptions::default())
        .expect("diagnosis");
    assert_eq!(accepted(&d), vec![EffectId::RateRipple], "{}", check(&d));
    within_3_sigma(&d, EffectId::RateRipple, "relative_amplitude", 1e-5);
    within_3_sigma(&d, EffectId::RateRipple, "phase_rad", 0.0);
    assert_eq!(param(&d, EffectId::RateRipple, "cycles_per_rev").0, 16.0);
}

#[test]
fn periodic_bias_is_found_not_mistaken_for_other_effects() {
    // A 22 min oscillation (lab air conditioning) at four times the flicker floor: named alone
    // (not a step, a once-per-revolution term or a temperature effect), its period and
    // amplitude within 3σ.
    let e = on(&[(EffectId::PeriodicBias, &[4e-8, 1320.0, 0.6])]);
    single(e, 13, EffectId::PeriodicBias, "amplitude_rad_s", 4e-8);
    let d = run_with(e, 13);
    within_3_sigma(&d, EffectId::PeriodicBias, "period_s", 1320.0);
}
