//! Pure, I/O-free codecs for every wire protocol bench speaks.
//!
//! Each module holds the frame types of one protocol, an encoder and an incremental decoder (feed
//! bytes as they arrive, take frames out; partial frames wait for more bytes, leading junk is
//! skipped and reported). Decoders never panic: a bad input is a [`DecodeError`] that carries the
//! byte offset in the stream and what was actually received, and the decoder carries on with the
//! next frame. Transports (serial, TCP, SLCAN) sit on top and are not in this module.
//!
//! | module | device | direction |
//! |---|---|---|
//! | [`actidyn`] | Actidyn rate-table controller (ASCII, `\n`) | host and controller side |
//! | [`acutrol`] | Acutronic ACUTROL (SCPI-like, `\r\n`) | host and controller side |
//! | [`kvh_dsp3000`] | KVH DSP-3000 FOG (ASCII 100 Hz, binary 1000 Hz) | gyro → host |
//! | [`kvh1750`] | KVH 1750/1775 IMU format A (36-byte frames, CRC-32/MPEG-2) | gyro → host |
//! | [`slcan`] | Lawicel SLCAN serial-CAN adapter | host and adapter side |
//! | [`gyro_can`] | bench's own high-resolution gyro CAN frame set | gyro → host |
//! | [`modbus_map`] | chamber controller register maps (Watlow, Eurotherm) | register words ↔ °C |
//!
//! ```
//! use bench_drivers::protocol::kvh1750::{Frame, Decoder};
//! let frame = Frame { gyro: [1e-6, 0.0, 0.0], accel: [0.0, 0.0, 1.0], status: 0x77, seq: 5, temp_c: 25 };
//! let mut dec = Decoder::new();
//! dec.push(&[0x00, 0x13]); // junk before the header is skipped and reported
//! dec.push(&frame.encode());
//! assert!(dec.next_frame().unwrap().is_err());
//! assert_eq!(dec.next_frame().unwrap().unwrap(), frame);
//! assert!(dec.next_frame().is_none());
//! ```

pub mod actidyn;
pub mod acutrol;
pub mod gyro_can;
pub mod kvh1750;
pub mod kvh_dsp3000;
mod line;
pub mod modbus_map;
pub mod slcan;

pub use line::{LineDecoder, LineFormat};

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::{DeviceError, ErrorKind};

/// How many received bytes an error keeps (the rest is elided).
pub const ERROR_CONTEXT_BYTES: usize = 64;

/// Bytes that could not be decoded: where they start, what was expected and what was received.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("at byte {offset}: expected {expected}, received {}", Received(&self.received))]
pub struct DecodeError {
    /// Offset of the first offending byte: from the start of the stream for incremental
    /// decoders, from the start of the input for one-shot parsers.
    pub offset: u64,
    /// What the decoder expected there.
    pub expected: String,
    /// The bytes actually received (at most [`ERROR_CONTEXT_BYTES`]).
    pub received: Vec<u8>,
}

impl DecodeError {
    /// A new error at `offset`; keeps at most [`ERROR_CONTEXT_BYTES`] of `received`.
    pub fn new(offset: u64, expected: impl Into<String>, received: &[u8]) -> Self {
        let keep = received.get(..ERROR_CONTEXT_BYTES).unwrap_or(received);
        Self { offset, expected: expected.into(), received: keep.to_vec() }
    }

    /// The same error moved `by` bytes further into the stream.
    pub fn shifted(mut self, by: u64) -> Self {
        self.offset = self.offset.saturating_add(by);
        self
    }
}

impl From<DecodeError> for DeviceError {
    fn from(e: DecodeError) -> Self {
        DeviceError::new(ErrorKind::Protocol, e.to_string())
    }
}

/// A value that cannot be put on the wire (not finite, out of the field's range).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("cannot encode {field} = {value}: {reason}")]
pub struct EncodeError {
    /// Which field.
    pub field: &'static str,
    /// The offending value, as text.
    pub value: String,
    /// Why it does not fit.
    pub reason: &'static str,
}

impl EncodeError {
    pub(crate) fn new(field: &'static str, value: impl fmt::Display, reason: &'static str) -> Self {
        Self { field, value: value.to_string(), reason }
    }
}

impl From<EncodeError> for DeviceError {
    fn from(e: EncodeError) -> Self {
        DeviceError::new(ErrorKind::OutOfRange, e.to_string())
    }
}

/// Displays bytes as an escaped ASCII string: `"OK\r\n"`, `"\xfe\x81"`.
struct Received<'a>(&'a [u8]);

impl fmt::Display for Received<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("\"")?;
        for &b in self.0 {
            for c in std::ascii::escape_default(b) {
                fmt::Write::write_char(f, char::from(c))?;
            }
        }
        f.write_str("\"")?;
        if self.0.len() >= ERROR_CONTEXT_BYTES {
            f.write_str("…")?;
        }
        Ok(())
    }
}

/// Checks that a float is finite before it is formatted onto the wire.
pub(crate) fn finite(field: &'static str, v: f64) -> Result<f64, EncodeError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(EncodeError::new(field, v, "not a finite number"))
    }
}

/// Parses a decimal number, rejecting `inf`/`NaN` and surrounding junk.
pub(crate) fn parse_f64(s: &str) -> Option<f64> {
    let t = s.trim();
    // Rust accepts "inf", "nan", "infinity": none of them is a device value.
    if t.is_empty() || t.bytes().any(|b| b.is_ascii_alphabetic() && b != b'e' && b != b'E') {
        return None;
    }
    t.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Which controller language a rate table speaks (`dialect` of a bench config's `[table]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dialect {
    /// Actidyn controller (ST1300 class): `RMT`, `MOD`, `RAT`, `PRV`, `ALC` keep-alive.
    #[default]
    Actidyn,
    /// Acutronic ACUTROL, SCPI-like (`:mode:rate 1`, `:demand:rate 1, 010.000`).
    Acutrol,
}

impl std::fmt::Display for Dialect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Dialect::Actidyn => "actidyn",
            Dialect::Acutrol => "acutrol",
        })
    }
}
