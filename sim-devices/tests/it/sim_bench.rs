//! End-to-end behaviour of the simulated bench in virtual time, against closed forms.

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::clock::{run_virtual, timeout, VirtualClock};
use bench_drivers::{Chamber, Clock, ErrorKind, Gyro, GyroSample, RateTable, TableMode};
use bench_physics::earth::EARTH_RATE_RAD_S;
use bench_physics::noise::bias_instability_stationary_std;
use bench_physics::units::{ARCSEC, DEG, DEG_PER_MIN};
use bench_recording::status;
use bench_sim::{default_infos, SimBench, SimConfig};

fn bench(cfg: SimConfig) -> (VirtualClock, SimBench) {
    let clock = VirtualClock::new();
    let b = SimBench::new(cfg, Arc::new(clock.clone())).expect("valid config");
    (clock, b)
}

#[test]
fn table_reaches_rate_in_v_over_a_and_angle_is_omega_t() {
    let cfg = SimConfig::default();
    let sigma = cfg.table.rate_noise_rad_s;
    let (clock, mut b) = bench(cfg);
    let c = clock.clone();
    run_virtual(&clock, |_| async move {
        let (v, a) = (10.0 * DEG, 2.0 * DEG);
        b.table.set_rate(v, a).await.expect("accepted");
        c.sleep_until(Duration::from_millis(4900)).await;
        let r = b.table.read().await.expect("read");
        assert_eq!(r.status & status::table::SLEWING, status::table::SLEWING);
        assert_eq!(r.mode, TableMode::Rate);
        assert!((r.rate_rad_s - a * 4.9).abs() < 5.0 * sigma + 1e-5 * v);
        c.sleep_until(Duration::from_millis(5100)).await;
        let r = b.table.read().await.expect("read");
        assert_eq!(r.status & status::table::SLEWING, 0);
        assert!((r.rate_rad_s - v).abs() < 5.0 * sigma + 1e-5 * v);
        assert_eq!(r.rate_command_rad_s, v);
        // Angle: v²/2a during the slew, then v·(t − v/a); ripple adds at most 2ε/N = 0.26″.
        let want = v * v / (2.0 * a) + v * (5.1 - v / a);
        assert!((r.angle_rad - want).abs() <= 0.5 * ARCSEC + 2.0 * 1e-5 / 16.0 + 1e-12);
        let q = r.angle_rad / ARCSEC;
        assert!((q - q.round()).abs() < 1e-6, "angle not on the 1″ grid");
    })
    .expect("runs");
}

#[test]
fn angle_after_an_hour_at_the_seed_rate_is_within_one_arcsec() {
    let (clock, mut b) = bench(SimConfig::default());
    let c = clock.clone();
    run_virtual(&clock, |_| async move {
        let (w, a) = (-10.0 * DEG_PER_MIN, 1.0 * DEG);
        b.table.set_rate(w, a).await.expect("accepted");
        c.sleep_until(Duration::from_secs(3600)).await;
        let r = b.table.read().await.expect("read");
        // Slew lag: the acceleration phase loses w²/2a against w·T.
        let want = w * 3600.0 - w * w.abs() / (2.0 * a);
        assert!((r.angle_rad - want).abs() <= ARCSEC, "{} vs {want}", r.angle_rad);
        b.table.stop(a).await.expect("accepted");
        c.sleep_until(Duration::from_secs(3601)).await;
        let r = b.table.read().await.expect("read");
        assert_eq!(r.mode, TableMode::Stopped);
        assert_eq!(r.rate_command_rad_s, 0.0);
        assert!(b
            .table
            .set_rate(2000.0 * DEG, a)
            .await
            .is_err_and(|e| e.kind() == ErrorKind::OutOfRange));
    })
    .expect("runs");
}

