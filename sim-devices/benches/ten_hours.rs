//! Cost of simulated bench time: one hour of the seed procedure's device traffic (gyro at 20 Hz,
//! table and chamber polled at 20 Hz) in virtual time. The orchestrator's budget is a 10-hour
//! run at ≥ 20 000× real time, i.e. well under a second of simulation for 10 hours.

#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::clock::{run_virtual, VirtualClock};
use bench_drivers::{Chamber, Clock, Gyro, RateTable};
use bench_physics::units::{DEG, DEG_PER_MIN};
use bench_sim::{SimBench, SimConfig};
use criterion::{criterion_group, criterion_main, Criterion};

fn one_hour() -> f64 {
    let clock = VirtualClock::new();
    let bench = SimBench::new(SimConfig::default(), Arc::new(clock.clone())).expect("valid");
    let (mut table, mut chamber, mut gyro) = bench.into_parts();
    let n = 72_000u64;
    run_virtual(&clock, |_| {
        let c1 = clock.clone();
        let c2 = clock.clone();
        async move {
            table.set_rate(10.0 * DEG_PER_MIN, DEG).await.ok();
            chamber.set_target(60.0, Some(1.0 / 60.0)).await.ok();
            let g = async {
                let mut s = 0.0;
                for _ in 0..n {
                    s += gyro.next_sample().await.map(|x| x.rate_rad_s).unwrap_or(0.0);
                }
                s
            };
            let t = async {
                let mut s = 0.0;
                for k in 1..=n {
                    c1.sleep_until(Duration::from_millis(50 * k)).await;
                    s += table.read().await.map(|r| r.angle_rad).unwrap_or(0.0);
                }
                s
            };
            let c = async {
                let mut s = 0.0;
                for k in 1..=n {
                    c2.sleep_until(Duration::from_millis(50 * k)).await;
                    s += chamber.read().await.map(|r| r.temperature_c).unwrap_or(0.0);
                }
                s
            };
            let (a, b, c) = futures::join!(g, t, c);
            a + b + c
        }
    })
    .unwrap_or(f64::NAN)
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("sim");
    g.sample_size(10);
    g.bench_function("one_hour_20hz_all_devices", |b| b.iter(one_hour));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
