//! `bench export REC.mcap --format csv|parquet`: one table per channel, for pandas and Polars.
//!
//! Columns: `timestamp` (the log time: TIMESTAMP(NANOS, UTC) in Parquet, RFC 3339 UTC text
//! with nanoseconds in CSV), `log_time_ns`, `publish_time_ns`, `sequence`, then the message's
//! JSON fields in the order they first appear, nested objects flattened with dots
//! (`timestamp.sec`; a channel with a field `timestamp` gets `log_timestamp` instead). A field
//! the recording contract defines has the contract's type whatever the values
//! ([`contract_type`]: a gyro without a temperature sensor still has a DOUBLE
//! `temperature` column, all null). Other columns take the narrowest type of their values: all
//! integers an integer column (i64; u64 above `i64::MAX` make it a float column), all numbers a
//! float column (f64), all booleans a boolean column; anything else is text (arrays and mixed
//! values as JSON text). A missing field or `null` is an empty CSV cell or a Parquet NULL.
//! Channels whose message encoding is not `json` are skipped and reported. Any readable
//! recording exports, a cut one up to its cut.
//!
//! Units: every table carries the unit of each column that has one — Parquet in the file's
//! key-value metadata (`unit.<column>` = `rad/s`, and all of them as one JSON object under
//! `bench.units`), CSV in a sidecar `NAME.units.csv` (`column,unit`, one row per column, the
//! unit empty where there is none). With `merged`, one more table, `merged`: every gyro sample
//! with the latest table and chamber readings logged at or before it (an as-of join: nothing
//! from the future, nothing interpolated) and the label of the record window it falls in, null
//! outside ([`MERGED`]).
//!
//! ```no_run
//! use bench_recording::export::{export_file, Format};
//! let report = export_file("run.mcap".as_ref(), "out".as_ref(), Format::Csv)?;
//! for t in &report.tables { println!("{} → {} ({} rows)", t.topic, t.path.display(), t.rows); }
//! # Ok::<(), bench_recording::export::ExportError>(())
//! ```

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::Value;

use crate::message::{StepEvent, StepMsg};
use crate::reader::engine::{Chan, Decode, Msg, Unit};
use crate::reader::{ChannelInfo, End, Item, RecordingError, RecordingReader};

/// Output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated text, one header line.
    Csv,
    /// Apache Parquet, one row group, zstd-compressed columns.
    Parquet,
}

impl Format {
    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Parquet => "parquet",
        }
    }
}

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The recording could not be read.
    #[error(transparent)]
    Read(#[from] RecordingError),
    /// An output file could not be written.
    #[error("{}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The Parquet writer failed.
    #[error("{}: {source}", path.display())]
    Parquet {
        /// The file.
        path: PathBuf,
        /// The writer's error.
        #[source]
        source: parquet::errors::ParquetError,
    },
    /// A message body is not a JSON object.
    #[error("{topic} message sequence {sequence} (log_time {log_time_ns} ns): body is not a JSON object: {detail}")]
    NotJson {
        /// Channel.
        topic: String,
        /// Sequence.
        sequence: u32,
        /// Log time.
        log_time_ns: u64,
        /// What the decoder said.
        detail: String,
    },
}

/// One written table.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Channel.
    pub topic: String,
    /// File written.
    pub path: PathBuf,
    /// Rows (messages).
    pub rows: usize,
    /// Column names.
    pub columns: Vec<String>,
    /// The CSV table's units sidecar (`NAME.units.csv`); `None` for Parquet, which carries
    /// them in its metadata.
    pub units: Option<PathBuf>,
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExportReport {
    /// One per exported channel, by topic.
    pub tables: Vec<Table>,
    /// Channels skipped (not JSON), with their encoding.
    pub skipped: Vec<(String, String)>,
    /// Where the recording was cut, if it was.
    pub cut: Option<(u64, String)>,
}

/// The topic name given to the as-of-merged table in an [`ExportReport`].
pub const MERGED: &str = "(merged)";

/// The SI unit of a column of a contract channel (or of the merged table), as the recording
/// format defines it; `None` for a column without one.
pub fn column_unit(topic: &str, column: &str) -> Option<&'static str> {
    let (topic, column) = match (topic, column) {
        (MERGED, c) => match c.split_once('_') {
            Some(("gyro", rest)) => ("/gyro/rate", rest),
            Some(("table", rest)) => ("/table/state", rest),
            Some(("chamber", rest)) => ("/chamber/state", rest),
            _ if c == "bench_time_s" => return Some("s"),
            _ => (topic, c),
        },
        other => other,
    };
    match (topic, column) {
        (_, "log_time_ns" | "publish_time_ns") => Some("ns"),
        ("/gyro/rate" | "/table/state", "rate") => Some("rad/s"),
        ("/table/state", "rate_command") => Some("rad/s"),
        ("/table/state", "angle") => Some("rad"),
        ("/gyro/rate" | "/chamber/state", "temperature") => Some("°C"),
        ("/chamber/state", "setpoint") => Some("°C"),
        _ => None,
    }
}

