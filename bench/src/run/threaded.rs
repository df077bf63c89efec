//! An [`EventSink`] that hands events to another sink on a thread of its own, so that
//! serialising and compressing the recording runs beside the devices and the sequencer: on
//! the simulated bench it uses the second core, on a real bench it keeps compression stalls
//! away from the pollers.
//!
//! Kill-safety in virtual time: a batch is handed over when it is full or, with a hold limit
//! ([`ThreadedSink::hold_limit`]), once its first event has waited that long in wall-clock time,
//! and at most two batches wait for the writer thread; so the work a SIGKILL loses is what the
//! recorder had not flushed (it flushes by wall-clock time, `RecorderOptions::flush_wall`) plus
//! this hold. The run never waits on the writer beyond the two batches in flight.

use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{Event, EventSink};

/// Forwards events in batches to `S` on a writer thread.
pub struct ThreadedSink<S: EventSink> {
    batch: Vec<Event>,
    batch_len: usize,
    /// When the first event of the current batch was taken.
    batch_started: Option<Instant>,
    hold_limit: Option<Duration>,
    tx: Option<mpsc::SyncSender<Vec<Event>>>,
    thread: Option<JoinHandle<(S, Option<String>)>>,
    marks: Option<(Duration, u64)>,
    next_mark: Duration,
}

impl Event {
    /// The bench time of the event.
    pub fn t(&self) -> Duration {
        match self {
            Event::Gyro(t, _) | Event::Table(t, _) | Event::Chamber(t, _) => *t,
            Event::Step { t, .. } | Event::Log { t, .. } => *t,
        }
    }
}

impl<S: EventSink> ThreadedSink<S> {
    /// Start the writer thread. Events are passed on in batches of `batch_len` (1 = at once;
    /// larger batches cost less per event but hold events back until the batch is full, the
    /// hold limit passes, or [`ThreadedSink::finish`]). At most two batches (eight single
    /// events) wait for the writer: then the run waits.
    pub fn new(sink: S, batch_len: usize) -> std::io::Result<Self> {
        let batch_len = batch_len.max(1);
        let (tx, rx) = mpsc::sync_channel::<Vec<Event>>(if batch_len > 1 { 2 } else { 8 });
        let thread =
            std::thread::Builder::new().name("bench-recorder".into()).spawn(move || {
                let mut sink = sink;
                let mut error = None;
                for batch in rx {
                    if error.is_some() {
                        continue;
                    }
                    for ev in &batch {
                        if let Err(e) = sink.record(ev) {
                            error = Some(format!("{e:#}"));
                            break;
                        }
                    }
                }
                (sink, error)
            })?;
        Ok(Self {
            batch: Vec::with_capacity(batch_len),
            batch_len,
            batch_started: None,
            hold_limit: None,
            tx: Some(tx),
            thread: Some(thread),
            marks: None,
            next_mark: Duration::ZERO,
        })
    }

    /// Hand a batch over once its first event has waited `hold` of wall-clock time, full or not
    /// (checked every 256 events), so a slow stretch of a run cannot hold events back.
    pub fn hold_limit(mut self, hold: Duration) -> Self {
        self.hold_limit = Some(hold);
        self
    }

    /// Print `bench time T s (log time N ns)` on stderr each time the events handed over pass
    /// a multiple of `every` of bench time (`epoch_ns`: the recording's time zero), for
    /// supervisors and logs: at any moment the run has produced nothing later than the last
    /// mark plus `every`.
    pub fn time_marks(mut self, every: Duration, epoch_ns: u64) -> Self {
        if !every.is_zero() {
            self.marks = Some((every, epoch_ns));
        }
        self
    }

    fn send_batch(&mut self) -> anyhow::Result<()> {
        self.batch_started = None;
        if self.batch.is_empty() {
            return Ok(());
        }
        let batch = std::mem::replace(&mut self.batch, Vec::with_capacity(self.batch_len));
        match &self.tx {
            Some(tx) => {
                tx.send(batch).map_err(|_| anyhow::anyhow!("the recorder thread has stopped"))
            }
            None => Err(anyhow::anyhow!("the recorder has finished")),
        }
    }

