//! `/bench/step` events paired into steps: the one rule, used by `info`, the analyses' loader
//! and `export`.
//!
//! Events are taken in time order (a stable sort: events of one time stay in file order). A
//! `start` opens a step; an `end` or `abort` closes the latest open step of the same index. A
//! step never closed has no end (the file says no more of it: a run cut short, or a second
//! `start` of its index before its end); an `end` or `abort` with no open step of its index
//! is a step without a start.

use crate::message::{StepEvent, StepMsg};

/// One step as its events record it.
#[derive(Debug, Clone, PartialEq)]
pub struct PairedStep<'a, T> {
    /// Step index in the scenario.
    pub index: u64,
    /// Step name (of the first event).
    pub name: &'a str,
    /// Label (of the first event).
    pub label: &'a str,
    /// Time of its `start`, if the file has one.
    pub start: Option<T>,
    /// Time of its `end` or `abort` and which it was, if the file has one.
    pub end: Option<(T, StepEvent)>,
}

impl<T> PairedStep<'_, T> {
    /// Whether its label marks a calibration window ([`StepMsg::is_record`]).
    pub fn is_record(&self) -> bool {
        crate::message::is_record_label(self.label)
    }
}

/// Pair `events` (time, message) into steps (module docs), in the order of each step's first
/// event.
pub fn pair<'a, T: Copy + PartialOrd>(
    events: impl IntoIterator<Item = (T, &'a StepMsg)>,
) -> Vec<PairedStep<'a, T>> {
    let mut events: Vec<(T, &StepMsg)> = events.into_iter().collect();
    // Stable: equal times keep their order. Times that do not compare (none in practice)
    // keep theirs too.
    events.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(std::cmp::Ordering::Equal));
    let mut out: Vec<PairedStep<'a, T>> = Vec::new();
    for (t, m) in events {
        let open = match m.event {
            StepEvent::Start => None,
            StepEvent::End | StepEvent::Abort => out
                .iter_mut()
                .rev()
                .find(|s| s.index == m.index && s.start.is_some() && s.end.is_none()),
        };
        match open {
            Some(s) => s.end = Some((t, m.event)),
            None => out.push(PairedStep {
                index: m.index,
                name: &m.name,
                label: &m.label,
                start: (m.event == StepEvent::Start).then_some(t),
                end: (m.event != StepEvent::Start).then_some((t, m.event)),
            }),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(index: u64, event: StepEvent, label: &str) -> StepMsg {
        StepMsg { index, name: "s".into(), event, label: label.into() }
    }

    #[test]
    fn starts_pair_with_the_next_end_or_abort_of_their_index() {
        use StepEvent::{Abort, End, Start};
        let msgs = [
            (0u64, ev(0, Start, "to 20C")),
            (5, ev(0, End, "to 20C")),
            (5, ev(1, Start, "record cw")),
            // Out of file order: the pairing is by time.
            (12, ev(2, Start, "record ccw")),
            (9, ev(1, End, "record cw")),
            (14, ev(2, Abort, "record ccw")),
            // An end with no start; a start never ended.
            (15, ev(7, End, "")),
            (16, ev(3, Start, "wait")),
        ];
        let steps = pair(msgs.iter().map(|(t, m)| (*t, m)));
        let got: Vec<_> = steps.iter().map(|s| (s.index, s.start, s.end, s.is_record())).collect();
        assert_eq!(
            got,
            [
                (0, Some(0), Some((5, End)), false),
                (1, Some(5), Some((9, End)), true),
                (2, Some(12), Some((14, Abort)), true),
                (7, None, Some((15, End)), false),
                (3, Some(16), None, false),
            ]
        );
    }

    #[test]
    fn a_second_start_of_an_index_leaves_the_first_unended() {
        use StepEvent::{End, Start};
        let msgs = [(0.0, ev(4, Start, "a")), (1.0, ev(4, Start, "b")), (2.0, ev(4, End, "b"))];
        let steps = pair(msgs.iter().map(|(t, m)| (*t, m)));
        let got: Vec<_> = steps.iter().map(|s| (s.label, s.start, s.end)).collect();
        assert_eq!(got, [("a", Some(0.0), None), ("b", Some(1.0), Some((2.0, End)))]);
    }
}
