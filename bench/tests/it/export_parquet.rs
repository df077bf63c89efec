//! `bench export --format parquet --merged` through the binary, read back by pyarrow from the
//! tests' pinned Python environment and checked against the recording read independently by
//! the Python `mcap` package (bench/tests/check_export.py): a UTC nanosecond `timestamp` column
//! in every table, units in the schema metadata, and the merged table's as-of values and
//! record-window labels.

use std::path::{Path, PathBuf};
use std::process::Command;

/// `BENCH_PYTHON` as scripts/test.sh sets it, else target/pyenv (scripts/pyenv.sh).
fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("BENCH_PYTHON").filter(|p| !p.is_empty()) {
        return PathBuf::from(p);
    }
    let local = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/pyenv/bin/python3");
    assert!(
        local.exists(),
        "this test reads the export with pyarrow: run `bash scripts/test.sh` (it installs the \
         pinned packages into target/pyenv) or set BENCH_PYTHON"
    );
    local
}

#[test]
fn parquet_export_has_timestamps_units_and_an_as_of_merged_table() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rec =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/demo-warm-up-and-step.mcap");
    let out = dir.path().join("ex");
    let run = Command::new(env!("CARGO_BIN_EXE_bench"))
        .arg("export")
        .arg(&rec)
        .args(["--format", "parquet", "--merged", "--out"])
        .arg(&out)
        .output()
        .expect("bench runs");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let listing = String::from_utf8_lossy(&run.stdout);
    assert!(
        listing.lines().any(|l| l.starts_with("(merged)") && l.contains("13373 rows")),
        "{listing}"
    );

    let check = Command::new(python())
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/check_export.py"))
        .arg(&rec)
        .arg(&out)
        .output()
        .expect("python runs");
    assert!(
        check.status.success(),
        "{}{}",
        String::from_utf8_lossy(&check.stdout),
        String::from_utf8_lossy(&check.stderr)
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&check.stdout).expect("the checker's JSON summary");
    eprintln!("{summary}");
    assert_eq!(summary["rows"], 13373);
    assert_eq!(summary["columns"], 19);
    // Some checked samples used a chamber reading older than themselves (0.5 Hz vs 2 Hz).
    assert!(summary["held_readings"].as_u64() > Some(0), "{summary}");
    assert_eq!(summary["windows"], 8);
    assert!(summary["in_record_windows"].as_u64() > Some(1000), "{summary}");
}
