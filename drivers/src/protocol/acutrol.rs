//! Acutronic ACUTROL rate-table controller, SCPI-like dialect (`\r\n`-terminated).
//!
//! **Inferred from public client code, not from a manual** (see `docs/protocols/table.md`).
//! Commands are a keyword path with long or short forms (`:mode:rate 1` = `:M:R 1`), an axis
//! number and, for demands, a value after `, ` (`:demand:rate 1, 010.000`, °/s). Set commands are
//! answered `OK`. The reply to `:read:rate`/`:read:position` is taken to be the bare number on a
//! line, and a refusal a line starting `ERR`; both must be confirmed against the lab's manual.
//!
//! The parser (controller side) accepts any non-empty prefix of each long keyword,
//! case-insensitively: at every level of the tree the first letters differ, so `:M:R`, `:mo:ra`
//! and `:MODE:RATE` are the same command.
//!
//! ```
//! use bench_drivers::protocol::acutrol::{Command, Encoding, Form};
//! let c = Command::DemandRate { axis: 1, rate_deg_s: 10.0 };
//! let short = Encoding { form: Form::Short, decimals: 3 };
//! assert_eq!(c.encode(short).unwrap(), b":D:R 1, 010.000\r\n");
//! assert_eq!(c.encode(Encoding::default()).unwrap(), b":demand:rate 1, 010.000000\r\n");
//! ```

use super::{finite, parse_f64, DecodeError, EncodeError, LineDecoder, LineFormat};

/// Longest line accepted, bytes.
pub const MAX_LINE: usize = 256;
/// TCP port public clients used.
pub const DEFAULT_TCP_PORT: u16 = 9888;
/// Shortest command cycle over Ethernet, s (GPIB: 40 ms).
pub const MIN_CYCLE_ETHERNET_S: f64 = 0.002;

/// Long (`:mode:rate`) or short (`:M:R`) keyword forms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Form {
    /// `:mode:rate 1`.
    #[default]
    Long,
    /// `:M:R 1`.
    Short,
}

/// How commands and replies are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Encoding {
    /// Keyword form. Default long.
    pub form: Form,
    /// Decimals of demand and read values. Default 6; the public client used 3
    /// (`010.000`), which limits a 10 °/min rate (0.1667 °/s) to 0.2 %: confirm what the
    /// controller accepts.
    pub decimals: u8,
}

impl Default for Encoding {
    fn default() -> Self {
        Self { form: Form::Long, decimals: 6 }
    }
}

/// One command (host → controller).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// `:utility:lockout on|off`: lock the front panel out.
    Lockout(bool),
    /// `:interlock:open <axis>`.
    InterlockOpen(u8),
    /// `:interlock:reset <axis>`.
    InterlockReset(u8),
    /// `:interlock:close <axis>`.
    InterlockClose(u8),
    /// `:mode:off <axis>`.
    ModeOff(u8),
    /// `:mode:rate <axis>`.
    ModeRate(u8),
    /// `:mode:position <axis>`.
    ModePosition(u8),
    /// `:demand:rate <axis>, <°/s>`.
    DemandRate {
        /// Axis.
        axis: u8,
        /// Rate, °/s.
        rate_deg_s: f64,
    },
    /// `:demand:position <axis>, <°>`.
    DemandPosition {
        /// Axis.
        axis: u8,
        /// Position, °.
        position_deg: f64,
    },
    /// `:read:rate <axis>`: answered with the rate, °/s.
    ReadRate(u8),
    /// `:read:position <axis>`: answered with the position, °.
    ReadPosition(u8),
}

/// Keyword tree: (long, short) per level.
const UTILITY: (&str, &str) = ("utility", "U");
const LOCKOUT: (&str, &str) = ("lockout", "L");
const INTERLOCK: (&str, &str) = ("interlock", "I");
const OPEN: (&str, &str) = ("open", "O");
const RESET: (&str, &str) = ("reset", "R");
const CLOSE: (&str, &str) = ("close", "C");
const MODE: (&str, &str) = ("mode", "M");
const OFF: (&str, &str) = ("off", "O");
const RATE: (&str, &str) = ("rate", "R");
const POSITION: (&str, &str) = ("position", "P");
const DEMAND: (&str, &str) = ("demand", "D");
const READ: (&str, &str) = ("read", "R");

fn fmt_value(v: f64, decimals: u8) -> String {
    let p = usize::from(decimals);
    format!("{:0w$.p$}", v, w = 4 + p, p = p)
}

impl Command {
    /// The keyword path of this command.
    fn path(&self) -> [(&'static str, &'static str); 2] {
        match self {
            Command::Lockout(_) => [UTILITY, LOCKOUT],
            Command::InterlockOpen(_) => [INTERLOCK, OPEN],
            Command::InterlockReset(_) => [INTERLOCK, RESET],
            Command::InterlockClose(_) => [INTERLOCK, CLOSE],
            Command::ModeOff(_) => [MODE, OFF],
            Command::ModeRate(_) => [MODE, RATE],
            Command::ModePosition(_) => [MODE, POSITION],
            Command::DemandRate { .. } => [DEMAND, RATE],
            Command::DemandPosition { .. } => [DEMAND, POSITION],
            Command::ReadRate(_) => [READ, RATE],
            Command::ReadPosition(_) => [READ, POSITION],
        }
    }

