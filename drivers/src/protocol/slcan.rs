//! Lawicel SLCAN: CAN over a serial line (ASCII, every message ends in `\r`).
//!
//! Host → adapter commands ([`HostCommand`]): `Sn` bit rate, `O` open, `L` open listen-only,
//! `C` close, `tiiildd…` / `Tiiiiiiiildd…` data frames, `riiil` / `Riiiiiiiil` remote frames,
//! `F` status flags, `V` version, `N` serial number, `Z0`/`Z1` time stamps off/on.
//!
//! Adapter → host messages ([`AdapterMessage`]): `\r` success, BEL (0x07) error, `z\r` / `Z\r`
//! transmit acknowledgements, `Fxx\r`, `Vhhss\r`, `Nxxxx\r`, and received frames in the same
//! `t`/`T`/`r`/`R` syntax, followed by a 4-hex-digit millisecond time stamp when `Z1` is on.
//!
//! Both sides are here: the host side ([`HostCommand::encode`], [`HostDecoder`]) for the driver
//! and the adapter side ([`AdapterDecoder`], [`AdapterMessage::encode`]) for the simulator.
//!
//! ```
//! use bench_drivers::protocol::slcan::{AdapterMessage, CanFrame, CanId, HostCommand, HostDecoder};
//! let f = CanFrame::new_data(CanId::standard(0x123).unwrap(), &[0x11, 0x22]).unwrap();
//! assert_eq!(HostCommand::Transmit(f).encode(), b"t12321122\r");
//! let mut dec = HostDecoder::new();
//! dec.push(b"z\rt1232112203E8\r");
//! assert_eq!(dec.next_message().unwrap().unwrap(), AdapterMessage::TransmitAck { extended: false });
//! assert_eq!(
//!     dec.next_message().unwrap().unwrap(),
//!     AdapterMessage::Received { frame: f, timestamp_ms: Some(1000) }
//! );
//! ```

use super::line::LineSplitter;
use super::{DecodeError, EncodeError, LineDecoder, LineFormat};

/// End of every message.
pub const CR: u8 = b'\r';
/// Error reply.
pub const BEL: u8 = 0x07;
/// Longest message accepted (a `T` frame with time stamp is 31 bytes).
pub const MAX_LINE: usize = 64;

/// Status flag bits (`Fxx`).
pub mod status {
    /// Receive FIFO full.
    pub const RX_FIFO_FULL: u8 = 1 << 0;
    /// Transmit FIFO full.
    pub const TX_FIFO_FULL: u8 = 1 << 1;
    /// Error warning.
    pub const ERROR_WARNING: u8 = 1 << 2;
    /// Data overrun.
    pub const OVERRUN: u8 = 1 << 3;
    /// Error passive.
    pub const ERROR_PASSIVE: u8 = 1 << 5;
    /// Arbitration lost.
    pub const ARBITRATION_LOST: u8 = 1 << 6;
    /// Bus error.
    pub const BUS_ERROR: u8 = 1 << 7;
}

/// A CAN identifier.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CanId {
    /// 11-bit identifier (0..=0x7FF).
    Standard(u16),
    /// 29-bit identifier (0..=0x1FFF_FFFF).
    Extended(u32),
}

impl CanId {
    /// An 11-bit identifier, `None` above 0x7FF.
    pub fn standard(id: u16) -> Option<Self> {
        (id <= 0x7FF).then_some(CanId::Standard(id))
    }

    /// A 29-bit identifier, `None` above 0x1FFF_FFFF.
    pub fn extended(id: u32) -> Option<Self> {
        (id <= 0x1FFF_FFFF).then_some(CanId::Extended(id))
    }

    /// The raw identifier value.
    pub fn raw(self) -> u32 {
        match self {
            CanId::Standard(id) => u32::from(id),
            CanId::Extended(id) => id,
        }
    }

    /// Whether this is a 29-bit identifier.
    pub fn is_extended(self) -> bool {
        matches!(self, CanId::Extended(_))
    }

