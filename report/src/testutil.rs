//! A synthetic recording for the reports' tests, written here from closed-form physics (not by
//! bench's simulator): per direction (CW, then CCW) a 3 min plateau at 20 °C, a recorded ramp to
//! 30 °C at 1 °C/min, a 3 min plateau at 30 °C after a soak, and a return to 20 °C. Gyro at
//! 20 Hz with white noise, table at 10 Hz with its angle on the 1″ grid, chamber at 1 Hz; the
//! gyro's own sensor lags the air by 120 s.

use std::io::Cursor;
use std::time::Duration;

use bench_physics::GyroModel;
use bench_recording::{
    ChamberMsg, GyroMsg, Outcome, Recorder, Recording, RunInfo, Site, StepEvent, TableMsg,
};

/// The gyro's truth, recorded as `bench.gyro_model`.
pub(crate) fn truth() -> GyroModel {
    GyroModel {
        bias: 5e-8,
        scale_factor_error: 3e-5,
        reference_temperature: 20.0,
        temp_coeff: 2e-9,
        temp_rate_coeff: 3e-5,
        arw: 3e-7,
        bias_instability: 0.0,
        earth_rate: true,
        thermal_time_constant: 0.0,
    }
}

/// Site latitude, degrees north.
pub(crate) const LATITUDE_DEG: f64 = 59.94;

/// Deterministic standard normal numbers (xorshift64* and Box–Muller).
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// What the procedure does over one interval.
#[derive(Clone, Copy)]
struct Leg {
    name: &'static str,
    label: &'static str,
    seconds: f64,
    /// Chamber set point at the leg's end (ramped linearly over the leg).
    setpoint_end_c: f64,
    /// Table rate command over the leg, in units of 10 °/min times the direction's sign.
    spin: f64,
}

fn legs(dir: &'static str) -> Vec<Leg> {
    let (r20, ramp, r30) = match dir {
        "cw" => ("record cw 20C", "record cw ramp 20C to 30C", "record cw 30C"),
        _ => ("record ccw 20C", "record ccw ramp 20C to 30C", "record ccw 30C"),
    };
    vec![
        Leg { name: "spin", label: "spin", seconds: 20.0, setpoint_end_c: 20.0, spin: 1.0 },
        Leg { name: "record", label: r20, seconds: 180.0, setpoint_end_c: 20.0, spin: 1.0 },
        Leg { name: "record", label: ramp, seconds: 600.0, setpoint_end_c: 30.0, spin: 1.0 },
        Leg { name: "wait", label: "soak 30C", seconds: 900.0, setpoint_end_c: 30.0, spin: 1.0 },
        Leg { name: "record", label: r30, seconds: 180.0, setpoint_end_c: 30.0, spin: 1.0 },
        Leg { name: "stop", label: "stop", seconds: 20.0, setpoint_end_c: 30.0, spin: 0.0 },
        Leg { name: "chamber", label: "to 20C", seconds: 120.0, setpoint_end_c: 20.0, spin: 0.0 },
        Leg { name: "wait", label: "soak 20C", seconds: 900.0, setpoint_end_c: 20.0, spin: 0.0 },
    ]
}

/// The synthetic run, recorded in memory.
pub(crate) fn short_run() -> Recording {
    Recording::from_bytes(&short_run_bytes()).expect("readable")
}

/// The synthetic run's file.
pub(crate) fn short_run_bytes() -> Vec<u8> {
    let m = truth();
    let dt = 0.05;
    let omega0 = 10f64.to_radians() / 60.0;
    let accel = 1f64.to_radians();
    let earth = 7.292_115e-5 * LATITUDE_DEG.to_radians().sin();
    let arcsec = 1f64.to_radians() / 3600.0;
    let mut info = RunInfo::new(
        1_767_225_600_000_000_000,
        "report-test",
        "",
        Site::at_latitude(LATITUDE_DEG),
        m.to_metadata(),
    );
    // This function is the simulator: its model is the data's truth.
    info.gyro_model_role = bench_recording::ModelRole::Simulation;
    let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("recorder starts");
    let mut noise = Normal(0x9e37_79b9_7f4a_7c15);
    let (mut air, mut coil, mut rate, mut angle) = (20.0f64, 20.0f64, 0.0f64, 0.0f64);
    let mut setpoint = 20.0f64;
    let mut prev_coil = coil;
    let mut k: u64 = 0;
    let mut index = 0u64;
    for (sign, dir) in [(-1.0, "cw"), (1.0, "ccw")] {
        for leg in legs(dir) {
            let t_start = Duration::from_nanos(k * 50_000_000);
            r.step(t_start, index, leg.name, StepEvent::Start, leg.label).expect("step");
            let sp0 = setpoint;
            let n = (leg.seconds / dt).round() as u64;
            for i in 1..=n {
                k += 1;
                let t = Duration::from_nanos(k * 50_000_000);
                setpoint = sp0 + (leg.setpoint_end_c - sp0) * i as f64 / n as f64;
                air += (setpoint - air) * dt / 60.0;
                coil += (air - coil) * dt / 120.0;
                let command = sign * leg.spin * omega0;
                rate += (command - rate).clamp(-accel * dt, accel * dt);
                angle += rate * dt;
                let dtdt = (coil - prev_coil) / dt;
                prev_coil = coil;
                let v = (1.0 + m.scale_factor_error) * (rate + earth)
                    + m.bias
                    + m.temp_coeff * (coil - m.reference_temperature)
                    + m.temp_rate_coeff * dtdt
                    + m.arw / dt.sqrt() * noise.next();
                let g = GyroMsg {
                    rate_rad_s: v,
                    temperature_c: Some((coil * 100.0).round() / 100.0),
                    seq: k,
                    status: 0,
                };
                r.gyro(t, None, &g).expect("gyro");
                if k.is_multiple_of(2) {
                    let tm = TableMsg {
                        angle_rad: (angle / arcsec).round() * arcsec,
                        rate_rad_s: rate,
                        rate_command_rad_s: command,
                        status: 0,
                    };
                    r.table(t, None, &tm).expect("table");
                }
                if k.is_multiple_of(20) {
                    let c = ChamberMsg {
                        temperature_c: (air * 10.0).round() / 10.0,
                        setpoint_c: setpoint,
                        status: 0,
                    };
                    r.chamber(t, None, &c).expect("chamber");
                }
            }
            let t_end = Duration::from_nanos(k * 50_000_000);
            r.step(t_end, index, leg.name, StepEvent::End, leg.label).expect("step");
            index += 1;
        }
    }
    r.finish(&Outcome::Completed).expect("finished").into_inner()
}