/// The type the recording contract gives a column of a contract channel (or of the merged
/// table), whatever the values in a file; `None` for a column it does not define.
pub fn contract_type(topic: &str, column: &str) -> Option<ColumnType> {
    use ColumnType::{Float, Int, Text};
    let (topic, column) = match (topic, column) {
        (MERGED, "bench_time_s") => return Some(Float),
        (MERGED, "record_window") => return Some(Text),
        (MERGED, c) => match c.split_once('_') {
            Some(("gyro", rest)) => ("/gyro/rate", rest),
            Some(("table", rest)) => ("/table/state", rest),
            Some(("chamber", rest)) => ("/chamber/state", rest),
            _ => return None,
        },
        other => other,
    };
    match (topic, column) {
        ("/gyro/rate" | "/table/state" | "/chamber/state", "log_time_ns") => Some(Int),
        ("/gyro/rate", "rate" | "temperature") => Some(Float),
        ("/gyro/rate", "seq") => Some(Int),
        ("/table/state", "angle" | "rate" | "rate_command") => Some(Float),
        ("/chamber/state", "temperature" | "setpoint") => Some(Float),
        ("/gyro/rate" | "/table/state" | "/chamber/state", "status") => Some(Int),
        ("/bench/step", "index") => Some(Int),
        ("/bench/step", "name" | "event" | "label") => Some(Text),
        _ => None,
    }
}

/// A column's type, the narrowest that holds every value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnType {
    /// Every value null.
    Null,
    /// Booleans.
    Bool,
    /// Integers within i64.
    Int,
    /// Numbers.
    Float,
    /// Anything else, as text.
    Text,
}

impl ColumnType {
    fn widen(self, v: &Cell) -> Self {
        use ColumnType::*;
        let this = match v {
            Cell::Null => return self,
            Cell::Bool(_) => Bool,
            Cell::Int(_) => Int,
            Cell::Big(_) | Cell::Float(_) => Float,
            Cell::Str(_) | Cell::Json(_) => Text,
        };
        match (self, this) {
            (Null, t) => t,
            (a, b) if a == b => a,
            (Int, Float) | (Float, Int) => Float,
            _ => Text,
        }
    }
}

/// One value of a message body, typed as the JSON has it (what `serde_json::Value` would hold,
/// without its allocations for numbers and the keys).
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    Null,
    Bool(bool),
    /// An integer within i64.
    Int(i64),
    /// An integer above `i64::MAX`.
    Big(u64),
    Float(f64),
    Str(Box<str>),
    /// An array, as JSON text.
    Json(Box<str>),
}

impl Cell {
    fn from_value(v: Value) -> Cell {
        match v {
            Value::Null => Cell::Null,
            Value::Bool(b) => Cell::Bool(b),
            Value::Number(n) => match (n.as_i64(), n.as_u64(), n.as_f64()) {
                (Some(i), _, _) => Cell::Int(i),
                (_, Some(u), _) => Cell::Big(u),
                (_, _, Some(f)) => Cell::Float(f),
                _ => Cell::Json(n.to_string().into()),
            },
            Value::String(s) => Cell::Str(s.into()),
            other => Cell::Json(other.to_string().into()),
        }
    }

    fn as_str(&self) -> Option<&str> {
        match self {
            Cell::Str(s) => Some(s),
            _ => None,
        }
    }

    fn as_bool(&self) -> Option<bool> {
        match *self {
            Cell::Bool(b) => Some(b),
            _ => None,
        }
    }

    fn as_i64(&self) -> Option<i64> {
        match *self {
            Cell::Int(i) => Some(i),
            _ => None,
        }
    }

    fn as_u64(&self) -> Option<u64> {
        match *self {
            Cell::Int(i) => u64::try_from(i).ok(),
            Cell::Big(u) => Some(u),
            _ => None,
        }
    }

    fn as_f64(&self) -> Option<f64> {
        match *self {
            Cell::Int(i) => Some(i as f64),
            Cell::Big(u) => Some(u as f64),
            Cell::Float(f) => Some(f),
            _ => None,
        }
    }
}

/// One channel's messages in memory.
struct Channel {
    encoding: String,
    columns: Vec<String>,
    index: HashMap<String, usize>,
    log: Vec<i64>,
    publish: Vec<i64>,
    sequence: Vec<i64>,
    /// Row-major cells, (column, value), every row's after the one before.
    cells: Vec<(u32, Cell)>,
    /// Where each row's cells end in `cells`.
    row_end: Vec<usize>,
}

/// One chunk's messages of one topic, parsed on a decoding thread: cells keyed by this part's
/// own table of member names (each name allocated once per chunk, not per message).
struct Part {
    info: Arc<ChannelInfo>,
    keys: Vec<Box<str>>,
    log: Vec<i64>,
    publish: Vec<i64>,
    sequence: Vec<i64>,
    cells: Vec<(u32, Cell)>,
    row_end: Vec<usize>,
    /// Messages of this part, parsed or not.
    messages: usize,
    /// The first body that is not a JSON object: its message's position in the part,
    /// sequence, log time and the decoder's words. Rows stop there.
    bad: Option<(usize, u32, u64, String)>,
}

impl Part {
    fn key(&mut self, name: &str) -> u32 {
        match self.keys.iter().position(|k| &**k == name) {
            Some(k) => k as u32,
            None => {
                self.keys.push(name.into());
                (self.keys.len() - 1) as u32
            }
        }
    }

