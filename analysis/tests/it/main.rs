//! The integration tests of the analysis crate, one module per subject, built as one test binary:
//! each binary links the whole dependency tree, so one instead of many saves minutes of CI.

mod diagnose_truth;
mod physics_truth;
