//! The Modbus chamber driver against the simulated controllers served over Modbus RTU on a pty
//! and Modbus TCP on loopback: ramps for each preset, the driver's own stepping, the register
//! words written byte for byte, every fault and the recovery after it, and connection probes.
//!
//! Time runs at 50× on a [`SystemClock`] shared by the simulated chamber and the driver, so
//! bench minutes pass in wall-clock seconds; waits are on bench-time conditions, never blind.

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::modbus_map::Preset;
use bench_drivers::real::chamber::{MapChoice, ModbusChamber, ModbusChamberConfig, ModelCheck};
use bench_drivers::{Chamber, Clock, ErrorKind, SystemClock};
use bench_recording::status;
use bench_sim::faults::{Fault, FaultSwitch};
use bench_sim::serve::chamber::{
    serve_chamber_rtu, serve_chamber_tcp, ChamberServeOptions, ServedChamber, WriteRecord,
};
use bench_sim::{SimBench, SimConfig};

const SCALE: f64 = 50.0;

#[derive(Clone, Copy, Debug)]
enum Wire {
    Rtu,
    Tcp,
}

struct Rig {
    clock: Arc<dyn Clock>,
    served: ServedChamber,
    faults: FaultSwitch,
    preset: Preset,
}

async fn make_rig(preset: Preset, wire: Wire, tweak: impl FnOnce(&mut ChamberServeOptions)) -> Rig {
    let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(SCALE));
    let mut cfg = SimConfig::default();
    // A quicker air response than the ST1300's 120 s, so the tests wait less for the PV.
    cfg.chamber.air_time_constant_s = 20.0;
    cfg.chamber.sensor_noise_c = 0.0;
    let bench = SimBench::new(cfg, clock.clone()).expect("valid sim config");
    let mut opts = ChamberServeOptions::preset(preset);
    tweak(&mut opts);
    let faults = opts.faults.clone();
    let chamber = Box::new(bench.chamber);
    let served = match wire {
        Wire::Rtu => serve_chamber_rtu(chamber, clock.clone(), opts).expect("pty"),
        Wire::Tcp => serve_chamber_tcp(chamber, clock.clone(), opts).await.expect("bind"),
    };
    Rig { clock, served, faults, preset }
}

impl Rig {
    fn config(&self) -> ModbusChamberConfig {
        let mut c =
            ModbusChamberConfig::new(self.served.endpoint.clone(), MapChoice::Preset(self.preset));
        c.request_timeout_s = Some(0.15);
        c.retries = 1;
        c.retry_backoff_s = Some(0.01);
        c
    }

    async fn driver(&self) -> ModbusChamber {
        ModbusChamber::connect(self.config(), self.clock.clone()).await.expect("connects")
    }

    async fn sleep(&self, bench_s: f64) {
        self.clock.sleep(Duration::from_secs_f64(bench_s)).await;
    }

    fn now_s(&self) -> f64 {
        self.clock.now().as_secs_f64()
    }
}