    /// Parse one message's body into a row (every message, whatever its channel's encoding:
    /// which encoding counts is the topic's first message's, known only in file order).
    fn message(&mut self, log_time: u64, publish_time: u64, sequence: u32, data: &[u8]) {
        self.messages += 1;
        if self.bad.is_some() {
            return;
        }
        let mark = self.cells.len();
        let mut de = serde_json::Deserializer::from_slice(data);
        let parsed =
            serde::Deserializer::deserialize_map(&mut de, Members(self)).and_then(|()| de.end());
        if let Err(e) = parsed {
            self.cells.truncate(mark);
            self.bad = Some((self.messages - 1, sequence, log_time, e.to_string()));
            return;
        }
        self.log.push(ns(log_time));
        self.publish.push(ns(publish_time));
        self.sequence.push(i64::from(sequence));
        self.row_end.push(self.cells.len());
    }
}

/// A JSON object's members in the order the body has them, flattened into a [`Part`]'s row;
/// a nested object's members sorted by name, as `serde_json::Map` has them.
struct Members<'a>(&'a mut Part);

impl<'de> serde::de::Visitor<'de> for Members<'_> {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a JSON object")
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut a: A) -> Result<(), A::Error> {
        let part = self.0;
        while let Some(k) = a.next_key_seed(Key(part))? {
            match a.next_value_seed(Member)? {
                Parsed::Cell(c) => part.cells.push((k, c)),
                Parsed::Object(inner) => {
                    let prefix = part.keys[k as usize].to_string();
                    let mut fields = Vec::new();
                    flatten(&prefix, inner, &mut fields);
                    for (name, v) in fields {
                        let k = part.key(&name);
                        part.cells.push((k, Cell::from_value(v)));
                    }
                }
            }
        }
        Ok(())
    }
}

/// A member's name, as its index in the part's key table.
struct Key<'a>(&'a mut Part);

impl<'de> serde::de::DeserializeSeed<'de> for Key<'_> {
    type Value = u32;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<u32, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Key<'_> {
    type Value = u32;
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a string")
    }
    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<u32, E> {
        Ok(self.0.key(v))
    }
}

/// A member's value.
enum Parsed {
    Cell(Cell),
    Object(serde_json::Map<String, Value>),
}

struct Member;

impl<'de> serde::de::DeserializeSeed<'de> for Member {
    type Value = Parsed;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<Parsed, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Member {
    type Value = Parsed;
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("any JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Bool(v)))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Int(v)))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Parsed, E> {
        Ok(Parsed::Cell(i64::try_from(v).map_or(Cell::Big(v), Cell::Int)))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Parsed, E> {
        // As `Value`: a number that is not finite is null.
        Ok(Parsed::Cell(if v.is_finite() { Cell::Float(v) } else { Cell::Null }))
    }
    fn visit_str<E>(self, v: &str) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Str(v.into())))
    }
    fn visit_string<E>(self, v: String) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Str(v.into())))
    }
    fn visit_unit<E>(self) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Null))
    }
    fn visit_none<E>(self) -> Result<Parsed, E> {
        Ok(Parsed::Cell(Cell::Null))
    }
    fn visit_some<D: serde::Deserializer<'de>>(self, d: D) -> Result<Parsed, D::Error> {
        d.deserialize_any(self)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, a: A) -> Result<Parsed, A::Error> {
        let v: Value =
            serde::Deserialize::deserialize(serde::de::value::SeqAccessDeserializer::new(a))?;
        Ok(Parsed::Cell(Cell::Json(v.to_string().into())))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, a: A) -> Result<Parsed, A::Error> {
        let v: Value =
            serde::Deserialize::deserialize(serde::de::value::MapAccessDeserializer::new(a))?;
        Ok(match v {
            Value::Object(m) => Parsed::Object(m),
            other => Parsed::Cell(Cell::from_value(other)),
        })
    }
}

fn flatten(
    prefix: &str,
    members: impl IntoIterator<Item = (String, Value)>,
    out: &mut Vec<(String, Value)>,
) {
    for (k, v) in members {
        let name = if prefix.is_empty() { k } else { format!("{prefix}.{k}") };
        match v {
            Value::Object(inner) => flatten(&name, inner, out),
            other => out.push((name, other)),
        }
    }
}

fn ns(v: u64) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

/// The part of `parts` for `info`'s topic, added if there is none yet.
fn part<'a>(parts: &'a mut Vec<Part>, info: &Arc<ChannelInfo>) -> &'a mut Part {
    let k = match parts.iter().position(|p| p.info.topic == info.topic) {
        Some(k) => k,
        None => {
            parts.push(Part {
                info: info.clone(),
                keys: Vec::new(),
                log: Vec::new(),
                publish: Vec::new(),
                sequence: Vec::new(),
                cells: Vec::new(),
                row_end: Vec::new(),
                messages: 0,
                bad: None,
            });
            parts.len() - 1
        }
    };
    &mut parts[k]
}

/// Parses each chunk's message bodies on the decoding threads: one [`Part`] per topic.
struct Parse;

impl Decode for Parse {
    type Out = Vec<Part>;

    fn start(&self) -> Vec<Part> {
        Vec::new()
    }

    fn message(&self, out: &mut Vec<Part>, chan: &Chan, m: Msg<'_>) {
        let h = &m.header;
        part(out, &chan.info).message(h.log_time, h.publish_time, h.sequence, m.data);
    }