    fn is_valid(self) -> bool {
        match self {
            CanId::Standard(id) => id <= 0x7FF,
            CanId::Extended(id) => id <= 0x1FFF_FFFF,
        }
    }
}

/// A classic CAN frame: identifier, data length 0..=8, data or remote request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A data frame; `data` holds at most 8 bytes.
    pub fn new_data(id: CanId, data: &[u8]) -> Result<Self, EncodeError> {
        if !id.is_valid() {
            return Err(EncodeError::new("CAN id", id.raw(), "outside the identifier range"));
        }
        let mut d = [0u8; 8];
        d.get_mut(..data.len())
            .ok_or_else(|| EncodeError::new("CAN data length", data.len(), "more than 8 bytes"))?
            .copy_from_slice(data);
        Ok(Self { id, remote: false, dlc: data.len() as u8, data: d })
    }

    /// A remote (RTR) frame requesting `dlc` bytes (at most 8).
    pub fn new_remote(id: CanId, dlc: u8) -> Result<Self, EncodeError> {
        if !id.is_valid() {
            return Err(EncodeError::new("CAN id", id.raw(), "outside the identifier range"));
        }
        if dlc > 8 {
            return Err(EncodeError::new("CAN dlc", dlc, "more than 8"));
        }
        Ok(Self { id, remote: true, dlc, data: [0; 8] })
    }

    /// Identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// Whether this is a remote request.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// Data length code (0..=8).
    pub fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The data bytes (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            self.data.get(..usize::from(self.dlc)).unwrap_or_default()
        }
    }

    /// SLCAN text without terminator, e.g. `t1232AABB`.
    fn to_text(self) -> String {
        let mut s = String::with_capacity(30);
        match (self.id, self.remote) {
            (CanId::Standard(id), false) => s.push_str(&format!("t{id:03X}")),
            (CanId::Standard(id), true) => s.push_str(&format!("r{id:03X}")),
            (CanId::Extended(id), false) => s.push_str(&format!("T{id:08X}")),
            (CanId::Extended(id), true) => s.push_str(&format!("R{id:08X}")),
        }
        s.push(char::from(b'0' + self.dlc.min(8)));
        for b in self.data() {
            s.push_str(&format!("{b:02X}"));
        }
        s
    }
}

/// SLCAN bit rates `S0`..`S8`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Bitrate {
    /// `S0`: 10 kbit/s.
    K10,
    /// `S1`: 20 kbit/s.
    K20,
    /// `S2`: 50 kbit/s.
    K50,
    /// `S3`: 100 kbit/s.
    K100,
    /// `S4`: 125 kbit/s.
    K125,
    /// `S5`: 250 kbit/s.
    K250,
    /// `S6`: 500 kbit/s.
    K500,
    /// `S7`: 800 kbit/s.
    K800,
    /// `S8`: 1 Mbit/s.
    M1,
}

const BITRATES: [(Bitrate, u32); 9] = [
    (Bitrate::K10, 10_000),
    (Bitrate::K20, 20_000),
    (Bitrate::K50, 50_000),
    (Bitrate::K100, 100_000),
    (Bitrate::K125, 125_000),
    (Bitrate::K250, 250_000),
    (Bitrate::K500, 500_000),
    (Bitrate::K800, 800_000),
    (Bitrate::M1, 1_000_000),
];

impl Bitrate {
    /// The `Sn` digit.
    pub fn code(self) -> u8 {
        BITRATES.iter().position(|(b, _)| *b == self).unwrap_or_default() as u8
    }

    /// From the `Sn` digit.
    pub fn from_code(n: u8) -> Option<Self> {
        BITRATES.get(usize::from(n)).map(|(b, _)| *b)
    }

    /// Bits per second.
    pub fn bits_per_s(self) -> u32 {
        BITRATES.iter().find(|(b, _)| *b == self).map_or(0, |(_, r)| *r)
    }

