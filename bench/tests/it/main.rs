//! The integration tests of the `bench` binary and library, one module per subject, built as one
//! test binary: each binary links the whole dependency tree, so one instead of many saves minutes
//! of CI.

mod bad_inputs;
mod cli_ux;
mod common;
mod damaged_files;
mod design;
mod diagnose_cli;
mod estimate;
mod export_parquet;
mod kill_safety;
mod memory_cli;
mod report_browser;
mod scenario_validation;
mod signals;
mod soak_cli;
mod verify_cli;
