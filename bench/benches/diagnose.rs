//! Diagnosis speed (issue 14: a 5 h 20 Hz recording diagnosed in ≤ 5 s).
//!
//! - `diagnose_lab_null_5h`: the independent lab writer's 5 h 20 Hz null recording
//!   (`tests/fixtures/lab/labwriter.py --preset lab-null --seed 1`: 366 k gyro samples at
//!   20 Hz, 10 Hz table, 1 Hz chamber, every lab trait; generated once by the pinned Python,
//!   cached in `target/lab-fixtures/`, so the same bytes every run), read from its bytes and
//!   diagnosed as `bench diagnose --no-report` does: `read_and_diagnose` (reading the MCAP,
//!   loading the arrays, the diagnosis with the re-simulation), `diagnose` (without reading),
//!   and `residual_scan` (the scan alone: every candidate's regressors over its grid tested
//!   against the refitted nominal design, the part `scripts/diagnose_numpy.py` does in NumPy,
//!   with `--recurrence` by the same rotation of the sinusoids as Rust);
//! - `diagnose_lab_warmup_step_5h`: the writer's `effect-warmup-step`, seed 1 (a warm-up and
//!   a bias step three time constants in: the candidates fitted again from each of the
//!   warm-up's grid values), `read_and_diagnose`;
//! - `diagnose_thermal_short_7h`: `scenarios/thermal-short.toml` (7.4 h of bench time at
//!   20 Hz, 532 k gyro samples) simulated once into memory, then `diagnose` and
//!   `read_and_diagnose` as above.
//!
//! Run: `cargo bench -p bench --bench diagnose` (needs the pinned Python for the lab file:
//! `BENCH_PYTHON` or `target/pyenv`, see `bench_tests::python`). `BENCH_DIAGNOSE_THREADS=1`
//! measures the serial time.
#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::{hint::black_box, path::Path, time::Duration};

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_analysis::diagnose::{residual_scan, DiagnoseOptions};
use bench_recording::Recording;
use bench_report::diagnose::diagnose_recording;
use criterion::{criterion_group, criterion_main, Criterion};

/// The default options, with `BENCH_DIAGNOSE_THREADS` threads when it is set (as the CLI).
fn options() -> DiagnoseOptions {
    let threads = std::env::var("BENCH_DIAGNOSE_THREADS").ok().and_then(|v| v.parse().ok());
    let default = DiagnoseOptions::default();
    DiagnoseOptions { threads: threads.filter(|&t| t >= 1).unwrap_or(default.threads), ..default }
}

fn simulated() -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/thermal-short.toml");
    let plan = bench::scenario::load(&path, &capabilities()).expect("valid scenario");
    simulate_in_memory(&plan, 1).expect("simulated run").1
}

fn lab_null_5h(c: &mut Criterion) {
    let path = bench_tests::lab_fixture("lab-null", 1, &[]);
    let bytes = std::fs::read(&path).expect("the lab writer's file");
    let rec = Recording::from_bytes(&bytes).expect("reads");
    let opts = options();
    let mut g = c.benchmark_group("diagnose_lab_null_5h");
    g.sample_size(10).measurement_time(Duration::from_secs(40));
    g.bench_function("read_and_diagnose", |b| {
        b.iter(|| {
            let rec = Recording::from_bytes(black_box(&bytes)).expect("reads");
            diagnose_recording(&rec, None, &opts).expect("diagnoses")
        })
    });
    g.bench_function("diagnose", |b| {
        b.iter(|| diagnose_recording(black_box(&rec), None, &opts).expect("diagnoses"))
    });
    let data = bench_report::load::load(&rec).expect("loads");
    let nominal = data.model.clone().expect("the recording's model");
    g.bench_function("residual_scan", |b| {
        b.iter(|| {
            residual_scan(black_box(&data.series), &nominal.model, &nominal.effects, &opts)
                .expect("scans")
        })
    });
    g.finish();
}

fn thermal_short_7h(c: &mut Criterion) {
    let bytes = simulated();
    let rec = Recording::from_bytes(&bytes).expect("reads");
    let opts = options();
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

/// A 5 h file where the search works hardest: a warm-up and a bias step that bends its time
/// constant, so every candidate is fitted again from each of the warm-up's grid values.
fn lab_warmup_step_5h(c: &mut Criterion) {
    let path = bench_tests::lab_fixture("effect-warmup-step", 1, &[]);
    let bytes = std::fs::read(&path).expect("the lab writer's file");
    let opts = options();
    let mut g = c.benchmark_group("diagnose_lab_warmup_step_5h");
    g.sample_size(10).measurement_time(Duration::from_secs(100));
    g.bench_function("read_and_diagnose", |b| {
        b.iter(|| {
            let rec = Recording::from_bytes(black_box(&bytes)).expect("reads");
            diagnose_recording(&rec, None, &opts).expect("diagnoses")
        })
    });
    g.finish();
}

criterion_group!(benches, lab_null_5h, thermal_short_7h, lab_warmup_step_5h);
criterion_main!(benches);
