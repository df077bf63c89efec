//! The same orchestrator in real (scaled) time on tokio gives the recording of the virtual-time
//! run, up to the timing jitter of the host: a check of the real-time path with the in-process
//! simulators before any wire protocol is involved.

use std::collections::BTreeMap;
use std::io::Cursor;

use bench::runner::{run, Bench, Pace, RunOptions};
use bench::simulate::{capabilities, sim_config, SIM_EPOCH_NS};
use bench_recording::Recording;

const MINI: &str = r#"
[scenario]
name = "mini"

[site]
latitude_deg = 48.0

[[step]]
label = "spin cw"
spin = "10 °/min"
direction = "cw"
accel = "1 °/s²"
settle = true

[[step]]
label = "record cw 20C"
record = "60 s"

[[step]]
label = "heat"
chamber = "22 °C"
ramp = "2 °C/min"

[[step]]
label = "record cw ramp"
record = "ramp end"
timeout = "5 min"

[[step]]
stop = "table"
"#;

/// Gyro samples (by the device's sequence number) inside the step labelled `label`.
fn window(rec: &Recording, label: &str) -> BTreeMap<u64, f64> {
    let start = rec.steps.iter().find(|s| s.msg.label == label && s.msg.event.as_str() == "start");
    let end = rec.steps.iter().find(|s| s.msg.label == label && s.msg.event.as_str() == "end");
    let (t0, t1) = (start.map_or(0, |s| s.log_time_ns), end.map_or(0, |s| s.log_time_ns));
    rec.gyro
        .iter()
        // Judge by the device's own time stamp: the host's receive time jitters in real time.
        .filter(|g| g.publish_time_ns > t0 && g.publish_time_ns <= t1)
        .map(|g| (g.msg.seq, g.msg.rate_rad_s))
        .collect()
}

#[test]
fn scaled_real_time_run_matches_the_virtual_run() {
    let plan = bench::scenario::parse(MINI, "mini.toml", &capabilities()).expect("valid");
    let seed = 11;
    // The one run API, paced two ways.
    let paced = |pace| {
        let bench = Bench::Simulated(sim_config(&plan, seed));
        let opts = RunOptions { pace, ..RunOptions::default() };
        run(&plan, bench, Cursor::new(Vec::new()), opts)
    };

    let (virt, cur) = paced(Pace::Virtual).expect("virtual run");
    assert_eq!(virt.outcome, bench_recording::Outcome::Completed);
    let a = Recording::from_bytes(cur.get_ref()).expect("readable");

    let scale = 50.0;
    let (real, cur) = paced(Pace::RealTime(scale)).expect("real-time run");
    assert_eq!(real.outcome, bench_recording::Outcome::Completed);
    let b = Recording::from_bytes(cur.get_ref()).expect("readable");

    // Same steps in the same order.
    let steps = |r: &Recording| -> Vec<(u64, String, String)> {
        r.steps
            .iter()
            .map(|s| (s.msg.index, s.msg.event.as_str().to_string(), s.msg.label.clone()))
            .collect()
    };
    assert_eq!(steps(&a), steps(&b));

    // The gyro's own counter has no gap in either run, and its time stamps are on the 20 Hz
    // grid: the device clock does not jitter, only the host's receive time does.
    for r in [&a, &b] {
        assert!(r.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1));
        assert!(r
            .gyro
            .iter()
            .all(|g| (g.publish_time_ns - SIM_EPOCH_NS).is_multiple_of(50_000_000)));
    }

    // Sample by sample, the gyro agrees: the noise streams are indexed by sample number, so
    // only command timing (host jitter × time scale, ~0.1 s of bench time) separates the runs.
    // On the plateau that shifts the table's ripple phase (1e-5 × rate at 16 cycles/rev:
    // ≤ 1.3e-10 rad/s); on the ramp the dT/dt term by temp_rate_coeff × d²T/dt² × jitter
    // (≤ 1.5e-5 × 2.8e-4 × 0.1 ≈ 4e-10 rad/s). Tolerances keep a margin of ~10.
    for (label, tol) in [("record cw 20C", 2e-9), ("record cw ramp", 5e-9)] {
        let (wa, wb) = (window(&a, label), window(&b, label));
        let common: Vec<_> = wa.keys().filter(|k| wb.contains_key(k)).collect();
        assert!(common.len() > 1000, "{label}: {} common samples", common.len());
        let worst = common.iter().map(|k| (wa[k] - wb[k]).abs()).fold(0.0, f64::max);
        assert!(worst < tol, "{label}: worst sample difference {worst:e} rad/s");
    }
    // Bench time passed at the scale asked for (loosely: the host may be busy).
    assert!(real.speed() > 0.5 * scale && real.speed() < 1.1 * scale, "{}", real.speed());
}
