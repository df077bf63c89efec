//! From a recording to the analysis' inputs: record windows aligned on the gyro's time stamps,
//! the whole-run temperature series, the site and the recording's gyro model.
//!
//! - **Windows**: every step whose `start` event has a label beginning with `record`, from that
//!   event to the same step's `end` or `abort` event (or the last gyro sample, for a file cut
//!   short). Gyro samples with a non-zero `status` are left out and counted.
//! - **Alignment**: the gyro's `log_time` is the time base. Table rate and chamber air
//!   temperature are interpolated linearly between their own samples (held at the ends).
//! - **Table rate from the angle**: the input rate is the slope of the table's unwrapped angle
//!   over a centred [`TABLE_RATE_WINDOW_S`] window (`local_linear_rate`), not the measured-rate
//!   field. A table's angle readout is its precise quantity (1″ on an ST1300 class table: over
//!   20 s at 10 °/min the quantisation averages over ~12 000 steps), while its rate readout is
//!   an encoder difference whose noise (≈ 1e-6 rad/s) is ten times the gyro's own white noise
//!   at 20 Hz and would swamp the Allan deviation of `gyro − table`.
//! - **Model temperature**: the gyro's own sensor where every sample of the run carries one;
//!   otherwise chamber air. A gyro whose sensor reads only sometimes has the gaps filled
//!   linearly.

use std::collections::BTreeMap;

use bench_analysis::{
    calibrate::TemperatureSeries, temperature_rate::local_linear_rate, RecordWindow,
};
use bench_physics::GyroModel;

use crate::record::schema::{META_GYRO_MODEL, META_SITE, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_TABLE};
use crate::record::StepEvent;
use crate::recording::Recording;

use super::CalibrateError;

/// Window of the angle-slope filter that gives the table rate, s.
pub const TABLE_RATE_WINDOW_S: f64 = 20.0;

/// One record window as found in the recording.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowSpan {
    /// Step label.
    pub label: String,
    /// Step index.
    pub step_index: u64,
    /// Start, s from the recording's time origin.
    pub start_s: f64,
    /// End, s from the time origin.
    pub end_s: f64,
    /// The step was aborted (or never ended): its data is kept, flagged.
    pub incomplete: bool,
    /// Gyro samples left out for a non-zero status.
    pub bad_samples: usize,
}

/// Everything the calibration needs from a recording.
#[derive(Debug, Clone)]
pub struct CalibrationData {
    /// Record windows, in time order, each with at least 2 good samples.
    pub windows: Vec<RecordWindow>,
    /// Where each window came from (same order as `windows`).
    pub spans: Vec<WindowSpan>,
    /// Record steps with fewer than 2 good gyro samples (label, samples).
    pub empty_windows: Vec<(String, usize)>,
    /// The model temperature over the whole run (gyro sensor, else chamber air).
    pub temperature: TemperatureSeries,
    /// Whether `temperature` is the gyro's own sensor.
    pub gyro_sensor: bool,
    /// `bench.site` latitude, degrees north.
    pub latitude_deg: Option<f64>,
    /// `bench.site` axis: true for up (the default).
    pub axis_up: bool,
    /// `bench.gyro_model`, with keys the model does not know.
    pub model: Option<(GyroModel, BTreeMap<String, String>)>,
    /// Median gyro sample interval, s.
    pub gyro_dt_s: f64,
    /// Time origin: the first gyro sample's `log_time`, ns since the Unix epoch.
    pub origin_ns: u64,
    /// Whole-run gyro series (time s, rate rad/s), good samples only, for plots.
    pub gyro_time_s: Vec<f64>,
    /// Whole-run gyro rate, rad/s.
    pub gyro_rate_rad_s: Vec<f64>,
    /// Whole-run chamber air (time s, °C).
    pub chamber: TemperatureSeries,
    /// Whole-run table rate (time s, rad/s).
    pub table_time_s: Vec<f64>,
    /// Whole-run table rate (slope of the angle), rad/s.
    pub table_rate_rad_s: Vec<f64>,
}

