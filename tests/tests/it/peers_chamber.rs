//! bench's real Modbus chamber driver against independent pymodbus peers of the Watlow F4,
//! Watlow F4T and Eurotherm 3216 (`tests/peers/chamber.py`, written from the public register
//! facts, not from bench's register maps), over Modbus TCP on loopback and Modbus RTU on a
//! pseudo-terminal. Each test builds the driver from a `[chamber]` section as a bench config
//! would, runs connect, set point, read back, ramp and the safe set point, and checks the
//! peer's log for exactly the expected requests (function, register, words). See
//! docs/protocols/peers.md.

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::real::chamber::{ModbusChamber, ModbusChamberConfig};
use bench_drivers::{Chamber, ChamberReading, Clock, ErrorKind, SystemClock};
use bench_tests::peer::Peer;
use serde_json::Value;

const SCALE: f64 = 10.0;

fn start(model: &str, transport: &str, extra: &[&str]) -> Peer {
    let scale = SCALE.to_string();
    let mut args =
        vec!["--model", model, "--transport", transport, "--time-scale", &scale, "--tau-s", "4"];
    args.extend_from_slice(extra);
    Peer::start("chamber.py", &args)
}

/// The `[chamber]` section of a bench config reaching `peer`, plus `extra` lines.
fn config(peer: &Peer, map: &str, extra: &str) -> ModbusChamberConfig {
    let endpoint = match peer.ready.get("tcp") {
        Some(_) => format!("{{ tcp = {{ addr = \"{}\" }} }}", peer.tcp()),
        None => format!("{{ serial = {{ path = \"{}\", baud = 9600 }} }}", peer.pty()),
    };
    toml::from_str(&format!("endpoint = {endpoint}\nmap = \"{map}\"\n{extra}"))
        .expect("a valid [chamber] section")
}

async fn connect(peer: &Peer, cfg: ModbusChamberConfig, clock: &SystemClock) -> ModbusChamber {
    ModbusChamber::connect(cfg, Arc::new(clock.clone()))
        .await
        .unwrap_or_else(|e| panic!("connect: {e}\npeer log: {:#?}\n{}", peer.log(), peer.stderr()))
}

/// Each request as `r<addr>x<count>` or `w<addr>=<words>` (`!<code>` when refused), with
/// back-to-back repeats of one request or a pair collapsed (polls depend on timing).
fn requests(log: &[Value]) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for e in log.iter().filter(|e| e["fc"].is_number()) {
        let addr = &e["addr"];
        let mut s = match e["fc"].as_u64() {
            Some(3) => format!("r{addr}x{}", e["count"]),
            Some(fc) => {
                let words: Vec<String> = e["words"]
                    .as_array()
                    .map(|w| w.iter().map(|x| format!("{:04X}", x.as_u64().unwrap_or(0))).collect())
                    .unwrap_or_default();
                format!("w{addr}={}/fc{fc}", words.join(","))
            }
            None => unreachable!(),
        };
        if let Some(code) = e["exception"].as_u64() {
            s += &format!("!{code}");
        }
        v.push(s);
        for k in [1, 2] {
            let n = v.len();
            if n >= 2 * k && v[n - k..] == v[n - 2 * k..n - k] {
                v.truncate(n - k);
            }
        }
    }
    v
}

/// Read every 0.5 s of bench time until `done` (at most 10 s wall), servicing driver ramps.
async fn poll_until(
    c: &mut ModbusChamber,
    clock: &SystemClock,
    mut done: impl FnMut(&ChamberReading) -> bool,
) -> ChamberReading {
    let wait = async {
        loop {
            c.service().await.expect("service");
            let r = c.read().await.expect("read");
            if done(&r) {
                return r;
            }
            clock.sleep(Duration::from_millis(500)).await;
        }
    };
    tokio::time::timeout(Duration::from_secs(10), wait).await.expect("condition reached in time")
}

/// The two words of `v` as float32, low word first (the F4T fact), as the log prints them.
fn f4t_words(v: f32) -> String {
    let b = v.to_bits();
    format!("{:04X},{:04X}", b & 0xFFFF, b >> 16)
}

fn int16(v: i16) -> String {
    format!("{:04X}", v as u16)
}

