//! KVH DSP-3000 single-axis FOG outputs (manual 54-0215).
//!
//! * 100 Hz version: RS-232 38400 8N1, ASCII lines `(-)xxx.xxxxxx y\r\n`, `y` = 1 when valid.
//!   The value is the configured output (rate °/s, incremental angle ° or integrated angle °).
//! * 1000 Hz version: 115200 baud, 4-byte binary words, most significant byte first:
//!
//! | bits | field |
//! |---|---|
//! | 31 | validity (1 = BIT OK, contents valid) |
//! | 30–29 | synchronisation |
//! | 28–27 | type: 0 rate, 1 incremental angle, 2 integrated angle |
//! | 26 | parity |
//! | 25–0 | content, 26-bit two's complement: 60 µ°/s (rate) or 6 µ° (incremental angle) |
//!
//! **Parity**: the manual presets bit 26 to 1 and then sets it to the XOR of all 32 bits, which
//! makes the number of 1 bits in the whole word odd: *odd parity over the 32-bit word*. The
//! synchronous interface section of the same manual says "odd parity" for the same bit.
//!
//! **Synchronisation** (bench's assumption): the manual's section on the sync bits (3.1.4) was
//! not available, so the decoder does not rely on their values. A byte stream has no frame
//! marker, so the decoder finds word alignment by requiring [`BinaryDecoder::LOCK_WORDS`]
//! consecutive candidate words that each have odd parity, a defined type (not 3) and the same
//! type; bytes skipped before lock are reported as one error. Once locked, a word that fails
//! parity (or has type 3) is reported with its offset and dropped; a single bad word is taken as
//! a bit error and the alignment is kept, two in a row mean the alignment was lost (a slipped
//! byte) and the search starts again, reporting the bytes it skips. A lab with the manual can make the check stricter with
//! [`BinaryDecoder::with_sync`].
//!
//! ```
//! use bench_drivers::protocol::kvh_dsp3000::{AsciiSample, BinaryWord, DataType};
//! let w = BinaryWord { valid: true, sync: 0, data_type: DataType::Rate, value: -1 };
//! assert_eq!(w.encode(), [0x83, 0xff, 0xff, 0xff]);
//! let s = AsciiSample::parse(b" -12.345678 1").unwrap();
//! assert_eq!((s.value, s.valid), (-12.345678, true));
//! ```

use super::line::LineSplitter;
use super::{finite, parse_f64, DecodeError, EncodeError};

/// Rate LSB of the binary output, °/s.
pub const RATE_LSB_DEG_S: f64 = 60e-6;
/// Incremental-angle LSB of the binary output, °.
pub const ANGLE_LSB_DEG: f64 = 6e-6;
/// Largest content value (26-bit two's complement).
pub const VALUE_MAX: i32 = (1 << 25) - 1;
/// Smallest content value.
pub const VALUE_MIN: i32 = -(1 << 25);

/// One line of the 100 Hz ASCII output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AsciiSample {
    /// The output value in the gyro's configured unit (°/s rate or ° angle).
    pub value: f64,
    /// Validity flag (`1`).
    pub valid: bool,
}

impl AsciiSample {
    /// Line text with terminator: value with 6 decimals, a space, the flag, `\r\n`.
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        let v = finite("value", self.value)?;
        Ok(format!("{v:11.6} {}\r\n", u8::from(self.valid)).into_bytes())
    }

    /// Parses one line without its terminator. Offsets count from the start of `line`.
    pub fn parse(line: &[u8]) -> Result<Self, DecodeError> {
        let text = std::str::from_utf8(line).map_err(|e| {
            let at = e.valid_up_to();
            DecodeError::new(at as u64, "ASCII text", line.get(at..).unwrap_or_default())
        })?;
        let lead = text.len() - text.trim_start().len();
        let t = text.trim();
        let Some((v, flag)) = t.rsplit_once(' ') else {
            return Err(DecodeError::new(0, "`<value> <flag>`", line));
        };
        let six_decimals = v.split_once('.').is_some_and(|(i, f)| {
            let i = i.strip_prefix('-').unwrap_or(i);
            !i.is_empty()
                && i.bytes().all(|b| b.is_ascii_digit())
                && f.len() == 6
                && f.bytes().all(|b| b.is_ascii_digit())
        });
        let value = parse_f64(v).filter(|_| six_decimals).ok_or_else(|| {
            DecodeError::new(lead as u64, "a value with 6 decimals such as -0.012345", v.as_bytes())
        })?;
        let flag_at = (lead + v.len() + 1) as u64;
        let valid = match flag {
            "1" => true,
            "0" => false,
            _ => return Err(DecodeError::new(flag_at, "a validity flag 0 or 1", flag.as_bytes())),
        };
        Ok(Self { value, valid })
    }
}