/// Linear interpolation of `(xs, ys)` (xs non-decreasing) at increasing query points, held
/// constant outside the data.
struct Interp<'a> {
    xs: &'a [f64],
    ys: &'a [f64],
    i: usize,
}

impl<'a> Interp<'a> {
    fn new(xs: &'a [f64], ys: &'a [f64]) -> Self {
        Self { xs, ys, i: 0 }
    }
    fn at(&mut self, x: f64) -> f64 {
        let (xs, ys) = (self.xs, self.ys);
        let n = xs.len();
        if x <= xs[0] {
            return ys[0];
        }
        if x >= xs[n - 1] {
            return ys[n - 1];
        }
        while self.i + 1 < n && xs[self.i + 1] < x {
            self.i += 1;
        }
        // Restart when queried out of order (never in this module's use).
        if xs[self.i] > x {
            self.i = 0;
            return self.at(x);
        }
        let (x0, x1) = (xs[self.i], xs[self.i + 1]);
        let (y0, y1) = (ys[self.i], ys[self.i + 1]);
        if x1 > x0 {
            y0 + (y1 - y0) * (x - x0) / (x1 - x0)
        } else {
            y1
        }
    }
}

fn secs(ns: u64, origin: u64) -> f64 {
    (ns as f64 - origin as f64) * 1e-9
}

/// Metadata number, with the key named when it is not one.
fn meta_num(
    meta: &BTreeMap<String, String>,
    record: &'static str,
    key: &'static str,
) -> Result<Option<f64>, CalibrateError> {
    match meta.get(key) {
        None => Ok(None),
        Some(v) => v
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .map(Some)
            .ok_or_else(|| CalibrateError::BadMetadata { record, key, value: v.clone() }),
    }
}

/// `bench.site`: latitude (degrees north, if given) and whether the sensing axis points up
/// (the default), each checked against the contract.
pub fn site(rec: &Recording) -> Result<(Option<f64>, bool), CalibrateError> {
    let Some(site) = rec.metadata(META_SITE) else { return Ok((None, true)) };
    let lat = meta_num(site, META_SITE, "latitude_deg")?;
    if let Some(l) = lat.filter(|l| !(-90.0..=90.0).contains(l)) {
        return Err(CalibrateError::BadMetadata {
            record: META_SITE,
            key: "latitude_deg",
            value: l.to_string(),
        });
    }
    let axis_up = match site.get("axis").map(|a| a.trim()) {
        None | Some("up") => true,
        Some("down") => false,
        Some(other) => {
            return Err(CalibrateError::BadMetadata {
                record: META_SITE,
                key: "axis",
                value: other.to_owned(),
            })
        }
    };
    Ok((lat, axis_up))
}

/// Table rate as the slope of its angle (module docs); empty for fewer than 3 samples.
fn angle_rate(time_s: &[f64], angle_rad: &[f64]) -> Result<Vec<f64>, CalibrateError> {
    if time_s.len() < 3 {
        return Ok(Vec::new());
    }
    Ok(local_linear_rate(time_s, angle_rad, TABLE_RATE_WINDOW_S)?)
}

/// Keep only strictly increasing times (a duplicate time stamp keeps its first sample).
pub(crate) fn strictly_increasing(t: &mut Vec<f64>, cols: &mut [&mut Vec<f64>]) {
    let mut keep = 0;
    for i in 0..t.len() {
        if keep == 0 || t[i] > t[keep - 1] {
            t[keep] = t[i];
            for c in cols.iter_mut() {
                c[keep] = c[i];
            }
            keep += 1;
        }
    }
    t.truncate(keep);
    for c in cols.iter_mut() {
        c.truncate(keep);
    }
}

