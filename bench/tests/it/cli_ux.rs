//! What a gyro-test engineer meets first, through the binary: a recording is never overwritten,
//! the estimate and the lab's limits in `bench validate`, the sim-vs-real workflow (`bench
//! model`, `bench diagnose --model REC.mcap`), a pure simulation diagnosing without missing
//! physics, and the exit codes.

use std::path::Path;

use crate::common::{bench, json, scenario, text, text_of};

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

    // A KVH gyro's settings are checked where they are written.
    let kvh =
        lab.replace("baud = 921600 }", "baud = 921600 }\nsample_rate_hz = 0\nwatchdog_periods = 0");
    std::fs::write(d.join("kvh.toml"), kvh).expect("config");
    let r = bench(&["validate", &scenario("seed.toml"), "--bench", "kvh.toml"], d);
    assert_eq!(r.status.code(), Some(3), "{}", text(&r.stderr));
    let err = text(&r.stderr);
    assert!(err.contains("kvh.toml:11:18: [gyro] sample_rate_hz = 0 must be > 0"), "{err}");
    assert!(err.contains("kvh.toml:12:20: [gyro] watchdog_periods = 0 must be ≥ 1"), "{err}");

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
    let r = bench(&["diagnose", "real.mcap", "--model", "sim.mcap", "--no-report", "-o", "d2"], d);
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

    // A file that is neither: a clear error, not "stream did not contain valid UTF-8": an
    // invalid model file (exit 3) at its first bad byte.
    std::fs::write(d.join("junk.bin"), [0xffu8, 0xfe, 0, 1]).expect("junk");
    let r = bench(&["diagnose", "real.mcap", "--model", "junk.bin", "-q", "--no-report"], d);
    assert_eq!(r.status.code(), Some(3), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("junk.bin:1:1: not UTF-8"), "{}", text(&r.stderr));
}

#[test]
fn station_metadata_is_recorded_and_the_calibration_judged_against_its_limits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let seed = std::fs::read_to_string(scenario("seed.toml")).expect("seed");
    // A generous bias limit passes; an impossible temp_coeff limit fails.
    let st = format!(
        "{seed}\n[station]\nstation = \"bench 3\"\noperator = \"A. Tester\"\n\
         [acceptance]\nbias_rad_s = 4.8e-6\ntemp_coeff_rad_s_per_c = 1e-12\n"
    );
    std::fs::write(d.join("st.toml"), st).expect("scenario");
    let r = bench(&["run", "st.toml", "-q", "-o", "st.mcap", "--unit-serial", "FOG-0042"], d);
    assert!(r.status.success(), "{}", text_of(&r));
    let r = bench(&["info", "st.mcap", "--json", "i.json", "-q"], d);
    assert!(r.status.success(), "{}", text_of(&r));
    assert!(r.stdout.is_empty(), "-q: no text");
    let i = json(&d.join("i.json"));
    assert_eq!(i["metadata"]["bench.station"]["unit_serial"], "FOG-0042");
    assert_eq!(i["metadata"]["bench.station"]["operator"], "A. Tester");
    assert_eq!(i["metadata"]["bench.acceptance"]["bias_rad_s"], "4.8e-6");
    assert_eq!(i["container"]["library"].as_str().map(|l| l.starts_with("mcap")), Some(true));
    assert!(i["container"]["chunks_by_compression"]["zstd"].as_u64() > Some(0));
    assert_eq!(i["duration"], "1 h 18 min 16 s");
    assert_eq!(i["channels"][0]["timing_from"], "log_time");

    let r = bench(&["calibrate", "st.mcap", "--no-report", "-o", "cal", "--json", "c.json"], d);
    // A failed unit is a failed test: exit 9 (the calibration itself is sound and written).
    assert_eq!(r.status.code(), Some(9), "{}", text_of(&r));
    assert!(d.join("cal/calibration.toml").exists());
    let out = text(&r.stdout);
    assert!(out.contains("unit serial FOG-0042, operator A. Tester, station bench 3"), "{out}");
    assert!(out.contains("acceptance bias_rad_s:") && out.contains(": pass"), "{out}");
    assert!(out.contains("acceptance: FAIL"), "{out}");
    let c = json(&d.join("c.json"));
    let a = &c["acceptance"];
    assert_eq!(a["result"], "fail");
    let check = |key: &str| {
        a["checks"].as_array().and_then(|v| v.iter().find(|c| c["key"] == key)).cloned()
    };
    assert_eq!(check("bias_rad_s").map(|c| c["judgement"].clone()), Some("pass".into()));
    let tc = check("temp_coeff_rad_s_per_c").expect("checked");
    assert_eq!(tc["judgement"], "fail");
    assert!(tc["sigma"].as_f64().is_some_and(|s| s > 0.0));
}

