//! A lab's recording made from a simulated one: the traits a real bench's files have and
//! bench's own simulated files do not, applied to a recording in memory so that the studies
//! can measure what each does to the analyses.
//!
//! [`LabTraits::lab`] is what a lab's host typically records: table telemetry at 10 Hz and the
//! chamber at 1 Hz against a 20 Hz gyro, the table angle on the 1″ grid of an ST1300 class
//! readout, host stamps with 2 ms of jitter and a constant latency per channel (the gyro's own
//! sample times kept as its device stamps), lost gyro frames (sequence gaps, in bursts of 1–3)
//! and frames flagged bad with garbage values, and record steps that begin at the table's
//! reversal instead of after it settles. [`LabTraits::none`] changes nothing. The result is
//! written with bench's recorder and read back, so it goes through the same reader as any file.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::time::Duration;

use anyhow::Context as _;
use bench_recording::schema::{META_GYRO_MODEL, META_SCENARIO};
use bench_recording::{
    ChamberMsg, GyroMsg, Outcome, Recorder, RecorderOptions, Recording, RunInfo, Site, StepEvent,
    StepMsg, TableMsg,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The traits applied (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabTraits {
    /// Table telemetry rate, Hz (`None`: as recorded).
    pub table_hz: Option<f64>,
    /// Chamber telemetry rate, Hz (`None`: as recorded).
    pub chamber_hz: Option<f64>,
    /// The table angle rounded to this step, rad (`None`: as recorded).
    pub angle_quantum_rad: Option<f64>,
    /// Host stamps' jitter, 1σ, s.
    pub jitter_s: f64,
    /// Host stamps' constant latency behind the sample (gyro, table, chamber), s.
    pub latency_s: [f64; 3],
    /// Keep the gyro's sample times as its device stamps (`publish_time`).
    pub gyro_device_stamps: bool,
    /// Probability that a gyro frame starts a burst of 1–3 lost frames.
    pub lost_frames: f64,
    /// Probability that a gyro frame is flagged bad (status 1, garbage rate and temperature).
    pub bad_frames: f64,
    /// Record steps begin at the table's last command change before them (the reversal) and
    /// end at its next one, where no other record step lies between.
    pub windows_from_reversal: bool,
}

impl LabTraits {
    /// Nothing changed.
    pub fn none() -> Self {
        Self {
            table_hz: None,
            chamber_hz: None,
            angle_quantum_rad: None,
            jitter_s: 0.0,
            latency_s: [0.0; 3],
            gyro_device_stamps: false,
            lost_frames: 0.0,
            bad_frames: 0.0,
            windows_from_reversal: false,
        }
    }

    /// A lab's host (module docs).
    pub fn lab() -> Self {
        Self {
            table_hz: Some(10.0),
            chamber_hz: Some(1.0),
            angle_quantum_rad: Some(bench_physics::units::ARCSEC),
            jitter_s: 0.002,
            latency_s: [0.003, 0.012, 0.040],
            gyro_device_stamps: true,
            lost_frames: 1e-4,
            bad_frames: 5e-5,
            windows_from_reversal: true,
        }
    }
}

/// Keep a message of a stream at `hz` when it is the first in its period.
fn decimate<T>(msgs: &[bench_recording::Stamped<T>], hz: Option<f64>) -> Vec<usize> {
    let Some(hz) = hz else { return (0..msgs.len()).collect() };
    let mut last = i64::MIN;
    let mut keep = Vec::new();
    for (i, m) in msgs.iter().enumerate() {
        let slot = (m.log_time_ns as f64 * 1e-9 * hz).floor() as i64;
        if slot != last {
            keep.push(i);
            last = slot;
        }
    }
    keep
}

/// `rec` with `traits` applied, drawn from `seed` (module docs).
pub fn apply(rec: &Recording, traits: &LabTraits, seed: u64) -> anyhow::Result<Recording> {
    Ok(Recording::from_bytes(&apply_to_bytes(rec, traits, seed)?)?)
}

/// [`apply`], the result as the MCAP file's bytes.
pub fn apply_to_bytes(rec: &Recording, traits: &LabTraits, seed: u64) -> anyhow::Result<Vec<u8>> {
    let zero = rec.time_zero_ns().context("the recording has no messages")?;
    // Bench time zero one second before the first message: jitter may stamp earlier.
    let epoch = zero.saturating_sub(1_000_000_000);
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1ab_7a17);
    let stamp = |t_ns: u64, latency: f64, rng: &mut ChaCha8Rng| -> Duration {
        let e: f64 = StandardNormal.sample(rng);
        let s = (t_ns - epoch) as f64 * 1e-9 + latency + traits.jitter_s * e;
        Duration::from_secs_f64(s.max(0.0))
    };

    // Gyro: lost and bad frames, host stamps, device stamps.
    let mut gyro: Vec<(Duration, Option<Duration>, GyroMsg)> = Vec::with_capacity(rec.gyro.len());
    let mut lost = 0usize;
    for g in &rec.gyro {
        if lost > 0 {
            lost -= 1;
            continue;
        }
        if traits.lost_frames > 0.0 && rng.random::<f64>() < traits.lost_frames {
            lost = rng.random_range(0..3);
            continue;
        }
        let mut msg = g.msg;
        if traits.bad_frames > 0.0 && rng.random::<f64>() < traits.bad_frames {
            msg.status |= bench_recording::status::gyro::INVALID;
            msg.rate_rad_s = if rng.random::<bool>() { 12.3 } else { 0.0 };
            msg.temperature_c = msg.temperature_c.map(|_| -273.0);
        }
        let device = traits.gyro_device_stamps.then(|| Duration::from_nanos(g.log_time_ns - epoch));
        gyro.push((stamp(g.log_time_ns, traits.latency_s[0], &mut rng), device, msg));
    }
    // Table: decimated, the angle on the readout's grid.
    let mut table: Vec<(Duration, TableMsg)> = decimate(&rec.table, traits.table_hz)
        .into_iter()
        .map(|i| {
            let m = &rec.table[i];
            let mut msg = m.msg;
            if let Some(q) = traits.angle_quantum_rad {
                msg.angle_rad = (msg.angle_rad / q).round() * q;
            }
            (stamp(m.log_time_ns, traits.latency_s[1], &mut rng), msg)
        })
        .collect();
    let mut chamber: Vec<(Duration, ChamberMsg)> = decimate(&rec.chamber, traits.chamber_hz)
        .into_iter()
        .map(|i| {
            let m = &rec.chamber[i];
            (stamp(m.log_time_ns, traits.latency_s[2], &mut rng), m.msg)
        })
        .collect();
    // Host stamps go in arrival order: a later sample may arrive first under jitter.
    gyro.sort_by_key(|g| g.0);
    table.sort_by_key(|t| t.0);
    chamber.sort_by_key(|c| c.0);

    // Steps, record windows moved to the table's command changes.
    let mut steps: Vec<(u64, StepMsg)> =
        rec.steps.iter().map(|s| (s.log_time_ns, s.msg.clone())).collect();
    if traits.windows_from_reversal {
        let changes: Vec<u64> = rec
            .table
            .windows(2)
            .filter(|w| w[1].msg.rate_command_rad_s != w[0].msg.rate_command_rad_s)
            .map(|w| w[1].log_time_ns)
            .collect();
        move_record_steps(&mut steps, &changes);
    }
    steps.sort_by_key(|s| s.0);

    let meta = |name: &str| rec.metadata(name).cloned().unwrap_or_default();
    let scenario = meta(META_SCENARIO);
    let site = rec.site()?.unwrap_or_else(|| Site::at_latitude(0.0));
    let mut info = RunInfo::new(
        epoch,
        scenario.get("name").cloned().unwrap_or_default(),
        scenario.get("text").cloned().unwrap_or_default(),
        site,
        meta(META_GYRO_MODEL),
    );
    info.gyro_model_role = rec.gyro_model_role();
    let opts = RecorderOptions { flush_interval: None, ..RecorderOptions::default() };
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info, opts)?;
    for (t, device, msg) in &gyro {
        r.gyro(*t, *device, msg)?;
    }
    for (t, msg) in &table {
        r.table(*t, None, msg)?;
    }
    for (t, msg) in &chamber {
        r.chamber(*t, None, msg)?;
    }
    for (t_ns, s) in &steps {
        let t = Duration::from_nanos(t_ns.saturating_sub(epoch));
        r.step(t, s.index, &s.name, s.event, &s.label)?;
    }
    let outcome = rec.outcome().unwrap_or(Outcome::Completed);
    Ok(r.finish(&outcome)?.into_inner())
}

