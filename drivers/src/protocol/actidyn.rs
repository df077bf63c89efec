//! Actidyn rate-table controller command language (ASCII, `\n`-terminated).
//!
//! **Inferred, not from a manual.** The command set comes from a public C# client for an Actidyn
//! two-axis table (see `docs/protocols/table.md`): commands are a mnemonic, a space and
//! comma-separated arguments with the axis first (`&` = all axes), several commands may be
//! chained with `:` on one line, and a line ends with `\n`. The client shows that a reply echoes
//! the command, then gives a value count, then the values; the *exact* reply grammar below is
//! bench's concrete reading of that and must be confirmed against the lab's controller manual:
//!
//! ```text
//! reply line   = element *( ":" element ) "\n"      ; one element per chained command
//! element      = MNE " " axis "," count *( "," value )          ; count = number of values
//!              | MNE " " axis ",ERR," code "," text             ; the command failed
//! ```
//!
//! Set commands are acknowledged with a count of 0 (`RAT 1,0`); `PRV 1,?` is answered
//! `PRV 1,3,<position °>,<rate °/s>,<acceleration °/s²>`; `MOD &,?` is answered
//! `MOD &,2,RAT,OFF`. Units on the wire are degrees and seconds.
//!
//! Both directions are here: the host side ([`encode_commands`], [`ReplyDecoder`]) and the
//! controller side used by the simulator ([`CommandDecoder`], [`encode_replies`]).
//!
//! ```
//! use bench_drivers::protocol::actidyn::{Axis, Command, ReplyDecoder, encode_commands};
//! let line = encode_commands(&[Command::ClearAlarms, Command::QueryPrv { axis: Axis::Number(1) }]).unwrap();
//! assert_eq!(line, b"ALC 0:PRV 1,?\n");
//! let mut dec = ReplyDecoder::new();
//! dec.push(b"ALC 0,0:PRV 1,3,12.5,0.25,0\n");
//! let replies = dec.next_message().unwrap().unwrap();
//! let prv = replies[1].prv().unwrap();
//! assert_eq!((prv.position_deg, prv.rate_deg_s, prv.accel_deg_s2), (12.5, 0.25, 0.0));
//! ```

use std::fmt::{self, Write as _};

use super::{finite, parse_f64, DecodeError, EncodeError, LineDecoder, LineFormat};

/// Longest line accepted, bytes.
pub const MAX_LINE: usize = 1024;
/// Interval at which the host re-sends `ALC 0` (the drive switches off if alarms are not
/// cleared within 30 s; the public client used 20 s).
pub const KEEP_ALIVE_S: f64 = 20.0;
/// TCP port the public client used.
pub const DEFAULT_TCP_PORT: u16 = 62000;

/// Which axis a command addresses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// `&`: every axis.
    All,
    /// One axis by number (1 = first; session commands use 0).
    Number(u8),
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Axis::All => f.write_char('&'),
            Axis::Number(n) => write!(f, "{n}"),
        }
    }
}

/// Axis modes (`MOD <axis>,<mode>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mode {
    /// `1`: servo on (hold).
    ServoOn,
    /// `OFF`: drive off.
    Off,
    /// `POS`: position mode.
    Position,
    /// `RAT`: rate mode.
    Rate,
    /// `SIN`: sine mode.
    Sine,
    /// `STP`: controlled stop.
    Stop,
}

impl Mode {
    /// Wire token.
    pub fn token(self) -> &'static str {
        match self {
            Mode::ServoOn => "1",
            Mode::Off => "OFF",
            Mode::Position => "POS",
            Mode::Rate => "RAT",
            Mode::Sine => "SIN",
            Mode::Stop => "STP",
        }
    }

    /// Parses a wire token (case-insensitive).
    pub fn from_token(s: &str) -> Option<Mode> {
        [Mode::ServoOn, Mode::Off, Mode::Position, Mode::Rate, Mode::Sine, Mode::Stop]
            .into_iter()
            .find(|m| m.token().eq_ignore_ascii_case(s.trim()))
    }
}