#[test]
fn allan_of_a_rotating_record_window_with_its_curve() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let r = bench(&["run", "short.toml", "-q", "-o", "s.mcap"], d);
    assert!(r.status.success(), "{}", text_of(&r));
    let r = bench(
        &["allan", "s.mcap", "--window", "record cw", "--json", "a.json", "--csv", "a.csv", "-q"],
        d,
    );
    assert!(r.status.success(), "{}", text_of(&r));
    let a = json(&d.join("a.json"));
    // The table's 10 °/min is taken out; the default gyro's ARW is 2.9e-8 rad/√s.
    let rate = a["table_rate_rad_s"].as_f64().expect("rate");
    assert!((rate + 10f64.to_radians() / 60.0).abs() < 1e-6, "{rate}");
    let n = a["arw_rad_per_sqrt_s"]["value"].as_f64().expect("N");
    assert!((n / 2.9089e-8 - 1.0).abs() < 0.2, "{n}");
    let curve = a["curve"].as_array().expect("curve");
    let csv = std::fs::read_to_string(d.join("a.csv")).expect("csv");
    assert_eq!(csv.lines().count(), curve.len() + 1);
    let r = bench(&["allan", "s.mcap", "--window", "no such", "-q"], d);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("record windows: record cw"), "{}", text_of(&r));
}

#[test]
fn completions_exit_codes_and_no_ansi_off_a_terminal() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let r = bench(&["completions", "bash"], d);
    assert!(r.status.success());
    assert!(text(&r.stdout).contains("complete -F _bench"), "{}", text_of(&r));
    // A usage error is 2 (clap), an invalid scenario 3.
    assert_eq!(bench(&["run"], d).status.code(), Some(2));
    std::fs::write(d.join("bad.toml"), "[scenario]\nname = \"x\"\n").expect("scenario");
    let r = bench(&["validate", "bad.toml"], d);
    assert_eq!(r.status.code(), Some(3));
    let r = bench(&["run", "bad.toml", "-o", "x.mcap"], d);
    assert_eq!(r.status.code(), Some(3));
    // stderr is a pipe here: no escape codes, even with -v log lines.
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let r = bench(&["-v", "run", "short.toml", "-o", "v.mcap"], d);
    assert!(r.status.success(), "{}", text_of(&r));
    assert!(!r.stderr.contains(&0x1b), "{}", text(&r.stderr));
    // A scenario given as a recording is named as one (exit 2, a usage error).
    let r = bench(&["model", "bad.toml"], d);
    assert_eq!(r.status.code(), Some(2));
}

