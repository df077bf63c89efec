//! `scripts/bad_inputs.py` through the binary: broken scenarios, bench configs and model files
//! and corrupted recordings, every one refused with a located error or read as far as it goes;
//! no panic, no hang, no error without a location. The quick set: recordings through `info`,
//! `model` and `recover` (the script without `--quick` adds `calibrate` and a replay).

use std::path::PathBuf;
use std::process::Command;

/// The pinned Python environment (`scripts/pyenv.sh`): `BENCH_PYTHON` as `scripts/test.sh`
/// sets it, else `target/pyenv/bin/python3`.
fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("BENCH_PYTHON") {
        return PathBuf::from(p);
    }
    let local = root().join("target/pyenv/bin/python3");
    assert!(
        local.exists(),
        "this test runs scripts/bad_inputs.py with the pinned `mcap` package: run `bash \
         scripts/test.sh` (it installs it into target/pyenv) or set BENCH_PYTHON"
    );
    local
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn broken_inputs_give_located_errors_and_never_a_panic_or_a_hang() {
    let out = Command::new(python())
        .arg(root().join("scripts/bad_inputs.py"))
        .args(["--quick", "--timeout", "30", "--bench", env!("CARGO_BIN_EXE_bench")])
        .output()
        .expect("python runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "bad_inputs.py failed:\n{stdout}\n{stderr}");
    assert!(stdout.contains("total"), "{stdout}");
}
