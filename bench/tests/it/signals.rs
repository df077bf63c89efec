//! Signals through the binary: `bench run` on the simulated bench in real time; SIGTERM aborts
//! like a first Ctrl-C, to the safe state, with a readable recording that ends with an `abort`
//! step event and names the cause; a second Ctrl-C stops at once (no recording tail).

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use bench_recording::Recording;

const SCENARIO: &str = "[scenario]\nname = \"signals\"\n[site]\nlatitude_deg = 45\n\
                        [[step]]\nspin = \"10 °/min\"\ndirection = \"cw\"\n\
                        [[step]]\nlabel = \"record cw\"\nrecord = \"10 h\"\n";

/// Start `bench run` at `scale`× real time; the receiver gets each time mark (bench seconds)
/// and the thread returns every other stderr line.
fn start(dir: &Path, scale: &str) -> (Child, mpsc::Receiver<f64>, std::thread::JoinHandle<String>) {
    std::fs::write(dir.join("signals.toml"), SCENARIO).expect("scenario");
    let mut child = Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(["run", "signals.toml", "-q", "-o", "out.mcap", "--time-marks-s", "1"])
        .args(["--time-scale", scale])
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bench runs");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut other = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            match line.strip_prefix("bench time ").and_then(|r| r.split(' ').next()) {
                Some(t) => {
                    let _ = tx.send(t.parse::<f64>().unwrap_or(0.0));
                }
                None => {
                    other.push_str(&line);
                    other.push('\n');
                }
            }
        }
        other
    });
    (child, rx, reader)
}

/// Wait for a time mark at or past `t_s` of bench time.
fn wait_for(rx: &mpsc::Receiver<f64>, t_s: f64) {
    loop {
        let t = rx.recv_timeout(Duration::from_secs(60)).expect("the run goes on");
        if t >= t_s {
            return;
        }
    }
}

fn signal(child: &Child, name: &str) {
    let ok = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(ok.success());
}

/// The exit code, waiting at most a minute (a hang fails the test instead of blocking it).
fn exit_code(child: &mut Child) -> Option<i32> {
    for _ in 0..600 {
        if let Some(s) = child.try_wait().expect("wait") {
            return s.code();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let _ = child.kill();
    panic!("bench run did not end within a minute of the signal");
}

#[test]
fn sigterm_aborts_to_the_safe_state_like_a_first_ctrl_c() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut child, rx, reader) = start(dir.path(), "20");
    wait_for(&rx, 60.0);
    signal(&child, "TERM");
    assert_eq!(exit_code(&mut child), Some(4), "{}", reader.join().expect("stderr"));
    let stderr = reader.join().expect("stderr");
    assert!(!stderr.contains("second interrupt"), "{stderr}");

    let rec = Recording::load(&dir.path().join("out.mcap")).expect("a complete recording");
    assert!(rec.complete);
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 1 (record cw)"), "{outcome}");
    assert!(outcome.ends_with("interrupted by the operator (SIGTERM)"), "{outcome}");
    let last = rec.steps.last().expect("steps");
    assert_eq!((last.msg.label.as_str(), last.msg.event.as_str()), ("record cw", "abort"));
    // Safe state: the table was commanded to rest, and the recording went on for its 1 s tail.
    // At 20× real time a stall of the gyro's poller on a loaded host costs 20× its length in
    // bench time at the tail's end (CI, 2026-11-30: 0.88 s, the last sample 0.12 s short):
    // half the tail shows it was recorded, a missing tail is ~0.
    assert_eq!(rec.table.last().map(|t| t.msg.rate_command_rad_s), Some(0.0));
    let tail_ns = rec.gyro.last().map_or(0, |g| g.log_time_ns) - last.log_time_ns;
    assert!(tail_ns >= 500_000_000, "tail of {tail_ns} ns after the abort");
}

#[test]
fn a_second_ctrl_c_stops_at_once_with_the_safe_state_commands_sent() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Real time: the second interrupt, 0.2 s after the first, lands in the 1 s tail (or
    // before it) and cuts it.
    let (mut child, rx, reader) = start(dir.path(), "1");
    wait_for(&rx, 2.0);
    signal(&child, "INT");
    std::thread::sleep(Duration::from_millis(200));
    signal(&child, "INT");
    assert_eq!(exit_code(&mut child), Some(4));
    let stderr = reader.join().expect("stderr");
    assert!(stderr.contains("second interrupt: stopping now"), "{stderr}");

    let rec = Recording::load(&dir.path().join("out.mcap")).expect("a complete recording");
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.ends_with("interrupted by the operator (Ctrl-C)"), "{outcome}");
    let abort = rec.steps.last().expect("steps");
    assert_eq!(abort.msg.event.as_str(), "abort");
    // The safe-state command was sent: the table's last command is rest.
    assert_eq!(rec.table.last().map(|t| t.msg.rate_command_rad_s), Some(0.0));
    // No 1 s tail: the streams end well before it would have.
    let end = rec.gyro.last().map_or(0, |g| g.log_time_ns).max(abort.log_time_ns);
    assert!(
        end - abort.log_time_ns < 900_000_000,
        "{} ns after the abort",
        end - abort.log_time_ns
    );
}

#[test]
fn bad_time_scales_and_flush_intervals_are_refused_before_anything_runs() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("signals.toml"), SCENARIO).expect("scenario");
    for (args, says) in [
        (&["--flush-interval-s", "0"][..], "--flush-interval-s must be a number of seconds"),
        (&["--time-marks-s", "nan"][..], "--time-marks-s must be a number of seconds"),
        (&["--time-scale", "0"][..], "--time-scale must be a positive number, got 0"),
    ] {
        let r = Command::new(env!("CARGO_BIN_EXE_bench"))
            .args(["run", "signals.toml", "-q", "-o", "out.mcap"])
            .args(args)
            .current_dir(dir.path())
            .output()
            .expect("bench runs");
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!dir.path().join("out.mcap").exists(), "{args:?}: nothing recorded");
    }
}
