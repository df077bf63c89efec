//! KVH 1750 decoder never panics; every frame it accepts has a valid CRC and re-encodes to
//! bytes that decode to the same frame.
#![no_main]

use bench_drivers::protocol::kvh1750::{Decoder, Frame};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let split = data.first().map_or(0, |b| usize::from(*b)).min(data.len());
    let (a, b) = data.split_at(split);
    let mut d = Decoder::new();
    for piece in [a, b] {
        d.push(piece);
        while let Some(r) = d.next_frame() {
            if let Ok(f) = r {
                let again = Frame::decode(&f.encode()).ok();
                // NaN payloads compare unequal: compare the bytes instead.
                assert_eq!(again.map(|g| g.encode()), Some(f.encode()));
            }
        }
    }
});