#[test]
fn a_connection_error_says_each_piece_of_context_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // A port nothing listens on.
    let port =
        std::net::TcpListener::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr");
    let config = format!(
        "[site]\nlatitude_deg = 45.0\n[table]\ndialect = \"actidyn\"\n\
         endpoint = {{ tcp = {{ addr = \"{port}\" }} }}\n[chamber]\n\
         endpoint = {{ tcp = {{ addr = \"{port}\" }} }}\nunit_id = 1\nmap = \"watlow_f4t\"\n\
         [gyro]\ndriver = \"can\"\ntransport = {{ kind = \"slcan\", serial = {{ path = \
         \"/dev/null\", baud = 115200 }}, bitrate = 1000000 }}\nsample_rate_hz = 20.0\n"
    );
    std::fs::write(d.join("lab.toml"), config).expect("config");
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let r = bench(&["run", "short.toml", "-q", "--bench", "lab.toml", "-o", "x.mcap"], d);
    let err = text(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    let line = err.lines().find(|l| l.starts_with("error:")).expect("an error line");
    assert!(line.contains("rate table"), "{line}");
    assert!(line.contains(&port.to_string()), "{line}");
    for piece in ["link error", "connecting to the actidyn table", "Connection refused"] {
        assert_eq!(line.matches(piece).count(), 1, "{piece} in {line}");
    }
}

#[test]
fn recover_refuses_an_existing_output_and_reports_as_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    // A demo recording cut in the middle, as a crash leaves it.
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/demo-null.mcap");
    let bytes = std::fs::read(demo).expect("demo");
    let cut = bytes.len() / 2;
    std::fs::write(d.join("cut.mcap"), &bytes[..cut]).expect("cut");
    std::fs::write(d.join("out.mcap"), b"precious").expect("file");
    let r = bench(&["recover", "cut.mcap", "out.mcap"], d);
    assert_eq!(r.status.code(), Some(1), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("out.mcap exists"), "{}", text(&r.stderr));
    assert_eq!(std::fs::read(d.join("out.mcap")).expect("kept"), b"precious");
    let r = bench(&["recover", "cut.mcap", "new.mcap", "-q", "--json", "r.json"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(r.stdout.is_empty(), "-q: no text");
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("r.json")).expect("json")).expect("parses");
    assert_eq!(j["complete"], false);
    assert_eq!(j["input_bytes"].as_u64(), Some(cut as u64));
    let at = j["break"]["at_byte"].as_u64().expect("where it broke");
    assert!(at > 0 && at <= cut as u64, "{at}");
    assert!(j["total_messages"].as_u64() > Some(0));
    assert!(d.join("new.mcap").exists());
}

#[test]
fn export_is_quiet_on_request_and_reports_as_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/demo-null.mcap");
    let demo = demo.display().to_string();
    let r = bench(&["export", &demo, "-o", "csv", "-q"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(r.stdout.is_empty(), "-q: {}", text(&r.stdout));
    let r = bench(&["export", &demo, "-o", "csv", "--json", "-", "--force"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).expect("only JSON on stdout");
    assert_eq!(j["format"], "csv");
    let tables = j["tables"].as_array().expect("tables");
    assert!(tables.iter().any(|t| t["topic"] == "/gyro/rate"), "{j}");
    for t in tables {
        let path = Path::new(t["path"].as_str().expect("path"));
        let lines = std::fs::read_to_string(d.join(path).canonicalize().unwrap_or(path.into()))
            .map_or(0, |s| s.lines().count());
        assert_eq!(lines as u64, t["rows"].as_u64().expect("rows") + 1, "{t}");
    }
    assert!(j["cut"].is_null());
}

#[test]
fn run_reports_as_json() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let r = bench(&["run", "short.toml", "-q", "--json", "-"], d);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&r.stdout).expect("only JSON on stdout");
    assert_eq!(j["completed"], true, "{j}");
    assert_eq!(j["recording"], "short.mcap");
    assert!(j["fault"].is_null());
    // Two minutes recorded at 20 Hz, plus the spin-up and the stop.
    let samples = j["gyro_samples"].as_u64().expect("samples");
    let bench_s = j["bench_time_s"].as_f64().expect("bench time");
    assert!(bench_s >= 120.0 && (samples as f64 - 20.0 * bench_s).abs() <= 2.0, "{j}");
    assert!(d.join("short.mcap").exists());
}

