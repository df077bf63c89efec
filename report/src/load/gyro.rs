//! The gyro's intake: messages taken one at a time, as a stream passes, and reduced to blocks
//! (the loader's module docs, "Reduction").
//!
//! A block holds up to `n` consecutive usable samples in file order and their sums: rate,
//! temperature, and each candidate time axis (host stamps, device stamps, device counter) as
//! the first sample's value plus the sum of offsets from it. The time base is chosen and fitted
//! once the stream has passed ([`GyroIntake::finish`]), on the blocks: the fitted time is a
//! line of the device's, so the mean of the samples' fitted times is the line at the mean of
//! their device times — a block's time is exact whatever the line turns out to be. With `n = 1`
//! every block is one message and every number is the one the full-rate arrays had.
//!
//! A block closes at a message left out (a non-zero status, a non-finite rate), at a counter
//! that skips (a lost sample: a gap), at a step event, and when it holds `n` samples. A message
//! left out is a block of its own, kept for the clock fit and for the times of samples left
//! out, as the full-rate loader kept every message.
//!
//! With `n > 1` each usable block also leaves the full-rate Allan variance's sums below the
//! block ([`SubBlockSums`]: its own samples and, when joined, the full block before it; a
//! break — a message left out, a counter skip, a step — joins nothing across it).

use bench_analysis::allan_sub::SubBlockSums;
use bench_analysis::timebase::median_interval;
use bench_recording::reader::seconds_since;
use bench_recording::{status, GyroMsg, Stamped};

use super::{TimeBase, TimeSource};
use bench_recording::schema::TOPIC_GYRO;

/// The rate the thermal model needs, Hz: samples are averaged in blocks of `⌊f / 40 Hz⌋`.
pub const REDUCED_RATE_HZ: f64 = 40.0;

/// Messages buffered at the start of a stream to read the gyro's sample rate.
const RATE_PROBE: usize = 64;

/// Samples per block for a gyro sampled every `interval_s`: `⌊f / 40 Hz⌋`, at least 1.
pub fn block_len(interval_s: f64) -> usize {
    if !(interval_s.is_finite() && interval_s > 0.0) {
        return 1;
    }
    // The small margin keeps an exact multiple of 40 Hz (80 Hz: 12.5 ms) from falling to the
    // integer below on rounding.
    ((1.0 / (interval_s * REDUCED_RATE_HZ)) + 1e-3).floor().max(1.0) as usize
}

/// How the gyro's samples are kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reduction {
    /// Every sample (the full-rate arrays).
    Full,
    /// Blocks of `⌊f / 40 Hz⌋` samples, `f` read from the stream's first messages.
    ToModelRate,
    /// Blocks of exactly this many samples.
    Blocks(usize),
}

/// One block of consecutive samples (module docs).
#[derive(Debug, Clone, Copy)]
struct Block {
    /// First message's `log_time`, ns, and the sum of the others' offsets from it.
    host_ns: u64,
    host_rel_ns: f64,
    /// First message's `publish_time`, ns, and the offsets' sum.
    pub_ns: u64,
    pub_rel_ns: f64,
    /// First message's counter (with the wraps before it), and the offsets' sum.
    seq: u64,
    wraps: u32,
    seq_rel: f64,
    /// Messages in the block.
    count: u32,
    /// Temperature readings in it.
    temps: u32,
    /// Sums of rate and of the finite temperatures.
    rate_sum: f64,
    temp_sum: f64,
    /// Usable samples (else one message left out).
    usable: bool,
}

impl Block {
    fn new(m: &Stamped<GyroMsg>, wraps: u32, usable: bool) -> Self {
        let temp = m.msg.temperature_c.filter(|t| t.is_finite());
        Block {
            host_ns: m.log_time_ns,
            host_rel_ns: 0.0,
            pub_ns: m.publish_time_ns,
            pub_rel_ns: 0.0,
            seq: m.msg.seq,
            wraps,
            seq_rel: 0.0,
            count: 1,
            temps: u32::from(temp.is_some()),
            rate_sum: m.msg.rate_rad_s,
            temp_sum: temp.unwrap_or(0.0),
            usable,
        }
    }

    fn add(&mut self, m: &Stamped<GyroMsg>) {
        self.host_rel_ns += m.log_time_ns.wrapping_sub(self.host_ns) as i64 as f64;
        self.pub_rel_ns += m.publish_time_ns.wrapping_sub(self.pub_ns) as i64 as f64;
        self.seq_rel += m.msg.seq.wrapping_sub(self.seq) as i64 as f64;
        self.count += 1;
        self.rate_sum += m.msg.rate_rad_s;
        if let Some(t) = m.msg.temperature_c.filter(|t| t.is_finite()) {
            self.temps += 1;
            self.temp_sum += t;
        }
    }

    /// Mean offset of the block's messages from its first, in the unit of `rel`.
    fn mean(&self, rel: f64) -> f64 {
        if self.count == 1 {
            0.0
        } else {
            rel / f64::from(self.count)
        }
    }
}

