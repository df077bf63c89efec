//! Gyro CAN frame decoding and sample assembly over arbitrary SLCAN traffic never panic.
#![no_main]

use bench_drivers::protocol::gyro_can::{GyroCanFrame, GyroCanIds, SampleAssembler};
use bench_drivers::protocol::slcan::{AdapterMessage, HostDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let ids = GyroCanIds {
        delta_angle: 0x10,
        housekeeping: 0x11,
        info: 0x12,
        extended: false,
    };
    let mut asm = SampleAssembler::new(ids, 0.05);
    let mut d = HostDecoder::new();
    d.push(data);
    while let Some(r) = d.next_message() {
        if let Ok(AdapterMessage::Received { frame, .. }) = r {
            if let Ok(Some(f)) = GyroCanFrame::decode(&ids, &frame) {
                assert_eq!(f.encode(&ids).ok(), Some(frame));
            }
            if let Some(Ok(s)) = asm.push(&frame) {
                assert!(s.interval_s > 0.0);
            }
        }
    }
});
