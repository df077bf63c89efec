//! The recorder: writes one run to an MCAP file per the recording format, version 1
//! (`FORMAT.md` of this crate).
//!
//! ```
//! use std::{collections::BTreeMap, io::Cursor, time::Duration};
//! use bench_recording::{GyroMsg, Outcome, Recorder, RunInfo, Site};
//!
//! let info = RunInfo::new(1_700_000_000_000_000_000, "demo", "name = \"demo\"\n",
//!     Site::at_latitude(45.0), BTreeMap::new());
//! let mut rec = Recorder::new(Cursor::new(Vec::new()), info)?;
//! let s = GyroMsg { rate_rad_s: 1e-5, temperature_c: None, seq: 0, status: 0 };
//! rec.gyro(Duration::from_millis(50), None, &s)?;
//! let file = rec.finish(&Outcome::Completed)?.into_inner();
//! assert!(file.starts_with(mcap::MAGIC));
//! # Ok::<(), bench_recording::RecordError>(())
//! ```

use std::{
    borrow::Cow,
    collections::BTreeMap,
    fs::File,
    io::{BufWriter, Seek, Write},
    path::Path,
    time::{Duration, Instant},
};

use mcap::{records::MessageHeader, Compression, WriteOptions};
use serde::Serialize;

use crate::message::{ChamberMsg, GyroMsg, LogLevel, Outcome, StepEvent, TableMsg};
use crate::schema::*;
use crate::site::{MetadataError, Site};
use crate::status;

/// What went wrong while recording.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The MCAP writer (or the file under it) failed.
    #[error("recording: MCAP write failed while {context}: {source}")]
    Mcap {
        /// What the recorder was doing.
        context: &'static str,
        /// The writer's error.
        #[source]
        source: mcap::McapError,
    },
    /// Creating or flushing the output file failed.
    #[error("recording: I/O error while {context}: {source}")]
    Io {
        /// What the recorder was doing.
        context: &'static str,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A message's time is before the previous message's on the same channel.
    #[error(
        "recording {topic}: time {got:?} is before the previous message's {previous:?} \
         (messages of a channel must be written in non-decreasing time)"
    )]
    TimeWentBack {
        /// Channel.
        topic: &'static str,
        /// Bench time of the previous message.
        previous: Duration,
        /// Bench time given now.
        got: Duration,
    },
    /// A bench time does not fit in u64 nanoseconds since the Unix epoch.
    #[error("recording {topic}: start epoch + {t:?} overflows u64 nanoseconds")]
    TimeOverflow {
        /// Channel.
        topic: &'static str,
        /// Bench time given.
        t: Duration,
    },
    /// A number that must be finite is NaN or infinite (JSON has no such numbers).
    #[error("recording {topic}: field `{field}` must be a finite number, got {value}")]
    NonFinite {
        /// Channel.
        topic: &'static str,
        /// Field in the message body.
        field: &'static str,
        /// The value given.
        value: f64,
    },
    /// A site value is not what the contract allows.
    #[error("recording: {0}")]
    BadSite(#[from] MetadataError),
    /// JSON encoding failed (cannot happen for the bodies bench writes; kept for honesty).
    #[error("recording {topic}: JSON encoding failed: {source}")]
    Json {
        /// Channel.
        topic: &'static str,
        /// Encoder error.
        #[source]
        source: serde_json::Error,
    },
}

fn mcap_err(context: &'static str) -> impl FnOnce(mcap::McapError) -> RecordError {
    move |source| RecordError::Mcap { context, source }
}

/// A file attached to the recording (media type `application/toml`).
#[derive(Debug, Clone, PartialEq)]
pub struct TomlAttachment {
    /// Attachment name, usually the file's name (e.g. `thermal.toml`).
    pub name: String,
    /// The file's text.
    pub text: String,
}

