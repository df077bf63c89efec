//! bench: orchestrator of the FOG thermal-calibration bench.
//!
//! Scenario TOML → validated [`plan::RunPlan`] ([`scenario`]) → run on devices behind the
//! `bench-drivers` traits ([`run`]) → MCAP per the recording format (`bench-recording`),
//! analysed by `bench-report`. [`simulate`] is the embedded default bench: the in-process
//! simulators in virtual time.
//!
//! ```no_run
//! use bench::simulate::{run_scenario_file, SimOptions};
//! let report = run_scenario_file(
//!     "scenarios/seed.toml".as_ref(),
//!     "seed.mcap".as_ref(),
//!     &SimOptions { seed: 7, ..Default::default() },
//! )?;
//! println!("{} in {:?} of bench time", report.outcome, report.bench_time);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod bench_config;
pub mod live_view;
pub mod plan;
pub mod progress;
pub mod replay;
pub mod run;
pub mod runner;
pub mod scenario;
pub mod simulate;
pub mod soak;
pub mod study;
pub mod suggest;
