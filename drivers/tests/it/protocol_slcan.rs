//! SLCAN codec, both directions, and the gyro CAN frame set carried over it.
#![allow(clippy::unwrap_used)]

use bench_drivers::protocol::gyro_can::{
    DeltaAngle, GyroCanFrame, GyroCanIds, Housekeeping, Info, SampleAssembler, ANGLE_LSB_RAD,
    DELTA_MAX, DELTA_MIN,
};
use bench_drivers::protocol::slcan::{
    AdapterDecoder, AdapterMessage, Bitrate, CanFrame, CanId, HostCommand, HostDecoder,
};
use proptest::prelude::*;

fn std_id(id: u16) -> CanId {
    CanId::standard(id).unwrap()
}

#[test]
fn host_commands_byte_exact() {
    let cases: Vec<(HostCommand, &[u8])> = vec![
        (HostCommand::SetBitrate(Bitrate::K500), b"S6\r"),
        (HostCommand::SetBitrate(Bitrate::K10), b"S0\r"),
        (HostCommand::SetBitrate(Bitrate::M1), b"S8\r"),
        (HostCommand::Open, b"O\r"),
        (HostCommand::ListenOnly, b"L\r"),
        (HostCommand::Close, b"C\r"),
        (HostCommand::ReadStatus, b"F\r"),
        (HostCommand::Version, b"V\r"),
        (HostCommand::SerialNumber, b"N\r"),
        (HostCommand::Timestamps(true), b"Z1\r"),
        (HostCommand::Timestamps(false), b"Z0\r"),
        (HostCommand::Transmit(CanFrame::new_data(std_id(0x7FF), &[]).unwrap()), b"t7FF0\r"),
        (
            HostCommand::Transmit(
                CanFrame::new_data(
                    CanId::extended(0x1234_5678).unwrap(),
                    &[0xDE, 0xAD, 0xBE, 0xEF],
                )
                .unwrap(),
            ),
            b"T123456784DEADBEEF\r",
        ),
        (HostCommand::Transmit(CanFrame::new_remote(std_id(0x100), 8).unwrap()), b"r1008\r"),
        (
            HostCommand::Transmit(
                CanFrame::new_remote(CanId::extended(0x1FFF_FFFF).unwrap(), 2).unwrap(),
            ),
            b"R1FFFFFFF2\r",
        ),
    ];
    let mut dec = AdapterDecoder::new();
    for (cmd, bytes) in &cases {
        assert_eq!(cmd.encode(), *bytes, "{cmd:?}");
        dec.push(bytes);
        assert_eq!(dec.next_message().unwrap().unwrap(), *cmd);
    }
    assert_eq!(Bitrate::K500.bits_per_s(), 500_000);
    assert_eq!(Bitrate::from_bits_per_s(125_000), Some(Bitrate::K125));
}

#[test]
fn adapter_messages_byte_exact() {
    let f = CanFrame::new_data(std_id(0x123), &[0x11, 0x22]).unwrap();
    let cases: Vec<(AdapterMessage, &[u8])> = vec![
        (AdapterMessage::Ok, b"\r"),
        (AdapterMessage::Error, b"\x07"),
        (AdapterMessage::TransmitAck { extended: false }, b"z\r"),
        (AdapterMessage::TransmitAck { extended: true }, b"Z\r"),
        (AdapterMessage::Status(0xA5), b"FA5\r"),
        (AdapterMessage::Version { hardware: 0x10, software: 0x13 }, b"V1013\r"),
        (AdapterMessage::Serial(*b"A123"), b"NA123\r"),
        (AdapterMessage::Received { frame: f, timestamp_ms: None }, b"t12321122\r"),
        (AdapterMessage::Received { frame: f, timestamp_ms: Some(0xEA5F) }, b"t12321122EA5F\r"),
    ];
    let mut dec = HostDecoder::new();
    for (m, bytes) in &cases {
        assert_eq!(m.encode(), *bytes, "{m:?}");
        dec.push(bytes);
        assert_eq!(dec.next_message().unwrap().unwrap(), *m);
        assert!(dec.next_message().is_none());
    }
}

#[test]
fn partial_input_and_errors_with_offsets() {
    let mut dec = HostDecoder::new();
    dec.push(b"t1232112");
    assert!(dec.next_message().is_none());
    dec.push(b"2\rt12G0\rt1239\rxx\x07z\r");
    assert!(dec.next_message().unwrap().is_ok());
    // "t12G0" starts at 10; the bad hex digit is at 10 + 3.
    let e = dec.next_message().unwrap().unwrap_err();
    assert_eq!((e.offset, e.received.as_slice()), (13, &b"G"[..]));
    // DLC 9 at 16 + 4.
    let e = dec.next_message().unwrap().unwrap_err();
    assert_eq!(e.offset, 20);
    // Junk before a BEL is reported, then the BEL itself still arrives.
    let e = dec.next_message().unwrap().unwrap_err();
    assert_eq!((e.offset, e.received.as_slice()), (22, &b"xx"[..]));
    assert_eq!(dec.next_message().unwrap().unwrap(), AdapterMessage::Error);
    assert_eq!(
        dec.next_message().unwrap().unwrap(),
        AdapterMessage::TransmitAck { extended: false }
    );
    // Wrong data length for the DLC.
    assert!(AdapterMessage::parse(b"t123211").is_err());
    assert!(HostCommand::parse(b"S9").is_err());
    assert!(HostCommand::parse(b"t800").is_err(), "11-bit id above 0x7FF");
    assert!(CanFrame::new_data(std_id(1), &[0; 9]).is_err());
    assert!(CanId::standard(0x800).is_none());
    assert!(CanId::extended(0x2000_0000).is_none());
}