/// Ramp 20 → 22 °C at 2 °C/min: the working set point must follow the commanded ramp and the
/// air follow it. Each sample is bracketed by the bench times before `service()` and after
/// `read()`, so the bounds hold however late the scheduler runs the loop.
async fn ramp_reaches_target_at_rate(preset: Preset, wire: Wire) {
    let rig = make_rig(preset, wire, |_| {}).await;
    let mut d = rig.driver().await;
    let r0 = d.read().await.expect("read");
    assert!((r0.temperature_c - 20.0).abs() < 0.2, "{r0:?}");
    let rate = 2.0 / 60.0;
    let res = 0.1;
    let ideal = |t: f64| (20.0 + rate * t.max(0.0)).min(22.0);
    // The ramp starts when the controller takes the write: somewhere between the command
    // and its reply, however late a loaded scheduler runs the server.
    let t0 = rig.now_s();
    d.set_target(22.0, Some(rate)).await.expect("set_target");
    let started_by = rig.now_s() - t0;
    let mut reached = None;
    let mut samples = Vec::new();
    while rig.now_s() - t0 < 400.0 {
        let before = rig.now_s() - t0;
        d.service().await.expect("service");
        let r = d.read().await.expect("read");
        let after = rig.now_s() - t0;
        samples.push((before, after, r.setpoint_c, r.temperature_c));
        assert_eq!(r.target_c, 22.0);
        // Upper: the ramp cannot be ahead of the commanded rate from the command on. Lower:
        // from the reply on, a driver-stepped ramp writes once per 1 s period and the
        // controller follows each step within ~1.5 s.
        let (lo, hi) = (ideal(before - started_by - 2.5) - res, ideal(after) + res);
        assert!(
            r.setpoint_c >= lo - 1e-9 && r.setpoint_c <= hi + 1e-9,
            "{preset:?} {wire:?}: working set point {} outside [{lo}, {hi}] at {before}..{after} s",
            r.setpoint_c
        );
        let ramping = r.status & status::chamber::RAMPING != 0;
        if r.setpoint_c < 22.0 - res {
            assert!(ramping, "{preset:?} {wire:?}: not ramping at {r:?}");
        }
        if reached.is_none() && r.setpoint_c >= 22.0 - 1e-9 {
            reached = Some(after);
        }
        if reached.is_some() && (r.temperature_c - 22.0).abs() < 0.15 {
            assert!(!ramping, "{preset:?} {wire:?}: still ramping at {r:?}");
            break;
        }
        rig.sleep(1.0).await;
    }
    let Some(end) = reached else {
        panic!("{preset:?} {wire:?}: set point never reached 22 °C: {samples:?}");
    };
    // 2 °C at 2 °C/min = 60 s; the last 0.1 °C step is written once the ramp passes 21.95.
    assert!(end >= 57.0 - 1e-9, "{preset:?} {wire:?}: reached at {end} s");
    let last = samples.last().copied().unwrap_or_default();
    assert!((last.3 - 22.0).abs() < 0.15, "{preset:?} {wire:?}: PV {last:?} did not follow");
    // The air lags the set point, never leads it by more than the resolution.
    assert!(samples.iter().all(|s| s.3 <= s.2 + res + 1e-9), "{samples:?}");
}

#[tokio::test]
async fn watlow_f4_ramp_over_rtu() {
    ramp_reaches_target_at_rate(Preset::WatlowF4, Wire::Rtu).await;
}
#[tokio::test]
async fn watlow_f4_ramp_over_tcp() {
    ramp_reaches_target_at_rate(Preset::WatlowF4, Wire::Tcp).await;
}
#[tokio::test]
async fn watlow_f4t_ramp_over_rtu() {
    ramp_reaches_target_at_rate(Preset::WatlowF4T, Wire::Rtu).await;
}
#[tokio::test]
async fn watlow_f4t_ramp_over_tcp() {
    ramp_reaches_target_at_rate(Preset::WatlowF4T, Wire::Tcp).await;
}
#[tokio::test]
async fn eurotherm3216_ramp_over_rtu() {
    ramp_reaches_target_at_rate(Preset::Eurotherm3216, Wire::Rtu).await;
}
#[tokio::test]
async fn eurotherm3216_ramp_over_tcp() {
    ramp_reaches_target_at_rate(Preset::Eurotherm3216, Wire::Tcp).await;
}

fn rec(register: u16, words: &[u16], function: u8) -> WriteRecord {
    WriteRecord { register, words: words.to_vec(), function }
}