/// The gyro's messages reduced as they pass (module docs).
#[derive(Debug, Clone)]
pub struct GyroIntake {
    reduction: Reduction,
    /// Samples per block; 0 until the rate is read.
    n: usize,
    /// The first messages, until the rate is read (with the step boundaries among them).
    probe: Vec<(Stamped<GyroMsg>, bool)>,
    blocks: Vec<Block>,
    open: Option<Block>,
    /// The previous message's counter and `publish_time`.
    prev: Option<(u64, u64)>,
    messages: usize,
    stamped: usize,
    stamps_increase: bool,
    max_seq: u64,
    wraps: u32,
    min_log_ns: Option<u64>,
    /// The Allan variance's sums below the block (`n > 1`), per usable block.
    sub: Option<SubBlockSums>,
    /// The open block's rates and the previous block's (when full and joined to it).
    sub_cur: Vec<f64>,
    sub_prev: Vec<f64>,
    sub_scratch: Vec<f64>,
}

/// The gyro's arrays from the intake.
pub(super) struct GyroArrays {
    pub time_s: Vec<f64>,
    pub rate: Vec<f64>,
    pub temp: Vec<f64>,
    pub bad_time_s: Vec<f64>,
    pub base: TimeBase,
    pub block_len: usize,
    pub sub_block: Option<SubBlockSums>,
}

impl GyroIntake {
    /// An empty intake.
    pub fn new(reduction: Reduction) -> Self {
        let n = match reduction {
            Reduction::Full => 1,
            Reduction::ToModelRate => 0,
            Reduction::Blocks(n) => n.max(1),
        };
        GyroIntake {
            reduction,
            n,
            sub: (n > 1).then(|| SubBlockSums::new(n)),
            sub_cur: Vec::new(),
            sub_prev: Vec::new(),
            sub_scratch: Vec::new(),
            probe: Vec::new(),
            blocks: Vec::new(),
            open: None,
            prev: None,
            messages: 0,
            stamped: 0,
            stamps_increase: true,
            max_seq: 0,
            wraps: 0,
            min_log_ns: None,
        }
    }

    /// Gyro messages taken.
    pub fn messages(&self) -> usize {
        self.messages
    }

    /// Samples per block (1 = the full-rate arrays); 0 while the rate is not read yet.
    pub fn block_len(&self) -> usize {
        self.n
    }

    /// Blocks kept so far.
    pub fn blocks(&self) -> usize {
        self.blocks.len() + usize::from(self.open.is_some())
    }

    /// The earliest `log_time` of a gyro message.
    pub fn min_log_ns(&self) -> Option<u64> {
        self.min_log_ns
    }

    /// A step event passed: no block spans it.
    pub fn boundary(&mut self) {
        if self.n == 0 {
            if let Some(last) = self.probe.last_mut() {
                last.1 = true;
            }
            return;
        }
        self.close();
        self.sub_prev.clear();
    }

    /// Take one message, in file order.
    pub fn push(&mut self, m: &Stamped<GyroMsg>) {
        if self.n == 0 {
            self.probe.push((m.clone(), false));
            if self.probe.len() >= RATE_PROBE {
                self.start();
            }
            return;
        }
        self.take(m);
    }

    /// Read the rate from the probe and take its messages.
    fn start(&mut self) {
        let probe = std::mem::take(&mut self.probe);
        let stamped = probe.iter().filter(|(m, _)| m.publish_time_ns != m.log_time_ns).count();
        let times: Vec<f64> = probe
            .iter()
            .map(|(m, _)| {
                let ns = if stamped * 2 > probe.len() { m.publish_time_ns } else { m.log_time_ns };
                ns as f64 * 1e-9
            })
            .collect();
        self.n = match self.reduction {
            Reduction::ToModelRate => median_interval(&times).map_or(1, block_len),
            Reduction::Full => 1,
            Reduction::Blocks(n) => n.max(1),
        };
        self.sub = (self.n > 1).then(|| SubBlockSums::new(self.n));
        for (m, boundary) in &probe {
            self.take(m);
            if *boundary {
                self.close();
                self.sub_prev.clear();
            }
        }
    }

    fn close(&mut self) {
        if let Some(b) = self.open.take() {
            if let Some(sub) = self.sub.as_mut() {
                sub.push_block(&self.sub_prev, &self.sub_cur, &mut self.sub_scratch);
                if self.sub_cur.len() == self.n {
                    std::mem::swap(&mut self.sub_prev, &mut self.sub_cur);
                } else {
                    self.sub_prev.clear();
                }
                self.sub_cur.clear();
            }
            self.blocks.push(b);
        }
    }

