//! The procedure [`super`] designs: chamber sweeps between two temperatures at one ramp rate,
//! the table reversing at a fixed period throughout, optional holds at the ends; written as a
//! scenario and laid out as the samples the calibration would fit.

use std::fmt::Write as _;

use bench_analysis::calibrate::{lag_nuisance, model_series_windows, TemperatureSeries};
use bench_analysis::joint_fit::Nuisance;
use bench_analysis::RecordWindow;
use bench_physics::units::DEG_PER_MIN;
use bench_physics::GyroModel;

/// Time after each reversal before recording (the table has reached its rate; the
/// calibration's steady rule trims the rest), s.
pub const SETTLE_S: f64 = 30.0;

/// The shortest record window a candidate may have, s.
pub const MIN_RECORD_S: f64 = 120.0;

/// The smoothing window of the model temperature's rate, s (the calibration's default).
pub const RATE_WINDOW_S: f64 = 60.0;

/// One candidate procedure: what the design varies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Procedure {
    /// Low and high end of the sweeps, °C.
    pub range_c: (f64, f64),
    /// Sweep rate, °C/min (both signs: legs alternate up and down).
    pub ramp_c_min: f64,
    /// Number of sweeps (legs) between the ends; the first goes up.
    pub legs: usize,
    /// Table rate magnitude, °/min.
    pub table_deg_min: f64,
    /// Time between table reversals (record window plus reversal), min.
    pub reversal_min: f64,
    /// Hold at each end after a sweep, recorded, min (0: none).
    pub hold_min: f64,
    /// Table acceleration, °/s².
    pub accel_deg_s2: f64,
    /// Chamber (and gyro) temperature at the start, °C.
    pub initial_c: f64,
    /// Ramp of the unrecorded move from the start to the low end, °C/min (the chamber's
    /// fastest cooling or heating).
    pub transit_c_min: f64,
}

/// One record window of the timeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Label of the record step.
    pub label: String,
    /// Start and end, s from the start of the run (nominal).
    pub span_s: (f64, f64),
    /// Table rate, rad/s (cw negative).
    pub rate_rad_s: f64,
    /// The record step lasts until the ramp ends (the last of a sweep).
    pub to_ramp_end: bool,
}

/// A step of the scenario, in order.
#[derive(Debug, Clone, PartialEq)]
enum Step {
    Chamber { to_c: f64, ramp_c_min: f64 },
    WaitRampEnd,
    Spin { cw: bool },
    Settle,
    Record(usize),
    Stop,
}

/// The nominal timeline of a procedure.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// The chamber's air temperature: knots (s, °C), linear between.
    pub air: Vec<(f64, f64)>,
    /// The record windows.
    pub segments: Vec<Segment>,
    steps: Vec<Step>,
    /// Chamber time, s (start to the end of the last window).
    pub duration_s: f64,
}

impl Procedure {
    /// Time of one reversal plus the settling after it, s.
    pub fn overhead_s(&self) -> f64 {
        2.0 * self.table_deg_min / 60.0 / self.accel_deg_s2 + SETTLE_S
    }