/// Record steps' start events moved back to the last command change before them, and their
/// end events forward to the next one, where no other record step's event lies between.
fn move_record_steps(steps: &mut [(u64, StepMsg)], changes: &[u64]) {
    let record_times: Vec<u64> =
        steps.iter().filter(|(_, s)| s.is_record()).map(|(t, _)| *t).collect();
    let others_between = |a: u64, b: u64, own: u64| {
        record_times.iter().any(|&t| t > a.min(b) && t < a.max(b) && t != own)
    };
    let mut moved: BTreeMap<usize, u64> = BTreeMap::new();
    for (i, (t, s)) in steps.iter().enumerate() {
        if !s.is_record() {
            continue;
        }
        let target = match s.event {
            StepEvent::Start => changes.iter().rev().find(|&&c| c <= *t).copied(),
            StepEvent::End => changes.iter().find(|&&c| c >= *t).copied(),
            StepEvent::Abort => None,
        };
        if let Some(c) = target.filter(|&c| !others_between(c, *t, *t)) {
            moved.insert(i, c);
        }
    }
    for (i, c) in moved {
        steps[i].0 = c;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::capabilities;

    #[test]
    fn a_simulated_run_gets_a_labs_traits() {
        let plan = crate::scenario::load(
            std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/seed.toml")),
            &capabilities(),
        )
        .expect("the shipped seed scenario");
        let (_, bytes) = crate::runner::simulate_in_memory(&plan, 1).expect("simulated");
        let rec = Recording::from_bytes(&bytes).expect("readable");
        let lab = apply(&rec, &LabTraits::lab(), 1).expect("lab traits");
        // Rates: table at 10 Hz, chamber at 1 Hz, gyro minus lost frames.
        let ratio = |a: usize, b: usize| a as f64 / b as f64;
        assert!((ratio(lab.table.len(), rec.table.len()) - 0.5).abs() < 0.01);
        assert!((ratio(lab.chamber.len(), rec.chamber.len()) - 0.05).abs() < 0.005);
        let lost = rec.gyro.len() - lab.gyro.len();
        assert!(lost > 0 && lost < rec.gyro.len() / 1000, "{lost}");
        assert!(lab.gyro.iter().any(|g| g.msg.status & 1 != 0));
        // Angles on the 1″ grid; host stamps jittered, device stamps exact.
        let q = bench_physics::units::ARCSEC;
        assert!(lab.table.iter().all(|t| {
            let k = t.msg.angle_rad / q;
            (k - k.round()).abs() < 1e-6
        }));
        let offsets: Vec<f64> = lab
            .gyro
            .iter()
            .map(|g| (g.log_time_ns as f64 - g.publish_time_ns as f64) * 1e-9)
            .collect();
        let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
        let sd =
            (offsets.iter().map(|o| (o - mean).powi(2)).sum::<f64>() / offsets.len() as f64).sqrt();
        assert!((mean - 0.003).abs() < 2e-4 && (sd - 0.002).abs() < 2e-4, "{mean} {sd}");
        // Every record step now starts at a table command change (the reversal) or where the
        // previous one ended.
        let starts = |r: &Recording| -> Vec<u64> {
            r.steps
                .iter()
                .filter(|s| s.msg.is_record() && s.msg.event == StepEvent::Start)
                .map(|s| s.log_time_ns)
                .collect()
        };
        let (a, b) = (starts(&rec), starts(&lab));
        assert_eq!(a.len(), b.len());
        assert!(a.iter().zip(&b).any(|(x, y)| y < x), "some windows moved back");
        assert!(a.iter().zip(&b).all(|(x, y)| y <= x));
        // Nothing changed with no traits.
        let same = apply(&rec, &LabTraits::none(), 1).expect("none");
        assert_eq!(same.gyro.len(), rec.gyro.len());
        assert_eq!(
            same.gyro.iter().map(|g| g.msg.rate_rad_s).collect::<Vec<_>>(),
            rec.gyro.iter().map(|g| g.msg.rate_rad_s).collect::<Vec<_>>()
        );
    }
}
