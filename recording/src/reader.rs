//! The reader: accepts any conforming MCAP file, whoever wrote it — with or without a summary
//! section (a crashed run), chunked or not, chunks compressed with zstd, lz4 or not at all — and
//! loses only what is damaged.
//!
//! [`RecordingReader`] streams a file in one linear pass and decodes the four required
//! channels into typed messages, ignoring unknown channels and unknown fields. The top level is
//! framed on the caller's thread; chunks are decompressed, CRC-checked and decoded on worker
//! threads, several at once, and handed out in file order (memory stays at a few chunks). A
//! chunk that fails its CRC or does not decompress, bytes that do not frame as records, a
//! message that does not match the contract or whose channel no record defines: each is skipped
//! and listed with its byte offset, channel and time span ([`DamageReport`]), and reading goes
//! on after it. A file that stops part-way is read up to where it stops ([`End::Cut`]).
//! [`Recording::load`] collects everything; [`crate::info`] computes the `bench info` report;
//! [`summary_counts`] reads the message counts of the summary section, an independent path.

pub(crate) mod chunk;
mod damage;
pub(crate) mod engine;
mod notes;
pub(crate) mod scan;

use std::{
    collections::BTreeMap,
    fs::File,
    io::{BufReader, Read, Seek, SeekFrom},
    path::{Path, PathBuf},
    sync::Arc,
};

use mcap::{
    records::{op, Record},
    sans_io::{SummaryReadEvent, SummaryReader},
};

pub use damage::{Damage, DamageKind, DamageReport};
use engine::{Chan, Decode, Engine, Kind, Msg, Unit};

use crate::message::{ChamberMsg, GyroMsg, Outcome, StepMsg, TableMsg};
use crate::schema::{MESSAGE_ENCODING, META_RUN, META_SITE};
use crate::site::{MetadataError, Site};

/// What stops a recording from being read at all. Damage inside a file is not an error (it is
/// skipped and listed: [`DamageReport`]), nor is a file that stops part-way (see [`End`]).
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened or read.
    #[error("{}: {source}", path.display())]
    Open {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Reading failed part-way.
    #[error("read error at byte {at_byte}: {source}")]
    Io {
        /// Bytes read so far.
        at_byte: u64,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The data does not start like an MCAP file.
    #[error("not an MCAP recording (at byte {at_byte}): {reason}")]
    NotMcap {
        /// Bytes read so far.
        at_byte: u64,
        /// What the MCAP reader saw.
        reason: String,
    },
    /// A required channel uses a message encoding other than `json`.
    #[error("{topic}: message encoding `{encoding}` is not `json`")]
    UnsupportedEncoding {
        /// Channel.
        topic: String,
        /// Its message encoding.
        encoding: String,
    },
    /// The summary section is present but unreadable.
    #[error("{}: summary section: {source}", path.display())]
    Summary {
        /// The file.
        path: PathBuf,
        /// The MCAP reader's error.
        #[source]
        source: mcap::McapError,
    },
}

/// A decoded message with its MCAP header fields.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamped<T> {
    /// When the sample was taken, ns since the Unix epoch.
    pub log_time_ns: u64,
    /// The device's time stamp, or `log_time_ns`.
    pub publish_time_ns: u64,
    /// Channel sequence number.
    pub sequence: u32,
    /// The body.
    pub msg: T,
}

/// A metadata record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MetadataRecord {
    /// Record name, e.g. `bench.run`.
    pub name: String,
    /// Its keys and values, unknown keys included.
    pub entries: BTreeMap<String, String>,
}

/// An attachment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AttachmentRecord {
    /// Name, e.g. `scenario.toml`.
    pub name: String,
    /// Media type, e.g. `application/toml`.
    pub media_type: String,
    /// Log time, ns since the Unix epoch.
    pub log_time_ns: u64,
    /// Content.
    pub data: Vec<u8>,
}

