//! The integration tests of the workspace (simulated bench, virtual ports, independent peers and
//! fixture writers), one module per subject, built as one test binary: each binary links the whole
//! dependency tree, so one instead of many saves minutes of CI.

mod abort_run;
mod calibrate_run;
mod diagnose_run;
mod effects_run;
mod faults_e2e;
mod gyro_e2e;
mod interlocks;
mod lab_calibrate;
mod lab_diagnose;
mod lab_fixture;
mod lab_model_elsewhere;
mod lab_reduction;
mod peers_bench_run;
mod peers_chamber;
mod peers_faults;
mod peers_gyro;
mod peers_table;
mod ports_e2e;
mod python_fixture;
mod realtime_run;
mod replay_roundtrip;
mod replay_serve;
mod seed_run;
mod support;
mod table_e2e;
