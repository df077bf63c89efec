//! End to end through the wire protocols: `scenarios/seed.toml` run by the real drivers
//! (Actidyn table on a pty, Eurotherm 3216 chamber over Modbus RTU on a pty, gyro CAN frames
//! over SLCAN on a pty) against the simulators served on virtual ports at 60× real time, and
//! compared with the in-process (virtual-time) run of the same seed.
//!
//! The chamber's sensor noise is off in both runs: the served controller reads the simulated
//! chamber more often than the in-process poller (one read per register), so with noise the two
//! runs would draw different noise and their soaks, which wait for the noisy 0.1 °C process
//! value to stay in a band, would end at different times for that reason alone.
//!
//! Stated tolerances (what separates the two runs is host timing × 60, ~0.1 s of bench time per
//! command, and the wire's resolution):
//! - same steps, same labels, both completed;
//! - fixed-length steps (waits, record windows) last the same within 1.5 s (2 s for a ramp's
//!   record), command steps within 30 s (0.5 s of a loaded host's round trips, × 60);
//! - soaks (waits for a temperature) last the same within 5 s: the 0.1 °C process value crosses
//!   its band edge at a time the jitter moves;
//! - table rate commands equal within 1e-6 relative (the wire carries °/s in decimal text);
//! - gyro: the mean rate of every record window within 5e-9 rad/s (0.001 °/h), the gyro
//!   samples' device counter continuous, each window ≥ 95 % as many samples;
//! - chamber air in the plateau windows within 0.15 °C.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::PathBuf;
use std::sync::Arc;

use bench::bench_config::for_served_bench;
use bench::runner::{run, run_info, Bench, Pace, RunOptions};
use bench::simulate::{capabilities, sim_config};
use bench_drivers::{Clock, SystemClock};
use bench_recording::Recording;
use bench_report::calibrate::{calibrate_recording, CalibrateSettings};
use bench_report::load::TimeSource;

const SCALE: f64 = 60.0;
const SEED: u64 = 3;

fn windows(rec: &Recording) -> BTreeMap<String, (u64, u64)> {
    let mut open = BTreeMap::new();
    let mut out = BTreeMap::new();
    for s in &rec.steps {
        match s.msg.event.as_str() {
            "start" => {
                open.insert(s.msg.index, s.log_time_ns);
            }
            _ => {
                let t0 = open.remove(&s.msg.index).unwrap_or(0);
                out.insert(format!("{:02} {}", s.msg.index, s.msg.label), (t0, s.log_time_ns));
            }
        }
    }
    out
}

fn gyro_mean(rec: &Recording, (t0, t1): (u64, u64)) -> (f64, usize) {
    let v: Vec<f64> = rec
        .gyro
        .iter()
        .filter(|g| g.log_time_ns > t0 && g.log_time_ns < t1)
        .map(|g| g.msg.rate_rad_s)
        .collect();
    (v.iter().sum::<f64>() / v.len().max(1) as f64, v.len())
}

fn air_range(rec: &Recording, (t0, t1): (u64, u64)) -> (f64, f64) {
    rec.chamber
        .iter()
        .filter(|c| c.log_time_ns > t0 && c.log_time_ns < t1)
        .map(|c| c.msg.temperature_c)
        .fold((f64::MAX, f64::MIN), |(lo, hi), t| (lo.min(t), hi.max(t)))
}

/// With `BENCH_E2E_KEEP=<dir>` the two recordings are written there (`inproc.mcap`,
/// `wired.mcap`): what a failure on a loaded machine recorded can then be calibrated again.
fn keep(name: &str, bytes: &[u8]) {
    if let Some(dir) = std::env::var_os("BENCH_E2E_KEEP") {
        let path = PathBuf::from(dir).join(name);
        let written = std::fs::create_dir_all(path.parent().unwrap_or(&path))
            .and_then(|()| std::fs::write(&path, bytes));
        if let Err(e) = written {
            println!("BENCH_E2E_KEEP: {}: {e}", path.display());
        }
    }
}

