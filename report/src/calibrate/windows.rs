//! Record windows for the calibration, from the shared loader's arrays ([`crate::load`]).
//!
//! - **Windows**: every `record …` step, its gyro samples in `(start, end]`.
//! - **Table rate from the angle**: the input rate is the slope of the table's unwrapped angle
//!   over a centred [`TABLE_RATE_WINDOW_S`] window (`local_linear_rate`) of the window's own
//!   table samples, not the measured-rate field. A table's angle readout is its precise
//!   quantity (1″ on an ST1300 class table: over 20 s at 10 °/min the quantisation averages over
//!   ~12 000 steps), while its rate readout is an encoder difference whose noise (≈ 1e-6 rad/s)
//!   is ten times the gyro's own white noise at 20 Hz and would swamp the Allan deviation of
//!   `gyro − table`.
//! - **Model temperature**: the gyro's own sensor where it has one (the loader's rule);
//!   otherwise chamber air, interpolated at the gyro's times.

use bench_analysis::calibrate::TemperatureSeries;
use bench_analysis::interp::{interp_at, Cursor};
use bench_analysis::run::StepEnd;
use bench_analysis::temperature_rate::local_linear_rate;
use bench_analysis::RecordWindow;

use super::CalibrateError;
use crate::load::RunData;

/// Window of the angle-slope filter that gives the table rate, s.
pub const TABLE_RATE_WINDOW_S: f64 = 20.0;

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
    /// Where each window came from (same order as `windows`).
    pub spans: Vec<WindowSpan>,
    /// Record steps with fewer than 2 good gyro samples (label, samples).
    pub empty_windows: Vec<(String, usize)>,
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

    let mut windows = Vec::new();
    let mut spans = Vec::new();
    let mut empty_windows = Vec::new();
    for step in run.record_steps() {
        let span = WindowSpan {
            label: step.label.clone(),
            step_index: step.index,
            start_s: step.start_s,
            end_s: step.end_s,
            incomplete: step.ended != StepEnd::End,
            bad_samples: run.bad_gyro_samples_in(step.start_s, step.end_s),
        };
        let lo = s.gyro_time_s.partition_point(|&t| t <= span.start_s);
        let hi = s.gyro_time_s.partition_point(|&t| t <= span.end_s);
        if hi < lo + 2 {
            empty_windows.push((span.label.clone(), hi.saturating_sub(lo)));
            continue;
        }
        let time: Vec<f64> = s.gyro_time_s[lo..hi].to_vec();
        // The angle slope from the window's own table samples: a centred filter reaching past
        // the window's end would mix in the stop that follows it.
        let (a, b) = (
            s.table_time_s.partition_point(|&t| t < span.start_s),
            s.table_time_s.partition_point(|&t| t <= span.end_s),
        );
        let win_rate = angle_rate(&s.table_time_s[a..b], &s.table_angle_rad[a..b])?;
        let table = if win_rate.is_empty() {
            let mut c = Cursor::new(&s.table_time_s, &table_rate);
            time.iter().map(|&t| c.at(t)).collect()
        } else {
            interp_at(&s.table_time_s[a..b], &win_rate, &time)
        };
        let air = interp_at(&chamber.time_s, &chamber.temp_c, &time);
        let sensor = s.gyro_temp_c.as_ref().map(|g| g[lo..hi].to_vec());
        let w = RecordWindow::new(
            span.label.clone(),
            time,
            s.gyro_rate_rad_s[lo..hi].to_vec(),
            table,
            sensor,
            air,
        )
        .map_err(CalibrateError::Analysis)?;
        windows.push(w);
        spans.push(span);
    }
    if spans.is_empty() && empty_windows.is_empty() {
        return Err(CalibrateError::NoRecordWindows { steps: s.steps.len() });
    }
    let table_rate_rad_s =
        if table_rate.is_empty() { vec![0.0; s.table_time_s.len()] } else { table_rate };
    Ok(CalibrationData {
        run,
        windows,
        spans,
        empty_windows,
        temperature,
        chamber,
        table_rate_rad_s,
    })
}
