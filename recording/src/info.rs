//! `bench info`: what a recording holds, from one linear pass (works without a summary).

use std::{
    collections::BTreeMap,
    fmt,
    io::Read,
    path::{Path, PathBuf},
};

use crate::message::StepEvent;
use crate::reader::{seconds_since, time_zero_ns};
use crate::reader::{DamageReport, End, Item, RecordingError, RecordingReader};
use crate::schema::{META_RUN, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_STEP, TOPIC_TABLE};

/// A gap in a channel: an interval between consecutive messages longer than 1.5 × the
/// channel's median period.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// Log time of the message before the gap, s from the recording's first message.
    pub from_s: f64,
    /// Log time of the message after the gap, s from the first message.
    pub to_s: f64,
}

/// One channel's statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelReport {
    /// Topic.
    pub topic: String,
    /// Schema name.
    pub schema_name: String,
    /// Message encoding.
    pub message_encoding: String,
    /// Messages read.
    pub count: u64,
    /// First log time, s from the recording's first message.
    pub first_s: Option<f64>,
    /// Last log time, s from the first message.
    pub last_s: Option<f64>,
    /// Mean rate: (count - 1) / (last - first), Hz.
    pub mean_rate_hz: Option<f64>,
    /// Median interval between consecutive messages, s.
    pub median_period_s: Option<f64>,
    /// Intervals longer than 1.5 × the median period.
    pub gaps: Vec<Gap>,
    /// Whether the channel is a periodic stream (nine in ten periods within 10 % of the
    /// median); gaps are only looked for in periodic channels.
    pub periodic: bool,
    /// The same judged by the device's own time stamps (`publish_time`), when they differ
    /// from the log times: a real-time stream's rate and gaps without the host's jitter.
    pub device_time: Option<DeviceTiming>,
}

/// A channel's rate and gaps by its device time stamps (times in s from the recording's first
/// log time).
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceTiming {
    /// Mean rate, Hz.
    pub mean_rate_hz: Option<f64>,
    /// Median interval, s.
    pub median_period_s: Option<f64>,
    /// Intervals longer than 1.5 × the median.
    pub gaps: Vec<Gap>,
    /// Whether the device times are periodic.
    pub periodic: bool,
}

/// A step as its events record it (times in s from the recording's first message).
#[derive(Debug, Clone, PartialEq)]
pub struct StepReport {
    /// Step index.
    pub index: u64,
    /// Step name.
    pub name: String,
    /// Label.
    pub label: String,
    /// Start event time.
    pub start_s: Option<f64>,
    /// End event time.
    pub end_s: Option<f64>,
    /// Abort event time.
    pub abort_s: Option<f64>,
}

/// Everything `bench info` reports.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingInfo {
    /// The file, if read from one.
    pub path: Option<PathBuf>,
    /// Bytes read.
    pub bytes: u64,
    /// Log time of the first message, ns since the Unix epoch.
    pub start_ns: Option<u64>,
    /// Last log time minus first, s.
    pub duration_s: f64,
    /// Channels in id order.
    pub channels: Vec<ChannelReport>,
    /// Steps in order of their first event.
    pub steps: Vec<StepReport>,
    /// Metadata records (name, entries) in file order.
    pub metadata: Vec<(String, BTreeMap<String, String>)>,
    /// Attachments: name, media type, size in bytes.
    pub attachments: Vec<(String, String, usize)>,
    /// `bench.run` `outcome`; `None` if the file has no `bench.run` record (the run did not end
    /// normally).
    pub outcome: Option<String>,
    /// How the file ended.
    pub end: End,
    /// The container's own description (header, summary), when read from a file.
    pub container: Option<ContainerInfo>,
    /// What was damaged and skipped (empty for an intact file).
    pub damage: DamageReport,
    /// Chunks read, and how many of them had a CRC, checked.
    pub chunks: (u64, u64),
}

