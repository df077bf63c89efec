//! The real rate-table driver against the simulated controller (physics table behind the
//! Actidyn or ACUTROL dialect) on a pseudo-terminal and on loopback TCP, in scaled real time:
//! motion, keep-alive and watchdog, injected faults and recovery.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::Dialect;
use bench_drivers::real::table::{RateTableDriver, TableDriverConfig};
use bench_drivers::transport::{Endpoint, SerialSettings};
use bench_drivers::{Clock, ErrorKind, RateTable, SystemClock, TableMode, TableReading};
use bench_physics::units::DEG;
use bench_recording::status;
use bench_sim::faults::{Fault, FaultSwitch};
use bench_sim::ports::{loopback_listener, Pty};
use bench_sim::serve::table::{
    serve_table_pty, serve_table_tcp, TableController, TableServeOptions, TableServerStats,
};
use bench_sim::{SimBench, SimConfig};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Port {
    Pty,
    Tcp,
}

struct Rig {
    clock: Arc<SystemClock>,
    faults: FaultSwitch,
    stats: Arc<TableServerStats>,
    endpoint: Endpoint,
    server: tokio::task::JoinHandle<std::io::Result<()>>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.server.abort();
    }
}

fn n(c: &AtomicU64) -> u64 {
    TableServerStats::get(c)
}

/// A simulated controller serving on `port`, ready before this returns (the pty path exists,
/// the listener is bound).
async fn rig(dialect: Dialect, port: Port, scale: f64) -> Rig {
    let clock = Arc::new(SystemClock::new(scale));
    let bench = SimBench::new(SimConfig::default(), clock.clone()).expect("sim");
    let faults = FaultSwitch::new();
    let ctl = TableController::new(
        bench.table,
        clock.clone(),
        TableServeOptions::new(dialect, faults.clone()),
    );
    let stats = ctl.stats();
    let (endpoint, server) = match port {
        Port::Pty => {
            let pty = Pty::new().expect("pty");
            let ep = Endpoint::Serial(SerialSettings {
                path: pty.path.clone(),
                baud: 115_200,
                parity: Default::default(),
                data_bits: 8,
                stop_bits: 1,
            });
            (ep, tokio::spawn(serve_table_pty(pty, ctl)))
        }
        Port::Tcp => {
            let l = loopback_listener().await.expect("bind");
            let ep = Endpoint::Tcp { addr: l.local_addr().expect("addr").to_string() };
            (ep, tokio::spawn(serve_table_tcp(l, ctl)))
        }
    };
    Rig { clock, faults, stats, endpoint, server }
}

impl Rig {
    fn config(&self, dialect: Dialect) -> TableDriverConfig {
        TableDriverConfig {
            reply_timeout_s: 0.1,
            retry_backoff_s: 0.01,
            ..TableDriverConfig::new(self.endpoint.clone(), dialect)
        }
    }

    async fn driver(&self, dialect: Dialect) -> RateTableDriver {
        RateTableDriver::connect_with_clock(self.config(dialect), self.clock.clone())
            .await
            .expect("connect")
    }

    /// Read, with the bench-time window the reading was taken in.
    async fn timed_read(&self, t: &mut RateTableDriver) -> (TableReading, f64, f64) {
        let before = self.clock.now().as_secs_f64();
        let r = t.read().await.expect("read");
        (r, before, self.clock.now().as_secs_f64())
    }

    /// Service and read every bench second until `done` holds (at most 30 s of wall time).
    async fn poll_until(
        &self,
        t: &mut RateTableDriver,
        mut done: impl FnMut(&TableReading) -> bool,
    ) -> TableReading {
        let wait = async {
            loop {
                t.service().await.expect("service");
                let r = t.read().await.expect("read");
                if done(&r) {
                    return r;
                }
                self.clock.sleep(Duration::from_secs(1)).await;
            }
        };
        tokio::time::timeout(Duration::from_secs(30), wait).await.expect("condition reached")
    }

    /// Service and read every bench second for `secs` of bench time.
    async fn run_for(&self, t: &mut RateTableDriver, secs: u64) -> TableReading {
        let end = self.clock.now() + Duration::from_secs(secs);
        let clock = self.clock.clone();
        self.poll_until(t, move |_| clock.now() >= end).await
    }
}

const RATE_DEG_S: f64 = 10.0;

