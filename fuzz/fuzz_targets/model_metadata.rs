//! A recording's nominal model (`bench.gyro_model` metadata: the contract keys and `effect.*`
//! keys, as `bench model`, `bench calibrate` and `bench diagnose` read it): arbitrary
//! `key=value` lines never panic; a model that parses is finite.
#![no_main]

use std::collections::BTreeMap;

use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let meta: BTreeMap<String, String> = text
        .lines()
        .map(|l| match l.split_once('=') {
            Some((k, v)) => (k.to_string(), v.to_string()),
            None => (l.to_string(), String::new()),
        })
        .collect();
    if let Ok((m, _extra)) = GyroModel::from_metadata(&meta) {
        assert!(m.bias.is_finite() && m.arw.is_finite() && m.thermal_time_constant.is_finite());
    }
    let _ = Effects::from_metadata(&meta);
});
