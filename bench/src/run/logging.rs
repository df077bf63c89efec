//! `tracing` events of a run, forwarded to the recording's `/log` channel.

use std::sync::{Arc, Mutex};

use bench_drivers::Clock;
use futures::channel::mpsc::UnboundedSender;
use tracing::field::{Field, Visit};
use tracing::{Event as TraceEvent, Subscriber};
use tracing_subscriber::layer::Context;
use tracing_subscriber::Layer;

use super::{Event, LogLevel};

/// A layer that sends every event it sees to the run's recorder, stamped with bench time.
///
/// Events come from every task of the run, on any thread of a multi-threaded runtime, while
/// the recorder requires non-decreasing times on `/log`. Stamping and sending are therefore
/// one step under [`Self::order`]: otherwise a thread preempted between the two (as on a
/// loaded host) sends its older stamp after a newer one, and the recorder aborts the run.
pub struct RecordingLayer {
    tx: UnboundedSender<Event>,
    clock: Arc<dyn Clock>,
    order: Mutex<()>,
}

impl RecordingLayer {
    /// Forward to `tx`, stamping with `clock`.
    pub fn new(tx: UnboundedSender<Event>, clock: Arc<dyn Clock>) -> Self {
        Self { tx, clock, order: Mutex::new(()) }
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
        // Stamp and send in one step, so that `/log` is in time order (see the type's doc).
        let _order = self.order.lock().unwrap_or_else(|p| p.into_inner());
        // The recorder may already have finished (events after the end of the run): then the
        // message has nowhere to go and is dropped, which is the documented end of `/log`.
        let _ = self.tx.unbounded_send(Event::Log {
            t: self.clock.now(),
            level: log_level(*meta.level()),
            message,
            name: meta.target().to_string(),
            file: meta.file().unwrap_or("").to_string(),
            line: meta.line().unwrap_or(0),
        });
    }
}

/// The `foxglove.Log` level of a tracing level (trace counts as debug).
fn log_level(l: tracing::Level) -> LogLevel {
    match l {
        tracing::Level::ERROR => LogLevel::Error,
        tracing::Level::WARN => LogLevel::Warning,
        tracing::Level::INFO => LogLevel::Info,
        _ => LogLevel::Debug,
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::time::Duration;

    use futures::channel::mpsc;
    use futures::future::BoxFuture;
    use tracing_subscriber::layer::SubscriberExt;

    use super::*;

    /// A clock that ticks on every reading and then lets other threads run, so that a thread
    /// holding a stamp is overtaken whenever stamping and sending are two steps.
    struct TickingClock(AtomicU64);

    impl Clock for TickingClock {
        fn now(&self) -> Duration {
            let t = self.0.fetch_add(1, Ordering::SeqCst);
            std::thread::yield_now();
            Duration::from_nanos(t)
        }
        fn sleep_until(&self, _: Duration) -> BoxFuture<'static, ()> {
            Box::pin(std::future::ready(()))
        }
        fn is_virtual(&self) -> bool {
            false
        }
    }

    #[test]
    fn log_events_from_many_threads_arrive_in_time_order() {
        let (tx, mut rx) = mpsc::unbounded();
        let clock: Arc<dyn Clock> = Arc::new(TickingClock(AtomicU64::new(0)));
        let dispatch = tracing::Dispatch::new(
            tracing_subscriber::Registry::default().with(RecordingLayer::new(tx, clock)),
        );
        let (threads, per_thread) = (4, 500);
        std::thread::scope(|s| {
            for i in 0..threads {
                let d = dispatch.clone();
                s.spawn(move || {
                    tracing::dispatcher::with_default(&d, || {
                        (0..per_thread).for_each(|n| tracing::info!(i, n, "event"));
                    });
                });
            }
        });
        drop(dispatch);
        let mut times = Vec::new();
        while let Ok(event) = rx.try_recv() {
            if let Event::Log { t, .. } = event {
                times.push(t);
            }
        }
        assert_eq!(times.len(), threads * per_thread);
        assert!(times.windows(2).all(|w| w[0] <= w[1]), "a /log stamp went back in time");
    }
}