/// Report on a recording file.
pub fn info(path: &Path) -> Result<RecordingInfo, RecordingError> {
    let mut info = info_from_reader(RecordingReader::open(path)?)?;
    info.path = Some(path.to_path_buf());
    // A damaged summary must not hide what the linear read found.
    info.container = container_info(path).ok();
    Ok(info)
}

/// Report on a recording from any reader. Keeps 8 bytes per message (log times, for the
/// median period and gaps): a 40 h run at 60 messages/s needs about 70 MB.
pub fn info_from_reader<R: Read>(
    mut reader: RecordingReader<R>,
) -> Result<RecordingInfo, RecordingError> {
    let mut times: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    // Device time stamps (publish_time) per topic, and whether any differs from log_time.
    let mut device: BTreeMap<String, (Vec<u64>, bool)> = BTreeMap::new();
    // Step events (log time, message), paired at the end (`crate::steps`).
    let mut step_events: Vec<(u64, crate::message::StepMsg)> = Vec::new();
    let mut metadata = Vec::new();
    let mut attachments = Vec::new();
    for item in reader.by_ref() {
        let (channel, t) = match item? {
            Item::Gyro(m) => {
                note_device(&mut device, TOPIC_GYRO, m.log_time_ns, m.publish_time_ns);
                (TOPIC_GYRO, m.log_time_ns)
            }
            Item::Table(m) => {
                note_device(&mut device, TOPIC_TABLE, m.log_time_ns, m.publish_time_ns);
                (TOPIC_TABLE, m.log_time_ns)
            }
            Item::Chamber(m) => {
                note_device(&mut device, TOPIC_CHAMBER, m.log_time_ns, m.publish_time_ns);
                (TOPIC_CHAMBER, m.log_time_ns)
            }
            Item::Step(m) => {
                let t = m.log_time_ns;
                step_events.push((t, m.msg));
                (TOPIC_STEP, t)
            }
            Item::Other(m) => {
                note_device(&mut device, &m.channel.topic, m.log_time_ns, m.publish_time_ns);
                match times.get_mut(&m.channel.topic) {
                    Some(v) => v.push(m.log_time_ns),
                    None => {
                        times.insert(m.channel.topic.clone(), vec![m.log_time_ns]);
                    }
                }
                continue;
            }
            Item::Metadata(m) => {
                metadata.push((m.name, m.entries));
                continue;
            }
            Item::Attachment(a) => {
                attachments.push((a.name, a.media_type, a.data.len()));
                continue;
            }
        };
        match times.get_mut(channel) {
            Some(v) => v.push(t),
            None => {
                times.insert(channel.to_string(), vec![t]);
            }
        }
    }
    let first = |topic: &str| times.get(topic).and_then(|v| v.iter().min().copied());
    let start_ns = time_zero_ns([TOPIC_GYRO, TOPIC_TABLE, TOPIC_CHAMBER, TOPIC_STEP].map(first))
        .or_else(|| times.values().filter_map(|v| v.iter().min()).min().copied());
    let end_ns = times.values().filter_map(|v| v.iter().max()).max().copied();
    let t0 = start_ns.unwrap_or(0);
    let rel = |t: u64| seconds_since(t0, t);

    let mut channels: Vec<_> = reader.channels();
    channels.sort_by_key(|c| c.id);
    let channels = channels
        .into_iter()
        .map(|c| {
            // Two channels on one topic: the first (lowest id) gets the topic's messages.
            let ts = times.remove(&c.topic).unwrap_or_default();
            let mut report = channel_report(c.topic, c.schema_name, c.message_encoding, &ts, t0);
            if let Some((mut pt, true)) = device.remove(&report.topic) {
                pt.sort_unstable();
                let d = channel_report(String::new(), String::new(), String::new(), &pt, t0);
                report.device_time = Some(DeviceTiming {
                    mean_rate_hz: d.mean_rate_hz,
                    median_period_s: d.median_period_s,
                    gaps: d.gaps,
                    periodic: d.periodic,
                });
            }
            report
        })
        .collect();
    let outcome = metadata
        .iter()
        .rev()
        .find(|(n, _)| n == META_RUN)
        .and_then(|(_, m)| m.get("outcome").cloned());
    Ok(RecordingInfo {
        path: None,
        bytes: reader.bytes_read(),
        start_ns,
        duration_s: match (start_ns, end_ns) {
            (Some(a), Some(b)) => b.saturating_sub(a) as f64 * 1e-9,
            _ => 0.0,
        },
        channels,
        steps: crate::steps::pair(step_events.iter().map(|(t, m)| (*t, m)))
            .into_iter()
            .map(|s| {
                let at = |event: StepEvent| s.end.filter(|e| e.1 == event).map(|e| rel(e.0));
                StepReport {
                    index: s.index,
                    name: s.name.to_owned(),
                    label: s.label.to_owned(),
                    start_s: s.start.map(rel),
                    end_s: at(StepEvent::End),
                    abort_s: at(StepEvent::Abort),
                }
            })
            .collect(),
        metadata,
        attachments,
        outcome,
        end: reader.end().clone(),
        container: None,
        damage: reader.damage().clone(),
        chunks: reader.chunks_read(),
    })
}

