//! bench: orchestrator of the FOG thermal-calibration bench.

pub mod plan;
pub mod record;
pub mod recording;
pub mod scenario;