    fn take(&mut self, m: &Stamped<GyroMsg>) {
        self.messages += 1;
        self.min_log_ns = Some(self.min_log_ns.map_or(m.log_time_ns, |t| t.min(m.log_time_ns)));
        if m.publish_time_ns != m.log_time_ns {
            self.stamped += 1;
        }
        let seq = m.msg.seq;
        let skipped = match self.prev {
            Some((p, pub_ns)) => {
                if m.publish_time_ns <= pub_ns {
                    self.stamps_increase = false;
                }
                if seq < p {
                    self.wraps += 1;
                }
                seq != p.wrapping_add(1)
            }
            None => false,
        };
        self.prev = Some((seq, m.publish_time_ns));
        self.max_seq = self.max_seq.max(seq);
        let usable = status::gyro::usable(m.msg.status, skipped) && m.msg.rate_rad_s.is_finite();
        if !usable {
            self.close();
            self.sub_prev.clear();
            self.blocks.push(Block::new(m, self.wraps, false));
            return;
        }
        if skipped {
            self.close();
            self.sub_prev.clear();
        }
        if self.sub.is_some() {
            self.sub_cur.push(m.msg.rate_rad_s);
        }
        match self.open.as_mut() {
            Some(b) => b.add(m),
            None => self.open = Some(Block::new(m, self.wraps, true)),
        }
        if self.open.as_ref().is_some_and(|b| b.count as usize >= self.n) {
            self.close();
        }
    }

    /// The arrays, times in s from `zero_ns` (the loader's time base, its usable-sample rule):
    /// usable blocks in time order, the times of messages left out, the time base.
    pub(super) fn finish(mut self, zero_ns: u64) -> GyroArrays {
        if self.n == 0 {
            self.start();
        }
        self.close();
        let n = self.n;
        let blocks = std::mem::take(&mut self.blocks);
        let host: Vec<f64> = blocks
            .iter()
            .map(|b| seconds_since(zero_ns, b.host_ns) + b.mean(b.host_rel_ns) * 1e-9)
            .collect();
        let (times, base) = self.times(&blocks, host, n);
        let mut out = GyroArrays {
            time_s: Vec::with_capacity(blocks.len()),
            rate: Vec::with_capacity(blocks.len()),
            temp: Vec::with_capacity(blocks.len()),
            bad_time_s: Vec::new(),
            base,
            block_len: n,
            sub_block: None,
        };
        // A block's time is the end of its last sample's interval, as a sample's is: its mean
        // time plus half the samples after the first.
        let dt_sample = if n > 1 {
            let usable: Vec<f64> =
                blocks.iter().zip(&times).filter(|(b, _)| b.usable).map(|(_, t)| *t).collect();
            median_interval(&usable).unwrap_or(0.0) / n as f64
        } else {
            0.0
        };
        out.sub_block = self.sub.take().map(|mut s| {
            s.set_dt_s(dt_sample);
            s
        });
        for (b, &t) in blocks.iter().zip(&times) {
            if !b.usable {
                out.bad_time_s.push(t);
                continue;
            }
            let c = f64::from(b.count);
            out.time_s.push(if n > 1 { t + 0.5 * (c - 1.0) * dt_sample } else { t });
            out.rate.push(if b.count == 1 { b.rate_sum } else { b.rate_sum / c });
            out.temp.push(if b.temps == 0 {
                f64::NAN
            } else if b.temps == 1 {
                b.temp_sum
            } else {
                b.temp_sum / f64::from(b.temps)
            });
        }
        out.bad_time_s.sort_by(f64::total_cmp);
        out
    }

    /// The blocks' times and the gyro's time base (the loader's rule, `channel_times`, on
    /// blocks: with `n = 1` on every message).
    fn times(&self, blocks: &[Block], host: Vec<f64>, n: usize) -> (Vec<f64>, TimeBase) {
        let topic = TOPIC_GYRO;
        let host_only = |host| (host, TimeBase { topic, source: TimeSource::Host, fit: None });
        let (Some(first), true) = (blocks.first(), blocks.len() >= 10) else {
            return host_only(host);
        };
        let stamps = (self.messages >= 10 && self.stamped * 2 > self.messages)
            .then(|| {
                blocks
                    .iter()
                    .map(|b| seconds_since(first.pub_ns, b.pub_ns) + b.mean(b.pub_rel_ns) * 1e-9)
                    .collect::<Vec<f64>>()
            })
            .filter(|d| self.stamps_increase && d.windows(2).all(|w| w[1] > w[0]));
        let (device, source) = match stamps {
            Some(d) => (d, TimeSource::DeviceStamps),
            None => {
                let max = self.max_seq;
                let width: u128 = if max == u64::MAX {
                    1u128 << 64
                } else {
                    u128::from(max + 1).next_power_of_two()
                };
                let value = |b: &Block| (u128::from(b.wraps) * width + u128::from(b.seq)) as f64;
                let first = value(first);
                let d = blocks.iter().map(|b| value(b) - first + b.mean(b.seq_rel)).collect();
                (d, TimeSource::DeviceCounter)
            }
        };
        // A counter's seconds per count: the host's median interval per sample.
        let per_count = match source {
            TimeSource::DeviceCounter => median_interval(&host).unwrap_or(0.0) / n.max(1) as f64,
            _ => 1.0,
        };
        super::on_device_clock(topic, device, source, host, per_count)
    }
}
