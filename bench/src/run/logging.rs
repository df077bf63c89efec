//! `tracing` events of a run, forwarded to the recording's `/log` channel.

use std::sync::Arc;

use bench_drivers::Clock;
use futures::channel::mpsc::UnboundedSender;
use tracing::field::{Field, Visit};
use tracing::{Event as TraceEvent, Subscriber};
use tracing_subscriber::layer::Context;
use tracing_subscriber::Layer;

use super::{Event, LogLevel};

/// A layer that sends every event it sees to the run's recorder, stamped with bench time.
pub struct RecordingLayer {
    tx: UnboundedSender<Event>,
    clock: Arc<dyn Clock>,
}

impl RecordingLayer {
    /// Forward to `tx`, stamping with `clock`.
    pub fn new(tx: UnboundedSender<Event>, clock: Arc<dyn Clock>) -> Self {
        Self { tx, clock }
    }
}

#[derive(Default)]
struct MessageVisitor {
    message: String,
    fields: String,
}

impl Visit for MessageVisitor {
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.message.push_str(value);
        } else {
            self.fields.push_str(&format!(" {}={}", field.name(), value));
        }
    }
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.message.push_str(&format!("{value:?}"));
        } else {
            self.fields.push_str(&format!(" {}={:?}", field.name(), value));
        }
    }
}

impl<S: Subscriber> Layer<S> for RecordingLayer {
    fn on_event(&self, event: &TraceEvent<'_>, _ctx: Context<'_, S>) {
        let meta = event.metadata();
        let mut v = MessageVisitor::default();
        event.record(&mut v);
        let message = if v.fields.is_empty() { v.message } else { v.message + &v.fields };
        // The recorder may already have finished (events after the end of the run): then the
        // message has nowhere to go and is dropped, which is the documented end of `/log`.
        let _ = self.tx.unbounded_send(Event::Log {
            t: self.clock.now(),
            level: LogLevel::from(*meta.level()),
            message,
            name: meta.target().to_string(),
            file: meta.file().unwrap_or("").to_string(),
            line: meta.line().unwrap_or(0),
        });
    }
}
