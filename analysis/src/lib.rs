//! Calibration analysis of bench recordings: pure functions over arrays, no I/O.
//!
//! - [`run`]: a whole run as arrays ([`run::RunSeries`]), the input of both analyses;
//!   [`interp`]: the one linear interpolator.
//! - [`steady`]: where the table turns steadily, from its own readings — the one rule of which
//!   samples enter a fit, for calibration and diagnosis alike.
//! - [`timebase`]: host stamps mapped onto a device's own clock (its stamps or its counter).
//! - [`nominal`]: the nominal model's stated effects, sample by sample (known physics a
//!   calibration of the base terms takes out first).
//! - [`windows`]: the calibration's input, one record window (a `record …` step of a recording) as
//!   arrays of time, gyro rate, table rate and temperatures.
//! - [`temperature_rate`]: dT/dt from quantised temperature readings (local linear regression).
//! - [`seed_method`]: the seed's plateau method reproduced (`docs/seed-method.md`):
//!   K = (k1 + k2)/2 per plateau, a two-point line for the temperature coefficient and a slope
//!   through the origin for the temperature-rate coefficient.
//! - [`joint_fit`]: one least-squares fit of bias, scale-factor error, temperature and
//!   temperature-rate coefficients over all windows, Earth's rotation removed: generalised
//!   least squares under the Allan noise model, standard errors that respect coloured noise.
//! - [`gls`]: generalised least squares under the gyro noise model (white, flicker as
//!   Gauss–Markov states, rate random walk) by Kalman-filter whitening, O(n).
//! - [`calibrate`]: the whole calibration of a recording's windows: pooled Allan deviation,
//!   thermal-lag profile, seed method and joint fit, and what the data lack.
//! - [`diagnose`]: where a recording departs from the simulation of the same run, which
//!   effects of the library explain it (judged against the Allan noise model), and what is
//!   left unexplained.
//! - [`allan_fit`]: IEEE Std 952 noise terms (N, B, K) with confidence intervals from an
//!   overlapping Allan deviation.
//!
//! Coefficients use the `bench.gyro_model` keys and units of the recording format
//! (`recording/FORMAT.md`).

pub mod allan_fit;
pub mod allan_sub;
pub mod angle_fit;
pub mod calibrate;
pub mod compensation;
pub mod diagnose;
pub mod error;
pub mod fit_check;
pub mod gls;
pub mod information;
pub mod interp;
pub mod joint_fit;
pub mod nominal;
pub mod run;
pub mod seed_method;
pub mod stats;
pub mod steady;
pub mod temperature_rate;
pub mod timebase;
pub mod windows;

pub use error::AnalysisError;
pub use windows::{Direction, RecordWindow};