/// A channel as its Channel and Schema records define it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Channel id.
    pub id: u16,
    /// Topic.
    pub topic: String,
    /// Schema name (empty if none).
    pub schema_name: String,
    /// Schema encoding (empty if none).
    pub schema_encoding: String,
    /// Message encoding.
    pub message_encoding: String,
}

/// A message on a channel this reader does not decode (kept as raw bytes).
#[derive(Debug, Clone, PartialEq)]
pub struct OtherMessage {
    /// Its channel.
    pub channel: Arc<ChannelInfo>,
    /// Log time, ns since the Unix epoch.
    pub log_time_ns: u64,
    /// Publish time.
    pub publish_time_ns: u64,
    /// Sequence number.
    pub sequence: u32,
    /// Raw body.
    pub data: Vec<u8>,
}

/// One item of a recording, in file order.
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    /// `/gyro/rate`.
    Gyro(Stamped<GyroMsg>),
    /// `/table/state`.
    Table(Stamped<TableMsg>),
    /// `/chamber/state`.
    Chamber(Stamped<ChamberMsg>),
    /// `/bench/step`.
    Step(Stamped<StepMsg>),
    /// Any other channel (e.g. `/log`).
    Other(OtherMessage),
    /// A metadata record.
    Metadata(MetadataRecord),
    /// An attachment.
    Attachment(AttachmentRecord),
}

/// How the file ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum End {
    /// Not at the end yet.
    Reading,
    /// Data end, summary and footer were read: the file was finished normally.
    Complete,
    /// The file stops before its footer (a crashed run, or damage): everything before
    /// `at_byte` was read.
    Cut {
        /// Bytes read when the MCAP reader stopped.
        at_byte: u64,
        /// What the MCAP reader saw there.
        reason: String,
    },
}

/// One decoded item, a damaged part, or an error, as the workers hand them on.
enum Slot {
    Item(Item),
    Damage(Damage),
    Error(RecordingError),
}

/// Decodes the contract's channels into [`Item`]s; other channels stay raw.
struct Items;

impl Decode for Items {
    type Out = Vec<Slot>;

    fn start(&self) -> Vec<Slot> {
        Vec::new()
    }

    fn message(&self, out: &mut Vec<Slot>, chan: &Chan, m: Msg<'_>) {
        let h = &m.header;
        let slot = if chan.kind == Kind::Other {
            Slot::Item(Item::Other(OtherMessage {
                channel: chan.info.clone(),
                log_time_ns: h.log_time,
                publish_time_ns: h.publish_time,
                sequence: h.sequence,
                data: m.data.to_vec(),
            }))
        } else {
            match decode_body(chan.kind, &m) {
                Ok(item) => Slot::Item(item),
                Err(detail) => Slot::Damage(Damage {
                    at_byte: m.at,
                    bytes: 0,
                    kind: DamageKind::Message {
                        topic: chan.info.topic.clone(),
                        sequence: h.sequence,
                        log_time_ns: h.log_time,
                        detail,
                    },
                    span_ns: Some((h.log_time, h.log_time)),
                    lost: BTreeMap::new(),
                    in_summary: false,
                }),
            }
        };
        out.push(slot);
    }

    fn orphan(&self, out: &mut Vec<Slot>, m: Msg<'_>) {
        let h = &m.header;
        out.push(Slot::Damage(Damage {
            at_byte: m.at,
            bytes: 0,
            kind: DamageKind::Orphan {
                channel_id: h.channel_id,
                sequence: h.sequence,
                log_time_ns: h.log_time,
            },
            span_ns: Some((h.log_time, h.log_time)),
            lost: BTreeMap::new(),
            in_summary: false,
        }));
    }

    fn channel(&self, out: &mut Vec<Slot>, chan: &Chan) {
        if !conforms(chan.kind, &chan.info.message_encoding) {
            out.push(Slot::Error(RecordingError::UnsupportedEncoding {
                topic: chan.info.topic.clone(),
                encoding: chan.info.message_encoding.clone(),
            }));
        }
    }
}

