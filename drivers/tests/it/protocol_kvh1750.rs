//! KVH 1750/1775 format A codec against the ICD's sample frame.
#![allow(clippy::unwrap_used)]

use bench_drivers::protocol::kvh1750::{crc32_mpeg2, Decoder, Frame, FRAME_LEN};
use proptest::prelude::*;

/// The ICD 56-0298 sample message (bytes 0–31 as published in public driver test code), with
/// its CRC 0x4BFA34D8 appended.
const SAMPLE: [u8; FRAME_LEN] = [
    0xFE, 0x81, 0xFF, 0x55, 0x37, 0xA9, 0x6A, 0x6E, 0x38, 0x58, 0x6C, 0x1F, 0xB7, 0x5B, 0xF8, 0x62,
    0xBF, 0x80, 0x3E, 0x78, 0xBB, 0x65, 0x0D, 0x28, 0x3B, 0x0A, 0x37, 0xAC, 0x77, 0x3D, 0x00, 0x28,
    0x4B, 0xFA, 0x34, 0xD8,
];

fn sample_frame() -> Frame {
    Frame {
        gyro: [
            f32::from_bits(0x37A9_6A6E),
            f32::from_bits(0x3858_6C1F),
            f32::from_bits(0xB75B_F862),
        ],
        accel: [
            f32::from_bits(0xBF80_3E78),
            f32::from_bits(0xBB65_0D28),
            f32::from_bits(0x3B0A_37AC),
        ],
        status: 0x77,
        seq: 61,
        temp_c: 40,
    }
}

#[test]
fn icd_sample_crc_is_4bfa34d8() {
    assert_eq!(crc32_mpeg2(&SAMPLE[..32]), 0x4BFA_34D8);
    // The catalogue check value of CRC-32/MPEG-2.
    assert_eq!(crc32_mpeg2(b"123456789"), 0x0376_E6E7);
}

#[test]
fn icd_sample_decodes_to_published_fields() {
    let f = Frame::decode(&SAMPLE).unwrap();
    assert_eq!(f.status, 0x77);
    assert_eq!(f.seq, 61);
    assert_eq!(f.temp_c, 40);
    assert_eq!(f, sample_frame());
    // Plausible physical values: small delta angles (rad), accel ≈ -1 g on x.
    assert!((f.accel[0] + 1.0019).abs() < 1e-3, "{}", f.accel[0]);
    assert!(f.gyro.iter().all(|g| g.abs() < 1e-4));
    assert!((0..3).all(|a| f.gyro_valid(a) && f.accel_valid(a)));
}

#[test]
fn icd_sample_encodes_byte_exactly() {
    assert_eq!(sample_frame().encode(), SAMPLE);
}

#[test]
fn decoder_handles_byte_by_byte_input() {
    let mut d = Decoder::new();
    for (i, b) in SAMPLE.iter().chain(SAMPLE.iter()).enumerate() {
        d.push(&[*b]);
        match d.next_frame() {
            Some(r) => {
                assert!(i == FRAME_LEN - 1 || i == 2 * FRAME_LEN - 1, "frame at byte {i}");
                assert_eq!(r.unwrap(), sample_frame());
            }
            None => assert!(i != FRAME_LEN - 1 && i != 2 * FRAME_LEN - 1),
        }
    }
    assert!(d.next_frame().is_none());
}

#[test]
fn leading_junk_is_reported_then_skipped() {
    let mut d = Decoder::new();
    // Junk containing a partial header (FE 81) that is not followed by FF 55.
    d.push(&[0x01, 0xFE, 0x81, 0x00, 0x55]);
    d.push(&SAMPLE);
    let e = d.next_frame().unwrap().unwrap_err();
    assert_eq!(e.offset, 0);
    assert_eq!(e.received, vec![0x01, 0xFE, 0x81, 0x00, 0x55]);
    assert!(e.to_string().contains("5 bytes skipped"), "{e}");
    assert_eq!(d.next_frame().unwrap().unwrap(), sample_frame());
    assert!(d.next_frame().is_none());
}

#[test]
fn bad_crc_reports_offset_and_resynchronises() {
    let mut bad = SAMPLE;
    bad[10] ^= 0x01;
    let mut d = Decoder::new();
    d.push(&[0xAA, 0xBB]);
    d.push(&bad);
    d.push(&SAMPLE);
    let junk = d.next_frame().unwrap().unwrap_err();
    assert_eq!(junk.offset, 0);
    let crc = d.next_frame().unwrap().unwrap_err();
    // Frame starts at 2; the CRC field at 2 + 32.
    assert_eq!(crc.offset, 34);
    assert_eq!(crc.received, vec![0x4B, 0xFA, 0x34, 0xD8]);
    assert!(crc.to_string().contains("CRC"), "{crc}");
    // The rest of the bad frame is skipped silently, the good one follows.
    assert_eq!(d.next_frame().unwrap().unwrap(), sample_frame());
    assert!(d.next_frame().is_none());
}

#[test]
fn truncated_frame_waits_then_bad_sequence_is_rejected() {
    let mut d = Decoder::new();
    d.push(&SAMPLE[..35]);
    assert!(d.next_frame().is_none());
    let mut f = sample_frame();
    f.seq = 200;
    let e = Frame::decode(&f.encode()).unwrap_err();
    assert_eq!(e.offset, 29);
    assert!(Frame::decode(&SAMPLE[..20]).is_err());
}

#[test]
fn header_inside_a_corrupt_frame_does_not_swallow_the_next() {
    // A corrupted frame whose payload contains a header: the decoder must still find the
    // real frame that follows.
    let mut bad = SAMPLE;
    bad[8..12].copy_from_slice(&[0xFE, 0x81, 0xFF, 0x55]);
    let mut d = Decoder::new();
    d.push(&bad);
    d.push(&SAMPLE);
    let mut frames = 0;
    let mut errors = 0;
    while let Some(r) = d.next_frame() {
        match r {
            Ok(f) => {
                assert_eq!(f, sample_frame());
                frames += 1;
            }
            Err(_) => errors += 1,
        }
    }
    assert_eq!(frames, 1);
    assert!(errors >= 1);
}

fn any_frame() -> impl Strategy<Value = Frame> {
    let f = || any::<f32>().prop_filter("finite", |v| v.is_finite());
    ([f(), f(), f()], [f(), f(), f()], any::<u8>(), 0u8..=127, any::<i16>())
        .prop_map(|(gyro, accel, status, seq, temp_c)| Frame { gyro, accel, status, seq, temp_c })
}

proptest! {
    #[test]
    fn roundtrip(frames in proptest::collection::vec(any_frame(), 1..5), junk in proptest::collection::vec(0u8..0xFE, 0..10), split in 0usize..200) {
        let mut bytes = junk.clone();
        for f in &frames {
            bytes.extend_from_slice(&f.encode());
        }
        let split = split.min(bytes.len());
        let mut d = Decoder::new();
        d.push(&bytes[..split]);
        let mut got = Vec::new();
        while let Some(r) = d.next_frame() { if let Ok(f) = r { got.push(f) } }
        d.push(&bytes[split..]);
        while let Some(r) = d.next_frame() { if let Ok(f) = r { got.push(f) } }
        prop_assert_eq!(got, frames);
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut d = Decoder::new();
        d.push(&bytes);
        while d.next_frame().is_some() {}
    }
}