async fn watlow_f4(transport: &str) {
    let peer = start("watlow_f4", transport, &[]);
    let clock = SystemClock::new(SCALE);
    let cfg = config(
        &peer,
        "watlow_f4",
        "model_check = { register = 0, value = 5270 }\ncapabilities = { max_temp_c = 200.0 }\n",
    );
    let mut c = connect(&peer, cfg, &clock).await;
    assert_eq!(c.decimals(), 1);
    let r = c.read().await.expect("read");
    assert_eq!((r.temperature_c, r.setpoint_c), (23.0, 23.0));
    c.set_target(30.0, None).await.expect("set point");
    let r = poll_until(&mut c, &clock, |r| r.temperature_c >= 29.0).await;
    assert_eq!((r.setpoint_c, r.target_c), (30.0, 30.0));
    // A driver-run ramp (the F4 preset has no rate register): 30 → 29.7 at 0.05 °C/s.
    c.set_target(29.7, Some(0.05)).await.expect("ramp");
    let r = poll_until(&mut c, &clock, |r| r.setpoint_c == 29.7 && r.status == 0).await;
    assert_eq!(r.target_c, 29.7);
    // Outside the controller's set-point limits (602/603: -70..190 °C) but inside bench's
    // capabilities widened for the test: the controller's exception 3 is OutOfRange.
    let e = c.set_target(195.0, None).await.expect_err("refused by the controller");
    assert_eq!(e.kind(), ErrorKind::OutOfRange, "{e}");
    c.set_target(23.0, None).await.expect("safe set point");
    drop(c);
    let log = peer.stop();
    let ramp: Vec<String> =
        [297, 298, 299].iter().rev().map(|&w| format!("w300={}/fc6", int16(w))).collect();
    let mut expected = vec!["r100x1", "r606x1", "r901x1", "r0x1", "r300x1", "r100x1"]
        .into_iter()
        .map(String::from)
        .collect::<Vec<_>>();
    expected.push(format!("w300={}/fc6", int16(300)));
    expected.push("r100x1".into());
    for w in ramp {
        expected.push(w);
        expected.push("r100x1".into());
    }
    expected.push(format!("w300={}/fc6!3", int16(1950)));
    expected.push(format!("w300={}/fc6", int16(230)));
    let got = requests(&log);
    assert_eq!(got, expected, "{got:#?}");
}

#[tokio::test]
async fn watlow_f4_over_tcp() {
    watlow_f4("tcp").await;
}

#[tokio::test]
async fn watlow_f4_over_rtu() {
    watlow_f4("rtu").await;
}

async fn watlow_f4t(transport: &str) {
    let peer = start("watlow_f4t", transport, &[]);
    let clock = SystemClock::new(SCALE);
    let mut c = connect(&peer, config(&peer, "watlow_f4t", ""), &clock).await;
    let r = c.read().await.expect("read");
    assert_eq!((r.temperature_c, r.setpoint_c), (23.0, 23.0));
    c.set_target(-12.5, None).await.expect("set point");
    let r = poll_until(&mut c, &clock, |r| r.temperature_c <= -11.0).await;
    assert_eq!((r.setpoint_c, r.target_c), (-12.5, -12.5));
    c.set_target(23.0, None).await.expect("safe set point");
    drop(c);
    let log = peer.stop();
    assert_eq!(
        requests(&log),
        [
            "r2820x2".to_string(),
            "r2810x2".into(),
            format!("w2782={}/fc16", f4t_words(-12.5)),
            "r2820x2".into(),
            "r2810x2".into(),
            format!("w2782={}/fc16", f4t_words(23.0)),
        ],
        "{log:#?}"
    );
}

#[tokio::test]
async fn watlow_f4t_over_tcp() {
    watlow_f4t("tcp").await;
}

#[tokio::test]
async fn watlow_f4t_over_rtu() {
    watlow_f4t("rtu").await;
}

