//! The read loop every reader shares: the top level framed on the caller's thread
//! ([`super::scan`]), chunks opened and their messages decoded on worker threads, several at
//! once, and the results handed out in file order.
//!
//! What a message decodes into is the [`Decode`] implementation's choice (typed items for
//! [`super::RecordingReader`], table columns for the export). Channels are shared between the
//! workers as they are defined: a worker that meets a message of a channel it does not know yet
//! waits until every earlier chunk is done (the channel may be defined there) before it calls
//! the message an orphan.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::io::Read;
use std::sync::{mpsc, Arc, Condvar, Mutex};

use mcap::records::{op, MessageHeader, Record};

use super::damage::{Damage, DamageKind};
use super::scan::{Scanner, Top};
use super::{AttachmentRecord, ChannelInfo, End, MetadataRecord, RecordingError};
use crate::schema::{TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_STEP, TOPIC_TABLE};

/// Which contract channel a topic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Gyro,
    Table,
    Chamber,
    Step,
    Other,
}

impl Kind {
    pub(crate) fn of(topic: &str) -> Kind {
        match topic {
            TOPIC_GYRO => Kind::Gyro,
            TOPIC_TABLE => Kind::Table,
            TOPIC_CHAMBER => Kind::Chamber,
            TOPIC_STEP => Kind::Step,
            _ => Kind::Other,
        }
    }
}

/// A defined channel.
#[derive(Debug)]
pub(crate) struct Chan {
    pub info: Arc<ChannelInfo>,
    pub kind: Kind,
}

/// A message as framed: header, body, and the offset of its chunk (or record).
pub(crate) struct Msg<'a> {
    pub header: MessageHeader,
    pub data: &'a [u8],
    pub at: u64,
}

/// What messages decode into, per unit of work.
pub(crate) trait Decode: Send + Sync + 'static {
    /// The decoded messages of one chunk (or batch of top-level records).
    type Out: Send + 'static;
    /// An empty output.
    fn start(&self) -> Self::Out;
    /// A message on a defined channel.
    fn message(&self, out: &mut Self::Out, chan: &Chan, m: Msg<'_>);
    /// A message on a channel no record defines.
    fn orphan(&self, out: &mut Self::Out, m: Msg<'_>);
    /// A Channel record, met in the file (every one, repeats included).
    fn channel(&self, out: &mut Self::Out, chan: &Chan);
}

/// One unit of the file, in order.
pub(crate) enum Unit<O> {
    /// Messages (and channel notes) of a chunk or of consecutive top-level records.
    Out(O),
    /// A metadata record.
    Metadata(MetadataRecord),
    /// An attachment.
    Attachment(AttachmentRecord),
    /// A damaged part, skipped.
    Damage(Damage),
    /// The input is not MCAP, or the source failed: nothing more follows.
    Error(RecordingError),
}

/// Channels and schemas defined so far, and which units of work are done.
#[derive(Default)]
struct Defs {
    /// By id; copied on write, so a job reads its own snapshot without locking.
    channels: Arc<Vec<Option<Arc<Chan>>>>,
    schemas: BTreeMap<u16, (String, String)>,
    /// Every job below this id is done.
    done_below: u64,
    /// Jobs done at or above `done_below`.
    done: BTreeSet<u64>,
}

#[derive(Default)]
struct Shared {
    defs: Mutex<Defs>,
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> std::sync::MutexGuard<'_, Defs> {
        self.defs.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Define a channel (the first definition of an id stays); returns it.
    fn define(&self, c: mcap::records::Channel, raw: bool) -> Arc<Chan> {
        let mut d = self.lock();
        let id = usize::from(c.id);
        if let Some(Some(existing)) = d.channels.get(id) {
            return existing.clone();
        }
        let (schema_name, schema_encoding) =
            d.schemas.get(&c.schema_id).cloned().unwrap_or_default();
        let kind = if raw { Kind::Other } else { Kind::of(&c.topic) };
        let chan = Arc::new(Chan {
            info: Arc::new(ChannelInfo {
                id: c.id,
                topic: c.topic,
                schema_name,
                schema_encoding,
                message_encoding: c.message_encoding,
            }),
            kind,
        });
        let channels = Arc::make_mut(&mut d.channels);
        if channels.len() <= id {
            channels.resize_with(id + 1, || None);
        }
        channels[id] = Some(chan.clone());
        drop(d);
        self.changed.notify_all();
        chan
    }

    fn schema(&self, id: u16, name: String, encoding: String) {
        self.lock().schemas.entry(id).or_insert((name, encoding));
    }

    fn get(&self, id: u16) -> Option<Arc<Chan>> {
        self.lock().channels.get(usize::from(id)).cloned().flatten()
    }

    /// The channels defined now.
    fn snapshot(&self) -> Arc<Vec<Option<Arc<Chan>>>> {
        self.lock().channels.clone()
    }

    /// The channel `id`, waiting (job `job`) until every earlier job is done if it is not
    /// defined yet.
    fn wait_for(&self, id: u16, job: u64) -> Option<Arc<Chan>> {
        let mut d = self.lock();
        loop {
            if let Some(Some(c)) = d.channels.get(usize::from(id)) {
                return Some(c.clone());
            }
            if d.done_below >= job {
                return None;
            }
            d = self.changed.wait(d).unwrap_or_else(|p| p.into_inner());
        }
    }

    fn finished(&self, job: u64) {
        let mut d = self.lock();
        d.done.insert(job);
        loop {
            let next = d.done_below;
            if !d.done.remove(&next) {
                break;
            }
            d.done_below += 1;
        }
        drop(d);
        self.changed.notify_all();
    }
}

/// Marks a job done however its worker leaves it (a panic included), so no other waits for it.
struct DoneGuard<'a>(&'a Shared, u64);
impl Drop for DoneGuard<'_> {
    fn drop(&mut self) {
        self.0.finished(self.1);
    }
}