/// The wired run paces the bench clock at 60× real time: a millisecond the host is late is
/// 60 ms of bench time on a command, a soak's end or a table reading. The test asks the kernel
/// to schedule its threads first (nice −10 on every thread of the process; threads started
/// later inherit it), as a lab's bench controller would run. Beside 3 and 4 busy loops on 2
/// cores the run then matched the in-process one as it does alone (fit sound, coefficients
/// within 0.8σ); at the default priority beside 3 loops the record windows' gyro means were
/// 6e-9 rad/s apart (the tolerance is 5e-9: the chamber's history shifted by seconds) and its
/// table readings glitched over 31 % of a stretch. Where the kernel refuses it says so and the
/// test runs at the default priority.
fn schedule_first() {
    let tids: Vec<String> = std::fs::read_dir("/proc/self/task")
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned())))
        .map(Iterator::collect)
        .unwrap_or_default();
    let raised = !tids.is_empty()
        && std::process::Command::new("renice")
            .args(["--priority", "-10", "-p"])
            .args(&tids)
            .output()
            .is_ok_and(|o| o.status.success());
    if !raised {
        println!(
            "could not raise this test's scheduling priority (renice --priority -10): it runs \
             at the default one, where a loaded host moves the wired run's timing"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn seed_scenario_through_the_wire_matches_the_in_process_run() {
    schedule_first();
    // Server-side problems are logged, not returned: show them (RUST_LOG=debug for more).
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_test_writer()
        .try_init();
    let scenario = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenarios/seed.toml");
    let plan = bench::scenario::load(&scenario, &capabilities()).expect("valid");

    let mut sim = sim_config(&plan, SEED);
    sim.chamber.sensor_noise_c = 0.0;
    let (virt, cur) =
        run(&plan, Bench::Simulated(sim.clone()), Cursor::new(Vec::new()), RunOptions::default())
            .expect("in-process run");
    assert_eq!(virt.outcome, bench_recording::Outcome::Completed);
    let a = Recording::from_bytes(cur.get_ref()).expect("readable");
    keep("inproc.mcap", cur.get_ref());

    // The simulators on virtual ports, and the bench config that reaches them.
    let sim_clock: Arc<dyn Clock> = Arc::new(SystemClock::new(SCALE));
    let served = bench_sim::serve::bench::serve_bench(sim, sim_clock).await.expect("served");
    let config =
        for_served_bench(&served.endpoints, SCALE, plan.site.latitude_deg, plan.site.axis_up());
    // The config round-trips through its file format.
    let config = bench::bench_config::BenchConfig::parse(
        &config.to_toml().expect("serialises"),
        "bench-sim.toml",
    )
    .expect("parses");

    let clock = SystemClock::new(SCALE);
    let (devices, caps) = config.connect(Arc::new(clock.clone())).await.expect("devices answer");
    let wire_plan = bench::scenario::load(&scenario, &caps).expect("valid on the wired bench");
    let info = Box::new(run_info(&wire_plan, bench::simulate::SIM_EPOCH_NS));
    let wired = Bench::Connected { devices, clock, info };
    let opts = RunOptions { pace: Pace::RealTime(SCALE), ..RunOptions::default() };
    // The run blocks its thread (the runtime's other worker serves the simulators).
    let (real, cur) =
        tokio::task::block_in_place(|| run(&wire_plan, wired, Cursor::new(Vec::new()), opts))
            .expect("wired run");
    drop(served);
    assert_eq!(real.outcome, bench_recording::Outcome::Completed);
    keep("wired.mcap", cur.get_ref());
    let b = Recording::from_bytes(cur.get_ref()).expect("readable");

    let (wa, wb) = (windows(&a), windows(&b));
    assert_eq!(wa.keys().collect::<Vec<_>>(), wb.keys().collect::<Vec<_>>());
    // One row per step: durations, and for record windows the gyro mean and chamber air; every
    // tolerance broken is listed under the table.
    let mut report = String::new();
    let mut broken = Vec::new();
    for (k, &(a0, a1)) in &wa {
        let (b0, b1) = wb[k];
        let (da, db) = ((a1 - a0) as f64 * 1e-9, (b1 - b0) as f64 * 1e-9);
        report += &format!("{k:<40} {da:9.2} s {db:9.2} s");
        let soak = k.contains("soak") || k.contains("settle 40C");
        // Command steps (no duration in virtual time) last a few wire round trips, × 60 in
        // bench time: up to 0.5 s of wall time, what a loaded 2-core machine may add to a
        // Modbus write (4.1 s of bench time seen with two builds running, 9.1 s with the whole
        // suite beside a study); soaks 5 s; waits and records end on the clock, 1.5 s (2 s
        // across a ramp's start).
        let tol = if da < 1.0 {
            0.5 * SCALE
        } else if soak {
            5.0
        } else if k.contains("ramp") {
            2.0
        } else {
            1.5
        };
        if (da - db).abs() > tol {
            broken.push(format!("{k}: lasted {da:.2} s vs {db:.2} s (tolerance {tol} s)"));
        }
        if k.contains("record") {
            let ((ma, na), (mb, nb)) = (gyro_mean(&a, (a0, a1)), gyro_mean(&b, (b0, b1)));
            report += &format!("  gyro {ma:+.6e} {mb:+.6e} ({na}/{nb})");
            if nb * 100 < na * 95 {
                broken.push(format!("{k}: {nb} of {na} gyro samples"));
            }
            if (ma - mb).abs() >= 5e-9 {
                broken.push(format!("{k}: gyro mean {ma:e} vs {mb:e} rad/s"));
            }
            if !k.contains("ramp") {
                let (ra, rb) = (air_range(&a, (a0, a1)), air_range(&b, (b0, b1)));
                report += &format!("  air {:.2}..{:.2} {:.2}..{:.2}", ra.0, ra.1, rb.0, rb.1);
                if (ra.0 - rb.0).abs() > 0.15 || (ra.1 - rb.1).abs() > 0.15 {
                    broken.push(format!("{k}: air {ra:?} vs {rb:?} °C"));
                }
            }
        }
        report += "\n";
    }
    println!("{report}");
    assert!(broken.is_empty(), "{}\n{report}", broken.join("\n"));
    assert!(b.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1), "device counter gap");
    let cmds = |r: &Recording| -> Vec<f64> {
        let mut v: Vec<f64> = r.table.iter().map(|t| t.msg.rate_command_rad_s).collect();
        v.dedup();
        v
    };
    let (ca, cb) = (cmds(&a), cmds(&b));
    assert_eq!(ca.len(), cb.len(), "{ca:?} vs {cb:?}");
    for (x, y) in ca.iter().zip(&cb) {
        assert!((x - y).abs() <= 1e-6 * x.abs().max(1e-9), "rate command {x} vs {y}");
    }

    // The wired recording calibrates as the in-process one does: the gyro's samples carry its
    // counter's clock (publish_time), the analysis runs on it, and the coefficients agree
    // within 3σ; the fit is sound on both.
    let stamped = b.gyro.iter().filter(|g| g.publish_time_ns != g.log_time_ns).count();
    assert!(stamped * 10 > b.gyro.len() * 9, "device stamps on {stamped} of {}", b.gyro.len());
    let settings = CalibrateSettings { replicates: Some(100), ..Default::default() };
    let ka = calibrate_recording(&a, &settings).expect("in-process calibrates");
    let kb = calibrate_recording(&b, &settings).expect("wired calibrates");
    let gyro_base = kb.data.run.time_bases.iter().find(|t| t.topic == "/gyro/rate").expect("gyro");
    assert_eq!(gyro_base.source, TimeSource::DeviceStamps);
    let (ja, jb) = (
        ka.calibration.joint.as_ref().expect("joint fit"),
        kb.calibration.joint.as_ref().expect("joint fit"),
    );
    let mut table = String::new();
    for key in bench_physics::ModelKey::CALIBRATED {
        let (ea, eb) = (ja.estimate(key).expect("a"), jb.estimate(key).expect("b"));
        assert!(!ea.held, "{}: the in-process run determines every coefficient", key.key());
        if eb.held {
            // A loaded host's late stamps can cost the wired run whole windows (glitches of
            // the table's readings, steady parts cut short), and with them the information on
            // a coefficient: it is then held, and so said, not measured — nothing to compare.
            table += &format!("{:<20} {:+.4e} ± {:.1e}  held\n", key.key(), ea.value, ea.std_err);
            continue;
        }
        let z = (ea.value - eb.value) / ea.std_err.max(eb.std_err);
        table += &format!(
            "{:<20} {:+.4e} ± {:.1e}  {:+.4e} ± {:.1e}  ({z:+.2}σ)\n",
            key.key(),
            ea.value,
            ea.std_err,
            eb.value,
            eb.std_err
        );
        assert!(z.abs() < 3.0, "{}\n{table}", key.key());
    }
    println!("in-process vs wired calibration:\n{table}");
    assert!(!ka.quality.poor(), "{:?}", ka.quality.lines());
    // At 60× a millisecond of the host's scheduling is 60 ms of bench time on the table's host
    // stamps (the Actidyn protocol has no time stamp; a reading is stamped at its round trip's
    // midpoint, which halves what a late read adds): 36″ of angle at 10 °/min, so the steady
    // rule splits some windows and the fit check may call the wired run poor. It must then say
    // where: next to what it left out. (Stamped on the reply's arrival, a loaded host put the
    // wired bias 9.5σ off the in-process one: CI, stop 45.)
    println!("wired fit: {} {:?}", kb.quality.verdict, kb.quality.lines());
    assert!((0.8..1.25).contains(&jb.whitened_residual_rms), "{}", jb.whitened_residual_rms);
    for x in &kb.quality.excursions {
        assert!(x.context.contains("table"), "{x:?}");
    }
}
