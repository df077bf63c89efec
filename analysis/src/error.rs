//! Errors of the analysis.

use thiserror::Error;

/// Why an analysis could not be done on the data given.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AnalysisError {
    /// Arrays of one window differ in length.
    #[error("window `{label}`: array `{array}` has {got} samples, expected {expected}")]
    LengthMismatch {
        /// Window label.
        label: String,
        /// Name of the offending array.
        array: &'static str,
        /// Samples in the offending array.
        got: usize,
        /// Samples in the time array.
        expected: usize,
    },
    /// Too few samples for the computation.
    #[error("{what}: {got} samples, at least {min} needed")]
    TooFewSamples {
        /// What was being computed.
        what: String,
        /// Samples available.
        got: usize,
        /// Samples needed.
        min: usize,
    },
    /// A value is NaN or infinite.
    #[error("window `{label}`: array `{array}` has a non-finite value at index {index}")]
    NonFinite {
        /// Window label.
        label: String,
        /// Name of the offending array.
        array: &'static str,
        /// Index of the first non-finite value.
        index: usize,
    },
    /// Time stamps do not increase.
    #[error("window `{label}`: time does not increase at index {index}")]
    TimeNotIncreasing {
        /// Window label.
        label: String,
        /// Index of the first sample not later than its predecessor.
        index: usize,
    },
    /// A parameter is out of its valid range.
    #[error("invalid parameter {name} = {value}: {why}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What is required.
        why: &'static str,
    },
    /// The data cannot determine what was asked for.
    #[error("{0}")]
    Insufficient(String),
}