async fn eurotherm_3216(transport: &str) {
    let peer = start("eurotherm_3216", transport, &[]);
    let clock = SystemClock::new(SCALE);
    let mut c = connect(&peer, config(&peer, "eurotherm_3216", ""), &clock).await;
    // 23 → 24 °C at 5 °C/min: the controller ramps its working set point (12 s of bench time).
    c.set_target(24.0, Some(5.0 / 60.0)).await.expect("ramp");
    let r = c.read().await.expect("read");
    assert!(r.setpoint_c < 24.0 && r.status != 0, "ramping: {r:?}");
    let r = poll_until(&mut c, &clock, |r| r.setpoint_c == 24.0 && r.status == 0).await;
    assert_eq!(r.target_c, 24.0);
    c.set_target(23.0, None).await.expect("safe set point");
    drop(c);
    let log = peer.stop();
    assert_eq!(
        requests(&log),
        [
            "w276=0001/fc6".to_string(),
            "r1x1".into(),
            "r5x1".into(),
            format!("w35={}/fc6", int16(50)),
            format!("w26={}/fc6", int16(240)),
            "r1x1".into(),
            "r5x1".into(),
            "w35=0000/fc6".into(),
            format!("w26={}/fc6", int16(230)),
        ],
        "{log:#?}"
    );
    // The EEPROM registers (2, 24, 25) were never written.
    let exit = log.iter().find(|e| e["event"] == "exit").expect("exit record");
    assert_eq!(exit["eeprom_writes"], serde_json::json!({}), "{exit}");
}

#[tokio::test]
async fn eurotherm_3216_over_tcp() {
    eurotherm_3216("tcp").await;
}

#[tokio::test]
async fn eurotherm_3216_over_rtu() {
    eurotherm_3216("rtu").await;
}

/// Issue 17: a Watlow F4 set to °F (register 901 = 0) sends °F in register 100; the driver
/// must not take 73.4 °F for 73.4 °C.
#[tokio::test]
async fn issue17_watlow_f4_in_fahrenheit_is_refused_at_connect() {
    let peer = start("watlow_f4", "tcp", &["--fahrenheit"]);
    let clock = SystemClock::new(SCALE);
    let e = ModbusChamber::connect(config(&peer, "watlow_f4", ""), Arc::new(clock))
        .await
        .err()
        .expect("refused");
    assert_eq!(e.kind(), ErrorKind::Unsupported, "{e}");
    assert!(e.to_string().contains("901"), "{e}");
    drop(peer);
}

/// A custom map with the alarm and door bits of a status register (the peer serves one at
/// 1000: bit 0 alarm, bit 1 door; the public facts give no such register for these
/// controllers, so no preset has one): each poll reads it, and the reading's status shows
/// `ALARM` and `DOOR_OPEN` once the peer sets them — what the run's `chamber_alarm` and
/// `chamber_door_open` interlocks abort on.
#[tokio::test]
async fn alarm_and_door_bits_of_a_custom_map_reach_the_reading() {
    use bench_recording::status::chamber::{ALARM, DOOR_OPEN};
    let peer = start(
        "eurotherm_3216",
        "tcp",
        &["--status-register", "1000", "--alarm-after", "20", "--door-open-after", "40"],
    );
    let clock = SystemClock::new(SCALE);
    let map = "{ model = \"Eurotherm 3216 + status\", encoding = { type = \"int16\", decimals = \
               { fixed = 1 } }, process_value = 1, set_point = 26, working_set_point = 5, \
               ramp_rate = 35, on_connect = [{ register = 276, value = 1 }], \
               eeprom_registers = [2, 24, 25], alarm = { register = 1000, mask = 1 }, \
               door = { register = 1000, mask = 2 } }";
    let cfg: ModbusChamberConfig = toml::from_str(&format!(
        "endpoint = {{ tcp = {{ addr = \"{}\" }} }}\nmap = {map}\n",
        peer.tcp()
    ))
    .expect("a valid [chamber] section");
    let mut c = connect(&peer, cfg, &clock).await;
    let first = c.read().await.expect("read");
    assert_eq!(first.status & (ALARM | DOOR_OPEN), 0, "{first:?}");
    let alarm = poll_until(&mut c, &clock, |r| r.status & ALARM != 0).await;
    assert_eq!(alarm.status & DOOR_OPEN, 0, "{alarm:?}");
    let door = poll_until(&mut c, &clock, |r| r.status & DOOR_OPEN != 0).await;
    assert_eq!(door.status & ALARM, ALARM, "{door:?}");
    drop(c);
    let log = peer.stop();
    let reads: Vec<u64> =
        log.iter().filter(|e| e["fc"] == 3).filter_map(|e| e["addr"].as_u64()).collect();
    assert!(reads.windows(3).any(|w| w == [1, 5, 1000]), "PV, WSP, status per poll: {reads:?}");
}
