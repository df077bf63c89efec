//! Diagnosis speed: `scenarios/thermal-short.toml` (7.4 h of bench time at 20 Hz: 532 k gyro,
//! table and chamber samples each) simulated once into memory, then timed:
//!
//! - `diagnose`: loading the run's arrays, the diagnosis (table fit, bins, noise model, parameter
//!   refit, location, the search over every effect) and the re-simulation under the updated
//!   model (`diagnose_recording`);
//! - `read_and_diagnose`: what `bench diagnose --no-report` does after opening the file.
//!
//! Run: `cargo bench -p bench --bench diagnose`. Goal: a 5 h 20 Hz recording in ≤ 10 s, so this
//! longer one in ≤ 14.8 s.
#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::{hint::black_box, io::Cursor, path::Path, time::Duration};

use bench::simulate::{capabilities, run_plan, SimOptions};
use bench_analysis::diagnose::DiagnoseOptions;
use bench_recording::Recording;
use bench_report::diagnose::diagnose_recording;
use criterion::{criterion_group, criterion_main, Criterion};

fn recording() -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/thermal-short.toml");
    let plan = bench::scenario::load(&path, &capabilities()).expect("valid scenario");
    let (_, cursor) = run_plan(&plan, Cursor::new(Vec::new()), &SimOptions::default(), None)
        .expect("simulated run");
    cursor.into_inner()
}

fn diagnose(c: &mut Criterion) {
    let bytes = recording();
    let rec = Recording::from_bytes(&bytes).expect("reads");
    let opts = DiagnoseOptions::default();
    let mut g = c.benchmark_group("diagnose_thermal_short_7h");
    g.sample_size(10).measurement_time(Duration::from_secs(30));
    g.bench_function("diagnose", |b| {
        b.iter(|| diagnose_recording(black_box(&rec), None, &opts).expect("diagnoses"))
    });
    g.bench_function("read_and_diagnose", |b| {
        b.iter(|| {
            let rec = Recording::from_bytes(black_box(&bytes)).expect("reads");
            diagnose_recording(&rec, None, &opts).expect("diagnoses")
        })
    });
    g.finish();
}

criterion_group!(benches, diagnose);
criterion_main!(benches);
