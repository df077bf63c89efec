//! `bench recover IN OUT`: rebuild a readable, indexed MCAP file from a truncated or damaged one
//! (a crashed run, a copy that stopped half-way).
//!
//! Every intact record is read in one linear pass and written to a fresh file with the same
//! header profile, schema and channel ids, messages (headers and bodies as they were), metadata
//! and attachments, plus a summary section (statistics, chunk, metadata and attachment
//! indexes). Damage costs only itself, as in every reader of bench ([`crate::reader`]): a chunk
//! that fails its CRC or does not decompress is left out whole, bytes that do not frame as
//! records are skipped to the next valid record, and the pass ends where the file does (or at
//! its data end). Nothing is decoded: any MCAP file recovers, not only bench recordings.
//!
//! ```no_run
//! let report = bench_recording::recover::recover_file("crashed.mcap".as_ref(), "fixed.mcap".as_ref())?;
//! println!("{report}");
//! # Ok::<(), bench_recording::recover::RecoverError>(())
//! ```

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, Write};
use std::path::{Path, PathBuf};

use mcap::records::{op, Record};

use crate::reader::scan::{kind, Scanner, Top};
use crate::reader::{End, RecordingError};

/// Why nothing could be recovered.
#[derive(Debug, thiserror::Error)]
pub enum RecoverError {
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Reading failed part-way (not damage: the source itself failed).
    #[error("read error at byte {at_byte}: {source}")]
    Read {
        /// Bytes read so far.
        at_byte: u64,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The input does not start like an MCAP file: nothing to recover.
    #[error("not an MCAP file (at byte {at_byte}): {reason}")]
    NotMcap {
        /// Bytes read when it was given up.
        at_byte: u64,
        /// What the MCAP reader saw.
        reason: String,
    },
    /// Writing the new file failed.
    #[error("cannot write the recovered file: {0}")]
    Write(#[from] mcap::McapError),
}

/// What was kept.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RecoverReport {
    /// Input size, bytes.
    pub input_bytes: u64,
    /// Messages kept per topic.
    pub messages: BTreeMap<String, u64>,
    /// Schemas and channels kept.
    pub schemas: usize,
    /// Channels kept.
    pub channels: usize,
    /// Metadata records kept.
    pub metadata: usize,
    /// Attachments kept.
    pub attachments: usize,
    /// Messages dropped because their channel was never defined (or its schema was missing).
    pub orphans: u64,
    /// Whether the input was complete (footer read): then nothing was lost.
    pub complete: bool,
    /// Where the input breaks: the end of the last complete record, and what came after.
    pub break_at: Option<Break>,
    /// Damaged parts left out (chunks, unreadable spans), in file order; reading went on after
    /// each.
    pub skipped: Vec<Skipped>,
}

/// A damaged part of the input that was left out.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Skipped {
    /// Its first byte.
    pub at_byte: u64,
    /// Its length, bytes.
    pub bytes: u64,
    /// What is wrong with it.
    pub reason: String,
}

/// Where and why the input stops being readable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Break {
    /// End of the last complete record, bytes from the start of the file: everything before
    /// it was kept.
    pub at_byte: u64,
    /// The last complete record's kind (e.g. `Chunk`, `MessageIndex`).
    pub after_record: String,
    /// What the MCAP reader saw after it.
    pub reason: String,
}

impl RecoverReport {
    /// Messages kept, all channels.
    pub fn total_messages(&self) -> u64 {
        self.messages.values().sum()
    }
}

impl fmt::Display for RecoverReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.break_at {
            None => writeln!(f, "input complete ({} bytes): nothing was lost", self.input_bytes)?,
            Some(b) => writeln!(
                f,
                "input breaks at byte {} of {} ({:.1} %), after a {} record: {}",
                b.at_byte,
                self.input_bytes,
                100.0 * b.at_byte as f64 / (self.input_bytes.max(1)) as f64,
                b.after_record,
                b.reason
            )?,
        }
        writeln!(
            f,
            "kept {} message(s) on {} channel(s), {} schema(s), {} metadata record(s), {} \
             attachment(s)",
            self.total_messages(),
            self.channels,
            self.schemas,
            self.metadata,
            self.attachments
        )?;
        for (topic, n) in &self.messages {
            writeln!(f, "  {topic}: {n}")?;
        }
        for x in &self.skipped {
            writeln!(
                f,
                "left out bytes {}..{} ({} bytes): {}",
                x.at_byte,
                x.at_byte + x.bytes,
                x.bytes,
                x.reason
            )?;
        }
        if self.orphans > 0 {
            writeln!(f, "dropped {} message(s) of undefined channels", self.orphans)?;
        }
        Ok(())
    }
}

