//! KVH 1750/1775 IMU, normal-mode message format A (ICD 56-0298), 36 bytes big-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 0–3 | header `FE 81 FF 55` |
//! | 4–15 | gyro x, y, z: IEEE float32 (delta angle or rate, rad or °; default delta angle rad) |
//! | 16–27 | accelerometer x, y, z: IEEE float32, g |
//! | 28 | status: bits 0–2 gyro x/y/z valid, bits 4–6 accelerometer x/y/z valid |
//! | 29 | sequence number, 0–127, incremented per message |
//! | 30–31 | temperature, int16, °C |
//! | 32–35 | CRC-32/MPEG-2 over bytes 0–31 |
//!
//! The [`Decoder`] resynchronises on the header after junk or a CRC failure: it reports the
//! problem with the stream offset, drops one byte and searches for the next header, so a false
//! header inside a payload cannot swallow a good frame.
//!
//! ```
//! use bench_drivers::protocol::kvh1750::Frame;
//! let f = Frame { gyro: [0.0; 3], accel: [0.0, 0.0, 1.0], status: 0x77, seq: 1, temp_c: 21 };
//! let bytes = f.encode();
//! assert_eq!(&bytes[..4], &[0xFE, 0x81, 0xFF, 0x55]);
//! assert_eq!(Frame::decode(&bytes).unwrap(), f);
//! ```

use crc::{Crc, CRC_32_MPEG_2};

use super::DecodeError;

/// Frame header.
pub const HEADER: [u8; 4] = [0xFE, 0x81, 0xFF, 0x55];
/// Frame length, bytes.
pub const FRAME_LEN: usize = 36;
/// Bytes covered by the CRC.
pub const CRC_LEN: usize = 32;
/// Sequence numbers run 0..=127.
pub const SEQ_MAX: u8 = 127;
/// Status bits: gyro x, y, z valid.
pub const STATUS_GYRO_VALID: [u8; 3] = [1 << 0, 1 << 1, 1 << 2];
/// Status bits: accelerometer x, y, z valid.
pub const STATUS_ACCEL_VALID: [u8; 3] = [1 << 4, 1 << 5, 1 << 6];

const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_MPEG_2);

/// CRC-32/MPEG-2 of `bytes`.
pub fn crc32_mpeg2(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// One format A message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Gyro x, y, z in the configured unit (default: delta angle, rad).
    pub gyro: [f32; 3],
    /// Accelerometer x, y, z, g.
    pub accel: [f32; 3],
    /// Validity bits ([`STATUS_GYRO_VALID`], [`STATUS_ACCEL_VALID`]).
    pub status: u8,
    /// Sequence number 0..=127.
    pub seq: u8,
    /// Temperature, °C.
    pub temp_c: i16,
}

fn be_f32(b: &[u8], at: usize) -> f32 {
    f32::from_bits(be_u32(b, at))
}

fn be_u32(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        w.copy_from_slice(s);
    }
    u32::from_be_bytes(w)
}

impl Frame {
    /// The 36 bytes on the wire, CRC included.
    pub fn encode(&self) -> [u8; FRAME_LEN] {
        let mut out = [0u8; FRAME_LEN];
        let mut v = Vec::with_capacity(FRAME_LEN);
        v.extend_from_slice(&HEADER);
        for x in self.gyro.iter().chain(self.accel.iter()) {
            v.extend_from_slice(&x.to_be_bytes());
        }
        v.push(self.status);
        v.push(self.seq);
        v.extend_from_slice(&self.temp_c.to_be_bytes());
        let crc = crc32_mpeg2(&v);
        v.extend_from_slice(&crc.to_be_bytes());
        out.copy_from_slice(&v);
        out
    }

