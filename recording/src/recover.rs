//! `bench recover IN OUT`: rebuild a readable, indexed MCAP file from a truncated or damaged one
//! (a crashed run, a copy that stopped half-way).
//!
//! Every complete record before the damage is read in one linear pass (chunk CRCs checked: a
//! chunk that fails its CRC ends the pass) and written to a fresh file with the same header
//! profile, schema and channel ids, messages (headers and bodies as they were), metadata and
//! attachments, plus a summary section (statistics, chunk, metadata and attachment indexes).
//! Nothing is decoded: any MCAP file recovers, not only bench recordings.
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
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};

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
    let mut report = recover(BufReader::with_capacity(256 * 1024, file), BufWriter::new(out))
        .and_then(|(r, w)| {
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

fn kind(opcode: u8) -> String {
    match opcode {
        op::HEADER => "Header".into(),
        op::FOOTER => "Footer".into(),
        op::SCHEMA => "Schema".into(),
        op::CHANNEL => "Channel".into(),
        op::MESSAGE => "Message".into(),
        op::CHUNK => "Chunk".into(),
        op::MESSAGE_INDEX => "MessageIndex".into(),
        op::CHUNK_INDEX => "ChunkIndex".into(),
        op::ATTACHMENT => "Attachment".into(),
        op::ATTACHMENT_INDEX => "AttachmentIndex".into(),
        op::STATISTICS => "Statistics".into(),
        op::METADATA => "Metadata".into(),
        op::METADATA_INDEX => "MetadataIndex".into(),
        op::SUMMARY_OFFSET => "SummaryOffset".into(),
        op::DATA_END => "DataEnd".into(),
        other => format!("opcode 0x{other:02x}"),
    }
}

/// Recover from any byte source into `sink` (zstd chunks, full summary). Returns the report
/// (its `input_bytes` is the bytes read) and the finished sink.
pub fn recover<R: Read, W: Write + Seek>(
    mut source: R,
    sink: W,
) -> Result<(RecoverReport, W), RecoverError> {
    // Emit chunks whole, so that each event is one top-level record and its end is a byte
    // position of the file; their messages are read with a second reader.
    // A record longer than the reader's limit is damage, not a size to allocate: a killed
    // writer leaves its last chunk's length a placeholder (u64::MAX), and a corrupt one (7e18,
    // found by fuzzing) would abort the process on allocation. Both end the input.
    let options = LinearReaderOptions::default()
        .with_emit_chunks(true)
        .with_record_length_limit(crate::reader::MAX_RECORD);
    let mut reader = LinearReader::new_with_options(options);
    let mut at_byte: u64 = 0;
    let mut end_of_last: u64 = 0;
    let mut last_kind = String::new();
    let mut report = RecoverReport::default();
    let mut out: Option<Rebuild<W>> = None;
    let mut sink = Some(sink);
    let mut failure: Option<String> = None;
    loop {
        let event = match reader.next_event() {
            None => break,
            Some(Err(e)) => {
                failure = Some(e.to_string());
                break;
            }
            Some(Ok(ev)) => ev,
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = loop {
                    match source.read(reader.insert(need)) {
                        Ok(n) => break n,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(source) => return Err(RecoverError::Read { at_byte, source }),
                    }
                };
                reader.notify_read(n);
                at_byte += n as u64;
            }
            LinearReadEvent::Record { opcode, data } => {
                // Opcode (1) + length (8) + body: where this record ends. The start magic (8
                // bytes) precedes the first record.
                let start = if end_of_last == 0 { 8 } else { end_of_last };
                let end = start + 9 + data.len() as u64;
                let parsed = crate::reader::parse_record(opcode, data);
                let record = match parsed {
                    Ok(r) => r,
                    Err(e) => {
                        failure = Some(format!("bad {} record at byte {start}: {e}", kind(opcode)));
                        break;
                    }
                };
                if opcode == op::DATA_END {
                    end_of_last = end;
                    last_kind = kind(opcode);
                    report.complete = true;
                    break;
                }
                if let Record::Header(h) = &record {
                    let Some(s) = sink.take() else {
                        failure = Some(format!("a second Header record at byte {start}"));
                        break;
                    };
                    out = Some(Rebuild::new(s, &h.profile)?);
                } else if let Some(o) = out.as_mut() {
                    if let Err(reason) = o.take(record, &mut report) {
                        failure =
                            Some(format!("{} record at byte {start}: {reason}", kind(opcode)));
                        break;
                    }
                } else {
                    return Err(RecoverError::NotMcap {
                        at_byte,
                        reason: format!("the first record is a {}, not a Header", kind(opcode)),
                    });
                }
                end_of_last = end;
                last_kind = kind(opcode);
            }
        }
    }
    let Some(out) = out else {
        return Err(RecoverError::NotMcap {
            at_byte,
            reason: failure.unwrap_or_else(|| "no Header record".into()),
        });
    };
    if !report.complete {
        report.break_at = Some(Break {
            at_byte: end_of_last,
            after_record: last_kind,
            reason: failure.unwrap_or_else(|| "the file ends before its DataEnd record".into()),
        });
    }
    report.input_bytes = at_byte;
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
}

impl<W: Write + Seek> Rebuild<W> {
    fn new(sink: W, profile: &str) -> Result<Self, RecoverError> {
        let opts = mcap::WriteOptions::new()
            .profile(profile)
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1);
        Ok(Self {
            writer: opts.create(sink)?,
            schemas: HashSet::new(),
            channels: HashMap::new(),
            counts: BTreeMap::new(),
        })
    }

    /// Copy one top-level record (a chunk is opened and its records copied).
    fn take(&mut self, record: Record<'_>, report: &mut RecoverReport) -> Result<(), String> {
        match record {
            Record::Chunk { header, data } => {
                // mcap's chunk reader sizes its buffer from the header's uncompressed size: a
                // corrupt one (8e18) aborts the process on allocation (found by fuzzing).
                if header.uncompressed_size > MAX_CHUNK {
                    return Err(format!(
                        "chunk unreadable: its header claims {} uncompressed bytes (at most {} \
                         read)",
                        header.uncompressed_size, MAX_CHUNK
                    ));
                }
                // Decode the whole chunk first (its CRC is checked at its end): a damaged chunk
                // contributes nothing.
                let records =
                    chunk_records(&header, &data).map_err(|e| format!("chunk unreadable: {e}"))?;
                for inner in records {
                    self.take(inner, report)?;
                }
            }
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
                let Some(topic) = self.channels.get(&header.channel_id) else {
                    report.orphans += 1;
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

/// The records of a chunk, read with the reader's record length limit: `mcap::read::
/// ChunkReader` has none, and reserved a corrupt inner record's length (8e18) and aborted
/// (found by fuzzing). The chunk is read as a one-record file by the sans-IO reader.
fn chunk_records(
    header: &mcap::records::ChunkHeader,
    data: &[u8],
) -> Result<Vec<Record<'static>>, String> {
    let mut body = Vec::with_capacity(data.len() + 64);
    body.extend_from_slice(&header.message_start_time.to_le_bytes());
    body.extend_from_slice(&header.message_end_time.to_le_bytes());
    body.extend_from_slice(&header.uncompressed_size.to_le_bytes());
    body.extend_from_slice(&header.uncompressed_crc.to_le_bytes());
    let name = header.compression.as_bytes();
    body.extend_from_slice(&u32::try_from(name.len()).map_err(|e| e.to_string())?.to_le_bytes());
    body.extend_from_slice(name);
    body.extend_from_slice(&(data.len() as u64).to_le_bytes());
    body.extend_from_slice(data);
    let mut file = Vec::with_capacity(body.len() + 17);
    file.extend_from_slice(mcap::MAGIC);
    file.push(mcap::records::op::CHUNK);
    file.extend_from_slice(&(body.len() as u64).to_le_bytes());
    file.extend_from_slice(&body);
    let options = LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_validate_chunk_crcs(true)
        .with_record_length_limit(MAX_CHUNK as usize);
    let mut reader = LinearReader::new_with_options(options);
    let mut at: usize = 0;
    let mut out = Vec::new();
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| e.to_string())? {
            LinearReadEvent::ReadRequest(n) => {
                let src = file.get(at..at.saturating_add(n).min(file.len())).unwrap_or(&[]);
                let buf = reader.insert(n);
                buf[..src.len()].copy_from_slice(src);
                reader.notify_read(src.len());
                at += src.len();
            }
            LinearReadEvent::Record { opcode, data } => {
                out.push(
                    crate::reader::parse_record(opcode, data)
                        .map_err(|e| e.to_string())?
                        .into_owned(),
                );
            }
        }
    }
    Ok(out)
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

    fn recover_bytes(bytes: &[u8]) -> (RecoverReport, Vec<u8>) {
        let (report, out) = recover(bytes, Cursor::new(Vec::new())).expect("recovers");
        (report, out.into_inner())
    }

    #[test]
    fn a_chunk_claiming_an_impossible_size_is_a_break_not_an_abort() {
        // Found by the `recover` fuzz target: the chunk reader allocated the claimed
        // 8243118308127416885 bytes and the process aborted.
        let mut bytes = original(Some(mcap::Compression::Zstd));
        let mut pos = 8;
        while bytes[pos] != 0x06 {
            let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().expect("8 bytes"));
            pos += 9 + usize::try_from(len).expect("small");
        }
        // Chunk body: message start and end time, then the uncompressed size.
        bytes[pos + 25..pos + 33].copy_from_slice(&8_243_118_308_127_416_885u64.to_le_bytes());
        let (report, _) = recover_bytes(&bytes);
        let b = report.break_at.expect("breaks at the chunk");
        assert!(b.at_byte <= pos as u64, "{b:?}");
        assert!(b.reason.contains("8243118308127416885 uncompressed bytes"), "{b:?}");
    }

    #[test]
    fn a_record_claiming_an_impossible_length_is_a_break_not_an_abort() {
        // Found by the `recover` fuzz target: the reader allocated the claimed length.
        let mut bytes = original(Some(mcap::Compression::Zstd));
        let len = u64::from_le_bytes(bytes[9..17].try_into().expect("8 bytes"));
        let second = 17 + usize::try_from(len).expect("small");
        bytes[second + 1..second + 9].copy_from_slice(&7_308_324_466_015_219_617u64.to_le_bytes());
        let (report, _) = recover_bytes(&bytes);
        let b = report.break_at.expect("breaks at the record");
        assert!(b.at_byte <= second as u64, "{b:?}");
    }

    #[test]
    fn a_chunk_whose_record_claims_an_impossible_length_is_a_break_not_an_abort() {
        // Found by the `recover` fuzz target: mcap's chunk reader reserved the length.
        let bytes =
            include_bytes!("../../fuzz/regressions/recover-chunk-inner-record-length-abort");
        let (report, _) = recover_bytes(bytes);
        let b = report.break_at.expect("breaks at the chunk");
        assert!(b.reason.contains("chunk unreadable"), "{b:?}");
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
        // Flushed at 1, 2, …, 6 s: samples 0..=120 are kept, the open chunk is not.
        assert_eq!(report.messages.get("/gyro/rate"), Some(&121));
        assert!(Recording::from_bytes(&out).expect("recovered").complete);
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
