//! What `bench replay`, `bench calibrate` and `bench diagnose` make of a recording that reads:
//! the replay's device streams, the analysis arrays and the recorded model. Arbitrary bytes
//! (in practice: mutated recordings) never panic.
#![no_main]

use bench_recording::Recording;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(rec) = Recording::from_bytes(data) else { return };
    let _ = bench::replay::ReplayData::from_recording(&rec, "fuzz.mcap");
    let _ = bench_report::load::recorded_model(&rec);
    let _ = bench_report::load::load(&rec);
});
