//! What reading a recording lost, in words an analysis can put first: where the file is cut
//! (byte, bench time, the step open there) and what damage was skipped (parts, bytes, the bench
//! time they cover).

use std::collections::BTreeMap;

use super::{seconds_since, Recording};
use crate::info::human_duration;
use crate::message::StepEvent;

/// Seconds of bench time as `123.4 s (2 min 3 s)`.
fn bench_time(s: f64) -> String {
    if s < 60.0 {
        format!("{s:.1} s")
    } else {
        format!("{s:.1} s ({})", human_duration(s))
    }
}

impl Recording {
    /// The latest log time read on the contract's channels, ns.
    fn last_log_ns(&self) -> Option<u64> {
        [
            self.gyro.last().map(|m| m.log_time_ns),
            self.table.last().map(|m| m.log_time_ns),
            self.chamber.last().map(|m| m.log_time_ns),
            self.steps.last().map(|m| m.log_time_ns),
        ]
        .into_iter()
        .flatten()
        .max()
    }

    /// The step started and not ended when the recording stops: `#index name "label"`.
    fn step_open_at_end(&self) -> Option<String> {
        let mut open: BTreeMap<u64, (u64, &str, &str)> = BTreeMap::new();
        for s in &self.steps {
            match s.msg.event {
                StepEvent::Start => {
                    open.insert(s.msg.index, (s.log_time_ns, &s.msg.name, &s.msg.label));
                }
                StepEvent::End | StepEvent::Abort => {
                    open.remove(&s.msg.index);
                }
            }
        }
        let (index, (_, name, label)) = open.into_iter().max_by_key(|(_, v)| v.0)?;
        Some(if label.is_empty() {
            format!("#{index} {name}")
        } else {
            format!("#{index} {name} \"{label}\"")
        })
    }

    /// Where the file is cut, for an analysis to name first: `the recording is cut at byte N
    /// (bench time T, during step #i name "label")`; `None` for a finished file.
    pub fn cut_note(&self) -> Option<String> {
        let (at, _) = self.cut.as_ref()?;
        let mut where_ = Vec::new();
        if let (Some(z), Some(t)) = (self.time_zero_ns(), self.last_log_ns()) {
            where_.push(format!("bench time {}", bench_time(seconds_since(z, t))));
        }
        match self.step_open_at_end() {
            Some(s) => where_.push(format!("during step {s}")),
            None if !self.steps.is_empty() => where_.push("between steps".into()),
            None => {}
        }
        let place =
            if where_.is_empty() { String::new() } else { format!(" ({})", where_.join(", ")) };
        Some(format!("the recording is cut at byte {at}{place}: it ends there without its summary"))
    }

    /// What damage was skipped, for an analysis to warn of: the parts, their byte offsets and
    /// the bench time they cover; `None` when nothing was.
    pub fn damage_note(&self) -> Option<String> {
        let d = &self.damage;
        if !d.loses_data() {
            return None;
        }
        let mut text = format!("the recording is damaged: {}", d.summary());
        let offsets: Vec<String> = d.data_parts().map(|p| p.at_byte.to_string()).collect();
        if !offsets.is_empty() {
            let shown = offsets.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
            let more = if offsets.len() > 5 {
                format!(" and {} more", offsets.len() - 5)
            } else {
                String::new()
            };
            text += &format!(" (at byte {shown}{more})");
        }
        let spans = d.spans_ns();
        if let (Some(z), Some(first), Some(last)) =
            (self.time_zero_ns(), spans.first(), spans.last())
        {
            let covered: f64 = spans.iter().map(|(a, b)| b.saturating_sub(*a) as f64 * 1e-9).sum();
            text += &format!(
                "; the parts skipped cover {} of bench time, between {} and {}",
                human_duration(covered),
                bench_time(seconds_since(z, first.0)),
                bench_time(seconds_since(z, last.1)),
            );
        }
        let lost: u64 =
            d.entries.iter().map(|e| e.messages_lost()).sum::<u64>() + d.unlisted_messages;
        if lost > 0 {
            text += &format!("; {lost} messages lost");
        }
        Some(text)
    }
}
