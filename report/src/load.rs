//! From a recording to the analyses' inputs: the one loader that calibration and diagnosis share.
//!
//! - **Time zero**: [`Recording::time_zero_ns`] (the earliest message on the contract's four
//!   channels); every time in [`RunSeries`] is in seconds from it.
//! - **Gyro**: samples whose rate is finite and whose `status` is usable
//!   ([`status::gyro::usable`]: 0, or exactly the counter-gap bit `SEQ_GAP` on a sample whose
//!   `seq` did skip — the flag marks a gap *before* a good sample), in time order; a repeated time stamp keeps its first sample. Samples left out are
//!   counted, with their times.
//! - **Time from the device where it has one** ([`bench_analysis::timebase`]): a channel whose
//!   `publish_time` differs from `log_time` carries device stamps; the gyro's `seq` is its
//!   sample counter. Host stamps are fitted as a line of the device clock and every sample is
//!   placed on that line (the host's axis without its jitter); each channel's time source,
//!   drift and jitter are reported ([`TimeBase`]). A channel with neither keeps its host
//!   stamps.
//! - **Gyro temperature**: the gyro's own sensor where it reads on more than half of the kept
//!   samples (gaps filled linearly); otherwise none, and the analyses use chamber air.
//! - **Table and chamber**: every reading with finite values, in time order.
//! - **Steps**: paired by [`bench_recording::steps`] (each `start` with the next `end` or
//!   `abort` of its index); a step the file does not end runs to the last gyro sample.
//! - **Site and model**: `bench.site` ([`bench_recording::Site::from_metadata`]) and
//!   `bench.gyro_model` with its `effect.*` keys.
//! - **Test station** (optional): `bench.station` as recorded, `bench.acceptance` limits as
//!   numbers ([`crate::acceptance`] judges a calibration against them).
//!
//! **Reduction** ([`read_stream`], what `bench calibrate` and `bench diagnose` use): the file is
//! read as a stream and the gyro's messages are never all held. As they pass they are averaged
//! in blocks of `n = ⌊f / 40 Hz⌋` consecutive usable samples ([`GyroIntake`]; `n = 1`, the
//! identity, at ≤ 40 Hz: the arrays are then the full-rate loader's, number for number). A
//! block never spans a sample left out, a counter that skips (a lost sample) or a step event;
//! its time is the end of its last sample's interval and [`RunData::gyro_dt_s`] is the block's
//! interval `n·dt`, so "the samples whose whole interval lies in a span" reads the same on
//! blocks. The rules above apply to blocks as they did to samples: the time base is chosen and
//! fitted on them (the fitted time is a line of the device's time, so a block's mean device
//! time gives its mean fitted time exactly), messages left out stay one each. The full-rate
//! Allan variance below the block is kept as the samples pass ([`RunSeries::gyro_sub_block`],
//! `bench_analysis::allan_sub`): the noise model's curve starts at τ = dt again. Table, chamber,
//! steps, metadata and damage are kept whole, as [`load`] keeps them. Why the analyses' noise
//! model holds for block means: docs/calibrate.md, "Reduced samples".

use std::collections::BTreeMap;

use bench_analysis::allan_sub::SubBlockSums;
use bench_analysis::interp::interp_at;
use bench_analysis::run::{RunSeries, StepEnd, StepSpan};
use bench_analysis::timebase::{fit_clock, median_interval, ClockFit};
use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use bench_recording::reader::{seconds_since, time_zero_ns, Item, RecordingReader};
use bench_recording::RecordingError;
use std::io::Read;

mod gyro;
use bench_recording::schema::{
    META_ACCEPTANCE, META_GYRO_MODEL, META_STATION, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_TABLE,
};
use bench_recording::{MetadataError, Recording, Stamped, StepEvent};
use gyro::GyroArrays;
pub use gyro::{block_len, GyroIntake, Reduction, REDUCED_RATE_HZ};

/// Why a recording cannot be turned into arrays.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// A required channel is missing or nearly empty.
    #[error("{topic}: {messages} usable message(s); the analysis needs this channel")]
    MissingChannel {
        /// Channel.
        topic: &'static str,
        /// Usable messages.
        messages: usize,
    },
    /// `bench.site` is not as the contract says.
    #[error(transparent)]
    Site(#[from] MetadataError),
    /// `bench.gyro_model` has a value that is not a number, or an incomplete effect.
    #[error("metadata bench.gyro_model: {0}")]
    BadModel(String),
}

