use std::collections::BTreeMap;

use proptest::prelude::*;

use super::*;

/// Every effect on, parameters in `params()` order: the listed ones at chosen values, any other
/// (an effect added since) at [`example_values`].
fn every_effect() -> Effects {
    let on: &[(EffectId, &[f64])] = &[
        (EffectId::EarthRate, &[]),
        (EffectId::ThermalLag, &[312.5]),
        (EffectId::TemperatureQuadratic, &[2.1e-11]),
        (EffectId::ScaleFactorTemperature, &[-3e-7]),
        (EffectId::ThermalHysteresis, &[4e-9, HYSTERESIS_THRESHOLD_C_S]),
        (EffectId::OncePerRevolution, &[2e-8, 0.1 + 0.2]),
        (EffectId::TimeOffset, &[-0.0125]),
        (EffectId::WarmUp, &[1e-7, 900.0]),
        (EffectId::BiasStep, &[100.0, 1e-6]),
        (EffectId::RateSquared, &[1.0 / 3.0]),
        (EffectId::PeriodicBias, &[5e-8, 1234.5, -0.7]),
        (EffectId::RateRipple, &[1e-5, 16.0, 0.25]),
        (EffectId::AngleHarmonic, &[6e-8, 2.0, -0.4]),
    ];
    let mut e = Effects::default();
    for &(id, v) in on {
        e.set(id, v).expect("count fits");
    }
    let rest: Vec<EffectId> = EffectId::ALL.into_iter().filter(|&id| !e.has(id)).collect();
    for id in rest {
        e.set(id, &example_values(id)).expect("count fits");
    }
    e
}

/// Valid values for any effect's parameters: a positive parameter 123.5 (a time, a period, a
/// number of cycles), a finite one 2.5e-8 (a size in SI units), a phase 0.3.
fn example_values(id: EffectId) -> Vec<f64> {
    id.params()
        .iter()
        .map(|p| match (p.role, p.range) {
            (Role::Phase, _) => 0.3,
            (_, Range::Positive) => 123.5,
            _ => 2.5e-8,
        })
        .collect()
}

#[test]
fn every_effect_is_registered_once_with_its_own_key() {
    let mut keys: Vec<&str> = EffectId::ALL.iter().map(|id| id.key()).collect();
    assert_eq!(keys.len(), COUNT);
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), COUNT, "duplicate keys");
    for (k, id) in EffectId::ALL.into_iter().enumerate() {
        assert_eq!(id as usize, k);
        assert_eq!(EffectId::from_key(id.key()), Some(id));
        assert!(!id.description().contains('\n'));
        let e = id.effect();
        // A grid parameter exactly when the effect has a grid (or lags/offsets its input).
        let grid_params = e.params().iter().filter(|p| p.role == Role::Grid).count();
        assert_eq!(grid_params, usize::from(e.grid() != Grid::None), "{}", id.key());
        // Its rivals are effects of the library or nominal parameters.
        for r in e.rivals() {
            let known =
                EffectId::from_key(r.with).is_some() || crate::ModelKey::from_key(r.with).is_some();
            assert!(known, "rival `{}` of {}", r.with, id.key());
        }
        // It reports at most one size first.
        assert!(e.reported().iter().any(|r| r.is_size()), "{}", id.key());
    }
    assert_eq!(EffectId::from_key("nope"), None);
}