    /// The SLCAN rate for exactly `bps`.
    pub fn from_bits_per_s(bps: u32) -> Option<Self> {
        BITRATES.iter().find(|(_, r)| *r == bps).map(|(b, _)| *b)
    }
}

/// A host → adapter command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HostCommand {
    /// `Sn`: set the bit rate (channel closed).
    SetBitrate(Bitrate),
    /// `O`: open the channel.
    Open,
    /// `L`: open listen-only.
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `t`/`T`/`r`/`R`: transmit a frame.
    Transmit(CanFrame),
    /// `F`: read status flags.
    ReadStatus,
    /// `V`: read the version.
    Version,
    /// `N`: read the serial number.
    SerialNumber,
    /// `Z0`/`Z1`: time stamps off/on.
    Timestamps(bool),
}

impl HostCommand {
    /// The command with its `\r`.
    pub fn encode(&self) -> Vec<u8> {
        let mut s = match self {
            HostCommand::SetBitrate(b) => format!("S{}", b.code()),
            HostCommand::Open => "O".to_owned(),
            HostCommand::ListenOnly => "L".to_owned(),
            HostCommand::Close => "C".to_owned(),
            HostCommand::Transmit(f) => f.to_text(),
            HostCommand::ReadStatus => "F".to_owned(),
            HostCommand::Version => "V".to_owned(),
            HostCommand::SerialNumber => "N".to_owned(),
            HostCommand::Timestamps(on) => format!("Z{}", u8::from(*on)),
        }
        .into_bytes();
        s.push(CR);
        s
    }

    /// Parses one command without its `\r` (adapter side). Offsets count from `line`'s start.
    pub fn parse(line: &[u8]) -> Result<Self, DecodeError> {
        let bad = || DecodeError::new(0, "an SLCAN command (S O L C t T r R F V N Z)", line);
        let (&c, rest) = line.split_first().ok_or_else(bad)?;
        let no_args = |cmd: HostCommand| {
            if rest.is_empty() {
                Ok(cmd)
            } else {
                Err(DecodeError::new(1, "end of command", rest))
            }
        };
        match c {
            b'S' => match rest {
                [d @ b'0'..=b'8'] => {
                    Bitrate::from_code(d - b'0').map(HostCommand::SetBitrate).ok_or_else(bad)
                }
                _ => Err(DecodeError::new(1, "a bit-rate digit 0..8", rest)),
            },
            b'O' => no_args(HostCommand::Open),
            b'L' => no_args(HostCommand::ListenOnly),
            b'C' => no_args(HostCommand::Close),
            b'F' => no_args(HostCommand::ReadStatus),
            b'V' => no_args(HostCommand::Version),
            b'N' => no_args(HostCommand::SerialNumber),
            b'Z' => match rest {
                [b'0'] => Ok(HostCommand::Timestamps(false)),
                [b'1'] => Ok(HostCommand::Timestamps(true)),
                _ => Err(DecodeError::new(1, "0 or 1", rest)),
            },
            b't' | b'T' | b'r' | b'R' => {
                let (frame, ts) = parse_frame(line)?;
                match ts {
                    None => Ok(HostCommand::Transmit(frame)),
                    Some(_) => Err(DecodeError::new(0, "a frame without time stamp", line)),
                }
            }
            _ => Err(bad()),
        }
    }
}

fn hex_val(b: u8) -> Option<u8> {
    match b {
        b'0'..=b'9' => Some(b - b'0'),
        b'a'..=b'f' => Some(b - b'a' + 10),
        b'A'..=b'F' => Some(b - b'A' + 10),
        _ => None,
    }
}

/// Parses `n` hex digits at `at` in `line`.
fn hex_field(line: &[u8], at: usize, n: usize, what: &str) -> Result<u32, DecodeError> {
    let field = line
        .get(at..at + n)
        .ok_or_else(|| DecodeError::new(at as u64, format!("{n} hex digits ({what})"), line))?;
    let mut v = 0u32;
    for (i, &b) in field.iter().enumerate() {
        let d = hex_val(b).ok_or_else(|| {
            DecodeError::new((at + i) as u64, format!("a hex digit ({what})"), &[b])
        })?;
        v = (v << 4) | u32::from(d);
    }
    Ok(v)
}