    /// The timeline, or `None` when a record window would be shorter than [`MIN_RECORD_S`].
    pub fn timeline(&self) -> Option<Timeline> {
        let (lo, hi) = self.range_c;
        let o = self.overhead_s();
        let rate = self.table_deg_min * DEG_PER_MIN;
        let mut t = 0.0;
        let mut air = vec![(0.0, self.initial_c)];
        let mut steps = Vec::new();
        let mut segments = Vec::new();
        if (self.initial_c - lo).abs() > 1e-9 {
            let d = (self.initial_c - lo).abs() / (self.transit_c_min / 60.0);
            steps.push(Step::Chamber { to_c: lo, ramp_c_min: self.transit_c_min });
            steps.push(Step::WaitRampEnd);
            t += d;
            air.push((t, lo));
        }
        let mut cw = true;
        // Windows over `len_s` starting at `t`, each `P − overhead` long; the last of a sweep
        // lasts until the ramp ends.
        let mut windows =
            |t: f64, len_s: f64, what: &str, ramp: bool, steps: &mut Vec<Step>, cw: &mut bool| {
                let m = (len_s / (self.reversal_min * 60.0)).round().max(1.0);
                let rec = len_s / m - o;
                if rec < MIN_RECORD_S {
                    return false;
                }
                for k in 0..m as usize {
                    let start = t + k as f64 * (rec + o);
                    steps.push(Step::Spin { cw: *cw });
                    steps.push(Step::Settle);
                    let dir = if *cw { "cw" } else { "ccw" };
                    segments.push(Segment {
                        label: format!("record {dir} {what} [{}]", k + 1),
                        span_s: (start + o, start + o + rec),
                        rate_rad_s: if *cw { -rate } else { rate },
                        to_ramp_end: ramp && k + 1 == m as usize,
                    });
                    steps.push(Step::Record(segments.len() - 1));
                    *cw = !*cw;
                }
                true
            };
        for leg in 0..self.legs {
            let (from, to) = if leg % 2 == 0 { (lo, hi) } else { (hi, lo) };
            let d = (hi - lo) / (self.ramp_c_min / 60.0);
            steps.push(Step::Chamber { to_c: to, ramp_c_min: self.ramp_c_min });
            let what = format!("ramp {from}C to {to}C");
            if !windows(t, d, &what, true, &mut steps, &mut cw) {
                return None;
            }
            t += d;
            air.push((t, to));
            if self.hold_min > 0.0 {
                let h = self.hold_min * 60.0;
                if !windows(t, h, &format!("hold {to}C"), false, &mut steps, &mut cw) {
                    return None;
                }
                t += h;
                air.push((t, to));
            }
        }
        steps.push(Step::Stop);
        Some(Timeline { air, segments, steps, duration_s: t })
    }
}

