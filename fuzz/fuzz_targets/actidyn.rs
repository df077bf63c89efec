//! Actidyn command and reply decoders: arbitrary bytes in arbitrary pieces never panic, and
//! whatever parses re-encodes to something that parses to the same value.
#![no_main]

use bench_drivers::protocol::actidyn::{
    encode_commands, encode_replies, parse_command_line, parse_reply_line, CommandDecoder,
    ReplyDecoder,
};
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
                if let Ok(line) = encode_commands(&c) {
                    let again = parse_command_line(line.strip_suffix(b"\n").unwrap_or(&line));
                    assert_eq!(again.ok(), Some(c));
                }
            }
        }
        while let Some(r) = replies.next_message() {
            if let Ok(rs) = r {
                if let Ok(line) = encode_replies(&rs) {
                    let again = parse_reply_line(line.strip_suffix(b"\n").unwrap_or(&line));
                    assert_eq!(again.ok(), Some(rs));
                }
            }
        }
    }
});