/// Parses `t`/`T`/`r`/`R` frame text with an optional 4-digit time stamp.
fn parse_frame(line: &[u8]) -> Result<(CanFrame, Option<u16>), DecodeError> {
    let kind = line.first().copied().unwrap_or_default();
    let (id_len, remote) = match kind {
        b't' => (3, false),
        b'r' => (3, true),
        b'T' => (8, false),
        b'R' => (8, true),
        _ => return Err(DecodeError::new(0, "t, T, r or R", line)),
    };
    let raw = hex_field(line, 1, id_len, "identifier")?;
    let id = if id_len == 3 { CanId::standard(raw as u16) } else { CanId::extended(raw) }
        .ok_or_else(|| {
            DecodeError::new(
                1,
                "an identifier within range",
                line.get(1..=id_len).unwrap_or_default(),
            )
        })?;
    let dlc_at = 1 + id_len;
    let dlc = match line.get(dlc_at) {
        Some(d @ b'0'..=b'8') => d - b'0',
        other => {
            return Err(DecodeError::new(
                dlc_at as u64,
                "a data length 0..8",
                other.map(std::slice::from_ref).unwrap_or_default(),
            ))
        }
    };
    let data_at = dlc_at + 1;
    let data_len = if remote { 0 } else { 2 * usize::from(dlc) };
    let end = data_at + data_len;
    let ts = match line.len().checked_sub(end) {
        Some(0) => None,
        Some(4) => Some(hex_field(line, end, 4, "time stamp")? as u16),
        _ => {
            return Err(DecodeError::new(
                0,
                format!("{end} or {} characters for data length {dlc}", end + 4),
                line,
            ))
        }
    };
    let frame = if remote {
        CanFrame::new_remote(id, dlc)
    } else {
        let mut data = Vec::with_capacity(usize::from(dlc));
        for i in 0..usize::from(dlc) {
            data.push(hex_field(line, data_at + 2 * i, 2, "data byte")? as u8);
        }
        CanFrame::new_data(id, &data)
    }
    .map_err(|e| DecodeError::new(0, e.to_string(), line))?;
    Ok((frame, ts))
}

/// An adapter → host message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum AdapterMessage {
    /// `\r`: the command succeeded.
    Ok,
    /// BEL: the command failed.
    Error,
    /// `z\r` / `Z\r`: a standard / extended frame was queued for transmission.
    TransmitAck {
        /// Whether the acknowledged frame was extended (`Z`).
        extended: bool,
    },
    /// `Fxx\r`: status flags (bits in [`status`]).
    Status(u8),
    /// `Vhhss\r`: hardware and software versions (two hex digits each).
    Version {
        /// Hardware version.
        hardware: u8,
        /// Software version.
        software: u8,
    },
    /// `Nxxxx\r`: serial number (4 characters).
    Serial([u8; 4]),
    /// A received frame, with the adapter's ms time stamp when `Z1` is on.
    Received {
        /// The frame.
        frame: CanFrame,
        /// Milliseconds (the adapter wraps it at 60 000).
        timestamp_ms: Option<u16>,
    },
}

impl AdapterMessage {
    /// The message as sent by the adapter.
    pub fn encode(&self) -> Vec<u8> {
        let mut s = match self {
            AdapterMessage::Ok => String::new(),
            AdapterMessage::Error => return vec![BEL],
            AdapterMessage::TransmitAck { extended: false } => "z".to_owned(),
            AdapterMessage::TransmitAck { extended: true } => "Z".to_owned(),
            AdapterMessage::Status(f) => format!("F{f:02X}"),
            AdapterMessage::Version { hardware, software } => {
                format!("V{hardware:02X}{software:02X}")
            }
            AdapterMessage::Serial(n) => {
                let mut s = "N".to_owned();
                s.extend(n.iter().map(|&b| char::from(b)));
                s
            }
            AdapterMessage::Received { frame, timestamp_ms } => {
                let mut s = frame.to_text();
                if let Some(t) = timestamp_ms {
                    s.push_str(&format!("{t:04X}"));
                }
                s
            }
        }
        .into_bytes();
        s.push(CR);
        s
    }

