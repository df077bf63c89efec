//! Recording reader: arbitrary bytes (truncated, corrupt or foreign files) never panic; an error
//! or a cut names where reading stopped, inside the input.
#![no_main]

use bench_recording::Recording;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(rec) = Recording::from_bytes(data) {
        if let Some((at, _reason)) = &rec.cut {
            assert!(*at <= data.len() as u64);
        }
        let _ = rec.outcome();
    }
    let _ = bench_recording::info_from_reader(bench_recording::RecordingReader::new(data));
});
