//! A run that cannot finish aborts to the safe state and keeps everything it recorded.

use std::io::Cursor;

use bench::run::FaultCause;
use bench::simulate::{capabilities, run_plan, SimOptions};
use bench_recording::Recording;

/// The chamber heats from 20 °C at 1 °C/min, so the air cannot be within 0.1 °C of 60 °C after
/// 10 minutes: the wait times out and the run must abort.
const IMPOSSIBLE_WAIT: &str = r#"
[scenario]
name = "abort-test"

[site]
latitude_deg = 45.0

[[step]]
label = "spin cw"
spin = "10 °/min"
direction = "cw"
accel = "1 °/s²"

[[step]]
label = "heat"
chamber = "60 °C"
ramp = "1 °C/min"

[[step]]
label = "soak 60C"
wait_temperature = "60 °C"
band = "0.1 °C"
hold = "1 min"
timeout = "10 min"

[[step]]
label = "record cw 60C"
record = "5 min"
"#;

#[test]
fn timed_out_wait_aborts_to_safe_state_and_keeps_the_data() {
    let plan = bench::scenario::parse(IMPOSSIBLE_WAIT, "abort.toml", &capabilities())
        .expect("valid scenario");
    let (report, cursor) =
        run_plan(&plan, Cursor::new(Vec::new()), &SimOptions::default(), None).expect("runs");
    let outcome = report.outcome.to_string();
    assert!(outcome.starts_with("aborted: step 2 (wait_temperature soak 60C)"), "{outcome}");
    assert!(outcome.contains("not within 60 ± 0.1 °C"), "{outcome}");
    assert_eq!(report.fault.as_ref().map(|f| f.cause), Some(FaultCause::StepTimeout));

    let rec = Recording::from_bytes(cursor.get_ref()).expect("readable");
    assert_eq!(rec.outcome(), Some(report.outcome));

    // Step 2 started and aborted at its timeout; the record step never started.
    let events: Vec<(u64, String)> =
        rec.steps.iter().map(|s| (s.msg.index, s.msg.event.as_str().to_string())).collect();
    assert_eq!(
        events,
        vec![
            (0, "start".to_string()),
            (0, "end".to_string()),
            (1, "start".to_string()),
            (1, "end".to_string()),
            (2, "start".to_string()),
            (2, "abort".to_string())
        ]
    );
    let abort_t = rec.steps.last().map(|s| s.log_time_ns).unwrap_or(0);
    let start_t = rec.steps.get(4).map(|s| s.log_time_ns).unwrap_or(0);
    assert_eq!(abort_t - start_t, 600_000_000_000, "aborted at the 10 min timeout");

    // Every gyro sample up to the abort is there, at 20 Hz without gaps.
    let n = rec.gyro.len() as u64;
    let first = rec.gyro.first().map(|g| g.log_time_ns).unwrap_or(0);
    assert!(rec.gyro.last().map(|g| g.log_time_ns).unwrap_or(0) >= abort_t);
    assert_eq!(n, (rec.gyro.last().map(|g| g.log_time_ns).unwrap_or(0) - first) / 50_000_000 + 1);

    // Safe state: the table was commanded to rest and the chamber to the safe set point (20 °C
    // by default); the last readings show it.
    let last_table = rec.table.last().expect("table readings");
    assert_eq!(last_table.msg.rate_command_rad_s, 0.0);
    let last_chamber = rec.chamber.last().expect("chamber readings");
    assert!(last_chamber.log_time_ns >= abort_t);
    let log_text: Vec<&str> = rec.other_counts.keys().map(String::as_str).collect();
    assert!(log_text.contains(&"/log"), "log channel present: {log_text:?}");
}

/// A gyro whose driver hangs: no error, no sample, ever.
struct HangingGyro(bench_drivers::DeviceInfo<bench_drivers::GyroCapabilities>);

#[async_trait::async_trait]
impl bench_drivers::Gyro for HangingGyro {
    fn info(&self) -> &bench_drivers::DeviceInfo<bench_drivers::GyroCapabilities> {
        &self.0
    }
    async fn next_sample(&mut self) -> bench_drivers::DeviceResult<bench_drivers::GyroSample> {
        futures::future::pending().await
    }
    fn sample_rate_hz(&self) -> f64 {
        20.0
    }
}

#[test]
fn a_hanging_stream_is_caught_by_the_watchdog() {
    use bench_drivers::clock::{run_virtual, VirtualClock};
    use bench_drivers::Clock;
    use std::sync::Arc;

    let plan = bench::scenario::parse(IMPOSSIBLE_WAIT, "abort.toml", &capabilities())
        .expect("valid scenario");
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let sim = bench_sim::SimBench::new(bench::simulate::sim_config(&plan, 1), shared.clone())
        .expect("sim");
    let gyro_info = bench::simulate::capabilities().gyro;
    let (table, chamber, _) = sim.into_parts();
    let devices = bench::run::Devices {
        table: Box::new(table),
        chamber: Box::new(chamber),
        gyro: Box::new(HangingGyro(gyro_info)),
    };
    let recorder = bench_recording::Recorder::new(
        Cursor::new(Vec::new()),
        bench::runner::run_info(&plan, bench::simulate::SIM_EPOCH_NS),
    )
    .expect("recorder");
    let live = Arc::new(bench::run::Live::default());
    let result = run_virtual(&clock, |spawner| {
        bench::run::execute(
            &plan,
            devices,
            shared.clone(),
            recorder,
            spawner,
            live,
            Default::default(),
        )
    })
    .expect("no deadlock");
    let outcome = result.outcome().to_string();
    assert!(outcome.starts_with("aborted: step 2 (wait_temperature soak 60C)"), "{outcome}");
    assert!(
        outcome.contains("gyro data stale: no good reading for 31.0 s (limit 30.0 s)"),
        "{outcome}"
    );
    assert_eq!(result.fault.as_ref().map(|f| f.cause), Some(FaultCause::Stale { device: "gyro" }));
    let outcome = result.outcome();
    let bytes = result.sink.finish(&outcome).expect("finished").into_inner();
    let rec = Recording::from_bytes(&bytes).expect("readable");
    assert!(rec.gyro.is_empty() && !rec.table.is_empty());
    assert_eq!(rec.steps.last().map(|s| s.msg.event.as_str()), Some("abort"));
}