/// A unit of work.
enum Work {
    /// A chunk record's body.
    Chunk(Vec<u8>),
    /// Consecutive top-level Message records: (offset, body).
    Loose(Vec<(u64, Vec<u8>)>),
}

struct Job<D: Decode> {
    id: u64,
    at: u64,
    work: Work,
    decoder: Arc<D>,
    shared: Arc<Shared>,
    raw: bool,
    limit: u64,
    reply: mpsc::SyncSender<Done<D::Out>>,
}

/// A job's result.
struct Done<O> {
    out: O,
    /// A chunk that could not be used, and why.
    failure: Option<String>,
    /// The chunk's CRC was checked.
    crc_checked: bool,
}

/// Hand one message to the decoder, with its channel from the job's snapshot of the table, or
/// (not defined there) from the table itself, waiting for earlier jobs' definitions.
fn deliver<D: Decode>(
    decoder: &D,
    shared: &Shared,
    table: &mut Arc<Vec<Option<Arc<Chan>>>>,
    job: u64,
    out: &mut D::Out,
    m: Msg<'_>,
) {
    let id = m.header.channel_id;
    if let Some(Some(c)) = table.get(usize::from(id)) {
        return decoder.message(out, c, m);
    }
    match shared.wait_for(id, job) {
        Some(c) => {
            *table = shared.snapshot();
            decoder.message(out, &c, m)
        }
        None => decoder.orphan(out, m),
    }
}