/// Command mnemonics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mnemonic {
    /// `RMT`: remote control.
    Rmt,
    /// `LOC`: local control.
    Loc,
    /// `ALC`: clear alarms (keep-alive).
    Alc,
    /// `MOD`: set or query the mode.
    Mod,
    /// `POS`: position move or position query.
    Pos,
    /// `RAT`: rate command.
    Rat,
    /// `SIN`: sine command.
    Sin,
    /// `PRV`: position, rate, acceleration query.
    Prv,
}

const MNEMONICS: [(Mnemonic, &str); 8] = [
    (Mnemonic::Rmt, "RMT"),
    (Mnemonic::Loc, "LOC"),
    (Mnemonic::Alc, "ALC"),
    (Mnemonic::Mod, "MOD"),
    (Mnemonic::Pos, "POS"),
    (Mnemonic::Rat, "RAT"),
    (Mnemonic::Sin, "SIN"),
    (Mnemonic::Prv, "PRV"),
];

impl Mnemonic {
    /// Wire text.
    pub fn as_str(self) -> &'static str {
        MNEMONICS.iter().find(|(m, _)| *m == self).map_or("", |(_, s)| s)
    }

    /// Parses the wire text (case-insensitive).
    pub fn parse(s: &str) -> Option<Mnemonic> {
        MNEMONICS.iter().find(|(_, t)| t.eq_ignore_ascii_case(s)).map(|(m, _)| *m)
    }
}

/// One command (host → controller).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// `RMT 0`: take remote control.
    Remote,
    /// `LOC 0`: return to local control.
    Local,
    /// `ALC 0`: clear alarms; also the keep-alive (every [`KEEP_ALIVE_S`]).
    ClearAlarms,
    /// `MOD <axis>,<mode>`.
    SetMode {
        /// Axis.
        axis: Axis,
        /// Mode.
        mode: Mode,
    },
    /// `MOD <axis>,?`: each addressed axis' mode.
    QueryMode {
        /// Axis.
        axis: Axis,
    },
    /// `POS <axis>,<deg>,<deg/s>`: move to a position at a rate.
    Position {
        /// Axis.
        axis: Axis,
        /// Target position, °.
        position_deg: f64,
        /// Travel rate, °/s.
        rate_deg_s: f64,
    },
    /// `RAT <axis>,<deg/s>,<deg/s²>`: run at a rate, reached with an acceleration.
    Rate {
        /// Axis.
        axis: Axis,
        /// Rate, °/s.
        rate_deg_s: f64,
        /// Acceleration, °/s².
        accel_deg_s2: f64,
    },
    /// `SIN <axis>,<ampl>,<freq>,<phase>`: sinusoidal motion.
    Sine {
        /// Axis.
        axis: Axis,
        /// Amplitude, °.
        amplitude_deg: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase, °.
        phase_deg: f64,
    },
    /// `POS <axis>,?`: position query.
    QueryPosition {
        /// Axis.
        axis: Axis,
    },
    /// `PRV <axis>,?`: position, rate and acceleration query.
    QueryPrv {
        /// Axis.
        axis: Axis,
    },
}

impl Command {
    /// The command's mnemonic.
    pub fn mnemonic(&self) -> Mnemonic {
        match self {
            Command::Remote => Mnemonic::Rmt,
            Command::Local => Mnemonic::Loc,
            Command::ClearAlarms => Mnemonic::Alc,
            Command::SetMode { .. } | Command::QueryMode { .. } => Mnemonic::Mod,
            Command::Position { .. } | Command::QueryPosition { .. } => Mnemonic::Pos,
            Command::Rate { .. } => Mnemonic::Rat,
            Command::Sine { .. } => Mnemonic::Sin,
            Command::QueryPrv { .. } => Mnemonic::Prv,
        }
    }

    /// The axis the command addresses (`0` for session commands).
    pub fn axis(&self) -> Axis {
        match *self {
            Command::Remote | Command::Local | Command::ClearAlarms => Axis::Number(0),
            Command::SetMode { axis, .. }
            | Command::QueryMode { axis }
            | Command::Position { axis, .. }
            | Command::Rate { axis, .. }
            | Command::Sine { axis, .. }
            | Command::QueryPosition { axis }
            | Command::QueryPrv { axis } => axis,
        }
    }

