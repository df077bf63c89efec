//! Device faults from the independent peers (`tests/peers/serve_bench.py`, 10× real time),
//! through bench's real drivers as `bench run --bench peer.toml` connects them: the table's
//! drive dropping mid-record (an alarm, and a lost keep-alive) and the gyro's built-in test
//! failing. Each must abort the record step at the first reading that shows it — never mark it
//! completed — reach the safe state and keep every sample received before. The peers' clocks
//! time the detection: the first poll the table peer answers after it dropped the drive.

use std::time::Duration;

use crate::support::run_connected;
use bench::bench_config::BenchSource;
use bench_recording::{status, Recording};
use bench_tests::peer::{read_log, Peer};
use serde_json::Value;

const SCALE: &str = "10";

/// Spin (settled), record 2 min, stop: the faults are timed to fall inside the record window.
const SCENARIO: &str = r#"
[scenario]
name = "peer faults"

[site]
latitude_deg = 45.0

[gyro]
sample_rate = "20 Hz"

[safe]
decel = "10 °/s²"
temperature = "23 °C"

[[step]]
label = "spin cw"
spin = "10 °/s"
direction = "cw"
accel = "5 °/s²"
settle = true

[[step]]
label = "record cw"
record = "2 min"

[[step]]
label = "stop"
stop = "table"
"#;

struct Run {
    outcome: String,
    rec: Recording,
    table_log: Vec<Value>,
}

/// Serve the peers with `peer_args`, run [`SCENARIO`] on them; `keep_alive` off stops the
/// table driver's `ALC 0`.
async fn run_on_peers(peer_args: &[&str], keep_alive: bool) -> Run {
    let dir = tempfile::tempdir().expect("tempdir");
    let toml_path = dir.path().join("peer.toml");
    let logs = dir.path().join("logs");
    let (toml, logs_s) = (toml_path.to_str().expect("utf-8"), logs.to_str().expect("utf-8"));
    let mut args = vec!["--time-scale", SCALE, "--out", toml, "--log-dir", logs_s];
    args.extend_from_slice(peer_args);
    let peer = Peer::start("serve_bench.py", &args);
    let BenchSource::Devices(mut config) = BenchSource::load(&toml_path).expect("peer.toml loads")
    else {
        panic!("peer.toml names devices");
    };
    if !keep_alive {
        config.table.as_mut().expect("a table").keep_alive_s = 0.0;
    }
    let (report, bytes, _) = run_connected(&config, |caps| {
        bench::scenario::parse(SCENARIO, "peer-faults.toml", caps).expect("valid")
    })
    .await;
    drop(peer);
    let rec = Recording::from_bytes(&bytes).expect("readable");
    assert_eq!(rec.outcome(), Some(report.outcome.clone()));
    Run {
        outcome: rec.outcome_text().unwrap_or_default().to_string(),
        rec,
        table_log: read_log(&logs.join("table.jsonl")),
    }
}

/// The record step ended in `abort`, never `end`; the outcome names `name`.
fn assert_aborted_in_the_window(run: &Run, name: &str) {
    let o = &run.outcome;
    assert!(o.starts_with("aborted: step 1 (record cw)"), "{o}");
    assert!(o.contains(&format!(": {name}: ")), "{o}");
    let events: Vec<(&str, &str)> =
        run.rec.steps.iter().map(|s| (s.msg.label.as_str(), s.msg.event.as_str())).collect();
    assert_eq!(
        events,
        [("spin cw", "start"), ("spin cw", "end"), ("record cw", "start"), ("record cw", "abort")],
        "{o}"
    );
}

/// Every gyro sample up to the abort is kept, its counter continuous.
fn assert_gyro_kept(rec: &Recording) {
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    assert!(rec.gyro.last().map_or(0, |g| g.log_time_ns) >= abort_ns, "gyro ended early");
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1), "gyro counter gap");
}

