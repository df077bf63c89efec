//! bench's real rate-table driver against independent peers of the Actidyn and ACUTROL
//! controllers (`tests/peers/table.py`, written from the public facts, not from bench's codecs),
//! on loopback TCP and (Actidyn) a pseudo-terminal. Each test builds the driver from a `[table]`
//! section as a bench config would, runs connect, set rate, read back, stop and release, and
//! checks the peer's log for exactly the expected command lines. See docs/protocols/peers.md.

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::real::table::{RateTableDriver, TableDriverConfig};
use bench_drivers::{Clock, ErrorKind, RateTable, SystemClock, TableMode};
use bench_physics::units::DEG;
use bench_recording::status;
use bench_tests::peer::Peer;
use serde_json::Value;

/// Bench time per wall time, for both the peer's physics and the driver's clock.
const SCALE: f64 = 10.0;

fn table_config(section: &str) -> TableDriverConfig {
    toml::from_str(section).expect("a valid [table] section")
}

fn endpoint(peer: &Peer) -> String {
    match peer.ready.get("tcp") {
        Some(_) => format!("{{ tcp = {{ addr = \"{}\" }} }}", peer.tcp()),
        None => format!("{{ serial = {{ path = \"{}\", baud = 115200 }} }}", peer.pty()),
    }
}

/// The request lines the peer logged, with back-to-back repeats of a line or of a pair of lines
/// (ACUTROL reads position then rate) collapsed to one: the number of polls depends on timing.
fn requests(log: &[Value]) -> Vec<String> {
    let all = log.iter().filter_map(|e| e["rx"].as_str()).map(str::to_owned);
    let mut v: Vec<String> = Vec::new();
    for line in all {
        v.push(line);
        for k in [1, 2] {
            let n = v.len();
            if n >= 2 * k && v[n - k..] == v[n - 2 * k..n - k] {
                v.truncate(n - k);
            }
        }
    }
    v
}

/// Read (servicing the keep-alive) every 0.2 s of bench time until `done`, at most 10 s wall.
async fn poll_until(
    t: &mut RateTableDriver,
    clock: &SystemClock,
    mut done: impl FnMut(&bench_drivers::TableReading) -> bool,
) -> bench_drivers::TableReading {
    let wait = async {
        loop {
            t.service().await.expect("service");
            let r = t.read().await.expect("read");
            if done(&r) {
                return r;
            }
            clock.sleep(Duration::from_millis(200)).await;
        }
    };
    tokio::time::timeout(Duration::from_secs(10), wait).await.expect("condition reached in time")
}

async fn actidyn_sequence(transport: &str) {
    let peer = Peer::start(
        "table.py",
        &["--dialect", "actidyn", "--transport", transport, "--time-scale", &SCALE.to_string()],
    );
    let cfg = table_config(&format!("dialect = \"actidyn\"\nendpoint = {}\n", endpoint(&peer)));
    let clock = SystemClock::new(SCALE);
    let mut t = RateTableDriver::connect_with_clock(cfg, Arc::new(clock.clone()))
        .await
        .unwrap_or_else(|e| panic!("connect: {e}\npeer stderr:\n{}", peer.stderr()));
    t.set_rate(10.0 * DEG, 5.0 * DEG).await.expect("set_rate");
    let r = poll_until(&mut t, &clock, |r| (r.rate_rad_s - 10.0 * DEG).abs() < 1e-6).await;
    assert_eq!((r.mode, r.status), (TableMode::Rate, 0));
    let a0 = t.read().await.expect("read").angle_rad;
    clock.sleep(Duration::from_secs(2)).await;
    let a1 = t.read().await.expect("read").angle_rad;
    let turned = (a1 - a0) / DEG;
    assert!((15.0..30.0).contains(&turned), "turned {turned}° in ~2 s at 10 °/s");
    t.stop(10.0 * DEG).await.expect("stop");
    let r = poll_until(&mut t, &clock, |r| r.rate_rad_s == 0.0).await;
    assert_eq!(r.mode, TableMode::Stopped);
    t.release().await.expect("release");
    drop(t);
    let log = peer.stop();
    assert_eq!(
        requests(&log),
        [
            "RMT 0:ALC 0",
            "PRV 1,?:MOD 1,?",
            "MOD 1,RAT:RAT 1,10,5",
            "PRV 1,?:MOD 1,?",
            "MOD 1,STP",
            "PRV 1,?:MOD 1,?",
            "MOD 1,OFF:LOC 0",
        ],
        "{log:#?}"
    );
    // Every request was accepted (no ERR element in any reply).
    for e in &log {
        if let Some(tx) = e["tx"].as_str() {
            assert!(!tx.contains(",ERR,"), "refused: {e}");
        }
    }
}

#[tokio::test]
async fn actidyn_over_tcp() {
    actidyn_sequence("tcp").await;
}

#[tokio::test]
async fn actidyn_over_pty() {
    actidyn_sequence("pty").await;
}