/// The gyro model a recording carries in `bench.gyro_model`.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedModel {
    /// The contract's keys.
    pub model: GyroModel,
    /// Effects beyond it (`effect.*` keys).
    pub effects: Effects,
    /// Keys neither knows, kept to be reported.
    pub unknown_keys: BTreeMap<String, String>,
}

/// Where a channel's times come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeSource {
    /// The device's own stamps (`publish_time`), host stamps fitted to them.
    DeviceStamps,
    /// The device's sample counter (`seq`), host stamps fitted to it.
    DeviceCounter,
    /// The host's stamps (`log_time`) as they are.
    Host,
}

impl TimeSource {
    /// Short name, for JSON and tables.
    pub fn key(self) -> &'static str {
        match self {
            TimeSource::DeviceStamps => "device_stamps",
            TimeSource::DeviceCounter => "device_counter",
            TimeSource::Host => "host",
        }
    }
}

/// One channel's time base.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeBase {
    /// Topic.
    pub topic: &'static str,
    /// Where its times come from.
    pub source: TimeSource,
    /// The host clock as a line of the device's (with the host's jitter), when a device clock
    /// was used.
    pub fit: Option<ClockFit>,
}

/// A recording as arrays.
#[derive(Debug, Clone)]
pub struct RunData {
    /// The run's arrays, times in s from [`Self::zero_ns`].
    pub series: RunSeries,
    /// Time zero, ns since the Unix epoch.
    pub zero_ns: u64,
    /// What `model` is to the data: the simulator's truth, or nominal.
    pub model_role: bench_recording::ModelRole,
    /// `bench.gyro_model`, if the recording has one.
    pub model: Option<RecordedModel>,
    /// Times (s) of gyro samples left out for a non-zero status or a non-finite rate.
    pub bad_gyro_time_s: Vec<f64>,
    /// Median gyro sample interval, s (of the blocks, `n·dt`, where samples are averaged in
    /// blocks: module docs, "Reduction").
    pub gyro_dt_s: f64,
    /// Gyro samples averaged per block (1: every sample kept as it is).
    pub gyro_block_len: usize,
    /// Each device channel's time base (gyro, table, chamber).
    pub time_bases: Vec<TimeBase>,
    /// `bench.station` (unit serial, operator, station), empty without the record.
    pub station: BTreeMap<String, String>,
    /// `bench.acceptance`: the limit on |coefficient| per coefficient key, SI (keys whose value
    /// is not a positive number are left out and named in [`Self::acceptance_problems`]).
    pub acceptance: BTreeMap<String, f64>,
    /// `bench.acceptance` entries that are not a positive number.
    pub acceptance_problems: Vec<String>,
}

impl RunData {
    /// Whether the gyro's own temperature sensor is used.
    pub fn gyro_sensor(&self) -> bool {
        self.series.gyro_temp_c.is_some()
    }

    /// Gyro samples left out within `(start_s, end_s]`.
    pub fn bad_gyro_samples_in(&self, start_s: f64, end_s: f64) -> usize {
        let t = &self.bad_gyro_time_s;
        t.partition_point(|&x| x <= end_s) - t.partition_point(|&x| x <= start_s)
    }

    /// The record steps (labels starting with `record`), in time order.
    pub fn record_steps(&self) -> impl Iterator<Item = &StepSpan> {
        self.series.steps.iter().filter(|s| bench_recording::message::is_record_label(&s.label))
    }
}

/// Keep only strictly increasing times (a duplicate time stamp keeps its first sample).
fn strictly_increasing(t: &mut Vec<f64>, cols: &mut [&mut Vec<f64>]) {
    strictly_increasing_with(t, cols, None);
}

