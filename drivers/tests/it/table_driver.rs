//! The real rate-table driver against scripted fake controllers: byte-exact requests, reply
//! handling (unwrapping, error codes, garbled lines), retries and connect failures.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::Dialect;
use bench_drivers::real::table::{RateTableDriver, TableDriverConfig};
use bench_drivers::transport::{Endpoint, SerialSettings};
use bench_drivers::{Clock, ErrorKind, RateTable, SystemClock, TableMode};
use bench_recording::status;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// A scripted controller: expects these request lines in order and answers each with its
/// reply (none = stay silent). Stops at the first unexpected line. Returns every line received.
type Step = (&'static str, Option<&'static str>);

async fn scripted(listener: TcpListener, steps: Vec<Step>) -> Vec<String> {
    let (stream, _) = listener.accept().await.expect("accept");
    let (rd, mut wr) = stream.into_split();
    let mut rd = BufReader::new(rd);
    let mut got = Vec::new();
    for (expect, reply) in steps {
        let mut line = Vec::new();
        if rd.read_until(b'\n', &mut line).await.expect("read") == 0 {
            break;
        }
        let line = String::from_utf8_lossy(&line).into_owned();
        got.push(line.clone());
        if line != expect {
            break;
        }
        if let Some(r) = reply {
            wr.write_all(r.as_bytes()).await.expect("write");
        }
    }
    // Anything else the driver sends is recorded too.
    let mut rest = Vec::new();
    while let Ok(Ok(n)) =
        tokio::time::timeout(Duration::from_millis(50), rd.read_until(b'\n', &mut rest)).await
    {
        if n == 0 {
            break;
        }
        got.push(String::from_utf8_lossy(&rest).into_owned());
        rest.clear();
    }
    got
}

async fn listener() -> (TcpListener, Endpoint) {
    let l = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = l.local_addr().expect("addr").to_string();
    (l, Endpoint::Tcp { addr })
}

fn config(ep: Endpoint, dialect: Dialect) -> TableDriverConfig {
    TableDriverConfig { retry_backoff_s: 0.001, ..TableDriverConfig::new(ep, dialect) }
}

fn expected(steps: &[Step]) -> Vec<String> {
    steps.iter().map(|(e, _)| (*e).to_owned()).collect()
}

#[tokio::test]
async fn actidyn_requests_are_byte_exact_and_the_angle_is_unwrapped() {
    let steps: Vec<Step> = vec![
        ("RMT 0:ALC 0\n", Some("RMT 0,0:ALC 0,0\n")),
        ("PRV 1,?:MOD 1,?\n", Some("PRV 1,3,359.5,0,0:MOD 1,1,OFF\n")),
        ("MOD 1,RAT:RAT 1,10,5\n", Some("MOD 1,0:RAT 1,0\n")),
        ("PRV 1,?:MOD 1,?\n", Some("PRV 1,3,0.5,10,0:MOD 1,1,RAT\n")),
        ("MOD 1,STP\n", Some("MOD 1,0\n")),
        ("ALC 0\n", Some("ALC 0,0\n")),
        ("MOD 1,OFF:LOC 0\n", Some("MOD 1,0:LOC 0,0\n")),
    ];
    let (l, ep) = listener().await;
    let server = tokio::spawn(scripted(l, steps.clone()));
    let clock = Arc::new(SystemClock::new(100.0));
    let mut t = RateTableDriver::connect_with_clock(config(ep, Dialect::Actidyn), clock.clone())
        .await
        .expect("connect");
    t.service().await.expect("keep-alive not due yet: nothing sent");
    t.set_rate(10.0 * DEG, 5.0 * DEG).await.expect("set_rate");
    let r = t.read().await.expect("read");
    assert!((r.angle_rad - 360.5 * DEG).abs() < 1e-12, "unwrapped past 360°: {}", r.angle_rad);
    assert!((r.rate_rad_s - 10.0 * DEG).abs() < 1e-12);
    assert_eq!((r.rate_command_rad_s, r.mode, r.status), (10.0 * DEG, TableMode::Rate, 0));
    t.stop(5.0 * DEG).await.expect("stop");
    clock.sleep(Duration::from_secs(21)).await;
    t.service().await.expect("keep-alive");
    assert_eq!(t.counters().keep_alives, 1);
    t.release().await.expect("release");
    drop(t);
    assert_eq!(server.await.expect("server"), expected(&steps));
}

