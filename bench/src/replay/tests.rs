//! Replay devices on a small synthetic recording, in virtual time.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::sync::Arc;
use std::time::Duration;

use bench_drivers::clock::{run_virtual, VirtualClock};
use bench_drivers::{Chamber, Clock, Gyro, RateTable, TableMode};
use bench_recording::{ChamberMsg, GyroMsg, Outcome, Recorder, RunInfo, Site, StepEvent, TableMsg};

use super::*;

const EPOCH: u64 = 1_700_000_000_000_000_000;

/// 10 s at 10 Hz: the table spins up to 0.1 rad/s at 2 s, the chamber set point ramps
/// 20 → 30 °C from 5 s. The gyro's device time runs 1 ms behind.
fn recording() -> Recording {
    let info = RunInfo::new(EPOCH, "t", "", Site::at_latitude(12.5), BTreeMap::new());
    let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("start");
    r.step(Duration::ZERO, 0, "wait", StepEvent::Start, "").expect("step");
    for i in 1..=100u64 {
        let t = Duration::from_millis(100 * i);
        let cmd = if i >= 20 { 0.1 } else { 0.0 };
        r.gyro(
            t,
            Some(t - Duration::from_millis(1)),
            &GyroMsg { rate_rad_s: i as f64 * 1e-3, temperature_c: Some(20.0), seq: i, status: 0 },
        )
        .expect("gyro");
        r.table(
            t,
            None,
            &TableMsg { angle_rad: i as f64, rate_rad_s: cmd, rate_command_rad_s: cmd, status: 0 },
        )
        .expect("table");
        let sp = if i >= 50 { 20.0 + (i - 50) as f64 * 0.2 } else { 20.0 };
        r.chamber(t, None, &ChamberMsg { temperature_c: 19.0, setpoint_c: sp, status: 0 })
            .expect("chamber");
    }
    r.step(Duration::from_secs(10), 0, "wait", StepEvent::End, "").expect("step");
    let bytes = r.finish(&Outcome::Completed).expect("finish").into_inner();
    Recording::from_bytes(&bytes).expect("readable")
}

fn data() -> Arc<ReplayData> {
    Arc::new(ReplayData::from_recording(&recording(), "t.mcap").expect("replayable"))
}

#[test]
fn the_recording_is_placed_on_the_bench_time_axis() {
    let d = data();
    assert_eq!(d.epoch_ns, EPOCH);
    assert_eq!(d.gyro.t.first(), Some(&Duration::from_millis(100)));
    assert_eq!(d.gyro.device_time.first(), Some(&Some(Duration::from_millis(99))));
    assert_eq!(d.table.device_time.first(), Some(&None));
    assert_eq!(d.duration(), Duration::from_secs(10));
    assert_eq!(d.gyro_rate_hz(), 10.0);
    assert!(d.gyro_has_temperature());
    assert_eq!(d.site.map(|s| s.latitude_deg), Some(12.5));
    assert_eq!(d.capabilities().gyro.capabilities.sample_rates_hz, vec![10.0]);
}

#[test]
fn without_bench_run_the_epoch_is_the_first_message() {
    let mut rec = recording();
    rec.metadata.retain(|m| m.name != "bench.run");
    let d = ReplayData::from_recording(&rec, "t").expect("replayable");
    // The step start at bench time zero is the earliest message.
    assert_eq!(d.epoch_ns, EPOCH);
    rec.steps.clear();
    let d = ReplayData::from_recording(&rec, "t").expect("replayable");
    assert_eq!(d.epoch_ns, EPOCH + 100_000_000);
}

#[test]
fn a_recording_that_cannot_be_read_is_named_with_where_it_broke() {
    // Found by scripts/bad_inputs.py: `bench validate --bench replay:X` said
    // "/gyro/rate: message encoding `cbor` is not `json`" without naming X.
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.mcap");
    std::fs::write(&path, b"\x89MCAP0\r\n").expect("write");
    let e = ReplayData::load(&path).expect_err("unreadable").to_string();
    assert!(e.starts_with(&format!("cannot read {}: ", path.display())), "{e}");
    assert!(e.contains("byte 8"), "{e}");
}

