//! What the CLI tests share: run the `bench` binary in a folder and read what it printed.

use std::path::Path;
use std::process::{Command, Output};

/// The binary under test: this build's, or the one `BENCH_EXE` names (e.g. a build of the base
/// commit, to see a new test fail there).
pub fn exe() -> std::ffi::OsString {
    std::env::var_os("BENCH_EXE").unwrap_or_else(|| env!("CARGO_BIN_EXE_bench").into())
}

/// Run `bench ARGS` in `dir` and wait for it. `NO_COLOR` is removed: stdout and stderr are
/// pipes here, and bench must print no escape codes to a pipe by itself.
pub fn bench(args: &[&str], dir: &Path) -> Output {
    Command::new(exe())
        .args(args)
        .current_dir(dir)
        .env_remove("NO_COLOR")
        .output()
        .expect("bench runs")
}

/// Bytes a command printed, as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// stdout then stderr, for assertion messages.
pub fn text_of(r: &Output) -> String {
    format!("{}{}", text(&r.stdout), text(&r.stderr))
}

/// The path of a scenario of the repository's `scenarios/`.
pub fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios").join(name).display().to_string()
}

/// The path of a recording of the repository's `recordings/`.
pub fn recording(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings").join(name)
}

/// A JSON file bench wrote.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("json written")).expect("json")
}