/// Whether a channel of `kind` in `encoding` is one the contract allows: the contract's channels
/// are JSON; other channels are kept raw whatever their encoding.
fn conforms(kind: Kind, encoding: &str) -> bool {
    kind == Kind::Other || encoding == MESSAGE_ENCODING
}

/// A reader not started yet (options may still change).
struct Start<R> {
    source: R,
    limit: u64,
    file_len: Option<u64>,
    summary: Vec<(u8, Vec<u8>)>,
    raw: bool,
}

/// Streams one recording from any byte source, in file order (module docs). Damaged parts are
/// skipped and listed in [`RecordingReader::damage`]; items, their order and the damage are the
/// same however many threads decode.
pub struct RecordingReader<R> {
    start: Option<Start<R>>,
    engine: Option<Engine<R, Items>>,
    /// Items ready to hand out, in file order.
    ready: std::vec::IntoIter<Slot>,
    damage: DamageReport,
    /// Latest log time handed out, and the skipped spans waiting for the next one.
    last_log_ns: Option<u64>,
    open_spans: Vec<usize>,
    end: End,
    done: bool,
}

/// Largest record or chunk accepted when the file size is unknown.
pub(crate) const MAX_RECORD: usize = 1 << 30;

impl RecordingReader<BufReader<File>> {
    /// Open a file (its summary's channel definitions, where it has a readable one, stand in for
    /// definitions lost to damage).
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        Self::open_through(path, |file| file)
    }
}

impl<R: Read> RecordingReader<R> {
    /// Read from any source (records larger than 1 GiB are refused as damage).
    pub fn new(source: R) -> Self {
        Self::with_limit(source, MAX_RECORD as u64, None)
    }

    /// Read the file at `path` through `wrap` (e.g. a progress counter around the file).
    pub fn open_through(
        path: &Path,
        wrap: impl FnOnce(BufReader<File>) -> R,
    ) -> Result<Self, RecordingError> {
        let open = |source| RecordingError::Open { path: path.to_path_buf(), source };
        let mut file = File::open(path).map_err(open)?;
        let len = file.metadata().map_err(open)?.len();
        let summary = summary_records(&mut file, len).unwrap_or_default();
        file.seek(SeekFrom::Start(0)).map_err(open)?;
        let limit = len.min(MAX_RECORD as u64);
        let mut reader =
            Self::with_limit(wrap(BufReader::with_capacity(256 * 1024, file)), limit, Some(len));
        if let Some(s) = reader.start.as_mut() {
            s.summary = summary;
        }
        Ok(reader)
    }

    fn with_limit(source: R, limit: u64, file_len: Option<u64>) -> Self {
        Self {
            start: Some(Start {
                source,
                limit: limit.max(4096),
                file_len,
                summary: Vec::new(),
                raw: false,
            }),
            engine: None,
            ready: Vec::new().into_iter(),
            damage: DamageReport::default(),
            last_log_ns: None,
            open_spans: Vec::new(),
            end: End::Reading,
            done: false,
        }
    }

    /// Decode nothing: every message, on every channel, comes as [`Item::Other`] with its raw
    /// body (for tools that copy or export any channel).
    pub fn raw(mut self) -> Self {
        if let Some(s) = self.start.as_mut() {
            s.raw = true;
        }
        self
    }

    /// How the file ended (meaningful once the iterator returned `None`).
    pub fn end(&self) -> &End {
        &self.end
    }

    /// What was damaged and skipped so far.
    pub fn damage(&self) -> &DamageReport {
        &self.damage
    }

    /// Chunks read so far (damaged ones included), and how many of them had their CRC checked
    /// (a writer may leave a chunk's CRC 0: not computed).
    pub fn chunks_read(&self) -> (u64, u64) {
        self.engine.as_ref().map_or((0, 0), |e| (e.chunks_read, e.chunks_crc_checked))
    }