#[test]
fn adapter_side_skips_empty_commands() {
    let mut dec = AdapterDecoder::new();
    dec.push(b"\r\r\rS6\rO\r");
    assert_eq!(dec.next_message().unwrap().unwrap(), HostCommand::SetBitrate(Bitrate::K500));
    assert_eq!(dec.next_message().unwrap().unwrap(), HostCommand::Open);
}

fn any_id() -> impl Strategy<Value = CanId> {
    prop_oneof![
        (0u16..=0x7FF).prop_map(CanId::Standard),
        (0u32..=0x1FFF_FFFF).prop_map(CanId::Extended)
    ]
}

fn any_frame() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (any_id(), proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::new_data(id, &d).unwrap()),
        (any_id(), 0u8..=8).prop_map(|(id, n)| CanFrame::new_remote(id, n).unwrap()),
    ]
}

proptest! {
    #[test]
    fn received_frames_roundtrip(frames in proptest::collection::vec((any_frame(), proptest::option::of(any::<u16>())), 1..8), split in 0usize..300) {
        let msgs: Vec<AdapterMessage> = frames.into_iter()
            .map(|(frame, timestamp_ms)| AdapterMessage::Received { frame, timestamp_ms })
            .collect();
        let bytes: Vec<u8> = msgs.iter().flat_map(|m| m.encode()).collect();
        let split = split.min(bytes.len());
        let mut dec = HostDecoder::new();
        let mut got = Vec::new();
        dec.push(&bytes[..split]);
        while let Some(r) = dec.next_message() { got.push(r.unwrap()) }
        dec.push(&bytes[split..]);
        while let Some(r) = dec.next_message() { got.push(r.unwrap()) }
        prop_assert_eq!(got, msgs);
    }

    #[test]
    fn host_commands_roundtrip(frame in any_frame()) {
        let cmd = HostCommand::Transmit(frame);
        prop_assert_eq!(HostCommand::parse(cmd.encode().strip_suffix(b"\r").unwrap()).unwrap(), cmd);
    }

    #[test]
    fn gyro_can_roundtrip(seq in any::<u32>(), counts in DELTA_MIN..=DELTA_MAX, status in any::<u16>(), temp in any::<i16>(), period in 1u32..) {
        let ids = GyroCanIds::default();
        let frames = [
            GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: seq as u8, counts }),
            GyroCanFrame::Housekeeping(Housekeeping { seq, status, temp_centi_c: temp }),
            GyroCanFrame::Info(Info { sample_period_ns: period, angle_lsb_exp: 40, version: 1 }),
        ];
        for f in frames {
            let can = f.encode(&ids).unwrap();
            prop_assert_eq!(GyroCanFrame::decode(&ids, &can).unwrap(), Some(f));
        }
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut h = HostDecoder::new();
        h.push(&bytes);
        while h.next_message().is_some() {}
        let mut a = AdapterDecoder::new();
        a.push(&bytes);
        while a.next_message().is_some() {}
    }
}

#[test]
fn gyro_can_frames_byte_exact() {
    let ids = GyroCanIds::default();
    // Delta angle of -1 LSB, sequence 0x1234_56AB.
    let a = GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: 0xAB, counts: -1 }).encode(&ids).unwrap();
    assert_eq!(a.id(), std_id(0x180));
    assert_eq!(a.data(), &[0xAB, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]);
    // 1 µrad = 1e-6 × 2^40 LSB = 1_099_511.6 → 1_099_512 = 0x10C6F8.
    let d = DeltaAngle::from_rad(0x1234_56AB, 1e-6).unwrap();
    assert_eq!(d.counts, 1_099_512);
    let c = GyroCanFrame::DeltaAngle(d).encode(&ids).unwrap();
    assert_eq!(c.data(), &[0xAB, 0xF8, 0xC6, 0x10, 0, 0, 0, 0]);
    let h = GyroCanFrame::Housekeeping(Housekeeping {
        seq: 0x1234_56AB,
        status: 0x0102,
        temp_centi_c: -4000,
    })
    .encode(&ids)
    .unwrap();
    assert_eq!(h.id(), std_id(0x181));
    assert_eq!(h.data(), &[0xAB, 0x56, 0x34, 0x12, 0x02, 0x01, 0x60, 0xF0]);
    let i =
        GyroCanFrame::Info(Info { sample_period_ns: 50_000_000, angle_lsb_exp: 40, version: 1 })
            .encode(&ids)
            .unwrap();
    assert_eq!(i.data(), &[0x80, 0xF0, 0xFA, 0x02, 40, 1, 0, 0]);
    // Over SLCAN.
    assert_eq!(HostCommand::Transmit(h).encode(), b"t1818AB563412020160F0\r");
}

