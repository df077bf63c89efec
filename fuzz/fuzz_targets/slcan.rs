//! SLCAN host-side and adapter-side decoders never panic; parsed messages re-encode to bytes
//! that parse to the same message.
#![no_main]

use bench_drivers::protocol::slcan::{AdapterDecoder, AdapterMessage, HostCommand, HostDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let split = data.first().map_or(0, |b| usize::from(*b)).min(data.len());
    let (a, b) = data.split_at(split);
    let mut host = HostDecoder::new();
    let mut adapter = AdapterDecoder::new();
    for piece in [a, b] {
        host.push(piece);
        adapter.push(piece);
        while let Some(r) = host.next_message() {
            if let Ok(m) = r {
                let bytes = m.encode();
                let mut d = HostDecoder::new();
                d.push(&bytes);
                assert_eq!(d.next_message().and_then(Result::ok), Some(m));
            }
        }
        while let Some(r) = adapter.next_message() {
            if let Ok(c) = r {
                let bytes = c.encode();
                let again = HostCommand::parse(bytes.strip_suffix(b"\r").unwrap_or(&bytes));
                assert_eq!(again.ok(), Some(c));
            }
        }
    }
    let _ = AdapterMessage::parse(data);
});