#[tokio::test]
async fn register_words_written_are_byte_exact() {
    // Watlow F4: int16 with the decimals read from 606 (served as 1): 40.0 °C = 400.
    let rig = make_rig(Preset::WatlowF4, Wire::Rtu, |_| {}).await;
    let mut d = rig.driver().await;
    assert_eq!(d.decimals(), 1);
    d.set_target(40.0, None).await.expect("set");
    d.set_target(-40.0, None).await.expect("set");
    assert_eq!(rig.served.writes(), vec![rec(300, &[400], 6), rec(300, &[0xFE70], 6)]);

    // Watlow F4T: float32 low word first: 25.5 °C = 0x41CC0000 → [0x0000, 0x41CC], function 16.
    let rig = make_rig(Preset::WatlowF4T, Wire::Tcp, |_| {}).await;
    let mut d = rig.driver().await;
    d.set_target(25.5, None).await.expect("set");
    assert_eq!(rig.served.writes(), vec![rec(2782, &[0x0000, 0x41CC], 16)]);

    // Eurotherm 3216: remote SP selected once (276 = 1), then rate limit 35 (2.0 °C/min = 20)
    // before the remote set point 26 (40.0 °C = 400); the EEPROM registers 2, 24, 25 never.
    let rig = make_rig(Preset::Eurotherm3216, Wire::Rtu, |_| {}).await;
    let mut d = rig.driver().await;
    d.set_target(40.0, Some(2.0 / 60.0)).await.expect("set");
    d.set_target(30.0, None).await.expect("set");
    assert_eq!(
        rig.served.writes(),
        vec![
            rec(276, &[1], 6),
            rec(35, &[20], 6),
            rec(26, &[400], 6),
            rec(35, &[0], 6),
            rec(26, &[300], 6)
        ]
    );
}

#[tokio::test]
async fn stepping_writes_once_per_resolution_step_and_period() {
    // The F4 has no rate-limit register: the driver steps the set point in `service`.
    let rig = make_rig(Preset::WatlowF4, Wire::Tcp, |_| {}).await;
    let mut d = rig.driver().await;
    // 0.5 °C/min with 0.1 °C resolution and a 1 s period: a write every 12 s, each 1 count up.
    let t0 = rig.now_s();
    d.set_target(21.0, Some(0.5 / 60.0)).await.expect("set");
    while rig.now_s() - t0 < 150.0 {
        d.service().await.expect("service");
        if d.read().await.expect("read").setpoint_c >= 21.0 {
            break;
        }
        rig.sleep(0.25).await;
    }
    // The set point is rounded to the resolution: 21.0 is written once the ramp passes 20.95.
    let t_end = rig.now_s() - t0;
    assert!((113.0..125.0).contains(&t_end), "reached 21 °C after {t_end} s");
    let words: Vec<u16> = rig
        .served
        .writes()
        .iter()
        .filter(|w| w.register == 300)
        .filter_map(|w| w.words.first().copied())
        .collect();
    assert_eq!(words, (201..=210).collect::<Vec<u16>>(), "one write per 0.1 °C step");
}

#[tokio::test]
async fn faults_map_to_error_kinds_and_clear() {
    for wire in [Wire::Rtu, Wire::Tcp] {
        let rig = make_rig(Preset::Eurotherm3216, wire, |_| {}).await;
        let mut d = rig.driver().await;

        rig.faults.inject(Fault::Silence);
        let e = d.read().await.expect_err("silent");
        assert_eq!(e.kind(), ErrorKind::Timeout, "{wire:?}: {e}");
        assert!(e.message().contains("no reply within 150ms"), "{e}");
        rig.faults.clear();
        d.read().await.expect("recovers after silence");

        rig.faults.inject(Fault::ModbusException { code: 4 });
        let e = d.read().await.expect_err("exception");
        assert_eq!(e.kind(), ErrorKind::DeviceFault, "{wire:?}: {e}");
        assert!(e.message().contains("0x04 (server device failure)"), "{e}");
        rig.faults.inject(Fault::ModbusException { code: 2 });
        assert_eq!(d.read().await.expect_err("exception").kind(), ErrorKind::Unsupported);
        rig.faults.inject(Fault::ModbusException { code: 3 });
        let e = d.set_target(30.0, None).await.expect_err("exception");
        assert_eq!(e.kind(), ErrorKind::OutOfRange, "{e}");
        rig.faults.clear();
        d.read().await.expect("recovers after exceptions");

        rig.faults.inject(Fault::Corrupt { every: 1 });
        let e = d.read().await.expect_err("corrupt");
        assert_eq!(e.kind(), ErrorKind::Protocol, "{wire:?}: {e}");
        rig.faults.clear();
        d.read().await.expect("recovers after corruption");
        // Every other reply corrupted: the retry gets through.
        rig.faults.inject(Fault::Corrupt { every: 2 });
        for _ in 0..4 {
            d.read().await.expect("retried past one corrupt reply");
        }
        rig.faults.clear();
    }
}

