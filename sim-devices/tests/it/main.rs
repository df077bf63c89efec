//! The integration tests of the simulators, one module per subject, built as one test binary: each
//! binary links the whole dependency tree, so one instead of many saves minutes of CI.

mod chamber_modbus;
mod sim_bench;
