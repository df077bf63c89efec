//! Kill-safety through the binary: `bench run` children on the simulated bench, in real time
//! (`--time-scale 1`) and in virtual time, are SIGKILLed at random moments; `bench recover`
//! restores each file. In real time the bench time lost — from the last time mark the child
//! printed (it had produced nothing at or after that mark plus the mark period) to the last
//! message recovered — stays within the flush interval (1 s by default). In virtual time (a
//! deterministic function of scenario and seed, re-run in seconds) the bound is on wall-clock
//! work: from the moment the child printed the last mark it had recovered data for to the
//! kill. Prints one line per kill.

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use bench_recording::Recording;

/// Long enough that no child finishes before its kill.
const SCENARIO: &str = "[scenario]\nname = \"kill\"\n[site]\nlatitude_deg = 45\n\
                        [[step]]\nspin = \"10 °/min\"\ndirection = \"cw\"\n\
                        [[step]]\nchamber = \"40 °C\"\nramp = \"1 °C/min\"\n\
                        [[step]]\nlabel = \"record cw ramp\"\nrecord = \"ramp end\"\n\
                        [[step]]\nlabel = \"record cw 40C\"\nrecord = \"100 h\"\n";

/// The default flush interval of `bench run`, s.
const FLUSH_S: f64 = 1.0;

/// splitmix64: a seeded stream of uniform numbers in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

struct Kill {
    mode: &'static str,
    after_s: f64,
    produced_s: f64,
    recovered_s: f64,
    /// Wall-clock time from the arrival of the last mark at or before the last message
    /// recovered to the kill, s: an upper bound of the work lost (plus one mark period).
    lost_wall_s: f64,
}

impl Kill {
    /// Bench time lost, s: an upper bound (the child produced nothing at or after
    /// `produced_s`).
    fn lost_s(&self) -> f64 {
        self.produced_s - self.recovered_s
    }
}

/// `bench time T s (log time N ns)` → N.
fn mark_ns(line: &str) -> Option<u64> {
    let rest = line.strip_prefix("bench time ")?;
    let i = rest.find("(log time ")?;
    rest[i + 10..].strip_suffix(" ns)")?.parse().ok()
}

fn kill_once(dir: &Path, k: usize, mode: &'static str, after: Duration, mark_s: f64) -> Kill {
    let out = dir.join(format!("k{k}.mcap"));
    let mut args = vec![
        "run".to_string(),
        "kill.toml".into(),
        "-q".into(),
        "-o".into(),
        out.display().to_string(),
        "--time-marks-s".into(),
        mark_s.to_string(),
    ];
    if mode == "real time" {
        args.extend(["--time-scale".into(), "1".into()]);
    }
    let mut child = Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(&args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bench runs");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut marks: Vec<(Instant, u64)> = Vec::new();
        let mut other = Vec::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            match mark_ns(&line) {
                Some(ns) => {
                    if marks.is_empty() {
                        let _ = tx.send(());
                    }
                    marks.push((Instant::now(), ns));
                }
                None => other.push(line),
            }
        }
        (marks, other)
    });
    // The first mark: the recording has started.
    rx.recv_timeout(Duration::from_secs(60)).expect("the child prints time marks");
    std::thread::sleep(after);
    child.kill().expect("SIGKILL");
    let killed = Instant::now();
    let status = child.wait().expect("reaped");
    let (marks, other) = reader.join().expect("reader");
    assert_eq!(status.signal(), Some(9), "child {k} ended before its kill: {other:?}");
    let last = marks.last().expect("marks").1;

    let fixed = dir.join(format!("k{k}-recovered.mcap"));
    let r = Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(["recover", "-q"])
        .arg(&out)
        .arg(&fixed)
        .output()
        .expect("bench recover runs");
    assert!(r.status.success(), "recover {k}: {}", String::from_utf8_lossy(&r.stderr));
    let rec = Recording::load(&fixed).expect("the recovered file reads");
    assert!(rec.outcome().is_none(), "a killed run has no outcome");
    let latest = [
        rec.gyro.last().map(|m| m.log_time_ns),
        rec.table.last().map(|m| m.log_time_ns),
        rec.chamber.last().map(|m| m.log_time_ns),
    ]
    .into_iter()
    .flatten()
    .max()
    .expect("samples recovered");
    let epoch = bench::simulate::SIM_EPOCH_NS;
    // The child printed this mark after producing everything before it; all it produced since
    // (at most up to the next mark) is what the kill may have cost.
    let kept_since = marks.iter().rev().find(|(_, ns)| *ns <= latest).map_or(marks[0].0, |m| m.0);
    Kill {
        mode,
        after_s: after.as_secs_f64(),
        produced_s: (last - epoch) as f64 * 1e-9 + mark_s,
        recovered_s: (latest - epoch) as f64 * 1e-9,
        lost_wall_s: killed.saturating_duration_since(kept_since).as_secs_f64(),
    }
}