/// The keep-alive at the default settings (ALC every 20 s, drive off after 30 s without one),
/// 65 s of bench time: the drive stays on; then the watchdog itself, with a short interval and
/// the keep-alive disabled: the drive drops and the driver reports it.
#[tokio::test]
async fn actidyn_keep_alive_holds_the_drive_and_its_absence_drops_it() {
    let scale = 25.0;
    let peer = Peer::start(
        "table.py",
        &["--dialect", "actidyn", "--transport", "tcp", "--time-scale", &scale.to_string()],
    );
    let clock = SystemClock::new(scale);
    let cfg = table_config(&format!("endpoint = {}\n", endpoint(&peer)));
    let mut t =
        RateTableDriver::connect_with_clock(cfg, Arc::new(clock.clone())).await.expect("connect");
    t.set_rate(1.0 * DEG, 1.0 * DEG).await.expect("set_rate");
    let end = clock.now() + Duration::from_secs(65);
    while clock.now() < end {
        t.service().await.expect("service");
        let r = t.read().await.expect("read");
        assert_eq!(r.status & (status::table::ALARM | status::table::DRIVE_OFF), 0, "{r:?}");
        clock.sleep(Duration::from_secs(1)).await;
    }
    assert!(t.counters().keep_alives >= 3, "{:?}", t.counters());
    drop(t);
    let log = peer.stop();
    assert!(log.iter().all(|e| e["event"] != "watchdog"), "watchdog fired: {log:#?}");
    let alc: Vec<f64> = log
        .iter()
        .filter(|e| e["rx"].as_str().is_some_and(|r| r.contains("ALC 0")))
        .filter_map(|e| e["t"].as_f64())
        .collect();
    assert!(alc.windows(2).all(|w| w[1] - w[0] < 25.0), "ALC at {alc:?}");
    assert!(alc.windows(2).all(|w| w[1] - w[0] > 19.0), "ALC at {alc:?}");

    // Keep-alive off, watchdog 3 s: the drive drops, the driver flags it.
    let peer = Peer::start(
        "table.py",
        &["--dialect", "actidyn", "--watchdog-s", "3", "--time-scale", &SCALE.to_string()],
    );
    let clock = SystemClock::new(SCALE);
    let cfg = table_config(&format!("endpoint = {}\nkeep_alive_s = 0\n", endpoint(&peer)));
    let mut t =
        RateTableDriver::connect_with_clock(cfg, Arc::new(clock.clone())).await.expect("connect");
    t.set_rate(1.0 * DEG, 1.0 * DEG).await.expect("set_rate");
    let r = poll_until(&mut t, &clock, |r| r.mode == TableMode::Off).await;
    assert_ne!(r.status & status::table::ALARM, 0, "{r:?}");
    let e = t.set_rate(1.0 * DEG, 1.0 * DEG).await.expect_err("refused while the alarm is set");
    // The peer's own error code: bench maps codes it does not know to a device fault.
    assert_eq!(e.kind(), ErrorKind::DeviceFault, "{e}");
    assert!(e.to_string().contains("drive alarm"), "{e}");
    t.clear_alarms().await.expect("ALC 0");
    t.set_rate(1.0 * DEG, 1.0 * DEG).await.expect("drive back on after ALC 0");
    drop(t);
    let log = peer.stop();
    assert_eq!(log.iter().filter(|e| e["event"] == "watchdog").count(), 1, "{log:#?}");
}

async fn acutrol_sequence(extra: &str, expected: &[&str]) {
    let peer = Peer::start(
        "table.py",
        &["--dialect", "acutrol", "--transport", "tcp", "--time-scale", &SCALE.to_string()],
    );
    let cfg =
        table_config(&format!("dialect = \"acutrol\"\nendpoint = {}\n{extra}", endpoint(&peer)));
    let clock = SystemClock::new(SCALE);
    let mut t = RateTableDriver::connect_with_clock(cfg, Arc::new(clock.clone()))
        .await
        .unwrap_or_else(|e| panic!("connect: {e}\npeer log: {:#?}", peer.log()));
    t.set_rate(10.0 * DEG, 5.0 * DEG).await.expect("set_rate");
    let r = poll_until(&mut t, &clock, |r| (r.rate_rad_s - 10.0 * DEG).abs() < 1e-6).await;
    assert_eq!((r.mode, r.status), (TableMode::Rate, 0));
    t.stop(10.0 * DEG).await.expect("stop");
    poll_until(&mut t, &clock, |r| r.rate_rad_s == 0.0).await;
    t.release().await.expect("release");
    drop(t);
    let log = peer.stop();
    assert_eq!(requests(&log), expected, "{log:#?}");
    assert!(log.iter().all(|e| !e["tx"].as_str().unwrap_or("").starts_with("ERR")), "{log:#?}");
}

#[tokio::test]
async fn acutrol_over_tcp_long_form() {
    acutrol_sequence(
        "",
        &[
            ":utility:lockout on",
            ":interlock:open 1",
            ":interlock:reset 1",
            ":interlock:close 1",
            ":read:position 1",
            ":read:rate 1",
            ":mode:rate 1",
            ":demand:rate 1, 010.000000",
            ":read:position 1",
            ":read:rate 1",
            ":demand:rate 1, 000.000000",
            ":read:position 1",
            ":read:rate 1",
            ":mode:off 1",
            ":interlock:open 1",
            ":utility:lockout off",
        ],
    )
    .await;
}

/// The public client's form: short keywords where it showed them, 3 decimals.
#[tokio::test]
async fn acutrol_over_tcp_short_form_three_decimals() {
    acutrol_sequence(
        "acutrol_short_form = true\nacutrol_decimals = 3\n",
        &[
            ":utility:lockout on",
            ":interlock:open 1",
            ":interlock:reset 1",
            ":interlock:close 1",
            ":R:P 1",
            ":R:R 1",
            ":M:R 1",
            ":D:R 1, 010.000",
            ":R:P 1",
            ":R:R 1",
            ":D:R 1, 000.000",
            ":R:P 1",
            ":R:R 1",
            ":mode:off 1",
            ":interlock:open 1",
            ":utility:lockout off",
        ],
    )
    .await;
}