/// Everything known about a run when it starts.
#[derive(Debug, Clone, PartialEq)]
pub struct RunInfo {
    /// Start epoch: bench time zero, in ns since the Unix epoch (fixed for a simulated run,
    /// wall clock at start for a real one). `bench.run` `started` is this instant.
    pub epoch_ns: u64,
    /// Writer name and version (`bench.run` `software`); default `bench <crate version>`.
    pub software: String,
    /// Scenario name (`bench.scenario` `name`).
    pub scenario_name: String,
    /// The whole scenario file (`bench.scenario` `text`).
    pub scenario_text: String,
    /// Attachment name of the scenario file; `None`: the scenario is not attached.
    pub scenario_attachment: Option<String>,
    /// Bench configuration file to attach, if any.
    pub config: Option<TomlAttachment>,
    /// `bench.site`.
    pub site: Site,
    /// `bench.gyro_model` (from `GyroModel::to_metadata`); empty when no model was given.
    pub gyro_model: BTreeMap<String, String>,
    /// What `gyro_model` is to the data (`bench.run` `gyro_model_role`): the simulator's truth
    /// only for a simulated gyro.
    pub gyro_model_role: crate::ModelRole,
    /// `bench.station` (optional: `unit_serial`, `operator`, `station`); not written when
    /// empty.
    pub station: BTreeMap<String, String>,
    /// `bench.acceptance` (optional: the limit on |coefficient| per coefficient key, SI, units
    /// in the key names); not written when empty.
    pub acceptance: BTreeMap<String, String>,
}

impl RunInfo {
    /// Run info with the default software name, the scenario attached as `scenario.toml` and no
    /// configuration file.
    pub fn new(
        epoch_ns: u64,
        scenario_name: impl Into<String>,
        scenario_text: impl Into<String>,
        site: Site,
        gyro_model: BTreeMap<String, String>,
    ) -> Self {
        Self {
            epoch_ns,
            software: default_software(),
            scenario_name: scenario_name.into(),
            scenario_text: scenario_text.into(),
            scenario_attachment: Some("scenario.toml".to_string()),
            config: None,
            site,
            gyro_model,
            gyro_model_role: crate::ModelRole::Nominal,
            station: BTreeMap::new(),
            acceptance: BTreeMap::new(),
        }
    }
}

/// `bench <version>`.
pub fn default_software() -> String {
    format!("bench {}", env!("CARGO_PKG_VERSION"))
}

/// RFC 3339 UTC text of an instant in ns since the Unix epoch (nanosecond precision where
/// non-zero), e.g. `2024-01-01T00:00:00Z`.
pub fn rfc3339_utc(epoch_ns: u64) -> String {
    time::OffsetDateTime::from_unix_timestamp_nanos(i128::from(epoch_ns))
        .ok()
        .and_then(|t| t.format(&time::format_description::well_known::Rfc3339).ok())
        // Unreachable for any u64 (year < 2555); keep a valid RFC 3339 text anyway.
        .unwrap_or_else(|| "1970-01-01T00:00:00Z".to_string())
}

/// Recorder settings. Defaults suit a bench run.
#[derive(Debug, Clone)]
pub struct RecorderOptions {
    /// Chunk compression. Default zstd (best ratio for JSON; lz4 is faster, `None` biggest).
    pub compression: Option<Compression>,
    /// Target uncompressed chunk size, bytes. Default 1 MiB: bigger compresses better, smaller
    /// loses less on a crash when `flush_interval` is off.
    pub chunk_size: u64,
    /// Width of the gyro's own sample counter in bits (1..=64), for detecting counter gaps
    /// across wrap-around. Default 64 (drivers widen wrapping counters to u64).
    pub gyro_seq_bits: u32,
    /// Close the current chunk and flush the sink whenever a message's bench time has moved
    /// this far past the last flush, so a crash (SIGKILL) loses at most this much **bench
    /// time** of data, however fast the run goes (virtual time, scaled time). Default 1 s;
    /// `None`: only when chunks fill, on [`Recorder::flush`], at step ends and at the finish.
    /// The flush hands the data to the operating system (it survives the process, not a power
    /// loss before the OS writes it back).
    pub flush_interval: Option<Duration>,
    /// Also close the chunk and flush the sink whenever this much **wall-clock** time has
    /// passed since the last flush (checked every 64 messages): for a virtual-time run, which
    /// fills a chunk in milliseconds, this bounds what a kill loses in wall-clock work without
    /// closing chunks early. Default `None`.
    pub flush_wall: Option<Duration>,
    /// Also close the chunk and flush at every step end or abort. Default true.
    pub flush_on_step_end: bool,
    /// zstd worker threads (0: compress on the calling thread). Default 0: with 1 worker the
    /// recorder ran 2-3× slower (`benches/record.rs`), the mcap crate's default is one per core.
    pub compression_threads: u32,
    /// Compression level; 0 is the codec's default (zstd: 3). Default 1: on bench JSON, zstd
    /// level 1 was ~25 % faster than level 3 and no bigger (`benches/record.rs`).
    pub compression_level: u32,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            compression: Some(Compression::Zstd),
            chunk_size: 1024 * 1024,
            gyro_seq_bits: 64,
            flush_interval: Some(Duration::from_secs(1)),
            flush_wall: None,
            flush_on_step_end: true,
            compression_threads: 0,
            compression_level: 1,
        }
    }
}

