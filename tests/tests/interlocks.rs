//! Run-time interlocks end to end on the simulated bench (virtual time): a fault injected into
//! a device's readings from 120 s of bench time on trips its named interlock, the run aborts
//! to the safe state, and the recording ends with an `abort` step event and an `outcome` that
//! names the interlock.

use std::io::Cursor;
use std::sync::Arc;
use std::time::Duration;

use bench::run::FaultCause;
use bench::simulate::{capabilities, sim_config, SIM_EPOCH_NS};
use bench_drivers::clock::{run_virtual, VirtualClock};
use bench_drivers::{
    Chamber, ChamberCapabilities, ChamberReading, Clock, DeviceInfo, DeviceResult, Gyro,
    GyroCapabilities, GyroSample, RateTable, TableCapabilities, TableReading,
};
use bench_recording::Recording;

/// When the injected fault starts, bench time.
const FAULT_AT: Duration = Duration::from_secs(120);

type Edit<T> = Box<dyn Fn(&mut T) + Send>;

/// A device whose readings are edited from [`FAULT_AT`] on.
struct Faulty<D, T> {
    inner: D,
    clock: Arc<dyn Clock>,
    edit: Option<Edit<T>>,
}

impl<D, T> Faulty<D, T> {
    fn apply(&self, r: &mut T) {
        if let Some(edit) = &self.edit {
            if self.clock.now() >= FAULT_AT {
                edit(r);
            }
        }
    }
}

#[async_trait::async_trait]
impl<D: RateTable> RateTable for Faulty<D, TableReading> {
    fn info(&self) -> &DeviceInfo<TableCapabilities> {
        self.inner.info()
    }
    async fn set_rate(&mut self, rate_rad_s: f64, accel_rad_s2: f64) -> DeviceResult<()> {
        self.inner.set_rate(rate_rad_s, accel_rad_s2).await
    }
    async fn stop(&mut self, decel_rad_s2: f64) -> DeviceResult<()> {
        self.inner.stop(decel_rad_s2).await
    }
    async fn read(&mut self) -> DeviceResult<TableReading> {
        let mut r = self.inner.read().await?;
        self.apply(&mut r);
        Ok(r)
    }
}

#[async_trait::async_trait]
impl<D: Chamber> Chamber for Faulty<D, ChamberReading> {
    fn info(&self) -> &DeviceInfo<ChamberCapabilities> {
        self.inner.info()
    }
    async fn set_target(&mut self, target_c: f64, ramp_c_s: Option<f64>) -> DeviceResult<()> {
        self.inner.set_target(target_c, ramp_c_s).await
    }
    async fn read(&mut self) -> DeviceResult<ChamberReading> {
        let mut r = self.inner.read().await?;
        self.apply(&mut r);
        Ok(r)
    }
}

#[async_trait::async_trait]
impl<D: Gyro> Gyro for Faulty<D, GyroSample> {
    fn info(&self) -> &DeviceInfo<GyroCapabilities> {
        self.inner.info()
    }
    async fn next_sample(&mut self) -> DeviceResult<GyroSample> {
        let mut s = self.inner.next_sample().await?;
        self.apply(&mut s);
        Ok(s)
    }
    fn sample_rate_hz(&self) -> f64 {
        self.inner.sample_rate_hz()
    }
}

/// Spin, heat slowly, record 20 min; `interlocks` is the scenario's `[interlocks]` body.
fn scenario(interlocks: &str) -> String {
    format!(
        "[scenario]\nname = \"interlocks\"\n[site]\nlatitude_deg = 45\n[interlocks]\n{interlocks}\n\
         [[step]]\nspin = \"10 °/min\"\ndirection = \"cw\"\n\
         [[step]]\nchamber = \"40 °C\"\nramp = \"1 °C/min\"\n\
         [[step]]\nlabel = \"record cw\"\nrecord = \"20 min\"\n"
    )
}

#[derive(Default)]
struct Edits {
    table: Option<Edit<TableReading>>,
    chamber: Option<Edit<ChamberReading>>,
    gyro: Option<Edit<GyroSample>>,
}