fn run<D: Decode>(job: Job<D>) {
    let Job { id, at, work, decoder, shared, raw, limit, reply } = job;
    let guard = DoneGuard(&shared, id);
    let mut out = decoder.start();
    let mut table = shared.snapshot();
    let (mut failure, mut crc_checked) = (None, false);
    match work {
        Work::Loose(records) => {
            for (at, body) in records {
                if let Ok(Record::Message { header, data }) = mcap::parse_record(op::MESSAGE, &body)
                {
                    deliver(
                        &*decoder,
                        &shared,
                        &mut table,
                        id,
                        &mut out,
                        Msg { header, data: &data, at },
                    );
                }
            }
        }
        Work::Chunk(body) => {
            let opened =
                super::chunk::for_each_record(
                    &body,
                    limit,
                    |opcode, data| match super::parse_record(opcode, data) {
                        Ok(Record::Schema { header, .. }) => {
                            shared.schema(header.id, header.name, header.encoding)
                        }
                        Ok(Record::Channel(c)) => {
                            let chan = shared.define(c, raw);
                            decoder.channel(&mut out, &chan);
                        }
                        Ok(Record::Message { header, data }) => {
                            let m = Msg { header, data: &data, at };
                            deliver(&*decoder, &shared, &mut table, id, &mut out, m)
                        }
                        _ => {}
                    },
                );
            match opened {
                Ok(o) => crc_checked = o.crc_checked,
                Err(e) => failure = Some(e.reason),
            }
        }
    }
    drop(guard);
    let _ = reply.send(Done { out, failure, crc_checked });
}

/// Workers taking jobs in order from one queue.
struct Pool<D: Decode> {
    tx: Option<mpsc::Sender<Job<D>>>,
}

impl<D: Decode> Pool<D> {
    fn start(workers: usize) -> Option<Self> {
        let (tx, rx) = mpsc::channel::<Job<D>>();
        let rx = Arc::new(Mutex::new(rx));
        for k in 0..workers {
            let rx = rx.clone();
            let spawned = std::thread::Builder::new().name(format!("recording-decode-{k}")).spawn(
                move || loop {
                    let job = match rx.lock() {
                        Ok(r) => r.recv(),
                        Err(_) => return,
                    };
                    match job {
                        Ok(job) => run(job),
                        Err(_) => return,
                    }
                },
            );
            if let Err(e) = spawned {
                tracing::debug!("decoding recordings on fewer threads: {e}");
                if k == 0 {
                    return None;
                }
                break;
            }
        }
        Some(Self { tx: Some(tx) })
    }
}

/// A unit of the file, waiting to be handed out.
enum Pending<O> {
    Ready(Unit<O>),
    Job {
        rx: mpsc::Receiver<Done<O>>,
        at: u64,
        len: u64,
        /// The chunk header's message time span.
        span: Option<(u64, u64)>,
        /// Messages per channel id by the message indexes after the chunk.
        index: BTreeMap<u16, u64>,
        /// After the data end.
        in_summary: bool,
    },
}

/// Top-level messages batched per job.
const LOOSE_BATCH: usize = 2048;

/// The read loop (module docs).
pub(crate) struct Engine<R, D: Decode> {
    scan: Scanner<R>,
    decoder: Arc<D>,
    shared: Arc<Shared>,
    raw: bool,
    queue: VecDeque<Pending<D::Out>>,
    jobs_queued: usize,
    loose: Vec<(u64, Vec<u8>)>,
    loose_at: u64,
    next_job: u64,
    pool: Option<Pool<D>>,
    workers: usize,
    scanned_all: bool,
    after_data_end: bool,
    end: End,
    /// Chunks read and CRC-checked.
    pub chunks_read: u64,
    pub chunks_crc_checked: u64,
}

impl<R: Read, D: Decode> Engine<R, D> {
    pub(crate) fn new(src: R, limit: u64, file_len: Option<u64>, decoder: D, raw: bool) -> Self {
        let workers = std::thread::available_parallelism().map_or(1, |n| n.get()).min(4);
        Self {
            scan: Scanner::new(src, limit, file_len),
            decoder: Arc::new(decoder),
            shared: Arc::default(),
            raw,
            queue: VecDeque::new(),
            jobs_queued: 0,
            loose: Vec::new(),
            loose_at: 0,
            next_job: 0,
            pool: None,
            workers,
            scanned_all: false,
            after_data_end: false,
            end: End::Reading,
            chunks_read: 0,
            chunks_crc_checked: 0,
        }
    }

