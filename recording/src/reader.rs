//! The reader: accepts any conforming MCAP file, whoever wrote it — with or without a summary
//! section (a crashed run), chunked or not, chunks compressed with zstd, lz4 or not at all.
//!
//! [`RecordingReader`] streams a file in one linear pass (built on the sans-IO
//! `mcap::sans_io::LinearReader`, so memory stays at about one chunk) and decodes the four
//! required channels into typed messages, ignoring unknown channels and unknown fields.
//! [`Recording::load`] collects everything; [`crate::info`] computes the `bench info` report;
//! [`summary_counts`] reads the message counts of the summary section, an independent path.

use std::{
    collections::{BTreeMap, HashMap},
    fs::File,
    io::{BufReader, Read, Seek, SeekFrom},
    path::{Path, PathBuf},
    sync::{
        mpsc::{sync_channel, Receiver, SyncSender},
        Arc,
    },
};

use mcap::{
    records::Record,
    sans_io::{
        LinearReadEvent, LinearReader, LinearReaderOptions, SummaryReadEvent, SummaryReader,
    },
};

use crate::message::{ChamberMsg, GyroMsg, Outcome, StepMsg, TableMsg};
use crate::schema::{
    MESSAGE_ENCODING, META_RUN, META_SITE, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_STEP, TOPIC_TABLE,
};
use crate::site::{MetadataError, Site};

/// What went wrong reading a recording. Damage at the end of a file (a crashed run) is not an
/// error: see [`End`].
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
    /// A message on a required channel does not decode as its contract schema says.
    #[error(
        "{topic} message sequence {sequence} (log_time {log_time_ns} ns, before byte {at_byte}): \
         body does not match the contract: {detail}"
    )]
    BadMessage {
        /// Channel.
        topic: String,
        /// Channel sequence number.
        sequence: u32,
        /// Log time.
        log_time_ns: u64,
        /// Bytes read so far.
        at_byte: u64,
        /// Which field is wrong and how (or the JSON syntax error with its column).
        detail: String,
        /// The JSON decoder's error.
        #[source]
        source: serde_json::Error,
    },
    /// A required channel uses a message encoding other than `json`.
    #[error("{topic}: message encoding `{encoding}` is not `json`")]
    UnsupportedEncoding {
        /// Channel.
        topic: String,
        /// Its message encoding.
        encoding: String,
    },
    /// A message refers to a channel that no earlier Channel record defined.
    #[error("message sequence {sequence} (before byte {at_byte}) refers to unknown channel id {channel_id}")]
    UnknownChannel {
        /// Channel id.
        channel_id: u16,
        /// Sequence number.
        sequence: u32,
        /// Bytes read so far.
        at_byte: u64,
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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Gyro,
    Table,
    Chamber,
    Step,
    Other,
}

struct Chan {
    info: Arc<ChannelInfo>,
    kind: Kind,
}

/// Streams one recording from any byte source, in file order.
///
/// Framing (reading, chunk decompression and CRC checks) runs on the caller's thread; once a file
/// holds more than one batch of messages, the JSON bodies of the contract's channels are decoded
/// on a second thread, a batch behind, so the two overlap. Items, errors and their order are the
/// same either way.
pub struct RecordingReader<R> {
    framer: Framer<R>,
    /// Items ready to hand out, in file order.
    ready: std::vec::IntoIter<Result<Item, RecordingError>>,
    decoder: Decoder,
}

/// The single-threaded half: bytes in, records framed, message bodies batched.
struct Framer<R> {
    source: R,
    reader: LinearReader,
    state: FrameState,
}

struct FrameState {
    at_byte: u64,
    records: u64,
    schemas: HashMap<u16, (String, String)>,
    /// Indexed by channel id.
    channels: Vec<Option<Chan>>,
    end: End,
    /// No more input: the file ended, was cut, or failed.
    done: bool,
    raw: bool,
}

/// Where message bodies are decoded.
enum Decoder {
    /// Nothing framed yet.
    Unstarted,
    /// On the caller's thread (a file of one batch, or no thread could be started).
    Inline,
    /// On a worker thread, `in_flight` batches behind the framing.
    Worker {
        to: SyncSender<Batch>,
        from: Receiver<Vec<Result<Item, RecordingError>>>,
        in_flight: usize,
    },
}

/// Messages framed per batch handed to the decoder.
const BATCH_MESSAGES: usize = 2048;
/// Batches the framing may run ahead of the decoding.
const MAX_IN_FLIGHT: usize = 2;