#[tokio::test]
async fn acutrol_requests_are_byte_exact() {
    let steps: Vec<Step> = vec![
        (":utility:lockout on\r\n", Some("OK\r\n")),
        (":interlock:open 1\r\n", Some("OK\r\n")),
        (":interlock:reset 1\r\n", Some("OK\r\n")),
        (":interlock:close 1\r\n", Some("OK\r\n")),
        (":read:position 1\r\n", Some("359.500000\r\n")),
        (":read:rate 1\r\n", Some("000.000000\r\n")),
        (":mode:rate 1\r\n", Some("OK\r\n")),
        (":demand:rate 1, 010.000000\r\n", Some("OK\r\n")),
        // Already in rate mode: only the demand.
        (":demand:rate 1, -05.000000\r\n", Some("OK\r\n")),
        (":read:position 1\r\n", Some("000.500000\r\n")),
        (":read:rate 1\r\n", Some("-05.000000\r\n")),
        (":demand:rate 1, 000.000000\r\n", Some("OK\r\n")),
        (":mode:off 1\r\n", Some("OK\r\n")),
        (":interlock:open 1\r\n", Some("OK\r\n")),
        (":utility:lockout off\r\n", Some("OK\r\n")),
    ];
    let (l, ep) = listener().await;
    let server = tokio::spawn(scripted(l, steps.clone()));
    let mut t = RateTableDriver::connect(config(ep, Dialect::Acutrol)).await.expect("connect");
    t.set_rate(10.0 * DEG, 5.0 * DEG).await.expect("set_rate");
    t.set_rate(-5.0 * DEG, 5.0 * DEG).await.expect("set_rate");
    let r = t.read().await.expect("read");
    assert!((r.angle_rad - 360.5 * DEG).abs() < 1e-9, "{}", r.angle_rad / DEG);
    assert!((r.rate_rad_s + 5.0 * DEG).abs() < 1e-12);
    t.stop(5.0 * DEG).await.expect("stop");
    t.service().await.expect("no keep-alive for ACUTROL");
    t.release().await.expect("release");
    drop(t);
    assert_eq!(server.await.expect("server"), expected(&steps));
}

#[tokio::test]
async fn a_garbled_reply_is_counted_skipped_and_retried_with_its_byte_offset() {
    const SESSION: &str = "RMT 0,0:ALC 0,0\n";
    const PROBE: &str = "PRV 1,3,10,0,0:MOD 1,1,OFF\n";
    const BAD: &str = "PRV 1,3,1x.5,0,0:MOD 1,1,OFF\n";
    let steps: Vec<Step> = vec![
        ("RMT 0:ALC 0\n", Some(SESSION)),
        ("PRV 1,?:MOD 1,?\n", Some(PROBE)),
        ("PRV 1,?:MOD 1,?\n", Some(BAD)),
        ("PRV 1,?:MOD 1,?\n", Some(PROBE)),
        ("PRV 1,?:MOD 1,?\n", Some(BAD)),
        ("PRV 1,?:MOD 1,?\n", Some(BAD)),
        ("PRV 1,?:MOD 1,?\n", Some(BAD)),
        ("PRV 1,?:MOD 1,?\n", Some(BAD)),
    ];
    let (l, ep) = listener().await;
    let server = tokio::spawn(scripted(l, steps.clone()));
    let mut t = RateTableDriver::connect(config(ep, Dialect::Actidyn)).await.expect("connect");
    let r = t.read().await.expect("second attempt succeeds");
    assert!((r.angle_rad - 10.0 * DEG).abs() < 1e-12);
    assert_eq!((t.counters().corrupt_replies, t.counters().retries), (1, 1));
    let e = t.read().await.expect_err("every attempt garbled");
    assert_eq!(e.kind(), ErrorKind::Protocol);
    // The last bad line starts after SESSION, 2 PROBEs and 4 BADs; "1x.5" is its 9th byte.
    let offset = SESSION.len() + 2 * PROBE.len() + 4 * BAD.len() + 8;
    assert!(e.message().contains(&format!("at byte {offset}:")), "{e}");
    assert!(e.message().contains("sent `PRV 1,?:MOD 1,?`"), "{e}");
    assert!(e.message().contains("(4 attempts)"), "{e}");
    assert_eq!(t.counters().corrupt_replies, 5);
    drop(t);
    assert_eq!(server.await.expect("server"), expected(&steps));
}

