//! Record windows for the calibration, from the shared loader's arrays ([`crate::load`]).
//!
//! - **Windows**: every `record …` step, cut to the table's steady motion
//!   ([`bench_analysis::steady`]: the rule diagnosis uses too): each steady part of the step
//!   becomes a window of the gyro samples whose whole interval lies in it. What the step holds
//!   outside its steady parts — the reversal at its start, the table accelerating, settling or
//!   stopping, a gap in the table's data — is excluded, each span with its cause, and reported
//!   ([`WindowExclusion`]). A step with several steady parts gives one window per part.
//! - **Table rate from the angle**: the input rate is the slope of the steady part's straight
//!   line through the table's angle readings (plus the ripple the readings resolve), not the
//!   measured-rate field. A table's angle readout is its precise quantity (1″ on an ST1300
//!   class table: over minutes at 10 °/min the line averages thousands of steps and the host
//!   stamps' jitter), while its rate readout is an encoder difference whose noise (≈ 1e-6
//!   rad/s) is ten times the gyro's own white noise at 20 Hz.
//! - **Model temperature**: the gyro's own sensor where it has one (the loader's rule);
//!   otherwise chamber air, interpolated at the gyro's times.
//! - **Known effects**: what the recording's `bench.gyro_model` states beyond the base terms
//!   (its `effect.*` keys, e.g. a simulated table's rate ripple) is taken out of the gyro's
//!   output first ([`bench_analysis::nominal`]).

use bench_analysis::angle_fit::TableReadings;
use bench_analysis::calibrate::TemperatureSeries;
use bench_analysis::diagnose::series::Native;
use bench_analysis::interp::interp_at;
use bench_analysis::nominal::effects_per_sample;
use bench_analysis::run::{StepEnd, StepSpan};
use bench_analysis::steady::{TableMotion, Unsteady};
use bench_analysis::temperature_rate::local_linear_rate;
use bench_analysis::RecordWindow;

use super::CalibrateError;
use crate::load::RunData;

/// Window of the angle-slope filter that gives the whole run's table rate for plots, s.
pub const TABLE_RATE_WINDOW_S: f64 = 20.0;

/// Steady parts of a record step shorter than this are not used as windows, s.
pub const MIN_WINDOW_S: f64 = 30.0;

/// A span of a record step left out, with its cause and the gyro samples in it.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowExclusion {
    /// The step's label.
    pub label: String,
    /// From, s.
    pub start_s: f64,
    /// Until, s.
    pub end_s: f64,
    /// Why: what the table was doing.
    pub why: Unsteady,
    /// Good gyro samples in it (left out).
    pub samples: usize,
}

/// One record window as found in the recording.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowSpan {
    /// Step label.
    pub label: String,
    /// Step index.
    pub step_index: u64,
    /// Start, s from the recording's time zero.
    pub start_s: f64,
    /// End, s from the time zero.
    pub end_s: f64,
    /// The step was aborted (or never ended): its data is kept, flagged.
    pub incomplete: bool,
    /// Gyro samples left out for a non-zero status.
    pub bad_samples: usize,
}

/// Everything the calibration needs from a recording.
#[derive(Debug, Clone)]
pub struct CalibrationData {
    /// The recording's arrays.
    pub run: RunData,
    /// Record windows, in time order, each with at least 2 good samples.
    pub windows: Vec<RecordWindow>,
    /// The table's angle readings over each window (same order), for the angle-domain fit.
    pub readings: Vec<TableReadings>,
    /// Where each window came from (same order as `windows`).
    pub spans: Vec<WindowSpan>,
    /// Record steps with no steady part long enough to use (label, good gyro samples in it).
    pub empty_windows: Vec<(String, usize)>,
    /// What the record steps hold outside their windows, in time order.
    pub exclusions: Vec<WindowExclusion>,
    /// The table's steady motion over the whole run.
    pub motion: TableMotion,
    /// The model temperature over the whole run (gyro sensor, else chamber air).
    pub temperature: TemperatureSeries,
    /// Chamber air over the whole run.
    pub chamber: TemperatureSeries,
    /// Whole-run table rate (slope of the angle, at the table's times), rad/s, for plots.
    pub table_rate_rad_s: Vec<f64>,
}

/// Table rate as the slope of its angle (module docs); empty for fewer than 3 samples.
fn angle_rate(time_s: &[f64], angle_rad: &[f64]) -> Result<Vec<f64>, CalibrateError> {
    if time_s.len() < 3 {
        return Ok(Vec::new());
    }
    Ok(local_linear_rate(time_s, angle_rad, TABLE_RATE_WINDOW_S)?)
}

