//! What a gyro-test engineer meets first, through the binary: a recording is never overwritten,
//! the estimate and the lab's limits in `bench validate`, the sim-vs-real workflow (`bench
//! model`, `bench diagnose --model REC.mcap`), a pure simulation diagnosing without missing
//! physics, and the exit codes.

use std::path::Path;
use std::process::{Command, Output};

fn bench(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(args)
        .current_dir(dir)
        .env_remove("NO_COLOR")
        .output()
        .expect("bench runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios").join(name).display().to_string()
}

/// A two-minute scenario: spin, record, stop.
const SHORT: &str = "[scenario]\nname = \"short\"\n[site]\nlatitude_deg = 45\n\
                     [[step]]\nspin = \"10 °/min\"\ndirection = \"cw\"\n\
                     [[step]]\nlabel = \"record cw\"\nrecord = \"2 min\"\n\
                     [[step]]\nstop = \"table\"\n";

#[test]
fn an_existing_recording_is_never_overwritten_without_force() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    std::fs::write(d.join("keep.mcap"), b"precious").expect("file");
    let r = bench(&["run", "short.toml", "-q", "-o", "keep.mcap"], d);
    assert_eq!(r.status.code(), Some(1), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("keep.mcap exists"), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("--force"), "{}", text(&r.stderr));
    assert_eq!(std::fs::read(d.join("keep.mcap")).expect("kept"), b"precious");

    let r = bench(&["run", "short.toml", "-q", "-o", "keep.mcap", "--force"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert_ne!(std::fs::read(d.join("keep.mcap")).expect("written"), b"precious");

    // The default name (the scenario's) is taken: a fresh one is picked, and said.
    std::fs::write(d.join("short.mcap"), b"precious").expect("file");
    let r = bench(&["run", "short.toml", "-q"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("recording to short-2.mcap instead"), "{}", text(&r.stderr));
    assert_eq!(std::fs::read(d.join("short.mcap")).expect("kept"), b"precious");
    assert!(d.join("short-2.mcap").exists());
}

#[test]
fn validate_prints_the_physical_estimate_and_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let r = bench(&["validate", &scenario("seed.toml"), "--json", "v.json"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    // The seed's run takes 1:18:15 of bench time (chamber lag, the gyro's thermal lag).
    assert!(text(&r.stdout).contains("about 1:1"), "{}", text(&r.stdout));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("v.json")).expect("json"))
            .expect("valid json");
    assert_eq!(j["ok"], true);
    let s = j["estimated_bench_time_s"].as_f64().expect("estimate");
    assert!((s - 4695.0).abs() < 0.05 * 4695.0, "{s}");
}

#[test]
fn validate_against_the_labs_limits_without_connecting() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // Real drivers on ports that do not exist: nothing is connected.
    let lab = "[table]\ndialect = \"actidyn\"\nendpoint = { tcp = { addr = \"127.0.0.1:9\" } }\n\
               [chamber]\nendpoint = { tcp = { addr = \"127.0.0.1:9\" } }\nunit_id = 1\n\
               map = \"watlow_f4t\"\n\
               [gyro]\ndriver = \"kvh1750\"\nserial = { path = \"/dev/does-not-exist\", baud = 921600 }\n\
               [limits]\nchamber_max_heat_rate_c_min = 3.0\n";
    std::fs::write(d.join("lab.toml"), lab).expect("config");
    let r = bench(&["validate", &scenario("seed.toml"), "--bench", "lab.toml"], d);
    assert_eq!(r.status.code(), Some(3), "{}{}", text(&r.stdout), text(&r.stderr));
    let err = text(&r.stderr);
    assert!(err.contains("seed.toml:") && err.contains("lab.toml's [limits]"), "{err}");

    // Every problem of a config is listed, each located.
    let bad = "[bench]\ntime_scale = -1\nstale_after_s = 0\n[site]\nlatitude_deg = 100\n\
               [acceptance]\nbias_rad_s = -1\n";
    std::fs::write(d.join("bad.toml"), bad).expect("config");
    let r = bench(&["validate", &scenario("seed.toml"), "--bench", "bad.toml"], d);
    assert_eq!(r.status.code(), Some(3), "{}", text(&r.stderr));
    let err = text(&r.stderr);
    for (at, what) in [
        ("bad.toml:2:", "time_scale"),
        ("bad.toml:3:", "stale_after_s"),
        ("bad.toml:5:", "latitude_deg"),
        ("bad.toml:7:", "bias_rad_s"),
    ] {
        assert!(err.lines().any(|l| l.starts_with(at) && l.contains(what)), "{at} {what}: {err}");
    }
    assert!(err.contains("4 error(s)"), "{err}");
}

#[test]
fn a_pure_simulation_has_no_missing_physics_and_its_model_is_a_nominal_for_another() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let r = bench(&["run", &scenario("seed.toml"), "-q", "-o", "sim.mcap"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    // The simulated table's ripple is recorded as nominal physics: not "missing".
    let r =
        bench(&["diagnose", "sim.mcap", "-q", "--no-report", "-o", "diag", "--json", "d.json"], d);
    assert!(matches!(r.status.code(), Some(0 | 6)), "{}{}", text(&r.stdout), text(&r.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("d.json")).expect("json"))
            .expect("valid json");
    assert_ne!(j["verdict"], "missing_physics");

    // A second run stands in for the real one; the first's model is the nominal.
    let r = bench(&["run", &scenario("seed.toml"), "-q", "-o", "real.mcap", "--seed", "7"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let r = bench(
        &["diagnose", "real.mcap", "--model", "sim.mcap", "-q", "--no-report", "-o", "d2"],
        d,
    );
    assert!(matches!(r.status.code(), Some(0 | 6)), "{}{}", text(&r.stdout), text(&r.stderr));
    assert!(
        text(&r.stdout).contains("nominal model: sim.mcap (bench.gyro_model)"),
        "{}",
        text(&r.stdout)
    );

    // The recording's model written out as a model TOML loads back as a nominal model.
    let r = bench(&["model", "sim.mcap", "-o", "model.toml"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let model = std::fs::read_to_string(d.join("model.toml")).expect("model");
    assert!(model.contains("[effects.rate_ripple]"), "{model}");
    assert!(model.contains("thermal_time_constant_s = 300.0"), "{model}");
    let r = bench(
        &["diagnose", "real.mcap", "--model", "model.toml", "-q", "--no-report", "-o", "d3"],
        d,
    );
    assert!(matches!(r.status.code(), Some(0 | 6)), "{}", text(&r.stderr));

    // A file that is neither: a clear error, not "stream did not contain valid UTF-8".
    std::fs::write(d.join("junk.bin"), [0xffu8, 0xfe, 0, 1]).expect("junk");
    let r = bench(&["diagnose", "real.mcap", "--model", "junk.bin", "-q", "--no-report"], d);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("junk.bin"), "{}", text(&r.stderr));
}
