//! Scenario parser tests: every validation error kind with its message, line and column; loop
//! expansion; unit conversions; garbage never panics.

use std::time::Duration;

use bench_drivers::{ChamberCapabilities, DeviceInfo, GyroCapabilities, TableCapabilities};
use bench_physics::units::{DEG, DEG_PER_MIN};
use proptest::prelude::*;

use super::*;
use crate::plan::{Action, TempSource};

fn info<C>(capabilities: C) -> DeviceInfo<C> {
    DeviceInfo { model: "test".into(), driver: "test".into(), capabilities }
}

/// ST1300-class table, its chamber, and a FOG with the seed's working range.
pub(crate) fn caps() -> Capabilities {
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

const HEAD: &str = "[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 59.94\n";

/// HEAD (4 lines) + `body`: line numbers of `body` start at 5.
fn with_head(body: &str) -> String {
    format!("{HEAD}{body}")
}

fn ok(body: &str) -> RunPlan {
    match parse(&with_head(body), "t.toml", &caps()) {
        Ok(p) => p,
        Err(e) => panic!("expected a valid scenario, got:\n{e}"),
    }
}

fn errs(text: &str) -> Vec<String> {
    match parse(text, "t.toml", &caps()) {
        Ok(_) => panic!("expected errors for:\n{text}"),
        Err(e) => e.iter().map(ToString::to_string).collect(),
    }
}

/// The single error of HEAD + `body`.
fn err1(body: &str) -> String {
    let e = errs(&with_head(body));
    assert_eq!(e.len(), 1, "expected one error, got {e:#?}");
    e.into_iter().next().unwrap_or_default()
}

// ------------------------------------------------------------------ valid scenarios

#[test]
fn minimal_scenario_gets_the_documented_defaults() {
    let p = ok("[[step]]\nwait = \"1 s\"\n");
    assert_eq!(p.name, "t");
    assert_eq!(p.source, "t.toml");
    assert_eq!(p.site.latitude_deg, 59.94);
    assert!(p.site.axis_up());
    assert_eq!(p.site.longitude_deg, None);
    assert_eq!(p.gyro.sample_rate_hz, 20.0);
    assert_eq!(p.gyro.model, bench_physics::GyroModel::default());
    assert_eq!(p.sim.truth, p.gyro.model);
    assert_eq!(p.sim.initial_temp_c, 20.0);
    assert_eq!(p.table_poll_hz, 20.0);
    assert_eq!(p.chamber_poll_hz, 20.0);
    assert_eq!(p.safe_temp_c, 20.0);
    assert!((p.safe_decel_rad_s2 - 10.0 * DEG).abs() < 1e-15);
    assert_eq!(p.steps.len(), 1);
    assert_eq!(p.steps[0].name, "wait");
    assert_eq!(p.steps[0].origin, "t.toml:6:1");
    assert_eq!(p.steps[0].action, Action::Wait { duration: Duration::from_secs(1) });
}

#[test]
fn every_setting_is_read() {
    let p = ok(r#"longitude_deg = 30.31
height_m = 10.5
axis = "down"
[gyro]
sample_rate_hz = 100
[gyro.model]
bias = 1e-6
earth_rate = false
temp_coeff = 2e-9
[table]
poll_rate = "50 Hz"
accel = "20 °/s²"
[chamber]
poll_rate_hz = 5
[safe]
decel_rad_s2 = 0.5
temperature_c = 25
[simulation]
initial_temp = "-10 °C"
[simulation.truth]
temp_coeff = 3e-9
[[step]]
spin_rad_s = 0.1
direction = "ccw"
settle = false
"#);
    assert_eq!(p.site.longitude_deg, Some(30.31));
    assert_eq!(p.site.height_m, Some(10.5));
    assert!(!p.site.axis_up());
    assert_eq!(p.gyro.sample_rate_hz, 100.0);
    assert_eq!(p.gyro.model.bias, 1e-6);
    assert!(!p.gyro.model.earth_rate);
    assert_eq!(p.gyro.model.temp_coeff, 2e-9);
    // Other keys keep GyroModel::default().
    assert_eq!(p.gyro.model.arw, bench_physics::GyroModel::default().arw);
    // The truth starts from the nominal model and overrides its own keys.
    assert_eq!(p.sim.truth.bias, 1e-6);
    assert_eq!(p.sim.truth.temp_coeff, 3e-9);
    assert_eq!(p.sim.initial_temp_c, -10.0);
    assert_eq!(p.table_poll_hz, 50.0);
    assert_eq!(p.chamber_poll_hz, 5.0);
    assert_eq!(p.safe_decel_rad_s2, 0.5);
    assert_eq!(p.safe_temp_c, 25.0);
    assert_eq!(
        p.steps[0].action,
        Action::Table { rate_rad_s: 0.1, accel_rad_s2: 20.0 * DEG, settle: false }
    );
}

#[test]
fn cw_is_negative_and_units_convert() {
    let p = ok(r#"[[step]]
spin = "10 °/min"
direction = "cw"
accel = "2 deg/s2"
[[step]]
spin = "15 deg/h"
direction = "CCW"
[[step]]
spin = "0.5 rad/s"
direction = "ccw"
accel = "1 rad/s²"
[[step]]
stop = "table"
decel = "5 °/s²"
"#);
    let Action::Table { rate_rad_s, accel_rad_s2, settle } = p.steps[0].action else {
        panic!("table step")
    };
    assert!((rate_rad_s + 2.9089e-3).abs() < 1e-7, "{rate_rad_s}");
    assert_eq!(rate_rad_s, -10.0 * DEG_PER_MIN);
    assert_eq!(accel_rad_s2, 2.0 * DEG);
    assert!(settle);
    assert!(
        matches!(p.steps[1].action, Action::Table { rate_rad_s, .. } if (rate_rad_s - 15.0 * DEG / 3600.0).abs() < 1e-18)
    );
    assert!(
        matches!(p.steps[2].action, Action::Table { rate_rad_s, accel_rad_s2, .. } if rate_rad_s == 0.5 && accel_rad_s2 == 1.0)
    );
    assert_eq!(p.steps[3].name, "table_stop");
    assert_eq!(p.steps[3].action, Action::TableStop { decel_rad_s2: 5.0 * DEG });
}

#[test]
fn chamber_waits_and_records() {
    let p = ok(r#"[[step]]
chamber = "40 °C"
ramp = "2 °C/min"
[[step]]
label = "record heat"
record = "ramp end"
[[step]]
chamber_c = 30
[[step]]
wait = "ramp end"
timeout = "1 h"
[[step]]
wait_temperature = "30 °C"
band = "0.5 K"
hold = "10 min"
timeout = "2 h"
[[step]]
wait_temperature_c = 30
source = "gyro"
band_c = 0.2
hold_s = 60
timeout_s = 600
[[step]]
label = "record 30C"
record_s = 90
[[step]]
wait_s = 2.5
"#);
    let a: Vec<&Action> = p.steps.iter().map(|s| &s.action).collect();
    assert_eq!(*a[0], Action::Chamber { target_c: 40.0, ramp_c_s: Some(2.0 / 60.0) });
    // Default timeout of a ramp-end wait: twice the ramp's 600 s plus 30 min.
    assert_eq!(*a[1], Action::Record { duration: Duration::from_secs(3000), until_ramp_end: true });
    assert_eq!(p.steps[1].label, "record heat");
    assert_eq!(*a[2], Action::Chamber { target_c: 30.0, ramp_c_s: None });
    assert_eq!(*a[3], Action::WaitRampEnd { timeout: Duration::from_secs(3600) });
    assert_eq!(p.steps[3].name, "wait_ramp_end");
    assert_eq!(
        *a[4],
        Action::WaitTemperature {
            source: TempSource::Air,
            target_c: 30.0,
            band_c: 0.5,
            hold: Duration::from_secs(600),
            timeout: Duration::from_secs(7200),
        }
    );
    assert!(
        matches!(a[5], Action::WaitTemperature { source: TempSource::Gyro, band_c, .. } if *band_c == 0.2)
    );
    assert_eq!(*a[6], Action::Record { duration: Duration::from_secs(90), until_ramp_end: false });
    assert_eq!(*a[7], Action::Wait { duration: Duration::from_millis(2500) });
}

#[test]
fn loops_expand_in_order_with_substitution() {
    let p = ok(r#"[[step]]
label = "a loop"
for.temp = [-20, "0", 20.5]
for.dir = ["cw", "ccw"]
  [[step.do]]
  chamber = "{temp} °C"
  [[step.do]]
  spin = "10 °/min"
  direction = "{dir}"
  label = "spin {dir} at {temp}C {{literal}}"
  [[step.do]]
  for.n = [1, 2]
    [[step.do.do]]
    label = "record {dir} {temp}C #{n}"
    record = "{n} min"
[[step]]
wait = "1 s"
"#);
    let labels: Vec<&str> = p.steps.iter().map(|s| s.label.as_str()).collect();
    // temp outermost (written first), dir inside it, n innermost.
    assert_eq!(p.steps.len(), 3 * 2 * 4 + 1);
    assert_eq!(
        &labels[..4],
        ["", "spin cw at -20C {literal}", "record cw -20C #1", "record cw -20C #2"]
    );
    assert_eq!(labels[5], "spin ccw at -20C {literal}");
    assert_eq!(labels[23], "record ccw 20.5C #2");
    assert_eq!(p.steps[0].action, Action::Chamber { target_c: -20.0, ramp_c_s: None });
    assert_eq!(p.steps[16].action, Action::Chamber { target_c: 20.5, ramp_c_s: None });
    assert!(matches!(p.steps[5].action, Action::Table { rate_rad_s, .. } if rate_rad_s > 0.0));
    assert_eq!(
        p.steps[3].action,
        Action::Record { duration: Duration::from_secs(120), until_ramp_end: false }
    );
    for (i, s) in p.steps.iter().enumerate() {
        assert_eq!(s.index, i);
    }
    // Origins name the step's line in the file, the same for every iteration.
    assert_eq!(p.steps[0].origin, "t.toml:10:3");
    assert_eq!(p.steps[4].origin, "t.toml:10:3");
    assert_eq!(p.steps[2].origin, "t.toml:19:5");
    assert_eq!(p.steps[24].name, "wait");
}

// ------------------------------------------------------------------ TOML, structure, keys

#[test]
fn toml_syntax_error_is_located() {
    let e = errs("[scenario]\nname = \"t\"\n[site]\nlatitude_deg = = 5\n");
    assert!(e[0].starts_with("t.toml:4:16: TOML syntax:"), "{e:?}");
}

#[test]
fn unknown_keys_are_rejected_with_the_allowed_ones() {
    assert_eq!(
        err1("[[step]]\nchamber = \"20 °C\"\nrmap = \"1 °C/min\"\n"),
        "t.toml:7:1: unknown key `rmap` in a `chamber` step; did you mean `ramp`? allowed: \
         `chamber`, `chamber_c`, `ramp`, `ramp_c_s`, `label`"
    );
    let e = errs("[scenario]\nname = \"t\"\ncolour = 1\n[site]\nlatitude_deg = 1\n[stie]\n[[step]]\nwait = \"1 s\"\n");
    assert_eq!(e.len(), 2, "{e:?}");
    assert!(e[0].starts_with(
        "t.toml:3:1: unknown key `colour` in [scenario]; allowed: `name`, `description`"
    ));
    assert!(
        e[1].starts_with(
            "t.toml:6:2: unknown key `stie` in the scenario file; did you mean `site`?"
        ),
        "{}",
        e[1]
    );
}

#[test]
fn missing_sections_and_steps() {
    let e = errs("[[step]]\nwait = \"1 s\"\n");
    assert_eq!(
        e,
        [
            "t.toml:1:1: missing [scenario] section with `name`",
            "t.toml:1:1: missing [site] section with `latitude_deg` (needed for Earth rate)",
        ]
    );
    assert_eq!(err1(""), "t.toml:1:1: the scenario has no steps: add [[step]] tables");
    let e =
        errs("[scenario]\ndescription = \"x\"\n[site]\naxis = \"up\"\n[[step]]\nwait = \"1 s\"\n");
    assert_eq!(
        e,
        [
            "t.toml:1:1: [scenario] needs `name`",
            "t.toml:3:1: [site] needs `latitude_deg` (degrees, north positive)",
        ]
    );
}

#[test]
fn step_without_or_with_two_actions() {
    assert_eq!(
        err1("[[step]]\nlabel = \"x\"\n"),
        "t.toml:5:1: step has no action: give one of `chamber`, `spin`, `stop`, `wait`, \
         `wait_temperature`, `record` or `for`"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"1 s\"\nchamber = \"20 °C\"\n"),
        "t.toml:7:1: one action per step: this step has both `wait` and `chamber`"
    );
}

#[test]
fn wrong_types() {
    assert_eq!(
        err1("axis = 1\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:5:8: `axis` must be a string, got a number"
    );
    assert_eq!(
        err1("[[step]]\nwait = 600\n"),
        "t.toml:6:8: `wait` takes a quantity with a unit, like \"10 min\" (units: s, min, h, \
         ms); for a plain number in s write `wait_s = 600`"
    );
    assert_eq!(
        err1("[[step]]\nwait_s = \"10 min\"\n"),
        "t.toml:6:10: `wait_s` takes a plain number in s, got a string; for units write `wait = \"10 min\"`"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"1 s\"\nwait_s = 1\n"),
        "t.toml:7:1: give either `wait` or `wait_s`, not both"
    );
    assert_eq!(
        err1("[[step]]\nspin = \"1 °/s\"\ndirection = \"cw\"\nsettle = \"yes\"\n"),
        "t.toml:8:10: `settle` must be true or false, got a string"
    );
    assert_eq!(
        errs("step = 3\n[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 1\n"),
        ["t.toml:1:8: `step` must be an array of tables ([[step]]), got a number"]
    );
}

#[test]
fn wrong_units_say_which_are_allowed() {
    assert_eq!(
        err1("[[step]]\nspin = \"10 rpm\"\ndirection = \"cw\"\n"),
        "t.toml:6:8: `spin`: unit `rpm` is not allowed here; allowed units: °/s, °/min, °/h, \
         deg/s, deg/min, deg/h, rad/s"
    );
    assert_eq!(
        err1("[[step]]\nchamber = \"300 K\"\n"),
        "t.toml:6:11: `chamber`: unit `K` is not allowed here; allowed units: °C, C, degC"
    );
    assert_eq!(
        err1("[[step]]\nchamber = \"40 °C\"\nramp = \"1 °C\"\n"),
        "t.toml:7:8: `ramp`: unit `°C` is not allowed here; allowed units: C/s, C/min, C/h, \
         °C/s, °C/min, °C/h"
    );
    assert_eq!(
        err1("[gyro]\nsample_rate = \"20\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:15: `sample_rate`: \"20\" has no unit; allowed units: Hz, kHz"
    );
}

// ------------------------------------------------------------------ capabilities

#[test]
fn table_rate_above_the_tables_maximum() {
    assert_eq!(
        err1("[[step]]\nspin = \"2000 °/s\"\ndirection = \"cw\"\n"),
        "t.toml:6:8: table rate 2000 °/s exceeds the table's maximum 1000 °/s"
    );
    // In the user's unit.
    assert_eq!(
        err1("[[step]]\nspin = \"20 rad/s\"\ndirection = \"cw\"\n"),
        "t.toml:6:8: table rate 20 rad/s exceeds the table's maximum 17.4533 rad/s"
    );
}

#[test]
fn table_rate_above_the_gyros_input_range() {
    assert_eq!(
        err1("[[step]]\nspin = \"600 °/s\"\ndirection = \"ccw\"\n"),
        "t.toml:6:8: table rate 600 °/s exceeds the gyro's input range 500 °/s"
    );
}

#[test]
fn acceleration_above_the_tables_maximum_or_not_positive() {
    assert_eq!(
        err1("[[step]]\nspin = \"1 °/s\"\ndirection = \"cw\"\naccel = \"1500 °/s²\"\n"),
        "t.toml:8:9: table acceleration 1500 °/s² exceeds the table's maximum 1000 °/s²"
    );
    assert_eq!(
        err1("[[step]]\nstop = \"table\"\ndecel = \"0 °/s²\"\n"),
        "t.toml:7:9: table deceleration must be greater than zero, got 0 °/s²"
    );
    assert_eq!(
        err1("[safe]\ndecel = \"2000 deg/s2\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:9: safe-state deceleration 2000 deg/s2 exceeds the table's maximum 1000 deg/s2"
    );
    assert_eq!(
        err1("[table]\naccel = \"1001 °/s²\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:9: default table acceleration 1001 °/s² exceeds the table's maximum 1000 °/s²"
    );
}

#[test]
fn spin_direction_rules() {
    assert_eq!(
        err1("[[step]]\nspin = \"10 °/min\"\n"),
        "t.toml:6:1: a spin needs `direction = \"cw\"` (clockwise seen from above, negative \
         rate) or `\"ccw\"`"
    );
    assert_eq!(
        err1("[[step]]\nspin = \"10 °/min\"\ndirection = \"left\"\n"),
        "t.toml:7:13: direction must be \"cw\" or \"ccw\", got \"left\""
    );
    assert_eq!(
        err1("[[step]]\nspin = \"-10 °/min\"\ndirection = \"cw\"\n"),
        "t.toml:6:8: give the rate's magnitude and set `direction`, got -10 °/min"
    );
    // Zero needs no direction.
    let p = ok("[[step]]\nspin = \"0 °/s\"\n");
    assert_eq!(
        p.steps[0].action,
        Action::Table { rate_rad_s: 0.0, accel_rad_s2: 10.0 * DEG, settle: true }
    );
}

#[test]
fn temperatures_outside_the_gyro_or_chamber_range() {
    assert_eq!(
        err1("[[step]]\nchamber = \"70 °C\"\n"),
        "t.toml:6:11: chamber target 70 °C is outside the gyro's operating range -40..60 °C"
    );
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"-45 °C\"\nband = \"1 °C\"\nhold = \"1 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:6:20: temperature -45 °C is outside the gyro's operating range -40..60 °C"
    );
    assert_eq!(
        err1("[safe]\ntemperature = \"61 C\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:15: safe-state temperature 61 C is outside the gyro's operating range -40..60 °C"
    );
    // A gyro rated wider than the chamber: the chamber's range applies.
    let mut c = caps();
    c.gyro.capabilities.operating_temp_c = (-80.0, 100.0);
    let e =
        parse(&with_head("[[step]]\nchamber = \"-60 °C\"\n"), "t.toml", &c).expect_err("too cold");
    assert_eq!(
        e.to_string(),
        "t.toml:6:11: chamber target -60 °C is outside the chamber's range -55..185 °C"
    );
}

#[test]
fn ramp_faster_than_the_chamber_heats_or_cools() {
    assert_eq!(
        err1("[[step]]\nchamber = \"40 °C\"\nramp = \"6 °C/min\"\n"),
        "t.toml:7:8: chamber ramp 6 °C/min (heating from 20 to 40 °C) exceeds the chamber's \
         maximum heating rate 5 °C/min"
    );
    // 4 °C/min heats but does not cool (3.5 °C/min).
    ok("[[step]]\nchamber = \"40 °C\"\nramp = \"4 °C/min\"\n");
    assert_eq!(
        err1("[[step]]\nchamber = \"40 °C\"\n[[step]]\nchamber = \"0 °C\"\nramp = \"4 °C/min\"\n"),
        "t.toml:9:8: chamber ramp 4 °C/min (cooling from 40 to 0 °C) exceeds the chamber's \
         maximum cooling rate 3.5 °C/min"
    );
    assert_eq!(
        err1("[[step]]\nchamber = \"40 °C\"\nramp = \"0 °C/min\"\n"),
        "t.toml:7:8: ramp must be greater than zero, got 0 °C/min"
    );
}

#[test]
fn sample_rate_not_offered_by_the_gyro() {
    assert_eq!(
        err1("[gyro]\nsample_rate = \"25 Hz\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:15: gyro sample rate 25 Hz is not offered by the gyro; it offers 1, 2, 5, 10, \
         20, 50, 100, 200, 500, 1000, 2000 Hz"
    );
    ok("[gyro]\nsample_rate = \"2 kHz\"\n[[step]]\nwait = \"1 s\"\n");
    // The default 20 Hz must be offered too.
    let mut c = caps();
    c.gyro.capabilities.sample_rates_hz = vec![100.0];
    let e = parse(&with_head("[[step]]\nwait = \"1 s\"\n"), "t.toml", &c).expect_err("20 Hz");
    assert_eq!(
        e.to_string(),
        "t.toml:1:1: gyro sample rate 20 Hz is not offered by the gyro; it offers 100 Hz"
    );
}

#[test]
fn record_labels_must_start_with_record() {
    assert_eq!(
        err1("[[step]]\nrecord = \"1 min\"\nlabel = \"cw 20C\"\n"),
        "t.toml:7:9: the label of a record step must start with `record` (e.g. \"record cw \
         20C\"), got \"cw 20C\""
    );
    assert_eq!(
        err1("[[step]]\nrecord = \"1 min\"\n"),
        "t.toml:6:1: a record step needs a label starting with `record`, e.g. \"record cw 20C\""
    );
    assert_eq!(
        err1("[[step]]\nwait = \"1 min\"\nlabel = \"recording warm-up\"\n"),
        "t.toml:7:9: label \"recording warm-up\" starts with `record`, which marks a calibration \
         window; only `record` steps may have such labels"
    );
}

#[test]
fn durations_and_bands_must_be_positive() {
    assert_eq!(
        err1("[[step]]\nwait = \"0 s\"\n"),
        "t.toml:6:8: wait must be greater than zero, got 0 s"
    );
    assert_eq!(
        err1("[[step]]\nlabel = \"record x\"\nrecord = \"-1 min\"\n"),
        "t.toml:7:10: record window must be greater than zero, got -1 min"
    );
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"20 °C\"\nband = \"0 °C\"\nhold = \"1 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:7:8: band must be greater than zero, got 0 °C"
    );
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"20 °C\"\nband = \"1 °C\"\nhold = \"0 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:8:8: hold must be greater than zero, got 0 min"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"2 years\"\n"),
        "t.toml:6:8: `wait`: unit `years` is not allowed here; allowed units: s, min, h, ms"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"9000 h\"\n"),
        "t.toml:6:8: wait 9000 h is longer than a year"
    );
    assert_eq!(
        err1("[gyro]\nsample_rate_hz = 0\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:18: gyro sample rate must be greater than zero, got 0 Hz"
    );
}

#[test]
fn wait_temperature_rules() {
    assert_eq!(
        errs(&with_head("[[step]]\nwait_temperature = \"20 °C\"\n"))[0],
        "t.toml:6:1: `wait_temperature` needs `band` (half-width, e.g. \"0.5 °C\")"
    );
    let e = errs(&with_head("[[step]]\nwait_temperature = \"20 °C\"\nband = \"1 C\"\n"));
    assert_eq!(
        e,
        [
            "t.toml:6:1: `wait_temperature` needs `hold` (e.g. \"10 min\")",
            "t.toml:6:1: `wait_temperature` needs `timeout` (e.g. \"2 h\")",
        ]
    );
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"20 °C\"\nband = \"1 °C\"\nhold = \"10 min\"\ntimeout = \"5 min\"\n"),
        "t.toml:9:11: timeout 5 min is shorter than hold 10 min; the wait could never succeed"
    );
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"20 °C\"\nsource = \"coil\"\nband = \"1 °C\"\nhold = \"1 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:7:10: source must be \"air\" or \"gyro\", got \"coil\""
    );
    // The chamber is at its initial 20 °C: 40 °C never comes.
    assert_eq!(
        err1("[[step]]\nwait_temperature = \"40 °C\"\nband = \"1 °C\"\nhold = \"1 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:6:20: waiting for 40 °C ± 1 °C can never succeed: the chamber is set to 20 °C at this point"
    );
    // During a ramp 20 → 40 °C, 30 °C is passed through: allowed.
    ok("[[step]]\nchamber = \"40 °C\"\nramp = \"1 °C/min\"\n[[step]]\nwait_temperature = \"30 °C\"\nband = \"1 °C\"\nhold = \"1 min\"\ntimeout = \"1 h\"\n");
}

#[test]
fn ramp_end_needs_a_ramp() {
    assert_eq!(
        err1("[[step]]\nwait = \"ramp end\"\n"),
        "t.toml:6:1: wait until \"ramp end\", but no chamber step starts a ramp before it (or its \
         end was already waited for)"
    );
    assert_eq!(
        err1("[[step]]\nchamber = \"30 °C\"\n[[step]]\nwait = \"ramp end\"\n[[step]]\nlabel = \"record x\"\nrecord = \"ramp end\"\n"),
        "t.toml:11:1: record until \"ramp end\", but no chamber step starts a ramp before it (or \
         its end was already waited for)"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"1 min\"\ntimeout = \"1 h\"\n"),
        "t.toml:7:1: `timeout` only applies to \"ramp end\""
    );
}

#[test]
fn site_values_are_checked() {
    let e = errs("[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 95\nlongitude_deg = \"east\"\naxis = \"sideways\"\n[[step]]\nwait = \"1 s\"\n");
    assert_eq!(
        e,
        [
            "t.toml:4:16: latitude_deg 95 is outside -90..90",
            "t.toml:5:17: `longitude_deg` must be a number, got a string",
            "t.toml:6:8: axis must be \"up\" or \"down\", got \"sideways\"",
        ]
    );
}

#[test]
fn a_model_is_checked_as_the_model_file_checks_it() {
    // One validation (`ModelKey::check`): a scale factor 1 + error must stay positive, in the
    // nominal model and in the simulator's truth alike.
    for section in ["[gyro.model]", "[simulation.truth]"] {
        let e = err1(&format!("{section}\nscale_factor_error = -1.5\n[[step]]\nwait = \"1 s\"\n"));
        assert!(e.ends_with("`scale_factor_error` must be finite and above -1, got -1.5"), "{e}");
    }
}

#[test]
fn gyro_model_keys_are_the_contracts() {
    let e = errs(&with_head("[gyro.model]\nbias = \"1 °/h\"\narw = -1.0\ntemp_cof = 1\nearth_rate = 2\n[[step]]\nwait = \"1 s\"\n"));
    assert_eq!(e.len(), 4, "{e:#?}");
    assert_eq!(e[0], "t.toml:6:8: `bias` must be a finite number in the contract's SI unit");
    assert_eq!(e[1], "t.toml:7:7: `arw` must be finite and not negative, got -1");
    assert!(
        e[2].starts_with(
            "t.toml:8:1: unknown key `temp_cof` in [gyro.model]; did you mean `temp_coeff`?"
        ),
        "{}",
        e[2]
    );
    assert_eq!(e[3], "t.toml:9:14: `earth_rate` must be true/false (or 1/0)");
}

#[test]
fn loop_errors() {
    assert_eq!(
        err1("[[step]]\nchamber = \"{temp} °C\"\n"),
        "t.toml:6:11: `{temp}` is not a loop variable: no `for` step encloses this one"
    );
    assert_eq!(
        err1("[[step]]\nfor.temp = [20]\n[[step.do]]\nchamber = \"{tmep} °C\"\n"),
        "t.toml:8:11: unknown loop variable `{tmep}`; defined here: {temp} (in loop: temp = 20)"
    );
    assert_eq!(
        err1("[[step]]\nfor.temp = []\n[[step.do]]\nwait = \"1 s\"\n"),
        "t.toml:6:12: loop variable `temp` has an empty list"
    );
    assert_eq!(
        err1("[[step]]\nfor.temp = [20]\n"),
        "t.toml:5:1: a `for` step needs steps to repeat: add [[step.do]] tables"
    );
    assert_eq!(
        err1("[[step]]\nfor.t = [1]\n[[step.do]]\nfor.t = [2]\n[[step.do.do]]\nwait = \"1 s\"\n"),
        "t.toml:8:5: loop variable `t` is already defined by an enclosing loop (in loop: t = 1)"
    );
    assert_eq!(
        err1("[[step]]\nfor.t = [true]\n[[step.do]]\nwait = \"1 s\"\n"),
        "t.toml:6:10: loop values must be numbers or strings, got a boolean"
    );
    assert_eq!(
        err1("[[step]]\nwait = \"1 s\"\nlabel = \"x {\"\n"),
        "t.toml:7:9: unclosed `{` in \"x {\" (write `{{` for a literal brace)"
    );
}

#[test]
fn a_loop_reports_each_distinct_error_once() {
    // 70 °C is bad (once, naming its iteration); the bad unit is reported once, not per iteration.
    let e = errs(&with_head(
        "[[step]]\nfor.temp = [20, 70, 80]\n[[step.do]]\nchamber = \"{temp} °C\"\n[[step.do]]\nwait = \"1 furlong\"\n",
    ));
    assert_eq!(
        e,
        [
            "t.toml:8:11: chamber target 70 °C is outside the gyro's operating range -40..60 °C (in loop: temp = 70)",
            "t.toml:8:11: chamber target 80 °C is outside the gyro's operating range -40..60 °C (in loop: temp = 80)",
            "t.toml:10:8: `wait`: unit `furlong` is not allowed here; allowed units: s, min, h, ms (in loop: temp = 20)",
        ]
    );
}

#[test]
fn expansion_is_bounded() {
    let list = (0..100).map(|i| i.to_string()).collect::<Vec<_>>().join(",");
    let text = with_head(&format!(
        "[[step]]\nfor.a = [{list}]\nfor.b = [{list}]\nfor.c = [{list}]\n[[step.do]]\nwait = \"1 s\"\n"
    ));
    let e = errs(&text);
    assert_eq!(e, [format!("t.toml:10:1: the scenario expands to more than {} steps (in loop: a = 10, b = 0, c = 0)", build::MAX_STEPS)]);
}

#[test]
fn all_errors_are_collected_in_file_order() {
    let text = "[scenario]\nname = \"\"\n[site]\nlatitude_deg = 100\n[[step]]\nspin = \"2000 °/s\"\ndirection = \"cw\"\n[[step]]\nchamber = \"99 °C\"\n";
    let e = errs(text);
    assert_eq!(e.len(), 4, "{e:#?}");
    let lines: Vec<&str> = e.iter().map(|m| m.split(": ").next().unwrap_or("")).collect();
    assert_eq!(lines, ["t.toml:2:8", "t.toml:4:16", "t.toml:6:8", "t.toml:9:11"]);
    assert_eq!(e[0], "t.toml:2:8: scenario name must not be empty");
}

#[test]
fn load_reads_files_and_reports_io_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, with_head("[[step]]\nwait = \"1 s\"\n")).expect("write");
    let plan = load(&path, &caps()).expect("loads");
    assert_eq!(plan.source, path.display().to_string());
    assert_eq!(plan.steps[0].origin, format!("{}:6:1", path.display()));
    let missing = dir.path().join("nope.toml");
    let e = load(&missing, &caps()).expect_err("missing file");
    assert!(matches!(e, LoadError::Io { .. }));
    assert!(e.to_string().starts_with(&format!("cannot read scenario {}:", missing.display())));
}