/// The table peer dropped its drive (`event`) mid-window: its next poll came within one poll
/// period (0.05 s) plus the peer's and the host's scheduling at 10× (in the peer's own clock),
/// the abort followed the first reading that showed the drive off, the reading before was at
/// speed, and the safe state's stop reached the controller.
fn assert_dropped_drive_aborts_at_once(run: &Run, event: &str) {
    assert_aborted_in_the_window(run, "table_drive_fault");
    assert!(run.outcome.contains("drive"), "{}", run.outcome);
    let log = &run.table_log;
    let dropped = log.iter().position(|e| e["event"] == event).expect("the peer dropped the drive");
    let t_drop = log[dropped]["t"].as_f64().unwrap_or(f64::NAN);
    let later: Vec<&Value> = log[dropped..].iter().filter(|e| e["rx"].is_string()).collect();
    let first_poll = later
        .iter()
        .find(|e| e["rx"].as_str().is_some_and(|r| r.starts_with("PRV 1,?")))
        .expect("a poll after the drop");
    let detect_s = first_poll["t"].as_f64().unwrap_or(f64::NAN) - t_drop;
    assert!((0.0..1.0).contains(&detect_s), "first poll {detect_s:.3} s after the drop");
    assert!(
        later.iter().any(|e| e["rx"] == "MOD 1,STP"),
        "no safe-state stop after the drop: {later:?}"
    );
    // In the recording: from the spin on, the drive reads on until the first reading that
    // shows it off, which comes at speed after one at speed, and the abort follows it at once.
    let rec = &run.rec;
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let spin_ns = rec.steps.first().map_or(0, |s| s.log_time_ns);
    let (last_on, first_off) = bench_tests::first_flagged(
        &rec.table,
        spin_ns,
        |t| t.log_time_ns,
        |t| t.msg.status & status::table::DRIVE_OFF != 0,
    )
    .expect("a reading with the drive off");
    assert!(first_off.log_time_ns <= abort_ns, "the reading that showed it is recorded");
    let to_abort = Duration::from_nanos(abort_ns - first_off.log_time_ns);
    assert!(to_abort <= Duration::from_secs(1), "abort {to_abort:?} after the reading");
    let deg_s = last_on.msg.rate_rad_s.abs().to_degrees();
    assert!((deg_s - 10.0).abs() < 0.01, "the reading before it at {deg_s} °/s");
    let kept = rec.gyro.iter().filter(|g| g.log_time_ns <= abort_ns).count();
    eprintln!(
        "{event}: next poll {detect_s:.3} s after the drop (peer clock), abort {:.3} s after \
         the reading that showed it, {:.3} s after the last at speed; {kept} gyro samples kept",
        to_abort.as_secs_f64(),
        (abort_ns - last_on.log_time_ns) as f64 * 1e-9
    );
    assert_gyro_kept(rec);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drive_alarm_mid_window_aborts_the_step_at_the_next_poll() {
    // The drive trips 60 s after the table was told to spin: mid-record.
    let run = run_on_peers(&["--drive-trip-after-rat", "60"], true).await;
    assert_dropped_drive_aborts_at_once(&run, "drive_trip");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_keep_alive_drops_the_drive_and_aborts_the_step_at_the_next_poll() {
    // No `ALC 0` after the session's first: the controller's 45 s watchdog drops the drive
    // mid-record (the spin and its settling take about 10 s of bench time after connecting).
    let run = run_on_peers(&["--watchdog-s", "45"], false).await;
    assert_dropped_drive_aborts_at_once(&run, "watchdog");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gyro_built_in_test_failure_aborts_the_step() {
    // The gyro peer's clock starts before bench connects (under a second of wall time at
    // 10×): its built-in-test bit from 60 s of its time falls inside the record window.
    let run = run_on_peers(&["--bit-fail-after", "60"], true).await;
    assert_aborted_in_the_window(&run, "gyro_bit_fail");
    let rec = &run.rec;
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let first_bad = rec
        .gyro
        .iter()
        .find(|g| g.msg.status & status::gyro::BIT_FAIL != 0)
        .expect("a sample with the built-in-test bit");
    // The sample that showed it was recorded, and the abort came within a few samples.
    let to_abort = Duration::from_nanos(abort_ns.saturating_sub(first_bad.log_time_ns));
    assert!(to_abort <= Duration::from_secs(1), "abort {to_abort:?} after the sample");
    eprintln!(
        "gyro_bit_fail: abort {:.3} s after the first flagged sample",
        to_abort.as_secs_f64()
    );
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1), "gyro counter gap");
}