    fn orphan(&self, _: &mut Vec<Part>, _: Msg<'_>) {}

    fn channel(&self, _: &mut Vec<Part>, _: &Chan) {}
}

/// Every channel's messages by topic, and where the recording was cut.
type Collected = (BTreeMap<String, Channel>, Option<(u64, String)>);

impl Channel {
    fn new(encoding: String) -> Channel {
        Channel {
            encoding,
            columns: Vec::new(),
            index: HashMap::new(),
            log: Vec::new(),
            publish: Vec::new(),
            sequence: Vec::new(),
            cells: Vec::new(),
            row_end: Vec::new(),
        }
    }

    fn rows(&self) -> usize {
        self.row_end.len()
    }

    fn row(&self, r: usize) -> &[(u32, Cell)] {
        let start = r.checked_sub(1).map_or(0, |p| self.row_end[p]);
        &self.cells[start..self.row_end[r]]
    }

    fn column(&mut self, name: &str) -> u32 {
        if let Some(&c) = self.index.get(name) {
            return c as u32;
        }
        self.columns.push(name.to_owned());
        self.index.insert(name.to_owned(), self.columns.len() - 1);
        (self.columns.len() - 1) as u32
    }

    fn end_row(&mut self, log: i64, publish: i64, sequence: i64) {
        self.log.push(log);
        self.publish.push(publish);
        self.sequence.push(sequence);
        self.row_end.push(self.cells.len());
    }

    /// Append a part in file order (its rows, its new columns in the order it met them);
    /// the error of its first body that is not a JSON object, on a `json` channel.
    fn append(&mut self, part: Part) -> Result<(), ExportError> {
        if self.encoding != "json" {
            self.log.extend(std::iter::repeat_n(0, part.messages));
            return Ok(());
        }
        // Columns in the order the cells first use them (a key may name a nested object,
        // which is no column).
        let mut cols = vec![u32::MAX; part.keys.len()];
        let base = self.cells.len();
        self.cells.reserve(part.cells.len());
        for (k, c) in part.cells {
            let col = &mut cols[k as usize];
            if *col == u32::MAX {
                *col = self.column(&part.keys[k as usize]);
            }
            self.cells.push((*col, c));
        }
        self.row_end.extend(part.row_end.iter().map(|e| base + e));
        self.log.extend_from_slice(&part.log);
        self.publish.extend_from_slice(&part.publish);
        self.sequence.extend_from_slice(&part.sequence);
        match part.bad {
            Some((_, sequence, log_time_ns, detail)) => Err(ExportError::NotJson {
                topic: part.info.topic.clone(),
                sequence,
                log_time_ns,
                detail,
            }),
            None => Ok(()),
        }
    }
}

/// Add one chunk's parts to the tables.
fn add_parts(
    channels: &mut BTreeMap<String, Channel>,
    parts: Vec<Part>,
) -> Result<(), ExportError> {
    for part in parts {
        let ch = match channels.get_mut(&part.info.topic) {
            Some(ch) => ch,
            None => channels
                .entry(part.info.topic.clone())
                .or_insert_with(|| Channel::new(part.info.message_encoding.clone())),
        };
        ch.append(part)?;
    }
    Ok(())
}

/// Read every channel of a recording from any byte source into tables: the bodies parsed on
/// the reader's decoding threads, chunk by chunk, and added in file order.
fn collect<R: std::io::Read>(reader: RecordingReader<R>) -> Result<Collected, ExportError> {
    let mut channels: BTreeMap<String, Channel> = BTreeMap::new();
    let mut engine = match reader.into_engine(Parse) {
        Ok(engine) => engine,
        // Already started: the rest of its items, parsed here.
        Err(reader) => {
            let mut reader = *reader;
            for item in reader.by_ref() {
                let Item::Other(m) = item? else { continue };
                let mut parts = Vec::new();
                part(&mut parts, &m.channel).message(
                    m.log_time_ns,
                    m.publish_time_ns,
                    m.sequence,
                    &m.data,
                );
                add_parts(&mut channels, parts)?;
            }
            let cut = match reader.end() {
                End::Cut { at_byte, reason } => Some((*at_byte, reason.clone())),
                _ => None,
            };
            return Ok((channels, cut));
        }
    };
    while let Some(unit) = engine.next_unit() {
        match unit {
            Unit::Out(parts) => add_parts(&mut channels, parts)?,
            Unit::Error(e) => return Err(e.into()),
            Unit::Metadata(_) | Unit::Attachment(_) | Unit::Damage(_) => {}
        }
    }
    let cut = match engine.end() {
        End::Cut { at_byte, reason } => Some((*at_byte, reason.clone())),
        _ => None,
    };
    Ok((channels, cut))
}

/// File name of a topic's table: the topic without its leading slash, `/` → `_`.
pub fn table_name(topic: &str) -> String {
    let name: String = topic
        .trim_start_matches('/')
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '.' { c } else { '_' })
        .collect();
    if name.is_empty() {
        "root".to_string()
    } else {
        name
    }
}

/// Export the recording at `input` into `out_dir` (created if needed), one file per channel.
pub fn export_file(
    input: &Path,
    out_dir: &Path,
    format: Format,
) -> Result<ExportReport, ExportError> {
    export_file_with(input, out_dir, format, false)
}

/// [`export_file`], and with `merged` the as-of-merged table too (`merged.csv|parquet`).
pub fn export_file_with(
    input: &Path,
    out_dir: &Path,
    format: Format,
    merged: bool,
) -> Result<ExportReport, ExportError> {
    export_with(RecordingReader::open(input)?, out_dir, format, merged)
}