/// Issue 30 item 1: one overwrite rule for every verb that writes. An existing output is
/// refused unless `--force`; an output folder holds one run's outputs only: `--force` removes
/// what bench wrote there before (its `.bench-outputs`), never a file bench did not write.
#[test]
fn every_verb_refuses_an_existing_output_and_a_folder_keeps_one_runs_outputs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("r.mcap")).expect("copy");
    let refused = |args: &[&str], what: &str| {
        let r = bench(args, d);
        assert_eq!(r.status.code(), Some(1), "{args:?}: {}", text_of(&r));
        let err = text(&r.stderr);
        assert!(err.contains(what) && err.contains("--force"), "{args:?}: {err}");
    };

    // A calibration folder: a second run into it is refused, the first's file untouched.
    let r = bench(&["calibrate", "r.mcap", "-q", "-o", "cal", "--json", "c.json"], d);
    assert_eq!(r.status.code(), Some(0), "{}", text_of(&r));
    assert!(d.join("cal/report.html").exists());
    let before = std::fs::read(d.join("cal/calibration.toml")).expect("calibration.toml");
    std::fs::write(d.join("cal/calibration.toml"), b"edited").expect("edit");
    refused(&["calibrate", "r.mcap", "-q", "--no-report", "-o", "cal"], "cal holds");
    refused(
        &["calibrate", "r.mcap", "-q", "--no-report", "-o", "new", "--json", "c.json"],
        "c.json exists",
    );
    assert_eq!(std::fs::read(d.join("cal/calibration.toml")).expect("kept"), b"edited");
    assert!(!d.join("new").exists(), "nothing written when refused");

    // --force: what bench wrote there before goes (no stale report beside the new file), a
    // file bench did not write stays, and is named.
    std::fs::write(d.join("cal/notes.txt"), b"mine").expect("notes");
    let r = bench(&["calibrate", "r.mcap", "-q", "--no-report", "-o", "cal", "--force"], d);
    assert_eq!(r.status.code(), Some(0), "{}", text_of(&r));
    assert!(!d.join("cal/report.html").exists(), "a stale report was left");
    assert!(!d.join("cal/fig1-raw-rate.png").exists(), "a stale figure was left");
    assert_eq!(std::fs::read(d.join("cal/calibration.toml")).expect("new"), before);
    assert_eq!(std::fs::read(d.join("cal/notes.txt")).expect("kept"), b"mine");
    assert!(
        text(&r.stderr).contains("notes.txt, which bench did not write: kept"),
        "{}",
        text_of(&r)
    );
    let listed = std::fs::read_to_string(d.join("cal/.bench-outputs")).expect("manifest");
    assert!(listed.lines().any(|l| l == "calibration.toml"), "{listed}");
    assert!(!listed.contains("notes.txt"), "{listed}");

    // The other verbs that write, each with the same rule.
    assert!(bench(&["export", "r.mcap", "-q", "-o", "csv"], d).status.success());
    refused(&["export", "r.mcap", "-q", "-o", "csv"], "csv holds");
    assert!(bench(&["export", "r.mcap", "-q", "-o", "csv", "--force"], d).status.success());
    assert!(bench(&["model", "r.mcap", "-q", "-o", "m.toml"], d).status.success());
    refused(&["model", "r.mcap", "-q", "-o", "m.toml"], "m.toml exists");
    assert!(bench(&["allan", "r.mcap", "-q", "--csv", "a.csv"], d).status.success());
    refused(&["allan", "r.mcap", "-q", "--csv", "a.csv"], "a.csv exists");
    assert!(bench(&["info", "r.mcap", "-q", "--json", "i.json"], d).status.success());
    refused(&["info", "r.mcap", "-q", "--json", "i.json"], "i.json exists");
    assert!(bench(&["info", "r.mcap", "-q", "--json", "i.json", "--force"], d).status.success());
    std::fs::create_dir(d.join("diag")).expect("diag");
    std::fs::write(d.join("diag/old.html"), b"x").expect("foreign");
    refused(
        &["diagnose", "r.mcap", "-q", "--no-report", "-o", "diag"],
        "diag holds files bench did not write",
    );
}