#[test]
fn chamber_ramps_at_its_limit_and_reports_ramping() {
    let (clock, mut b) = bench(SimConfig::default());
    let c = clock.clone();
    run_virtual(&clock, |_| async move {
        // 10 °C/min requested, 5 °C/min available.
        b.chamber.set_target(40.0, Some(10.0 / 60.0)).await.expect("accepted");
        c.sleep_until(Duration::from_secs(120)).await;
        let r = b.chamber.read().await.expect("read");
        assert!((r.setpoint_c - 30.0).abs() < 1e-9, "{}", r.setpoint_c);
        assert_eq!(r.target_c, 40.0);
        assert_eq!(r.status & status::chamber::RAMPING, status::chamber::RAMPING);
        // Air through the 120 s lag: 30 − 10·(1 − e^{−1}) = 23.68 °C.
        let air = 30.0 - 10.0 * (1.0 - (-1.0f64).exp());
        assert!((r.temperature_c - air).abs() < 0.05 + 5.0 * 0.01, "{}", r.temperature_c);
        c.sleep_until(Duration::from_secs(241)).await;
        let r = b.chamber.read().await.expect("read");
        assert_eq!(r.setpoint_c, 40.0);
        assert_eq!(r.status & status::chamber::RAMPING, 0);
        for bad in [200.0, -60.0, f64::NAN] {
            let e = b.chamber.set_target(bad, None).await.expect_err("rejected");
            assert_eq!(e.kind(), ErrorKind::OutOfRange);
        }
    })
    .expect("runs");
}

/// Collect `n` gyro samples after commanding the table to `w` and, optionally, reading the
/// table and chamber at odd times in between.
fn run_gyro(cfg: SimConfig, w: f64, n: usize, chatter: bool) -> Vec<GyroSample> {
    let (clock, b) = bench(cfg);
    let (mut table, mut chamber, mut gyro) = b.into_parts();
    let c = clock.clone();
    run_virtual(&clock, |_| async move {
        table.set_rate(w, 1.0 * DEG).await.expect("accepted");
        let samples = async {
            let mut v = Vec::with_capacity(n);
            for _ in 0..n {
                v.push(gyro.next_sample().await.expect("sample"));
            }
            v
        };
        let other = async {
            if chatter {
                for k in 1..(n as u64 / 7) {
                    c.sleep_until(Duration::from_micros(350_017 * k)).await;
                    table.read().await.expect("read");
                    chamber.read().await.expect("read");
                }
            }
        };
        futures::join!(samples, other).0
    })
    .expect("runs")
}

#[test]
fn gyro_mean_over_a_plateau_is_rate_plus_earth_within_noise() {
    let cfg = SimConfig::default();
    let m = cfg.gyro_model.clone();
    let w = 10.0 * DEG_PER_MIN;
    let n = 20 * 1200;
    let s = run_gyro(cfg, w, n, false);
    for (k, x) in s.iter().enumerate().take(50) {
        assert_eq!(x.seq, k as u64);
        assert_eq!(x.device_time, Some(Duration::from_millis(50 * (k as u64 + 1))));
        assert_eq!(x.status, 0);
        assert_eq!(x.temperature_c, Some(20.0));
    }
    // Skip the 2.9 ms slew; chamber at T0 = 20 °C, so only rate + Earth remain.
    let tail = &s[20..];
    let mean = tail.iter().map(|x| x.rate_rad_s).sum::<f64>() / tail.len() as f64;
    let want = w + EARTH_RATE_RAD_S * 59.94f64.to_radians().sin();
    let t = tail.len() as f64 / 20.0;
    let tol = 5.0 * (m.arw / t.sqrt() + bias_instability_stationary_std(m.bias_instability))
        + 2.0 * 1e-5 / 16.0 / t;
    assert!((mean - want).abs() < tol, "mean {mean:e}, want {want:e}, tol {tol:e}");
    // Earth rate is resolvable at this level: leaving it out would fail.
    assert!((mean - w).abs() > tol);
}