#[test]
fn a_recording_without_gyro_data_is_refused_by_name() {
    let mut rec = recording();
    rec.gyro.clear();
    let e = ReplayData::from_recording(&rec, "x.mcap").expect_err("empty").to_string();
    assert_eq!(e, "x.mcap: channel /gyro/rate has no message: nothing to replay for the gyro");
}

#[test]
fn devices_play_the_recording_in_virtual_time() {
    let d = data();
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let bench = d.devices(shared.clone(), ReplayOptions::default());
    let checks = bench.checks.clone();
    let (mut table, mut chamber, mut gyro) = (bench.table, bench.chamber, bench.gyro);
    let out = run_virtual(&clock, move |_| async move {
        // Gyro samples come out at their log times.
        let s = gyro.next_sample().await.expect("sample");
        assert_eq!(shared.now(), Duration::from_millis(100));
        assert_eq!((s.seq, s.rate_rad_s), (1, 1e-3));
        assert_eq!(s.device_time, Some(Duration::from_millis(99)));
        // Reads report the last reading at or before now.
        shared.sleep_until(Duration::from_millis(1_950)).await;
        let r = table.read().await.expect("read");
        assert_eq!((r.angle_rad, r.rate_command_rad_s, r.mode), (19.0, 0.0, TableMode::Stopped));
        // A command the recording agrees with (the next reading commands 0.1), then one it
        // does not.
        table.set_rate(0.1, 1.0).await.expect("accepted");
        table.set_rate(-0.1, 1.0).await.expect("accepted");
        let r = table.read().await.expect("read");
        assert_eq!(r.rate_command_rad_s, 0.0, "the recording, not the command");
        shared.sleep_until(Duration::from_millis(2_000)).await;
        assert_eq!(table.read().await.expect("read").rate_command_rad_s, 0.1);
        // The set point ramps toward 30 °C from 5 s: a 30 °C target agrees, 0 °C does not.
        shared.sleep_until(Duration::from_secs(5)).await;
        chamber.set_target(30.0, Some(0.2)).await.expect("accepted");
        let c = chamber.read().await.expect("read");
        assert_eq!((c.setpoint_c, c.target_c), (20.0, 30.0));
        chamber.set_target(0.0, None).await.expect("accepted");
        // Past the end (10 s + two periods) reads fail, not transiently.
        shared.sleep_until(Duration::from_millis(10_150)).await;
        assert_eq!(table.read().await.expect("read").angle_rad, 100.0);
        shared.sleep_until(Duration::from_millis(10_300)).await;
        let e = table.read().await.expect_err("ended");
        assert!(!e.kind().is_transient());
        assert!(e.to_string().contains("ends at 10.000 s"), "{e}");
        // The gyro hands out the rest, then fails 1.5 periods after its last sample.
        let mut n = 1;
        while gyro.next_sample().await.is_ok() {
            n += 1;
        }
        (n, shared.now())
    })
    .expect("no deadlock");
    assert_eq!(out, (100, Duration::from_millis(10_300)));
    assert_eq!(checks.counts(), (2, 1, 2, 1));
}

#[test]
fn held_devices_keep_the_last_reading() {
    let d = data();
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let opts = ReplayOptions { at_end: AtEnd::Hold };
    let mut bench = d.devices(shared.clone(), opts);
    let r = run_virtual(&clock, move |_| async move {
        shared.sleep_until(Duration::from_secs(3_600)).await;
        bench.chamber.read().await.map(|c| c.setpoint_c)
    })
    .expect("runs");
    assert_eq!(r.ok(), Some(30.0));
}

#[test]
fn a_sample_rate_other_than_the_recorded_one_is_refused() {
    let d = data();
    let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let mut g = d.devices(clock, ReplayOptions::default()).gyro;
    assert!(futures::executor::block_on(g.set_sample_rate(10.0)).is_ok());
    let e = futures::executor::block_on(g.set_sample_rate(20.0)).expect_err("refused");
    assert!(e.to_string().contains("ran at 10 Hz, not 20 Hz"), "{e}");
}