/// Issue 30 item 3: `-q` leaves nothing on stdout for every verb but what was asked for;
/// errors still on stderr.
#[test]
fn quiet_means_nothing_on_stdout_for_every_verb() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("r.mcap")).expect("copy");
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let runs: &[&[&str]] = &[
        &["run", "short.toml", "-q", "-o", "s.mcap"],
        &["validate", "short.toml", "-q"],
        &["info", "r.mcap", "-q"],
        &["calibrate", "r.mcap", "-q", "-o", "cal"],
        &["verify", "r.mcap", "-q", "--calibration", "cal/calibration.toml", "-o", "ver"],
        &["diagnose", "r.mcap", "-q", "-o", "diag", "--no-report"],
        &["export", "r.mcap", "-q", "-o", "csv"],
        &["model", "r.mcap", "-q", "-o", "m.toml"],
        &["allan", "r.mcap", "-q"],
    ];
    for args in runs {
        let r = bench(args, d);
        assert!(matches!(r.status.code(), Some(0 | 5 | 6 | 7)), "{args:?}: {}", text_of(&r));
        assert!(r.stdout.is_empty(), "{args:?} -q printed: {}", text(&r.stdout));
    }
    // What was asked for is printed with -q too; an error still goes to stderr.
    let r = bench(&["info", "r.mcap", "-q", "--json", "-"], d);
    assert!(serde_json::from_slice::<serde_json::Value>(&r.stdout).is_ok(), "{}", text_of(&r));
    let r = bench(&["calibrate", "nothing.mcap", "-q", "-o", "x"], d);
    assert_eq!(r.status.code(), Some(1));
    assert!(r.stdout.is_empty() && text(&r.stderr).contains("error:"), "{}", text_of(&r));
}

/// `bench calibrate REC | head`: a closed stdout ends the printing quietly (no panic), every
/// file is still written, and the exit code is the command's own.
#[test]
fn a_closed_stdout_ends_printing_quietly_and_every_file_is_written() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("r.mcap")).expect("copy");
    let mut child = Command::new(crate::common::exe())
        .args(["calibrate", "r.mcap", "-o", "cal", "--json", "c.json"])
        .current_dir(d)
        .env("NO_COLOR", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bench runs");
    // The reader goes away before bench prints: as `| head -0` does.
    drop(child.stdout.take());
    let r = child.wait_with_output().expect("bench ends");
    let err = text(&r.stderr);
    assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{err}");
    assert_eq!(r.status.code(), Some(0), "{err}");
    for f in ["cal/calibration.toml", "cal/report.html", "c.json"] {
        assert!(d.join(f).exists(), "{f} not written: {err}");
    }
}