/// Export a recording from any reader (e.g. `RecordingReader::new(&bytes[..])`) into
/// `out_dir`.
pub fn export<R: std::io::Read>(
    reader: RecordingReader<R>,
    out_dir: &Path,
    format: Format,
) -> Result<ExportReport, ExportError> {
    export_with(reader, out_dir, format, false)
}

/// [`export`], and with `merged` the as-of-merged table too.
pub fn export_with<R: std::io::Read>(
    reader: RecordingReader<R>,
    out_dir: &Path,
    format: Format,
    merged: bool,
) -> Result<ExportReport, ExportError> {
    let (channels, cut) = collect(reader)?;
    std::fs::create_dir_all(out_dir)
        .map_err(|source| ExportError::Write { path: out_dir.to_path_buf(), source })?;
    let mut report = ExportReport { cut, ..ExportReport::default() };
    let merged_table = merged.then(|| merge(&channels));
    let tables = channels.iter().map(|(t, ch)| (t.as_str(), ch, table_name(t)));
    let tables = tables.chain(merged_table.iter().map(|ch| (MERGED, ch, "merged".to_owned())));
    for (topic, ch, name) in tables {
        if ch.encoding != "json" {
            report.skipped.push((topic.to_owned(), ch.encoding.clone()));
            continue;
        }
        let path = out_dir.join(format!("{name}.{}", format.extension()));
        let types = column_types(topic, ch);
        let mut columns: Vec<String> =
            [timestamp_name(ch), "log_time_ns", "publish_time_ns", "sequence"]
                .map(String::from)
                .to_vec();
        columns.extend(ch.columns.iter().cloned());
        let units = match format {
            Format::Csv => {
                write_csv(&path, ch)?;
                let units = out_dir.join(format!("{name}.units.csv"));
                write_units(&units, topic, &columns)?;
                Some(units)
            }
            Format::Parquet => {
                write_parquet(&path, topic, ch, &types)?;
                None
            }
        };
        let rows = ch.rows();
        report.tables.push(Table { topic: topic.to_owned(), path, rows, columns, units });
    }
    Ok(report)
}

/// Each column's type: the contract's where it defines one and the values fit it, else the
/// narrowest that holds all its values.
fn column_types(topic: &str, ch: &Channel) -> Vec<ColumnType> {
    let mut types = vec![ColumnType::Null; ch.columns.len()];
    for (c, v) in &ch.cells {
        if let Some(t) = types.get_mut(*c as usize) {
            *t = t.widen(v);
        }
    }
    for (t, name) in types.iter_mut().zip(&ch.columns) {
        if let Some(want) = contract_type(topic, name) {
            *t = match (*t, want) {
                (ColumnType::Null, w) => w,
                (ColumnType::Int, ColumnType::Float) => ColumnType::Float,
                (got, _) => got,
            };
        }
    }
    types
}

/// The unit of a table's column as the units sidecar gives it.
fn sidecar_unit(topic: &str, column: &str) -> &'static str {
    match column {
        "timestamp" | "log_timestamp" => "RFC 3339, UTC",
        c => column_unit(topic, c).unwrap_or(""),
    }
}

/// `NAME.units.csv`: `column,unit`, one row per column of the table.
fn write_units(path: &Path, topic: &str, columns: &[String]) -> Result<(), ExportError> {
    let io = |source| ExportError::Write { path: path.to_path_buf(), source };
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut rows = vec![["column", "unit"]];
    rows.extend(columns.iter().map(|c| [c.as_str(), sidecar_unit(topic, c)]));
    for r in rows {
        w.write_record(r).map_err(|e| io(std::io::Error::other(e.to_string())))?;
    }
    let bytes = w.into_inner().map_err(|e| io(std::io::Error::other(e.to_string())))?;
    std::fs::write(path, bytes).map_err(io)
}

/// A log time as RFC 3339 UTC text with nanoseconds: `2026-11-27T10:00:00.050000000Z`
/// (empty out of range), into `out`.
fn rfc3339_into(ns: i64, out: &mut String) {
    use std::fmt::Write;
    if let Ok(t) = time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(ns)) {
        let _ = write!(
            out,
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:09}Z",
            t.year(),
            u8::from(t.month()),
            t.day(),
            t.hour(),
            t.minute(),
            t.second(),
            t.nanosecond()
        );
    }
}

/// The Parquet timestamp column's name: `timestamp`, or `log_timestamp` when the channel has
/// a field of that name.
fn timestamp_name(ch: &Channel) -> &'static str {
    if ch.index.contains_key("timestamp") {
        "log_timestamp"
    } else {
        "timestamp"
    }
}

/// A channel's rows in log-time order (stable: equal times keep file order).
fn by_time(ch: &Channel) -> Vec<usize> {
    let mut order: Vec<usize> = (0..ch.rows()).collect();
    order.sort_by_key(|&r| ch.log[r]);
    order
}

