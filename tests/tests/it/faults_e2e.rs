//! Faults injected into the served simulators while a scenario runs through the real drivers
//! (60× real time), each judged from the recording: transient faults are recovered and flagged,
//! persistent ones abort the run to its safe state with the reason in `bench.run` `outcome`,
//! keeping every sample received before.

use std::io::Cursor;
use std::sync::Arc;
use std::time::Duration;

use bench::bench_config::for_served_bench;
use bench::runner::{run, run_info, Bench, Pace, RunOptions};
use bench::simulate::{capabilities, sim_config, SIM_EPOCH_NS};
use bench_drivers::{Clock, SystemClock};
use bench_recording::status;
use bench_recording::Recording;
use bench_sim::faults::Fault;
use bench_sim::serve::bench::{serve_bench, BenchFaults};

const SCALE: f64 = 60.0;

const MINI: &str = r#"
[scenario]
name = "faults"

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
record = "3 min"

[[step]]
stop = "table"
"#;

/// Run MINI through the wire; `inject` switches faults at bench time `at` (of the simulator).
///
/// `at = 0` means "from the start": the faults are switched on here, before the run sends its
/// first command, not by the timed task. A server consults its switch when a request arrives,
/// so a fault that must be on for the first command (e.g. [`Fault::StuckTable`] for step 0's
/// rate command) cannot be left to a spawned task: on a loaded host that task may be polled
/// only after the command was served, and the run then completes.
async fn run_with(at: Duration, inject: impl FnOnce(&BenchFaults) + Send + 'static) -> Recording {
    run_text_with(MINI, at, inject).await
}

/// [`run_with`] for the scenario `text`.
async fn run_text_with(
    text: &str,
    at: Duration,
    inject: impl FnOnce(&BenchFaults) + Send + 'static,
) -> Recording {
    let plan = bench::scenario::parse(text, "faults.toml", &capabilities()).expect("valid");
    let sim_clock: Arc<dyn Clock> = Arc::new(SystemClock::new(SCALE));
    let served = serve_bench(sim_config(&plan, 5), sim_clock.clone()).await.expect("served");
    let mut config =
        for_served_bench(&served.endpoints, SCALE, plan.site.latitude_deg, plan.site.axis_up());
    // Short wall-clock reply timeouts keep the test quick; the policy is the same, and the
    // streams go stale after the default 30 s of bench time (the served config allows a
    // loaded host's 5 s of wall time).
    config.bench.stale_after_s = 30.0;
    if let Some(table) = config.table.as_mut() {
        table.reply_timeout_s = 0.05;
        table.retries = 1;
    }
    if let Some(bench::bench_config::ChamberConfig::Modbus(chamber)) = config.chamber.as_mut() {
        chamber.request_timeout_s = Some(0.05);
    }
    let clock = SystemClock::new(SCALE);
    let (devices, _) = config.connect(Arc::new(clock.clone())).await.expect("devices answer");
    let faults = served.faults.clone();
    let injector = if at.is_zero() {
        inject(&faults);
        None
    } else {
        Some(tokio::spawn(async move {
            sim_clock.sleep_until(at).await;
            inject(&faults);
        }))
    };
    let bench = Bench::Connected { devices, clock, info: Box::new(run_info(&plan, SIM_EPOCH_NS)) };
    let opts = RunOptions { pace: Pace::RealTime(SCALE), ..RunOptions::default() };
    // The run blocks its thread (the runtime's other worker serves the simulators).
    let (report, cur) =
        tokio::task::block_in_place(|| run(&plan, bench, Cursor::new(Vec::new()), opts))
            .expect("run ends (completed or aborted)");
    if let Some(injector) = injector {
        injector.abort();
    }
    drop(served);
    let rec = Recording::from_bytes(cur.get_ref()).expect("readable");
    assert_eq!(rec.outcome(), Some(report.outcome.clone()));
    rec
}