/// [`strictly_increasing`], with the gyro blocks' sub-block sums kept in step.
fn strictly_increasing_with(
    t: &mut Vec<f64>,
    cols: &mut [&mut Vec<f64>],
    mut sub: Option<&mut SubBlockSums>,
) {
    let mut keep = 0;
    let mut last = None;
    for i in 0..t.len() {
        if keep == 0 || t[i] > t[keep - 1] {
            t[keep] = t[i];
            for c in cols.iter_mut() {
                c[keep] = c[i];
            }
            if let Some(s) = sub.as_deref_mut() {
                s.move_block(i, keep, last);
            }
            last = Some(i);
            keep += 1;
        }
    }
    t.truncate(keep);
    for c in cols.iter_mut() {
        c.truncate(keep);
    }
    if let Some(s) = sub {
        s.truncate(keep);
    }
}

/// `bench.gyro_model` with its effects, if the recording has one.
pub fn recorded_model(rec: &Recording) -> Result<Option<RecordedModel>, LoadError> {
    let Some(meta) = rec.metadata(META_GYRO_MODEL) else { return Ok(None) };
    let (model, unknown) =
        GyroModel::from_metadata(meta).map_err(|e| LoadError::BadModel(e.to_string()))?;
    let effects = Effects::from_metadata(meta).map_err(LoadError::BadModel)?;
    let unknown_keys = unknown
        .into_iter()
        .filter(|(k, _)| !k.starts_with(bench_physics::effects::METADATA_PREFIX))
        .collect();
    Ok(Some(RecordedModel { model, effects, unknown_keys }))
}

/// Read the run's arrays from `rec` (module docs), every gyro sample kept.
pub fn load(rec: &Recording) -> Result<RunData, LoadError> {
    let mut gyro = GyroIntake::new(Reduction::Full);
    for m in &rec.gyro {
        gyro.push(m);
    }
    load_with(rec, gyro)
}

/// A recording read as a stream: everything but the gyro's messages as [`Recording`] holds it
/// (its `gyro` is empty), and the gyro's messages reduced as they passed ([`GyroIntake`]).
#[derive(Debug, Clone)]
pub struct Streamed {
    /// The recording without its gyro messages: the other channels, metadata, attachments, how
    /// the file ended, its damage.
    pub rec: Recording,
    /// The gyro's messages, reduced.
    pub gyro: GyroIntake,
}

/// Read a recording as a stream (module docs, "Reduction"): the gyro's messages are reduced
/// as they are read, never all held.
pub fn read_stream<R: Read>(
    mut reader: RecordingReader<R>,
    reduction: Reduction,
) -> Result<Streamed, RecordingError> {
    let mut rec = Recording::default();
    let mut gyro = GyroIntake::new(reduction);
    for item in reader.by_ref() {
        match item? {
            Item::Gyro(m) => gyro.push(&m),
            Item::Step(m) => {
                gyro.boundary();
                rec.steps.push(m);
            }
            other => rec.take(other),
        }
    }
    rec.finish_from(&reader);
    Ok(Streamed { rec, gyro })
}

/// The run's arrays from a recording read as a stream ([`read_stream`]).
pub fn load_streamed(s: Streamed) -> Result<RunData, LoadError> {
    load_with(&s.rec, s.gyro)
}