/// Recover `input` into a new file `output` (overwritten).
pub fn recover_file(input: &Path, output: &Path) -> Result<RecoverReport, RecoverError> {
    let file_err = |path: &Path| {
        let path = path.to_path_buf();
        move |source| RecoverError::File { path, source }
    };
    let file = File::open(input).map_err(file_err(input))?;
    let len = file.metadata().map_err(file_err(input))?.len();
    let out = File::create(output).map_err(file_err(output))?;
    let source = BufReader::with_capacity(256 * 1024, file);
    let mut report = recover_seekable(source, BufWriter::new(out)).and_then(|(r, w)| {
        let f = w.into_inner().map_err(|e| RecoverError::File {
            path: output.to_path_buf(),
            source: e.into_error(),
        })?;
        f.sync_all().map_err(file_err(output))?;
        Ok(r)
    })?;
    report.input_bytes = len;
    Ok(report)
}

/// Rewrite the finished recording at `path` in full chunks, in place: a paced run closes a
/// chunk at every flush (to bound what a kill loses), so its file is made of small ones. The
/// copy is written beside the file and renamed over it once complete, so a kill during the
/// compaction leaves the original. Returns whether the file was replaced: a file that is not
/// complete, or has damage, is left as it is.
pub fn compact_file(path: &Path) -> Result<bool, RecoverError> {
    let tmp = path.with_extension("mcap.compacting");
    let file_err = |p: &Path| {
        let p = p.to_path_buf();
        move |source| RecoverError::File { path: p, source }
    };
    let (report, written) = {
        let file = File::open(path).map_err(file_err(path))?;
        let out = File::create(&tmp).map_err(file_err(&tmp))?;
        let source = BufReader::with_capacity(256 * 1024, file);
        let (report, w) = recover_with(source, BufWriter::new(out), write_options(), &[])?;
        let f = w
            .into_inner()
            .map_err(|e| RecoverError::File { path: tmp.clone(), source: e.into_error() })?;
        f.sync_all().map_err(file_err(&tmp))?;
        (report, f)
    };
    drop(written);
    let intact = report.complete
        && report.break_at.is_none()
        && report.skipped.is_empty()
        && report.orphans == 0;
    if !intact {
        let _ = std::fs::remove_file(&tmp);
        return Ok(false);
    }
    std::fs::rename(&tmp, path).map_err(file_err(path))?;
    Ok(true)
}

/// Recover from any byte source into `sink` (zstd chunks, full summary). Returns the report
/// (its `input_bytes` is the bytes read) and the finished sink.
pub fn recover<R: Read, W: Write + Seek>(
    source: R,
    sink: W,
) -> Result<(RecoverReport, W), RecoverError> {
    recover_with(source, sink, write_options(), &[])
}

/// [`recover`] from a source that can seek: the channel definitions of its summary section,
/// where it has a readable one, stand in for those lost to damage (as `bench recover` does).
pub fn recover_seekable<R: Read + Seek, W: Write + Seek>(
    mut source: R,
    sink: W,
) -> Result<(RecoverReport, W), RecoverError> {
    let read = |source| RecoverError::Read { at_byte: 0, source };
    let len = source.seek(std::io::SeekFrom::End(0)).map_err(read)?;
    let fallback = crate::reader::summary_records(&mut source, len).unwrap_or_default();
    source.seek(std::io::SeekFrom::Start(0)).map_err(read)?;
    recover_with(source, sink, write_options(), &fallback)
}

/// zstd level 1 chunks of the recorder's size.
fn write_options() -> mcap::WriteOptions {
    crate::writer::RecorderOptions::default().write_options()
}

