//! Scenario files: TOML text → validated, loop-expanded [`RunPlan`].
//!
//! The format is described in `docs/scenario.md`. Parsing is strict (unknown keys are errors)
//! and every value is checked against the devices' capabilities before anything moves. All
//! errors are collected, each naming `file:line:column` of the offending key or value:
//!
//! ```
//! use bench::scenario::{parse, Capabilities};
//! let caps = Capabilities::from(bench_sim::default_infos()); // ST1300-class simulated bench
//! let text = r#"
//! scenario.name = "spin"
//! site.latitude_deg = 59.94
//! [[step]]
//! spin = "2000 °/s"
//! direction = "cw"
//! "#;
//! let errors = parse(text, "x.toml", &caps).expect_err("too fast");
//! assert_eq!(
//!     errors.to_string(),
//!     "x.toml:5:8: table rate 2000 °/s exceeds the table's maximum 1000 °/s"
//! );
//! ```

mod build;
pub mod quantity;

use bench_recording::toml_doc as doc;
#[cfg(test)]
mod tests;

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use bench_drivers::{ChamberCapabilities, DeviceInfo, GyroCapabilities, TableCapabilities};

use crate::plan::RunPlan;

/// The three devices' descriptions a scenario is validated against.
#[derive(Debug, Clone, PartialEq)]
pub struct Capabilities {
    /// The rate table.
    pub table: DeviceInfo<TableCapabilities>,
    /// The climatic chamber.
    pub chamber: DeviceInfo<ChamberCapabilities>,
    /// The gyro.
    pub gyro: DeviceInfo<GyroCapabilities>,
}

impl From<bench_sim::SimInfos> for Capabilities {
    /// The simulated bench's devices (`bench_sim::default_infos()` or `SimConfig::infos()`).
    fn from(i: bench_sim::SimInfos) -> Self {
        Self { table: i.table, chamber: i.chamber, gyro: i.gyro }
    }
}

/// One problem in a scenario, located in its file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScenarioError {
    /// The scenario's name for messages (usually its path).
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// Byte range of the offending key or value in the text.
    pub span: Range<usize>,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: {}", self.file, self.line, self.column, self.message)
    }
}

impl std::error::Error for ScenarioError {}

/// Every problem found in a scenario, in file order; displayed one per line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub struct ScenarioErrors(pub Vec<ScenarioError>);

impl fmt::Display for ScenarioErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl ScenarioErrors {
    /// The errors, in file order.
    pub fn iter(&self) -> std::slice::Iter<'_, ScenarioError> {
        self.0.iter()
    }

    /// Number of errors.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are none (never the case for a returned error).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// Why a scenario file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("cannot read scenario {}: {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file was read but is not a valid scenario.
    #[error("{0}")]
    Invalid(#[from] ScenarioErrors),
}

/// Read, parse and validate the scenario at `path` against `caps`.
pub fn load(path: &Path, caps: &Capabilities) -> Result<RunPlan, LoadError> {
    let bytes =
        std::fs::read(path).map_err(|source| LoadError::Io { path: path.to_path_buf(), source })?;
    let file = path.display().to_string();
    let text =
        bench_recording::toml_doc::utf8_text(bytes).map_err(|(at, line, column, message)| {
            ScenarioErrors(vec![ScenarioError {
                file: file.clone(),
                line,
                column,
                span: at..at + 1,
                message,
            }])
        })?;
    Ok(parse(&text, &file, caps)?)
}

/// Parse and validate scenario `text` against `caps`; `source_name` (usually the path) prefixes
/// every error message and step origin. Never panics.
pub fn parse(
    text: &str,
    source_name: &str,
    caps: &Capabilities,
) -> Result<RunPlan, ScenarioErrors> {
    let issues = match doc::parse(text) {
        Ok(root) => match build::build(&root, text, source_name, caps) {
            Ok(plan) => return Ok(plan),
            Err(issues) => issues,
        },
        Err(issues) => issues,
    };
    let mut errors: Vec<ScenarioError> = issues
        .into_iter()
        .map(|(span, message)| {
            let (line, column) = doc::line_col(text, span.start);
            ScenarioError { file: source_name.to_string(), line, column, span, message }
        })
        .collect();
    errors.sort_by_key(|e| (e.span.start, e.line));
    if errors.is_empty() {
        // Cannot happen (build only fails with issues), but never return an empty error.
        errors.push(ScenarioError {
            file: source_name.to_string(),
            line: 1,
            column: 1,
            span: 0..0,
            message: "invalid scenario".to_string(),
        });
    }
    Err(ScenarioErrors(errors))
}