/// Keep a message's device time stamp, noting whether it differs from its log time.
fn note_device(
    device: &mut BTreeMap<String, (Vec<u64>, bool)>,
    topic: &str,
    log_ns: u64,
    publish_ns: u64,
) {
    let entry = match device.get_mut(topic) {
        Some(e) => e,
        None => device.entry(topic.to_string()).or_default(),
    };
    entry.0.push(publish_ns);
    entry.1 |= publish_ns != log_ns;
}

/// What the MCAP container says of itself: the header's library and profile, and, from the
/// summary section when the file has one, chunk counts by compression, message, schema and
/// channel counts, encodings, and the first and last message times.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContainerInfo {
    /// The header's `library` (the writer), if the header could be read.
    pub library: Option<String>,
    /// The header's `profile`.
    pub profile: Option<String>,
    /// Whether the file has a summary section (the rest is from it).
    pub summary: bool,
    /// Chunks per compression (`zstd`, `lz4`, `""` for none).
    pub chunks_by_compression: BTreeMap<String, u64>,
    /// Chunks in all.
    pub chunk_count: Option<u64>,
    /// Messages in all.
    pub message_count: Option<u64>,
    /// Schemas.
    pub schema_count: Option<u64>,
    /// Channels.
    pub channel_count: Option<u64>,
    /// Attachments.
    pub attachment_count: Option<u64>,
    /// Metadata records.
    pub metadata_count: Option<u64>,
    /// Message encodings of the channels.
    pub message_encodings: Vec<String>,
    /// Schema encodings.
    pub schema_encodings: Vec<String>,
    /// Earliest message log time, ns since the Unix epoch.
    pub message_start_ns: Option<u64>,
    /// Latest message log time, ns.
    pub message_end_ns: Option<u64>,
}

/// The header's profile and library: magic, opcode 0x01, record length, then two strings
/// (u32 length + bytes, little-endian).
fn read_header(file: &mut std::fs::File) -> Option<(String, String)> {
    use std::io::{Seek, SeekFrom};
    file.seek(SeekFrom::Start(0)).ok()?;
    let mut head = [0u8; 17];
    file.read_exact(&mut head).ok()?;
    if head[..8] != mcap::MAGIC[..] || head[8] != 0x01 {
        return None;
    }
    let len = u64::from_le_bytes(head[9..17].try_into().ok()?);
    if len > 1 << 20 {
        return None;
    }
    let mut body = vec![0u8; usize::try_from(len).ok()?];
    file.read_exact(&mut body).ok()?;
    let mut at = 0usize;
    let mut string = || -> Option<String> {
        let n = u32::from_le_bytes(body.get(at..at + 4)?.try_into().ok()?) as usize;
        let s = String::from_utf8_lossy(body.get(at + 4..at + 4 + n)?).into_owned();
        at += 4 + n;
        Some(s)
    };
    let profile = string()?;
    let library = string()?;
    Some((profile, library))
}

