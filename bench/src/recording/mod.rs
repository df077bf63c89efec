//! Reader of bench recordings (`/work/shared/spec/recording.md`): accepts any conforming MCAP
//! file, whoever wrote it — with or without a summary section (a crashed run), chunked or not,
//! chunks compressed with zstd, lz4 or not at all.
//!
//! [`RecordingReader`] streams a file in one linear pass (built on the sans-IO
//! `mcap::sans_io::LinearReader`, so memory stays at about one chunk) and decodes the four
//! required channels into typed messages, ignoring unknown channels and unknown fields.
//! [`Recording::load`] collects everything; [`info`] computes the `bench info` report;
//! [`summary_counts`] reads the message counts of the summary section, an independent path.
//!
//! ```no_run
//! let rec = bench::recording::Recording::load(std::path::Path::new("run.mcap"))?;
//! println!("{} gyro samples, outcome {:?}", rec.gyro.len(), rec.outcome());
//! # Ok::<(), bench::recording::RecordingError>(())
//! ```

mod info;

pub use info::{info, info_from_reader, ChannelReport, Gap, RecordingInfo, StepReport};

use std::{
    collections::{BTreeMap, HashMap},
    fs::File,
    io::{BufReader, Read, Seek, SeekFrom},
    path::{Path, PathBuf},
    sync::Arc,
};

use mcap::{
    records::Record,
    sans_io::{
        LinearReadEvent, LinearReader, LinearReaderOptions, SummaryReadEvent, SummaryReader,
    },
};
use serde::Deserialize;

use crate::record::schema::{
    MESSAGE_ENCODING, META_RUN, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_STEP, TOPIC_TABLE,
};
pub use crate::record::{Outcome, StepEvent};

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

/// `/gyro/rate` body.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct GyroMsg {
    /// Mean rate over the sample interval ending at log_time, rad/s.
    #[serde(rename = "rate")]
    pub rate_rad_s: f64,
    /// Gyro internal temperature, °C, if it has a sensor.
    #[serde(rename = "temperature", default)]
    pub temperature_c: Option<f64>,
    /// Device sample counter.
    pub seq: u64,
    /// Status bits, 0 = valid.
    pub status: u32,
}

/// `/table/state` body.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct TableMsg {
    /// Unwrapped axis angle, rad.
    #[serde(rename = "angle")]
    pub angle_rad: f64,
    /// Measured rate, rad/s.
    #[serde(rename = "rate")]
    pub rate_rad_s: f64,
    /// Commanded rate, rad/s.
    #[serde(rename = "rate_command")]
    pub rate_command_rad_s: f64,
    /// Status bits, 0 = ok.
    pub status: u32,
}

/// `/chamber/state` body.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct ChamberMsg {
    /// Chamber air temperature, °C.
    #[serde(rename = "temperature")]
    pub temperature_c: f64,
    /// Working set point, °C.
    #[serde(rename = "setpoint")]
    pub setpoint_c: f64,
    /// Status bits, 0 = ok.
    pub status: u32,
}

/// `/bench/step` body.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct StepMsg {
    /// Step index.
    pub index: u64,
    /// Step name.
    pub name: String,
    /// Start, end or abort.
    pub event: StepEvent,
    /// Label (a label starting with `record` marks calibration data).
    pub label: String,
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
pub struct RecordingReader<R> {
    source: R,
    reader: LinearReader,
    at_byte: u64,
    records: u64,
    schemas: HashMap<u16, (String, String)>,
    channels: HashMap<u16, Chan>,
    end: End,
    failed: bool,
    raw: bool,
}

