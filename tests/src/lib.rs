//! Workspace integration tests live in `tests/tests/`; this library holds what they share.

use std::path::PathBuf;

/// The Python interpreter of the tests' pinned environment (independent peers and fixture
/// writers): `BENCH_PYTHON` as set by `scripts/test.sh`, else `target/pyenv/bin/python3` when
/// `scripts/pyenv.sh` has made it.
///
/// # Panics
/// When neither exists, with what to run: a test that needs an independent writer must not pass
/// without one.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("BENCH_PYTHON") {
        return PathBuf::from(p);
    }
    let local = workspace_root().join("target/pyenv/bin/python3");
    assert!(
        local.exists(),
        "this test runs an independent Python peer or writer: run `bash scripts/test.sh` (it \
         installs the pinned packages into target/pyenv) or set BENCH_PYTHON"
    );
    local
}

/// The workspace's root directory.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("."))
}

pub mod peer;