#[test]
fn sigkill_at_random_moments_loses_at_most_the_flush_interval() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("kill.toml"), SCENARIO).expect("scenario");
    let mut rng = Rng(0x5AFE_2026);
    let mut kills = Vec::new();
    // Real time: marks every 50 ms, killed 0.2..2.2 s after the first mark.
    for k in 0..10 {
        let after = Duration::from_secs_f64(0.2 + 2.0 * rng.next());
        kills.push(kill_once(dir.path(), k, "real time", after, 0.05));
    }
    // Virtual time (thousands of times real time): marks every 2 s of bench time (well under
    // a millisecond of wall time), killed 0.2..1.7 s of wall time after the first mark.
    for k in 10..22 {
        let after = Duration::from_secs_f64(0.2 + 1.5 * rng.next());
        kills.push(kill_once(dir.path(), k, "virtual", after, 2.0));
    }
    println!(
        "kill  mode       wall after start  bench produced  bench recovered  bench lost  wall lost"
    );
    for (k, x) in kills.iter().enumerate() {
        println!(
            "{k:>4}  {:<9}  {:>13.3} s  {:>12.3} s  {:>13.3} s  {:>8.3} s  {:>7.3} s",
            x.mode,
            x.after_s,
            x.produced_s,
            x.recovered_s,
            x.lost_s(),
            x.lost_wall_s
        );
    }
    for mode in ["real time", "virtual"] {
        let of = |f: fn(&Kill) -> f64| {
            let mut v: Vec<f64> = kills.iter().filter(|x| x.mode == mode).map(f).collect();
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2], v[v.len() - 1])
        };
        let (bm, bx) = of(Kill::lost_s);
        let (wm, wx) = of(|x| x.lost_wall_s);
        println!(
            "{mode}: bench time lost median {bm:.3} s, max {bx:.3} s; wall time lost median \
             {wm:.3} s, max {wx:.3} s (bound {FLUSH_S} s)"
        );
    }
    for (k, x) in kills.iter().enumerate() {
        // Nothing recovered lies beyond what the child had produced…
        assert!(x.lost_s() >= 0.0, "kill {k}: recovered past the last mark");
        if x.mode == "virtual" {
            // …and a virtual run loses at most the bound of wall-clock work (plus a margin
            // for the scheduling of a shared machine: the kill and the marks' arrival are
            // seen from another process).
            assert!(
                x.lost_wall_s <= FLUSH_S + 0.5,
                "kill {k} (virtual): {:.3} s of wall-clock work lost ({:.1} s of bench time)",
                x.lost_wall_s,
                x.lost_s()
            );
        } else {
            // …and a real-time run at most the flush interval of bench time (plus the mark
            // period, the bound's own resolution).
            assert!(
                x.lost_s() <= FLUSH_S + 0.05 + 1e-6,
                "kill {k} (real time): {:.3} s of bench time lost",
                x.lost_s()
            );
        }
    }
    // The virtual runs went well past their start: the bound held at speed.
    assert!(kills.iter().any(|x| x.mode == "virtual" && x.produced_s > 60.0));
}