#[test]
fn a_file_that_is_not_utf8_is_located() {
    // Found by scripts/bad_inputs.py: "cannot read scenario …: stream did not contain valid
    // UTF-8", without a place.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("s.toml");
    std::fs::write(&path, b"[scenario]\nname = \"b\xFF\"\n").expect("write");
    let e = load(&path, &caps()).expect_err("not UTF-8");
    assert!(matches!(e, LoadError::Invalid(_)), "{e}");
    assert!(e.to_string().starts_with(&format!("{}:2:10: not UTF-8", path.display())), "{e}");
}

#[test]
fn substitute_handles_braces() {
    let vars = vec![("a".to_string(), "1".to_string()), ("bc".to_string(), "x y".to_string())];
    assert_eq!(build::substitute("{a}-{bc}", &vars), Ok("1-x y".to_string()));
    assert_eq!(build::substitute("{{a}} }}", &vars), Ok("{a} }".to_string()));
    assert!(build::substitute("a}", &vars).is_err());
    assert!(build::substitute("{", &vars).is_err());
    assert_eq!(build::substitute("plain", &[]), Ok("plain".to_string()));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Arbitrary text never panics.
    #[test]
    fn garbage_never_panics(text in "\\PC{0,300}") {
        let _ = parse(&text, "g.toml", &caps());
    }

    /// Text built from scenario-like fragments never panics, and errors always have a location
    /// inside the text.
    #[test]
    fn scenario_like_text_never_panics(
        parts in proptest::collection::vec(
            proptest::sample::select(vec![
                "[scenario]\n", "name = \"x\"\n", "[site]\n", "latitude_deg = 59.9\n",
                "[[step]]\n", "[[step.do]]\n", "[[step.do.do]]\n", "for.t = [1, \"2\", -3.5]\n",
                "chamber = \"{t} °C\"\n", "ramp = \"1e9 °C/min\"\n", "spin = \"1e308 rad/s\"\n",
                "direction = \"cw\"\n", "wait = \"ramp end\"\n", "record = \"nan s\"\n",
                "label = \"record {t}\"\n", "label = \"{\"\n", "wait_s = inf\n", "wait = \"-0 s\"\n",
                "wait_temperature = \"20 °C\"\n", "band = \"1 °C\"\n", "hold = \"1 min\"\n",
                "timeout = \"1 h\"\n", "[gyro]\n", "sample_rate_hz = 1e400\n", "[gyro.model]\n",
                "bias = nan\n", "x = [[[[1]]]]\n", "\"°\" = 1\n", "stop = \"table\"\n", "= \n",
                "a.b.c = 1\n", "[safe]\n", "temperature = \"-1e999 °C\"\n", "for = 3\n",
            ]),
            0..40,
        ),
    ) {
        let text: String = parts.concat();
        if let Err(e) = parse(&text, "g.toml", &caps()) {
            prop_assert!(!e.is_empty());
            for err in e.iter() {
                prop_assert!(err.span.start <= text.len());
                prop_assert!(err.line >= 1 && err.column >= 1);
            }
        }
    }
}