/// Issue 30 item 7, the text defects: a device counter's time base in s per count (not "host
/// clock -950000.0 ppm against it"), "K ≤" (not "K = ≤"), the abort naming a record step once,
/// and `thermal_time_constant` null in result.json where the lag was not estimated, with the
/// model's value the same in result.json and calibration.toml.
#[test]
fn counters_bounds_aborted_steps_and_the_lag_are_written_as_what_they_are() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("r.mcap")).expect("copy");
    let r = bench(&["calibrate", "r.mcap", "-o", "cal", "--json", "c.json"], d);
    assert_eq!(r.status.code(), Some(0), "{}", text_of(&r));
    let out = text(&r.stdout);
    assert!(out.contains("K ≤ ") && !out.contains("= ≤"), "{out}");
    let html = std::fs::read_to_string(d.join("cal/report.html")).expect("report");
    assert!(html.contains("/gyro/rate: device counter, 0.500000 s per count"), "time bases");
    assert!(
        !html.contains("ppm against it, host stamps&#39; jitter 0 ms"),
        "a counter read as a clock"
    );
    let c = json(&d.join("c.json"));
    let counter = &c["time_bases"][0];
    assert_eq!(counter["source"], "device_counter");
    assert!(counter["drift_ppm"].is_null(), "{counter}");
    assert_eq!(counter["s_per_count"].as_f64(), Some(0.5), "{counter}");
    // The demo's gyro has its own sensor: no lag is estimated.
    assert!(c["thermal_time_constant"].is_null(), "{}", c["thermal_time_constant"]);
    let toml = std::fs::read_to_string(d.join("cal/calibration.toml")).expect("calibration");
    let tau = c["gyro_model"]["thermal_time_constant"].as_f64().expect("model's τ");
    assert!(toml.contains(&format!("thermal_time_constant_s = {tau:?}")), "{tau} vs {toml}");

    // A record step aborted by an interlock is named once: "(record cw ramp …)".
    let abort = "[scenario]\nname = \"abort\"\n[site]\nlatitude_deg = 45\n[interlocks]\n\
                 setpoint_tolerance = \"0.01 °C\"\nsetpoint_not_tracked_for = \"1 s\"\n\
                 [[step]]\nchamber = \"30 °C\"\nramp = \"5 °C/min\"\n\
                 [[step]]\nlabel = \"record cw ramp\"\nrecord = \"5 min\"\n";
    std::fs::write(d.join("abort.toml"), abort).expect("scenario");
    let r = bench(&["run", "abort.toml", "-o", "a.mcap"], d);
    assert_eq!(r.status.code(), Some(4), "{}", text_of(&r));
    let all = text_of(&r);
    assert!(all.contains("step 1 (record cw ramp) at abort.toml"), "{all}");
    assert!(!all.contains("record record"), "{all}");
}

/// Issue 30 item 5: a file of the wrong kind is named with the verbs that take it (exit 2).
#[test]
fn a_wrong_kind_of_file_is_named_with_the_verbs_that_take_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("seed.mcap")).expect("copy");
    std::fs::write(d.join("soaks.toml"), SHORT).expect("scenario");
    let model = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios/models/diagnose-demo-params-off.toml");
    std::fs::copy(model, d.join("cal.toml")).expect("model");
    std::fs::write(
        d.join("lab.toml"),
        "[table]\ndialect = \"actidyn\"\nendpoint = { tcp = { addr = \"127.0.0.1:9\" } }\n",
    )
    .expect("config");
    for (args, says) in [
        (&["validate", "seed.mcap"][..], "seed.mcap is an MCAP recording: use bench info / calibrate / diagnose / replay"),
        (&["run", "seed.mcap"][..], "seed.mcap is an MCAP recording"),
        (&["calibrate", "soaks.toml"][..], "soaks.toml is a scenario (TOML): use bench validate / run"),
        (&["info", "soaks.toml"][..], "soaks.toml is a scenario (TOML)"),
        (&["diagnose", "cal.toml"][..], "cal.toml is a model or calibration file (TOML, [gyro_model]): give it as --calibration to bench verify"),
        (&["export", "lab.toml"][..], "lab.toml is a bench config (TOML): give it as --bench to bench run / validate"),
        (&["validate", "soaks.toml", "--bench", "cal.toml"][..], "cal.toml is a model or calibration file"),
        (&["verify", "seed.mcap", "--calibration", "soaks.toml"][..], "soaks.toml is a scenario"),
        (&["diagnose", "seed.mcap", "--model", "lab.toml"][..], "lab.toml is a bench config"),
    ] {
        let r = bench(args, d);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {}", text_of(&r));
        assert!(text(&r.stderr).contains(says), "{args:?}: {}", text(&r.stderr));
    }
}

