//! A run that cannot finish aborts to the safe state and keeps everything it recorded.

use std::io::Cursor;

use bench::run::FaultCause;
use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
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
    let (report, bytes) = simulate_in_memory(&plan, 1).expect("runs");
    let outcome = report.outcome.to_string();
    assert!(outcome.starts_with("aborted: step 2 (wait_temperature soak 60C)"), "{outcome}");
    assert!(outcome.contains("not within 60 ± 0.1 °C"), "{outcome}");
    assert_eq!(report.fault.as_ref().map(|f| f.cause), Some(FaultCause::StepTimeout));

    let rec = Recording::from_bytes(&bytes).expect("readable");
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

/// A table that never answers the stop command (it hangs), otherwise the simulator's.
struct DeafToStop(Box<dyn bench_drivers::RateTable>);

#[async_trait::async_trait]
impl bench_drivers::RateTable for DeafToStop {
    fn info(&self) -> &bench_drivers::DeviceInfo<bench_drivers::TableCapabilities> {
        self.0.info()
    }
    async fn set_rate(
        &mut self,
        rate_rad_s: f64,
        accel_rad_s2: f64,
    ) -> bench_drivers::DeviceResult<()> {
        self.0.set_rate(rate_rad_s, accel_rad_s2).await
    }
    async fn stop(&mut self, _decel_rad_s2: f64) -> bench_drivers::DeviceResult<()> {
        futures::future::pending().await
    }
    async fn read(&mut self) -> bench_drivers::DeviceResult<bench_drivers::TableReading> {
        self.0.read().await
    }
}

/// Run IMPOSSIBLE_WAIT with a table deaf to stop; `stop_at`: stop requests at these bench
/// times. Returns the run's end, the abort event's time and the recording.
fn run_deaf(
    stop_at: &[std::time::Duration],
) -> (std::time::Duration, std::time::Duration, Recording, bench::run::RunResult<()>) {
    use bench_drivers::clock::{run_virtual, VirtualClock};
    use bench_drivers::Clock;
    use futures::task::SpawnExt;
    use std::sync::Arc;

    let plan = bench::scenario::parse(IMPOSSIBLE_WAIT, "abort.toml", &capabilities())
        .expect("valid scenario");
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let sim = bench_sim::SimBench::new(bench::simulate::sim_config(&plan, 1), shared.clone())
        .expect("sim");
    let (table, chamber, gyro) = sim.into_parts();
    let devices = bench::run::Devices {
        table: Box::new(DeafToStop(Box::new(table))),
        chamber: Box::new(chamber),
        gyro: Box::new(gyro),
    };
    let recorder = bench_recording::Recorder::new(
        Cursor::new(Vec::new()),
        bench::runner::run_info(&plan, bench::simulate::SIM_EPOCH_NS),
    )
    .expect("recorder");
    let (stopper, stop) = bench::run::Stopper::new();
    let live = Arc::new(bench::run::Live::default());
    let times = stop_at.to_vec();
    let result = run_virtual(&clock, |spawner| {
        let c = shared.clone();
        spawner
            .spawn(async move {
                for t in times {
                    c.sleep_until(t).await;
                    stopper.stop("interrupted by the test");
                }
            })
            .expect("spawned");
        bench::run::execute(
            &plan,
            devices,
            shared.clone(),
            recorder,
            spawner,
            live,
            bench::run::ExecOptions { stop: Some(stop), ..Default::default() },
        )
    })
    .expect("the teardown does not hang");
    let outcome = result.outcome();
    let bytes = result.sink.finish(&outcome).expect("finished").into_inner();
    let rec = Recording::from_bytes(&bytes).expect("readable");
    let abort = rec
        .steps
        .iter()
        .find(|s| s.msg.event.as_str() == "abort")
        .map(|s| std::time::Duration::from_nanos(s.log_time_ns - bench::simulate::SIM_EPOCH_NS))
        .expect("an abort event");
    let r = bench::run::RunResult {
        fault: result.fault,
        sink: (),
        duration: result.duration,
        table_link: result.table_link,
    };
    (result.duration, abort, rec, r)
}