// ------------------------------------------------------------------ effects

#[test]
fn every_effect_is_parsed_into_the_truth_and_the_nominal_model() {
    use bench_physics::effects::*;
    // Chosen values for these; any effect added since is on at its parameters' examples.
    let listed = [
        EffectId::EarthRate,
        EffectId::ThermalLag,
        EffectId::TemperatureQuadratic,
        EffectId::ScaleFactorTemperature,
        EffectId::ThermalHysteresis,
        EffectId::OncePerRevolution,
        EffectId::TimeOffset,
        EffectId::WarmUp,
        EffectId::BiasStep,
        EffectId::RateSquared,
        EffectId::PeriodicBias,
        EffectId::RateRipple,
        EffectId::AngleHarmonic,
    ];
    let added: Vec<EffectId> =
        EffectId::ALL.into_iter().filter(|id| !listed.contains(id)).collect();
    let added_toml: String = added
        .iter()
        .map(|id| {
            let params: Vec<String> =
                id.params().iter().map(|p| format!("{} = {:e}", p.name, p.example())).collect();
            format!("{} = {{ {} }}\n", id.key(), params.join(", "))
        })
        .collect();
    let p = ok(&format!(
        r#"[gyro.model.effects]
rate_squared = {{ coeff_s_per_rad = 1e-3 }}
warm_up = {{ amplitude_rad_s = 5e-8, time_constant_s = 60 }}
[simulation.truth.effects]
earth_rate = true
thermal_lag = {{ time_constant_s = 300 }}
temperature_quadratic = {{ coeff_rad_s_per_c2 = 2e-11 }}
scale_factor_temperature = {{ coeff_per_c = -1e-6 }}
thermal_hysteresis = {{ half_width_rad_s = 4e-9, threshold_c_s = 0.001 }}
once_per_revolution = {{ amplitude_rad_s = 2e-8, phase_rad = 0.5 }}
time_offset = {{ offset_s = 0.01 }}
warm_up = {{ amplitude_rad_s = 1e-7, time_constant_s = 900 }}
bias_step = {{ time_s = 100, step_rad_s = 1e-6 }}
periodic_bias = {{ amplitude_rad_s = 3e-8, period_s = 1200, phase_rad = -1 }}
rate_ripple = {{ relative_amplitude = 1e-5, cycles_per_rev = 16, phase_rad = 0 }}
angle_harmonic = {{ amplitude_rad_s = 6e-8, cycles_per_rev = 2, phase_rad = -0.4 }}
{added_toml}[simulation.truth.effects.rate_squared]
coeff_s_per_rad = 2e-3
[[step]]
wait = "1 s"
"#
    ));
    let on = |list: &[(EffectId, &[f64])]| {
        let mut e = Effects::default();
        for (id, v) in list {
            e.set(*id, v).expect("count fits");
        }
        e
    };
    let nominal = on(&[(EffectId::RateSquared, &[1e-3]), (EffectId::WarmUp, &[5e-8, 60.0])]);
    assert_eq!(p.gyro.effects, nominal);
    let truth = on(&[
        (EffectId::EarthRate, &[]),
        (EffectId::ThermalLag, &[300.0]),
        (EffectId::TemperatureQuadratic, &[2e-11]),
        (EffectId::ScaleFactorTemperature, &[-1e-6]),
        (EffectId::ThermalHysteresis, &[4e-9, 0.001]),
        (EffectId::OncePerRevolution, &[2e-8, 0.5]),
        (EffectId::TimeOffset, &[0.01]),
        (EffectId::WarmUp, &[1e-7, 900.0]),
        (EffectId::BiasStep, &[100.0, 1e-6]),
        (EffectId::RateSquared, &[2e-3]),
        (EffectId::PeriodicBias, &[3e-8, 1200.0, -1.0]),
        (EffectId::RateRipple, &[1e-5, 16.0, 0.0]),
        (EffectId::AngleHarmonic, &[6e-8, 2.0, -0.4]),
    ]);
    let mut truth = truth;
    for id in added {
        let v: Vec<f64> = id.params().iter().map(Param::example).collect();
        truth.set(id, &v).expect("count fits");
    }
    assert_eq!(p.sim.truth_effects, truth);
    assert_eq!(p.sim.truth_effects.ids().len(), EffectId::ALL.len());
    // The base model is untouched by effects.
    assert_eq!(p.gyro.model, bench_physics::GyroModel::default());
}