/// Framed records in file order; message bodies still to decode are slices of `bytes`.
#[derive(Default)]
struct Batch {
    bytes: Vec<u8>,
    slots: Vec<Slot>,
}

enum Slot {
    Ready(Result<Item, RecordingError>),
    Body(Body),
}

/// A message on one of the contract's channels, framed but not decoded.
struct Body {
    kind: Kind,
    log_time_ns: u64,
    publish_time_ns: u64,
    sequence: u32,
    at_byte: u64,
    range: std::ops::Range<usize>,
}

/// Largest record or chunk accepted when the file size is unknown.
pub(crate) const MAX_RECORD: usize = 1 << 30;

impl RecordingReader<BufReader<File>> {
    /// Open a file.
    pub fn open(path: &Path) -> Result<Self, RecordingError> {
        let open = |source| RecordingError::Open { path: path.to_path_buf(), source };
        let file = File::open(path).map_err(open)?;
        let len = file.metadata().map_err(open)?.len();
        let limit = usize::try_from(len).unwrap_or(MAX_RECORD).min(MAX_RECORD);
        Ok(Self::with_limit(BufReader::with_capacity(256 * 1024, file), limit))
    }
}

impl<R: Read> RecordingReader<R> {
    /// Read from any source (records larger than 1 GiB are refused as damage).
    pub fn new(source: R) -> Self {
        Self::with_limit(source, MAX_RECORD)
    }

    fn with_limit(source: R, record_length_limit: usize) -> Self {
        let options = LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(record_length_limit.max(4096));
        Self {
            framer: Framer {
                source,
                reader: LinearReader::new_with_options(options),
                state: FrameState {
                    at_byte: 0,
                    records: 0,
                    schemas: HashMap::new(),
                    channels: Vec::new(),
                    end: End::Reading,
                    done: false,
                    raw: false,
                },
            },
            ready: Vec::new().into_iter(),
            decoder: Decoder::Unstarted,
        }
    }

    /// Decode nothing: every message, on every channel, comes as [`Item::Other`] with its raw
    /// body (for tools that copy or export any channel).
    pub fn raw(mut self) -> Self {
        self.framer.state.raw = true;
        self
    }

    /// How the file ended (meaningful once the iterator returned `None`).
    pub fn end(&self) -> &End {
        &self.framer.state.end
    }

    /// Channels seen so far, by id (framing may run a few thousand messages ahead of the items
    /// handed out).
    pub fn channels(&self) -> impl Iterator<Item = &ChannelInfo> {
        self.framer.state.channels.iter().flatten().map(|c| c.info.as_ref())
    }

    /// Bytes read so far (framing may run ahead of the items handed out).
    pub fn bytes_read(&self) -> u64 {
        self.framer.state.at_byte
    }
}

impl<R: Read> Framer<R> {
    /// Frame records until a batch is full or the input ends.
    fn batch(&mut self) -> Batch {
        let mut batch = Batch {
            bytes: Vec::with_capacity(BATCH_MESSAGES * 128),
            slots: Vec::with_capacity(BATCH_MESSAGES),
        };
        let state = &mut self.state;
        while !state.done && batch.slots.len() < BATCH_MESSAGES {
            let Some(event) = self.reader.next_event() else {
                state.done = true;
                break;
            };
            let parsed = match event {
                Err(e) => {
                    state.stop(e.to_string(), &mut batch);
                    break;
                }
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let n = loop {
                        match self.source.read(self.reader.insert(need)) {
                            Ok(n) => break Ok(n),
                            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                            Err(source) => break Err(source),
                        }
                    };
                    match n {
                        Ok(n) => {
                            self.reader.notify_read(n);
                            state.at_byte += n as u64;
                        }
                        Err(source) => {
                            state.done = true;
                            let at_byte = state.at_byte;
                            batch
                                .slots
                                .push(Slot::Ready(Err(RecordingError::Io { at_byte, source })));
                        }
                    }
                    continue;
                }
                Ok(LinearReadEvent::Record { opcode, data }) => parse_record(opcode, data),
            };
            match parsed {
                Err(e) => state.stop(format!("bad record: {e}"), &mut batch),
                Ok(record) => state.on_record(record, &mut batch),
            }
        }
        batch
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

impl FrameState {
    /// The MCAP reader gave up: a file that never looked like MCAP is an error, anything after
    /// the first record is a cut file.
    fn stop(&mut self, reason: String, batch: &mut Batch) {
        self.done = true;
        if self.records == 0 {
            let at_byte = self.at_byte;
            batch.slots.push(Slot::Ready(Err(RecordingError::NotMcap { at_byte, reason })));
        } else {
            self.end = End::Cut { at_byte: self.at_byte, reason };
        }
    }