/// Incremental decoder of the 100 Hz ASCII output.
#[derive(Debug, Clone)]
pub struct AsciiDecoder {
    lines: LineSplitter,
    /// Still discarding the (possibly partial) first line.
    skip_first: bool,
}

impl Default for AsciiDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl AsciiDecoder {
    /// A decoder for a stream that starts on a line boundary (a simulator's pty, a recording).
    pub fn new() -> Self {
        Self { lines: LineSplitter::new(b"\n", 64), skip_first: false }
    }

    /// A decoder for a port opened while the gyro is already streaming: the first line may be
    /// the tail of a line (`3.456789 1` looks valid on its own), so it is silently dropped.
    pub fn mid_stream() -> Self {
        Self { lines: LineSplitter::new(b"\n", 64), skip_first: true }
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.lines.push(bytes);
    }

    /// The next sample, or `None` until a line is complete. A line that does not parse is
    /// reported with its stream offset and skipped.
    pub fn next_sample(&mut self) -> Option<Result<AsciiSample, DecodeError>> {
        loop {
            let line = match self.lines.next_line()? {
                Ok(l) => l,
                Err(e) => return Some(Err(e)),
            };
            if std::mem::take(&mut self.skip_first)
                || line.bytes.iter().all(u8::is_ascii_whitespace)
            {
                continue;
            }
            return Some(AsciiSample::parse(&line.bytes).map_err(|e| e.shifted(line.offset)));
        }
    }
}

/// The content type of a binary word (bits 28–27).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DataType {
    /// Rate, LSB [`RATE_LSB_DEG_S`].
    Rate,
    /// Incremental angle, LSB [`ANGLE_LSB_DEG`].
    IncrementalAngle,
    /// Integrated angle (LSB not given in the public manual pages).
    IntegratedAngle,
}

impl DataType {
    fn bits(self) -> u32 {
        match self {
            DataType::Rate => 0,
            DataType::IncrementalAngle => 1,
            DataType::IntegratedAngle => 2,
        }
    }

    fn from_bits(b: u32) -> Option<Self> {
        match b {
            0 => Some(DataType::Rate),
            1 => Some(DataType::IncrementalAngle),
            2 => Some(DataType::IntegratedAngle),
            _ => None,
        }
    }
}

/// One 32-bit word of the 1000 Hz binary output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BinaryWord {
    /// Bit 31: hardware BIT OK and contents valid.
    pub valid: bool,
    /// Bits 30–29 (0..=3).
    pub sync: u8,
    /// Bits 28–27.
    pub data_type: DataType,
    /// Bits 25–0, sign-extended (in [`VALUE_MIN`]..=[`VALUE_MAX`]).
    pub value: i32,
}

/// Whether a 32-bit word has odd parity (bit 26 included).
pub fn parity_ok(word: u32) -> bool {
    word.count_ones() % 2 == 1
}

impl BinaryWord {
    /// The 32-bit word with the parity bit set for odd parity. `sync` is masked to 2 bits and
    /// `value` to 26 bits (out-of-range values wrap; see [`BinaryWord::from_rate_deg_s`]).
    pub fn to_u32(&self) -> u32 {
        let mut w = (u32::from(self.valid) << 31)
            | ((u32::from(self.sync) & 0b11) << 29)
            | (self.data_type.bits() << 27)
            | ((self.value as u32) & 0x03ff_ffff);
        if !parity_ok(w) {
            w |= 1 << 26;
        }
        w
    }

    /// The four bytes as sent, most significant first.
    pub fn encode(&self) -> [u8; 4] {
        self.to_u32().to_be_bytes()
    }

    /// Decodes a word, checking parity and type. The error offset is 0 (the word's first byte).
    pub fn from_u32(word: u32) -> Result<Self, DecodeError> {
        if !parity_ok(word) {
            return Err(DecodeError::new(0, "a word with odd parity", &word.to_be_bytes()));
        }
        let data_type = DataType::from_bits((word >> 27) & 0b11).ok_or_else(|| {
            DecodeError::new(0, "type bits 0, 1 or 2 (type 3 is undefined)", &word.to_be_bytes())
        })?;
        Ok(Self {
            valid: word & (1 << 31) != 0,
            sync: ((word >> 29) & 0b11) as u8,
            data_type,
            value: ((word << 6) as i32) >> 6,
        })
    }

    /// A valid rate word for `rate_deg_s`, rounded to the LSB.
    pub fn from_rate_deg_s(rate_deg_s: f64, sync: u8) -> Result<Self, EncodeError> {
        Ok(Self {
            valid: true,
            sync,
            data_type: DataType::Rate,
            value: to_counts("rate_deg_s", rate_deg_s, RATE_LSB_DEG_S)?,
        })
    }

    /// The rate in rad/s for a rate word.
    pub fn rate_rad_s(&self) -> Option<f64> {
        (self.data_type == DataType::Rate)
            .then(|| f64::from(self.value) * RATE_LSB_DEG_S.to_radians())
    }