/// [`ContainerInfo`] of the file at `path`.
pub fn container_info(path: &Path) -> Result<ContainerInfo, RecordingError> {
    let open = |source| RecordingError::Open { path: path.to_path_buf(), source };
    let mut file = std::fs::File::open(path).map_err(open)?;
    let mut out = ContainerInfo::default();
    if let Some((profile, library)) = read_header(&mut file) {
        out.profile = Some(profile);
        out.library = Some(library);
    }
    let Some(summary) = crate::reader::read_summary(path)? else { return Ok(out) };
    out.summary = true;
    for c in &summary.chunk_indexes {
        *out.chunks_by_compression.entry(c.compression.clone()).or_default() += 1;
    }
    let mut enc: Vec<String> =
        summary.channels.values().map(|c| c.message_encoding.clone()).collect();
    enc.sort();
    enc.dedup();
    out.message_encodings = enc;
    let mut enc: Vec<String> = summary.schemas.values().map(|s| s.encoding.clone()).collect();
    enc.sort();
    enc.dedup();
    out.schema_encodings = enc;
    if let Some(st) = &summary.stats {
        out.chunk_count = Some(u64::from(st.chunk_count));
        out.message_count = Some(st.message_count);
        out.schema_count = Some(u64::from(st.schema_count));
        out.channel_count = Some(u64::from(st.channel_count));
        out.attachment_count = Some(u64::from(st.attachment_count));
        out.metadata_count = Some(u64::from(st.metadata_count));
        if st.message_count > 0 {
            out.message_start_ns = Some(st.message_start_time);
            out.message_end_ns = Some(st.message_end_time);
        }
    } else {
        out.chunk_count = Some(summary.chunk_indexes.len() as u64);
    }
    Ok(out)
}

/// Seconds as a human duration: `13 h 42 min 49 s`, `2 min 0 s`, `0.500 s`.
pub fn human_duration(s: f64) -> String {
    if !s.is_finite() || s < 0.0 {
        return "-".to_string();
    }
    if s < 60.0 {
        return format!("{s:.3} s");
    }
    let t = s.round() as u64;
    let (h, m, sec) = (t / 3600, (t / 60) % 60, t % 60);
    let days = h / 24;
    match (days, h) {
        (d, _) if d > 0 => format!("{d} d {} h {m} min {sec} s", h % 24),
        (_, 0) => format!("{m} min {sec} s"),
        _ => format!("{h} h {m} min {sec} s"),
    }
}

