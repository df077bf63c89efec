//! Independent protocol peers (`tests/peers/*.py`) as child processes: start one, wait for its
//! ready line, read its JSON-lines command log.
//!
//! A peer prints exactly one line on stdout when it listens — `{"ready": NAME, "tcp": ADDR}` or
//! `{"ready": NAME, "pty": PATH}` — and exits when its stdin closes. Its stderr goes to a file
//! shown in failure messages.

use std::io::{BufRead, BufReader, Write as _};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::Value;

/// How long a peer may take to print its ready line (Python start-up and imports, on a loaded
/// two-core machine).
const READY_TIMEOUT: Duration = Duration::from_secs(30);

/// A running peer; dropping it closes its stdin and kills it if it has not exited.
pub struct Peer {
    child: Child,
    stdin: Option<ChildStdin>,
    /// The ready line.
    pub ready: Value,
    /// Its command log (JSON lines).
    pub log_path: PathBuf,
    stderr_path: PathBuf,
    _dir: tempfile::TempDir,
}

/// `tests/peers/NAME`.
pub fn script(name: &str) -> PathBuf {
    crate::workspace_root().join("tests/peers").join(name)
}

impl Peer {
    /// Start `tests/peers/<script>` with `args` (and `--log`), and wait for its ready line.
    ///
    /// # Panics
    /// When the peer cannot start or exits or stays silent before its ready line; the message
    /// holds its stderr.
    pub fn start(script_name: &str, args: &[&str]) -> Peer {
        let dir = tempfile::tempdir().expect("temporary directory for the peer's log");
        let log_path = dir.path().join("commands.jsonl");
        let stderr_path = dir.path().join("stderr.txt");
        let stderr = std::fs::File::create(&stderr_path).expect("peer stderr file");
        let mut child = Command::new(crate::python())
            .arg(script(script_name))
            .args(args)
            .arg("--log")
            .arg(&log_path)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start the peer {script_name}: {e}"));
        let stdout = child.stdout.take().expect("peer stdout");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let r = BufReader::new(stdout).read_line(&mut line).map(|_| line);
            let _ = tx.send(r);
        });
        let stdin = child.stdin.take();
        let line = rx.recv_timeout(READY_TIMEOUT);
        let ready = match line {
            Ok(Ok(l)) if !l.trim().is_empty() => serde_json::from_str::<Value>(&l)
                .unwrap_or_else(|e| panic!("peer {script_name}: bad ready line {l:?}: {e}")),
            other => {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "peer {script_name} {args:?} did not get ready ({other:?}); stderr:\n{}",
                    std::fs::read_to_string(&stderr_path).unwrap_or_default()
                );
            }
        };
        Peer { child, stdin, ready, log_path, stderr_path, _dir: dir }
    }

    /// The TCP address it announced.
    pub fn tcp(&self) -> String {
        self.ready["tcp"].as_str().expect("a TCP peer").to_owned()
    }

    /// The pseudo-terminal path it announced.
    pub fn pty(&self) -> String {
        self.ready["pty"].as_str().expect("a pty peer").to_owned()
    }

    /// Its command log so far, one JSON value per line.
    pub fn log(&self) -> Vec<Value> {
        read_log(&self.log_path)
    }

    /// Its stderr so far.
    pub fn stderr(&self) -> String {
        std::fs::read_to_string(&self.stderr_path).unwrap_or_default()
    }

    /// Close its stdin, wait for it to exit (at most 10 s) and return the whole log.
    pub fn stop(mut self) -> Vec<Value> {
        self.finish();
        self.log()
    }

    /// Send `text` on its stdin (peers that take commands there).
    pub fn send(&mut self, text: &str) {
        if let Some(s) = self.stdin.as_mut() {
            let _ = s.write_all(text.as_bytes());
            let _ = s.flush();
        }
    }

    fn finish(&mut self) {
        drop(self.stdin.take());
        let end = Instant::now() + Duration::from_secs(10);
        while Instant::now() < end {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            drop(self.stdin.take());
            std::thread::sleep(Duration::from_millis(50));
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// A JSON-lines file (missing file: empty).
pub fn read_log(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("bad log line {l:?}: {e}")))
        .collect()
}