    /// Decodes exactly one frame from the start of `bytes` (at least 36 bytes). Checks header,
    /// CRC and sequence range; error offsets count from the start of `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<Self, DecodeError> {
        let Some(b) = bytes.get(..FRAME_LEN) else {
            return Err(DecodeError::new(0, format!("{FRAME_LEN} bytes"), bytes));
        };
        if b.get(..4) != Some(&HEADER[..]) {
            return Err(DecodeError::new(0, "header FE 81 FF 55", b.get(..4).unwrap_or(b)));
        }
        let expected = crc32_mpeg2(b.get(..CRC_LEN).unwrap_or_default());
        let got = be_u32(b, CRC_LEN);
        if expected != got {
            return Err(DecodeError::new(
                CRC_LEN as u64,
                format!("CRC {expected:08X} over bytes 0–31 (frame {})", hex(b)),
                b.get(CRC_LEN..).unwrap_or_default(),
            ));
        }
        let seq = b.get(29).copied().unwrap_or_default();
        if seq > SEQ_MAX {
            return Err(DecodeError::new(29, "a sequence number 0..=127", &[seq]));
        }
        Ok(Self {
            gyro: [be_f32(b, 4), be_f32(b, 8), be_f32(b, 12)],
            accel: [be_f32(b, 16), be_f32(b, 20), be_f32(b, 24)],
            status: b.get(28).copied().unwrap_or_default(),
            seq,
            temp_c: i16::from_be_bytes([
                b.get(30).copied().unwrap_or_default(),
                b.get(31).copied().unwrap_or_default(),
            ]),
        })
    }

    /// Whether gyro axis `axis` (0..3) is flagged valid.
    pub fn gyro_valid(&self, axis: usize) -> bool {
        STATUS_GYRO_VALID.get(axis).is_some_and(|m| self.status & m != 0)
    }

    /// Whether accelerometer axis `axis` (0..3) is flagged valid.
    pub fn accel_valid(&self, axis: usize) -> bool {
        STATUS_ACCEL_VALID.get(axis).is_some_and(|m| self.status & m != 0)
    }
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect::<Vec<_>>().join(" ")
}

/// Incremental decoder: feed bytes, take frames.
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    /// Stream offset of `buf[0]`.
    base: u64,
    /// The bytes up to the next header belong to a frame already reported as bad.
    after_error: bool,
}

impl Decoder {
    /// A decoder at stream offset 0.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    fn drop_front(&mut self, n: usize) {
        let n = n.min(self.buf.len());
        self.buf.drain(..n);
        self.base = self.base.saturating_add(n as u64);
    }

    /// The next frame, an error (junk skipped, bad CRC, bad sequence), or `None` until more
    /// bytes arrive. After an error, decoding carries on with the next header.
    pub fn next_frame(&mut self) -> Option<Result<Frame, DecodeError>> {
        loop {
            // Find a header (or a header prefix at the very end of the buffer).
            let start = (0..self.buf.len())
                .find(|&i| {
                    let tail = self.buf.get(i..).unwrap_or_default();
                    let n = tail.len().min(HEADER.len());
                    tail.get(..n) == HEADER.get(..n)
                })
                .unwrap_or(self.buf.len());
            if start > 0 {
                let at = self.base;
                let err = DecodeError::new(
                    at,
                    format!("header FE 81 FF 55 ({start} bytes skipped)"),
                    self.buf.get(..start).unwrap_or_default(),
                );
                self.drop_front(start);
                if std::mem::take(&mut self.after_error) {
                    // The rest of a frame already reported: skip it silently.
                    continue;
                }
                return Some(Err(err));
            }
            if self.buf.len() < FRAME_LEN {
                return None;
            }
            let at = self.base;
            return match Frame::decode(&self.buf) {
                Ok(f) => {
                    self.drop_front(FRAME_LEN);
                    self.after_error = false;
                    Some(Ok(f))
                }
                Err(e) => {
                    // Drop only the header's first byte: a real frame may start inside this one.
                    self.drop_front(1);
                    self.after_error = true;
                    Some(Err(e.shifted(at)))
                }
            };
        }
    }
}
