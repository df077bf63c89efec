//! Kill-safety through the binary: `bench run` children on the simulated bench, in real time
//! (`--time-scale 1`) and in virtual time, are SIGKILLed at random moments; `bench recover`
//! restores each file, and the bench time lost — from the last time mark the child printed
//! (it had produced nothing at or after that mark plus the mark period) to the last message
//! recovered — stays within the flush interval (1 s by default). Prints one line per kill.

use std::io::{BufRead, BufReader};
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

use bench_recording::Recording;

/// Long enough that no child finishes before its kill.
const SCENARIO: &str = "[scenario]\nname = \"kill\"\n[site]\nlatitude_deg = 45\n\
                        [[step]]\nspin = \"10 °/min\"\ndirection = \"cw\"\n\
                        [[step]]\nchamber = \"40 °C\"\nramp = \"1 °C/min\"\n\
                        [[step]]\nlabel = \"record cw ramp\"\nrecord = \"ramp end\"\n\
                        [[step]]\nlabel = \"record cw 40C\"\nrecord = \"10 h\"\n";

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
        let mut last = None;
        let mut other = Vec::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            match mark_ns(&line) {
                Some(ns) => {
                    if last.is_none() {
                        let _ = tx.send(());
                    }
                    last = Some(ns);
                }
                None => other.push(line),
            }
        }
        (last, other)
    });
    // The first mark: the recording has started.
    rx.recv_timeout(Duration::from_secs(60)).expect("the child prints time marks");
    std::thread::sleep(after);
    child.kill().expect("SIGKILL");
    let status = child.wait().expect("reaped");
    let (last, other) = reader.join().expect("reader");
    assert_eq!(status.signal(), Some(9), "child {k} ended before its kill: {other:?}");
    let last = last.expect("marks");

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
    Kill {
        mode,
        after_s: after.as_secs_f64(),
        produced_s: (last - epoch) as f64 * 1e-9 + mark_s,
        recovered_s: (latest - epoch) as f64 * 1e-9,
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
    // Virtual time (hundreds of times real time): marks every 0.1 s of bench time, killed
    // 0.05..1.5 s of wall time after the first mark.
    for k in 10..22 {
        let after = Duration::from_secs_f64(0.05 + 1.45 * rng.next());
        kills.push(kill_once(dir.path(), k, "virtual", after, 0.1));
    }
    println!("kill  mode       wall after start  bench produced  bench recovered  bench lost");
    for (k, x) in kills.iter().enumerate() {
        println!(
            "{k:>4}  {:<9}  {:>13.3} s  {:>12.3} s  {:>13.3} s  {:>8.3} s",
            x.mode,
            x.after_s,
            x.produced_s,
            x.recovered_s,
            x.lost_s()
        );
    }
    let mut lost: Vec<f64> = kills.iter().map(Kill::lost_s).collect();
    lost.sort_by(f64::total_cmp);
    println!(
        "{} kills: bench time lost median {:.3} s, max {:.3} s (flush interval {FLUSH_S} s)",
        lost.len(),
        lost[lost.len() / 2],
        lost[lost.len() - 1]
    );
    for (k, x) in kills.iter().enumerate() {
        // Nothing recovered lies beyond what the child had produced…
        assert!(x.lost_s() >= 0.0, "kill {k}: recovered past the last mark");
        // …and at most the flush interval (plus the mark period, the bound's own resolution)
        // is lost.
        let mark_s = if x.mode == "virtual" { 0.1 } else { 0.05 };
        assert!(
            x.lost_s() <= FLUSH_S + mark_s + 1e-6,
            "kill {k} ({}): {:.3} s of bench time lost",
            x.mode,
            x.lost_s()
        );
    }
    // The virtual runs went well past their start: the bound held at speed.
    assert!(kills.iter().any(|x| x.mode == "virtual" && x.produced_s > 60.0));
}