/// [`recover`], writing with `options` (their profile is replaced by the input's), with the
/// Schema and Channel records `fallback` (opcode, body; a file's summary section) defining the
/// channels whose own records are lost to damage.
pub fn recover_with<R: Read, W: Write + Seek>(
    source: R,
    sink: W,
    options: mcap::WriteOptions,
    fallback: &[(u8, Vec<u8>)],
) -> Result<(RecoverReport, W), RecoverError> {
    let mut scan = Scanner::new(source, crate::reader::MAX_RECORD as u64, None);
    let mut report = RecoverReport::default();
    let mut out: Option<Rebuild<W>> = None;
    let mut sink = Some(sink);
    let mut last_kind = String::new();
    while let Some(top) = scan.next_top() {
        match top {
            Top::Failed(RecordingError::Io { at_byte, source }) => {
                return Err(RecoverError::Read { at_byte, source })
            }
            Top::Failed(e) => {
                let (at_byte, reason) = match e {
                    RecordingError::NotMcap { at_byte, reason } => (at_byte, reason),
                    other => (scan.offset(), other.to_string()),
                };
                return Err(RecoverError::NotMcap { at_byte, reason });
            }
            Top::Skipped { at, to, reason } => {
                report.skipped.push(Skipped { at_byte: at, bytes: to - at, reason })
            }
            Top::End(End::Cut { at_byte, reason }) => {
                report.break_at = Some(Break { at_byte, after_record: last_kind.clone(), reason });
            }
            Top::End(_) => {}
            Top::Record { at, opcode, body } => {
                // The summary section repeats schemas and channels (kept once) and indexes (the
                // writer makes its own): reading on costs nothing and survives a false data end.
                if opcode == op::DATA_END || opcode == op::FOOTER {
                    report.complete = true;
                    continue;
                }
                let record = match crate::reader::parse_record(opcode, &body) {
                    Ok(r) => r,
                    Err(e) => {
                        let reason = format!("bad {} record: {e}", kind(opcode));
                        report.skipped.push(Skipped {
                            at_byte: at,
                            bytes: 9 + body.len() as u64,
                            reason,
                        });
                        continue;
                    }
                };
                let rebuild = match (&mut out, &record) {
                    (Some(o), _) => o,
                    (None, r) => {
                        let profile = match r {
                            Record::Header(h) => h.profile.clone(),
                            _ => String::new(),
                        };
                        let Some(s) = sink.take() else { break };
                        let mut r = Rebuild::new(s, options.clone().profile(profile))?;
                        r.fallback(fallback);
                        out.insert(r)
                    }
                };
                let taken = match record {
                    // Opened whole (decompressed, its CRC checked) before any of its records is
                    // copied: a damaged chunk contributes nothing.
                    Record::Chunk { .. } => chunk_records(&body).and_then(|records| {
                        records.into_iter().try_for_each(|r| rebuild.take(r, &mut report))
                    }),
                    other => rebuild.take(other, &mut report),
                };
                if let Err(reason) = taken {
                    let bytes = 9 + body.len() as u64;
                    report.skipped.push(Skipped { at_byte: at, bytes, reason });
                }
                last_kind = kind(opcode);
            }
        }
    }
    let Some(out) = out else {
        return Err(RecoverError::NotMcap {
            at_byte: scan.offset(),
            reason: "no MCAP record".into(),
        });
    };
    if !report.complete && report.break_at.is_none() {
        report.break_at = Some(Break {
            at_byte: scan.offset(),
            after_record: last_kind,
            reason: "the file ends before its DataEnd record".into(),
        });
    }
    report.input_bytes = scan.offset();
    let (counts, sink) = out.finish()?;
    report.messages = counts;
    Ok((report, sink))
}

/// The new file being written.
struct Rebuild<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: HashSet<u16>,
    channels: HashMap<u16, String>,
    counts: BTreeMap<String, u64>,
    /// Definitions to use where the file's own are lost (its summary's).
    spare: HashMap<u16, Record<'static>>,
    spare_schemas: HashMap<u16, Record<'static>>,
}

impl<W: Write + Seek> Rebuild<W> {
    fn new(sink: W, opts: mcap::WriteOptions) -> Result<Self, RecoverError> {
        Ok(Self {
            writer: opts.create(sink)?,
            schemas: HashSet::new(),
            channels: HashMap::new(),
            counts: BTreeMap::new(),
            spare: HashMap::new(),
            spare_schemas: HashMap::new(),
        })
    }

