//! KVH DSP-3000 ASCII and binary codecs.
#![allow(clippy::unwrap_used)]

use bench_drivers::protocol::kvh_dsp3000::{
    parity_ok, AsciiDecoder, AsciiSample, BinaryDecoder, BinaryWord, DataType, VALUE_MAX, VALUE_MIN,
};
use proptest::prelude::*;

#[test]
fn ascii_line_byte_exact() {
    let s = AsciiSample { value: -0.012345, valid: true };
    assert_eq!(s.encode().unwrap(), b"  -0.012345 1\r\n");
    let s = AsciiSample { value: 123.4567891, valid: false };
    assert_eq!(s.encode().unwrap(), b" 123.456789 0\r\n");
    assert!(AsciiSample { value: f64::NAN, valid: true }.encode().is_err());
}

#[test]
fn ascii_decoder_partial_and_leading_junk() {
    let mut d = AsciiDecoder::new();
    // The port opened mid-line: "456 1\r\n" is the tail of a line.
    d.push(b"456 1\r\n  -0.0");
    let e = d.next_sample().unwrap().unwrap_err();
    assert_eq!(e.offset, 0);
    assert_eq!(e.received, b"456");
    assert!(d.next_sample().is_none());
    d.push(b"12345 1\r\n   1.000000 0\r\n");
    assert_eq!(d.next_sample().unwrap().unwrap(), AsciiSample { value: -0.012345, valid: true });
    assert_eq!(d.next_sample().unwrap().unwrap(), AsciiSample { value: 1.0, valid: false });
    assert!(d.next_sample().is_none());
}

#[test]
fn ascii_mid_stream_skips_the_first_partial_line() {
    let mut d = AsciiDecoder::mid_stream();
    // A tail that would parse as a sample on its own.
    d.push(b"3.456789 1\r\n   0.250000 1\r\n");
    assert_eq!(d.next_sample().unwrap().unwrap(), AsciiSample { value: 0.25, valid: true });
    assert!(d.next_sample().is_none());
}

#[test]
fn ascii_bad_flag_has_offset() {
    let mut d = AsciiDecoder::new();
    d.push(b"  0.500000 1\r\n  0.500000 x\r\n");
    d.next_sample().unwrap().unwrap();
    let e = d.next_sample().unwrap().unwrap_err();
    // Second line starts at 14; the flag is at 14 + 11.
    assert_eq!(e.offset, 25);
    assert_eq!(e.received, b"x");
}

#[test]
fn binary_word_layout_and_odd_parity() {
    // valid, sync 0, rate, value +1: 0x80000001 has two 1 bits -> parity bit set.
    let w = BinaryWord { valid: true, sync: 0, data_type: DataType::Rate, value: 1 };
    assert_eq!(w.encode(), [0x84, 0x00, 0x00, 0x01]);
    // valid, sync 2, incremental angle, value -2 (0x3FFFFFE).
    let w = BinaryWord { valid: true, sync: 2, data_type: DataType::IncrementalAngle, value: -2 };
    // 0xCBFFFFFE has 28 one bits, so the parity bit is set.
    assert_eq!(w.to_u32(), 0xCFFF_FFFE);
    assert!(parity_ok(0xCFFF_FFFE));
    assert!(!parity_ok(0xCBFF_FFFE));
    // The manual's rule: preset bit 26 to 1, then bit 26 = XOR of all 32 bits.
    for raw in [0x8000_0001u32, 0x0000_0000, 0xC800_1234, 0x13FF_FFFF] {
        let preset = raw | (1 << 26);
        let bit = preset.count_ones() % 2;
        let manual = (raw & !(1 << 26)) | (bit << 26);
        let ours = BinaryWord::from_u32(BinaryWord { ..word_of(raw) }.to_u32()).unwrap().to_u32();
        assert_eq!(ours, manual, "{raw:#010x}");
    }
    let w = BinaryWord::from_rate_deg_s(-60e-6 * 1000.0, 0).unwrap();
    assert_eq!(w.value, -1000);
    assert!((w.rate_rad_s().unwrap() + 0.06f64.to_radians()).abs() < 1e-15);
    assert!(BinaryWord::from_rate_deg_s(2100.0, 0).is_err());
}