impl RecorderOptions {
    /// The mcap writer options the recorder uses (also used by the benchmark's baseline).
    pub fn write_options(&self) -> WriteOptions {
        WriteOptions::new()
            .profile("")
            .compression(self.compression)
            .chunk_size(Some(self.chunk_size))
            .compression_threads(self.compression_threads)
            .compression_level(self.compression_level)
    }
}

/// Per-channel writer state.
#[derive(Debug, Clone, Copy)]
struct Chan {
    topic: &'static str,
    id: u16,
    next_sequence: u32,
    last_log_time: u64,
    last_t: Duration,
}

impl Chan {
    fn new(topic: &'static str, id: u16) -> Self {
        Self { topic, id, next_sequence: 0, last_log_time: 0, last_t: Duration::ZERO }
    }
}

/// A step body by reference (the same fields, in the same order, as
/// [`crate::message::StepMsg`]).
#[derive(Serialize)]
struct StepRef<'a> {
    index: u64,
    name: &'a str,
    event: StepEvent,
    label: &'a str,
}

#[derive(Serialize)]
struct LogTime {
    sec: u64,
    nsec: u32,
}

#[derive(Serialize)]
struct LogBody<'a> {
    timestamp: LogTime,
    level: u8,
    message: &'a str,
    name: &'a str,
    file: &'a str,
    line: u32,
}

fn finite(topic: &'static str, field: &'static str, value: f64) -> Result<f64, RecordError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(RecordError::NonFinite { topic, field, value })
    }
}

/// Writes one run's recording: the four required channels, `/log`, metadata and attachments.
///
/// Times are bench times (`Duration` since the run's start epoch). Use from one task; each
/// call serialises into a reused buffer and appends to the current compressed chunk. Nothing
/// recorded is lost on an abort as long as [`Recorder::finish`] runs; on a crash, everything up
/// to the last closed chunk stays readable (chunks close when full, every
/// [`RecorderOptions::flush_interval`] of bench time or [`RecorderOptions::flush_wall`] of
/// wall-clock time, at step ends and on [`Recorder::flush`]). If the
/// recorder is dropped without `finish`, the mcap writer still writes the summary, but no
/// `bench.run` record.
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    epoch_ns: u64,
    software: String,
    model_role: crate::ModelRole,
    buf: Vec<u8>,
    gyro: Chan,
    table: Chan,
    chamber: Chan,
    step: Chan,
    log: Chan,
    gyro_seq_mask: u64,
    last_gyro_seq: Option<u64>,
    gyro_seq_gaps: u64,
    flush_interval: Option<Duration>,
    flush_wall: Option<Duration>,
    flush_on_step_end: bool,
    /// Bench time of the last flush (the latest message time then).
    last_flush_t: Duration,
    /// Wall-clock time of the last flush, and messages since the clock was last read.
    last_flush_wall: Instant,
    unchecked: u32,
    /// Latest message time seen, any channel.
    latest_t: Duration,
}

