//! Run-time interlocks end to end on the simulated bench (virtual time): a fault injected into
//! a device's readings from 120 s of bench time on trips its named interlock, the run aborts
//! to the safe state, and the recording ends with an `abort` step event and an `outcome` that
//! names the interlock. The devices' own fault reports (drive alarm, drive off, interlock,
//! mode, chamber alarm and door, gyro built-in test) trip within one poll period.

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
    use bench::run::interlocks as il;
    let names = [
        il::TABLE_OVERSPEED,
        il::RATE_DISAGREEMENT,
        il::CHAMBER_OVER_TEMPERATURE,
        il::CHAMBER_UNDER_TEMPERATURE,
        il::SETPOINT_NOT_TRACKED,
        il::GYRO_STATUS,
    ];
    let constant = names
        .into_iter()
        .chain(il::DEVICE_REPORTS)
        .find(|n| *n == name)
        .unwrap_or_else(|| panic!("no interlock named {name}"));
    assert_eq!(fault.cause, FaultCause::Interlock { name: constant });
    let outcome = rec.outcome_text().unwrap_or_default().to_string();
    assert!(outcome.starts_with("aborted: step 2 (record cw)"), "{outcome}");
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
fn a_gyro_flagging_its_samples_invalid_trips_gyro_status_after_its_time() {
    let (f, at, rec) = run(
        "gyro_status_for = \"2 s\"",
        Edits {
            gyro: Some(Box::new(|s| s.status |= bench_recording::status::gyro::INVALID)),
            ..Edits::default()
        },
    );
    assert_named(&f, &rec, "gyro_status");
    near(at, FAULT_AT + Duration::from_secs(2));
}

/// A device's own fault report trips its interlock at the first reading that shows it: within
/// one poll period (the table and chamber are polled at 20 Hz, the gyro streams at 20 Hz) of
/// [`FAULT_AT`]. The table is stopped (the safe state, checked by `run`), and every gyro sample
/// up to the abort is kept, its counter without a gap.
fn device_report(edits: Edits, name: &str) {
    let (f, at, rec) = run("", edits);
    assert_named(&f, &rec, name);
    let late = at.saturating_sub(FAULT_AT);
    assert!(at >= FAULT_AT && late <= Duration::from_millis(50), "tripped {late:?} after it");
    let abort_ns = rec.steps.last().map_or(0, |s| s.log_time_ns);
    let before = rec.gyro.iter().filter(|g| g.log_time_ns <= abort_ns).count();
    assert!(before >= 2390, "{before} gyro samples up to the abort");
    eprintln!("{name}: abort {late:?} after the fault, {before} gyro samples kept before it");
    assert!(rec.gyro.windows(2).all(|w| w[1].msg.seq == w[0].msg.seq + 1), "a counter gap");
}

#[test]
fn a_table_drive_alarm_trips_table_drive_fault_at_once() {
    use bench_recording::status::table::{ALARM, DRIVE_OFF};
    // The real Actidyn driver's reading when the controller switched the drive off.
    device_report(
        Edits {
            table: Some(Box::new(|r| {
                r.mode = bench_drivers::TableMode::Off;
                r.status |= DRIVE_OFF | ALARM;
            })),
            ..Edits::default()
        },
        "table_drive_fault",
    );
}

#[test]
fn a_table_drive_off_with_rate_commanded_trips_table_drive_fault() {
    // No alarm bit: the mode alone reads off while bench commanded rate mode.
    device_report(
        Edits {
            table: Some(Box::new(|r| r.mode = bench_drivers::TableMode::Off)),
            ..Edits::default()
        },
        "table_drive_fault",
    );
}

#[test]
fn an_open_table_interlock_trips_table_interlock_open() {
    device_report(
        Edits {
            table: Some(Box::new(|r| r.status |= bench_recording::status::table::INTERLOCK)),
            ..Edits::default()
        },
        "table_interlock_open",
    );
}

#[test]
fn a_table_leaving_rate_mode_trips_table_mode_lost() {
    device_report(
        Edits {
            table: Some(Box::new(|r| r.mode = bench_drivers::TableMode::Position)),
            ..Edits::default()
        },
        "table_mode_lost",
    );
}

#[test]
fn a_chamber_alarm_trips_chamber_alarm() {
    device_report(
        Edits {
            chamber: Some(Box::new(|r| r.status |= bench_recording::status::chamber::ALARM)),
            ..Edits::default()
        },
        "chamber_alarm",
    );
}

#[test]
fn an_open_chamber_door_trips_chamber_door_open() {
    device_report(
        Edits {
            chamber: Some(Box::new(|r| r.status |= bench_recording::status::chamber::DOOR_OPEN)),
            ..Edits::default()
        },
        "chamber_door_open",
    );
}

#[test]
fn a_gyro_failing_its_built_in_test_trips_gyro_bit_fail_at_once() {
    device_report(
        Edits {
            gyro: Some(Box::new(|s| s.status |= bench_recording::status::gyro::BIT_FAIL)),
            ..Edits::default()
        },
        "gyro_bit_fail",
    );
}

#[test]
fn the_same_run_without_faults_completes() {
    let text = scenario("");
    let plan = bench::scenario::parse(&text, "interlocks.toml", &capabilities()).expect("valid");
    let (report, _) = bench::runner::simulate_in_memory(&plan, 3).expect("runs");
    assert!(report.completed(), "{}", report.outcome);
}