#[test]
fn a_rivalry_is_declared_once_and_holds_both_ways() {
    for id in EffectId::ALL {
        for other in id.rival_effects() {
            assert!(other.rival_effects().contains(&id), "{} / {}", id.key(), other.key());
            assert!(id.rivalry_with(other.key()).is_some(), "{} / {}", id.key(), other.key());
        }
    }
    assert!(EffectId::WarmUp.rival_effects().contains(&EffectId::BiasStep));
    assert_eq!(
        EffectId::RateSquared.rivalry_with("bias"),
        Some("a run at one |rate| without rests")
    );
    assert_eq!(EffectId::WarmUp.rivalry_with("once_per_revolution"), None);
    // A hysteresis that switches once is a bias step: declared by the hysteresis, held both
    // ways.
    assert!(EffectId::BiasStep.rival_effects().contains(&EffectId::ThermalHysteresis));
    assert_eq!(
        EffectId::BiasStep.rivalry_with("thermal_hysteresis"),
        Some("one switch between heating and cooling")
    );
    // A lagged term's settling after the run's first ramp is a warm-up's decay: declared by
    // the lag (the lab writer's study, pair seed 5: a warm-up named `thermal_lag`).
    assert!(EffectId::WarmUp.rival_effects().contains(&EffectId::ThermalLag));
    // Table rates held in blocks of the run: a warm-up moves one |rate|'s level against the
    // others as an asymmetry does (the lab writer's study, pair seed 15: a warm-up and a rate²
    // named a scale-factor asymmetry and the rate²). Declared by the warm-up: its longer run
    // separates them.
    assert!(EffectId::ScaleFactorAsymmetry.rival_effects().contains(&EffectId::WarmUp));
}

#[test]
fn owners_split_what_travels_with_a_model() {
    let e = every_effect();
    let t = e.travelling();
    assert!(t.has(EffectId::WarmUp) && t.has(EffectId::EarthRate));
    assert!(!t.has(EffectId::RateRipple) && !t.has(EffectId::TimeOffset));
    let b = e.of_the_bench();
    assert_eq!(b.ids(), vec![EffectId::TimeOffset, EffectId::RateRipple]);
    // A model from elsewhere on a recording's bench: its gyro effects, the recording's table
    // and clocks (here a ripple of its own and no time offset).
    let own = Effects::default().with(EffectId::RateRipple, &[2e-5, 8.0, 0.1]).expect("count");
    let on = e.on_the_bench_of(&own);
    assert_eq!(on.get(EffectId::RateRipple), Some(&[2e-5, 8.0, 0.1][..]));
    assert!(!on.has(EffectId::TimeOffset));
    assert_eq!(on.travelling(), t);
    assert_eq!(e.on_the_bench_of(&Effects::default()), t);
}

#[test]
fn metadata_keys_and_values_are_the_documented_ones() {
    let m = every_effect().to_metadata();
    assert_eq!(m.get("effect.earth_rate").map(String::as_str), Some("1"));
    assert_eq!(
        m.get("effect.once_per_revolution.amplitude_rad_s").map(String::as_str),
        Some("2e-8")
    );
    assert_eq!(m.get("effect.bias_step.time_s").map(String::as_str), Some("1e2"));
    assert_eq!(m.get("effect.warm_up.time_constant_s").map(String::as_str), Some("9e2"));
    // One key per parameter, and one per effect without parameters.
    let keys: usize = EffectId::ALL.iter().map(|id| id.params().len().max(1)).sum();
    assert_eq!(m.len(), keys);
    assert!(m.len() > 22, "the thirteen first effects' keys at least");
    assert!(m.keys().all(|k| k.starts_with(METADATA_PREFIX)));
    assert!(Effects::default().to_metadata().is_empty());
}

#[test]
fn metadata_round_trips_exactly_and_ignores_other_keys() {
    let e = every_effect();
    let mut m = e.to_metadata();
    m.insert("bias".into(), "1e-8".into());
    m.insert("effect.unknown_thing.x".into(), "zzz".into());
    m.insert("effect.warm_up.colour".into(), "blue".into());
    assert_eq!(Effects::from_metadata(&m), Ok(e));
    for id in EffectId::ALL {
        let mut one = Effects::default();
        one.set(id, &e.param_values(id).expect("on")).expect("count fits");
        assert_eq!(Effects::from_metadata(&one.to_metadata()), Ok(one), "{}", id.key());
    }
    assert_eq!(Effects::from_metadata(&BTreeMap::new()), Ok(Effects::default()));
}