    /// The incremental angle in rad for an incremental-angle word.
    pub fn delta_angle_rad(&self) -> Option<f64> {
        (self.data_type == DataType::IncrementalAngle)
            .then(|| f64::from(self.value) * ANGLE_LSB_DEG.to_radians())
    }
}

fn to_counts(field: &'static str, v: f64, lsb: f64) -> Result<i32, EncodeError> {
    let c = (finite(field, v)? / lsb).round();
    if c < f64::from(VALUE_MIN) || c > f64::from(VALUE_MAX) {
        return Err(EncodeError::new(field, v, "outside the 26-bit range"));
    }
    Ok(c as i32)
}

/// Incremental decoder of the 1000 Hz binary output with alignment search.
#[derive(Debug, Clone)]
pub struct BinaryDecoder {
    buf: Vec<u8>,
    /// Stream offset of `buf[0]`.
    base: u64,
    locked: bool,
    /// Consecutive bad words while locked.
    failures: u8,
    /// Stream offset where the current run of skipped bytes began.
    skipped_from: Option<u64>,
    skipped: Vec<u8>,
    sync: Option<u8>,
}

impl Default for BinaryDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl BinaryDecoder {
    /// Consecutive good words needed to accept an alignment.
    pub const LOCK_WORDS: usize = 4;

    /// A decoder at stream offset 0 that ignores the sync bits' values.
    pub fn new() -> Self {
        Self {
            buf: Vec::new(),
            base: 0,
            locked: false,
            failures: 0,
            skipped_from: None,
            skipped: Vec::new(),
            sync: None,
        }
    }

    /// Also require the sync bits to equal `sync` (once the lab's manual confirms they are
    /// constant).
    pub fn with_sync(mut self, sync: u8) -> Self {
        self.sync = Some(sync & 0b11);
        self
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Whether word alignment is established.
    pub fn is_locked(&self) -> bool {
        self.locked
    }

    /// Stream offset of the next byte not yet decoded: just past the word last returned.
    pub fn offset(&self) -> u64 {
        self.base
    }

    fn word_at(&self, i: usize) -> Option<u32> {
        let b = self.buf.get(i..i.checked_add(4)?)?;
        Some(u32::from_be_bytes([*b.first()?, *b.get(1)?, *b.get(2)?, *b.get(3)?]))
    }

    fn check(&self, w: u32) -> Result<BinaryWord, DecodeError> {
        let word = BinaryWord::from_u32(w)?;
        if let Some(s) = self.sync {
            if word.sync != s {
                return Err(DecodeError::new(0, format!("sync bits {s:#04b}"), &w.to_be_bytes()));
            }
        }
        Ok(word)
    }

    fn drop_front(&mut self, n: usize) -> Vec<u8> {
        let n = n.min(self.buf.len());
        let rest = self.buf.split_off(n);
        self.base = self.base.saturating_add(n as u64);
        std::mem::replace(&mut self.buf, rest)
    }

    fn skip_one(&mut self) {
        if self.skipped_from.is_none() {
            self.skipped_from = Some(self.base);
        }
        let b = self.drop_front(1);
        if self.skipped.len() < super::ERROR_CONTEXT_BYTES {
            self.skipped.extend_from_slice(&b);
        }
    }

    /// The next word, an error, or `None` until more bytes are needed.
    pub fn next_word(&mut self) -> Option<Result<BinaryWord, DecodeError>> {
        loop {
            if self.locked {
                let w = self.word_at(0)?;
                let at = self.base;
                return match self.check(w) {
                    Ok(word) => {
                        self.drop_front(4);
                        self.failures = 0;
                        Some(Ok(word))
                    }
                    Err(e) => {
                        // Drop the bad word. One bad word is a bit error: keep the alignment.
                        // Two in a row: alignment lost, search again.
                        self.drop_front(4);
                        self.failures = self.failures.saturating_add(1);
                        if self.failures >= 2 {
                            self.locked = false;
                            self.failures = 0;
                        }
                        Some(Err(e.shifted(at)))
                    }
                };
            }
            // Searching: need LOCK_WORDS good words of one type at the buffer's start.
            let mut first_type = None;
            let mut good = true;
            for k in 0..Self::LOCK_WORDS {
                let w = self.word_at(k * 4)?;
                match self.check(w) {
                    Ok(word) if first_type.is_none_or(|t| t == word.data_type) => {
                        first_type = Some(word.data_type);
                    }
                    _ => {
                        good = false;
                        break;
                    }
                }
            }
            if good {
                self.locked = true;
                if let Some(from) = self.skipped_from.take() {
                    let skipped = std::mem::take(&mut self.skipped);
                    let n = self.base.saturating_sub(from);
                    return Some(Err(DecodeError::new(
                        from,
                        format!("word alignment ({n} bytes skipped)"),
                        &skipped,
                    )));
                }
                continue;
            }
            self.skip_one();
        }
    }
}