#[tokio::test]
async fn a_reply_after_its_timeout_is_drained_before_the_retry_and_counted_late() {
    // The controller answers the first state request 0.3 s late: after the driver's 0.1 s
    // timeout, before its 0.6 s back-off ends. The retry is answered at once.
    let (l, ep) = listener().await;
    let server = tokio::spawn(async move {
        let (stream, _) = l.accept().await.expect("accept");
        let (rd, mut wr) = stream.into_split();
        let mut rd = BufReader::new(rd);
        let mut got = Vec::new();
        for (i, reply) in [
            "RMT 0,0:ALC 0,0\n",
            "PRV 1,3,10,0,0:MOD 1,1,OFF\n",
            "PRV 1,3,20,0,0:MOD 1,1,OFF\n",
            "PRV 1,3,30,0,0:MOD 1,1,OFF\n",
        ]
        .into_iter()
        .enumerate()
        {
            let mut line = String::new();
            if rd.read_line(&mut line).await.expect("read") == 0 {
                break;
            }
            got.push(line);
            if i == 2 {
                tokio::time::sleep(Duration::from_millis(300)).await;
            }
            wr.write_all(reply.as_bytes()).await.expect("write");
        }
        got
    });
    let cfg = TableDriverConfig {
        reply_timeout_s: 0.1,
        retry_backoff_s: 0.6,
        ..TableDriverConfig::new(ep, Dialect::Actidyn)
    };
    let mut t = RateTableDriver::connect(cfg).await.expect("connect");
    let r = t.read().await.expect("the retry is answered");
    // The late answer (20°) was drained, not taken for the retry's (30°).
    assert!((r.angle_rad - 30.0 * DEG).abs() < 1e-12, "{}", r.angle_rad);
    let c = t.counters();
    assert_eq!((c.late_replies, c.stale_replies, c.retries), (1, 0, 1), "{c:?}");
    assert_eq!(t.link_counters(), Some(c));
    drop(t);
    assert_eq!(server.await.expect("server").len(), 4);
}