    /// Whether this is a query (its reply carries values).
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::QueryMode { .. } | Command::QueryPosition { .. } | Command::QueryPrv { .. }
        )
    }

    /// Command text without terminator, e.g. `RAT 1,0,5`.
    pub fn to_text(&self) -> Result<String, EncodeError> {
        let m = self.mnemonic().as_str();
        let a = self.axis();
        Ok(match *self {
            Command::Remote | Command::Local | Command::ClearAlarms => format!("{m} 0"),
            Command::SetMode { mode, .. } => format!("{m} {a},{}", mode.token()),
            Command::QueryMode { .. }
            | Command::QueryPosition { .. }
            | Command::QueryPrv { .. } => {
                format!("{m} {a},?")
            }
            Command::Position { position_deg, rate_deg_s, .. } => format!(
                "{m} {a},{},{}",
                finite("position_deg", position_deg)?,
                finite("rate_deg_s", rate_deg_s)?
            ),
            Command::Rate { rate_deg_s, accel_deg_s2, .. } => format!(
                "{m} {a},{},{}",
                finite("rate_deg_s", rate_deg_s)?,
                finite("accel_deg_s2", accel_deg_s2)?
            ),
            Command::Sine { amplitude_deg, frequency_hz, phase_deg, .. } => format!(
                "{m} {a},{},{},{}",
                finite("amplitude_deg", amplitude_deg)?,
                finite("frequency_hz", frequency_hz)?,
                finite("phase_deg", phase_deg)?
            ),
        })
    }

    /// One command as a complete line (`…\n`).
    pub fn encode(&self) -> Result<Vec<u8>, EncodeError> {
        encode_commands(std::slice::from_ref(self))
    }
}

/// Chains commands with `:` into one `\n`-terminated line.
pub fn encode_commands(commands: &[Command]) -> Result<Vec<u8>, EncodeError> {
    let mut out = String::new();
    for (i, c) in commands.iter().enumerate() {
        if i > 0 {
            out.push(':');
        }
        out.push_str(&c.to_text()?);
    }
    out.push('\n');
    Ok(out.into_bytes())
}

/// A value in a reply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// A number (°, °/s or °/s² depending on the query).
    Number(f64),
    /// A mode token (replies to `MOD <axis>,?`).
    Mode(Mode),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Number(v) => write!(f, "{v}"),
            Value::Mode(m) => f.write_str(m.token()),
        }
    }
}

/// What a reply element says.
#[derive(Debug, Clone, PartialEq)]
pub enum ReplyBody {
    /// Success with `values.len()` values (0 for a set command).
    Values(Vec<Value>),
    /// The controller refused the command.
    Error {
        /// Controller error code.
        code: u16,
        /// Controller error text (no `:` or line breaks).
        message: String,
    },
}

/// One reply element (controller → host), answering one command.
#[derive(Debug, Clone, PartialEq)]
pub struct Reply {
    /// Echo of the command's mnemonic.
    pub mnemonic: Mnemonic,
    /// Echo of the command's axis.
    pub axis: Axis,
    /// Values or error.
    pub body: ReplyBody,
}

/// Position, rate and acceleration of one axis (reply to `PRV <axis>,?`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prv {
    /// Position, °.
    pub position_deg: f64,
    /// Rate, °/s.
    pub rate_deg_s: f64,
    /// Acceleration, °/s².
    pub accel_deg_s2: f64,
}

impl Reply {
    /// Acknowledgement of a set command: the echo with a count of 0.
    pub fn ack(command: &Command) -> Self {
        Self::values(command, Vec::new())
    }

    /// Success reply carrying values.
    pub fn values(command: &Command, values: Vec<Value>) -> Self {
        Self { mnemonic: command.mnemonic(), axis: command.axis(), body: ReplyBody::Values(values) }
    }

    /// Error reply.
    pub fn error(command: &Command, code: u16, message: impl Into<String>) -> Self {
        Self {
            mnemonic: command.mnemonic(),
            axis: command.axis(),
            body: ReplyBody::Error { code, message: message.into() },
        }
    }

    /// Whether this reply echoes `command` (same mnemonic and axis).
    pub fn answers(&self, command: &Command) -> bool {
        self.mnemonic == command.mnemonic() && self.axis == command.axis()
    }

    /// The numbers of a success reply (`None` for an error or a mode value).
    pub fn numbers(&self) -> Option<Vec<f64>> {
        match &self.body {
            ReplyBody::Values(v) => v
                .iter()
                .map(|v| match v {
                    Value::Number(x) => Some(*x),
                    Value::Mode(_) => None,
                })
                .collect(),
            ReplyBody::Error { .. } => None,
        }
    }

