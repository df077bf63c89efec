//! The strongest check: a short scenario (`tests/peers/scenario.toml`) run end to end on the
//! three independent peers together (`tests/peers/serve_bench.py`: Actidyn table on a pty,
//! Eurotherm 3216 over Modbus RTU on a pty, gyro behind an SLCAN adapter on a pty, at 15× real
//! time), through the bench config file the peers wrote — loaded, connected and run as
//! `bench run SCENARIO --bench peer.toml` does — then the recording and the peers' logs are
//! checked. See docs/protocols/peers.md.

use std::path::PathBuf;

use crate::support::run_connected;
use bench::bench_config::BenchSource;
use bench_drivers::Clock;
use bench_recording::Recording;
use bench_tests::peer::{read_log, Peer};
use serde_json::Value;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scenario_on_the_three_peers_through_peer_toml() {
    let dir = tempfile::tempdir().expect("tempdir");
    let toml_path = dir.path().join("peer.toml");
    let logs = dir.path().join("logs");
    let peer = Peer::start(
        "serve_bench.py",
        &[
            "--time-scale",
            "15",
            "--out",
            toml_path.to_str().expect("utf-8"),
            "--log-dir",
            logs.to_str().expect("utf-8"),
        ],
    );
    assert_eq!(peer.ready["config"].as_str().map(PathBuf::from), Some(toml_path.clone()));

    // As `bench run --bench peer.toml`: load, connect every device, validate, run.
    let BenchSource::Devices(config) = BenchSource::load(&toml_path).expect("peer.toml loads")
    else {
        panic!("peer.toml names devices");
    };
    let scenario = bench_tests::workspace_root().join("tests/peers/scenario.toml");
    let (report, bytes, clock) = run_connected(&config, |caps| {
        bench::scenario::load(&scenario, caps).expect("valid on the peers")
    })
    .await;
    // After the run: 35 s of bench time without keep-alive (see the table check below).
    clock.sleep(std::time::Duration::from_secs(35)).await;
    drop(peer);
    let log = |name: &str| read_log(&logs.join(name));
    let (table, chamber, gyro) = (log("table.jsonl"), log("chamber.jsonl"), log("gyro.jsonl"));
    assert!(report.completed(), "{}; table log: {table:#?}", report.outcome);

    let rec = Recording::from_bytes(&bytes).expect("readable");
    let labels: Vec<&str> = rec
        .steps
        .iter()
        .filter(|s| s.msg.event.as_str() == "end")
        .map(|s| s.msg.label.as_str())
        .collect();
    assert_eq!(labels, ["to 25C", "soak 25C", "spin cw", "record cw 25C", "stop"], "{labels:?}");
    assert!(rec.gyro.len() > 100, "{} gyro samples", rec.gyro.len());
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1), "gyro counter gap");
    let spun = rec.table.iter().any(|t| (t.msg.rate_rad_s + 10f64.to_radians()).abs() < 1e-6);
    assert!(spun, "the table reached -10 °/s");
    let air = rec.chamber.iter().map(|c| c.msg.temperature_c).fold(f64::MIN, f64::max);
    assert!((24.7..25.5).contains(&air), "air peaked at {air} °C");

    check_table(&table);
    check_chamber(&chamber);
    check_gyro(&gyro);
}

fn rx(log: &[Value]) -> Vec<&str> {
    log.iter().filter_map(|e| e["rx"].as_str()).collect()
}

/// Session, spin, stop, keep-alives at least every 20 s of bench time during the run; and no
/// release at the end: the drive stays on with the keep-alive gone, so the controller drops it
/// 30 s later (a disagreement with the facts' session, documented in peers.md).
fn check_table(log: &[Value]) {
    let lines = rx(log);
    assert_eq!(lines.first(), Some(&"RMT 0:ALC 0"), "{lines:?}");
    let sets: Vec<&str> = lines.iter().copied().filter(|l| !l.starts_with("PRV 1,?")).collect();
    let mut no_alc = sets.clone();
    no_alc.retain(|l| *l != "ALC 0");
    // The stop step, then the safe state's stop at the end of the run.
    assert_eq!(
        no_alc,
        ["RMT 0:ALC 0", "MOD 1,RAT:RAT 1,-10,5", "MOD 1,STP", "MOD 1,STP"],
        "{sets:?}"
    );
    let alc: Vec<f64> = log
        .iter()
        .filter(|e| e["rx"].as_str().is_some_and(|r| r.contains("ALC 0")))
        .filter_map(|e| e["t"].as_f64())
        .collect();
    assert!(alc.len() >= 3 && alc.windows(2).all(|w| w[1] - w[0] < 25.0), "ALC at {alc:?}");
    assert!(!lines.contains(&"MOD 1,OFF:LOC 0"), "bench now releases the table: update peers.md");
    let watchdog: Vec<&Value> = log.iter().filter(|e| e["event"] == "watchdog").collect();
    assert_eq!(watchdog.len(), 1, "the drive dropped once, after the run: {watchdog:?}");
    let last_rx = log.iter().filter(|e| e["rx"].is_string()).filter_map(|e| e["t"].as_f64());
    let (end, dropped) = (last_rx.fold(0.0, f64::max), watchdog[0]["t"].as_f64().unwrap_or(0.0));
    assert!(dropped > end, "dropped at {dropped} s, after the last request at {end} s");
}

/// Remote set point selected once, ramp rate then set point, the safe set point at the end,
/// and never a write to an EEPROM register.
fn check_chamber(log: &[Value]) {
    let writes: Vec<(u64, Vec<u64>)> = log
        .iter()
        .filter(|e| e["fc"] == 6 || e["fc"] == 16)
        .map(|e| {
            let words = e["words"].as_array().map(|w| w.iter().filter_map(Value::as_u64).collect());
            (e["addr"].as_u64().unwrap_or(0), words.unwrap_or_default())
        })
        .collect();
    assert_eq!(
        writes,
        [(276, vec![1]), (35, vec![50]), (26, vec![250]), (35, vec![0]), (26, vec![230])],
        "{log:#?}"
    );
    let reads: Vec<u64> =
        log.iter().filter(|e| e["fc"] == 3).filter_map(|e| e["addr"].as_u64()).collect();
    assert!(reads.iter().all(|a| *a == 1 || *a == 5), "{reads:?}");
    assert!(log.iter().all(|e| e["exception"].is_null()), "{log:#?}");
    let exit = log.iter().find(|e| e["event"] == "exit").expect("exit record");
    assert_eq!(exit["eeprom_writes"], serde_json::json!({}));
}

fn check_gyro(log: &[Value]) {
    let mut commands: Vec<&str> = rx(log);
    commands.retain(|c| *c != "F");
    assert_eq!(commands[..4], ["C", "S6", "V", "O"], "{commands:?}");
    assert!(log.iter().filter(|e| e.get("sample").is_some()).count() > 100);
}