    /// Channels seen so far, by id (framing may run a few chunks ahead of the items handed
    /// out).
    pub fn channels(&self) -> Vec<ChannelInfo> {
        self.engine
            .as_ref()
            .map(|e| e.channels().iter().map(|c| c.as_ref().clone()).collect())
            .unwrap_or_default()
    }

    /// Bytes read so far (framing may run ahead of the items handed out).
    pub fn bytes_read(&self) -> u64 {
        self.engine.as_ref().map_or(0, |e| e.bytes_read())
    }

    /// The read loop of this reader, not started yet, decoding into `decoder`'s output instead
    /// of items (every channel raw: [`Kind::Other`]); `None` once the reader has started.
    #[cfg_attr(not(feature = "export"), allow(dead_code))]
    pub(crate) fn into_engine<D: Decode>(mut self, decoder: D) -> Result<Engine<R, D>, Box<Self>> {
        let Some(s) = self.start.take() else { return Err(Box::new(self)) };
        let mut e = Engine::new(s.source, s.limit, s.file_len, decoder, true);
        e.predefine(&s.summary);
        Ok(e)
    }

    fn engine(&mut self) -> &mut Engine<R, Items> {
        if let Some(s) = self.start.take() {
            let mut e = Engine::new(s.source, s.limit, s.file_len, Items, s.raw);
            e.predefine(&s.summary);
            self.engine = Some(e);
        }
        self.engine.as_mut().expect("started above")
    }

    fn note_damage(&mut self, mut d: Damage) {
        if let DamageKind::Bytes { .. } = d.kind {
            // Between the messages before and after it.
            if let Some(t) = self.last_log_ns {
                d.span_ns = Some((t, t));
                self.open_spans.push(self.damage.entries.len());
            }
        }
        self.damage.push(d);
    }

    fn note_time(&mut self, t: u64) {
        for i in self.open_spans.drain(..) {
            if let Some(Some(span)) = self.damage.entries.get_mut(i).map(|d| d.span_ns.as_mut()) {
                span.1 = span.1.max(t);
            }
        }
        self.last_log_ns = Some(self.last_log_ns.map_or(t, |l| l.max(t)));
    }
}

