//! The top level of an MCAP byte stream, read so that damage costs only itself.
//!
//! mcap's readers stop at the first record that does not frame (a flipped bit in a length, a
//! chunk that fails its CRC) and cannot start again further on: a stream has no index to jump
//! with. [`Scanner`] splits the stream into top-level records itself (an opcode and a length,
//! the only framing MCAP has), has every record body parsed by `mcap::parse_record`, and where a
//! record does not frame or parse, looks for the next place where valid records start again
//! ([`Scanner::resync`]): the bytes between are reported as skipped, everything after them is
//! read. A file that ends inside a record is cut there. Chunks are handed on whole (compressed);
//! [`super::chunk`] opens them.

use std::io::Read;

use mcap::records::{op, Record};

use super::{End, RecordingError};

/// One event of the top level, in file order.
pub(crate) enum Top {
    /// A record whose framing holds and whose body parses.
    Record {
        /// Its offset in the file (its opcode byte).
        at: u64,
        /// Opcode.
        opcode: u8,
        /// Body (without opcode and length).
        body: Vec<u8>,
    },
    /// Bytes `at..to` that do not frame as records; reading resumes at `to`.
    Skipped {
        /// First byte skipped.
        at: u64,
        /// First byte read again.
        to: u64,
        /// What was found at `at`.
        reason: String,
    },
    /// The end of the input.
    End(End),
    /// The input is not MCAP, or the source failed.
    Failed(RecordingError),
}

/// Longest record accepted where reading resumes after damage (a chunk of bench's is 1 MiB
/// uncompressed; other writers' are of the same order).
const RESYNC_LIMIT: u64 = 256 << 20;
/// Largest chunk (uncompressed) opened.
pub(crate) const MAX_CHUNK: u64 = super::MAX_RECORD as u64;
/// Bytes asked of the source at a time.
const READ_SIZE: usize = 256 * 1024;

/// Whether `opcode` can start a top-level record: the 15 opcodes of the MCAP spec, or a private
/// record (0x80 and up).
fn known_opcode(opcode: u8) -> bool {
    (op::HEADER..=op::DATA_END).contains(&opcode) || opcode >= 0x80
}

