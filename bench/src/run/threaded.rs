//! An [`EventSink`] that hands events to another sink on a thread of its own, so that
//! serialising and compressing the recording runs beside the devices and the sequencer: on
//! the simulated bench it uses the second core, on a real bench it keeps compression stalls
//! away from the pollers.
//!
//! Kill-safety: with a lag limit ([`ThreadedSink::lag_limit`]) the run may not get further
//! ahead of the writer thread than that much bench time (the producer waits, which costs
//! nothing in virtual time), so what a SIGKILL loses is bounded by the recorder's flush
//! interval plus this lag, however fast the run goes.

use std::sync::{mpsc, Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use super::{Event, EventSink};

/// What the writer thread has recorded so far.
#[derive(Default)]
struct Done {
    /// Bench time of the last event recorded.
    t: Duration,
    /// Events recorded (or skipped after an error).
    n: u64,
    /// The thread has ended.
    ended: bool,
}

type Shared = Arc<(Mutex<Done>, Condvar)>;

/// Forwards events in batches to `S` on a writer thread.
pub struct ThreadedSink<S: EventSink> {
    batch: Vec<Event>,
    batch_len: usize,
    tx: Option<mpsc::SyncSender<Vec<Event>>>,
    thread: Option<JoinHandle<(S, Option<String>)>>,
    done: Shared,
    sent: u64,
    lag_limit: Option<Duration>,
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
    /// larger batches cost less per event but hold events back until the batch is full or
    /// [`ThreadedSink::finish`]).
    pub fn new(sink: S, batch_len: usize) -> std::io::Result<Self> {
        let batch_len = batch_len.max(1);
        // A few batches in flight: enough to decouple, bounded so memory stays flat.
        let (tx, rx) = mpsc::sync_channel::<Vec<Event>>(8);
        let done: Shared = Arc::default();
        let thread_done = done.clone();
        let thread =
            std::thread::Builder::new().name("bench-recorder".into()).spawn(move || {
                let mut sink = sink;
                let mut error = None;
                let (lock, cvar) = &*thread_done;
                for batch in rx {
                    if error.is_none() {
                        for ev in &batch {
                            if let Err(e) = sink.record(ev) {
                                error = Some(format!("{e:#}"));
                                break;
                            }
                        }
                    }
                    let mut d = lock.lock().unwrap_or_else(|p| p.into_inner());
                    d.n += batch.len() as u64;
                    if let Some(last) = batch.last() {
                        d.t = d.t.max(last.t());
                    }
                    cvar.notify_all();
                }
                lock.lock().unwrap_or_else(|p| p.into_inner()).ended = true;
                cvar.notify_all();
                (sink, error)
            })?;
        Ok(Self {
            batch: Vec::with_capacity(batch_len),
            batch_len,
            tx: Some(tx),
            thread: Some(thread),
            done,
            sent: 0,
            lag_limit: None,
            marks: None,
            next_mark: Duration::ZERO,
        })
    }

    /// Keep the run within `lag` of bench time of what the writer thread has recorded: a batch
    /// is handed over once it spans half of `lag`, and `record` waits while the thread is
    /// further behind. Only for virtual time, where waiting stops no clock.
    pub fn lag_limit(mut self, lag: Duration) -> Self {
        self.lag_limit = Some(lag);
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
        if self.batch.is_empty() {
            return Ok(());
        }
        let batch = std::mem::replace(&mut self.batch, Vec::with_capacity(self.batch_len));
        let n = batch.len() as u64;
        match &self.tx {
            Some(tx) => {
                tx.send(batch).map_err(|_| anyhow::anyhow!("the recorder thread has stopped"))?;
                self.sent += n;
                Ok(())
            }
            None => Err(anyhow::anyhow!("the recorder has finished")),
        }
    }

    /// Wait until the writer thread has recorded every event more than `lag` before `t`, or
    /// everything handed over, or has ended.
    fn wait_for_writer(&self, t: Duration, lag: Duration) {
        let (lock, cvar) = &*self.done;
        let mut d = lock.lock().unwrap_or_else(|p| p.into_inner());
        while !d.ended && d.n < self.sent && d.t + lag < t {
            d = cvar.wait(d).unwrap_or_else(|p| p.into_inner());
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
        let first_t = self.batch.first().map(Event::t);
        self.batch.push(event.clone());
        let spans = match (self.lag_limit, first_t) {
            (Some(lag), Some(t0)) => t.saturating_sub(t0) * 2 >= lag,
            _ => false,
        };
        if self.batch.len() >= self.batch_len || spans {
            self.send_batch()?;
        }
        if let Some(lag) = self.lag_limit {
            self.wait_for_writer(t, lag);
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

    /// Records slowly, noting how far behind the producer it was at each event.
    struct Slow(Arc<Mutex<Vec<Duration>>>);
    impl EventSink for Slow {
        fn record(&mut self, event: &Event) -> anyhow::Result<()> {
            std::thread::sleep(Duration::from_micros(200));
            self.0.lock().expect("lock").push(event.t());
            Ok(())
        }
    }

    #[test]
    fn with_a_lag_limit_the_producer_never_runs_further_ahead() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let lag = Duration::from_millis(500);
        let mut s = ThreadedSink::new(Slow(seen.clone()), 4096).expect("thread").lag_limit(lag);
        let mut worst = Duration::ZERO;
        for i in 0..400u64 {
            let t = Duration::from_millis(50 * i);
            s.record(&Event::Step {
                t,
                index: i as usize,
                name: "wait".into(),
                event: super::super::StepEvent::Start,
                label: String::new(),
            })
            .expect("queued");
            // After `record` returns, the writer has recorded everything older than t - lag.
            let recorded = seen.lock().expect("lock").last().copied().unwrap_or_default();
            if t > lag {
                worst = worst.max(t - recorded);
            }
        }
        let (sink, err) = s.finish().expect("joined");
        assert!(err.is_none());
        assert_eq!(sink.0.lock().expect("lock").len(), 400);
        assert!(worst <= lag, "the producer ran {worst:?} ahead (limit {lag:?})");
    }
}