/// Extract the calibration inputs from `rec`.
pub fn calibration_data(rec: &Recording) -> Result<CalibrationData, CalibrateError> {
    for (topic, n) in [
        (TOPIC_GYRO, rec.gyro.len()),
        (TOPIC_TABLE, rec.table.len()),
        (TOPIC_CHAMBER, rec.chamber.len()),
    ] {
        if n < 2 {
            return Err(CalibrateError::MissingChannel { topic, messages: n });
        }
    }
    let origin_ns = rec.gyro[0].log_time_ns;

    // Site and model.
    let (latitude_deg, axis_up) = site(rec)?;
    let model = rec
        .metadata(META_GYRO_MODEL)
        .map(GyroModel::from_metadata)
        .transpose()
        .map_err(CalibrateError::BadModel)?;

    // Whole-run series.
    let mut gyro_time_s = Vec::with_capacity(rec.gyro.len());
    let mut gyro_rate = Vec::with_capacity(rec.gyro.len());
    let mut gyro_temp = Vec::with_capacity(rec.gyro.len());
    let mut sensor_all = true;
    for g in rec.gyro.iter().filter(|g| g.msg.status == 0 && g.msg.rate_rad_s.is_finite()) {
        gyro_time_s.push(secs(g.log_time_ns, origin_ns));
        gyro_rate.push(g.msg.rate_rad_s);
        match g.msg.temperature_c.filter(|t| t.is_finite()) {
            Some(t) => gyro_temp.push(t),
            None => {
                sensor_all = false;
                gyro_temp.push(f64::NAN);
            }
        }
    }
    strictly_increasing(&mut gyro_time_s, &mut [&mut gyro_rate, &mut gyro_temp]);
    if gyro_time_s.len() < 2 {
        return Err(CalibrateError::MissingChannel {
            topic: TOPIC_GYRO,
            messages: gyro_time_s.len(),
        });
    }
    let mut dts: Vec<f64> = gyro_time_s.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let gyro_dt_s = dts[dts.len() / 2];

    let mut table_time_s = Vec::with_capacity(rec.table.len());
    let mut table_angle = Vec::with_capacity(rec.table.len());
    for t in rec.table.iter().filter(|t| t.msg.angle_rad.is_finite()) {
        table_time_s.push(secs(t.log_time_ns, origin_ns));
        table_angle.push(t.msg.angle_rad);
    }
    strictly_increasing(&mut table_time_s, &mut [&mut table_angle]);
    // Whole-run rate, for plots; windows use their own samples only (below).
    let table_rate = angle_rate(&table_time_s, &table_angle)?;
    let mut air_time_s = Vec::with_capacity(rec.chamber.len());
    let mut air_c = Vec::with_capacity(rec.chamber.len());
    for c in rec.chamber.iter().filter(|c| c.msg.temperature_c.is_finite()) {
        air_time_s.push(secs(c.log_time_ns, origin_ns));
        air_c.push(c.msg.temperature_c);
    }
    strictly_increasing(&mut air_time_s, &mut [&mut air_c]);
    for (topic, n) in [(TOPIC_TABLE, table_time_s.len()), (TOPIC_CHAMBER, air_time_s.len())] {
        if n < 2 {
            return Err(CalibrateError::MissingChannel { topic, messages: n });
        }
    }

    // The gyro's sensor, gaps filled, if it reads at all.
    let sensor_readings = gyro_temp.iter().filter(|t| t.is_finite()).count();
    let gyro_sensor = sensor_readings >= 2 && (sensor_all || sensor_readings * 2 > gyro_temp.len());
    if gyro_sensor && !sensor_all {
        let (ts, vs): (Vec<f64>, Vec<f64>) = gyro_time_s
            .iter()
            .zip(&gyro_temp)
            .filter(|(_, v)| v.is_finite())
            .map(|(t, v)| (*t, *v))
            .unzip();
        let mut it = Interp::new(&ts, &vs);
        for (t, v) in gyro_time_s.iter().zip(gyro_temp.iter_mut()) {
            if !v.is_finite() {
                *v = it.at(*t);
            }
        }
    }
    let chamber = TemperatureSeries { time_s: air_time_s, temp_c: air_c };
    let temperature = if gyro_sensor {
        TemperatureSeries { time_s: gyro_time_s.clone(), temp_c: gyro_temp.clone() }
    } else {
        chamber.clone()
    };

    // Record steps.
    let mut steps = rec.steps.clone();
    steps.sort_by_key(|s| s.log_time_ns);
    let last_ns = rec.gyro.last().map_or(origin_ns, |g| g.log_time_ns);
    let mut spans = Vec::new();
    for (i, s) in steps.iter().enumerate() {
        if s.msg.event != StepEvent::Start || !s.msg.label.starts_with("record") {
            continue;
        }
        let end = steps[i + 1..]
            .iter()
            .find(|e| e.msg.index == s.msg.index && e.msg.event != StepEvent::Start);
        let (end_ns, incomplete) = match end {
            Some(e) => (e.log_time_ns, e.msg.event == StepEvent::Abort),
            None => (last_ns, true),
        };
        spans.push(WindowSpan {
            label: s.msg.label.clone(),
            step_index: s.msg.index,
            start_s: secs(s.log_time_ns, origin_ns),
            end_s: secs(end_ns, origin_ns),
            incomplete,
            bad_samples: rec
                .gyro
                .iter()
                .filter(|g| g.log_time_ns > s.log_time_ns && g.log_time_ns <= end_ns)
                .filter(|g| g.msg.status != 0)
                .count(),
        });
    }
    if spans.is_empty() {
        return Err(CalibrateError::NoRecordWindows { steps: rec.steps.len() });
    }

    let mut windows = Vec::new();
    let mut kept_spans = Vec::new();
    let mut empty_windows = Vec::new();
    let mut table_it = Interp::new(&table_time_s, &table_rate);
    let mut air_it = Interp::new(&chamber.time_s, &chamber.temp_c);
    for span in spans {
        let lo = gyro_time_s.partition_point(|&t| t <= span.start_s);
        let hi = gyro_time_s.partition_point(|&t| t <= span.end_s);
        if hi < lo + 2 {
            empty_windows.push((span.label.clone(), hi.saturating_sub(lo)));
            continue;
        }
        let time: Vec<f64> = gyro_time_s[lo..hi].to_vec();
        // The angle slope from the window's own table samples: a centred filter reaching past
        // the window's end would mix in the stop that follows it.
        let (a, b) = (
            table_time_s.partition_point(|&t| t < span.start_s),
            table_time_s.partition_point(|&t| t <= span.end_s),
        );
        let win_rate = angle_rate(&table_time_s[a..b], &table_angle[a..b])?;
        let table: Vec<f64> = if win_rate.is_empty() {
            table_it.i = 0;
            time.iter().map(|&t| table_it.at(t)).collect()
        } else {
            let mut it = Interp::new(&table_time_s[a..b], &win_rate);
            time.iter().map(|&t| it.at(t)).collect()
        };
        air_it.i = 0;
        let air: Vec<f64> = time.iter().map(|&t| air_it.at(t)).collect();
        let sensor = gyro_sensor.then(|| gyro_temp[lo..hi].to_vec());
        let w = RecordWindow::new(
            span.label.clone(),
            time,
            gyro_rate[lo..hi].to_vec(),
            table,
            sensor,
            air,
        )
        .map_err(CalibrateError::Analysis)?;
        windows.push(w);
        kept_spans.push(span);
    }

    Ok(CalibrationData {
        windows,
        spans: kept_spans,
        empty_windows,
        temperature,
        gyro_sensor,
        latitude_deg,
        axis_up,
        model,
        gyro_dt_s,
        origin_ns,
        gyro_time_s,
        gyro_rate_rad_s: gyro_rate,
        chamber,
        table_rate_rad_s: if table_rate.is_empty() {
            vec![0.0; table_time_s.len()]
        } else {
            table_rate
        },
        table_time_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_linear_inside_and_held_outside() {
        let xs = [0.0, 1.0, 3.0];
        let ys = [0.0, 10.0, 30.0];
        let mut it = Interp::new(&xs, &ys);
        assert_eq!(it.at(-1.0), 0.0);
        assert_eq!(it.at(0.5), 5.0);
        assert_eq!(it.at(2.0), 20.0);
        assert_eq!(it.at(5.0), 30.0);
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
