//! DSP-3000 ASCII and binary decoders never panic; decoded binary words re-encode to the same
//! four bytes.
#![no_main]

use bench_drivers::protocol::kvh_dsp3000::{AsciiDecoder, BinaryDecoder, BinaryWord};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let split = data.first().map_or(0, |b| usize::from(*b)).min(data.len());
    let (a, b) = data.split_at(split);
    let mut bin = BinaryDecoder::new();
    let mut ascii = AsciiDecoder::mid_stream();
    for piece in [a, b] {
        bin.push(piece);
        ascii.push(piece);
        while let Some(r) = bin.next_word() {
            if let Ok(w) = r {
                assert_eq!(BinaryWord::from_u32(w.to_u32()).ok(), Some(w));
            }
        }
        while ascii.next_sample().is_some() {}
    }
});
