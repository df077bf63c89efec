//! Calibration speed: `scenarios/thermal-short.toml` (7.4 h of bench time at 20 Hz: 532 k gyro,
//! table and chamber samples each) simulated once into memory, then timed:
//!
//! - `read`: the MCAP read (`Recording::from_bytes`);
//! - `calibrate`: windows, Allan deviation, seed method and joint fit with 400 bootstrap
//!   replicates (`calibrate_recording`);
//! - `read_and_calibrate`: what `bench calibrate --no-report` does after opening the file;
//! - `lab_like/calibrate`: the same run with a lab's traits (`bench::study::lab`: 10 Hz table
//!   with 1″ angle, 1 Hz chamber, jittered host stamps, device stamps, lost and flagged frames,
//!   record steps from the reversal). Goal: ≤ 5 s for 5 h, so ≤ 7.4 s here.
//!
//! Run: `cargo bench -p bench --bench calibrate`. Goal: a 5 h 20 Hz recording in ≤ 5 s, so this
//! longer one in ≤ 7.4 s.
#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::{hint::black_box, path::Path, time::Duration};

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_recording::Recording;
use bench_report::calibrate::{calibrate_recording, CalibrateSettings};
use criterion::{criterion_group, criterion_main, Criterion};

fn recording() -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/thermal-short.toml");
    let plan = bench::scenario::load(&path, &capabilities()).expect("valid scenario");
    simulate_in_memory(&plan, 1).expect("simulated run").1
}

fn calibrate(c: &mut Criterion) {
    let bytes = recording();
    let rec = Recording::from_bytes(&bytes).expect("reads");
    let settings = CalibrateSettings::default();
    let mut g = c.benchmark_group("calibrate_thermal_short_7h");
    g.sample_size(10).measurement_time(Duration::from_secs(30));
    g.bench_function("read", |b| b.iter(|| Recording::from_bytes(black_box(&bytes))));
    g.bench_function("calibrate", |b| {
        b.iter(|| calibrate_recording(black_box(&rec), &settings).expect("calibrates"))
    });
    g.bench_function("read_and_calibrate", |b| {
        b.iter(|| {
            let rec = Recording::from_bytes(black_box(&bytes)).expect("reads");
            calibrate_recording(&rec, &settings).expect("calibrates")
        })
    });
    g.finish();

    let lab = bench::study::lab::apply(&rec, &bench::study::lab::LabTraits::lab(), 1)
        .expect("lab traits applied");
    let mut g = c.benchmark_group("lab_like_thermal_short_7h");
    g.sample_size(10).measurement_time(Duration::from_secs(30));
    g.bench_function("calibrate", |b| {
        b.iter(|| calibrate_recording(black_box(&lab), &settings).expect("calibrates"))
    });
    g.finish();
}

criterion_group!(benches, calibrate);
criterion_main!(benches);
