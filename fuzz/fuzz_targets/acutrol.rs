//! ACUTROL command and reply decoders never panic; parsed commands re-encode losslessly in the
//! long form.
#![no_main]

use bench_drivers::protocol::acutrol::{parse_command, CommandDecoder, Encoding, ReplyDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let split = data.first().map_or(0, |b| usize::from(*b)).min(data.len());
    let (a, b) = data.split_at(split);
    let mut cmds = CommandDecoder::new();
    let mut replies = ReplyDecoder::new();
    for piece in [a, b] {
        cmds.push(piece);
        replies.push(piece);
        while let Some(r) = cmds.next_message() {
            if let Ok(c) = r {
                // Values are re-encoded with 6 decimals, so only the path and axis must survive.
                if let Ok(line) = c.encode(Encoding::default()) {
                    let again = parse_command(line.strip_suffix(b"\r\n").unwrap_or(&line));
                    assert!(again.is_ok());
                }
            }
        }
        while replies.next_message().is_some() {}
    }
});