impl Timeline {
    /// Air temperature at `t`, °C.
    fn air_at(&self, t: f64) -> f64 {
        let i = self.air.partition_point(|k| k.0 <= t);
        match (self.air.get(i.wrapping_sub(1)), self.air.get(i)) {
            (Some(a), Some(b)) if b.0 > a.0 => a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0),
            (Some(a), _) => a.1,
            (None, Some(b)) => b.1,
            (None, None) => f64::NAN,
        }
    }

    /// The record windows as the calibration fits them, sampled every `dt_s` (white noise's
    /// information does not depend on it: each sample's variance is `N²/dt`), with the model
    /// temperature (the air through the gyro's lag `tau_s`, smoothed as the calibration does);
    /// with `lag_fitted` (no gyro sensor: the lag is estimated from the air) the lag's
    /// nuisance column under `model`'s coefficients.
    pub fn windows(
        &self,
        dt_s: f64,
        model: &GyroModel,
        lag_fitted: bool,
    ) -> Option<(Vec<RecordWindow>, Option<Nuisance>)> {
        let n = (self.duration_s / dt_s).ceil() as usize + 1;
        let time: Vec<f64> = (0..n).map(|i| i as f64 * dt_s).collect();
        let air = TemperatureSeries {
            temp_c: time.iter().map(|&t| self.air_at(t)).collect(),
            time_s: time,
        };
        let tau = model.thermal_time_constant;
        let gyro = if tau > 0.0 { air.lagged(tau) } else { air.clone() };
        let mut windows = Vec::with_capacity(self.segments.len());
        for s in &self.segments {
            let k = ((s.span_s.1 - s.span_s.0) / dt_s).floor() as usize;
            let t: Vec<f64> = (0..=k).map(|i| s.span_s.0 + i as f64 * dt_s).collect();
            let g = gyro.sample(&t);
            let a = air.sample(&t);
            let w = RecordWindow::new(
                s.label.clone(),
                t.clone(),
                vec![0.0; t.len()],
                vec![s.rate_rad_s; t.len()],
                (!lag_fitted).then_some(g),
                a,
            )
            .ok()?;
            windows.push(w);
        }
        let model_windows = model_series_windows(&windows, &gyro, RATE_WINDOW_S);
        let nuisance = if lag_fitted && tau > 0.0 {
            let c = [model.bias, model.scale_factor_error, model.temp_coeff, model.temp_rate_coeff];
            Some(lag_nuisance(&model_windows, &air, tau, c, RATE_WINDOW_S)?)
        } else {
            None
        };
        Some((model_windows, nuisance))
    }

    /// The scenario TOML: `header` (comment lines) first, then `[scenario]`, the site, the
    /// gyro and its model, and the steps.
    pub fn scenario(
        &self,
        p: &Procedure,
        name: &str,
        header: &str,
        setup: &ScenarioSetup,
    ) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let _ = writeln!(out, "# {line}");
        }
        let _ = writeln!(
            out,
            "\n[scenario]\nname = \"{name}\"\ndescription = \"Designed by bench design: {} sweeps \
             {lo}..{hi} °C at ±{r} °C/min, table ±{w} °/min reversed every {rev} min, holds {h} \
             min.\"\n",
            p.legs,
            lo = p.range_c.0,
            hi = p.range_c.1,
            r = p.ramp_c_min,
            w = p.table_deg_min,
            rev = p.reversal_min,
            h = p.hold_min,
        );
        let _ = writeln!(
            out,
            "[site]\nlatitude_deg = {}\naxis = \"{}\"\n",
            setup.latitude_deg,
            if setup.axis_up { "up" } else { "down" }
        );
        let _ = writeln!(out, "[gyro]\nsample_rate = \"{} Hz\"\n", setup.sample_rate_hz);
        let _ = writeln!(out, "[gyro.model]");
        for (k, v) in setup.model.to_metadata() {
            let value = if k == "earth_rate" { (v == "1" || v == "true").to_string() } else { v };
            let _ = writeln!(out, "{k} = {value}");
        }
        let _ = writeln!(out, "\n[table]\naccel = \"{} °/s²\"\n", p.accel_deg_s2);
        let _ = writeln!(out, "[simulation]\ninitial_temp = \"{} °C\"\n", p.initial_c);
        let _ = writeln!(
            out,
            "[safe]\ndecel = \"{} °/s²\"\ntemperature = \"{} °C\"\n",
            p.accel_deg_s2, p.initial_c
        );
        let mut spin = String::new();
        for s in &self.steps {
            let body = match s {
                Step::Chamber { to_c, ramp_c_min } => {
                    format!("label = \"to {to_c}C\"\nchamber = \"{to_c} °C\"\nramp = \"{ramp_c_min} °C/min\"")
                }
                Step::WaitRampEnd => "label = \"reach the low end\"\nwait = \"ramp end\"".into(),
                Step::Spin { cw } => {
                    spin = if *cw { "cw" } else { "ccw" }.into();
                    format!(
                        "label = \"spin {spin}\"\nspin = \"{} °/min\"\ndirection = \"{spin}\"",
                        p.table_deg_min
                    )
                }
                Step::Settle => format!("label = \"settle {spin}\"\nwait = \"{SETTLE_S} s\""),
                Step::Record(i) => {
                    let seg = &self.segments[*i];
                    if seg.to_ramp_end {
                        format!("label = \"{}\"\nrecord = \"ramp end\"", seg.label)
                    } else {
                        let len = seg.span_s.1 - seg.span_s.0;
                        format!("label = \"{}\"\nrecord = \"{len:.1} s\"", seg.label)
                    }
                }
                Step::Stop => "label = \"stop\"\nstop = \"table\"".into(),
            };
            let _ = writeln!(out, "[[step]]\n{body}\n");
        }
        out
    }
}

/// What a designed scenario says beyond the procedure.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioSetup {
    /// Site latitude, degrees.
    pub latitude_deg: f64,
    /// Sensing axis up.
    pub axis_up: bool,
    /// Gyro output rate, Hz.
    pub sample_rate_hz: f64,
    /// The gyro's model (written as `[gyro.model]`, and so the simulator's truth).
    pub model: GyroModel,
}
