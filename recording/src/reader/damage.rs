//! What a reader skipped in a damaged file, and where: chunks that fail their CRC or do not
//! decompress, bytes that do not frame as records, messages that do not match the contract or
//! whose channel no readable record defines. Reading goes on past each; only what is damaged is
//! lost.

use std::collections::BTreeMap;
use std::fmt;

/// One damaged part of a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damage {
    /// Byte offset in the file: of the chunk, of the skipped bytes, or of the record (for a
    /// message inside a chunk, of its chunk).
    pub at_byte: u64,
    /// Bytes lost: the chunk record's or the skipped span's length (0 for one message).
    pub bytes: u64,
    /// What is wrong.
    pub kind: DamageKind,
    /// Log times (ns since the Unix epoch) of the first and last message it held, where the
    /// file says (a chunk's header, a message's own time), or of the messages read just before
    /// and after it (skipped bytes).
    pub span_ns: Option<(u64, u64)>,
    /// Messages lost per topic, where the file says (the message indexes after a chunk).
    pub lost: BTreeMap<String, u64>,
    /// In the summary section (after the data end): no data was lost.
    pub in_summary: bool,
}

/// The kinds of damage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DamageKind {
    /// A chunk that fails its CRC, does not decompress, or whose records do not frame: all its
    /// messages are skipped.
    Chunk {
        /// What failed.
        reason: String,
    },
    /// Bytes that do not frame as MCAP records: reading resumed at the next valid record.
    Bytes {
        /// What was found there.
        reason: String,
    },
    /// A message on a contract channel whose body does not match the contract.
    Message {
        /// Channel.
        topic: String,
        /// Channel sequence number.
        sequence: u32,
        /// Log time, ns since the Unix epoch.
        log_time_ns: u64,
        /// Which field is wrong and how.
        detail: String,
    },
    /// A message on a channel that no readable Channel record defines.
    Orphan {
        /// The channel id it names.
        channel_id: u16,
        /// Its sequence number.
        sequence: u32,
        /// Log time, ns since the Unix epoch.
        log_time_ns: u64,
    },
}

impl Damage {
    /// Messages this damage is known to have cost (one for a bad or orphaned message; a chunk's
    /// count where its message indexes say).
    pub fn messages_lost(&self) -> u64 {
        match self.kind {
            DamageKind::Message { .. } | DamageKind::Orphan { .. } => 1,
            _ => self.lost.values().sum(),
        }
    }
}

impl fmt::Display for Damage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.kind {
            DamageKind::Chunk { reason } => write!(
                f,
                "chunk at byte {} ({} bytes) skipped: {reason}",
                self.at_byte, self.bytes
            )?,
            DamageKind::Bytes { reason } => write!(
                f,
                "bytes {}..{} skipped ({} bytes): {reason}",
                self.at_byte,
                self.at_byte + self.bytes,
                self.bytes
            )?,
            DamageKind::Message { topic, sequence, detail, .. } => write!(
                f,
                "{topic} message sequence {sequence} (chunk or record at byte {}) skipped: body \
                 does not match the contract: {detail}",
                self.at_byte
            )?,
            DamageKind::Orphan { channel_id, sequence, .. } => write!(
                f,
                "message sequence {sequence} at byte {} skipped: no readable record defines its \
                 channel id {channel_id}",
                self.at_byte
            )?,
        }
        if !self.lost.is_empty() {
            let parts: Vec<String> = self.lost.iter().map(|(t, n)| format!("{t} {n}")).collect();
            write!(f, "; messages lost: {}", parts.join(", "))?;
        }
        if self.in_summary {
            write!(f, " (in the summary section: no data lost)")?;
        }
        Ok(())
    }
}