    fn on_record(&mut self, record: Record<'_>, batch: &mut Batch) {
        self.records += 1;
        let ready = |batch: &mut Batch, item| batch.slots.push(Slot::Ready(item));
        match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let (schema_name, schema_encoding) =
                    self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                let kind = match c.topic.as_str() {
                    _ if self.raw => Kind::Other,
                    TOPIC_GYRO => Kind::Gyro,
                    TOPIC_TABLE => Kind::Table,
                    TOPIC_CHAMBER => Kind::Chamber,
                    TOPIC_STEP => Kind::Step,
                    _ => Kind::Other,
                };
                if kind != Kind::Other && c.message_encoding != MESSAGE_ENCODING {
                    let error = RecordingError::UnsupportedEncoding {
                        topic: c.topic,
                        encoding: c.message_encoding,
                    };
                    return ready(batch, Err(error));
                }
                let info = ChannelInfo {
                    id: c.id,
                    topic: c.topic,
                    schema_name,
                    schema_encoding,
                    message_encoding: c.message_encoding,
                };
                // The summary repeats channels; keep the first definition.
                let id = usize::from(c.id);
                if self.channels.len() <= id {
                    self.channels.resize_with(id + 1, || None);
                }
                self.channels[id].get_or_insert(Chan { info: Arc::new(info), kind });
            }
            Record::Message { header, data } => {
                let Some(Some(chan)) = self.channels.get(usize::from(header.channel_id)) else {
                    let error = RecordingError::UnknownChannel {
                        channel_id: header.channel_id,
                        sequence: header.sequence,
                        at_byte: self.at_byte,
                    };
                    return ready(batch, Err(error));
                };
                if chan.kind == Kind::Other {
                    let item = Item::Other(OtherMessage {
                        channel: chan.info.clone(),
                        log_time_ns: header.log_time,
                        publish_time_ns: header.publish_time,
                        sequence: header.sequence,
                        data: data.into_owned(),
                    });
                    return ready(batch, Ok(item));
                }
                let start = batch.bytes.len();
                batch.bytes.extend_from_slice(&data);
                batch.slots.push(Slot::Body(Body {
                    kind: chan.kind,
                    log_time_ns: header.log_time,
                    publish_time_ns: header.publish_time,
                    sequence: header.sequence,
                    at_byte: self.at_byte,
                    range: start..batch.bytes.len(),
                }));
            }
            Record::Metadata(m) => ready(
                batch,
                Ok(Item::Metadata(MetadataRecord { name: m.name, entries: m.metadata })),
            ),
            Record::Attachment { header, data, .. } => ready(
                batch,
                Ok(Item::Attachment(AttachmentRecord {
                    name: header.name,
                    media_type: header.media_type,
                    log_time_ns: header.log_time,
                    data: data.into_owned(),
                })),
            ),
            Record::Footer(_) => self.end = End::Complete,
            _ => {}
        }
    }
}

/// Decode a batch's message bodies, keeping file order.
fn decode(batch: Batch) -> Vec<Result<Item, RecordingError>> {
    let Batch { bytes, slots } = batch;
    slots
        .into_iter()
        .map(|slot| match slot {
            Slot::Ready(item) => item,
            Slot::Body(b) => decode_body(&b, &bytes[b.range.clone()]),
        })
        .collect()
}

fn decode_body(b: &Body, data: &[u8]) -> Result<Item, RecordingError> {
    let topic = match b.kind {
        Kind::Gyro => TOPIC_GYRO,
        Kind::Table => TOPIC_TABLE,
        Kind::Chamber => TOPIC_CHAMBER,
        Kind::Step => TOPIC_STEP,
        Kind::Other => "",
    };
    let bad = |source| RecordingError::BadMessage {
        topic: topic.to_string(),
        sequence: b.sequence,
        log_time_ns: b.log_time_ns,
        at_byte: b.at_byte,
        detail: diagnose(b.kind, data, &source),
        source,
    };
    macro_rules! stamped {
        ($variant:ident) => {
            Item::$variant(Stamped {
                log_time_ns: b.log_time_ns,
                publish_time_ns: b.publish_time_ns,
                sequence: b.sequence,
                msg: serde_json::from_slice(data).map_err(bad)?,
            })
        };
    }
    Ok(match b.kind {
        Kind::Gyro => stamped!(Gyro),
        Kind::Table => stamped!(Table),
        Kind::Chamber => stamped!(Chamber),
        Kind::Step => stamped!(Step),
        // Framing hands out other channels' messages as they are.
        Kind::Other => return Err(bad(serde::de::Error::custom("not a contract channel"))),
    })
}