impl<R: Read> Iterator for RecordingReader<R> {
    type Item = Result<Item, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            match self.ready.next() {
                Some(Slot::Item(item)) => {
                    let t = match &item {
                        Item::Gyro(m) => Some(m.log_time_ns),
                        Item::Table(m) => Some(m.log_time_ns),
                        Item::Chamber(m) => Some(m.log_time_ns),
                        Item::Step(m) => Some(m.log_time_ns),
                        Item::Other(m) => Some(m.log_time_ns),
                        _ => None,
                    };
                    if let Some(t) = t {
                        self.note_time(t);
                    }
                    return Some(Ok(item));
                }
                Some(Slot::Damage(d)) => {
                    self.note_damage(d);
                    continue;
                }
                Some(Slot::Error(e)) => return Some(Err(e)),
                None => {}
            }
            if self.done {
                return None;
            }
            let unit = self.engine().next_unit();
            let Some(unit) = unit else {
                self.end = self.engine().end().clone();
                self.done = true;
                return None;
            };
            match unit {
                Unit::Out(slots) => self.ready = slots.into_iter(),
                Unit::Metadata(m) => return Some(Ok(Item::Metadata(m))),
                Unit::Attachment(a) => return Some(Ok(Item::Attachment(a))),
                Unit::Damage(d) => self.note_damage(d),
                Unit::Error(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

/// `mcap::parse_record`, without its panic on an Attachment record too short for its own
/// fields (mcap 0.26 slices `body[header_len..len - 4]` unchecked; found by fuzzing).
pub(crate) fn parse_record(opcode: u8, body: &[u8]) -> mcap::McapResult<Record<'_>> {
    if opcode == mcap::records::op::ATTACHMENT && !attachment_fits(body) {
        return Err(mcap::McapError::BadAttachmentLength {
            header: 0,
            available: body.len() as u64,
        });
    }
    mcap::parse_record(opcode, body)
}

/// Whether an Attachment record's body holds its times, name, media type, data length and
/// CRC (the data itself is checked by mcap).
fn attachment_fits(body: &[u8]) -> bool {
    let u32_at = |at: usize| {
        body.get(at..at.checked_add(4)?)
            .and_then(|b| <[u8; 4]>::try_from(b).ok())
            .map(|b| u32::from_le_bytes(b) as usize)
    };
    let mut at = 16usize; // log_time, create_time
    for _ in 0..2 {
        // name, media_type: u32 length and the bytes
        let Some(next) = u32_at(at).and_then(|n| at.checked_add(4)?.checked_add(n)) else {
            return false;
        };
        at = next;
    }
    at.checked_add(12).is_some_and(|end| end <= body.len()) // data length, CRC
}

/// Decode one message of a contract channel, or say which field is wrong.
fn decode_body(kind: Kind, m: &Msg<'_>) -> Result<Item, String> {
    let h = &m.header;
    macro_rules! stamped {
        ($variant:ident) => {
            Item::$variant(Stamped {
                log_time_ns: h.log_time,
                publish_time_ns: h.publish_time,
                sequence: h.sequence,
                msg: serde_json::from_slice(m.data).map_err(|e| diagnose(kind, m.data, &e))?,
            })
        };
    }
    Ok(match kind {
        Kind::Gyro => stamped!(Gyro),
        Kind::Table => stamped!(Table),
        Kind::Chamber => stamped!(Chamber),
        Kind::Step => stamped!(Step),
        Kind::Other => return Err("not a contract channel".into()),
    })
}

/// The summary section's records (opcode, body) of a finished file, every one framing and
/// parsing; `None` without a footer or where any of them is damaged. Where the section fails
/// its CRC, a flip that still parses is somewhere in it: a contract channel's definition there
/// is kept only if it conforms (its encoding the contract's), so a damaged fallback never
/// overrules the chunks' own intact definitions or fails the read.
pub(crate) fn summary_records<S: Read + Seek>(src: &mut S, len: u64) -> Option<Vec<(u8, Vec<u8>)>> {
    let (bytes, intact) = summary_section(src, len)?;
    let mut out = Vec::new();
    let mut at = 0usize;
    while at < bytes.len() {
        let opcode = *bytes.get(at)?;
        let n = u64::from_le_bytes(bytes.get(at + 1..at + 9)?.try_into().ok()?);
        let end = (at + 9).checked_add(usize::try_from(n).ok()?)?;
        let body = bytes.get(at + 9..end)?;
        let allowed = [
            op::SCHEMA,
            op::CHANNEL,
            op::CHUNK_INDEX,
            op::ATTACHMENT_INDEX,
            op::METADATA_INDEX,
            op::STATISTICS,
            op::SUMMARY_OFFSET,
        ];
        let record = parse_record(opcode, body);
        if !allowed.contains(&opcode) || record.is_err() {
            return None;
        }
        let kept = match record {
            Ok(Record::Channel(c)) => conforms(Kind::of(&c.topic), &c.message_encoding),
            _ => true,
        };
        if intact || kept {
            out.push((opcode, body.to_vec()));
        }
        at = end;
    }
    Some(out)
}

/// The bytes of the summary section, by the footer at the end of the file, and whether they
/// pass the footer's CRC.
fn summary_section<S: Read + Seek>(src: &mut S, len: u64) -> Option<(Vec<u8>, bool)> {
    // Footer record (opcode, length 20, summary start, summary offset start, CRC) + magic.
    const TAIL: u64 = 9 + 20 + 8;
    if len < 8 + TAIL {
        return None;
    }
    src.seek(SeekFrom::Start(len - TAIL)).ok()?;
    let mut tail = [0u8; TAIL as usize];
    src.read_exact(&mut tail).ok()?;
    if tail[29..] != mcap::MAGIC[..] || tail[0] != op::FOOTER || tail[1..9] != 20u64.to_le_bytes() {
        return None;
    }
    let start = u64::from_le_bytes(tail[9..17].try_into().ok()?);
    let footer_at = len - TAIL;
    if start == 0 || start < 8 || start > footer_at || footer_at - start > 64 << 20 {
        return None;
    }
    src.seek(SeekFrom::Start(start)).ok()?;
    let mut bytes = vec![0u8; usize::try_from(footer_at - start).ok()?];
    src.read_exact(&mut bytes).ok()?;
    // The footer's CRC covers the summary section and the footer up to the CRC itself (0: not
    // computed).
    let crc = u32::from_le_bytes(tail[25..29].try_into().ok()?);
    let intact = crc == 0 || {
        let crc32 = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
        let mut digest = crc32.digest();
        digest.update(&bytes);
        digest.update(&tail[..25]);
        digest.finalize() == crc
    };
    Some((bytes, intact))
}

/// JSON types of the contract's fields.
#[derive(Clone, Copy)]
enum Ty {
    Number,
    NumberOrNull,
    Unsigned,
    Text,
    Event,
}

/// Name the first contract field of `data` that is missing or of the wrong type; otherwise the
/// decoder's own message.
fn diagnose(kind: Kind, data: &[u8], err: &serde_json::Error) -> String {
    use serde_json::Value;
    let fields: &[(&str, Ty)] = match kind {
        Kind::Gyro => &[
            ("rate", Ty::Number),
            ("temperature", Ty::NumberOrNull),
            ("seq", Ty::Unsigned),
            ("status", Ty::Unsigned),
        ],
        Kind::Table => &[
            ("angle", Ty::Number),
            ("rate", Ty::Number),
            ("rate_command", Ty::Number),
            ("status", Ty::Unsigned),
        ],
        Kind::Chamber => {
            &[("temperature", Ty::Number), ("setpoint", Ty::Number), ("status", Ty::Unsigned)]
        }
        Kind::Step => &[
            ("index", Ty::Unsigned),
            ("name", Ty::Text),
            ("event", Ty::Event),
            ("label", Ty::Text),
        ],
        Kind::Other => &[],
    };
    let Ok(Value::Object(map)) = serde_json::from_slice::<Value>(data) else {
        return err.to_string();
    };
    for (name, ty) in fields {
        let v = map.get(*name);
        let (ok, want) = match ty {
            Ty::Number => (v.is_some_and(Value::is_number), "a number"),
            Ty::NumberOrNull => {
                (v.is_none_or(|v| v.is_number() || v.is_null()), "a number or null")
            }
            Ty::Unsigned => (v.is_some_and(Value::is_u64), "a non-negative integer"),
            Ty::Text => (v.is_some_and(Value::is_string), "a string"),
            Ty::Event => (
                v.and_then(Value::as_str).is_some_and(|e| ["start", "end", "abort"].contains(&e)),
                "\"start\", \"end\" or \"abort\"",
            ),
        };
        if !ok {
            return match v {
                None => format!("field `{name}` is missing"),
                Some(v) => format!("field `{name}` must be {want}, got {v}"),
            };
        }
    }
    err.to_string()
}

/// A whole recording in memory: the four required channels decoded, metadata, attachments.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// `/gyro/rate`, in file order.
    pub gyro: Vec<Stamped<GyroMsg>>,
    /// `/table/state`.
    pub table: Vec<Stamped<TableMsg>>,
    /// `/chamber/state`.
    pub chamber: Vec<Stamped<ChamberMsg>>,
    /// `/bench/step`.
    pub steps: Vec<Stamped<StepMsg>>,
    /// Messages on other channels (e.g. `/log`), counted by topic.
    pub other_counts: BTreeMap<String, u64>,
    /// Metadata records in file order.
    pub metadata: Vec<MetadataRecord>,
    /// Attachments in file order.
    pub attachments: Vec<AttachmentRecord>,
    /// Whether the file was finished normally.
    pub complete: bool,
    /// Where and why reading stopped, for a file without a footer.
    pub cut: Option<(u64, String)>,
    /// What was damaged and skipped (empty for an intact file).
    pub damage: DamageReport,
}

impl Recording {
    /// Read a recording file.
    pub fn load(path: &Path) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::open(path)?)
    }

    /// Read a recording file through `wrap` (e.g. a progress counter around the file).
    pub fn load_through<R: Read>(
        path: &Path,
        wrap: impl FnOnce(BufReader<File>) -> R,
    ) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::open_through(path, wrap)?)
    }

    /// Read a recording from any reader, e.g. one that counts the bytes for a progress bar.
    pub fn from_reader<R: Read>(source: R) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::new(source))
    }

    /// Read a recording from memory (its summary's channel definitions, where it has a
    /// readable one, stand in for definitions lost to damage).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, RecordingError> {
        let len = bytes.len() as u64;
        let summary = summary_records(&mut std::io::Cursor::new(bytes), len).unwrap_or_default();
        let mut reader = RecordingReader::with_limit(bytes, len, Some(len));
        if let Some(s) = reader.start.as_mut() {
            s.summary = summary;
        }
        Self::from_items(reader)
    }

    /// Read everything `reader` has left.
    pub fn from_items<R: Read>(mut reader: RecordingReader<R>) -> Result<Self, RecordingError> {
        let mut rec = Recording::default();
        for item in reader.by_ref() {
            rec.take(item?);
        }
        rec.finish_from(&reader);
        Ok(rec)
    }

    /// Keep one item read from the file, in file order (messages of other channels are
    /// counted by topic). A reader of a stream keeps what it does not reduce itself this way.
    pub fn take(&mut self, item: Item) {
        match item {
            Item::Gyro(m) => self.gyro.push(m),
            Item::Table(m) => self.table.push(m),
            Item::Chamber(m) => self.chamber.push(m),
            Item::Step(m) => self.steps.push(m),
            Item::Other(m) => *self.other_counts.entry(m.channel.topic.clone()).or_default() += 1,
            Item::Metadata(m) => self.metadata.push(m),
            Item::Attachment(a) => self.attachments.push(a),
        }
    }

    /// How the file ended and what was damaged, from the reader that has read it to its end.
    pub fn finish_from<R: Read>(&mut self, reader: &RecordingReader<R>) {
        match reader.end() {
            End::Complete => self.complete = true,
            End::Cut { at_byte, reason } => self.cut = Some((*at_byte, reason.clone())),
            End::Reading => {}
        }
        self.damage = reader.damage().clone();
    }

    /// The last metadata record called `name`.
    pub fn metadata(&self, name: &str) -> Option<&BTreeMap<String, String>> {
        self.metadata.iter().rev().find(|m| m.name == name).map(|m| &m.entries)
    }

    /// `bench.run` `outcome`, if the run recorded one the contract's way (`completed` or
    /// `aborted: <reason>`); [`Self::outcome_text`] has any text.
    pub fn outcome(&self) -> Option<Outcome> {
        Outcome::parse(self.outcome_text()?)
    }

    /// What `bench.gyro_model` is to the data (`bench.run` `gyro_model_role`; nominal when
    /// the recording does not say).
    pub fn gyro_model_role(&self) -> crate::ModelRole {
        crate::ModelRole::from_key(
            self.metadata(META_RUN)
                .and_then(|m| m.get(crate::schema::RUN_KEY_MODEL_ROLE))
                .map(String::as_str),
        )
    }

    /// `bench.run` `outcome` as written, if the run ended.
    pub fn outcome_text(&self) -> Option<&str> {
        self.metadata(META_RUN)?.get("outcome").map(String::as_str)
    }

    /// `bench.site`, checked ([`Site::from_metadata`]); `None` without a record or a latitude.
    pub fn site(&self) -> Result<Option<Site>, MetadataError> {
        self.metadata(META_SITE).map_or(Ok(None), Site::from_metadata)
    }

    /// The recording's time zero ([`time_zero_ns`]) over its four contract channels.
    pub fn time_zero_ns(&self) -> Option<u64> {
        time_zero_ns([
            self.gyro.iter().map(|m| m.log_time_ns).min(),
            self.table.iter().map(|m| m.log_time_ns).min(),
            self.chamber.iter().map(|m| m.log_time_ns).min(),
            self.steps.iter().map(|m| m.log_time_ns).min(),
        ])
    }
}

