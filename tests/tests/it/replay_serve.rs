//! A replayed gyro served over SLCAN on a pseudo-terminal (what `bench replay --serve` does),
//! read back by the real `CanGyro` driver: the samples equal the recorded ones within the CAN
//! codec's quantisation (delta angle LSB 2^-40 rad per period, temperature 0.01 °C).

use std::collections::BTreeMap;
use std::io::Cursor;
use std::sync::Arc;
use std::time::Duration;

use bench::replay::{AtEnd, ReplayData, ReplayOptions};
use bench_drivers::protocol::gyro_can::ANGLE_LSB_RAD;
use bench_drivers::real::gyro_can::{CanGyro, CanGyroConfig};
use bench_drivers::{Clock, Gyro, SystemClock};
use bench_recording::{ChamberMsg, GyroMsg, Outcome, Recorder, Recording, RunInfo, Site, TableMsg};
use bench_sim::faults::FaultSwitch;
use bench_sim::ports::Pty;
use bench_sim::serve::gyro::{serve_slcan, SlcanAdapterOptions};

/// 60 s of a 20 Hz gyro: a slowly varying rate with a temperature ramp.
fn recording() -> Recording {
    let info = RunInfo::new(1_000_000_000, "t", "", Site::at_latitude(45.0), BTreeMap::new());
    let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("start");
    for i in 0..1_200u64 {
        let t = Duration::from_millis(50 * i);
        let s = GyroMsg {
            rate_rad_s: 1e-3 * (i as f64 * 0.05).sin() + 5.2e-5,
            temperature_c: Some(20.0 + i as f64 * 0.013),
            seq: i,
            status: 0,
        };
        r.gyro(t, None, &s).expect("gyro");
    }
    // Table and chamber streams are required for a replay.
    let tr = TableMsg { angle_rad: 0.0, rate_rad_s: 0.0, rate_command_rad_s: 0.0, status: 0 };
    r.table(Duration::ZERO, None, &tr).expect("table");
    let cr = ChamberMsg { temperature_c: 20.0, setpoint_c: 20.0, status: 0 };
    r.chamber(Duration::ZERO, None, &cr).expect("chamber");
    let bytes = r.finish(&Outcome::Completed).expect("finish").into_inner();
    Recording::from_bytes(&bytes).expect("readable")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replayed_gyro_over_slcan_reads_back_as_recorded() {
    let rec = recording();
    let data = Arc::new(ReplayData::from_recording(&rec, "gyro.mcap").expect("replayable"));
    // 20× real time: 60 recorded samples per wall second.
    let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(20.0));
    let gyro = data.devices(clock.clone(), ReplayOptions { at_end: AtEnd::Hold }).gyro;
    let pty = Pty::new().expect("pty");
    let server = tokio::spawn(serve_slcan(
        gyro,
        pty.server,
        SlcanAdapterOptions::default(),
        FaultSwitch::new(),
        clock.clone(),
    ));
    let mut config = CanGyroConfig::slcan(&pty.path);
    config.sample_rate_hz = 20.0;
    config.watchdog_periods = 40.0;
    let mut driver = CanGyro::open(&config, clock.clone()).await.expect("open");
    let mut got = Vec::new();
    for _ in 0..100 {
        got.push(driver.next_sample().await.expect("sample"));
    }
    // The driver starts wherever the replay was when it opened, then follows without a gap.
    for w in got.windows(2) {
        assert_eq!(w[1].seq, w[0].seq + 1);
    }
    let tol = 0.5 * ANGLE_LSB_RAD * 20.0 + 1e-15;
    for s in &got {
        let r = &rec.gyro[s.seq as usize].msg;
        assert_eq!(r.seq, s.seq);
        assert!((s.rate_rad_s - r.rate_rad_s).abs() <= tol, "seq {}: {s:?} vs {r:?}", s.seq);
        let (t, rt) = (s.temperature_c.expect("temp"), r.temperature_c.expect("temp"));
        assert!((t - rt).abs() <= 0.005 + 1e-9, "temperature {t} vs {rt}");
        assert_eq!(s.status, 0);
    }
    assert_eq!(driver.sample_rate_hz(), 20.0);
    server.abort();
}

/// `bench replay --serve` without `--start-now`: the whole bench served from a replay on a held
/// clock. Nothing plays while nobody asks; a bench connecting seconds later (through the bench
/// config the command writes) starts the replay with its first request and reads the gyro from
/// the first samples. On a free-running clock it would have started 6 s of bench time late.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_served_replay_waits_for_its_first_client() {
    use bench::bench_config::for_served_bench;
    use bench_drivers::HeldClock;

    const SPEED: f64 = 2.0;
    let rec = recording();
    let data = Arc::new(ReplayData::from_recording(&rec, "gyro.mcap").expect("replayable"));
    let held = HeldClock::new(SPEED);
    let served = data.serve(&held).await.expect("served");

    tokio::time::sleep(Duration::from_secs(3)).await;
    assert!(!held.is_started(), "nobody asked yet");
    assert_eq!(held.now(), Duration::ZERO);

    let config = for_served_bench(&served.endpoints, SPEED, 45.0, true);
    let own_clock = Arc::new(SystemClock::new(SPEED));
    let (mut devices, _) = config.connect(own_clock).await.expect("devices answer");
    assert!(held.is_started(), "connecting asks the table");
    // Connecting takes well under 1.5 s of wall time (3 s of bench time); the free-running
    // clock would be past 6 s.
    let connected = held.now();
    assert!(connected < Duration::from_secs(3), "replay at {connected:?} when connected");
    let first = devices.gyro.next_sample().await.expect("sample");
    assert!(first.seq < 60, "first sample {} of the replay", first.seq);
    let r = &rec.gyro[first.seq as usize].msg;
    assert!((first.rate_rad_s - r.rate_rad_s).abs() <= 0.5 * ANGLE_LSB_RAD * 20.0 + 1e-15);
}