/// Issue 30 item 6: a misspelt action key gets "did you mean" at its own line and column, also
/// inside a `for` step's `do`.
#[test]
fn a_misspelt_action_is_named_at_its_key_with_the_action_meant() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let typo = "[scenario]\nname = \"typo\"\n[site]\nlatitude_deg = 45\n\
                [[step]]\nfor.dir = [\"cw\", \"ccw\"]\n  [[step.do]]\n  label = \"spin {dir}\"\n  \
                spn = \"10 °/min\"\n  direction = \"{dir}\"\n  [[step.do]]\n  record = \"1 min\"\n";
    std::fs::write(d.join("typo.toml"), typo).expect("scenario");
    let r = bench(&["validate", "typo.toml"], d);
    assert_eq!(r.status.code(), Some(3), "{}", text_of(&r));
    let err = text(&r.stderr);
    assert!(
        err.contains("typo.toml:9:3: unknown key `spn` in a step; did you mean `spin`?"),
        "{err}"
    );
}

/// Issue 30 item 9: the read bar shows no ETA until it has a rate (not "(70m)" or "(0s)" from
/// the first bytes of a 2 s job). stderr must be a terminal for the bar: `script` gives one.
#[test]
fn the_read_bar_shows_no_eta_before_it_has_a_rate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::copy(crate::common::recording("demo-null.mcap"), d.join("r.mcap")).expect("copy");
    let exe = crate::common::exe();
    let cmd = format!("{} diagnose r.mcap -o diag --no-report", exe.to_string_lossy());
    let r = std::process::Command::new("script")
        .args(["-qefc", &cmd, "/dev/null"])
        .current_dir(d)
        .env_remove("NO_COLOR")
        .output()
        .expect("`script` (util-linux) gives bench a terminal");
    let shown = text(&r.stdout);
    let frames: Vec<&str> =
        shown.split(['\r', '\n']).filter(|f| f.contains("reading r.mcap")).collect();
    assert!(!frames.is_empty(), "no read bar drawn: {shown}");
    let first = frames[0];
    assert!(first.contains(" 0 B/"), "{first}");
    assert!(!first.contains('('), "an ETA before any rate: {first}");
}

/// Issue 30 item 8: a paced run (`--time-scale 60`) keeps its 20 Hz streams' rates and gap
/// checks in `bench info`, though a paced host stamps them unevenly.
#[test]
fn a_paced_run_keeps_its_channel_rates_in_info() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(d.join("short.toml"), SHORT).expect("scenario");
    let r = bench(&["run", "short.toml", "-q", "-o", "p.mcap", "--time-scale", "60"], d);
    assert!(r.status.success(), "{}", text_of(&r));
    let r = bench(&["info", "p.mcap", "--json", "-"], d);
    let i: serde_json::Value = serde_json::from_slice(&r.stdout).expect("json");
    for topic in ["/gyro/rate", "/table/state", "/chamber/state"] {
        let c = i["channels"].as_array().and_then(|v| v.iter().find(|c| c["topic"] == topic));
        let c = c.expect("channel");
        // The gyro's own stamps (publish_time) carry its rate when the host's are uneven.
        let c = if c["periodic"] == false { &c["device_time"] } else { c };
        assert_eq!(c["periodic"], true, "{topic}: {c}");
        let hz = c["mean_rate_hz"].as_f64().expect("rate");
        assert!((hz - 20.0).abs() < 1.0, "{topic}: {hz}");
        let period = c["median_period_s"].as_f64().expect("period");
        assert!((period - 0.05).abs() < 0.005, "{topic}: {period}");
    }
    let r = bench(&["info", "p.mcap"], d);
    let shown = text(&r.stdout);
    let lines: Vec<&str> = shown
        .lines()
        .filter(|l| l.contains("/gyro/") || l.contains("/table/") || l.contains("/chamber/"))
        .collect();
    assert!(lines.len() == 3 && lines.iter().all(|l| l.contains(" Hz")), "{shown}");
}