/// Time zero of a recording: the earliest `log_time` of any message on the contract's four
/// channels (gyro, table, chamber, steps), given each channel's earliest. Every time that bench
/// shows or analyses in seconds is counted from it; other channels (`/log`, a writer's extras)
/// do not move it.
pub fn time_zero_ns(channel_firsts: impl IntoIterator<Item = Option<u64>>) -> Option<u64> {
    channel_firsts.into_iter().flatten().min()
}

/// Seconds from `zero_ns` to `t_ns` (negative before it).
pub fn seconds_since(zero_ns: u64, t_ns: u64) -> f64 {
    if t_ns >= zero_ns {
        (t_ns - zero_ns) as f64 * 1e-9
    } else {
        -((zero_ns - t_ns) as f64 * 1e-9)
    }
}

/// The summary section of the file at `path`, read without the data section; `None` when it
/// has none (no footer: a crashed run).
pub fn read_summary(path: &Path) -> Result<Option<mcap::Summary>, RecordingError> {
    let open = |source| RecordingError::Open { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(open)?;
    let len = file.metadata().map_err(open)?.len();
    // No end magic: no footer, no summary.
    let mut tail = [0u8; 8];
    if len < 8 + 8 + 29 {
        return Ok(None);
    }
    file.seek(SeekFrom::End(-8)).map_err(open)?;
    file.read_exact(&mut tail).map_err(open)?;
    if tail != mcap::MAGIC {
        return Ok(None);
    }
    // mcap's summary reader parses every record it meets (and panics on some damaged ones):
    // each is checked here first.
    if summary_records(&mut file, len).is_none() {
        let source = mcap::McapError::BadFooter;
        return Err(RecordingError::Summary { path: path.to_path_buf(), source });
    }
    file.seek(SeekFrom::Start(0)).map_err(open)?;
    let summary_err = |source| RecordingError::Summary { path: path.to_path_buf(), source };
    let mut reader = SummaryReader::new_with_options(
        mcap::sans_io::SummaryReaderOptions::default().with_file_size(len),
    );
    while let Some(event) = reader.next_event() {
        match event.map_err(summary_err)? {
            SummaryReadEvent::ReadRequest(n) => {
                let got = file.read(reader.insert(n)).map_err(open)?;
                reader.notify_read(got);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = file.seek(to).map_err(open)?;
                reader.notify_seeked(pos);
            }
        }
    }
    Ok(reader.finish())
}

/// Message counts per topic from the file's summary section (Statistics record), read without
/// the data section: `None` when the file has no summary or no statistics (a crashed run).
pub fn summary_counts(path: &Path) -> Result<Option<BTreeMap<String, u64>>, RecordingError> {
    let Some(summary) = read_summary(path)? else {
        return Ok(None);
    };
    let Some(stats) = summary.stats.as_ref() else {
        return Ok(None);
    };
    let mut counts = BTreeMap::new();
    for (id, n) in &stats.channel_message_counts {
        let topic = summary
            .channels
            .get(id)
            .map(|c| c.topic.clone())
            .unwrap_or_else(|| format!("(channel {id})"));
        *counts.entry(topic).or_default() += n;
    }
    Ok(Some(counts))
}

#[cfg(test)]
mod tests;