    /// Channel definitions to fall back on before reading: the Schema and Channel records of
    /// a file's summary section (opcode, body).
    pub(crate) fn predefine(&mut self, records: &[(u8, Vec<u8>)]) {
        for (opcode, body) in records {
            match super::parse_record(*opcode, body) {
                Ok(Record::Schema { header, .. }) => {
                    self.shared.schema(header.id, header.name, header.encoding)
                }
                Ok(Record::Channel(c)) => {
                    self.shared.define(c, self.raw);
                }
                _ => {}
            }
        }
    }

    pub(crate) fn end(&self) -> &End {
        &self.end
    }

    pub(crate) fn bytes_read(&self) -> u64 {
        self.scan.offset()
    }

    /// Channels defined so far, by id.
    pub(crate) fn channels(&self) -> Vec<Arc<ChannelInfo>> {
        self.shared.lock().channels.iter().flatten().map(|c| c.info.clone()).collect()
    }

    fn dispatch(&mut self, at: u64, len: u64, work: Work, span: Option<(u64, u64)>) {
        let id = self.next_job;
        self.next_job += 1;
        let (reply, rx) = mpsc::sync_channel(1);
        let job = Job {
            id,
            at,
            work,
            decoder: self.decoder.clone(),
            shared: self.shared.clone(),
            raw: self.raw,
            limit: super::scan::MAX_CHUNK,
            reply,
        };
        // The first job runs here (a small file needs no threads); later ones on the workers.
        if id > 0 && self.pool.is_none() && self.workers > 1 {
            self.pool = Pool::start(self.workers);
            if self.pool.is_none() {
                self.workers = 1;
            }
        }
        let job = match self.pool.as_ref().and_then(|p| p.tx.as_ref()) {
            Some(tx) => match tx.send(job) {
                Ok(()) => None,
                Err(mpsc::SendError(job)) => Some(job),
            },
            None => Some(job),
        };
        if let Some(job) = job {
            run(job);
        }
        self.jobs_queued += 1;
        let in_summary = self.after_data_end;
        self.queue.push_back(Pending::Job {
            rx,
            at,
            len,
            span,
            index: BTreeMap::new(),
            in_summary,
        });
    }

    fn flush_loose(&mut self) {
        if !self.loose.is_empty() {
            let records = std::mem::take(&mut self.loose);
            self.dispatch(self.loose_at, 0, Work::Loose(records), None);
        }
    }

    fn ready(&mut self, unit: Unit<D::Out>) {
        self.flush_loose();
        self.queue.push_back(Pending::Ready(unit));
    }

    /// Frame one top-level event.
    fn frame(&mut self) {
        let Some(top) = self.scan.next_top() else {
            self.flush_loose();
            self.scanned_all = true;
            return;
        };
        match top {
            Top::Record { at, opcode, body } => self.record(at, opcode, body),
            Top::Skipped { at, to, reason } => {
                let d = Damage {
                    at_byte: at,
                    bytes: to - at,
                    kind: DamageKind::Bytes { reason },
                    span_ns: None,
                    lost: BTreeMap::new(),
                    in_summary: self.after_data_end,
                };
                self.ready(Unit::Damage(d));
            }
            Top::End(end) => {
                self.end = end;
                self.flush_loose();
                self.scanned_all = true;
            }
            Top::Failed(e) => {
                self.ready(Unit::Error(e));
                self.scanned_all = true;
            }
        }
    }

