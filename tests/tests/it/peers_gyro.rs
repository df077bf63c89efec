//! bench's real CAN gyro driver on an SLCAN adapter, against an independent peer of the adapter
//! and the gyro behind it (`tests/peers/gyro.py`: Lawicel text protocol and bench's CAN frame
//! set, implemented from the public protocol and docs/protocols/gyro-can.md, not from bench's
//! codecs), on a pseudo-terminal. And python-can's `slcan` interface as an independent client
//! of the same adapter peer, so the peer itself is checked by a third party. See
//! docs/protocols/peers.md.

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::real::gyro_can::{CanGyro, CanGyroConfig};
use bench_drivers::{Gyro, SystemClock};
use bench_recording::status;
use bench_tests::peer::Peer;
use serde_json::Value;

#[tokio::test]
async fn can_gyro_over_slcan_on_a_pty() {
    let scale = 5.0;
    let peer = Peer::start(
        "gyro.py",
        &["--time-scale", "5", "--rate-hz", "20", "--seq0", "0xFFFFFFF0", "--status-demo"],
    );
    // The [gyro] section of a bench config.
    let cfg: CanGyroConfig = toml::from_str(&format!(
        "transport = {{ kind = \"slcan\", serial = {{ path = \"{}\", baud = 115200 }}, bitrate = 500000 }}\nsample_rate_hz = 20.0\n",
        peer.pty()
    ))
    .expect("a valid [gyro] section (driver = \"can\")");
    let clock = Arc::new(SystemClock::new(scale));
    let mut g = CanGyro::open(&cfg, clock)
        .await
        .unwrap_or_else(|e| panic!("open: {e}\npeer log: {:#?}", peer.log()));
    let mut got = Vec::new();
    for _ in 0..40 {
        let s = tokio::time::timeout(Duration::from_secs(10), g.next_sample())
            .await
            .expect("a sample in time")
            .expect("sample");
        got.push(s);
    }
    g.close().await.expect("close");
    drop(g);
    let log = peer.stop();

    // Every sample as the peer sent it: rate = delta × 2⁻⁴⁰ / period, temperature in 0.01 °C,
    // the u32 counter across its wrap, and the status bits mapped.
    let sent: Vec<&Value> = log.iter().filter_map(|e| e.get("sample")).collect();
    for s in &got {
        let p = sent
            .iter()
            .find(|p| p["seq"].as_u64() == Some(s.seq))
            .unwrap_or_else(|| panic!("sample {} was not sent", s.seq));
        let period_s = p["period_ns"].as_f64().expect("period") * 1e-9;
        let rate = p["delta"].as_f64().expect("delta") * 2f64.powi(-40) / period_s;
        assert!((s.rate_rad_s - rate).abs() <= 1e-12 * rate.abs(), "{s:?} vs {p}");
        let peer_status = p["status"].as_u64().expect("status");
        let temp =
            (peer_status & 0x8 == 0).then(|| p["temp_centi"].as_f64().unwrap_or(0.0) / 100.0);
        assert_eq!(s.temperature_c, temp, "{s:?} vs {p}");
        let mut expected = 0;
        if peer_status & 0x5 != 0 {
            expected |= status::gyro::INVALID;
        }
        if peer_status & 0x2 != 0 {
            expected |= status::gyro::BIT_FAIL;
        }
        assert_eq!(s.status, expected, "{s:?} vs {p}");
    }
    assert!(got.windows(2).all(|w| w[1].seq == (w[0].seq + 1) % (1 << 32)), "{got:?}");
    assert!(got.iter().any(|s| s.seq == 0), "the counter wrapped");

    // The adapter saw: close (BEL: it was closed), bit rate 500k, version, open, status polls,
    // close.
    let commands: Vec<(&str, &str)> =
        log.iter().filter_map(|e| Some((e["rx"].as_str()?, e["tx"].as_str()?))).collect();
    let (polls, other): (Vec<_>, Vec<_>) = commands.iter().copied().partition(|(rx, _)| *rx == "F");
    assert_eq!(
        other,
        [("C", "BEL"), ("S6", ""), ("V", "V1013"), ("O", ""), ("C", "")],
        "{commands:?}"
    );
    assert!(!polls.is_empty() && polls.iter().all(|(_, tx)| *tx == "F00"), "{polls:?}");
}

/// python-can's `slcan` interface reads the adapter peer: frames decoded as gyro-can.md says
/// match the samples the peer logged, and it answers `V` and `N`.
#[test]
fn python_can_reads_the_adapter_peer() {
    let out = std::process::Command::new(bench_tests::python())
        .arg(bench_tests::peer::script("check_slcan_python_can.py"))
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\nstderr:\n{}", String::from_utf8_lossy(&out.stderr));
    let r: Value = serde_json::from_str(stdout.trim()).expect("one JSON line");
    assert!(r["decoded_samples"].as_u64() >= Some(10), "{r}");
    // python-can reads the version digits as decimal (bench: hex; see peers.md).
    assert_eq!(r["version"], serde_json::json!([10, 13]), "{r}");
    assert_eq!(r["serial_number"], "A123", "{r}");
    // python-can's open: C, S6, an empty command (no data bit rate), O, and O again.
    let commands = r["commands"].as_array().expect("commands");
    assert_eq!(
        commands[..5],
        serde_json::json!(["C", "S6", "", "O", "O"]).as_array().expect("a")[..],
        "{r}"
    );
}