    fn fallback(&mut self, records: &[(u8, Vec<u8>)]) {
        for (opcode, body) in records {
            match crate::reader::parse_record(*opcode, body).map(Record::into_owned) {
                Ok(Record::Schema { header, data }) => {
                    self.spare_schemas.insert(header.id, Record::Schema { header, data });
                }
                Ok(Record::Channel(c)) => {
                    self.spare.insert(c.id, Record::Channel(c));
                }
                _ => {}
            }
        }
    }

    /// Define channel `id` (and its schema) from the spare definitions; whether it now is.
    fn define_spare(&mut self, id: u16, report: &mut RecoverReport) -> Result<bool, String> {
        let Some(Record::Channel(c)) = self.spare.remove(&id) else { return Ok(false) };
        if c.schema_id != 0 && !self.schemas.contains(&c.schema_id) {
            if let Some(schema) = self.spare_schemas.remove(&c.schema_id) {
                self.take(schema, report)?;
            }
        }
        self.take(Record::Channel(c), report)?;
        Ok(self.channels.contains_key(&id))
    }

    /// Copy one top-level record (a chunk is opened and its records copied).
    fn take(&mut self, record: Record<'_>, report: &mut RecoverReport) -> Result<(), String> {
        match record {
            Record::Schema { header, data } if self.schemas.insert(header.id) => {
                self.writer
                    .add_schema_with_id(header.id, &header.name, &header.encoding, &data)
                    .map_err(|e| e.to_string())?;
                report.schemas += 1;
            }
            Record::Channel(c) => {
                if self.channels.contains_key(&c.id) {
                    return Ok(());
                }
                if c.schema_id != 0 && !self.schemas.contains(&c.schema_id) {
                    // Its schema never came: the channel cannot be written.
                    return Ok(());
                }
                self.writer
                    .add_channel_with_id(
                        c.id,
                        c.schema_id,
                        &c.topic,
                        &c.message_encoding,
                        &c.metadata,
                    )
                    .map_err(|e| e.to_string())?;
                self.channels.insert(c.id, c.topic);
                report.channels += 1;
            }
            Record::Message { header, data } => {
                if !self.channels.contains_key(&header.channel_id)
                    && !self.define_spare(header.channel_id, report)?
                {
                    report.orphans += 1;
                    return Ok(());
                }
                let Some(topic) = self.channels.get(&header.channel_id) else {
                    return Ok(());
                };
                *self.counts.entry(topic.clone()).or_default() += 1;
                self.writer.write_to_known_channel(&header, &data).map_err(|e| e.to_string())?;
            }
            Record::Metadata(m) => {
                self.writer.write_metadata(&m).map_err(|e| e.to_string())?;
                report.metadata += 1;
            }
            Record::Attachment { header, data, .. } => {
                self.writer
                    .attach(&mcap::Attachment {
                        log_time: header.log_time,
                        create_time: header.create_time,
                        name: header.name,
                        media_type: header.media_type,
                        data,
                    })
                    .map_err(|e| e.to_string())?;
                report.attachments += 1;
            }
            // Indexes, statistics and the like are rebuilt by the writer.
            _ => {}
        }
        Ok(())
    }

    fn finish(mut self) -> Result<(BTreeMap<String, u64>, W), RecoverError> {
        self.writer.finish()?;
        Ok((self.counts, self.writer.into_inner()))
    }
}

/// The records of a chunk record's `body`, all of them, or why the chunk is unreadable.
fn chunk_records(body: &[u8]) -> Result<Vec<Record<'static>>, String> {
    let mut records = Vec::new();
    let opened = crate::reader::chunk::for_each_record(body, MAX_CHUNK, |op, data| {
        records.push(crate::reader::parse_record(op, data).map(Record::into_owned))
    });
    opened.map_err(|e| format!("chunk unreadable: {}", e.reason))?;
    records.into_iter().map(|r| r.map_err(|e| format!("chunk unreadable: {e}"))).collect()
}