fn last_step_event(rec: &Recording) -> (String, String) {
    rec.steps
        .last()
        .map(|s| (s.msg.label.clone(), s.msg.event.as_str().to_string()))
        .unwrap_or_default()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn corrupt_and_dropped_gyro_frames_are_flagged_and_the_run_completes() {
    let rec = run_with(Duration::from_secs(30), |f| {
        f.gyro.inject(Fault::Corrupt { every: 97 });
        f.gyro.inject(Fault::Drop { every: 113 });
    })
    .await;
    assert_eq!(rec.outcome(), Some(bench_recording::Outcome::Completed));
    let flagged = |bit: u32| rec.gyro.iter().filter(|g| g.msg.status & bit != 0).count();
    let (gaps, after_corrupt) =
        (flagged(status::gyro::SEQ_GAP), flagged(status::gyro::AFTER_CORRUPT));
    // ≈ 3 min at 20 Hz after the faults start: ≥ 30 drops and ≥ 30 corrupt frames.
    assert!(gaps >= 30, "{gaps} samples flagged SEQ_GAP");
    assert!(after_corrupt >= 30, "{after_corrupt} samples flagged AFTER_CORRUPT");
    // Every device counter jump is flagged, and nothing else is.
    for w in rec.gyro.windows(2) {
        let jumped = w[1].msg.seq != w[0].msg.seq + 1;
        assert_eq!(jumped, w[1].msg.status & status::gyro::SEQ_GAP != 0, "{:?}", w[1].msg);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_silent_table_aborts_to_the_safe_state_keeping_the_data() {
    // Each read now fails after 2 attempts × 50 ms (+ backoff) of wall time; at 60× the
    // orchestrator's watchdog (no good reading for 30 s of bench time = 0.5 s of wall time)
    // trips before the poller's budget of 5 consecutive errors (≈ 0.75 s of wall time).
    let rec = run_with(Duration::from_secs(30), |f| f.table.inject(Fault::Silence)).await;
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 1 (record cw 20C)"), "{outcome}");
    assert!(
        outcome.contains("stream_stale: rate table data stale: no good reading for"),
        "{outcome}"
    );
    assert_eq!(last_step_event(&rec), ("record cw 20C".into(), "abort".into()));
    // The gyro kept streaming until the end: every sample up to the abort is there, in order.
    let abort_t = rec.steps.last().map_or(0, |s| s.log_time_ns);
    assert!(rec.gyro.last().map_or(0, |g| g.log_time_ns) >= abort_t);
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1));
    // The table's last good reading came before the silence.
    assert!(rec.table.last().map_or(0, |t| t.log_time_ns) < abort_t);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_chamber_device_failure_aborts_at_once() {
    let rec =
        run_with(Duration::from_secs(60), |f| f.chamber.inject(Fault::ModbusException { code: 4 }))
            .await;
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(
        outcome.contains("chamber failed after 1 consecutive error(s): device fault"),
        "{outcome}"
    );
    assert!(outcome.contains("Modbus exception 0x04"), "{outcome}");
    assert_eq!(last_step_event(&rec).1, "abort");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stuck_table_fails_to_settle_and_the_run_aborts() {
    // The controller acknowledges the rate command but the axis does not follow. The fault is
    // on before the run starts (`at = 0`), so step 0's command is the one ignored.
    let rec = run_with(Duration::ZERO, |f| f.table.inject(Fault::StuckTable)).await;
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 0 (table spin cw)"), "{outcome}");
    assert!(outcome.contains("table_stall: table rate"), "{outcome}");
    assert!(outcome.contains("did not settle on -2.908882e-3 rad/s"), "{outcome}");
    assert!(rec.table.iter().all(|t| t.msg.rate_rad_s.abs() < 1e-4), "the axis never moved");
    assert_eq!(last_step_event(&rec), ("spin cw".into(), "abort".into()));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_short_table_line_outage_is_ridden_out() {
    // 3 s of bench time without replies (50 ms of wall time): retries cover it.
    let rec =
        run_with(Duration::from_secs(60), |f| f.table.inject(Fault::Disconnect { seconds: 3.0 }))
            .await;
    assert_eq!(rec.outcome(), Some(bench_recording::Outcome::Completed));
    // The outage shows as a hole in the table's stream, shorter than the watchdog's limit.
    let longest = rec
        .table
        .windows(2)
        .map(|w| (w[1].log_time_ns - w[0].log_time_ns) as f64 * 1e-9)
        .fold(0.0, f64::max);
    assert!((1.0..30.0).contains(&longest), "longest table gap {longest:.2} s");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_chamber_overshooting_through_the_wire_trips_chamber_over_temperature() {
    // The served controller's process value overshoots each new set point by up to 20 °C: on
    // the way to 30 °C the air reads above the 35 °C interlock.
    let text = "[scenario]\nname = \"overshoot\"\n[site]\nlatitude_deg = 48.0\n\
                [interlocks]\nchamber_max_temp = \"35 °C\"\n\
                [[step]]\nchamber = \"30 °C\"\n\
                [[step]]\nlabel = \"record hot\"\nrecord = \"30 min\"\n";
    let rec = run_text_with(text, Duration::ZERO, |f| {
        f.chamber.inject(Fault::ChamberOvershoot { overshoot_c: 20.0 })
    })
    .await;
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 1 (record hot)"), "{outcome}");
    assert!(outcome.contains(": chamber_over_temperature: chamber air"), "{outcome}");
    assert!(outcome.contains("above the limit 35 °C"), "{outcome}");
    assert_eq!(last_step_event(&rec), ("record hot".into(), "abort".into()));
    // The reading that tripped it is recorded, and it is the first above the limit.
    let abort_t = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let first_hot = rec.chamber.iter().find(|c| c.msg.temperature_c > 35.0).expect("a hot reading");
    assert!(first_hot.log_time_ns <= abort_t);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drive_alarm_mid_window_aborts_at_the_next_poll_with_table_drive_fault() {
    // The served Actidyn controller drops its drive 60 s in (mid-record): bench used to record
    // the rest of the window with the table at rest and mark it completed.
    let rec = run_with(Duration::from_secs(60), |f| f.table.inject(Fault::DriveAlarm)).await;
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 1 (record cw 20C)"), "{outcome}");
    assert!(outcome.contains(": table_drive_fault: "), "{outcome}");
    assert_eq!(last_step_event(&rec), ("record cw 20C".into(), "abort".into()));
    assert!(!rec
        .steps
        .iter()
        .any(|s| s.msg.label == "record cw 20C" && s.msg.event.as_str() == "end"));
    // The first reading with the drive off ends the window: the abort follows it within a
    // second of bench time (a 60× run), and the reading before was at speed.
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let spin_ns = rec.steps.first().map_or(0, |s| s.log_time_ns);
    let (before, first_off) = bench_tests::first_flagged(
        &rec.table,
        spin_ns,
        |t| t.log_time_ns,
        |t| t.msg.status & status::table::DRIVE_OFF != 0,
    )
    .expect("a reading with the drive off");
    let to_abort = Duration::from_nanos(abort_ns.saturating_sub(first_off.log_time_ns));
    assert!(to_abort <= Duration::from_secs(1), "abort {to_abort:?} after the reading");
    assert!((before.msg.rate_rad_s.abs().to_degrees() * 60.0 - 10.0).abs() < 0.01);
    eprintln!(
        "drive_alarm: abort {:.3} s after the reading that showed it, {:.3} s after the last \
         at speed",
        to_abort.as_secs_f64(),
        (abort_ns - before.log_time_ns) as f64 * 1e-9
    );
    // Every gyro sample up to the abort is kept; the safe state commanded the table to rest.
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1));
    assert!(rec.gyro.last().map_or(0, |g| g.log_time_ns) >= abort_ns);
    assert_eq!(rec.table.last().map(|t| t.msg.rate_command_rad_s), Some(0.0));
}