    /// Whether the controller answers with a value rather than `OK`.
    pub fn is_query(&self) -> bool {
        matches!(self, Command::ReadRate(_) | Command::ReadPosition(_))
    }

    /// Whether the public client showed this command's short form (`:M:R`, `:D:R`, `:R:R`,
    /// `:R:P`). Only these are written short with [`Form::Short`]: the short forms of the
    /// others (`:U:L`, `:I:O`, `:M:O`, …) are not known, so they stay long.
    pub fn has_known_short_form(&self) -> bool {
        matches!(
            self,
            Command::ModeRate(_)
                | Command::DemandRate { .. }
                | Command::ReadRate(_)
                | Command::ReadPosition(_)
        )
    }

    /// Command text without terminator. With [`Form::Short`], only the commands whose short
    /// form is known ([`Command::has_known_short_form`]) are written short.
    pub fn to_text(&self, enc: Encoding) -> Result<String, EncodeError> {
        let short = enc.form == Form::Short && self.has_known_short_form();
        let mut s = String::new();
        for (long, abbrev) in self.path() {
            s.push(':');
            s.push_str(if short { abbrev } else { long });
        }
        let args = match *self {
            Command::Lockout(on) => if on { "on" } else { "off" }.to_owned(),
            Command::InterlockOpen(a)
            | Command::InterlockReset(a)
            | Command::InterlockClose(a)
            | Command::ModeOff(a)
            | Command::ModeRate(a)
            | Command::ModePosition(a)
            | Command::ReadRate(a)
            | Command::ReadPosition(a) => a.to_string(),
            Command::DemandRate { axis, rate_deg_s } => {
                format!("{axis}, {}", fmt_value(finite("rate_deg_s", rate_deg_s)?, enc.decimals))
            }
            Command::DemandPosition { axis, position_deg } => format!(
                "{axis}, {}",
                fmt_value(finite("position_deg", position_deg)?, enc.decimals)
            ),
        };
        s.push(' ');
        s.push_str(&args);
        Ok(s)
    }

    /// The command as a complete `\r\n`-terminated line.
    pub fn encode(&self, enc: Encoding) -> Result<Vec<u8>, EncodeError> {
        let mut s = self.to_text(enc)?;
        s.push_str("\r\n");
        Ok(s.into_bytes())
    }
}

fn err(at: usize, expected: impl Into<String>, got: &[u8]) -> DecodeError {
    DecodeError::new(at as u64, expected, got)
}

/// Whether `word` is a non-empty prefix of the long keyword (case-insensitive).
fn matches_keyword(word: &str, (long, _): (&str, &str)) -> bool {
    !word.is_empty()
        && word.len() <= long.len()
        && long.get(..word.len()).is_some_and(|p| p.eq_ignore_ascii_case(word))
}

/// Parses one command line (without terminator; controller side). Offsets count from the
/// start of `line`.
pub fn parse_command(line: &[u8]) -> Result<Command, DecodeError> {
    let s = std::str::from_utf8(line).map_err(|e| {
        err(e.valid_up_to(), "ASCII text", line.get(e.valid_up_to()..).unwrap_or_default())
    })?;
    let lead = s.len() - s.trim_start().len();
    let t = s.trim();
    let (path, args) = t.split_once([' ', '\t']).unwrap_or((t, ""));
    let args_at = lead + path.len() + 1;
    let words: Vec<&str> = path.strip_prefix(':').unwrap_or(path).split(':').collect();
    let bad_path = || err(lead, "a command path such as :mode:rate or :M:R", path.as_bytes());
    let [w1, w2] = words.as_slice() else {
        return Err(bad_path());
    };
    let (w1, w2) = (*w1, *w2);
    let is = |w: &str, k| matches_keyword(w, k);
    let axis = |a: &str| -> Result<u8, DecodeError> {
        a.trim().parse::<u8>().map_err(|_| err(args_at, "an axis number", a.as_bytes()))
    };
    let (a0, a1) = match args.split_once(',') {
        Some((a, v)) => (a, Some(v)),
        None => (args, None),
    };
    let no_value = |c: Command| -> Result<Command, DecodeError> {
        match a1 {
            None => Ok(c),
            Some(v) => Err(err(args_at, "no value after the axis", v.as_bytes())),
        }
    };
    let value = |what: &str| -> Result<f64, DecodeError> {
        let v = a1.ok_or_else(|| err(args_at, format!("<axis>, <{what}>"), args.as_bytes()))?;
        parse_f64(v)
            .ok_or_else(|| err(args_at + a0.len() + 1, format!("{what} (a number)"), v.as_bytes()))
    };
    if is(w1, UTILITY) && is(w2, LOCKOUT) {
        let on = match args.trim().to_ascii_lowercase().as_str() {
            "on" | "1" => true,
            "off" | "0" => false,
            _ => return Err(err(args_at, "on or off", args.as_bytes())),
        };
        return Ok(Command::Lockout(on));
    }
    if is(w1, INTERLOCK) {
        let a = axis(a0)?;
        return no_value(if is(w2, OPEN) {
            Command::InterlockOpen(a)
        } else if is(w2, RESET) {
            Command::InterlockReset(a)
        } else if is(w2, CLOSE) {
            Command::InterlockClose(a)
        } else {
            return Err(bad_path());
        });
    }
    if is(w1, MODE) {
        let a = axis(a0)?;
        return no_value(if is(w2, OFF) {
            Command::ModeOff(a)
        } else if is(w2, RATE) {
            Command::ModeRate(a)
        } else if is(w2, POSITION) {
            Command::ModePosition(a)
        } else {
            return Err(bad_path());
        });
    }
    if is(w1, DEMAND) {
        let axis = axis(a0)?;
        return if is(w2, RATE) {
            Ok(Command::DemandRate { axis, rate_deg_s: value("rate °/s")? })
        } else if is(w2, POSITION) {
            Ok(Command::DemandPosition { axis, position_deg: value("position °")? })
        } else {
            Err(bad_path())
        };
    }
    if is(w1, READ) {
        let a = axis(a0)?;
        return no_value(if is(w2, RATE) {
            Command::ReadRate(a)
        } else if is(w2, POSITION) {
            Command::ReadPosition(a)
        } else {
            return Err(bad_path());
        });
    }
    Err(bad_path())
}