/// The run's arrays from `rec`'s other channels and the gyro's intake (module docs).
fn load_with(rec: &Recording, gyro: GyroIntake) -> Result<RunData, LoadError> {
    let need = |topic, n: usize| {
        if n < 2 {
            Err(LoadError::MissingChannel { topic, messages: n })
        } else {
            Ok(())
        }
    };
    need(TOPIC_GYRO, gyro.messages())?;
    need(TOPIC_TABLE, rec.table.len())?;
    need(TOPIC_CHAMBER, rec.chamber.len())?;
    let zero_ns = time_zero_ns([
        gyro.min_log_ns(),
        rec.table.iter().map(|m| m.log_time_ns).min(),
        rec.chamber.iter().map(|m| m.log_time_ns).min(),
        rec.steps.iter().map(|m| m.log_time_ns).min(),
    ])
    .unwrap_or(0);
    let secs = |ns: u64| seconds_since(zero_ns, ns);
    let site = rec.site()?;

    let GyroArrays {
        time_s: mut gyro_time_s,
        rate: mut gyro_rate,
        temp: mut gyro_temp,
        bad_time_s: bad_gyro_time_s,
        base: gyro_base,
        block_len: gyro_block_len,
        sub_block: mut gyro_sub_block,
    } = gyro.finish(zero_ns);
    strictly_increasing_with(
        &mut gyro_time_s,
        &mut [&mut gyro_rate, &mut gyro_temp],
        gyro_sub_block.as_mut(),
    );
    need(TOPIC_GYRO, gyro_time_s.len())?;
    let readings = gyro_temp.iter().filter(|t| t.is_finite()).count();
    let gyro_temp_c = (readings >= 2 && readings * 2 > gyro_temp.len()).then(|| {
        let (ts, vs): (Vec<f64>, Vec<f64>) = gyro_time_s
            .iter()
            .zip(&gyro_temp)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| (*t, *v))
            .unzip();
        let filled = interp_at(&ts, &vs, &gyro_time_s);
        gyro_temp.iter().zip(filled).map(|(v, f)| if v.is_finite() { *v } else { f }).collect()
    });
    let gyro_dt_s = median_interval(&gyro_time_s).unwrap_or(f64::NAN);

    let (table_times, table_base) = channel_times(TOPIC_TABLE, &rec.table, zero_ns);
    let mut table_time_s = Vec::with_capacity(rec.table.len());
    let mut angle = Vec::with_capacity(rec.table.len());
    let mut command = Vec::with_capacity(rec.table.len());
    for (m, &t) in rec.table.iter().zip(&table_times) {
        if m.msg.angle_rad.is_finite() && m.msg.rate_command_rad_s.is_finite() {
            table_time_s.push(t);
            angle.push(m.msg.angle_rad);
            command.push(m.msg.rate_command_rad_s);
        }
    }
    strictly_increasing(&mut table_time_s, &mut [&mut angle, &mut command]);
    let (chamber_times, chamber_base) = channel_times(TOPIC_CHAMBER, &rec.chamber, zero_ns);
    let mut chamber_time_s = Vec::with_capacity(rec.chamber.len());
    let mut air = Vec::with_capacity(rec.chamber.len());
    for (m, &t) in rec.chamber.iter().zip(&chamber_times) {
        if m.msg.temperature_c.is_finite() {
            chamber_time_s.push(t);
            air.push(m.msg.temperature_c);
        }
    }
    strictly_increasing(&mut chamber_time_s, &mut [&mut air]);
    need(TOPIC_TABLE, table_time_s.len())?;
    need(TOPIC_CHAMBER, chamber_time_s.len())?;

    // Steps: paired as everywhere (`bench_recording::steps`); a step the file does not end
    // runs to the last gyro sample, an end without a start is no span.
    let last_s = gyro_time_s.last().copied().unwrap_or(0.0);
    let steps = bench_recording::steps::pair(rec.steps.iter().map(|s| (s.log_time_ns, &s.msg)))
        .into_iter()
        .filter_map(|s| {
            let (end_s, ended) = match s.end {
                Some((t, StepEvent::Abort)) => (secs(t), StepEnd::Abort),
                Some((t, _)) => (secs(t), StepEnd::End),
                None => (last_s, StepEnd::Missing),
            };
            Some(StepSpan {
                index: s.index,
                name: s.name.to_owned(),
                label: s.label.to_owned(),
                start_s: secs(s.start?),
                end_s,
                ended,
            })
        })
        .collect();

    let mut acceptance = BTreeMap::new();
    let mut acceptance_problems = Vec::new();
    for (k, v) in rec.metadata(META_ACCEPTANCE).into_iter().flatten() {
        match v.trim().parse::<f64>() {
            Ok(x) if x.is_finite() && x > 0.0 => {
                acceptance.insert(k.clone(), x);
            }
            _ => acceptance_problems
                .push(format!("{META_ACCEPTANCE} {k} = {v:?}: a limit must be a positive number")),
        }
    }
    Ok(RunData {
        series: RunSeries {
            gyro_time_s,
            gyro_rate_rad_s: gyro_rate,
            gyro_sub_block,
            gyro_temp_c,
            table_time_s,
            table_angle_rad: angle,
            table_rate_command_rad_s: command,
            chamber_time_s,
            chamber_temp_c: air,
            steps,
            latitude_deg: site.map(|s| s.latitude_deg),
            axis_up: site.is_none_or(|s| s.axis_up()),
        },
        zero_ns,
        model: recorded_model(rec)?,
        model_role: rec.gyro_model_role(),
        bad_gyro_time_s,
        gyro_dt_s,
        gyro_block_len,
        time_bases: vec![gyro_base, table_base, chamber_base],
        station: rec.metadata(META_STATION).cloned().unwrap_or_default(),
        acceptance,
        acceptance_problems,
    })
}