#[test]
fn bad_metadata_names_the_key() {
    let mut m = every_effect().to_metadata();
    m.insert("effect.warm_up.time_constant_s".into(), "soon".into());
    let e = Effects::from_metadata(&m).expect_err("unparsable");
    assert!(e.contains("`effect.warm_up.time_constant_s`") && e.contains("soon"), "{e}");
    let mut m = every_effect().to_metadata();
    m.remove("effect.bias_step.step_rad_s");
    let e = Effects::from_metadata(&m).expect_err("incomplete");
    assert!(e.starts_with("`effect.bias_step.step_rad_s` is missing"), "{e}");
    let mut m = BTreeMap::new();
    m.insert("effect.earth_rate".to_string(), "yes".to_string());
    let e = Effects::from_metadata(&m).expect_err("not a flag");
    assert!(e.contains("`effect.earth_rate`"), "{e}");
}

#[test]
fn set_checks_the_count_and_overrides_replace_per_effect() {
    let mut e = Effects::default();
    assert!(e.set(EffectId::WarmUp, &[1.0]).is_err());
    e.set(EffectId::WarmUp, &[1e-7, 60.0]).expect("fits");
    e.set(EffectId::RateSquared, &[2e-3]).expect("fits");
    let mut over = Effects::default();
    over.set(EffectId::WarmUp, &[2e-7, 30.0]).expect("fits");
    over.set(EffectId::EarthRate, &[]).expect("fits");
    let t = e.overridden_by(&over);
    assert_eq!(t.get(EffectId::WarmUp), Some(&[2e-7, 30.0][..]));
    assert_eq!(t.get(EffectId::RateSquared), e.get(EffectId::RateSquared));
    assert!(t.has(EffectId::EarthRate));
    let cleared = t.without(EffectId::WarmUp);
    assert!(!cleared.has(EffectId::WarmUp) && cleared.has(EffectId::RateSquared));
}

#[test]
fn validate_names_the_parameter() {
    assert_eq!(every_effect().validate(), Ok(()));
    let e = Effects::default().with(EffectId::WarmUp, &[1e-7, 0.0]).expect("fits");
    assert_eq!(e.validate(), Err("`warm_up.time_constant_s` must be positive, got 0".into()));
    let e = Effects::default().with(EffectId::BiasStep, &[f64::NAN, 1e-7]).expect("fits");
    assert_eq!(e.validate(), Err("`bias_step.time_s` must be a finite number, got NaN".into()));
}

