//! Bench config parser (`--bench CONFIG`: device sections with their drivers' settings, Modbus
//! register maps, limits, site, acceptance; or a `[replay]`): arbitrary text never panics;
//! every error names the file with a line and column inside the text; every config that parses
//! gives its limits, station, site and simulated effects without panicking.
#![no_main]

use bench::bench_config::{BenchSource, ConfigError};
use libfuzzer_sys::fuzz_target;

fn check(e: &ConfigError, text: &str) {
    match e {
        ConfigError::Invalid { file, line, column, .. } => {
            assert_eq!(file, "fuzz.toml");
            assert!(*line >= 1 && *line <= text.lines().count().max(1) + 1);
            assert!(*column >= 1);
            assert!(e.to_string().starts_with("fuzz.toml:"));
        }
        ConfigError::Several(v) => {
            assert!(!v.is_empty());
            for e in v {
                assert!(matches!(e, ConfigError::Invalid { .. }));
                check(e, text);
            }
        }
        other => panic!("parsing gave an unlocated error: {other}"),
    }
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match BenchSource::parse(&text, "fuzz.toml") {
        Err(e) => check(&e, &text),
        Ok(BenchSource::Devices(cfg)) => {
            let _ = cfg.limits();
            let _ = cfg.station();
            let _ = cfg.site();
            let _ = cfg.sim_effects();
            let _ = cfg.is_simulated();
            let _ = cfg.to_toml();
        }
        Ok(BenchSource::Replay(_)) => {}
    }
});
