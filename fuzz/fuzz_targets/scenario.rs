//! Scenario parser: arbitrary text never panics; every error is located inside the text; every
//! plan that validates respects the capabilities it was checked against.
#![no_main]

use bench::plan::Action;
use bench::scenario::{parse, Capabilities};
use bench_drivers::{ChamberCapabilities, DeviceInfo, GyroCapabilities, TableCapabilities};
use libfuzzer_sys::fuzz_target;

fn caps() -> Capabilities {
    let info = |m: &str| (m.to_string(), "fuzz".to_string());
    let (tm, td) = info("table");
    let (cm, cd) = info("chamber");
    let (gm, gd) = info("gyro");
    Capabilities {
        table: DeviceInfo {
            model: tm,
            driver: td,
            capabilities: TableCapabilities {
                max_rate_rad_s: 17.453_292_519_943_297,
                max_accel_rad_s2: 17.453_292_519_943_297,
                position_resolution_rad: 4.8481e-6,
            },
        },
        chamber: DeviceInfo {
            model: cm,
            driver: cd,
            capabilities: ChamberCapabilities {
                min_temp_c: -55.0,
                max_temp_c: 185.0,
                max_heat_rate_c_s: 5.0 / 60.0,
                max_cool_rate_c_s: 3.5 / 60.0,
                temp_resolution_c: 0.01,
            },
        },
        gyro: DeviceInfo {
            model: gm,
            driver: gd,
            capabilities: GyroCapabilities {
                sample_rates_hz: vec![1.0, 20.0, 2000.0],
                max_rate_rad_s: 8.726_646_259_971_648,
                operating_temp_c: (-40.0, 60.0),
                has_temperature: true,
            },
        },
    }
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let caps = caps();
    match parse(&text, "fuzz.toml", &caps) {
        Err(errors) => {
            assert!(!errors.is_empty());
            for e in errors.iter() {
                assert!(e.span.start <= text.len());
                assert!(e.line >= 1 && e.column >= 1);
                assert!(e.to_string().starts_with("fuzz.toml:"));
            }
        }
        Ok(plan) => {
            let (glo, ghi) = caps.gyro.capabilities.operating_temp_c;
            for (i, s) in plan.steps.iter().enumerate() {
                assert_eq!(s.index, i);
                assert_eq!(bench_recording::message::is_record_label(&s.label), s.name == "record");
                match s.action {
                    Action::Chamber { target_c, ramp_c_s } => {
                        assert!((glo..=ghi).contains(&target_c));
                        assert!(ramp_c_s.is_none_or(|r| r > 0.0));
                    }
                    Action::Table { rate_rad_s, accel_rad_s2, .. } => {
                        assert!(rate_rad_s.abs() <= caps.table.capabilities.max_rate_rad_s);
                        assert!(accel_rad_s2 > 0.0);
                    }
                    _ => {}
                }
            }
        }
    }
});