    fn record(&mut self, at: u64, opcode: u8, body: Vec<u8>) {
        if opcode == op::MESSAGE {
            if self.loose.is_empty() {
                self.loose_at = at;
            }
            self.loose.push((at, body));
            if self.loose.len() >= LOOSE_BATCH {
                self.flush_loose();
            }
            return;
        }
        if opcode == op::CHUNK {
            self.flush_loose();
            self.chunks_read += 1;
            let span = match super::parse_record(op::CHUNK, &body) {
                Ok(Record::Chunk { header, .. }) => {
                    Some((header.message_start_time, header.message_end_time))
                }
                _ => None,
            };
            let len = body.len() as u64 + 9;
            self.dispatch(at, len, Work::Chunk(body), span);
            return;
        }
        let Ok(record) = super::parse_record(opcode, &body) else { return };
        match record {
            Record::MessageIndex(m) => {
                // Counts of the chunk just before, in case it turns out damaged.
                if let Some(Pending::Job { index, len, .. }) = self.queue.back_mut() {
                    if *len > 0 {
                        *index.entry(m.channel_id).or_default() += m.records.len() as u64;
                    }
                }
            }
            Record::Schema { header, .. } => {
                self.shared.schema(header.id, header.name, header.encoding)
            }
            Record::Channel(c) => {
                let chan = self.shared.define(c, self.raw);
                let mut out = self.decoder.start();
                self.decoder.channel(&mut out, &chan);
                self.ready(Unit::Out(out));
            }
            Record::Metadata(m) => {
                self.ready(Unit::Metadata(MetadataRecord { name: m.name, entries: m.metadata }))
            }
            Record::Attachment { header, data, .. } => {
                self.ready(Unit::Attachment(AttachmentRecord {
                    name: header.name,
                    media_type: header.media_type,
                    log_time_ns: header.log_time,
                    data: data.into_owned(),
                }))
            }
            Record::DataEnd(_) => {
                self.flush_loose();
                self.after_data_end = true;
            }
            Record::Footer(_) => {
                self.flush_loose();
                self.end = if self.scan.footer_magic() {
                    End::Complete
                } else {
                    let at_byte = self.scan.offset();
                    End::Cut { at_byte, reason: "the end magic after the footer is missing".into() }
                };
                self.scanned_all = true;
            }
            _ => {}
        }
    }

    /// The next unit in file order; `None` at the end.
    pub(crate) fn next_unit(&mut self) -> Option<Unit<D::Out>> {
        loop {
            if matches!(self.queue.front(), Some(Pending::Ready(_))) {
                if let Some(Pending::Ready(u)) = self.queue.pop_front() {
                    return Some(u);
                }
            }
            let in_flight = self.jobs_queued < 2 * self.workers + 2;
            if !self.scanned_all && (self.queue.is_empty() || in_flight) {
                self.frame();
                continue;
            }
            match self.queue.pop_front()? {
                Pending::Ready(u) => return Some(u),
                Pending::Job { rx, at, len, span, index, in_summary } => {
                    self.jobs_queued -= 1;
                    let Ok(done) = rx.recv() else {
                        self.scanned_all = true;
                        self.queue.clear();
                        let source = std::io::Error::other("a decoding thread stopped");
                        return Some(Unit::Error(RecordingError::Io { at_byte: at, source }));
                    };
                    self.chunks_crc_checked += u64::from(done.crc_checked);
                    if let Some(reason) = done.failure {
                        // The messages decoded before the failure (a chunk without CRC) come
                        // first, then the damage.
                        let lost = index
                            .into_iter()
                            .map(|(id, n)| {
                                let topic = self.shared.get(id).map_or_else(
                                    || format!("(channel {id})"),
                                    |c| c.info.topic.clone(),
                                );
                                (topic, n)
                            })
                            .collect();
                        let d = Damage {
                            at_byte: at,
                            bytes: len,
                            kind: DamageKind::Chunk { reason },
                            span_ns: span.filter(|(a, b)| a <= b),
                            lost,
                            in_summary,
                        };
                        self.queue.push_front(Pending::Ready(Unit::Damage(d)));
                    }
                    return Some(Unit::Out(done.out));
                }
            }
        }
    }
}