    /// Position, rate and acceleration from a `PRV` reply with 3 numbers.
    pub fn prv(&self) -> Option<Prv> {
        if self.mnemonic != Mnemonic::Prv {
            return None;
        }
        match self.numbers()?.as_slice() {
            [p, r, a] => Some(Prv { position_deg: *p, rate_deg_s: *r, accel_deg_s2: *a }),
            _ => None,
        }
    }

    /// Position from a `POS` query reply with 1 number, °.
    pub fn position_deg(&self) -> Option<f64> {
        match (self.mnemonic, self.numbers()?.as_slice()) {
            (Mnemonic::Pos, [p]) => Some(*p),
            _ => None,
        }
    }

    /// Modes from a `MOD` query reply.
    pub fn modes(&self) -> Option<Vec<Mode>> {
        match (&self.body, self.mnemonic) {
            (ReplyBody::Values(v), Mnemonic::Mod) => v
                .iter()
                .map(|v| match v {
                    Value::Mode(m) => Some(*m),
                    Value::Number(_) => None,
                })
                .collect(),
            _ => None,
        }
    }

    /// Reply element text without terminator.
    pub fn to_text(&self) -> Result<String, EncodeError> {
        let mut s = format!("{} {}", self.mnemonic.as_str(), self.axis);
        match &self.body {
            ReplyBody::Values(values) => {
                let _ = write!(s, ",{}", values.len());
                for v in values {
                    if let Value::Number(x) = v {
                        finite("reply value", *x)?;
                    }
                    let _ = write!(s, ",{v}");
                }
            }
            ReplyBody::Error { code, message } => {
                if message.contains([':', '\n', '\r']) {
                    return Err(EncodeError::new(
                        "error message",
                        message,
                        "must not contain ':' or line breaks",
                    ));
                }
                let _ = write!(s, ",ERR,{code},{message}");
            }
        }
        Ok(s)
    }
}

/// Replies to a chained command line, joined with `:` and terminated by `\n`.
pub fn encode_replies(replies: &[Reply]) -> Result<Vec<u8>, EncodeError> {
    let mut out = String::new();
    for (i, r) in replies.iter().enumerate() {
        if i > 0 {
            out.push(':');
        }
        out.push_str(&r.to_text()?);
    }
    out.push('\n');
    Ok(out.into_bytes())
}

/// Splits `s` at `sep`, keeping each piece's byte offset in `s`.
fn split_offsets(s: &str, sep: char) -> impl Iterator<Item = (usize, &str)> {
    let mut start = 0;
    s.split(sep).map(move |piece| {
        let at = start;
        start += piece.len() + sep.len_utf8();
        (at, piece)
    })
}

fn line_str(line: &[u8]) -> Result<&str, DecodeError> {
    std::str::from_utf8(line).map_err(|e| {
        let at = e.valid_up_to();
        DecodeError::new(at as u64, "ASCII text", line.get(at..).unwrap_or_default())
    })
}

fn err(at: usize, expected: impl Into<String>, got: &str) -> DecodeError {
    DecodeError::new(at as u64, expected, got.as_bytes())
}

/// Arguments with their byte offsets in the line.
type Args<'a> = Vec<(usize, &'a str)>;

/// Splits one element into mnemonic and arguments, each with its offset in the line.
fn split_element(base: usize, element: &str) -> Result<(Mnemonic, Args<'_>), DecodeError> {
    let lead = element.len() - element.trim_start().len();
    let body = element.trim();
    let (mne, rest) = body.split_once(' ').unwrap_or((body, ""));
    let mnemonic = Mnemonic::parse(mne)
        .ok_or_else(|| err(base + lead, "a mnemonic (RMT LOC ALC MOD POS RAT SIN PRV)", body))?;
    let args_at = base + lead + mne.len() + 1;
    let args = if rest.trim().is_empty() {
        Vec::new()
    } else {
        split_offsets(rest, ',').map(|(o, a)| (args_at + o, a)).collect()
    };
    Ok((mnemonic, args))
}