/// Every damaged part a reader met, with counts. Individual bad messages are listed up to
/// [`DamageReport::MAX_LISTED`] and counted beyond.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DamageReport {
    /// Damaged parts in file order (messages up to [`Self::MAX_LISTED`]).
    pub entries: Vec<Damage>,
    /// Bad or orphaned messages not listed in `entries`.
    pub unlisted_messages: u64,
    /// Bad or orphaned messages per topic (`(channel N)` for an undefined channel), all of
    /// them.
    pub bad_messages: BTreeMap<String, u64>,
    /// Messages listed in `entries`.
    listed: usize,
}

impl DamageReport {
    /// Bad messages listed one by one, at most.
    pub const MAX_LISTED: usize = 1000;

    /// Nothing was damaged.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty() && self.unlisted_messages == 0
    }

    /// Chunks skipped.
    pub fn chunks_damaged(&self) -> usize {
        self.entries.iter().filter(|d| matches!(d.kind, DamageKind::Chunk { .. })).count()
    }

    /// Bytes skipped as unreadable (chunks and unframed spans).
    pub fn bytes_skipped(&self) -> u64 {
        self.entries
            .iter()
            .filter(|d| matches!(d.kind, DamageKind::Chunk { .. } | DamageKind::Bytes { .. }))
            .map(|d| d.bytes)
            .sum()
    }

    /// Bad or orphaned messages skipped, all channels.
    pub fn bad_message_count(&self) -> u64 {
        self.bad_messages.values().sum()
    }

    /// Whether the data section was damaged (damage in the summary section loses no data).
    pub fn loses_data(&self) -> bool {
        self.unlisted_messages > 0 || self.entries.iter().any(|d| !d.in_summary)
    }

    /// Parts that cost data (chunks and skipped spans of the data section), in file order.
    pub fn data_parts(&self) -> impl Iterator<Item = &Damage> {
        self.entries.iter().filter(|d| {
            !d.in_summary && matches!(d.kind, DamageKind::Chunk { .. } | DamageKind::Bytes { .. })
        })
    }

    /// The union of the log-time spans of the damage, ns, merged where they overlap: the
    /// bench time it covers.
    pub fn spans_ns(&self) -> Vec<(u64, u64)> {
        let mut spans: Vec<(u64, u64)> = self
            .entries
            .iter()
            .filter(|d| !d.in_summary)
            .filter_map(|d| d.span_ns)
            .filter(|(a, b)| a <= b)
            .collect();
        spans.sort_unstable();
        let mut out: Vec<(u64, u64)> = Vec::new();
        for (a, b) in spans {
            match out.last_mut() {
                Some(last) if a <= last.1 => last.1 = last.1.max(b),
                _ => out.push((a, b)),
            }
        }
        out
    }

    /// One line: how many chunks, spans and messages, and the bytes.
    pub fn summary(&self) -> String {
        let mut parts = Vec::new();
        let chunks = self.chunks_damaged();
        if chunks > 0 {
            parts.push(format!("{chunks} damaged chunk(s) skipped"));
        }
        let spans =
            self.entries.iter().filter(|d| matches!(d.kind, DamageKind::Bytes { .. })).count();
        if spans > 0 {
            parts.push(format!("{spans} unreadable span(s) skipped"));
        }
        let bad = self.bad_message_count();
        if bad > 0 {
            parts.push(format!("{bad} message(s) that do not match the contract skipped"));
        }
        let bytes = self.bytes_skipped();
        if bytes > 0 {
            parts.push(format!("{bytes} bytes unreadable"));
        }
        if parts.is_empty() {
            "no damage".to_string()
        } else {
            parts.join(", ")
        }
    }

    pub(crate) fn push(&mut self, d: Damage) {
        match &d.kind {
            DamageKind::Message { topic, .. } => {
                *self.bad_messages.entry(topic.clone()).or_default() += 1;
            }
            DamageKind::Orphan { channel_id, .. } => {
                *self.bad_messages.entry(format!("(channel {channel_id})")).or_default() += 1;
            }
            _ => {
                self.entries.push(d);
                return;
            }
        }
        if self.listed < Self::MAX_LISTED {
            self.listed += 1;
            self.entries.push(d);
        } else {
            self.unlisted_messages += 1;
        }
    }
}