/// A word with the fields of `raw` (parity ignored).
fn word_of(raw: u32) -> BinaryWord {
    BinaryWord::from_u32(if parity_ok(raw) { raw } else { raw ^ (1 << 26) }).unwrap()
}

fn rate_words(values: &[i32]) -> Vec<u8> {
    values
        .iter()
        .enumerate()
        .flat_map(|(i, &v)| {
            BinaryWord { valid: true, sync: (i % 4) as u8, data_type: DataType::Rate, value: v }
                .encode()
        })
        .collect()
}

#[test]
fn binary_decoder_finds_alignment_after_junk() {
    let mut bytes = vec![0x12, 0x34, 0x56];
    bytes.extend(rate_words(&[1, -1, 100, -100, 7]));
    let mut d = BinaryDecoder::new();
    d.push(&bytes);
    let e = d.next_word().unwrap().unwrap_err();
    assert_eq!(e.offset, 0);
    assert_eq!(e.received, vec![0x12, 0x34, 0x56]);
    let got: Vec<i32> = std::iter::from_fn(|| d.next_word()).map(|r| r.unwrap().value).collect();
    assert_eq!(got, vec![1, -1, 100, -100, 7]);
    assert!(d.is_locked());
}

#[test]
fn binary_parity_error_reports_offset_and_relocks() {
    let mut bytes = rate_words(&[1, 2, 3, 4, 5, 6, 7, 8]);
    bytes[4 * 5 + 3] ^= 0x01; // corrupt word 5
    let mut d = BinaryDecoder::new();
    // Feed in 3-byte pieces to exercise partial words.
    let mut out = Vec::new();
    for chunk in bytes.chunks(3) {
        d.push(chunk);
        while let Some(r) = d.next_word() {
            out.push(r.map(|w| w.value).map_err(|e| e.offset));
        }
    }
    assert_eq!(out, vec![Ok(1), Ok(2), Ok(3), Ok(4), Ok(5), Err(20), Ok(7), Ok(8)]);
}

#[test]
fn binary_sync_check_is_optional() {
    let bytes = rate_words(&[1, 2, 3, 4]); // sync bits 0,1,2,3
    let mut strict = BinaryDecoder::new().with_sync(0);
    strict.push(&bytes);
    strict.push(&bytes);
    // With sync counting 0..3 no 4-word window has constant sync 0: nothing is accepted.
    assert!(std::iter::from_fn(|| strict.next_word()).all(|r| r.is_err()));
}

proptest! {
    #[test]
    fn binary_roundtrip(values in proptest::collection::vec(VALUE_MIN..=VALUE_MAX, 4..40), split in 0usize..200) {
        let bytes = rate_words(&values);
        let split = split.min(bytes.len());
        let mut d = BinaryDecoder::new();
        let mut got = Vec::new();
        d.push(&bytes[..split]);
        while let Some(r) = d.next_word() { got.push(r.unwrap().value) }
        d.push(&bytes[split..]);
        while let Some(r) = d.next_word() { got.push(r.unwrap().value) }
        prop_assert_eq!(got, values);
    }

    #[test]
    fn ascii_roundtrip(micro in -999_999_999i64..999_999_999, valid in any::<bool>()) {
        let s = AsciiSample { value: micro as f64 / 1e6, valid };
        let mut d = AsciiDecoder::new();
        d.push(&s.encode().unwrap());
        prop_assert_eq!(d.next_sample().unwrap().unwrap(), s);
    }

    #[test]
    fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut b = BinaryDecoder::new();
        b.push(&bytes);
        while b.next_word().is_some() {}
        let mut a = AsciiDecoder::new();
        a.push(&bytes);
        while a.next_sample().is_some() {}
    }
}