/// The as-of merge: one row per gyro sample (its log time, publish time and sequence), the
/// gyro's fields as `gyro_<field>`, `bench_time_s` (s from the recording's time zero: the
/// earliest message of the four contract channels), the latest `/table/state` and
/// `/chamber/state` messages logged at or before the sample as `table_<field>` and
/// `chamber_<field>` with their `table_log_time_ns` / `chamber_log_time_ns` (null before the
/// first), and `record_window`: the label of the `record…` step whose start ≤ t < end (its
/// abort, or the end of the recording when it has none), null outside.
fn merge(channels: &BTreeMap<String, Channel>) -> Channel {
    let empty = Channel::new("json".into());
    let gyro = channels.get("/gyro/rate").filter(|c| c.encoding == "json").unwrap_or(&empty);
    let t0 = ["/gyro/rate", "/table/state", "/chamber/state", "/bench/step"]
        .iter()
        .filter_map(|t| channels.get(*t))
        .filter_map(|c| c.log.iter().min().copied())
        .min()
        .unwrap_or(0);
    let mut out = Channel::new(empty.encoding.clone());
    let add = |out: &mut Channel, name: String| out.column(&name);
    let bench_time = add(&mut out, "bench_time_s".into());
    let gyro_cols: Vec<u32> =
        gyro.columns.iter().map(|c| add(&mut out, format!("gyro_{c}"))).collect();
    // (channel, its rows by time, its log times in that order, log-time column, field columns)
    let mut joined = Vec::new();
    for (topic, prefix) in [("/table/state", "table"), ("/chamber/state", "chamber")] {
        let Some(ch) = channels.get(topic).filter(|c| c.encoding == "json") else { continue };
        let order = by_time(ch);
        let times: Vec<i64> = order.iter().map(|&r| ch.log[r]).collect();
        let log_col = add(&mut out, format!("{prefix}_log_time_ns"));
        let cols: Vec<u32> =
            ch.columns.iter().map(|c| add(&mut out, format!("{prefix}_{c}"))).collect();
        joined.push((ch, order, times, log_col, cols));
    }
    let window_col = add(&mut out, "record_window".into());
    let windows = record_windows(channels.get("/bench/step"));
    for r in by_time(gyro) {
        let t = gyro.log[r];
        out.cells.push((bench_time, Cell::Float((t - t0) as f64 * 1e-9)));
        out.cells.extend(gyro.row(r).iter().map(|(c, v)| (gyro_cols[*c as usize], v.clone())));
        for (ch, order, times, log_col, cols) in &joined {
            // The last reading logged at or before t.
            let Some(k) = times.partition_point(|&x| x <= t).checked_sub(1) else { continue };
            let src = order[k];
            out.cells.push((*log_col, Cell::Int(ch.log[src])));
            out.cells.extend(ch.row(src).iter().map(|(c, v)| (cols[*c as usize], v.clone())));
        }
        let label = windows.iter().find(|(a, b, _)| *a <= t && t < *b);
        out.cells
            .push((window_col, label.map_or(Cell::Null, |(_, _, l)| Cell::Str(l.as_str().into()))));
        out.end_row(t, gyro.publish[r], gyro.sequence[r]);
    }
    out
}

impl Channel {
    fn field(&self, row: usize, name: &str) -> Option<&Cell> {
        let c = *self.index.get(name)? as u32;
        (row < self.rows()).then(|| self.row(row).iter().find(|(i, _)| *i == c).map(|(_, v)| v))?
    }
}

/// The record windows of `/bench/step`: (start, end, label) in log time, ns, for each step
/// whose label begins with `record`, paired as everywhere ([`crate::steps`]); a window with no
/// `end`/`abort` runs to the end of time.
fn record_windows(steps: Option<&Channel>) -> Vec<(i64, i64, String)> {
    let Some(st) = steps.filter(|c| c.encoding == "json") else { return Vec::new() };
    let events: Vec<(i64, StepMsg)> = (0..st.rows())
        .filter_map(|r| {
            let event = match st.field(r, "event").and_then(Cell::as_str)? {
                "start" => StepEvent::Start,
                "end" => StepEvent::End,
                "abort" => StepEvent::Abort,
                _ => return None,
            };
            let index = st.field(r, "index").and_then(Cell::as_u64).unwrap_or(u64::MAX);
            let label = st.field(r, "label").and_then(Cell::as_str).unwrap_or("").to_owned();
            Some((st.log[r], StepMsg { index, name: String::new(), event, label }))
        })
        .collect();
    let mut out: Vec<(i64, i64, String)> = crate::steps::pair(events.iter().map(|(t, m)| (*t, m)))
        .into_iter()
        .filter(|s| s.is_record())
        .filter_map(|s| Some((s.start?, s.end.map_or(i64::MAX, |e| e.0), s.label.to_owned())))
        .collect();
    out.sort_by_key(|w| w.0);
    out
}

/// A cell's text: integers as integers, floats in the shortest form that reads back the same
/// (`ryu`'s: `2.3e-5` is `0.000023`), null as empty, strings as they are, arrays as JSON.
fn cell(v: &Cell) -> String {
    let mut bytes = Vec::new();
    cell_into(v, &mut bytes);
    String::from_utf8(bytes).unwrap_or_default()
}

/// [`cell`], appended to `out`.
fn cell_into(v: &Cell, out: &mut Vec<u8>) {
    match v {
        Cell::Null => {}
        Cell::Bool(b) => out.extend_from_slice(if *b { b"true" } else { b"false" }),
        Cell::Int(i) => out.extend_from_slice(itoa::Buffer::new().format(*i).as_bytes()),
        Cell::Big(u) => out.extend_from_slice(itoa::Buffer::new().format(*u).as_bytes()),
        Cell::Float(f) => out.extend_from_slice(ryu::Buffer::new().format(*f).as_bytes()),
        Cell::Str(s) | Cell::Json(s) => out.extend_from_slice(s.as_bytes()),
    }
}