/// A reply line (controller → host).
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `OK`: a set command was accepted.
    Ok,
    /// A value answering a read (°/s or °).
    Value(f64),
    /// `ERR <text>`: the command was refused (format inferred).
    Error(String),
}

impl Reply {
    /// The reply as a complete `\r\n`-terminated line.
    pub fn encode(&self, enc: Encoding) -> Result<Vec<u8>, EncodeError> {
        let s = match self {
            Reply::Ok => "OK".to_owned(),
            Reply::Value(v) => fmt_value(finite("reply value", *v)?, enc.decimals),
            Reply::Error(text) => {
                if text.contains(['\r', '\n']) {
                    return Err(EncodeError::new("error text", text, "contains a line break"));
                }
                format!("ERR {text}")
            }
        };
        Ok(format!("{s}\r\n").into_bytes())
    }
}

/// Parses one reply line (without terminator).
pub fn parse_reply(line: &[u8]) -> Result<Reply, DecodeError> {
    let s = std::str::from_utf8(line).map_err(|e| {
        err(e.valid_up_to(), "ASCII text", line.get(e.valid_up_to()..).unwrap_or_default())
    })?;
    let t = s.trim();
    if t.eq_ignore_ascii_case("OK") {
        return Ok(Reply::Ok);
    }
    if t.len() >= 3 && t.get(..3).is_some_and(|p| p.eq_ignore_ascii_case("ERR")) {
        let rest = t.get(3..).unwrap_or_default();
        return Ok(Reply::Error(rest.trim_start().to_owned()));
    }
    parse_f64(t).map(Reply::Value).ok_or_else(|| err(0, "OK, a number or ERR <text>", line))
}

/// Reply lines (host side); blank lines are skipped.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReplyLines;

impl LineFormat for ReplyLines {
    type Message = Reply;
    const MAX_LINE: usize = MAX_LINE;
    fn parse(line: &[u8]) -> Result<Reply, DecodeError> {
        parse_reply(line)
    }
}

/// Command lines (controller side, used by the simulator); blank lines are skipped.
#[derive(Debug, Clone, Copy, Default)]
pub struct CommandLines;

impl LineFormat for CommandLines {
    type Message = Command;
    const MAX_LINE: usize = MAX_LINE;
    fn parse(line: &[u8]) -> Result<Command, DecodeError> {
        parse_command(line)
    }
}

/// Incremental reply decoder (host side).
pub type ReplyDecoder = LineDecoder<ReplyLines>;
/// Incremental command decoder (controller side).
pub type CommandDecoder = LineDecoder<CommandLines>;

/// The [`crate::ErrorKind`] of an ACUTROL `ERR <text>` reply, by keyword (the controller's error
/// format is unknown; this reading is inferred): `interlock` → `InterlockTripped`, `range` or
/// `limit` → `OutOfRange`, `remote`, `lockout` or `mode` → `NotReady`, anything else →
/// `DeviceFault`.
pub fn error_kind(text: &str) -> crate::ErrorKind {
    let t = text.to_ascii_lowercase();
    if t.contains("interlock") {
        crate::ErrorKind::InterlockTripped
    } else if t.contains("range") || t.contains("limit") {
        crate::ErrorKind::OutOfRange
    } else if t.contains("remote") || t.contains("lockout") || t.contains("mode") {
        crate::ErrorKind::NotReady
    } else {
        crate::ErrorKind::DeviceFault
    }
}