fn parse_axis(at: usize, s: &str) -> Result<Axis, DecodeError> {
    let t = s.trim();
    if t == "&" {
        return Ok(Axis::All);
    }
    t.parse::<u8>().map(Axis::Number).map_err(|_| err(at, "an axis number or '&'", s))
}

fn parse_num(at: usize, s: &str, what: &str) -> Result<f64, DecodeError> {
    parse_f64(s).ok_or_else(|| err(at, format!("{what} (a finite number)"), s))
}

/// Parses one command element (controller side).
fn parse_command(base: usize, element: &str) -> Result<Command, DecodeError> {
    let (mnemonic, args) = split_element(base, element)?;
    let n_expected = |n: usize, what: &str| -> Result<(), DecodeError> {
        if args.len() == n {
            Ok(())
        } else {
            Err(err(base, format!("{} with {what}", mnemonic.as_str()), element))
        }
    };
    let axis = |i: usize| -> Result<Axis, DecodeError> {
        let (at, a) = args.get(i).copied().unwrap_or((base, ""));
        parse_axis(at, a)
    };
    let num = |i: usize, what: &str| -> Result<f64, DecodeError> {
        let (at, a) = args.get(i).copied().unwrap_or((base, ""));
        parse_num(at, a, what)
    };
    let is_query = args.len() == 2 && args.get(1).is_some_and(|(_, a)| a.trim() == "?");
    Ok(match mnemonic {
        Mnemonic::Rmt | Mnemonic::Loc | Mnemonic::Alc => {
            n_expected(1, "the argument 0")?;
            axis(0)?;
            match mnemonic {
                Mnemonic::Rmt => Command::Remote,
                Mnemonic::Loc => Command::Local,
                _ => Command::ClearAlarms,
            }
        }
        Mnemonic::Mod => {
            n_expected(2, "an axis and a mode")?;
            let axis = axis(0)?;
            if is_query {
                Command::QueryMode { axis }
            } else {
                let (at, m) = args.get(1).copied().unwrap_or((base, ""));
                let mode = Mode::from_token(m)
                    .ok_or_else(|| err(at, "a mode (1 OFF POS RAT SIN STP) or '?'", m))?;
                Command::SetMode { axis, mode }
            }
        }
        Mnemonic::Pos if is_query => Command::QueryPosition { axis: axis(0)? },
        Mnemonic::Pos => {
            n_expected(3, "an axis, a position and a rate, or '?'")?;
            Command::Position {
                axis: axis(0)?,
                position_deg: num(1, "position °")?,
                rate_deg_s: num(2, "rate °/s")?,
            }
        }
        Mnemonic::Rat => {
            n_expected(3, "an axis, a rate and an acceleration")?;
            Command::Rate {
                axis: axis(0)?,
                rate_deg_s: num(1, "rate °/s")?,
                accel_deg_s2: num(2, "acceleration °/s²")?,
            }
        }
        Mnemonic::Sin => {
            n_expected(4, "an axis, an amplitude, a frequency and a phase")?;
            Command::Sine {
                axis: axis(0)?,
                amplitude_deg: num(1, "amplitude °")?,
                frequency_hz: num(2, "frequency Hz")?,
                phase_deg: num(3, "phase °")?,
            }
        }
        Mnemonic::Prv => {
            if !is_query {
                return Err(err(base, "PRV <axis>,?", element));
            }
            Command::QueryPrv { axis: axis(0)? }
        }
    })
}

/// Parses one command line (without its `\n`) into its chained commands. Offsets in errors
/// count from the start of `line`.
pub fn parse_command_line(line: &[u8]) -> Result<Vec<Command>, DecodeError> {
    let s = line_str(line)?;
    split_offsets(s, ':').map(|(at, e)| parse_command(at, e)).collect()
}

