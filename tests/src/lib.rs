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

/// Among `readings` taken after `after_ns` (by `time`, ns), the first that is `flagged` and
/// the one before it (itself when it is the first): where a stream shows a fault begin, e.g.
/// the first table reading with the drive off and the last one before it. `None` when none is
/// flagged.
pub fn first_flagged<T>(
    readings: &[T],
    after_ns: u64,
    time: impl Fn(&T) -> u64,
    flagged: impl Fn(&T) -> bool,
) -> Option<(&T, &T)> {
    let after: Vec<&T> = readings.iter().filter(|r| time(r) > after_ns).collect();
    let i = after.iter().position(|r| flagged(r))?;
    Some((after[i.saturating_sub(1)], after[i]))
}

/// A recording written by the independent lab writer (`tests/fixtures/lab/labwriter.py`, see
/// `tests/fixtures/lab/README.md`): `preset` (e.g. `short-lab-null`), `seed`, and `--set`
/// overrides `("traits.lost_frames.rate", "1e-3")` (values are JSON, else strings). Its truth is
/// beside it ([`lab_truth`]).
///
/// Files are cached under `target/lab-fixtures/`, keyed by a hash of the writer, its presets,
/// the preset, the seed and the overrides: tests that ask for the same file share it, and one
/// writes it while the others wait (a lock file beside it). The writer runs in a private
/// temporary directory and its files are renamed into place (truth first, the `.mcap` last).
///
/// # Panics
/// When the writer fails (with its output), or the pinned Python is missing ([`python`]).
pub fn lab_fixture(preset: &str, seed: u64, overrides: &[(&str, &str)]) -> PathBuf {
    let root = workspace_root();
    let lab = root.join("tests/fixtures/lab");
    let writer = lab.join("labwriter.py");
    let mut key = Fnv1a::new();
    key.write(&read_or_panic(&writer));
    let mut presets: Vec<PathBuf> = std::fs::read_dir(lab.join("presets"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    presets.sort();
    for p in &presets {
        key.write(p.file_name().map(|n| n.as_encoded_bytes()).unwrap_or_default());
        key.write(&read_or_panic(p));
    }
    key.write(preset.as_bytes());
    key.write(&seed.to_le_bytes());
    for (k, v) in overrides {
        key.write(k.as_bytes());
        key.write(b"=");
        key.write(v.as_bytes());
        key.write(b"\0");
    }
    let cache = root.join("target/lab-fixtures");
    let stem = format!("{preset}-s{seed}-{:016x}", key.0);
    let out = cache.join(format!("{stem}.mcap"));
    if out.exists() {
        return out;
    }
    // One writer per file: a test asking for a file another test is writing waits for it
    // (nextest runs tests as processes; the lock goes with the process that holds it).
    std::fs::create_dir_all(&cache)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", cache.display()));
    let lock_path = cache.join(format!(".{stem}.lock"));
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .unwrap_or_else(|e| panic!("cannot open {}: {e}", lock_path.display()));
    lock.lock().unwrap_or_else(|e| panic!("cannot lock {}: {e}", lock_path.display()));
    if out.exists() {
        return out;
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let tmp = cache.join(format!(".tmp-{stem}-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&tmp)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", tmp.display()));
    let mut cmd = std::process::Command::new(python());
    cmd.arg(&writer).arg(tmp.join(format!("{stem}.mcap"))).args([
        "--preset",
        preset,
        "--seed",
        &seed.to_string(),
        "-q",
    ]);
    for (k, v) in overrides {
        cmd.arg("--set").arg(format!("{k}={v}"));
    }
    let run = cmd.output().unwrap_or_else(|e| panic!("cannot run {}: {e}", writer.display()));
    assert!(
        run.status.success(),
        "labwriter.py --preset {preset} --seed {seed} {overrides:?} failed:\n{}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    for ext in ["truth.json", "debug.npz", "mcap"] {
        let from = tmp.join(format!("{stem}.{ext}"));
        if from.exists() {
            let to = cache.join(format!("{stem}.{ext}"));
            std::fs::rename(&from, &to)
                .unwrap_or_else(|e| panic!("cannot move {} into place: {e}", to.display()));
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
    out
}

/// The truth file (`OUT.truth.json`) of a lab fixture `OUT.mcap`.
pub fn lab_truth(mcap: &std::path::Path) -> PathBuf {
    let stem = mcap.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    mcap.with_file_name(format!("{stem}.truth.json"))
}

fn read_or_panic(path: &std::path::Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

/// FNV-1a, 64 bits: a cache key stable across Rust versions (std's hasher is not promised to be).
struct Fnv1a(u64);

impl Fnv1a {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        // Length-delimit each part so ("ab", "c") and ("a", "bc") differ.
        for b in (bytes.len() as u64).to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}