    /// Pass on what is still batched, stop the thread and return the sink with the first
    /// error it met, if any.
    pub fn finish(mut self) -> anyhow::Result<(S, Option<String>)> {
        self.send_batch()?;
        self.tx = None;
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => Ok(r),
            Some(Err(_)) => Err(anyhow::anyhow!("the recorder thread panicked")),
            None => Err(anyhow::anyhow!("the recorder has finished")),
        }
    }
}

impl<S: EventSink> EventSink for ThreadedSink<S> {
    fn record(&mut self, event: &Event) -> anyhow::Result<()> {
        let t = event.t();
        if let Some((every, epoch_ns)) = self.marks {
            if t >= self.next_mark {
                let k = (t.as_nanos() / every.as_nanos()) as u32;
                let mark = every * k;
                eprintln!(
                    "bench time {:.3} s (log time {} ns)",
                    mark.as_secs_f64(),
                    epoch_ns.saturating_add(mark.as_nanos() as u64)
                );
                self.next_mark = mark + every;
            }
        }
        if self.batch.is_empty() && self.hold_limit.is_some() {
            self.batch_started = Some(Instant::now());
        }
        self.batch.push(event.clone());
        let held = match (self.hold_limit, self.batch_started) {
            (Some(hold), Some(t0)) => self.batch.len().is_multiple_of(256) && t0.elapsed() >= hold,
            _ => false,
        };
        if self.batch.len() >= self.batch_len || held {
            self.send_batch()?;
        }
        Ok(())
    }
}

impl<S: EventSink> Drop for ThreadedSink<S> {
    fn drop(&mut self) {
        // Dropped without `finish` (an error path): still hand over every event and let the
        // writer thread end, so nothing recorded is lost from the sink's point of view.
        let _ = self.send_batch();
        self.tx = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    #[derive(Default)]
    struct Collect(Vec<Event>);
    impl EventSink for Collect {
        fn record(&mut self, event: &Event) -> anyhow::Result<()> {
            if self.0.len() == 5 {
                anyhow::bail!("disk full");
            }
            self.0.push(event.clone());
            Ok(())
        }
    }

    fn step(i: usize) -> Event {
        Event::Step {
            t: Duration::from_secs(i as u64),
            index: i,
            name: "wait".into(),
            event: super::super::StepEvent::Start,
            label: String::new(),
        }
    }

    #[test]
    fn events_arrive_in_order_and_the_first_error_is_kept() {
        let mut s = ThreadedSink::new(Collect::default(), 3).expect("thread");
        for i in 0..8 {
            s.record(&step(i)).expect("queued");
        }
        let (sink, err) = s.finish().expect("joined");
        assert_eq!(sink.0, (0..5).map(step).collect::<Vec<_>>());
        assert_eq!(err.as_deref(), Some("disk full"));
    }

    /// Records slowly.
    struct Slow(Arc<Mutex<Vec<Duration>>>);
    impl EventSink for Slow {
        fn record(&mut self, event: &Event) -> anyhow::Result<()> {
            std::thread::sleep(Duration::from_micros(20));
            self.0.lock().expect("lock").push(event.t());
            Ok(())
        }
    }

    #[test]
    fn a_held_batch_is_handed_over_by_wall_clock_time_not_only_when_full() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let mut s = ThreadedSink::new(Slow(seen.clone()), 1 << 20)
            .expect("thread")
            .hold_limit(Duration::from_millis(20));
        for i in 0..512u64 {
            s.record(&step(i as usize)).expect("queued");
            std::thread::sleep(Duration::from_micros(100));
        }
        // 512 events over ≥ 51 ms with a 20 ms hold: the writer has at least the first 256
        // (5 ms of writing) well before the finish, though a batch holds 2^20.
        std::thread::sleep(Duration::from_millis(500));
        let before_finish = seen.lock().expect("lock").len();
        assert!(before_finish >= 256, "{before_finish} events reached the writer");
        let (sink, err) = s.finish().expect("joined");
        assert!(err.is_none());
        assert_eq!(sink.0.lock().expect("lock").len(), 512);
    }
}