/// RFC 3339 time stamps of consecutive log times, the date and time of day formatted once per
/// second ([`rfc3339_into`]'s text).
#[derive(Default)]
struct Stamps {
    second: Option<i64>,
    /// `YYYY-MM-DDTHH:MM:SS` of `second`; empty when out of range.
    prefix: String,
}

impl Stamps {
    fn push(&mut self, ns: i64, out: &mut Vec<u8>) {
        const NS: i64 = 1_000_000_000;
        let (second, nanos) = (ns.div_euclid(NS), ns.rem_euclid(NS));
        if self.second != Some(second) {
            self.second = Some(second);
            self.prefix.clear();
            // The second's date and time of day (from `ns` itself where the whole second is
            // out of i64's range).
            rfc3339_into(second.checked_mul(NS).unwrap_or(ns), &mut self.prefix);
            let date_time = self.prefix.find('.').unwrap_or(0);
            self.prefix.truncate(date_time);
        }
        if self.prefix.is_empty() {
            return;
        }
        out.extend_from_slice(self.prefix.as_bytes());
        // Nine digits with their leading zeros: those of 10⁹ + nanos after its leading 1.
        let mut digits = itoa::Buffer::new();
        out.push(b'.');
        out.extend_from_slice(&digits.format(NS + nanos).as_bytes()[1..]);
        out.push(b'Z');
    }
}

/// Rows formatted per block, the blocks on the machine's threads and written in order.
const CSV_BLOCK: usize = 32 * 1024;

/// The CSV text of rows `rows` of a table (no header): the same bytes as one writer for the
/// whole table writes for them. Each row's fields are formatted into one buffer and handed to
/// the `csv` writer as slices of it (it quotes where a field needs it).
fn csv_rows(ch: &Channel, rows: std::ops::Range<usize>) -> Result<Vec<u8>, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::with_capacity(rows.len() * 96));
    let mut slots: Vec<Option<&Cell>> = vec![None; ch.columns.len()];
    let mut buf: Vec<u8> = Vec::with_capacity(256);
    let mut ends: Vec<usize> = Vec::with_capacity(4 + ch.columns.len());
    let mut stamps = Stamps::default();
    let mut int = itoa::Buffer::new();
    for r in rows {
        buf.clear();
        ends.clear();
        let log = ch.log.get(r).copied().unwrap_or_default();
        stamps.push(log, &mut buf);
        ends.push(buf.len());
        for v in [log, ch.publish.get(r).copied().unwrap_or_default()] {
            buf.extend_from_slice(int.format(v).as_bytes());
            ends.push(buf.len());
        }
        buf.extend_from_slice(
            int.format(ch.sequence.get(r).copied().unwrap_or_default()).as_bytes(),
        );
        ends.push(buf.len());
        slots.iter_mut().for_each(|s| *s = None);
        for (c, v) in ch.row(r) {
            if let Some(slot) = slots.get_mut(*c as usize) {
                *slot = Some(v);
            }
        }
        for v in &slots {
            if let Some(v) = v {
                cell_into(v, &mut buf);
            }
            ends.push(buf.len());
        }
        let starts = std::iter::once(0).chain(ends.iter().copied());
        w.write_record(starts.zip(ends.iter()).map(|(a, &b)| &buf[a..b]))?;
    }
    w.into_inner().map_err(|e| e.into_error().into())
}

fn write_csv(path: &Path, ch: &Channel) -> Result<(), ExportError> {
    use std::io::Write;
    let io = |source| ExportError::Write { path: path.to_path_buf(), source };
    let file = File::create(path).map_err(io)?;
    let mut w = csv::Writer::from_writer(BufWriter::new(file));
    let csv_err = |e: csv::Error| ExportError::Write {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    };
    let mut header: Vec<&str> =
        vec![timestamp_name(ch), "log_time_ns", "publish_time_ns", "sequence"];
    header.extend(ch.columns.iter().map(String::as_str));
    w.write_record(&header).map_err(csv_err)?;
    let mut out = w.into_inner().map_err(|e| io(std::io::Error::other(e.to_string())))?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 4);
    let blocks: Vec<std::ops::Range<usize>> =
        (0..ch.rows()).step_by(CSV_BLOCK).map(|a| a..(a + CSV_BLOCK).min(ch.rows())).collect();
    for round in blocks.chunks(threads) {
        // One block here, the others beside it.
        let texts: Vec<Result<Vec<u8>, csv::Error>> = std::thread::scope(|s| {
            let others: Vec<_> =
                round[1..].iter().map(|b| s.spawn(|| csv_rows(ch, b.clone()))).collect();
            let mut texts = vec![csv_rows(ch, round[0].clone())];
            for h in others {
                texts.push(h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
            }
            texts
        });
        for text in texts {
            out.write_all(&text.map_err(csv_err)?).map_err(io)?;
        }
    }
    out.into_inner().map_err(|e| io(e.into_error()))?.sync_all().map_err(io)
}

