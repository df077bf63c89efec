//! Analyses of bench recordings and what they report: a recording in, numbers, a model file, JSON
//! and an HTML/PNG report out. Pure functions over a [`bench_recording::Recording`]: no devices,
//! no async runtime.
//!
//! - [`load`]: the one recording → arrays loader (one time zero, one rule for samples left out,
//!   steps paired, site and model read once), shared by both analyses.
//! - [`calibrate`]: the gyro's thermal calibration (`bench calibrate`).
//! - [`diagnose`]: where a recording departs from the simulation of its run, and the physics
//!   left out (`bench diagnose`).
//! - [`acceptance`]: a calibration's coefficients against the recording's acceptance limits.
//! - [`verify`]: a calibration file applied to another run (`bench verify`), judged;
//!   [`verify_html`] its report.
//! - [`display`]: the engineering units shown to people; [`render`]: the figures and the HTML
//!   page both reports share.
//!
//! ```no_run
//! let rec = bench_recording::Recording::load("run.mcap".as_ref())?;
//! let out = bench_report::calibrate::calibrate_recording(&rec, &Default::default())?;
//! if let Some(m) = &out.model {
//!     println!("bias {:e} rad/s", m.bias);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod acceptance;
pub mod calibrate;
pub mod diagnose;
pub mod display;
pub mod load;
pub mod npy;
pub(crate) mod render;
#[cfg(test)]
mod testutil;
pub mod verify;
pub mod verify_html;

pub use render::{ReportError, ReportFiles};