#[test]
fn toml_tables_round_trip_and_refuse_what_is_unknown() {
    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct File {
        effects: Effects,
    }
    let e = every_effect();
    let text = serde_json::to_string(&File { effects: e }).expect("serializes");
    let back: File = serde_json::from_str(&text).expect("parses");
    assert_eq!(back.effects, e);
    // Earth's rate is always written, effects that are off never.
    let none = serde_json::to_string(&Effects::default()).expect("serializes");
    assert_eq!(none, r#"{"earth_rate":false}"#);
    let err = serde_json::from_str::<Effects>(r#"{"warmup":{}}"#).expect_err("unknown");
    assert!(err.to_string().starts_with("unknown field `warmup`, expected one of `earth_rate`"));
    let err = serde_json::from_str::<Effects>(r#"{"warm_up":{"amplitude_rad_s":1}}"#)
        .expect_err("incomplete");
    assert!(err.to_string().starts_with("missing field `time_constant_s`"), "{err}");
    let err = serde_json::from_str::<Effects>(r#"{"warm_up":{"tau_s":1}}"#).expect_err("typo");
    assert!(
        err.to_string()
            .starts_with("unknown field `tau_s`, expected `amplitude_rad_s` or `time_constant_s`"),
        "{err}"
    );
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
        -1e3..1e3f64,
        Just(0.0),
        Just(-0.0),
        Just(f64::MIN_POSITIVE),
    ]
}

proptest! {
    #[test]
    fn any_finite_effects_round_trip_exactly(
        on in proptest::collection::vec(any::<bool>(), COUNT),
        values in proptest::collection::vec(finite(), 3 * COUNT),
    ) {
        let mut e = Effects::default();
        for (k, id) in EffectId::ALL.into_iter().enumerate() {
            if on[k] {
                let n = id.params().len();
                e.set(id, &values[3 * k..3 * k + n]).expect("count fits");
            }
        }
        let back = Effects::from_metadata(&e.to_metadata()).expect("parses");
        // Bitwise: -0.0 must stay -0.0.
        for id in EffectId::ALL {
            let a = e.param_values(id).map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
            let b = back.param_values(id).map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
            prop_assert_eq!(a, b);
        }
    }
}

#[test]
fn value_matches_the_closed_forms() {
    let s = EffectSample {
        t_s: 100.0,
        input_rad_s: 0.003,
        table_rate_rad_s: 0.0029,
        temp_minus_ref_c: -10.0,
        angle_mid_rad: 0.7,
        hysteresis: -1.0,
        earth_rad_s: 6.3e-5,
    };
    let one = |id: EffectId, v: &[f64]| {
        Effects::default().with(id, v).expect("count fits").value(&s, 1.001)
    };
    assert_eq!(Effects::default().value(&s, 1.001), 0.0);
    assert_eq!(one(EffectId::EarthRate, &[]), 6.3e-5 * 1.001);
    assert_eq!(one(EffectId::TemperatureQuadratic, &[2e-11]), 2e-11 * 100.0);
    assert!((one(EffectId::ScaleFactorTemperature, &[1e-6]) + 3e-8).abs() < 1e-22);
    assert_eq!(one(EffectId::ThermalHysteresis, &[4e-9, 1e-3]), -4e-9);
    let got = one(EffectId::OncePerRevolution, &[2e-8, 0.3]);
    assert!((got - 2e-8 * (0.7f64 + 0.3).sin()).abs() < 1e-22);
    let got = one(EffectId::WarmUp, &[1e-7, 50.0]);
    assert!((got - 1e-7 * (-2.0f64).exp()).abs() < 1e-22);
    assert_eq!(one(EffectId::BiasStep, &[100.0, 3e-9]), 3e-9);
    assert_eq!(one(EffectId::BiasStep, &[100.1, 3e-9]), 0.0);
    assert!((one(EffectId::RateSquared, &[1e-3]) - 9e-9).abs() < 1e-22);
    let got = one(EffectId::PeriodicBias, &[4e-8, 800.0, -0.4]);
    // 100 s of an 800 s period: a quarter of π on.
    let want = 4e-8 * (std::f64::consts::FRAC_PI_4 - 0.4).sin();
    assert!((got - want).abs() < 1e-22, "{got} vs {want}");
    let got = one(EffectId::RateRipple, &[1e-5, 16.0, 0.2]);
    let want = 1e-5 * 0.0029 * (16.0f64 * 0.7 + 0.2).sin();
    assert!((got - want).abs() < 1e-22, "{got} vs {want}");
    // The input transforms add nothing themselves.
    assert_eq!(one(EffectId::ThermalLag, &[300.0]), 0.0);
    assert_eq!(one(EffectId::TimeOffset, &[0.01]), 0.0);
}

#[test]
fn hysteresis_remembers_the_last_direction() {
    let r = [0.0, 1e-4, 2e-3, 0.0, -1e-4, -5e-3, 0.0, 1e-3];
    assert_eq!(HysteresisState::series(1e-3, &r), vec![0., 0., 1., 1., 1., -1., -1., -1.]);
}

#[test]
fn lagged_ramp_trails_by_rate_times_tau() {
    let t: Vec<f64> = (0..20_000).map(|k| k as f64 * 0.5).collect();
    let temp: Vec<f64> = t.iter().map(|t| 0.01 * t).collect();
    let lagged = lag_temperature(&t, &temp, 300.0);
    let last = lagged.len() - 1;
    // After 33 time constants the lag is rate·τ = 3 °C to rounding.
    assert!((temp[last] - lagged[last] - 3.0).abs() < 1e-9);
    assert_eq!(lag_temperature(&t, &temp, 0.0), temp);
}

#[test]
fn the_docs_effect_table_is_the_registrys() {
    let docs = include_str!("../../../docs/diagnose.md");
    let table = Effects::table_markdown();
    assert!(
        docs.contains(&table),
        "docs/diagnose.md's effect table is not the registry's:\n{table}"
    );
}
