//! `bench recover`: arbitrary bytes never panic; what it writes is a complete MCAP file that
//! the recording reader reads to its footer, and the break it reports lies inside the input.
#![no_main]

use std::io::Cursor;

use bench_recording::RecordingReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((report, out)) = bench_recording::recover::recover(data, Cursor::new(Vec::new())) {
        if let Some(b) = &report.break_at {
            assert!(b.at_byte <= data.len() as u64);
        }
        let bytes = out.into_inner();
        let mut reader = RecordingReader::new(&bytes[..]).raw();
        let n = reader.by_ref().filter(|i| i.is_ok()).count();
        assert!(n as u64 >= report.total_messages());
        assert_eq!(reader.end(), &bench_recording::End::Complete);
    }
});