fn channel_report(
    topic: String,
    schema_name: String,
    message_encoding: String,
    ts: &[u64],
    t0: u64,
) -> ChannelReport {
    let rel = |t: u64| seconds_since(t0, t);
    let mut periods: Vec<u64> = ts.windows(2).map(|w| w[1].saturating_sub(w[0])).collect();
    let median = if periods.is_empty() {
        None
    } else {
        let mid = periods.len() / 2;
        let (_, m, _) = periods.select_nth_unstable(mid);
        Some(*m)
    };
    // A channel is periodic (a device stream) when nine in ten of its periods lie within 10 %
    // of the median; event channels (steps, log) have no gaps to speak of.
    let steady = |periods: &[u64], m: u64| {
        let near =
            periods.iter().filter(|&&p| (p as f64 - m as f64).abs() <= 0.1 * m as f64).count();
        m > 0 && near * 10 >= periods.len() * 9
    };
    let mut periodic = median.is_some_and(|m| steady(&periods, m));
    // A stream whose stamps are uneven (a paced run's polls, a busy host) is still a stream
    // when the mean period over blocks of messages (a twentieth of them, 20 to 200) is steady: its rate is that mean and
    // a gap is a period beyond 1.5 × the largest of its ordinary ones (the 99th percentile).
    let block = (ts.len() / 20).clamp(20, 200);
    let mut gap_after = median.map_or(f64::INFINITY, |m| 1.5 * m as f64);
    let mut median = median;
    if !periodic && ts.len() >= 10 * block {
        let mut blocks: Vec<u64> =
            ts.windows(block + 1).map(|w| (w[block] - w[0]) / block as u64).collect();
        let mid = blocks.len() / 2;
        let m = *blocks.select_nth_unstable(mid).1;
        if steady(&blocks, m) {
            periodic = true;
            median = Some(m);
            let at = (periods.len() * 99 / 100).min(periods.len() - 1);
            let p99 = *periods.select_nth_unstable(at).1;
            gap_after = 1.5 * p99.max(m) as f64;
        }
    }
    let gaps = match median.filter(|_| periodic) {
        Some(_) => ts
            .windows(2)
            .filter(|w| (w[1].saturating_sub(w[0])) as f64 > gap_after)
            .map(|w| Gap { from_s: rel(w[0]), to_s: rel(w[1]) })
            .collect(),
        None => Vec::new(),
    };
    let first = ts.first().copied();
    let last = ts.last().copied();
    let mean_rate_hz = match (first, last) {
        (Some(a), Some(b)) if b > a => Some((ts.len() - 1) as f64 / ((b - a) as f64 * 1e-9)),
        _ => None,
    };
    ChannelReport {
        topic,
        schema_name,
        message_encoding,
        count: ts.len() as u64,
        first_s: first.map(rel),
        last_s: last.map(rel),
        mean_rate_hz,
        median_period_s: median.map(|m| m as f64 * 1e-9),
        periodic,
        gaps,
        device_time: None,
    }
}

impl RecordingInfo {
    /// Chunks and their CRCs, and every damaged part with its bench time.
    fn fmt_damage(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (chunks, checked) = self.chunks;
        if chunks > 0 {
            writeln!(
                f,
                "  chunks: {chunks} read, {checked} CRC-checked, {} damaged",
                self.damage.chunks_damaged()
            )?;
        }
        if self.damage.is_empty() {
            return Ok(());
        }
        let t0 = self.start_ns.unwrap_or(0);
        let rel = |t: u64| seconds_since(t0, t);
        writeln!(f, "  DAMAGED: {}; the rest was read", self.damage.summary())?;
        let read: u64 = self.channels.iter().map(|c| c.count).sum();
        if let Some(n) = self.container.as_ref().and_then(|c| c.message_count) {
            if n > read {
                writeln!(
                    f,
                    "    the summary counts {n} messages; {read} were read ({} lost)",
                    n - read
                )?;
            }
        }
        let covered: f64 =
            self.damage.spans_ns().iter().map(|(a, b)| b.saturating_sub(*a) as f64 * 1e-9).sum();
        if covered > 0.0 {
            writeln!(f, "    the damage covers {} of bench time", human_duration(covered))?;
        }
        const SHOWN: usize = 20;
        for d in self.damage.entries.iter().take(SHOWN) {
            write!(f, "    {d}")?;
            if let Some((a, b)) = d.span_ns {
                write!(f, "; bench time {:.3} s .. {:.3} s", rel(a), rel(b))?;
            }
            writeln!(f)?;
        }
        let more =
            self.damage.entries.len().saturating_sub(SHOWN) as u64 + self.damage.unlisted_messages;
        if more > 0 {
            writeln!(f, "    ... {more} more")?;
        }
        Ok(())
    }
}

/// The first 10 gaps of a stream, one line each, and how many more there are.
fn write_gaps(f: &mut std::fmt::Formatter<'_>, gaps: &[Gap]) -> std::fmt::Result {
    for g in gaps.iter().take(10) {
        writeln!(f, "      gap {:.3} s .. {:.3} s ({:.3} s)", g.from_s, g.to_s, g.to_s - g.from_s)?;
    }
    if gaps.len() > 10 {
        writeln!(f, "      ... {} more", gaps.len() - 10)?;
    }
    Ok(())
}