async fn motion(dialect: Dialect, port: Port) {
    let rig = rig(dialect, port, 100.0).await;
    let mut t = rig.driver(dialect).await;
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("set_rate");
    let r = rig.poll_until(&mut t, |r| (r.rate_rad_s - RATE_DEG_S * DEG).abs() < 0.01 * DEG).await;
    assert_eq!((r.mode, r.rate_command_rad_s), (TableMode::Rate, RATE_DEG_S * DEG));
    // The angle advances at the commanded rate, unwrapped past 360° (the controller wraps).
    let (r1, a1, b1) = rig.timed_read(&mut t).await;
    rig.run_for(&mut t, 40).await;
    let (r2, a2, b2) = rig.timed_read(&mut t).await;
    let turned_deg = (r2.angle_rad - r1.angle_rad) / DEG;
    let expected_deg = RATE_DEG_S * ((a2 + b2) / 2.0 - (a1 + b1) / 2.0);
    let window_deg = RATE_DEG_S * ((b1 - a1) + (b2 - a2)) / 2.0 + 0.01;
    assert!(turned_deg > 360.0, "{turned_deg}");
    assert!(
        (turned_deg - expected_deg).abs() <= window_deg,
        "turned {turned_deg}°, expected {expected_deg}° ± {window_deg}°"
    );
    assert_eq!(r2.status, 0);
    t.stop(10.0 * DEG).await.expect("stop");
    let r = rig.poll_until(&mut t, |r| r.rate_rad_s.abs() < 0.001 * DEG).await;
    assert_eq!((r.mode, r.rate_command_rad_s), (TableMode::Stopped, 0.0));
    assert_eq!(n(&rig.stats.watchdog_trips), 0);
    assert_eq!(n(&rig.stats.bad_requests), 0);
}

#[tokio::test]
async fn actidyn_on_a_pty_reaches_the_rate_turns_at_it_and_stops() {
    motion(Dialect::Actidyn, Port::Pty).await;
}

#[tokio::test]
async fn actidyn_on_tcp_reaches_the_rate_turns_at_it_and_stops() {
    motion(Dialect::Actidyn, Port::Tcp).await;
}

#[tokio::test]
async fn acutrol_on_a_pty_reaches_the_rate_turns_at_it_and_stops() {
    motion(Dialect::Acutrol, Port::Pty).await;
}

#[tokio::test]
async fn acutrol_on_tcp_reaches_the_rate_turns_at_it_and_stops() {
    motion(Dialect::Acutrol, Port::Tcp).await;
}

#[tokio::test]
async fn actidyn_keep_alive_is_sent_every_20_s_and_keeps_the_drive_on() {
    let rig = rig(Dialect::Actidyn, Port::Tcp, 100.0).await;
    let mut t = rig.driver(Dialect::Actidyn).await;
    assert_eq!(n(&rig.stats.alarm_clears), 1, "session start");
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("set_rate");
    let r = rig.run_for(&mut t, 70).await;
    assert!(t.counters().keep_alives >= 3, "{:?}", t.counters());
    assert_eq!(n(&rig.stats.alarm_clears), 1 + t.counters().keep_alives);
    assert_eq!(n(&rig.stats.watchdog_trips), 0);
    assert_eq!((r.mode, r.status), (TableMode::Rate, 0));
}

#[tokio::test]
async fn without_keep_alive_the_watchdog_drops_the_drive_until_alarms_are_cleared() {
    let rig = rig(Dialect::Actidyn, Port::Pty, 100.0).await;
    let cfg = TableDriverConfig { keep_alive_s: 0.0, ..rig.config(Dialect::Actidyn) };
    // Read before connecting: the session-start ALC reaches the controller after this instant,
    // so its watchdog cannot trip before `before_alc + 30 s` (reading it after `connect` returns
    // can be late by the scheduling delay of a loaded machine, times the 100× clock).
    let before_alc = rig.clock.now();
    let mut t = RateTableDriver::connect_with_clock(cfg, rig.clock.clone()).await.expect("connect");
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("set_rate");
    let r = rig.poll_until(&mut t, |r| r.mode == TableMode::Off).await;
    assert!(rig.clock.now() >= before_alc + Duration::from_secs(30));
    assert_eq!(r.status, status::table::DRIVE_OFF | status::table::ALARM);
    assert_eq!(n(&rig.stats.watchdog_trips), 1);
    assert_eq!(t.counters().keep_alives, 0);
    let r = rig.poll_until(&mut t, |r| r.rate_rad_s.abs() < 0.001 * DEG).await;
    assert_eq!(r.mode, TableMode::Off, "the table came to rest with the drive off");
    let e = t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect_err("drive alarm");
    assert_eq!(e.kind(), ErrorKind::DeviceFault);
    assert!(e.message().contains("error 20 drive alarm"), "{e}");
    t.clear_alarms().await.expect("ALC");
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("drive on again");
    let r = rig.poll_until(&mut t, |r| (r.rate_rad_s - RATE_DEG_S * DEG).abs() < 0.01 * DEG).await;
    assert_eq!((r.mode, r.status), (TableMode::Rate, 0));
}