#[test]
fn a_table_deaf_to_the_stop_command_cannot_hang_the_teardown() {
    use std::time::Duration;
    let (end, abort, rec, r) = run_deaf(&[]);
    // The wait times out at 10 min; the safe state gives the stop its 10 s and goes on.
    assert_eq!(r.fault.as_ref().map(|f| f.cause), Some(FaultCause::StepTimeout));
    let timeout = bench::run::FaultPolicy::default().safe_state_timeout;
    let spent = end - abort;
    assert!(spent >= timeout, "the stop was given its {timeout:?} (ended after {spent:?})");
    assert!(
        spent <= timeout + bench::run::SAFE_STATE_TAIL + Duration::from_millis(100),
        "teardown took {spent:?}"
    );
    // The chamber's safe-state command went out beside the hanging one: its working set point,
    // heating towards 60 °C until the abort, turns down towards the safe 20 °C.
    let abort_ns = abort.as_nanos() as u64 + bench::simulate::SIM_EPOCH_NS;
    let at_abort = rec.chamber.iter().rfind(|c| c.log_time_ns <= abort_ns).expect("reading");
    let last = rec.chamber.last().expect("chamber readings");
    assert!(
        last.msg.setpoint_c < at_abort.msg.setpoint_c - 0.1,
        "set point {} °C at the abort, {} °C at the end",
        at_abort.msg.setpoint_c,
        last.msg.setpoint_c
    );
}

#[test]
fn a_second_stop_request_cuts_the_safe_state_short() {
    use std::time::Duration;
    let first = Duration::from_secs(120);
    let second = first + Duration::from_secs(2);
    let (end, abort, _rec, r) = run_deaf(&[first, second]);
    assert_eq!(r.fault.as_ref().map(|f| f.cause), Some(FaultCause::Operator));
    let message = r.fault.map(|f| f.message).unwrap_or_default();
    assert!(message.ends_with("interrupted by the test"), "{message}");
    assert_eq!(abort, first, "the first request aborts the step at once");
    // The second request, 2 s in, leaves the stop 1 more second, and no tail.
    let hurried = bench::run::HURRIED_SAFE_STATE_TIMEOUT;
    assert!(end >= second + hurried, "ended at {end:?}");
    assert!(end <= second + hurried + Duration::from_millis(100), "ended at {end:?}");
}

#[test]
fn a_chamber_told_to_hold_keeps_its_set_point_in_the_safe_state() {
    let text = IMPOSSIBLE_WAIT.replace(
        "[[step]]\nlabel = \"spin cw\"",
        "[safe]\nchamber_hold = true\n\n[[step]]\nlabel = \"spin cw\"",
    );
    let plan = bench::scenario::parse(&text, "abort.toml", &capabilities()).expect("valid");
    assert!(plan.safe_chamber_hold);
    let (report, bytes) = simulate_in_memory(&plan, 1).expect("runs");
    assert_eq!(report.fault.as_ref().map(|f| f.cause), Some(FaultCause::StepTimeout));
    let rec = Recording::from_bytes(&bytes).expect("readable");
    // Heating on at 1 °C/min through the abort and the tail: the set point does not turn down.
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let at_abort = rec.chamber.iter().rfind(|c| c.log_time_ns <= abort_ns).expect("reading");
    let last = rec.chamber.last().expect("readings");
    assert!(last.msg.setpoint_c >= at_abort.msg.setpoint_c, "{:?} → {:?}", at_abort.msg, last.msg);
    // The run said so in /log, and sent no safe set point.
    let logs: Vec<String> = mcap::MessageStream::new(&bytes)
        .expect("mcap")
        .filter_map(Result::ok)
        .filter(|m| m.channel.topic == "/log")
        .map(|m| String::from_utf8_lossy(&m.data).into_owned())
        .collect();
    assert!(logs.iter().any(|l| l.contains("chamber holds its set point")), "{logs:?}");
    assert!(!logs.iter().any(|l| l.contains("safe state: chamber set point")), "{logs:?}");
    // The table still went to rest.
    assert_eq!(rec.table.last().map(|t| t.msg.rate_command_rad_s), Some(0.0));
}