/// The calibration's windows from the loader's arrays.
pub fn calibration_data(run: RunData) -> Result<CalibrationData, CalibrateError> {
    let s = &run.series;
    let table_rate = angle_rate(&s.table_time_s, &s.table_angle_rad)?;
    let chamber =
        TemperatureSeries { time_s: s.chamber_time_s.clone(), temp_c: s.chamber_temp_c.clone() };
    let temperature = match &s.gyro_temp_c {
        Some(t) => TemperatureSeries { time_s: s.gyro_time_s.clone(), temp_c: t.clone() },
        None => chamber.clone(),
    };
    let motion = TableMotion::fit(&s.table_time_s, &s.table_angle_rad, &s.table_rate_command_rad_s);
    let gyro_rate = without_known_effects(&run, &motion);
    let inputs = Inputs {
        run: &run,
        motion: &motion,
        chamber: &chamber,
        gyro_rate: &gyro_rate,
        samples: GyroSamples { time_s: &s.gyro_time_s, dt: run.gyro_dt_s },
    };
    let mut out = Collected::default();
    let record_steps = run.record_steps().count();
    for step in run.record_steps() {
        step_windows(&inputs, step, &mut out)?;
    }
    let Collected { windows, readings, spans, empty_windows, mut exclusions } = out;
    exclusions.sort_by(|x, y| x.start_s.total_cmp(&y.start_s));
    if record_steps == 0 {
        return Err(CalibrateError::NoRecordWindows { steps: s.steps.len() });
    }
    let table_rate_rad_s =
        if table_rate.is_empty() { vec![0.0; s.table_time_s.len()] } else { table_rate };
    Ok(CalibrationData {
        run,
        windows,
        readings,
        spans,
        empty_windows,
        exclusions,
        motion,
        temperature,
        chamber,
        table_rate_rad_s,
    })
}

/// The gyro's output with the effects the recording's model states (e.g. a simulated table's
/// rate ripple) taken out: known physics, removed before the base terms are fitted.
fn without_known_effects(run: &RunData, motion: &TableMotion) -> Vec<f64> {
    let s = &run.series;
    let known: Option<Vec<f64>> = run.model.as_ref().and_then(|m| {
        let stated = m.effects.without(bench_physics::effects::EffectId::EarthRate);
        if !stated.any() {
            return None;
        }
        let native = Native::build(s, motion, m.model.thermal_time_constant).ok()?;
        Some(effects_per_sample(&native, &m.model, &stated, s.axis_up, s.latitude_deg))
    });
    match &known {
        Some(k) => s.gyro_rate_rad_s.iter().zip(k).map(|(v, e)| v - e).collect(),
        None => s.gyro_rate_rad_s.clone(),
    }
}

/// The gyro's sample times and interval.
struct GyroSamples<'a> {
    time_s: &'a [f64],
    dt: f64,
}

impl GyroSamples<'_> {
    /// The samples (index range) whose whole interval `(t − dt, t]` lies in `[a, b]`.
    fn within(&self, a: f64, b: f64) -> (usize, usize) {
        let lo = self.time_s.partition_point(|&t| t - self.dt < a);
        let hi = self.time_s.partition_point(|&t| t <= b);
        (lo, hi.max(lo))
    }
}

/// What every record step's windows are cut from.
struct Inputs<'a> {
    run: &'a RunData,
    motion: &'a TableMotion,
    chamber: &'a TemperatureSeries,
    /// The gyro's output, known effects removed.
    gyro_rate: &'a [f64],
    samples: GyroSamples<'a>,
}

/// The windows and what was left out, as the record steps are cut.
#[derive(Default)]
struct Collected {
    windows: Vec<RecordWindow>,
    readings: Vec<TableReadings>,
    spans: Vec<WindowSpan>,
    empty_windows: Vec<(String, usize)>,
    exclusions: Vec<WindowExclusion>,
}

/// One record step: a window per steady part long enough, the rest excluded with its cause.
fn step_windows(
    inp: &Inputs<'_>,
    step: &StepSpan,
    out: &mut Collected,
) -> Result<(), CalibrateError> {
    let parts: Vec<(f64, f64, usize)> = inp
        .motion
        .steady_within(step.start_s, step.end_s)
        .into_iter()
        .filter(|(a, b, _)| b - a >= MIN_WINDOW_S)
        .collect();
    // Exclusions: the steady-motion rule's, plus steady parts too short to use.
    for e in inp.motion.exclusions(step.start_s, step.end_s) {
        let (lo, hi) = inp.samples.within(e.start_s, e.end_s);
        out.exclusions.push(WindowExclusion {
            label: step.label.clone(),
            start_s: e.start_s,
            end_s: e.end_s,
            why: e.why,
            samples: hi - lo,
        });
    }
    for (a, b, _) in inp.motion.steady_within(step.start_s, step.end_s) {
        if b - a < MIN_WINDOW_S {
            let (lo, hi) = inp.samples.within(a, b);
            out.exclusions.push(WindowExclusion {
                label: step.label.clone(),
                start_s: a,
                end_s: b,
                why: Unsteady::NotSteady,
                samples: hi - lo,
            });
        }
    }
    if parts.is_empty() {
        let (lo, hi) = inp.samples.within(step.start_s, step.end_s);
        out.empty_windows.push((step.label.clone(), hi - lo));
        return Ok(());
    }
    let many = parts.len() > 1;
    for (k, part) in parts.iter().copied().enumerate() {
        let label = if many {
            format!("{} [{}/{}]", step.label, k + 1, parts.len())
        } else {
            step.label.clone()
        };
        part_window(inp, step, label, part, out)?;
    }
    Ok(())
}