/// A record kind's name, for messages.
pub(crate) fn kind(opcode: u8) -> String {
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

/// The length a parsed record's body has when written as the spec says, for the records whose
/// fields say it (`None`: the body has no length of its own, e.g. a Message's data runs to its
/// end). A body longer than this was given a length too large: a damaged length field.
fn exact_len(record: &Record<'_>) -> Option<u64> {
    let s = |x: &str| 4 + x.len() as u64;
    let map = |m: &std::collections::BTreeMap<String, String>| {
        4 + m.iter().map(|(k, v)| s(k) + s(v)).sum::<u64>()
    };
    Some(match record {
        Record::Header(h) => s(&h.profile) + s(&h.library),
        Record::Footer(_) => 20,
        Record::Schema { header, data } => {
            2 + s(&header.name) + s(&header.encoding) + 4 + data.len() as u64
        }
        Record::Channel(c) => 4 + s(&c.topic) + s(&c.message_encoding) + map(&c.metadata),
        Record::Chunk { header, .. } => 28 + s(&header.compression) + 8 + header.compressed_size,
        Record::MessageIndex(m) => 6 + 16 * m.records.len() as u64,
        Record::Attachment { header, data, .. } => {
            16 + s(&header.name) + s(&header.media_type) + 8 + data.len() as u64 + 4
        }
        Record::Metadata(m) => s(&m.name) + map(&m.metadata),
        Record::DataEnd(_) => 4,
        _ => return None,
    })
}

/// How a place in the stream frames.
enum Check {
    /// A record: opcode, and the body length to read (its length field, or the length its
    /// fields give where the field was damaged).
    Record(u8, u64),
    /// Not a record: why.
    Bad(String),
    /// The input ends before the record does: why.
    Eof(String),
}

/// Splits an MCAP byte stream into top-level records (module docs).
pub(crate) struct Scanner<R> {
    src: R,
    buf: Vec<u8>,
    /// Start of the unread bytes in `buf`.
    head: usize,
    /// File offset of `buf[0]`.
    base: u64,
    eof: bool,
    file_len: Option<u64>,
    limit: u64,
    started: bool,
    done: bool,
    /// Records read.
    records: u64,
    /// The last record's kind (for the reason of a cut).
    last_kind: Option<u8>,
    /// The end magic follows the footer.
    footer_magic: bool,
}

impl<R: Read> Scanner<R> {
    /// Read `src`; `limit`: the longest record accepted; `file_len`: the input's length where
    /// known (a record claiming more is damage).
    pub(crate) fn new(src: R, limit: u64, file_len: Option<u64>) -> Self {
        Self {
            src,
            buf: Vec::new(),
            head: 0,
            base: 0,
            eof: false,
            file_len,
            limit,
            started: false,
            done: false,
            records: 0,
            last_kind: None,
            footer_magic: false,
        }
    }

    /// Whether the footer read was followed by the end magic.
    pub(crate) fn footer_magic(&self) -> bool {
        self.footer_magic
    }

    /// Bytes consumed so far (the offset of the next record).
    pub(crate) fn offset(&self) -> u64 {
        self.base + self.head as u64
    }

    /// Make `buf[..end]` available (`end` an index into `buf`, which only grows here); false at
    /// the end of input.
    fn fill_to(&mut self, end: usize) -> std::io::Result<bool> {
        while self.buf.len() < end && !self.eof {
            let have = self.buf.len();
            let want = (end - have).max(READ_SIZE);
            self.buf.resize(have + want, 0);
            let n = loop {
                match self.src.read(&mut self.buf[have..]) {
                    Ok(n) => break n,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        self.buf.truncate(have);
                        return Err(e);
                    }
                }
            };
            self.buf.truncate(have + n);
            if n == 0 {
                self.eof = true;
            }
        }
        Ok(self.buf.len() >= end)
    }

    /// Drop the bytes before `head` (indices into `buf` move by what it returns).
    fn compact(&mut self) -> usize {
        let shift = self.head;
        if shift > 0 {
            self.buf.drain(..shift);
            self.base += shift as u64;
            self.head = 0;
        }
        shift
    }

    /// How the bytes at `buf[pos..]` frame. Where reading resumes after damage (`resync`), a
    /// record's length must be exactly what its fields say.
    fn check(&mut self, pos: usize, resync: bool) -> std::io::Result<Check> {
        if !self.fill_to(pos + 9)? {
            let left = self.buf.len().saturating_sub(pos);
            return Ok(Check::Eof(format!("the file ends {left} byte(s) into a record header")));
        }
        let opcode = self.buf[pos];
        let len = u64::from_le_bytes(self.buf[pos + 1..pos + 9].try_into().unwrap_or([0xFF; 8]));
        if !known_opcode(opcode) {
            return Ok(Check::Bad(format!("opcode 0x{opcode:02x} starts no MCAP record")));
        }
        let at = self.base + pos as u64;
        let limit = if resync { self.limit.min(RESYNC_LIMIT) } else { self.limit };
        if len > limit {
            return Ok(Check::Bad(format!(
                "a {} record claims {len} bytes (at most {limit} read)",
                kind(opcode)
            )));
        }
        if let Some(n) = self.file_len {
            if at + 9 + len > n {
                return Ok(Check::Eof(format!(
                    "a {} record of {len} bytes runs past the end of the file ({n} bytes)",
                    kind(opcode)
                )));
            }
        }
        let end = pos + 9 + len as usize;
        if !self.fill_to(end)? {
            return Ok(Check::Eof(format!(
                "the file ends inside a {} record of {len} bytes",
                kind(opcode)
            )));
        }
        let exact = match super::parse_record(opcode, &self.buf[pos + 9..end]) {
            Err(e) => return Ok(Check::Bad(format!("bad {} record: {e}", kind(opcode)))),
            Ok(Record::Chunk { header, .. })
                if !["", "zstd", "lz4"].contains(&header.compression.as_str()) =>
            {
                return Ok(Check::Bad(format!(
                    "a chunk compressed with unknown `{}`",
                    header.compression.escape_debug()
                )));
            }
            Ok(Record::Chunk { header, .. }) if header.uncompressed_size > MAX_CHUNK => {
                return Ok(Check::Bad(format!(
                    "a chunk claiming {} uncompressed bytes (at most {MAX_CHUNK} read)",
                    header.uncompressed_size
                )));
            }
            Ok(record) => exact_len(&record),
        };
        // A body longer than its fields say, with a valid record right after what they say:
        // the length field was damaged, the fields are right.
        let len = match exact {
            Some(x) if x != len && resync => {
                return Ok(Check::Bad(format!(
                    "a {} record's fields disagree with its length",
                    kind(opcode)
                )))
            }
            Some(x) if x < len && self.follows(pos + 9 + x as usize, opcode)? => x,
            // The data end and footer have fixed fields: anything longer is another record
            // with a damaged opcode.
            Some(x) if x != len && [op::DATA_END, op::FOOTER].contains(&opcode) => {
                return Ok(Check::Bad(format!("a {} record of {len} bytes", kind(opcode))))
            }
            _ => len,
        };
        Ok(Check::Record(opcode, len))
    }

    /// Whether what starts at `pos` (after a record of `opcode`) is a valid record of the
    /// spec (private records, which have no structure to check, do not count), or the end magic
    /// after a footer.
    fn follows(&mut self, pos: usize, opcode: u8) -> std::io::Result<bool> {
        if opcode == op::FOOTER {
            return Ok(self.fill_to(pos + 8)? && self.buf[pos..pos + 8] == mcap::MAGIC[..]);
        }
        Ok(matches!(self.check(pos, true)?, Check::Record(op, _) if op < 0x80))
    }

    /// Whether a record found while looking for valid data again (`opcode`, body of `len` at
    /// `buf[pos + 9..]`) is surely one: a chunk that opens (its CRC holds where it has one),
    /// an attachment whose CRC holds, a footer followed by the end magic, a record whose fields
    /// account for its length exactly followed by another valid record, or a message followed
    /// by two. Private records (0x80 and up) have nothing to check and are never taken.
    fn sure(&mut self, pos: usize, opcode: u8, len: u64) -> std::io::Result<bool> {
        let body = pos + 9..pos + 9 + len as usize;
        let next = body.end;
        match opcode {
            0x80.. | op::HEADER => Ok(false),
            op::CHUNK => {
                let opened = super::chunk::for_each_record(&self.buf[body], MAX_CHUNK, |_, _| {});
                Ok(opened.is_ok())
            }
            op::ATTACHMENT => match super::parse_record(opcode, &self.buf[body]) {
                Ok(Record::Attachment { crc, .. }) if crc != 0 => Ok(true),
                _ => self.follows(next, opcode),
            },
            op::FOOTER => self.follows(next, opcode),
            op::MESSAGE => {
                let Check::Record(op2, len2) = self.check(next, true)? else { return Ok(false) };
                Ok(op2 < 0x80 && self.follows(next + 9 + len2 as usize, op2)?)
            }
            _ => self.follows(next, opcode),
        }
    }

    /// The next place after `buf[from]` where valid records start for sure ([`Self::sure`]);
    /// `None` if none does before the end.
    fn resync(&mut self, from: usize) -> std::io::Result<Option<usize>> {
        let mut p = from;
        loop {
            // Bytes before `p` are skipped whatever comes: let them go.
            if p > self.head + (8 << 20) {
                self.head = p;
                p -= self.compact();
            }
            if !self.fill_to(p + 9)? {
                return Ok(None);
            }
            let opcode = self.buf[p];
            let len = u64::from_le_bytes(self.buf[p + 1..p + 9].try_into().unwrap_or([0xFF; 8]));
            let at = self.base + p as u64;
            let plausible = known_opcode(opcode)
                && len <= self.limit.min(RESYNC_LIMIT)
                && self.file_len.is_none_or(|n| at + 9 + len <= n);
            if plausible {
                if let Check::Record(opcode, len) = self.check(p, true)? {
                    if self.sure(p, opcode, len)? {
                        return Ok(Some(p));
                    }
                }
            }
            p += 1;
        }
    }

    fn take(&mut self, opcode: u8, len: u64) -> Top {
        let at = self.offset();
        let start = self.head + 9;
        let end = start + len as usize;
        let body = self.buf[start..end].to_vec();
        self.head = end;
        self.records += 1;
        self.last_kind = Some(opcode);
        Top::Record { at, opcode, body }
    }

    fn fail(&mut self, e: std::io::Error) -> Top {
        self.done = true;
        Top::Failed(RecordingError::Io { at_byte: self.offset(), source: e })
    }

    /// The end of input at the current offset, or a cut there because of `reason`.
    fn finish(&mut self, reason: Option<String>) -> Top {
        self.done = true;
        let at_byte = self.offset();
        if self.records == 0 {
            let reason = reason.unwrap_or_else(|| "no MCAP record".into());
            return Top::Failed(RecordingError::NotMcap { at_byte, reason });
        }
        let reason = reason.unwrap_or_else(|| match self.last_kind {
            Some(k) => format!("the file ends after a {} record, before its footer", kind(k)),
            None => "the file ends before its footer".into(),
        });
        Top::End(End::Cut { at_byte, reason })
    }

    /// The next top-level event; `None` after the end.
    pub(crate) fn next_top(&mut self) -> Option<Top> {
        if self.done {
            return None;
        }
        if self.head >= READ_SIZE && self.head * 2 >= self.buf.len() {
            self.compact();
        }
        if !self.started {
            self.started = true;
            match self.fill_to(8) {
                Err(e) => return Some(self.fail(e)),
                Ok(false) => {
                    self.done = true;
                    let at_byte = self.buf.len() as u64;
                    let reason = "the file is shorter than the MCAP magic".to_string();
                    return Some(Top::Failed(RecordingError::NotMcap { at_byte, reason }));
                }
                Ok(true) => {}
            }
            let flipped: u32 =
                self.buf[..8].iter().zip(mcap::MAGIC).map(|(a, b)| (a ^ b).count_ones()).sum();
            self.head = 8;
            if flipped > 2 {
                self.done = true;
                let reason = "Bad magic number".to_string();
                return Some(Top::Failed(RecordingError::NotMcap { at_byte: 8, reason }));
            }
            if flipped > 0 {
                let reason = format!("the MCAP magic has {flipped} damaged bit(s)");
                return Some(Top::Skipped { at: 0, to: 8, reason });
            }
        }
        if self.eof && self.head == self.buf.len() {
            return Some(self.finish(None));
        }
        let check = match self.fill_to(self.head + 1) {
            Err(e) => return Some(self.fail(e)),
            Ok(false) => return Some(self.finish(None)),
            Ok(true) => self.check(self.head, false),
        };
        let reason = match check {
            Err(e) => return Some(self.fail(e)),
            Ok(Check::Record(op::FOOTER, len)) => {
                // Nothing after the footer is the file's but its end magic.
                let magic = match self.fill_to(self.head + 9 + len as usize + 8) {
                    Ok(full) => {
                        full && {
                            let at = self.head + 9 + len as usize;
                            self.buf[at..at + 8] == mcap::MAGIC[..]
                        }
                    }
                    Err(e) => return Some(self.fail(e)),
                };
                let top = self.take(op::FOOTER, len);
                self.done = true;
                self.footer_magic = magic;
                return Some(top);
            }
            Ok(Check::Record(opcode, len)) => return Some(self.take(opcode, len)),
            Ok(Check::Bad(r) | Check::Eof(r)) => r,
        };
        let start = self.offset();
        let head = self.head;
        match self.resync(head + 1) {
            Err(e) => Some(self.fail(e)),
            Ok(Some(p)) => {
                self.head = p;
                Some(Top::Skipped { at: start, to: self.offset(), reason })
            }
            Ok(None) => {
                // Nothing valid after: the file is cut where the damage starts.
                self.base = start;
                self.buf.clear();
                self.head = 0;
                Some(self.finish(Some(reason)))
            }
        }
    }
}