fn opt_s(v: Option<f64>) -> String {
    v.map(|s| format!("{s:.3} s")).unwrap_or_else(|| "-".to_string())
}

/// Longest metadata value shown in full; longer ones (scenario text) are summarised.
const SHOW_VALUE: usize = 80;

impl fmt::Display for RecordingInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = &self.path {
            writeln!(f, "recording {}", p.display())?;
        }
        let started = self.start_ns.map(crate::writer::rfc3339_utc);
        let last = self.start_ns.map(|t| {
            crate::writer::rfc3339_utc(t.saturating_add((self.duration_s * 1e9).round() as u64))
        });
        writeln!(
            f,
            "  first message {}, last {}, duration {:.3} s ({}), {} bytes",
            started.as_deref().unwrap_or("-"),
            last.as_deref().unwrap_or("-"),
            self.duration_s,
            human_duration(self.duration_s),
            self.bytes
        )?;
        if let Some(c) = &self.container {
            writeln!(
                f,
                "  container: library {}, profile {:?}",
                c.library.as_deref().unwrap_or("-"),
                c.profile.as_deref().unwrap_or("")
            )?;
            if c.summary {
                let chunks: Vec<String> = c
                    .chunks_by_compression
                    .iter()
                    .map(|(k, n)| format!("{n} {}", if k.is_empty() { "uncompressed" } else { k }))
                    .collect();
                writeln!(
                    f,
                    "  summary: {} chunk(s) ({}), {} messages, {} schemas, {} channels, {} \
                     attachments, {} metadata; message encodings {}, schema encodings {}",
                    c.chunk_count.unwrap_or(0),
                    if chunks.is_empty() { "unchunked".to_string() } else { chunks.join(", ") },
                    c.message_count.map_or("-".into(), |n| n.to_string()),
                    c.schema_count.map_or("-".into(), |n| n.to_string()),
                    c.channel_count.map_or("-".into(), |n| n.to_string()),
                    c.attachment_count.map_or("-".into(), |n| n.to_string()),
                    c.metadata_count.map_or("-".into(), |n| n.to_string()),
                    c.message_encodings.join(", "),
                    c.schema_encodings.join(", "),
                )?;
            } else {
                writeln!(f, "  summary: none (counts below are from reading the whole file)")?;
            }
        }
        match &self.end {
            End::Complete => writeln!(f, "  file complete (summary and footer present)")?,
            End::Cut { at_byte, reason } => writeln!(
                f,
                "  FILE INCOMPLETE: no summary; reading stopped at byte {at_byte}: {reason}"
            )?,
            End::Reading => {}
        }
        self.fmt_damage(f)?;
        match &self.outcome {
            Some(o) => writeln!(f, "  outcome: {o}")?,
            None => writeln!(f, "  outcome: unknown (no bench.run record: the run did not end)")?,
        }
        writeln!(f, "channels:")?;
        for c in &self.channels {
            // A paced or busy host stamps a steady device stream unevenly: its rate and gaps
            // are then the device time's.
            if let Some(d) = c.device_time.as_ref().filter(|d| !c.periodic && d.periodic) {
                writeln!(
                    f,
                    "  {:<16} {:<20} {:>9} msgs  {} by device time (publish_time)  median \
                     period {}  {} gap(s); host stamps uneven",
                    c.topic,
                    c.schema_name,
                    c.count,
                    d.mean_rate_hz
                        .map(|r| format!("{r:>9.3} Hz"))
                        .unwrap_or_else(|| "        - Hz".into()),
                    opt_s(d.median_period_s),
                    d.gaps.len()
                )?;
                write_gaps(f, &d.gaps)?;
                continue;
            }
            if !c.periodic {
                writeln!(
                    f,
                    "  {:<16} {:<20} {:>9} msgs  event channel (no fixed rate)",
                    c.topic, c.schema_name, c.count
                )?;
                continue;
            }
            writeln!(
                f,
                "  {:<16} {:<20} {:>9} msgs  {}  median period {}  {} gap(s)",
                c.topic,
                c.schema_name,
                c.count,
                c.mean_rate_hz
                    .map(|r| format!("{r:>9.3} Hz"))
                    .unwrap_or_else(|| "        - Hz".into()),
                opt_s(c.median_period_s),
                c.gaps.len()
            )?;
            if let Some(d) = &c.device_time {
                writeln!(
                    f,
                    "      by device time (publish_time): {} median period {} {} gap(s)",
                    d.mean_rate_hz.map(|r| format!("{r:.3} Hz")).unwrap_or_else(|| "- Hz".into()),
                    opt_s(d.median_period_s),
                    d.gaps.len()
                )?;
            }
            write_gaps(f, &c.gaps)?;
        }
        writeln!(f, "steps:")?;
        for s in &self.steps {
            write!(f, "  #{:<3} {:<16} start {:>12}", s.index, s.name, opt_s(s.start_s))?;
            if let Some(e) = s.end_s {
                write!(f, "  end {:>12}", opt_s(Some(e)))?;
            }
            if let Some(a) = s.abort_s {
                write!(f, "  ABORT {:>12}", opt_s(Some(a)))?;
            }
            if s.end_s.is_none() && s.abort_s.is_none() {
                write!(f, "  (no end event)")?;
            }
            if !s.label.is_empty() {
                write!(f, "  label \"{}\"", s.label)?;
            }
            writeln!(f)?;
        }
        writeln!(f, "metadata:")?;
        for (name, m) in &self.metadata {
            writeln!(f, "  {name}")?;
            for (k, v) in m {
                if v.len() > SHOW_VALUE || v.contains('\n') {
                    writeln!(f, "    {k} = ({} bytes, {} lines)", v.len(), v.lines().count())?;
                } else {
                    writeln!(f, "    {k} = {v}")?;
                }
            }
        }
        writeln!(f, "attachments:")?;
        for (name, media, size) in &self.attachments {
            writeln!(f, "  {name} ({media}, {size} bytes)")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod device_time_tests {
    use std::io::Cursor;
    use std::time::Duration;

    use super::*;
    use crate::{GyroMsg, Outcome, Recorder, RunInfo, Site};

    /// Host stamps jitter (a sample every 40 or 60 ms, and one 300 ms late); the device's
    /// stamps are a steady 50 ms with one lost sample. By log time the stream is not even
    /// periodic; by device time it is 20 Hz with one gap.
    #[test]
    fn rate_and_gaps_are_judged_by_device_time_when_it_differs() {
        let info = RunInfo::new(1_000_000_000, "t", "", Site::at_latitude(45.0), BTreeMap::new());
        let mut rec = Recorder::new(Cursor::new(Vec::new()), info).expect("recorder");
        let mut host_ms = 0u64;
        for k in 1..=200u64 {
            if k == 100 {
                continue; // lost
            }
            host_ms += if k % 2 == 0 { 40 } else { 60 };
            let msg = GyroMsg { rate_rad_s: 0.0, temperature_c: None, seq: k, status: 0 };
            rec.gyro(Duration::from_millis(host_ms), Some(Duration::from_millis(50 * k)), &msg)
                .expect("writes");
        }
        let bytes = rec.finish(&Outcome::Completed).expect("finishes").into_inner();
        let info = info_from_reader(RecordingReader::new(&bytes[..])).expect("reads");
        let gyro = info.channels.iter().find(|c| c.topic == TOPIC_GYRO).expect("gyro");
        assert!(!gyro.periodic, "host stamps jitter by ±20 %");
        let d = gyro.device_time.as_ref().expect("device stamps differ from log times");
        assert!(d.periodic);
        assert!((d.mean_rate_hz.expect("rate") - 198.0 / 9.95).abs() < 1e-6);
        assert_eq!(d.median_period_s, Some(0.05));
        assert_eq!(d.gaps.len(), 1);
        assert_eq!(human_duration(49_369.0), "13 h 42 min 49 s");
        assert_eq!(human_duration(0.5), "0.500 s");
    }
}
