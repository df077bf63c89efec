//! bench: orchestrator of the FOG thermal-calibration bench.
//!
//! Scenario TOML → validated [`plan::RunPlan`] ([`scenario`]) → run on devices behind the
//! `bench-drivers` traits ([`run`]) → MCAP per the recording format (`bench-recording`),
//! analysed by `bench-report`. [`runner::run`] is the one way to run: on the embedded
//! simulated bench ([`simulate`]: the in-process simulators), a replay, or connected devices,
//! in virtual or real time.
//!
//! ```no_run
//! use bench::runner::{run, Bench, RunOptions};
//! use bench::simulate::{capabilities, sim_config};
//! let plan = bench::scenario::load("scenarios/seed.toml".as_ref(), &capabilities())?;
//! let file = std::io::BufWriter::new(std::fs::File::create("seed.mcap")?);
//! let bench = Bench::Simulated(sim_config(&plan, 7));
//! let (report, _file) = run(&plan, bench, file, RunOptions::default())?;
//! println!("{} in {:?} of bench time", report.outcome, report.bench_time);
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod bench_config;
pub mod design;
pub mod live_view;
pub mod plan;
pub mod process;
pub mod progress;
pub mod replay;
pub mod run;
pub mod runner;
pub mod scenario;
pub mod simulate;
pub mod soak;
pub mod study;
pub mod suggest;