#[tokio::test]
async fn tcp_disconnect_is_a_link_error_then_reconnects() {
    let rig = make_rig(Preset::WatlowF4T, Wire::Tcp, |_| {}).await;
    let mut cfg = rig.config();
    cfg.retries = 0;
    let mut d = ModbusChamber::connect(cfg, rig.clock.clone()).await.expect("connects");
    rig.faults.inject(Fault::Disconnect { seconds: 0.0 });
    let e = d.read().await.expect_err("closed");
    assert_eq!(e.kind(), ErrorKind::Link, "{e}");
    d.read().await.expect("reconnects");
    // With retries the caller does not see it.
    let mut d = rig.driver().await;
    rig.faults.inject(Fault::Disconnect { seconds: 0.0 });
    d.read().await.expect("retried on a new connection");
}

#[tokio::test]
async fn rtu_disconnect_goes_silent_for_its_duration() {
    let rig = make_rig(Preset::WatlowF4, Wire::Rtu, |_| {}).await;
    let mut d = rig.driver().await;
    rig.faults.inject(Fault::Disconnect { seconds: 60.0 });
    let t0 = rig.now_s();
    let e = d.read().await.expect_err("dead line");
    assert_eq!(e.kind(), ErrorKind::Timeout, "{e}");
    let left = 60.0 - (rig.now_s() - t0);
    rig.sleep(left + 1.0).await;
    d.read().await.expect("line back");
}

#[tokio::test]
async fn overshoot_fault_peaks_above_the_target_and_decays() {
    let rig = make_rig(Preset::WatlowF4T, Wire::Tcp, |o| o.overshoot_time_constant_s = 20.0).await;
    let mut d = rig.driver().await;
    rig.faults.inject(Fault::ChamberOvershoot { overshoot_c: 3.0 });
    let t0 = rig.now_s();
    d.set_target(20.5, None).await.expect("set");
    let mut peak = f64::MIN;
    let mut last = 0.0;
    while rig.now_s() - t0 < 200.0 {
        last = d.read().await.expect("read").temperature_c;
        peak = peak.max(last);
        rig.sleep(2.0).await;
    }
    // Physics alone settles on 20.5 without overshoot; the fault adds up to 3 °C at 20 s.
    assert!(peak > 20.5 + 2.5 && peak < 20.5 + 3.2, "peak {peak}");
    assert!((last - 20.5).abs() < 0.3, "decayed to {last}");
    rig.faults.clear();
}

#[tokio::test]
async fn connect_fails_clearly_on_wrong_unit_id_silence_or_wrong_model() {
    for wire in [Wire::Rtu, Wire::Tcp] {
        let rig = make_rig(Preset::WatlowF4, wire, |_| {}).await;
        let mut cfg = rig.config();
        cfg.unit_id = 7;
        let e = ModbusChamber::connect(cfg, rig.clock.clone()).await.err().expect("no unit 7");
        assert_eq!(e.kind(), ErrorKind::Timeout, "{e}");
        let m = e.message();
        for want in [
            "no Watlow F4 controller found at unit 7",
            &rig.served.endpoint.to_string(),
            "process value",
            "read holding register 100 ×1",
            "no reply within 150ms (2 attempts)",
        ] {
            assert!(m.contains(want), "{wire:?}: `{m}` lacks `{want}`");
        }

        rig.faults.inject(Fault::Silence);
        let e =
            ModbusChamber::connect(rig.config(), rig.clock.clone()).await.err().expect("silent");
        assert_eq!(e.kind(), ErrorKind::Timeout, "{e}");
        rig.faults.clear();

        let mut cfg = rig.config();
        cfg.model_check = Some(ModelCheck { register: 0, value: 5271 });
        let e = ModbusChamber::connect(cfg, rig.clock.clone()).await.err().expect("wrong model");
        assert_eq!(e.kind(), ErrorKind::Protocol, "{e}");
        assert!(e.message().contains("model register 0 holds [5270], expected 5271"), "{e}");
        let mut cfg = rig.config();
        cfg.model_check = Some(ModelCheck { register: 0, value: 5270 });
        ModbusChamber::connect(cfg, rig.clock.clone()).await.expect("right model");
    }
}
