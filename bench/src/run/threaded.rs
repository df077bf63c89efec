//! An [`EventSink`] that hands events to another sink on a thread of its own, so that
//! serialising and compressing the recording runs beside the devices and the sequencer: on
//! the simulated bench it uses the second core, on a real bench it keeps compression stalls
//! away from the pollers.

use std::sync::mpsc;
use std::thread::JoinHandle;

use super::{Event, EventSink};

/// Forwards events in batches to `S` on a writer thread.
pub struct ThreadedSink<S: EventSink> {
    batch: Vec<Event>,
    batch_len: usize,
    tx: Option<mpsc::SyncSender<Vec<Event>>>,
    thread: Option<JoinHandle<(S, Option<String>)>>,
}

impl<S: EventSink> ThreadedSink<S> {
    /// Start the writer thread. Events are passed on in batches of `batch_len` (1 = at once;
    /// larger batches cost less per event but hold events back until the batch is full or
    /// [`ThreadedSink::finish`]).
    pub fn new(sink: S, batch_len: usize) -> std::io::Result<Self> {
        let batch_len = batch_len.max(1);
        // A few batches in flight: enough to decouple, bounded so memory stays flat.
        let (tx, rx) = mpsc::sync_channel::<Vec<Event>>(8);
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
            tx: Some(tx),
            thread: Some(thread),
        })
    }

    fn send_batch(&mut self) -> anyhow::Result<()> {
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
        self.batch.push(event.clone());
        if self.batch.len() >= self.batch_len {
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
}