impl Recorder<BufWriter<File>> {
    /// Create (truncate) `path` and record into it with default options.
    pub fn create(path: &Path, info: RunInfo) -> Result<Self, RecordError> {
        let file = File::create(path)
            .map_err(|source| RecordError::Io { context: "creating the recording file", source })?;
        Self::new(BufWriter::with_capacity(256 * 1024, file), info)
    }
}

impl<W: Write + Seek> Recorder<W> {
    /// Start a recording with default options: writes the header, schemas, channels,
    /// `bench.site`, `bench.scenario`, `bench.gyro_model` and the attachments.
    pub fn new(sink: W, info: RunInfo) -> Result<Self, RecordError> {
        Self::with_options(sink, info, RecorderOptions::default())
    }

    /// Start a recording with the given options.
    pub fn with_options(
        sink: W,
        info: RunInfo,
        options: RecorderOptions,
    ) -> Result<Self, RecordError> {
        let site = info.site.to_metadata()?;
        let mut writer =
            options.write_options().create(sink).map_err(mcap_err("starting the file"))?;
        let no_meta = BTreeMap::new();
        let mut channel =
            |topic: &'static str, name: &str, doc: &str| -> Result<Chan, RecordError> {
                let schema = writer
                    .add_schema(name, SCHEMA_ENCODING, doc.as_bytes())
                    .map_err(mcap_err("adding a schema"))?;
                let id = writer
                    .add_channel(schema, topic, MESSAGE_ENCODING, &no_meta)
                    .map_err(mcap_err("adding a channel"))?;
                Ok(Chan::new(topic, id))
            };
        let gyro = channel(TOPIC_GYRO, SCHEMA_GYRO, GYRO_SCHEMA_JSON)?;
        let table = channel(TOPIC_TABLE, SCHEMA_TABLE, TABLE_SCHEMA_JSON)?;
        let chamber = channel(TOPIC_CHAMBER, SCHEMA_CHAMBER, CHAMBER_SCHEMA_JSON)?;
        let step = channel(TOPIC_STEP, SCHEMA_STEP, STEP_SCHEMA_JSON)?;
        let log = channel(TOPIC_LOG, SCHEMA_LOG, LOG_SCHEMA_JSON)?;

        let meta = |name: &str, metadata: BTreeMap<String, String>| mcap::records::Metadata {
            name: name.to_string(),
            metadata,
        };
        writer.write_metadata(&meta(META_SITE, site)).map_err(mcap_err("writing bench.site"))?;
        let scenario = BTreeMap::from([
            ("name".to_string(), info.scenario_name.clone()),
            ("text".to_string(), info.scenario_text.clone()),
        ]);
        writer
            .write_metadata(&meta(META_SCENARIO, scenario))
            .map_err(mcap_err("writing bench.scenario"))?;
        writer
            .write_metadata(&meta(META_GYRO_MODEL, info.gyro_model.clone()))
            .map_err(mcap_err("writing bench.gyro_model"))?;
        for (name, entries) in [(META_STATION, &info.station), (META_ACCEPTANCE, &info.acceptance)]
        {
            if !entries.is_empty() {
                writer
                    .write_metadata(&meta(name, entries.clone()))
                    .map_err(mcap_err("writing the station metadata"))?;
            }
        }
        let attachments = info
            .scenario_attachment
            .as_deref()
            .map(|name| (name, info.scenario_text.as_str()))
            .into_iter()
            .chain(info.config.as_ref().map(|c| (c.name.as_str(), c.text.as_str())));
        for (name, text) in attachments {
            writer
                .attach(&mcap::Attachment {
                    log_time: info.epoch_ns,
                    create_time: info.epoch_ns,
                    name: name.to_string(),
                    media_type: MEDIA_TYPE_TOML.to_string(),
                    data: Cow::Borrowed(text.as_bytes()),
                })
                .map_err(mcap_err("writing an attachment"))?;
        }
        writer.flush().map_err(mcap_err("flushing the file header"))?;