fn write_parquet(
    path: &Path,
    topic: &str,
    ch: &Channel,
    types: &[ColumnType],
) -> Result<(), ExportError> {
    use parquet::basic::{
        Compression, LogicalType, Repetition, TimeUnit, Type as Physical, ZstdLevel,
    };
    use parquet::data_type::{BoolType, ByteArray, ByteArrayType, DoubleType, Int64Type};
    use parquet::file::metadata::KeyValue;
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use parquet::schema::types::Type;

    let pq = |source| ExportError::Parquet { path: path.to_path_buf(), source };
    let io = |source| ExportError::Write { path: path.to_path_buf(), source };
    let required = |name: &str| {
        Type::primitive_type_builder(name, Physical::INT64)
            .with_repetition(Repetition::REQUIRED)
            .build()
    };
    // The log time as a timestamp, nanoseconds since the Unix epoch, UTC.
    let timestamp = Type::primitive_type_builder(timestamp_name(ch), Physical::INT64)
        .with_logical_type(Some(LogicalType::timestamp(true, TimeUnit::NANOS)))
        .with_repetition(Repetition::REQUIRED)
        .build()
        .map_err(pq)?;
    let mut fields = vec![
        Arc::new(timestamp),
        Arc::new(required("log_time_ns").map_err(pq)?),
        Arc::new(required("publish_time_ns").map_err(pq)?),
        Arc::new(required("sequence").map_err(pq)?),
    ];
    for (name, t) in ch.columns.iter().zip(types) {
        let b = match t {
            ColumnType::Bool => Type::primitive_type_builder(name, Physical::BOOLEAN),
            ColumnType::Int => Type::primitive_type_builder(name, Physical::INT64),
            ColumnType::Float => Type::primitive_type_builder(name, Physical::DOUBLE),
            ColumnType::Null | ColumnType::Text => {
                Type::primitive_type_builder(name, Physical::BYTE_ARRAY)
                    .with_logical_type(Some(LogicalType::String))
            }
        };
        fields.push(Arc::new(b.with_repetition(Repetition::OPTIONAL).build().map_err(pq)?));
    }
    let schema =
        Arc::new(Type::group_type_builder("schema").with_fields(fields).build().map_err(pq)?);
    // Units: `unit.<column>` each, and all of them as one JSON object under `bench.units`.
    let names =
        ["log_time_ns", "publish_time_ns"].into_iter().chain(ch.columns.iter().map(String::as_str));
    let units: Vec<(&str, &str)> =
        names.filter_map(|c| column_unit(topic, c).map(|u| (c, u))).collect();
    let mut kv: Vec<KeyValue> =
        units.iter().map(|(c, u)| KeyValue::new(format!("unit.{c}"), (*u).to_owned())).collect();
    let all: serde_json::Map<String, Value> =
        units.iter().map(|(c, u)| ((*c).to_owned(), Value::from(*u))).collect();
    kv.push(KeyValue::new("bench.units".to_owned(), Value::Object(all).to_string()));
    kv.push(KeyValue::new("bench.topic".to_owned(), topic.to_owned()));
    let props = Arc::new(
        WriterProperties::builder()
            .set_compression(Compression::ZSTD(ZstdLevel::try_new(1).map_err(pq)?))
            .set_key_value_metadata(Some(kv))
            .build(),
    );
    let file = File::create(path).map_err(io)?;
    let mut writer = SerializedFileWriter::new(file, schema, props).map_err(pq)?;
    let mut group = writer.next_row_group().map_err(pq)?;
    for fixed in [&ch.log, &ch.log, &ch.publish, &ch.sequence] {
        if let Some(mut col) = group.next_column().map_err(pq)? {
            col.typed::<Int64Type>().write_batch(fixed, None, None).map_err(pq)?;
            col.close().map_err(pq)?;
        }
    }
    for (c, t) in types.iter().enumerate() {
        // One column: the values present and the definition levels (1 present, 0 null).
        let mut present: Vec<Option<&Cell>> = vec![None; ch.rows()];
        for (r, slot) in present.iter_mut().enumerate() {
            if let Some((_, v)) = ch.row(r).iter().find(|(i, _)| *i as usize == c) {
                *slot = (*v != Cell::Null).then_some(v);
            }
        }
        let def: Vec<i16> = present.iter().map(|v| i16::from(v.is_some())).collect();
        let Some(mut col) = group.next_column().map_err(pq)? else { break };
        let values = present.iter().flatten();
        match t {
            ColumnType::Bool => {
                let v: Vec<bool> = values.map(|v| v.as_bool().unwrap_or_default()).collect();
                col.typed::<BoolType>().write_batch(&v, Some(&def), None)
            }
            ColumnType::Int => {
                let v: Vec<i64> = values.map(|v| v.as_i64().unwrap_or_default()).collect();
                col.typed::<Int64Type>().write_batch(&v, Some(&def), None)
            }
            ColumnType::Float => {
                let v: Vec<f64> = values.map(|v| v.as_f64().unwrap_or(f64::NAN)).collect();
                col.typed::<DoubleType>().write_batch(&v, Some(&def), None)
            }
            ColumnType::Null | ColumnType::Text => {
                let v: Vec<ByteArray> = values.map(|v| ByteArray::from(cell(v).as_str())).collect();
                col.typed::<ByteArrayType>().write_batch(&v, Some(&def), None)
            }
        }
        .map_err(pq)?;
        col.close().map_err(pq)?;
    }
    group.close().map_err(pq)?;
    writer.close().map_err(pq)?;
    Ok(())
}

#[cfg(test)]
mod tests;