/// One steady part `(a, b, segment)` of a record step: its window (the glitches of the
/// table's readings left out) and the table's readings over it.
fn part_window(
    inp: &Inputs<'_>,
    step: &StepSpan,
    label: String,
    (a, b, seg): (f64, f64, usize),
    out: &mut Collected,
) -> Result<(), CalibrateError> {
    let (s, motion, dt) = (&inp.run.series, inp.motion, inp.samples.dt);
    let span = WindowSpan {
        label: label.clone(),
        step_index: step.index,
        start_s: a,
        end_s: b,
        incomplete: step.ended != StepEnd::End,
        bad_samples: inp.run.bad_gyro_samples_in(a, b),
    };
    let (lo, hi) = inp.samples.within(a, b);
    // The samples that overlap a glitch of the table's readings leave the window.
    let glitches = motion.glitches_within(a, b);
    for &(g0, g1) in &glitches {
        let (glo, ghi) = inp.samples.within(g0, g1);
        out.exclusions.push(WindowExclusion {
            label: step.label.clone(),
            start_s: g0,
            end_s: g1,
            why: Unsteady::Glitch,
            samples: (ghi.min(hi)).saturating_sub(glo.max(lo)),
        });
    }
    let keep: Vec<usize> = (lo..hi)
        .filter(|&k| {
            let t = s.gyro_time_s[k];
            !glitches.iter().any(|&(g0, g1)| t > g0 && t - dt < g1)
        })
        .collect();
    if keep.len() < 2 {
        out.empty_windows.push((label, keep.len()));
        return Ok(());
    }
    let time: Vec<f64> = keep.iter().map(|&k| s.gyro_time_s[k]).collect();
    let table: Vec<f64> = time.iter().map(|&t| motion.rate(t - 0.5 * dt).unwrap_or(0.0)).collect();
    let air = interp_at(&inp.chamber.time_s, &inp.chamber.temp_c, &time);
    let sensor = s.gyro_temp_c.as_ref().map(|g| keep.iter().map(|&k| g[k]).collect());
    let rate = keep.iter().map(|&k| inp.gyro_rate[k]).collect();
    // The window's input rate is its steady line's slope: that slope's error is one constant
    // shared by every window on the line.
    let w = RecordWindow::new(label, time, rate, table, sensor, air)
        .map_err(CalibrateError::Analysis)?
        .with_reference_error(seg, motion.segments[seg].rate_sigma_rad_s);
    // Block means: the full-rate Allan sums below the block over the window's blocks.
    let w = match &s.gyro_sub_block {
        Some(sub) => w.with_sub_block(sub.pooled(&keep)),
        None => w,
    };
    let (ta, tb) =
        (s.table_time_s.partition_point(|&t| t < a), s.table_time_s.partition_point(|&t| t <= b));
    // The angle-domain reference: the readout through the steady motion at the reading times;
    // its slope is off by the steady line's own error, the same σ the rate domain carries
    // (`rate_sigma_rad_s`: the readings' scatter, white or in blocks). A whole readout step
    // over the part (`quantum/T`, the bound used before) stated k_sf's angle-domain σ 2.4×
    // its scatter over 32 lab files.
    // A glitch's readings are off the line (whatever the table did there), so the line's
    // angle is compared with the gyro's integral only outside the glitches; across them the
    // gyro's samples the rate domain left out are integrated all the same.
    let in_glitch = |t: f64| glitches.iter().any(|&(g0, g1)| t >= g0 && t <= g1);
    let time_s: Vec<f64> =
        s.table_time_s[ta..tb].iter().copied().filter(|&t| !in_glitch(t)).collect();
    let angle_rad: Vec<f64> = time_s.iter().map(|&t| motion.angle(t).unwrap_or(f64::NAN)).collect();
    let mut left_out = Vec::new();
    let mut kept = keep.iter().peekable();
    for k in lo..hi {
        if kept.next_if_eq(&&k).is_none() {
            left_out.push((s.gyro_time_s[k], inp.gyro_rate[k]));
        }
    }
    out.readings.push(TableReadings {
        time_s,
        angle_rad,
        sigma_rad: 1e-9,
        drift_sigma_rad_s: motion.segments[seg].rate_sigma_rad_s,
        left_out,
    });
    out.windows.push(w);
    out.spans.push(span);
    Ok(())
}
