//! `bench info`: what a recording holds, from one linear pass (works without a summary).

use std::{
    collections::BTreeMap,
    fmt,
    io::Read,
    path::{Path, PathBuf},
};

use crate::message::StepEvent;
use crate::reader::{seconds_since, time_zero_ns};
use crate::reader::{End, Item, RecordingError, RecordingReader};
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
}

/// Report on a recording file.
pub fn info(path: &Path) -> Result<RecordingInfo, RecordingError> {
    let mut info = info_from_reader(RecordingReader::open(path)?)?;
    info.path = Some(path.to_path_buf());
    Ok(info)
}

/// Report on a recording from any reader. Keeps 8 bytes per message (log times, for the
/// median period and gaps): a 40 h run at 60 messages/s needs about 70 MB.
pub fn info_from_reader<R: Read>(
    mut reader: RecordingReader<R>,
) -> Result<RecordingInfo, RecordingError> {
    let mut times: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    // (index, name, label, start, end, abort) in ns.
    type StepNs = (u64, String, String, Option<u64>, Option<u64>, Option<u64>);
    let mut steps: Vec<StepNs> = Vec::new();
    let mut metadata = Vec::new();
    let mut attachments = Vec::new();
    for item in reader.by_ref() {
        let (channel, t) = match item? {
            Item::Gyro(m) => (TOPIC_GYRO, m.log_time_ns),
            Item::Table(m) => (TOPIC_TABLE, m.log_time_ns),
            Item::Chamber(m) => (TOPIC_CHAMBER, m.log_time_ns),
            Item::Step(m) => {
                let t = m.log_time_ns;
                let s = m.msg;
                let open = steps
                    .iter_mut()
                    .rev()
                    .find(|x| x.0 == s.index && x.1 == s.name && x.4.is_none() && x.5.is_none());
                match (s.event, open) {
                    (StepEvent::Start, _) | (_, None) => {
                        let mut new = (s.index, s.name, s.label, None, None, None);
                        match s.event {
                            StepEvent::Start => new.3 = Some(t),
                            StepEvent::End => new.4 = Some(t),
                            StepEvent::Abort => new.5 = Some(t),
                        }
                        steps.push(new);
                    }
                    (StepEvent::End, Some(x)) => x.4 = Some(t),
                    (StepEvent::Abort, Some(x)) => x.5 = Some(t),
                }
                (TOPIC_STEP, t)
            }
            Item::Other(m) => {
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

    let mut channels: Vec<_> = reader.channels().cloned().collect();
    channels.sort_by_key(|c| c.id);
    let channels = channels
        .into_iter()
        .map(|c| {
            // Two channels on one topic: the first (lowest id) gets the topic's messages.
            let ts = times.remove(&c.topic).unwrap_or_default();
            channel_report(c.topic, c.schema_name, c.message_encoding, &ts, t0)
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
        steps: steps
            .into_iter()
            .map(|(index, name, label, s, e, a)| StepReport {
                index,
                name,
                label,
                start_s: s.map(rel),
                end_s: e.map(rel),
                abort_s: a.map(rel),
            })
            .collect(),
        metadata,
        attachments,
        outcome,
        end: reader.end().clone(),
    })
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
    let periodic = median.is_some_and(|m| {
        let near =
            periods.iter().filter(|&&p| (p as f64 - m as f64).abs() <= 0.1 * m as f64).count();
        m > 0 && near * 10 >= periods.len() * 9
    });
    let gaps = match median.filter(|_| periodic) {
        Some(m) => ts
            .windows(2)
            .filter(|w| (w[1].saturating_sub(w[0])) as f64 > 1.5 * m as f64)
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
    }
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
        writeln!(
            f,
            "  first message {}, duration {:.3} s, {} bytes",
            started.as_deref().unwrap_or("-"),
            self.duration_s,
            self.bytes
        )?;
        match &self.end {
            End::Complete => writeln!(f, "  file complete (summary and footer present)")?,
            End::Cut { at_byte, reason } => writeln!(
                f,
                "  FILE INCOMPLETE: no summary; reading stopped at byte {at_byte}: {reason}"
            )?,
            End::Reading => {}
        }
        match &self.outcome {
            Some(o) => writeln!(f, "  outcome: {o}")?,
            None => writeln!(f, "  outcome: unknown (no bench.run record: the run did not end)")?,
        }
        writeln!(f, "channels:")?;
        for c in &self.channels {
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
            for g in c.gaps.iter().take(10) {
                writeln!(
                    f,
                    "      gap {:.3} s .. {:.3} s ({:.3} s)",
                    g.from_s,
                    g.to_s,
                    g.to_s - g.from_s
                )?;
            }
            if c.gaps.len() > 10 {
                writeln!(f, "      ... {} more", c.gaps.len() - 10)?;
            }
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
