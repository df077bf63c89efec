//! Modbus round-trip time of the chamber driver against the simulated controller: one
//! `read()` of a Watlow F4 (one read of holding register 100, function 3) over Modbus RTU on a
//! pseudo-terminal (through the fault proxy, so two pty hops each way) and over Modbus TCP on
//! loopback. Client, server and simulated chamber share one current-thread tokio runtime.

#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::sync::Arc;
use std::time::Duration;

use bench_drivers::protocol::modbus_map::Preset;
use bench_drivers::real::chamber::{MapChoice, ModbusChamber, ModbusChamberConfig};
use bench_drivers::{Chamber, Clock, SystemClock};
use bench_sim::serve::chamber::{serve_chamber_rtu, serve_chamber_tcp, ChamberServeOptions};
use bench_sim::{SimBench, SimConfig};
use criterion::{criterion_group, criterion_main, Criterion};

fn rtt(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().expect("runtime");
    let mut group = c.benchmark_group("modbus_rtt");
    group.sample_size(50).measurement_time(Duration::from_secs(4));
    for wire in ["rtu_pty", "tcp_loopback"] {
        let mut driver = rt.block_on(async {
            let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(1.0));
            let bench = SimBench::new(SimConfig::default(), clock.clone()).expect("valid config");
            let opts = ChamberServeOptions::preset(Preset::WatlowF4);
            let chamber = Box::new(bench.chamber);
            let served = if wire == "rtu_pty" {
                serve_chamber_rtu(chamber, clock.clone(), opts).expect("pty")
            } else {
                serve_chamber_tcp(chamber, clock.clone(), opts).await.expect("bind")
            };
            let cfg = ModbusChamberConfig::new(
                served.endpoint.clone(),
                MapChoice::Preset(Preset::WatlowF4),
            );
            let d = ModbusChamber::connect(cfg, clock).await.expect("connects");
            (d, served)
        });
        group.bench_function(wire, |b| {
            b.iter(|| rt.block_on(driver.0.read()).expect("read"));
        });
    }
    group.finish();
}

criterion_group!(benches, rtt);
criterion_main!(benches);
