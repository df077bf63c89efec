//! The shipped scenarios parse, validate against an ST1300-class bench and against the
//! simulator's capabilities, and expand to the expected steps.

use std::path::{Path, PathBuf};
use std::time::Duration;

use bench::plan::{Action, RunPlan, TempSource};
use bench::scenario::{load, Capabilities};
use bench_drivers::{ChamberCapabilities, DeviceInfo, GyroCapabilities, TableCapabilities};
use bench_physics::units::{DEG, DEG_PER_MIN};

fn info<C>(capabilities: C) -> DeviceInfo<C> {
    DeviceInfo { model: "test".into(), driver: "test".into(), capabilities }
}

/// ST1300-class table (1000 °/s, 1000 °/s²), its chamber (-55..185 °C, heats 5 °C/min, cools
/// 3.5 °C/min) and a FOG rated -40..+60 °C offering 1..2000 Hz.
fn st1300() -> Capabilities {
    Capabilities {
        table: info(TableCapabilities {
            max_rate_rad_s: 1000.0 * DEG,
            max_accel_rad_s2: 1000.0 * DEG,
            position_resolution_rad: 4.8481e-6,
        }),
        chamber: info(ChamberCapabilities {
            min_temp_c: -55.0,
            max_temp_c: 185.0,
            max_heat_rate_c_s: 5.0 / 60.0,
            max_cool_rate_c_s: 3.5 / 60.0,
            temp_resolution_c: 0.01,
        }),
        gyro: info(GyroCapabilities {
            sample_rates_hz: vec![
                1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0,
            ],
            max_rate_rad_s: 500.0 * DEG,
            operating_temp_c: (-40.0, 60.0),
            has_temperature: true,
        }),
    }
}

fn scenario(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("scenarios").join(name)
}

fn load_ok(name: &str, caps: &Capabilities) -> RunPlan {
    match load(&scenario(name), caps) {
        Ok(p) => p,
        Err(e) => panic!("{name} must validate:\n{e}"),
    }
}

/// (label, duration, until ramp end) of every record step, in order.
fn records(p: &RunPlan) -> Vec<(String, Duration, bool)> {
    p.steps
        .iter()
        .filter_map(|s| match s.action {
            Action::Record { duration, until_ramp_end } => {
                Some((s.label.clone(), duration, until_ramp_end))
            }
            _ => None,
        })
        .collect()
}

fn table_rates(p: &RunPlan) -> Vec<f64> {
    p.steps
        .iter()
        .filter_map(|s| match s.action {
            Action::Table { rate_rad_s, .. } => Some(rate_rad_s),
            _ => None,
        })
        .collect()
}

#[test]
fn seed_scenario_is_the_seeds_procedure() {
    let p = load_ok("seed.toml", &st1300());
    assert_eq!(p.name, "seed");
    assert_eq!(p.site.latitude_deg, 59.94);
    assert!(p.site.axis_up());
    assert_eq!(p.gyro.sample_rate_hz, 20.0);
    assert_eq!(p.sim.initial_temp_c, 20.0);
    assert!(p.text.contains("[scenario]"));

    let min = |m: u64| Duration::from_secs(60 * m);
    assert_eq!(
        records(&p),
        [
            ("record cw 20C".to_string(), min(3), false),
            ("record cw ramp 20C to 40C".to_string(), min(15), true),
            ("record cw 40C".to_string(), min(2), false),
            ("record ccw 20C".to_string(), min(3), false),
            ("record ccw ramp 20C to 40C".to_string(), min(15), true),
            ("record ccw 40C".to_string(), min(2), false),
        ]
    );

    // CW is negative: 10 °/min = 2.9089e-3 rad/s.
    let rates = table_rates(&p);
    assert_eq!(rates.len(), 2);
    assert!((rates[0] + 2.9089e-3).abs() < 5e-8, "{}", rates[0]);
    assert_eq!(rates[0], -10.0 * DEG_PER_MIN);
    assert_eq!(rates[1], 10.0 * DEG_PER_MIN);

    // The step sequence of one rotation.
    let names: Vec<&str> = p.steps.iter().map(|s| s.name.as_str()).collect();
    let one = [
        "chamber",
        "wait_temperature",
        "table",
        "wait",
        "record",
        "chamber",
        "record",
        "wait_temperature",
        "record",
        "table_stop",
    ];
    assert_eq!(names, [one, one].concat());

    // Timeline from the table reaching its rate: 2 min settle, 3 min plateau at 20 °C (the
    // seed's samples 2400..6000), a 5 min ramp at 4 °C/min, 2 min plateau at 40 °C
    // (12000..14400) once the air has settled on 40 °C.
    assert_eq!(p.steps[3].action, Action::Wait { duration: min(2) });
    assert_eq!(p.steps[5].action, Action::Chamber { target_c: 40.0, ramp_c_s: Some(4.0 / 60.0) });
    let ramp_s = 20.0 / (4.0 / 60.0);
    assert!((ramp_s - 300.0_f64).abs() < 1e-9);
    assert!(matches!(
        p.steps[1].action,
        Action::WaitTemperature { source: TempSource::Gyro, target_c, .. } if target_c == 20.0
    ));
    // The second rotation starts by cooling back to 20 °C at full speed.
    assert!(matches!(
        p.steps[7].action,
        Action::WaitTemperature { source: TempSource::Air, target_c, .. } if target_c == 40.0
    ));
    assert_eq!(p.steps[10].action, Action::Chamber { target_c: 20.0, ramp_c_s: None });
    assert_eq!(p.steps[10].origin, format!("{}:44:3", scenario("seed.toml").display()));
}