    /// Parses one message without its `\r` (host side). Offsets count from `line`'s start.
    pub fn parse(line: &[u8]) -> Result<Self, DecodeError> {
        match line {
            [] => Ok(AdapterMessage::Ok),
            [b'z'] => Ok(AdapterMessage::TransmitAck { extended: false }),
            [b'Z'] => Ok(AdapterMessage::TransmitAck { extended: true }),
            [b'F', ..] if line.len() == 3 => {
                Ok(AdapterMessage::Status(hex_field(line, 1, 2, "status flags")? as u8))
            }
            [b'V', ..] if line.len() == 5 => Ok(AdapterMessage::Version {
                hardware: hex_field(line, 1, 2, "hardware version")? as u8,
                software: hex_field(line, 3, 2, "software version")? as u8,
            }),
            [b'N', a, b, c, d] if [a, b, c, d].iter().all(|x| x.is_ascii_alphanumeric()) => {
                Ok(AdapterMessage::Serial([*a, *b, *c, *d]))
            }
            [b't' | b'T' | b'r' | b'R', ..] => {
                let (frame, timestamp_ms) = parse_frame(line)?;
                Ok(AdapterMessage::Received { frame, timestamp_ms })
            }
            _ => Err(DecodeError::new(
                0,
                "an SLCAN reply (\\r, BEL, z, Z, Fxx, Vhhss, Nxxxx, t/T/r/R frame)",
                line,
            )),
        }
    }
}

/// Incremental decoder of adapter → host messages (host side).
#[derive(Debug, Clone)]
pub struct HostDecoder {
    lines: LineSplitter,
    /// A BEL that followed junk, returned after the junk's error.
    pending_bel: bool,
}

impl Default for HostDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl HostDecoder {
    /// A decoder at stream offset 0.
    pub fn new() -> Self {
        Self { lines: LineSplitter::new(&[CR, BEL], MAX_LINE), pending_bel: false }
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.lines.push(bytes);
    }

    /// The next message, an error for bytes that are not one, or `None` until one is complete.
    pub fn next_message(&mut self) -> Option<Result<AdapterMessage, DecodeError>> {
        if std::mem::take(&mut self.pending_bel) {
            return Some(Ok(AdapterMessage::Error));
        }
        let line = match self.lines.next_line()? {
            Ok(l) => l,
            Err(e) => return Some(Err(e)),
        };
        if line.terminator == BEL {
            if line.bytes.is_empty() {
                return Some(Ok(AdapterMessage::Error));
            }
            self.pending_bel = true;
            return Some(Err(DecodeError::new(line.offset, "nothing before BEL", &line.bytes)));
        }
        Some(AdapterMessage::parse(&line.bytes).map_err(|e| e.shifted(line.offset)))
    }
}

/// Host → adapter command lines (adapter side, used by the simulator). Empty commands (a bare
/// `\r`, which hosts send to flush the adapter) are skipped; the adapter answers an error with BEL.
#[derive(Debug, Clone, Copy, Default)]
pub struct CommandLines;

impl LineFormat for CommandLines {
    type Message = HostCommand;
    const TERMINATORS: &'static [u8] = &[CR];
    const MAX_LINE: usize = MAX_LINE;
    fn parse(line: &[u8]) -> Result<HostCommand, DecodeError> {
        HostCommand::parse(line)
    }
    fn is_filler(line: &[u8]) -> bool {
        line.is_empty()
    }
}

/// Incremental decoder of host → adapter commands (adapter side).
pub type AdapterDecoder = LineDecoder<CommandLines>;