#[test]
fn truth_effects_start_from_the_nominal_ones_and_false_switches_one_off() {
    let p = ok(r#"[gyro.model.effects]
earth_rate = true
bias_step = { time_s = 10, step_rad_s = 1e-7 }
rate_squared = { coeff_s_per_rad = 1e-3 }
[simulation.truth.effects]
bias_step = false
earth_rate = false
[[step]]
wait = "1 s"
"#);
    use bench_physics::effects::EffectId;
    assert!(p.gyro.effects.has(EffectId::EarthRate) && p.gyro.effects.has(EffectId::BiasStep));
    assert!(!p.sim.truth_effects.has(EffectId::EarthRate));
    assert_eq!(p.sim.truth_effects.get(EffectId::BiasStep), None);
    let rate_squared = EffectId::RateSquared;
    assert_eq!(p.sim.truth_effects.get(rate_squared), p.gyro.effects.get(rate_squared));
    // Without any effects table, none are on.
    let p = ok("[[step]]\nwait = \"1 s\"\n");
    assert!(!p.gyro.effects.any() && !p.sim.truth_effects.any());
}

#[test]
fn effect_errors_are_located() {
    // HEAD is 4 lines, the effects table header line 5, its entries from line 6.
    let head = "[simulation.truth.effects]\n";
    let step = "[[step]]\nwait = \"1 s\"\n";
    let e =
        err1(&format!("{head}warmup = {{ amplitude_rad_s = 1e-7, time_constant_s = 9 }}\n{step}"));
    assert!(
        e.starts_with(
            "t.toml:6:1: unknown effect `warmup` in [simulation.truth.effects]; did you mean \
             `warm_up`? known effects: `earth_rate`, `thermal_lag`,"
        ),
        "{e}"
    );
    let known: Vec<String> = bench_physics::effects::EffectId::ALL
        .into_iter()
        .map(|id| format!("`{}`", id.key()))
        .collect();
    assert!(e.ends_with(&known.join(", ")), "{e}");
    // An unknown parameter and the missing one are both reported.
    let e = errs(&with_head(&format!(
        "{head}warm_up = {{ amplitude_rad_s = 1e-7, tau_s = 9 }}\n{step}"
    )));
    assert_eq!(
        e,
        [
            "t.toml:6:11: effect `warm_up` needs `time_constant_s`; its parameters: \
             amplitude_rad_s, time_constant_s",
            "t.toml:6:37: unknown key `tau_s` in effect `warm_up`; allowed: `amplitude_rad_s`, \
             `time_constant_s`",
        ]
    );
    assert_eq!(
        err1(&format!("{head}bias_step = {{ time_s = \"100 s\", step_rad_s = 1e-6 }}\n{step}")),
        "t.toml:6:24: `time_s` must be a number, got a string"
    );
    assert_eq!(
        err1(&format!(
            "{head}once_per_revolution = {{ amplitude_rad_s = nan, phase_rad = 0 }}\n{step}"
        )),
        "t.toml:6:43: `amplitude_rad_s` must be a finite number"
    );
    assert_eq!(
        err1(&format!("{head}thermal_lag = {{ time_constant_s = 0 }}\n{step}")),
        "t.toml:6:35: `time_constant_s` of effect `thermal_lag` must be greater than zero, got 0"
    );
    assert_eq!(
        err1(&format!("[gyro.model.effects]\nwarm_up = {{ amplitude_rad_s = 1e-7, time_constant_s = -5 }}\n{step}")),
        "t.toml:6:55: `time_constant_s` of effect `warm_up` must be greater than zero, got -5"
    );
    assert_eq!(
        err1(&format!("{head}thermal_hysteresis = {{ half_width_rad_s = 1e-9, threshold_c_s = 0 }}\n{step}")),
        "t.toml:6:65: `threshold_c_s` of effect `thermal_hysteresis` must be greater than zero, got 0"
    );
    assert_eq!(
        err1(&format!("{head}earth_rate = 1\n{step}")),
        "t.toml:6:14: effect `earth_rate` must be true or false, got a number"
    );
    let e = err1(&format!("{head}rate_squared = 1e-3\n{step}"));
    assert!(
        e.starts_with(
            "t.toml:6:16: effect `rate_squared` must be a table of its parameters, like \
             `rate_squared = { coeff_s_per_rad = … }`, or false to switch it off; got a number"
        ),
        "{e}"
    );
    assert_eq!(
        err1(&format!("{head}time_offset = true\n{step}")),
        "t.toml:6:15: effect `time_offset` must be a table of its parameters, like \
         `time_offset = { offset_s = … }`, or false to switch it off; got a boolean"
    );
    assert_eq!(
        err1(&format!("[gyro.model]\neffects = 3\n{step}")),
        "t.toml:6:11: `effects` must be a table, got a number"
    );
}

#[test]
fn interlocks_are_parsed_with_defaults_from_the_devices() {
    let p = ok("[[step]]\nwait = \"1 s\"\n");
    let caps = crate::simulate::capabilities();
    assert_eq!(p.interlocks, crate::plan::Interlocks::defaults(&caps));
    // The simulated gyro is rated -40..60 °C: the air may go 5 °C beyond.
    assert_eq!((p.interlocks.chamber_min_temp_c, p.interlocks.chamber_max_temp_c), (-45.0, 65.0));
    let p = ok("[interlocks]\ntable_max_rate = \"20 °/min\"\nrate_tolerance = \"0.5 °/min\"\n\
                rate_disagreement_for = \"3 s\"\nchamber_max_temp = \"45 °C\"\n\
                chamber_min_temp_c = -10\nsetpoint_tolerance = \"2 K\"\n\
                setpoint_not_tracked_for = \"1 min\"\ngyro_status_for_s = 2\n\
                [[step]]\nwait = \"1 s\"\n");
    let l = &p.interlocks;
    assert!((l.table_max_rate_rad_s - 20.0 * DEG / 60.0).abs() < 1e-15);
    assert!((l.rate_tolerance_rad_s - 0.5 * DEG / 60.0).abs() < 1e-15);
    assert_eq!(l.rate_disagreement_for, std::time::Duration::from_secs(3));
    assert_eq!((l.chamber_min_temp_c, l.chamber_max_temp_c), (-10.0, 45.0));
    assert_eq!(l.setpoint_tolerance_c, 2.0);
    assert_eq!(l.setpoint_not_tracked_for, std::time::Duration::from_secs(60));
    assert_eq!(l.gyro_status_for, std::time::Duration::from_secs(2));
}

#[test]
fn commands_beyond_the_interlocks_are_refused_where_they_are_written() {
    assert_eq!(
        err1(
            "[interlocks]\ntable_max_rate = \"20 °/min\"\n[[step]]\nspin = \"30 °/min\"\n\
              direction = \"cw\"\n"
        ),
        "t.toml:8:8: table rate 30 °/min exceeds [interlocks] table_max_rate 20 °/min"
    );
    assert_eq!(
        err1("[interlocks]\nchamber_max_temp = \"45 °C\"\n[[step]]\nchamber = \"50 °C\"\n"),
        "t.toml:8:11: chamber target 50 °C is outside [interlocks] \
         chamber_min_temp..chamber_max_temp -45..45 °C"
    );
    assert_eq!(
        err1("[interlocks]\ntable_max_rate = \"2000 °/s\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:18: table_max_rate 2000 °/s exceeds the table's maximum 1000 °/s"
    );
    assert_eq!(
        err1("[interlocks]\ngyro_status_for = \"0 s\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:19: gyro_status_for must be greater than zero, got 0 s"
    );
    assert!(err1("[interlocks]\nmax_speed = 3\n[[step]]\nwait = \"1 s\"\n")
        .contains("unknown key `max_speed` in [interlocks]"));
}

#[test]
fn recording_flush_interval_is_read_with_units_and_checked_where_written() {
    assert_eq!(ok("[[step]]\nwait = \"1 s\"\n").flush_interval, None, "default: the CLI's 1 s");
    let p = ok("[recording]\nflush_interval = \"250 ms\"\n[[step]]\nwait = \"1 s\"\n");
    assert_eq!(p.flush_interval, Some(Duration::from_millis(250)));
    let p = ok("[recording]\nflush_interval_s = 5\n[[step]]\nwait = \"1 s\"\n");
    assert_eq!(p.flush_interval, Some(Duration::from_secs(5)));
    assert_eq!(
        err1("[recording]\nflush_interval = \"0 s\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:18: [recording] flush_interval must be greater than zero, got 0 s"
    );
    assert_eq!(
        err1("[recording]\nflush_interval = \"2 h\"\n[[step]]\nwait = \"1 s\"\n"),
        "t.toml:6:18: [recording] flush_interval 2 h is longer than 1 h: a kill could lose that \
         much of the run"
    );
    let e = err1("[recording]\nflush = \"1 s\"\n[[step]]\nwait = \"1 s\"\n");
    assert!(e.starts_with("t.toml:6:1: unknown key `flush` in [recording]"), "{e}");
    let e = err1("[recording]\nflush_interval = \"1 °C\"\n[[step]]\nwait = \"1 s\"\n");
    assert!(e.starts_with("t.toml:6:18: "), "{e}");
}