/// A channel's sample times in s from `zero_ns` (module docs): its device stamps when it has
/// them, else its host stamps (the gyro's counter is read by its intake, [`GyroIntake`]).
/// Messages are taken in file order (non-decreasing `log_time` per the format).
fn channel_times<T>(
    topic: &'static str,
    msgs: &[Stamped<T>],
    zero_ns: u64,
) -> (Vec<f64>, TimeBase) {
    let host: Vec<f64> = msgs.iter().map(|m| seconds_since(zero_ns, m.log_time_ns)).collect();
    let stamped = msgs.iter().filter(|m| m.publish_time_ns != m.log_time_ns).count();
    let stamps = (msgs.len() >= 10 && stamped * 2 > msgs.len()).then(|| {
        let first = msgs[0].publish_time_ns;
        msgs.iter().map(|m| seconds_since(first, m.publish_time_ns)).collect::<Vec<f64>>()
    });
    // Device stamps must increase with the file's order to be a clock.
    match stamps.filter(|d| d.windows(2).all(|w| w[1] > w[0])) {
        Some(d) => on_device_clock(topic, d, TimeSource::DeviceStamps, host, 1.0),
        None => (host, TimeBase { topic, source: TimeSource::Host, fit: None }),
    }
}

/// Times on the device's clock `device` (stamps in s, or a counter's counts) where it keeps
/// time with the host's stamps `host` (same length), else the host stamps. `per_count` is the
/// host's median seconds per count, for a counter.
fn on_device_clock(
    topic: &'static str,
    device: Vec<f64>,
    source: TimeSource,
    host: Vec<f64>,
    per_count: f64,
) -> (Vec<f64>, TimeBase) {
    let host_only = |host| (host, TimeBase { topic, source: TimeSource::Host, fit: None });
    if device.len() < 10 {
        return host_only(host);
    }
    let Some(fit) = fit_clock(&device, &host) else { return host_only(host) };
    // A clock keeps time with the host's: the line through the host stamps runs at the rate
    // of the device's within 1 % (a real clock drifts by ppm; stamps in another unit, or a
    // counter that does not count samples, are far off), and at most one host stamp in ten
    // lies off the line. The host stamps' scatter is not held against the device: however
    // large (a loaded host, a scaled clock), the device's stamps are the better times.
    // A counter counts samples: its rate (seconds per count) is the host's median interval
    // within 10 %.
    let expected = match source {
        TimeSource::DeviceCounter => (per_count, 0.1),
        _ => (1.0, 0.01),
    };
    let ok_rate = expected.0 > 0.0 && (fit.rate / expected.0 - 1.0).abs() <= expected.1;
    if !(ok_rate && fit.outliers * 10 < device.len()) {
        return host_only(host);
    }
    let times = device.iter().map(|&d| fit.host(d)).collect();
    (times, TimeBase { topic, source, fit: Some(fit) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_recording::{ChamberMsg, GyroMsg, Outcome, Recorder, RunInfo, Site, TableMsg};
    use std::time::Duration;

    fn streamed(bytes: &[u8], reduction: Reduction) -> RunData {
        let s = read_stream(RecordingReader::new(bytes), reduction).expect("reads");
        assert!(s.rec.gyro.is_empty(), "the gyro's messages are not held");
        load_streamed(s).expect("loads")
    }

    /// At 20 Hz the reduction is the identity: the streamed arrays are the full-rate loader's,
    /// number for number.
    #[test]
    fn a_20_hz_stream_gives_the_full_rate_arrays() {
        let bytes = crate::testutil::short_run_bytes();
        let full = load(&Recording::from_bytes(&bytes).expect("reads")).expect("loads");
        for reduction in [Reduction::ToModelRate, Reduction::Full] {
            let s = streamed(&bytes, reduction);
            assert_eq!(s.series, full.series);
            assert_eq!(s.zero_ns, full.zero_ns);
            assert_eq!(s.time_bases, full.time_bases);
            assert_eq!(s.bad_gyro_time_s, full.bad_gyro_time_s);
            assert_eq!(s.gyro_dt_s.to_bits(), full.gyro_dt_s.to_bits());
        }
        assert_eq!(block_len(0.05), 1);
        assert_eq!(block_len(1.0 / 80.0), 2);
        assert_eq!(block_len(0.005), 5);
        assert_eq!(block_len(0.0005), 50);
    }

    /// A 200 Hz gyro is averaged in blocks of 5 consecutive usable samples; a block never spans
    /// a lost sample, a flagged one or a step event, and a block's time is its last sample's.
    #[test]
    fn a_200_hz_stream_is_reduced_to_block_means_that_span_no_gap_flag_or_step() {
        let info = RunInfo::new(1_767_225_600_000_000_000, "t", "", Site::at_latitude(45.0), {
            bench_physics::GyroModel::default().to_metadata()
        });
        let mut r = Recorder::new(std::io::Cursor::new(Vec::new()), info).expect("starts");
        let at = |k: u64| Duration::from_millis(5 * k);
        r.step(at(0), 0, "record", StepEvent::Start, "record a").expect("step");
        for k in 1..=200u64 {
            if k == 53 {
                continue; // lost: the counter skips
            }
            let g = GyroMsg {
                rate_rad_s: k as f64,
                temperature_c: Some(20.0 + k as f64 * 0.01),
                seq: k,
                status: if k == 100 { 1 } else { 0 },
            };
            r.gyro(at(k), None, &g).expect("gyro");
            if k.is_multiple_of(20) {
                let tm = TableMsg {
                    angle_rad: 0.0,
                    rate_rad_s: 0.0,
                    rate_command_rad_s: 0.0,
                    status: 0,
                };
                r.table(at(k), None, &tm).expect("table");
                let c = ChamberMsg { temperature_c: 20.0, setpoint_c: 20.0, status: 0 };
                r.chamber(at(k), None, &c).expect("chamber");
            }
            if k == 71 {
                r.step(at(k), 0, "record", StepEvent::End, "record a").expect("step");
                r.step(at(k), 1, "record", StepEvent::Start, "record b").expect("step");
            }
        }
        let bytes = r.finish(&Outcome::Completed).expect("finished").into_inner();
        let d = streamed(&bytes, Reduction::ToModelRate);
        // Runs of consecutive usable samples, cut in blocks of 5.
        let runs = [(1..=52), (54..=71), (72..=99), (101..=200)];
        let mut rate = Vec::new();
        let mut time = Vec::new();
        for run in runs {
            let ks: Vec<u64> = run.collect();
            for b in ks.chunks(5) {
                rate.push(b.iter().sum::<u64>() as f64 / b.len() as f64);
                time.push(*b.last().expect("a block") as f64 * 0.005);
            }
        }
        assert_eq!(d.series.gyro_rate_rad_s, rate);
        assert_eq!(d.series.gyro_time_s.len(), time.len());
        for (got, want) in d.series.gyro_time_s.iter().zip(&time) {
            assert!((got - want).abs() < 1e-9, "{got} against {want}");
        }
        assert!((d.gyro_dt_s - 0.025).abs() < 1e-9, "{}", d.gyro_dt_s);
        assert_eq!(d.bad_gyro_time_s.len(), 1);
        assert!((d.bad_gyro_time_s[0] - 0.5).abs() < 1e-9);
        assert_eq!(d.time_bases[0].source, TimeSource::DeviceCounter);
        let temp = d.series.gyro_temp_c.as_ref().expect("the sensor reads");
        assert!((temp[0] - 20.03).abs() < 1e-12, "{}", temp[0]);
        // The full-rate loader of the same file keeps every usable sample.
        let full = load(&Recording::from_bytes(&bytes).expect("reads")).expect("loads");
        assert_eq!(full.series.gyro_time_s.len(), 198);
    }

    #[test]
    fn duplicate_time_stamps_keep_the_first_sample() {
        let mut t = vec![0.0, 1.0, 1.0, 2.0];
        let mut v = vec![1.0, 2.0, 3.0, 4.0];
        strictly_increasing(&mut t, &mut [&mut v]);
        assert_eq!(t, vec![0.0, 1.0, 2.0]);
        assert_eq!(v, vec![1.0, 2.0, 4.0]);
    }
}