#[tokio::test]
async fn device_error_replies_map_to_kinds_without_retries() {
    let steps: Vec<Step> = vec![
        ("RMT 0:ALC 0\n", Some("RMT 0,0:ALC 0,0\n")),
        ("PRV 1,?:MOD 1,?\n", Some("PRV 1,3,0,0,0:MOD 1,1,OFF\n")),
        ("MOD 1,RAT:RAT 1,1,1\n", Some("MOD 1,0:RAT 1,ERR,11,rate too high\n")),
        ("MOD 1,RAT:RAT 1,1,1\n", Some("MOD 1,ERR,30,door open:RAT 1,ERR,30,door open\n")),
        ("MOD 1,RAT:RAT 1,1,1\n", Some("MOD 1,ERR,20,drive alarm:RAT 1,ERR,20,drive alarm\n")),
        ("PRV 1,?:MOD 1,?\n", Some("PRV 1,3,0,0,0:MOD 1,1,OFF\n")),
    ];
    let (l, ep) = listener().await;
    let server = tokio::spawn(scripted(l, steps.clone()));
    let mut t = RateTableDriver::connect(config(ep, Dialect::Actidyn)).await.expect("connect");
    let mut got = Vec::new();
    for _ in 0..3 {
        let e = t.set_rate(DEG, DEG).await.expect_err("refused");
        got.push(e.kind());
        assert!(e.message().contains("the controller refused"), "{e}");
    }
    assert_eq!(
        got,
        vec![ErrorKind::OutOfRange, ErrorKind::InterlockTripped, ErrorKind::DeviceFault]
    );
    // Beyond the configured capability: refused before anything is sent.
    let e = t.set_rate(1000.0 * DEG, DEG).await.expect_err("too fast");
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert!(e.message().contains("max_rate_deg_s"), "{e}");
    let r = t.read().await.expect("read");
    assert_eq!(r.status, status::table::DRIVE_OFF | status::table::ALARM);
    assert_eq!(t.counters().retries, 0);
    drop(t);
    assert_eq!(server.await.expect("server"), expected(&steps));
}

#[tokio::test]
async fn connect_to_a_silent_serial_port_says_what_was_sent_and_that_nothing_came_back() {
    use tokio_serial::SerialPort;
    let (_master, mut slave) = tokio_serial::SerialStream::pair().expect("pty");
    slave.set_exclusive(false).expect("non-exclusive");
    let path = slave.name().expect("pty name");
    let ep = Endpoint::Serial(SerialSettings {
        path: path.clone(),
        baud: 115_200,
        parity: Default::default(),
        data_bits: 8,
        stop_bits: 1,
    });
    let cfg =
        TableDriverConfig { reply_timeout_s: 0.05, retries: 1, ..config(ep, Dialect::Actidyn) };
    let e = RateTableDriver::connect(cfg).await.expect_err("nobody answers");
    assert_eq!(e.kind(), ErrorKind::Timeout);
    let want = format!(
        "sent `RMT 0:ALC 0` on serial {path} at 115200 baud, no reply within 50 ms (2 attempts)"
    );
    assert!(e.message().contains(&want), "{e}");
    assert!(e.message().starts_with("connecting to the actidyn table on serial"), "{e}");
}

#[tokio::test]
async fn connect_to_a_closed_tcp_port_is_a_link_error_naming_the_address() {
    let (l, ep) = listener().await;
    drop(l);
    let Endpoint::Tcp { addr } = ep.clone() else { unreachable!() };
    let e = RateTableDriver::connect(config(ep, Dialect::Acutrol)).await.expect_err("refused");
    assert_eq!(e.kind(), ErrorKind::Link);
    assert!(e.message().contains(&format!("connecting to the acutrol table on tcp {addr}")), "{e}");
    assert!(e.message().contains(&format!("cannot connect to {addr}")), "{e}");
}

#[test]
fn config_parses_from_toml_with_documented_defaults_and_rejects_unknown_fields() {
    let c: TableDriverConfig =
        toml::from_str("dialect = \"acutrol\"\n[endpoint.tcp]\naddr = \"10.0.0.5:9888\"\n")
            .expect("parses");
    let d =
        TableDriverConfig::new(Endpoint::Tcp { addr: "10.0.0.5:9888".into() }, Dialect::Acutrol);
    assert_eq!(c, d);
    assert_eq!(
        (c.axis, c.reply_timeout_s, c.retries, c.retry_backoff_s, c.keep_alive_s),
        (1, 0.5, 3, 0.05, 20.0)
    );
    assert_eq!((c.max_rate_deg_s, c.max_accel_deg_s2, c.acutrol_decimals), (100.0, 10.0, 6));
    let e = toml::from_str::<TableDriverConfig>(
        "retry = 3\n[endpoint.tcp]\naddr = \"10.0.0.5:9888\"\n",
    )
    .expect_err("unknown field");
    assert!(e.to_string().contains("unknown field `retry`"), "{e}");
}