#[test]
fn gyro_can_resolution_and_range() {
    // Quantisation per 20 Hz sample, as a rate: well below 1e-8 rad/s.
    assert_eq!(ANGLE_LSB_RAD, 2f64.powi(-40));
    // 1e-8 rad/s (navigation-grade bias stability) over one 20 Hz sample is resolved by
    // hundreds of LSB: 5e-10 rad / 2^-40 rad ≈ 550.
    assert_eq!(DeltaAngle::from_rad(0, 1e-8 * 0.05).unwrap().counts, 550);
    // 500 °/s for a whole second fits.
    assert!(DeltaAngle::from_rad(0, 500f64.to_radians()).is_ok());
    assert!(DeltaAngle::from_rad(0, 40_000.0).is_err());
    assert!(DeltaAngle::from_rad(0, f64::NAN).is_err());
    assert!(Housekeeping::temp_from_c(400.0).is_err());
    assert_eq!(Housekeeping::temp_from_c(-40.004).unwrap(), -4000);
}

#[test]
fn assembler_pairs_by_sequence_in_either_order() {
    let ids = GyroCanIds {
        delta_angle: 0x1800_0001,
        housekeeping: 0x1800_0002,
        info: 0x1800_0003,
        extended: true,
    };
    let mut asm = SampleAssembler::new(ids, 0.05);
    let enc = |f: GyroCanFrame| f.encode(&ids).unwrap();
    // Info sets the interval to 1 ms.
    assert!(asm
        .push(&enc(GyroCanFrame::Info(Info {
            sample_period_ns: 1_000_000,
            angle_lsb_exp: 40,
            version: 1
        })))
        .is_none());
    assert_eq!(asm.interval_s(), 1e-3);
    // Housekeeping first, then delta angle.
    assert!(asm
        .push(&enc(GyroCanFrame::Housekeeping(Housekeeping {
            seq: 300,
            status: 0,
            temp_centi_c: 100
        })))
        .is_none());
    let s = asm
        .push(&enc(GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: 44, counts: 1 << 30 })))
        .unwrap()
        .unwrap();
    assert_eq!(s.seq, 300);
    assert_eq!(s.delta_angle_rad, 2f64.powi(-10));
    assert_eq!(s.rate_rad_s, 2f64.powi(-10) / 1e-3);
    assert_eq!(s.temp_c, 1.0);
    let g = s.to_gyro_sample();
    assert_eq!((g.seq, g.status, g.temperature_c), (300, 0, Some(1.0)));
    // A lost housekeeping frame: the stale delta angle is reported when the next one comes.
    assert!(asm
        .push(&enc(GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: 45, counts: 0 })))
        .is_none());
    let e = asm
        .push(&enc(GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: 46, counts: 0 })))
        .unwrap()
        .unwrap_err();
    assert_eq!(e.received, vec![45]);
    let s = asm
        .push(&enc(GyroCanFrame::Housekeeping(Housekeeping {
            seq: 302,
            status: 1,
            temp_centi_c: 0,
        })))
        .unwrap()
        .unwrap();
    assert_eq!(s.seq, 302);
    assert_eq!(s.to_gyro_sample().status, bench_recording::status::gyro::INVALID);
    // Foreign ids are ignored; a short frame with our id is an error at its length.
    assert!(asm.push(&CanFrame::new_data(std_id(0x7), &[1]).unwrap()).is_none());
    let short = CanFrame::new_data(CanId::extended(0x1800_0001).unwrap(), &[1, 2, 3]).unwrap();
    assert_eq!(asm.push(&short).unwrap().unwrap_err().offset, 3);
}

/// Issue 17: an independent peer's 2506 (0.01 °C) is 25.06 °C, the nearest double, as Python's
/// `2506 / 100` gives (bench multiplied by 0.01 and read 25.060000000000002).
#[test]
fn issue17_housekeeping_temperature_is_the_nearest_double() {
    use bench_drivers::protocol::gyro_can::Housekeeping;
    for centi in [2506_i16, -4000, 1, -1, 12345, i16::MAX, i16::MIN] {
        let h = Housekeeping { seq: 0, status: 0, temp_centi_c: centi };
        assert_eq!(h.temp_c(), f64::from(centi) / 100.0);
    }
    assert_eq!(Housekeeping { seq: 0, status: 0, temp_centi_c: 2506 }.temp_c(), 25.06);
}