#[test]
fn same_seed_same_samples_however_calls_interleave_other_seed_differs() {
    let cfg = SimConfig { seed: 5, ..SimConfig::default() };
    let w = 10.0 * DEG_PER_MIN;
    let a = run_gyro(cfg.clone(), w, 4000, false);
    let b = run_gyro(cfg.clone(), w, 4000, true);
    assert_eq!(a, b);
    let c = run_gyro(SimConfig { seed: 6, ..cfg }, w, 4000, false);
    assert_ne!(a[100].rate_rad_s, c[100].rate_rad_s);
}

#[test]
fn next_sample_is_cancel_safe() {
    let (clock, mut b) = bench(SimConfig::default());
    let c = clock.clone();
    run_virtual(&clock, |_| async move {
        // Give up after 30 ms, before the first sample at 50 ms.
        let r = timeout(&c, Duration::from_millis(30), b.gyro.next_sample()).await;
        assert!(r.is_none());
        let s = b.gyro.next_sample().await.expect("sample");
        assert_eq!((s.seq, s.device_time), (0, Some(Duration::from_millis(50))));
        assert_eq!(c.now(), Duration::from_millis(50));
        // Late callers get the backlog at once, in order.
        c.sleep_until(Duration::from_millis(210)).await;
        for k in 1..=3u64 {
            let s = b.gyro.next_sample().await.expect("sample");
            assert_eq!((s.seq, s.device_time), (k, Some(Duration::from_millis(50 * (k + 1)))));
        }
        assert_eq!(c.now(), Duration::from_millis(210));
        // Change to 100 Hz: the schedule continues from the last sample (200 ms).
        b.gyro.set_sample_rate(100.0).await.expect("listed rate");
        assert!(b.gyro.set_sample_rate(33.0).await.is_err());
        let s = b.gyro.next_sample().await.expect("sample");
        assert_eq!((s.seq, s.device_time), (4, Some(Duration::from_millis(210))));
    })
    .expect("runs");
}

#[test]
fn infos_are_available_without_a_world_and_config_is_validated() {
    let i = default_infos();
    assert!((i.table.capabilities.max_rate_rad_s - 1000.0 * DEG).abs() < 1e-12);
    assert_eq!(i.table.capabilities.position_resolution_rad, ARCSEC);
    assert_eq!(
        (i.chamber.capabilities.min_temp_c, i.chamber.capabilities.max_temp_c),
        (-55.0, 185.0)
    );
    assert_eq!(i.gyro.capabilities.operating_temp_c, (-40.0, 60.0));
    assert!(i.gyro.capabilities.sample_rates_hz.contains(&20.0));
    assert!(i.gyro.capabilities.has_temperature);
    let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let bad = SimConfig { gyro_sample_rate_hz: 33.0, ..SimConfig::default() };
    let e = SimBench::new(bad, clock.clone()).err().expect("rejected");
    assert_eq!(e.field, "gyro_sample_rate_hz");
    let bad = SimConfig { initial_temp_c: 300.0, ..SimConfig::default() };
    assert!(SimBench::new(bad, clock).is_err());
}

#[test]
fn several_outputs_of_one_gyro_read_the_same_samples_at_their_own_pace() {
    // `bench sim serve` serves one simulated coil on SLCAN and KVH outputs at once: clones of
    // the gyro must see one physical stream, whichever reads first or lags.
    let (clock, b) = bench(SimConfig { seed: 9, ..SimConfig::default() });
    let (mut fast, mut slow) = (b.gyro.clone(), b.gyro.clone());
    let c = clock.clone();
    let (a, l) = run_virtual(&clock, |_| async move {
        let mut a = Vec::new();
        for _ in 0..100 {
            a.push(fast.next_sample().await.expect("sample"));
        }
        // The lagging output starts 5 s late and catches up from the remembered samples.
        c.sleep_until(Duration::from_secs(6)).await;
        let mut l = Vec::new();
        for _ in 0..100 {
            l.push(slow.next_sample().await.expect("sample"));
        }
        (a, l)
    })
    .expect("runs");
    assert_eq!(a, l);
    assert!(a.iter().all(|s| s.status == 0 && s.rate_rad_s.is_finite()));
    assert!(a.windows(2).any(|w| w[0].rate_rad_s != w[1].rate_rad_s));
}