#[test]
fn thermal_full_covers_the_working_range_in_about_14_hours() {
    let p = load_ok("thermal-full.toml", &st1300());
    let recs = records(&p);
    let plateau: Vec<&str> = recs.iter().filter(|r| !r.2).map(|r| r.0.as_str()).collect();
    let mut expected = Vec::new();
    for t in [-40, -20, 0, 20, 40, 60] {
        expected.push(format!("record cw {t}C"));
        expected.push(format!("record ccw {t}C"));
    }
    assert_eq!(plateau, expected);
    assert!(recs.iter().filter(|r| !r.2).all(|r| r.1 == Duration::from_secs(600)));
    let ramps: Vec<&str> = recs.iter().filter(|r| r.2).map(|r| r.0.as_str()).collect();
    assert_eq!(
        ramps,
        [
            "record cw ramp 60C to -40C",
            "record cw ramp -40C to 60C",
            "record ccw ramp 60C to -40C",
            "record ccw ramp -40C to 60C",
        ]
    );
    // Ramps at 1 °C/min; every chamber target within -40..+60 °C.
    for s in &p.steps {
        if let Action::Chamber { target_c, ramp_c_s } = s.action {
            assert!((-40.0..=60.0).contains(&target_c));
            if let Some(r) = ramp_c_s {
                assert!((r - 1.0 / 60.0).abs() < 1e-15);
            }
        }
    }
    // CW and CCW alternate, CW negative.
    let rates = table_rates(&p);
    assert_eq!(rates.len(), 6 * 2 + 2);
    for pair in rates.chunks(2) {
        assert!(pair[0] < 0.0 && pair[1] > 0.0 && (pair[0] + pair[1]).abs() < 1e-18);
    }
    // Fixed waits, holds and ramps ≈ 10.2 h; the chamber air's lag and the gyro's 300 s
    // thermal lag behind it add ≈ 3.5 h of soaking (the estimate simulates both).
    let h = p.estimated_duration().as_secs_f64() / 3600.0;
    assert!((13.0..=14.5).contains(&h), "{h} h");
}

#[test]
fn shipped_scenarios_validate_against_the_simulator() {
    let caps = Capabilities::from(bench_sim::default_infos());
    for name in ["seed.toml", "thermal-full.toml"] {
        let p = load_ok(name, &caps);
        assert_eq!(p, load_ok(name, &st1300()), "{name}: same plan for both capability sets");
    }
}

#[test]
fn shipped_scenarios_fail_on_a_slower_chamber_with_located_errors() {
    // A chamber that heats at 3 °C/min cannot run the seed's 4 °C/min ramp.
    let mut caps = st1300();
    caps.chamber.capabilities.max_heat_rate_c_s = 3.0 / 60.0;
    let e = load(&scenario("seed.toml"), &caps).expect_err("too slow");
    let path = scenario("seed.toml").display().to_string();
    assert_eq!(
        e.to_string(),
        format!(
            "{path}:71:10: chamber ramp 4 °C/min (heating from 20 to 40 °C) exceeds the \
             chamber's maximum heating rate 3 °C/min (in loop: dir = cw)"
        )
    );
    // A gyro rated only to +50 °C: thermal-full's 60 °C steps are rejected, each once.
    let mut caps = st1300();
    caps.gyro.capabilities.operating_temp_c = (-40.0, 50.0);
    let e = load(&scenario("thermal-full.toml"), &caps).expect_err("too hot");
    let msgs = e.to_string();
    assert!(
        msgs.lines().all(|l| l.contains("is outside the gyro's operating range -40..50 °C")),
        "{msgs}"
    );
    assert!(msgs.lines().count() >= 3, "{msgs}");
}

#[test]
fn complete_examples_in_the_docs_validate() {
    let doc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/scenario.md");
    let doc = std::fs::read_to_string(&doc_path).expect("docs/scenario.md");
    let mut checked = 0;
    for block in doc.split("```toml\n").skip(1) {
        let text = block.split("```").next().unwrap_or("");
        if !text.starts_with("[scenario]") {
            continue; // a fragment
        }
        if let Err(e) = bench::scenario::parse(text, "docs/scenario.md", &st1300()) {
            panic!("example does not validate:\n{text}\n{e}");
        }
        checked += 1;
    }
    assert_eq!(checked, 2);
}

mod mutations {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 1500, ..ProptestConfig::default() })]

        /// The shipped scenarios with random edits (deleted, replaced and inserted characters)
        /// never panic, and every error is located inside the text.
        #[test]
        fn mutated_shipped_scenarios_never_panic(
            which in 0usize..2,
            edits in proptest::collection::vec(
                (any::<proptest::sample::Index>(), 0u8..3, proptest::char::any()),
                1..6,
            ),
        ) {
            let name = ["seed.toml", "thermal-full.toml"][which];
            let original = std::fs::read_to_string(scenario(name)).expect("read");
            let mut chars: Vec<char> = original.chars().collect();
            for (at, kind, c) in edits {
                if chars.is_empty() {
                    break;
                }
                let i = at.index(chars.len());
                match kind {
                    0 => {
                        chars.remove(i);
                    }
                    1 => chars[i] = c,
                    _ => chars.insert(i, c),
                }
            }
            let text: String = chars.into_iter().collect();
            if let Err(e) = bench::scenario::parse(&text, name, &st1300()) {
                prop_assert!(!e.is_empty());
                for err in e.iter() {
                    prop_assert!(err.span.start <= text.len());
                    prop_assert!(err.line >= 1 && err.column >= 1);
                }
            }
        }
    }
}