/// The largest chunk (uncompressed) `recover` decodes, as the reader's largest record.
const MAX_CHUNK: u64 = crate::reader::MAX_RECORD as u64;

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::io::Cursor;
    use std::time::Duration;

    use super::*;
    use crate::message::{GyroMsg, Outcome, StepEvent, TableMsg};
    use crate::reader::Recording;
    use crate::site::Site;
    use crate::writer::{Recorder, RecorderOptions, RunInfo};

    /// 60 s at 20 Hz, 16 kB chunks (so a cut loses little), one attachment (the scenario).
    fn original(compression: Option<mcap::Compression>) -> Vec<u8> {
        let info =
            RunInfo::new(1_000, "t", "name = 't'\n", Site::at_latitude(1.0), BTreeMap::new());
        let opts = RecorderOptions {
            chunk_size: 16 * 1024,
            flush_interval: None,
            compression,
            ..RecorderOptions::default()
        };
        let mut r = Recorder::with_options(Cursor::new(Vec::new()), info, opts).expect("start");
        r.step(Duration::ZERO, 0, "w", StepEvent::Start, "").expect("step");
        for i in 0..1_200u64 {
            let t = Duration::from_millis(50 * i);
            let s = GyroMsg { rate_rad_s: i as f64, temperature_c: None, seq: i, status: 0 };
            r.gyro(t, None, &s).expect("gyro");
            let tr = TableMsg {
                angle_rad: i as f64,
                rate_rad_s: 1.0,
                rate_command_rad_s: 1.0,
                status: 0,
            };
            r.table(t, None, &tr).expect("table");
        }
        r.step(Duration::from_secs(60), 0, "w", StepEvent::End, "").expect("step");
        r.finish(&Outcome::Completed).expect("finish").into_inner()
    }

    /// Recovered as `recover_file` does: the summary's channels stand in for lost ones.
    fn recover_bytes(bytes: &[u8]) -> (RecoverReport, Vec<u8>) {
        let (report, out) =
            recover_seekable(Cursor::new(bytes), Cursor::new(Vec::new())).expect("recovers");
        (report, out.into_inner())
    }

    #[test]
    fn a_chunk_claiming_an_impossible_size_is_left_out_not_an_abort() {
        // Found by the `recover` fuzz target: the chunk reader allocated the claimed
        // 8243118308127416885 bytes and the process aborted.
        let mut bytes = original(Some(mcap::Compression::Zstd));
        // The second chunk (the first holds the schemas and channels).
        let mut pos = 8;
        let mut chunks = 0;
        while bytes[pos] != 0x06 || chunks < 1 {
            chunks += usize::from(bytes[pos] == 0x06);
            let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().expect("8 bytes"));
            pos += 9 + usize::try_from(len).expect("small");
        }
        // Chunk body: message start and end time, then the uncompressed size.
        bytes[pos + 25..pos + 33].copy_from_slice(&8_243_118_308_127_416_885u64.to_le_bytes());
        let (report, out) = recover_bytes(&bytes);
        let x = report.skipped.first().expect("the chunk is left out");
        assert_eq!(x.at_byte, pos as u64, "{x:?}");
        assert!(x.reason.contains("8243118308127416885 uncompressed bytes"), "{x:?}");
        // The rest is kept: the file is complete, later chunks' messages recovered.
        assert!(report.complete && report.break_at.is_none(), "{report}");
        let full = Recording::from_bytes(&original(Some(mcap::Compression::Zstd))).expect("full");
        let got = Recording::from_bytes(&out).expect("recovered");
        assert!(!got.gyro.is_empty() && got.gyro.len() < full.gyro.len());
        assert_eq!(got.gyro.last(), full.gyro.last());
    }

    #[test]
    fn a_record_claiming_an_impossible_length_is_skipped_not_an_abort() {
        // Found by the `recover` fuzz target: the reader allocated the claimed length.
        let mut bytes = original(Some(mcap::Compression::Zstd));
        let len = u64::from_le_bytes(bytes[9..17].try_into().expect("8 bytes"));
        let second = 17 + usize::try_from(len).expect("small");
        bytes[second + 1..second + 9].copy_from_slice(&7_308_324_466_015_219_617u64.to_le_bytes());
        let (report, _) = recover_bytes(&bytes);
        let x = report.skipped.first().expect("skipped");
        assert_eq!(x.at_byte, second as u64, "{x:?}");
        assert!(x.reason.contains("7308324466015219617"), "{x:?}");
    }

    #[test]
    fn a_chunk_whose_record_claims_an_impossible_length_is_left_out_not_an_abort() {
        // Found by the `recover` fuzz target: mcap's chunk reader reserved the length.
        let bytes =
            include_bytes!("../../fuzz/regressions/recover-chunk-inner-record-length-abort");
        let (report, _) = recover_bytes(bytes);
        assert!(report.skipped.iter().any(|x| x.reason.contains("chunk unreadable")), "{report}");
    }

    #[test]
    fn a_complete_file_is_copied_whole() {
        let bytes = original(Some(mcap::Compression::Zstd));
        let (report, out) = recover_bytes(&bytes);
        assert!(report.complete && report.break_at.is_none());
        assert_eq!(report.messages.get("/gyro/rate"), Some(&1_200));
        assert_eq!(report.messages.get("/bench/step"), Some(&2));
        let (a, b) = (Recording::from_bytes(&bytes), Recording::from_bytes(&out));
        let (a, b) = (a.expect("original"), b.expect("recovered"));
        assert_eq!(a, b);
        assert_eq!((report.metadata, report.attachments), (4, 1));
    }

    #[test]
    fn truncated_files_recover_every_complete_record_with_an_index() {
        for compression in [Some(mcap::Compression::Zstd), Some(mcap::Compression::Lz4), None] {
            let bytes = original(compression);
            let full = Recording::from_bytes(&bytes).expect("original");
            let len = bytes.len();
            // 10 %, 50 %, 90 %, and in the middle of the record that straddles 50 %.
            for cut in [len / 10, len / 2, len * 9 / 10, len / 2 + 7] {
                let truncated = &bytes[..cut];
                let (report, out) = recover_bytes(truncated);
                let what = format!("{compression:?} cut at {cut} of {len}");
                let brk = report.break_at.clone().expect("broken");
                assert!(!report.complete, "{what}");
                assert!(brk.at_byte <= cut as u64 && brk.at_byte > 8, "{what}: {brk:?}");
                // The recovered file is complete, indexed, and holds what a reader of the cut
                // file sees: a prefix of the original.
                let summary = mcap::Summary::read(&out).expect("summary readable");
                let stats = summary.and_then(|s| s.stats).expect("statistics");
                assert_eq!(stats.message_count, report.total_messages(), "{what}");
                let got = Recording::from_bytes(&out).expect("recovered");
                assert!(got.complete, "{what}");
                // (The streaming reader may also hand out messages of the cut chunk before its
                // CRC could be checked; recover keeps whole chunks only.)
                let seen = Recording::from_bytes(truncated).expect("cut file readable");
                assert!(seen.gyro.len() >= got.gyro.len(), "{what}");
                assert!(seen.gyro.len() - got.gyro.len() <= 200, "{what}");
                assert_eq!(got.gyro[..], seen.gyro[..got.gyro.len()], "{what}");
                assert_eq!(got.table[..], seen.table[..got.table.len()], "{what}");
                assert_eq!(got.metadata[..], seen.metadata[..got.metadata.len()], "{what}");
                assert_eq!(got.gyro[..], full.gyro[..got.gyro.len()], "{what}");
                let kept = report.messages.get("/gyro/rate").copied().unwrap_or(0);
                assert_eq!(kept as usize, got.gyro.len(), "{what}");
                if cut >= len / 2 {
                    assert!(kept >= 400, "{what}: kept {kept}");
                }
                assert!(report.to_string().contains(&format!("breaks at byte {}", brk.at_byte)));
            }
        }
    }

    /// A writer killed mid-chunk leaves the chunk's length as a placeholder (u64::MAX): the
    /// recovery stops there (this overflowed the mcap reader's arithmetic and panicked).
    #[test]
    fn a_killed_writers_open_chunk_ends_the_input() {
        #[derive(Clone, Default)]
        struct Shared(std::rc::Rc<std::cell::RefCell<Cursor<Vec<u8>>>>);
        impl std::io::Write for Shared {
            fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
                self.0.borrow_mut().write(b)
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        impl std::io::Seek for Shared {
            fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
                self.0.borrow_mut().seek(pos)
            }
        }
        let info = RunInfo::new(1_000, "t", "", Site::at_latitude(1.0), BTreeMap::new());
        let opts = RecorderOptions {
            flush_interval: Some(Duration::from_secs(1)),
            compression: None,
            ..RecorderOptions::default()
        };
        let sink = Shared::default();
        let mut r = Recorder::with_options(sink.clone(), info, opts).expect("start");
        for i in 0..130u64 {
            let s = GyroMsg { rate_rad_s: 0.0, temperature_c: None, seq: i, status: 0 };
            r.gyro(Duration::from_millis(50 * i), None, &s).expect("gyro");
        }
        let killed = sink.0.borrow().get_ref().clone();
        drop(r);
        let (report, out) = recover_bytes(&killed);
        assert!(!report.complete);
        // Flushed at 1, 2, …, 6 s: samples 0..=120 are in closed chunks; the open chunk is
        // uncompressed, so its records are in the file too, after a header that does not
        // frame (its lengths are placeholders), and are kept as well.
        assert_eq!(report.messages.get("/gyro/rate"), Some(&130));
        assert_eq!(report.skipped.len(), 1, "{report}");
        assert!(Recording::from_bytes(&out).expect("recovered").complete);
    }

    #[test]
    fn compaction_rewrites_a_paced_runs_small_chunks_into_full_ones_losing_nothing() {
        // A paced run's file: a chunk closed every 0.75 s of bench time.
        let info = RunInfo::new(1_000, "t", "x = 1\n", Site::at_latitude(1.0), BTreeMap::new());
        let opts = RecorderOptions {
            flush_interval: Some(Duration::from_millis(750)),
            ..RecorderOptions::default()
        };
        let mut r = Recorder::with_options(Cursor::new(Vec::new()), info, opts).expect("start");
        r.step(Duration::ZERO, 0, "w", StepEvent::Start, "").expect("step");
        for i in 0..2_400u64 {
            let s = GyroMsg { rate_rad_s: i as f64, temperature_c: None, seq: i, status: 0 };
            r.gyro(Duration::from_millis(50 * i), None, &s).expect("gyro");
        }
        r.step(Duration::from_secs(120), 0, "w", StepEvent::End, "").expect("step");
        let small = r.finish(&Outcome::Completed).expect("finish").into_inner();
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("paced.mcap");
        std::fs::write(&path, &small).expect("write");
        assert!(compact_file(&path).expect("compacts"), "an intact file is replaced");
        let full = std::fs::read(&path).expect("read");
        let chunks = |b: &[u8]| {
            let summary = mcap::Summary::read(b).expect("summary").expect("has one");
            summary.chunk_indexes.len()
        };
        assert!(chunks(&small) >= 150, "{} chunks before", chunks(&small));
        assert!(chunks(&full) <= 2, "{} chunks after", chunks(&full));
        assert!(full.len() < small.len(), "{} → {} bytes", small.len(), full.len());
        let (a, b) =
            (Recording::from_bytes(&small).expect("a"), Recording::from_bytes(&full).expect("b"));
        assert_eq!(a.gyro, b.gyro);
        assert_eq!(a.steps, b.steps);
        assert_eq!(a.outcome(), b.outcome());
        assert!(!dir.path().join("paced.mcap.compacting").exists(), "no copy left behind");
        // A cut file is left as it is.
        std::fs::write(&path, &small[..small.len() / 2]).expect("write");
        assert!(!compact_file(&path).expect("reads"), "a cut file is not replaced");
        assert_eq!(std::fs::read(&path).expect("read").len(), small.len() / 2);
    }

    #[test]
    fn garbage_is_not_mcap() {
        let e = recover(&b"PAR1 this is parquet, not mcap"[..], Cursor::new(Vec::new()))
            .expect_err("refused");
        assert!(matches!(e, RecoverError::NotMcap { .. }), "{e}");
        let e = recover(&b""[..], Cursor::new(Vec::new())).expect_err("refused");
        assert!(e.to_string().starts_with("not an MCAP file"), "{e}");
    }
}