/// Silence, corruption, disconnection and a stuck table, each cleared again; scale 10 so the
/// retries (wall-clock time) stay well inside the 30 s watchdog.
async fn faults(dialect: Dialect, port: Port) {
    let rig = rig(dialect, port, 10.0).await;
    let mut t = rig.driver(dialect).await;

    rig.faults.inject(Fault::Silence);
    let e = t.read().await.expect_err("silent");
    assert_eq!(e.kind(), ErrorKind::Timeout);
    assert!(e.message().contains("no reply within 100 ms (4 attempts)"), "{e}");
    rig.faults.clear();
    t.service().await.expect("service");
    t.read().await.expect("recovered from silence");

    rig.faults.inject(Fault::Corrupt { every: 1 });
    let before = t.counters().corrupt_replies;
    let e = t.read().await.expect_err("every reply corrupt");
    assert_eq!(e.kind(), ErrorKind::Protocol);
    assert!(e.message().contains("at byte"), "{e}");
    assert_eq!(t.counters().corrupt_replies, before + 4);
    rig.faults.inject(Fault::Corrupt { every: 2 });
    for _ in 0..4 {
        t.read().await.expect("a corrupt reply is skipped and the command retried");
    }
    assert!(t.counters().corrupt_replies >= before + 6, "{:?}", t.counters());
    rig.faults.clear();
    t.service().await.expect("service");

    let retries = t.counters().retries;
    rig.faults.inject(Fault::Disconnect { seconds: 1.0 });
    t.read().await.expect("recovered from the disconnection within the retries");
    assert!(t.counters().retries > retries);
    match port {
        Port::Tcp => {
            assert_eq!(t.counters().reconnects, 1);
            assert_eq!(n(&rig.stats.connections), 2);
        }
        Port::Pty => assert_eq!(t.counters().reconnects, 0),
    }

    rig.faults.inject(Fault::StuckTable);
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("acknowledged");
    let r = rig.run_for(&mut t, 3).await;
    assert!(r.rate_rad_s.abs() < 0.01 * DEG, "stuck: {}", r.rate_rad_s / DEG);
    assert_eq!(r.rate_command_rad_s, RATE_DEG_S * DEG);
    assert_eq!(r.status & status::table::SLEWING, status::table::SLEWING);
    rig.faults.clear();
    t.set_rate(RATE_DEG_S * DEG, 10.0 * DEG).await.expect("set_rate");
    let r = rig.poll_until(&mut t, |r| (r.rate_rad_s - RATE_DEG_S * DEG).abs() < 0.01 * DEG).await;
    assert_eq!(r.status, 0);
    assert_eq!(n(&rig.stats.watchdog_trips), 0);
}

#[tokio::test]
async fn actidyn_on_tcp_survives_and_reports_each_fault() {
    faults(Dialect::Actidyn, Port::Tcp).await;
}

#[tokio::test]
async fn actidyn_on_a_pty_survives_and_reports_each_fault() {
    faults(Dialect::Actidyn, Port::Pty).await;
}

#[tokio::test]
async fn acutrol_on_tcp_survives_and_reports_each_fault() {
    faults(Dialect::Acutrol, Port::Tcp).await;
}

#[tokio::test]
async fn connect_to_a_silent_simulated_controller_fails_saying_what_was_tried() {
    let rig = rig(Dialect::Acutrol, Port::Pty, 1.0).await;
    rig.faults.inject(Fault::Silence);
    let e = RateTableDriver::connect_with_clock(rig.config(Dialect::Acutrol), rig.clock.clone())
        .await
        .expect_err("silent");
    assert_eq!(e.kind(), ErrorKind::Timeout);
    let Endpoint::Serial(s) = &rig.endpoint else { unreachable!() };
    let want = format!(
        "connecting to the acutrol table on serial {p} at 115200 baud: sent `:utility:lockout on` on serial {p} at 115200 baud, no reply within 100 ms (4 attempts)",
        p = s.path
    );
    assert_eq!(e.message(), want);
}