/// Largest record or chunk accepted when the file size is unknown.
const MAX_RECORD: usize = 1 << 30;

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
            source,
            reader: LinearReader::new_with_options(options),
            at_byte: 0,
            records: 0,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            end: End::Reading,
            failed: false,
            raw: false,
        }
    }

    /// Decode nothing: every message, on every channel, comes as [`Item::Other`] with its raw
    /// body (for tools that copy or export any channel).
    pub fn raw(mut self) -> Self {
        self.raw = true;
        self
    }

    /// How the file ended (meaningful once the iterator returned `None`).
    pub fn end(&self) -> &End {
        &self.end
    }

    /// Channels seen so far, by id.
    pub fn channels(&self) -> impl Iterator<Item = &ChannelInfo> {
        self.channels.values().map(|c| c.info.as_ref())
    }

    /// Bytes read so far.
    pub fn bytes_read(&self) -> u64 {
        self.at_byte
    }

    fn stop(&mut self, reason: String) -> Option<Result<Item, RecordingError>> {
        self.failed = true;
        if self.records == 0 {
            return Some(Err(RecordingError::NotMcap { at_byte: self.at_byte, reason }));
        }
        self.end = End::Cut { at_byte: self.at_byte, reason };
        None
    }

    fn on_record(&mut self, record: Record<'_>) -> Result<Option<Item>, RecordingError> {
        self.records += 1;
        Ok(match record {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, (header.name, header.encoding));
                None
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
                    return Err(RecordingError::UnsupportedEncoding {
                        topic: c.topic,
                        encoding: c.message_encoding,
                    });
                }
                let info = ChannelInfo {
                    id: c.id,
                    topic: c.topic,
                    schema_name,
                    schema_encoding,
                    message_encoding: c.message_encoding,
                };
                // The summary repeats channels; keep the first definition.
                self.channels.entry(c.id).or_insert(Chan { info: Arc::new(info), kind });
                None
            }
            Record::Message { header, data } => {
                let Some(chan) = self.channels.get(&header.channel_id) else {
                    return Err(RecordingError::UnknownChannel {
                        channel_id: header.channel_id,
                        sequence: header.sequence,
                        at_byte: self.at_byte,
                    });
                };
                let bad = |source| RecordingError::BadMessage {
                    topic: chan.info.topic.clone(),
                    sequence: header.sequence,
                    log_time_ns: header.log_time,
                    at_byte: self.at_byte,
                    detail: diagnose(chan.kind, &data, &source),
                    source,
                };
                macro_rules! stamped {
                    ($variant:ident) => {
                        Item::$variant(Stamped {
                            log_time_ns: header.log_time,
                            publish_time_ns: header.publish_time,
                            sequence: header.sequence,
                            msg: serde_json::from_slice(&data).map_err(bad)?,
                        })
                    };
                }
                Some(match chan.kind {
                    Kind::Gyro => stamped!(Gyro),
                    Kind::Table => stamped!(Table),
                    Kind::Chamber => stamped!(Chamber),
                    Kind::Step => stamped!(Step),
                    Kind::Other => Item::Other(OtherMessage {
                        channel: chan.info.clone(),
                        log_time_ns: header.log_time,
                        publish_time_ns: header.publish_time,
                        sequence: header.sequence,
                        data: data.into_owned(),
                    }),
                })
            }
            Record::Metadata(m) => {
                Some(Item::Metadata(MetadataRecord { name: m.name, entries: m.metadata }))
            }
            Record::Attachment { header, data, .. } => Some(Item::Attachment(AttachmentRecord {
                name: header.name,
                media_type: header.media_type,
                log_time_ns: header.log_time,
                data: data.into_owned(),
            })),
            Record::Footer(_) => {
                self.end = End::Complete;
                None
            }
            _ => None,
        })
    }
}

impl<R: Read> Iterator for RecordingReader<R> {
    type Item = Result<Item, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            let parsed = match self.reader.next_event()? {
                Err(e) => return self.stop(e.to_string()),
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let n = loop {
                        match self.source.read(self.reader.insert(need)) {
                            Ok(n) => break n,
                            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                            Err(source) => {
                                self.failed = true;
                                return Some(Err(RecordingError::Io {
                                    at_byte: self.at_byte,
                                    source,
                                }));
                            }
                        }
                    };
                    self.reader.notify_read(n);
                    self.at_byte += n as u64;
                    continue;
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    mcap::parse_record(opcode, data).map(Record::into_owned)
                }
            };
            match parsed {
                Err(e) => return self.stop(format!("bad record: {e}")),
                Ok(record) => match self.on_record(record) {
                    Ok(Some(item)) => return Some(Ok(item)),
                    Ok(None) => {}
                    Err(e) => return Some(Err(e)),
                },
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

    /// `bench.run` `outcome`, if the run recorded one.
    pub fn outcome(&self) -> Option<&str> {
        self.metadata(META_RUN)?.get("outcome").map(String::as_str)
    }
}

/// Message counts per topic from the file's summary section (Statistics record), read without
/// the data section: `None` when the file has no summary or no statistics (a crashed run).
pub fn summary_counts(path: &Path) -> Result<Option<BTreeMap<String, u64>>, RecordingError> {
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
    let Some(summary) = reader.finish() else {
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