/// A thread decoding batches in the order they are sent; `None` if it cannot be started.
fn spawn_decoder() -> Option<Decoder> {
    let (to, batches) = sync_channel::<Batch>(MAX_IN_FLIGHT);
    let (decoded, from) = sync_channel(MAX_IN_FLIGHT);
    std::thread::Builder::new()
        .name("recording-decode".into())
        .spawn(move || {
            // Ends when the reader is dropped (either channel closes).
            for batch in batches {
                if decoded.send(decode(batch)).is_err() {
                    break;
                }
            }
        })
        .map_err(|e| tracing::debug!("decoding recordings on the reading thread: {e}"))
        .ok()?;
    Some(Decoder::Worker { to, from, in_flight: 0 })
}

impl<R: Read> Iterator for RecordingReader<R> {
    type Item = Result<Item, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(item) = self.ready.next() {
                return Some(item);
            }
            match &mut self.decoder {
                Decoder::Unstarted => {
                    let batch = self.framer.batch();
                    let worker = if self.framer.state.done { None } else { spawn_decoder() };
                    let unsent = match worker {
                        Some(Decoder::Worker { to, from, .. }) => match to.send(batch) {
                            Ok(()) => {
                                self.decoder = Decoder::Worker { to, from, in_flight: 1 };
                                continue;
                            }
                            Err(std::sync::mpsc::SendError(batch)) => batch,
                        },
                        _ => batch,
                    };
                    // One batch, or no thread: decode here.
                    self.decoder = Decoder::Inline;
                    self.ready = decode(unsent).into_iter();
                }
                Decoder::Inline => {
                    if self.framer.state.done {
                        return None;
                    }
                    self.ready = decode(self.framer.batch()).into_iter();
                }
                Decoder::Worker { to, from, in_flight } => {
                    while *in_flight < MAX_IN_FLIGHT && !self.framer.state.done {
                        if to.send(self.framer.batch()).is_err() {
                            break;
                        }
                        *in_flight += 1;
                    }
                    if *in_flight == 0 {
                        return None;
                    }
                    match from.recv() {
                        Ok(items) => {
                            *in_flight -= 1;
                            self.ready = items.into_iter();
                        }
                        Err(_) => {
                            // The decoding thread is gone (it cannot panic on input, so this
                            // is a resource failure): report it where reading stopped.
                            let at_byte = self.framer.state.at_byte;
                            self.framer.state.done = true;
                            self.decoder = Decoder::Inline;
                            return Some(Err(RecordingError::Io {
                                at_byte,
                                source: std::io::Error::other("the decoding thread stopped"),
                            }));
                        }
                    }
                }
            }
        }
    }
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
}

impl Recording {
    /// Read a recording file.
    pub fn load(path: &Path) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::open(path)?)
    }

    /// Read a recording from any reader, e.g. one that counts the bytes for a progress bar.
    pub fn from_reader<R: Read>(source: R) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::new(source))
    }

    /// Read a recording from memory.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, RecordingError> {
        Self::from_items(RecordingReader::with_limit(bytes, bytes.len()))
    }

    fn from_items<R: Read>(mut reader: RecordingReader<R>) -> Result<Self, RecordingError> {
        let mut rec = Recording::default();
        for item in reader.by_ref() {
            match item? {
                Item::Gyro(m) => rec.gyro.push(m),
                Item::Table(m) => rec.table.push(m),
                Item::Chamber(m) => rec.chamber.push(m),
                Item::Step(m) => rec.steps.push(m),
                Item::Other(m) => {
                    *rec.other_counts.entry(m.channel.topic.clone()).or_default() += 1
                }
                Item::Metadata(m) => rec.metadata.push(m),
                Item::Attachment(a) => rec.attachments.push(a),
            }
        }
        match reader.end() {
            End::Complete => rec.complete = true,
            End::Cut { at_byte, reason } => rec.cut = Some((*at_byte, reason.clone())),
            End::Reading => {}
        }
        Ok(rec)
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