        let bits = options.gyro_seq_bits.clamp(1, 64);
        Ok(Self {
            writer,
            epoch_ns: info.epoch_ns,
            software: info.software,
            model_role: info.gyro_model_role,
            buf: Vec::with_capacity(512),
            gyro,
            table,
            chamber,
            step,
            log,
            gyro_seq_mask: if bits == 64 { u64::MAX } else { (1u64 << bits) - 1 },
            last_gyro_seq: None,
            gyro_seq_gaps: 0,
            flush_interval: options.flush_interval,
            flush_wall: options.flush_wall,
            flush_on_step_end: options.flush_on_step_end,
            last_flush_t: Duration::ZERO,
            last_flush_wall: Instant::now(),
            unchecked: 0,
            latest_t: Duration::ZERO,
        })
    }

    /// Number of gyro samples flagged with [`status::gyro::SEQ_GAP`] so far.
    pub fn gyro_seq_gaps(&self) -> u64 {
        self.gyro_seq_gaps
    }

    /// Record a gyro sample taken at bench time `t`, with the device's own time stamp
    /// `device_time` (on the bench-time scale) where it has one. Sets
    /// [`status::gyro::SEQ_GAP`] when the device counter did not advance by exactly one since
    /// the previous sample.
    pub fn gyro(
        &mut self,
        t: Duration,
        device_time: Option<Duration>,
        s: &GyroMsg,
    ) -> Result<(), RecordError> {
        let mut status = s.status;
        if let Some(prev) = self.last_gyro_seq {
            if s.seq & self.gyro_seq_mask != prev.wrapping_add(1) & self.gyro_seq_mask {
                status |= status::gyro::SEQ_GAP;
            }
        }
        if status & status::gyro::SEQ_GAP != 0 {
            self.gyro_seq_gaps += 1;
        }
        let topic = TOPIC_GYRO;
        finite(topic, "rate", s.rate_rad_s)?;
        if let Some(v) = s.temperature_c {
            finite(topic, "temperature", v)?;
        }
        let body = GyroMsg { status, ..*s };
        let mut ch = self.gyro;
        let r = self.write(&mut ch, t, device_time, &body);
        self.gyro = ch;
        if r.is_ok() {
            self.last_gyro_seq = Some(s.seq);
        }
        r
    }

    /// Record a table reading taken at bench time `t` (device time stamp as for [`Self::gyro`]).
    pub fn table(
        &mut self,
        t: Duration,
        device_time: Option<Duration>,
        r: &TableMsg,
    ) -> Result<(), RecordError> {
        let topic = TOPIC_TABLE;
        finite(topic, "angle", r.angle_rad)?;
        finite(topic, "rate", r.rate_rad_s)?;
        finite(topic, "rate_command", r.rate_command_rad_s)?;
        let mut ch = self.table;
        let res = self.write(&mut ch, t, device_time, r);
        self.table = ch;
        res
    }

    /// Record a chamber reading taken at bench time `t` (device time stamp as for
    /// [`Self::gyro`]).
    pub fn chamber(
        &mut self,
        t: Duration,
        device_time: Option<Duration>,
        r: &ChamberMsg,
    ) -> Result<(), RecordError> {
        let topic = TOPIC_CHAMBER;
        finite(topic, "temperature", r.temperature_c)?;
        finite(topic, "setpoint", r.setpoint_c)?;
        let mut ch = self.chamber;
        let res = self.write(&mut ch, t, device_time, r);
        self.chamber = ch;
        res
    }

    /// Record a step event at bench time `t`. With [`RecorderOptions::flush_on_step_end`], an
    /// end or abort closes the chunk and flushes the file.
    pub fn step(
        &mut self,
        t: Duration,
        index: u64,
        name: &str,
        event: StepEvent,
        label: &str,
    ) -> Result<(), RecordError> {
        let body = StepRef { index, name, event, label };
        let mut ch = self.step;
        let res = self.write(&mut ch, t, None, &body);
        self.step = ch;
        res?;
        if self.flush_on_step_end && event != StepEvent::Start {
            self.flush()?;
        }
        Ok(())
    }

    /// Record a log message at bench time `t` on `/log` (`foxglove.Log`). `name` is the
    /// emitting component (e.g. the tracing target), `file`/`line` its source location.
    pub fn log(
        &mut self,
        t: Duration,
        level: LogLevel,
        message: &str,
        name: &str,
        file: &str,
        line: u32,
    ) -> Result<(), RecordError> {
        let log_time = self.log_time(TOPIC_LOG, t)?;
        let body = LogBody {
            timestamp: LogTime {
                sec: log_time / 1_000_000_000,
                nsec: (log_time % 1_000_000_000) as u32,
            },
            level: level as u8,
            message,
            name,
            file,
            line,
        };
        let mut ch = self.log;
        let res = self.write(&mut ch, t, None, &body);
        self.log = ch;
        res
    }

    /// Close the current chunk and flush the sink: everything recorded so far is readable even
    /// if the process dies next.
    pub fn flush(&mut self) -> Result<(), RecordError> {
        self.writer.flush().map_err(mcap_err("flushing"))?;
        self.last_flush_t = self.latest_t;
        self.last_flush_wall = Instant::now();
        Ok(())
    }

    /// End the recording: write `bench.run` (format version, start, software, `outcome`), the
    /// summary section and footer; flush and return the sink.
    pub fn finish(mut self, outcome: &Outcome) -> Result<W, RecordError> {
        let run = BTreeMap::from([
            ("format_version".to_string(), FORMAT_VERSION.to_string()),
            ("started".to_string(), rfc3339_utc(self.epoch_ns)),
            ("software".to_string(), self.software.clone()),
            ("outcome".to_string(), outcome.to_string()),
            (crate::schema::RUN_KEY_MODEL_ROLE.to_string(), self.model_role.key().to_string()),
        ]);
        self.writer
            .write_metadata(&mcap::records::Metadata { name: META_RUN.to_string(), metadata: run })
            .map_err(mcap_err("writing bench.run"))?;
        self.writer.finish().map_err(mcap_err("writing the summary"))?;
        let mut sink = self.writer.into_inner();
        sink.flush()
            .map_err(|source| RecordError::Io { context: "flushing the finished file", source })?;
        Ok(sink)
    }

    fn log_time(&self, topic: &'static str, t: Duration) -> Result<u64, RecordError> {
        u64::try_from(t.as_nanos())
            .ok()
            .and_then(|ns| self.epoch_ns.checked_add(ns))
            .ok_or(RecordError::TimeOverflow { topic, t })
    }

    fn write<B: Serialize>(
        &mut self,
        ch: &mut Chan,
        t: Duration,
        device_time: Option<Duration>,
        body: &B,
    ) -> Result<(), RecordError> {
        let log_time = self.log_time(ch.topic, t)?;
        if log_time < ch.last_log_time {
            return Err(RecordError::TimeWentBack { topic: ch.topic, previous: ch.last_t, got: t });
        }
        let publish_time = match device_time {
            Some(d) => self.log_time(ch.topic, d)?,
            None => log_time,
        };
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, body)
            .map_err(|source| RecordError::Json { topic: ch.topic, source })?;
        let header =
            MessageHeader { channel_id: ch.id, sequence: ch.next_sequence, log_time, publish_time };
        self.writer
            .write_to_known_channel(&header, &self.buf)
            .map_err(mcap_err("writing a message"))?;
        ch.next_sequence = ch.next_sequence.wrapping_add(1);
        ch.last_log_time = log_time;
        ch.last_t = t;
        self.latest_t = self.latest_t.max(t);
        match self.flush_interval {
            Some(interval) if self.latest_t >= self.last_flush_t + interval => return self.flush(),
            _ => {}
        }
        if let Some(wall) = self.flush_wall {
            self.unchecked += 1;
            if self.unchecked >= 64 {
                self.unchecked = 0;
                if self.last_flush_wall.elapsed() >= wall {
                    return self.flush();
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