/// Parses one reply element.
fn parse_reply(base: usize, element: &str) -> Result<Reply, DecodeError> {
    let (mnemonic, args) = split_element(base, element)?;
    let mut it = args.into_iter();
    let (at, a) = it.next().ok_or_else(|| err(base, "an axis after the mnemonic", element))?;
    let axis = parse_axis(at, a)?;
    let (at, c) = it.next().ok_or_else(|| err(base, "a value count or ERR", element))?;
    if c.trim().eq_ignore_ascii_case("ERR") {
        let (at, code) = it.next().ok_or_else(|| err(at, "ERR,<code>,<text>", element))?;
        let code = code.trim().parse::<u16>().map_err(|_| err(at, "an error code", code))?;
        let message = it.map(|(_, t)| t).collect::<Vec<_>>().join(",");
        return Ok(Reply { mnemonic, axis, body: ReplyBody::Error { code, message } });
    }
    let count = c.trim().parse::<usize>().map_err(|_| err(at, "a value count or ERR", c))?;
    let values = it
        .map(|(at, v)| match Mode::from_token(v).filter(|_| mnemonic == Mnemonic::Mod) {
            Some(m) => Ok(Value::Mode(m)),
            None => parse_num(at, v, "a value").map(Value::Number),
        })
        .collect::<Result<Vec<_>, _>>()?;
    if values.len() != count {
        return Err(err(
            at,
            format!("{count} values as announced by the count"),
            &format!("{} values in {element:?}", values.len()),
        ));
    }
    Ok(Reply { mnemonic, axis, body: ReplyBody::Values(values) })
}

/// Parses one reply line (without its `\n`) into its chained reply elements. Offsets in errors
/// count from the start of `line`.
pub fn parse_reply_line(line: &[u8]) -> Result<Vec<Reply>, DecodeError> {
    let s = line_str(line)?;
    split_offsets(s, ':').map(|(at, e)| parse_reply(at, e)).collect()
}

/// Reply lines (host side): each line is the chained replies to one command line. A blank line is
/// an error, not skipped: the controller answers every command line.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReplyLines;

impl LineFormat for ReplyLines {
    type Message = Vec<Reply>;
    const MAX_LINE: usize = MAX_LINE;
    fn parse(line: &[u8]) -> Result<Vec<Reply>, DecodeError> {
        parse_reply_line(line)
    }
    fn is_filler(_line: &[u8]) -> bool {
        false
    }
}

/// Command lines (controller side, used by the simulator); blank lines are skipped.
#[derive(Debug, Clone, Copy, Default)]
pub struct CommandLines;

impl LineFormat for CommandLines {
    type Message = Vec<Command>;
    const MAX_LINE: usize = MAX_LINE;
    fn parse(line: &[u8]) -> Result<Vec<Command>, DecodeError> {
        parse_command_line(line)
    }
}

/// Incremental decoder of reply lines (host side).
pub type ReplyDecoder = LineDecoder<ReplyLines>;
/// Incremental decoder of command lines (controller side).
pub type CommandDecoder = LineDecoder<CommandLines>;

/// Error codes of Actidyn `ERR` replies. **bench's own convention** (the controller's codes are
/// unknown): the simulator answers with them and the driver maps them to an [`crate::ErrorKind`] with
/// [`error_kind`]; codes not listed here are device faults.
pub mod errors {
    /// The command was not understood (→ [`crate::ErrorKind::Other`]: retrying will not help).
    pub const SYNTAX: u16 = 1;
    /// Not in remote control (→ `NotReady`).
    pub const NOT_REMOTE: u16 = 10;
    /// An argument is outside the table's limits (→ `OutOfRange`).
    pub const OUT_OF_RANGE: u16 = 11;
    /// The axis is not in the mode the command needs (→ `NotReady`).
    pub const WRONG_MODE: u16 = 12;
    /// The command or mode is not available (→ `Unsupported`).
    pub const UNSUPPORTED: u16 = 13;
    /// Drive alarm, e.g. the drive was switched off because no `ALC` arrived within 30 s
    /// (→ `DeviceFault`).
    pub const DRIVE_ALARM: u16 = 20;
    /// A safety interlock is open (→ `InterlockTripped`).
    pub const INTERLOCK: u16 = 30;
}

/// The [`crate::ErrorKind`] of an Actidyn error code ([`errors`]).
pub fn error_kind(code: u16) -> crate::ErrorKind {
    match code {
        errors::SYNTAX => crate::ErrorKind::Other,
        errors::NOT_REMOTE | errors::WRONG_MODE => crate::ErrorKind::NotReady,
        errors::OUT_OF_RANGE => crate::ErrorKind::OutOfRange,
        errors::UNSUPPORTED => crate::ErrorKind::Unsupported,
        errors::INTERLOCK => crate::ErrorKind::InterlockTripped,
        _ => crate::ErrorKind::DeviceFault,
    }
}
