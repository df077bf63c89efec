//! Calibration-file parser (`bench calibrate`'s `calibration.toml`): arbitrary text never
//! panics; every parse error names the file with a line and column inside the text; every file
//! that parses gives a model with non-negative noise and lag that writes and parses back equal.
#![no_main]

use bench_recording::model_file::{CalibrationFile, ModelFileError};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match CalibrationFile::parse(&text, "fuzz.toml") {
        Err(ModelFileError::Parse { line, column, .. }) => {
            assert!(line >= 1 && line <= text.lines().count().max(1) + 1);
            assert!(column >= 1);
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.toml")),
        Ok(file) => {
            let m = file.model();
            assert!(m.arw >= 0.0 && m.bias_instability >= 0.0 && m.thermal_time_constant >= 0.0);
            let back = CalibrationFile::parse(&file.to_toml(), "again.toml").expect("round trip");
            assert_eq!(back.model(), m);
        }
    }
});