/// Run and return (fault, abort time, recording).
fn run(interlocks: &str, edits: Edits) -> (bench::run::Fault, Duration, Recording) {
    let text = scenario(interlocks);
    let plan = bench::scenario::parse(&text, "interlocks.toml", &capabilities()).expect("valid");
    let clock = VirtualClock::new();
    let shared: Arc<dyn Clock> = Arc::new(clock.clone());
    let sim = bench_sim::SimBench::new(sim_config(&plan, 3), shared.clone()).expect("sim");
    let (table, chamber, gyro) = sim.into_parts();
    let devices = bench::run::Devices {
        table: Box::new(Faulty { inner: table, clock: shared.clone(), edit: edits.table }),
        chamber: Box::new(Faulty { inner: chamber, clock: shared.clone(), edit: edits.chamber }),
        gyro: Box::new(Faulty { inner: gyro, clock: shared.clone(), edit: edits.gyro }),
    };
    let recorder = bench_recording::Recorder::new(
        Cursor::new(Vec::new()),
        bench::runner::run_info(&plan, SIM_EPOCH_NS),
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
    .expect("runs");
    let outcome = result.outcome();
    let fault = result.fault.clone().expect("the run aborted");
    let bytes = result.sink.finish(&outcome).expect("finished").into_inner();
    let rec = Recording::from_bytes(&bytes).expect("readable");
    assert_eq!(rec.outcome(), Some(outcome));
    let last = rec.steps.last().expect("steps");
    assert_eq!((last.msg.label.as_str(), last.msg.event.as_str()), ("record cw", "abort"));
    // The safe state: the table was commanded to rest.
    assert_eq!(rec.table.last().map(|t| t.msg.rate_command_rad_s), Some(0.0));
    (fault, Duration::from_nanos(last.log_time_ns - SIM_EPOCH_NS), rec)
}

fn assert_named(fault: &bench::run::Fault, rec: &Recording, name: &str) {
    assert_eq!(
        fault.cause,
        FaultCause::Interlock {
            name: match name {
                "table_overspeed" => bench::run::interlocks::TABLE_OVERSPEED,
                "rate_disagreement" => bench::run::interlocks::RATE_DISAGREEMENT,
                "chamber_over_temperature" => bench::run::interlocks::CHAMBER_OVER_TEMPERATURE,
                "chamber_under_temperature" => bench::run::interlocks::CHAMBER_UNDER_TEMPERATURE,
                "setpoint_not_tracked" => bench::run::interlocks::SETPOINT_NOT_TRACKED,
                _ => bench::run::interlocks::GYRO_STATUS,
            }
        }
    );
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 2 (record record cw)"), "{outcome}");
    assert!(outcome.contains(&format!(": {name}: ")), "{outcome}");
}

fn near(got: Duration, want: Duration) {
    let d = (got.as_secs_f64() - want.as_secs_f64()).abs();
    assert!(d <= 0.2, "tripped at {got:?}, expected {want:?}");
}

#[test]
fn an_overspeeding_table_trips_table_overspeed() {
    let (f, at, rec) = run(
        "table_max_rate = \"15 °/min\"",
        Edits { table: Some(Box::new(|r| r.rate_rad_s *= 2.0)), ..Edits::default() },
    );
    assert_named(&f, &rec, "table_overspeed");
    near(at, FAULT_AT);
}

#[test]
fn a_rate_leaving_its_command_trips_rate_disagreement_after_its_time() {
    let (f, at, rec) = run(
        "rate_disagreement_for = \"3 s\"",
        Edits {
            table: Some(Box::new(|r| r.rate_rad_s += 0.5f64.to_radians())),
            ..Edits::default()
        },
    );
    assert_named(&f, &rec, "rate_disagreement");
    near(at, FAULT_AT + Duration::from_secs(3));
}

#[test]
fn hot_and_cold_chamber_air_trip_the_temperature_interlocks() {
    let (f, at, rec) = run(
        "chamber_max_temp = \"45 °C\"",
        Edits { chamber: Some(Box::new(|r| r.temperature_c += 30.0)), ..Edits::default() },
    );
    assert_named(&f, &rec, "chamber_over_temperature");
    near(at, FAULT_AT);
    let (f, at, rec) = run(
        "chamber_min_temp = \"0 °C\"",
        Edits { chamber: Some(Box::new(|r| r.temperature_c -= 30.0)), ..Edits::default() },
    );
    assert_named(&f, &rec, "chamber_under_temperature");
    near(at, FAULT_AT);
}

#[test]
fn air_that_does_not_follow_its_set_point_trips_setpoint_not_tracked() {
    // From 120 s the air reads 3 °C below the working set point.
    let (f, at, rec) = run(
        "setpoint_tolerance = \"2 °C\"\nsetpoint_not_tracked_for = \"1 min\"",
        Edits {
            chamber: Some(Box::new(|r| r.temperature_c = r.setpoint_c - 3.0)),
            ..Edits::default()
        },
    );
    assert_named(&f, &rec, "setpoint_not_tracked");
    near(at, FAULT_AT + Duration::from_secs(60));
}

#[test]
fn a_gyro_failing_its_built_in_test_trips_gyro_status() {
    let (f, at, rec) = run(
        "gyro_status_for = \"2 s\"",
        Edits {
            gyro: Some(Box::new(|s| s.status |= bench_recording::status::gyro::BIT_FAIL)),
            ..Edits::default()
        },
    );
    assert_named(&f, &rec, "gyro_status");
    near(at, FAULT_AT + Duration::from_secs(2));
}

#[test]
fn the_same_run_without_faults_completes() {
    let text = scenario("");
    let plan = bench::scenario::parse(&text, "interlocks.toml", &capabilities()).expect("valid");
    let (report, _) = bench::runner::simulate_in_memory(&plan, 3).expect("runs");
    assert!(report.completed(), "{}", report.outcome);
}
