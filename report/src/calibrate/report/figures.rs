//! The report's figures, as plot descriptions computed from a [`CalibrationOutcome`].
//!
//! Units: rates in °/h, temperatures in °C, dT/dt in °C/min, time in hours from the first gyro
//! sample, τ in s.

use bench_analysis::calibrate::{thermal_bias, WindowKind};
use bench_analysis::temperature_rate::local_linear_rate;
use bench_analysis::Direction;
use bench_physics::allan::{AdevPoint, NoiseType};
use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::GyroModel;

use super::series::{bins, decimate, rms};
use crate::calibrate::CalibrationOutcome;
use crate::display;
use crate::render::plot::{colour, Axis, Item, Marker, MarkerPoint, Plot, Span};
pub(super) use crate::render::Figure;

/// Most points of a whole-run curve.
const MAX_POINTS: usize = 4000;
/// Bin width of residual and thermal-error curves, s (shorter for windows under 10 bins).
const BIN_S: f64 = 60.0;
/// Size of a one-panel figure, px.
const ONE: (u32, u32) = (960, 540);
/// Size of a two-panel figure, px.
const TWO: (u32, u32) = (1280, 540);

fn deg_h(x: f64) -> f64 {
    display::RATE.of(x)
}

fn hours(t: f64) -> f64 {
    display::HOURS.of(t)
}

/// Earth's rate along the sensing axis that the calibration removed, rad/s.
fn earth(o: &CalibrationOutcome) -> f64 {
    let opts = &o.calibration.options;
    opts.joint.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, opts.joint.axis_up))
}

/// Kind of window `i` of `data.spans` / `model_windows`: by position (the calibration keeps
/// the windows' order), or by label should the counts ever differ.
fn kind_of(o: &CalibrationOutcome, i: usize, label: &str) -> Option<WindowKind> {
    let ws = &o.calibration.windows;
    if ws.len() == o.calibration.model_windows.len() && ws.len() == o.data.spans.len() {
        ws.get(i).map(|w| w.kind)
    } else {
        ws.iter().find(|w| w.label == label).map(|w| w.kind)
    }
}

fn kind_name(k: Option<WindowKind>) -> (&'static str, plotters::style::RGBColor) {
    match k {
        Some(WindowKind::Plateau) => ("plateau window", colour::GREEN),
        Some(WindowKind::Ramp) => ("ramp window", colour::ORANGE),
        Some(WindowKind::Static) => ("static window", colour::GREY),
        None => ("record window", colour::SKY),
    }
}

/// The record windows as shaded spans on a time axis in hours.
fn window_spans(o: &CalibrationOutcome) -> Vec<Span> {
    o.data
        .spans
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let (label, colour) = kind_name(kind_of(o, i, &s.label));
            Span { x0: hours(s.start_s), x1: hours(s.end_s), colour, label: label.into() }
        })
        .collect()
}

fn line(label: Option<&str>, colour: plotters::style::RGBColor, points: Vec<(f64, f64)>) -> Item {
    Item::Line { label: label.map(str::to_owned), colour, width: 2, dashed: false, points }
}

fn dashed(label: Option<&str>, colour: plotters::style::RGBColor, points: Vec<(f64, f64)>) -> Item {
    Item::Line { label: label.map(str::to_owned), colour, width: 2, dashed: true, points }
}

/// Means of `v` over a window's equal bins of at most [`BIN_S`] (at least 10 bins), the last
/// one ending at the last sample, so no bin is a stub of a few samples.
fn window_bins(t: &[f64], v: &[f64]) -> Vec<super::series::Bin> {
    let dur = match (t.first(), t.last()) {
        (Some(a), Some(b)) => b - a,
        _ => return Vec::new(),
    };
    let n = (dur / BIN_S).ceil().max(10.0);
    bins(t, v, (dur / n * (1.0 + 1e-9)).max(1e-3))
}

/// All figures, in report order.
pub(super) fn figures(o: &CalibrationOutcome) -> Vec<Figure> {
    vec![
        raw_rate(o),
        temperature(o),
        temperature_rate(o),
        cw_ccw(o),
        error_functions(o),
        thermal_error(o),
        residual(o),
        allan(o),
        misclosure(o),
    ]
}

/// Angle misclosure per stretch (gyro integral minus the table's angle), before calibration
/// (Earth's rate only removed) and after (the angle-domain model and each stretch's offset
/// removed), arcseconds against time.
fn misclosure(o: &CalibrationOutcome) -> Figure {
    let arcsec = |v: f64| display::ARC_SECONDS.of(v);
    let mut before = Plot::new(
        "Before calibration",
        Axis::linear("time, h"),
        Axis::linear("angle misclosure, ″"),
    );
    let mut after = Plot::new(
        "After calibration",
        Axis::linear("time, h"),
        Axis::linear("angle misclosure, ″"),
    );
    before.spans = window_spans(o);
    after.spans = window_spans(o);
    let mut caption = String::from(
        "The seed's navigation check: over each steady stretch, the integrated gyro output minus \
         the table's angle (its readout through the steady line). Before: only Earth's rate \
         removed, so the bias, scale factor and thermal terms build up; after: the angle-domain \
         fit's model and each stretch's free offset removed, leaving the integrated noise.",
    );
    match o.calibration.angle.as_ref() {
        Some(Ok(a)) => {
            let n = a.misclosure.len().max(1);
            let per = (MAX_POINTS / n).max(8);
            for (k, m) in a.misclosure.iter().enumerate() {
                let b = decimate(&m.time_s, &m.before_rad, per);
                let c = decimate(&m.time_s, &m.after_rad, per);
                before.items.push(line(
                    (k == 0).then_some("bin mean"),
                    colour::ORANGE,
                    b.iter().map(|b| (hours(b.t), arcsec(b.mean))).collect(),
                ));
                after.items.push(line(
                    (k == 0).then_some("bin mean"),
                    colour::BLUE,
                    c.iter().map(|b| (hours(b.t), arcsec(b.mean))).collect(),
                ));
            }
            let (rb, ra) = a.misclosure_rms();
            let r = |v: f64| crate::render::sig(arcsec(v), 3);
            before.note = Some(format!("RMS {} ″", r(rb)));
            after.note = Some(format!("RMS {} ″", r(ra)));
            caption.push_str(&format!(
                " {} stretches, {} readings; RMS {} ″ before, {} ″ after.",
                a.stretches,
                a.readings,
                r(rb),
                r(ra)
            ));
        }
        Some(Err(e)) => {
            before.note = Some(format!("no angle-domain fit: {e}"));
            after.note = before.note.clone();
        }
        None => {
            before.note = Some("no table angle readings".into());
            after.note = before.note.clone();
        }
    }
    Figure {
        name: "fig9-angle-misclosure",
        title: "Angle misclosure",
        caption,
        panels: vec![before, after],
        size: TWO,
    }
}

fn raw_rate(o: &CalibrationOutcome) -> Figure {
    let d = &o.data;
    let mut p = Plot::new("Gyro output", Axis::linear("time, h"), Axis::linear("rate, °/h"));
    p.spans = window_spans(o);
    let g = decimate(&d.run.series.gyro_time_s, &d.run.series.gyro_rate_rad_s, MAX_POINTS);
    let width = match (d.run.series.gyro_time_s.first(), d.run.series.gyro_time_s.last()) {
        (Some(a), Some(b)) => (b - a) / MAX_POINTS as f64,
        _ => 0.0,
    };
    p.items.push(Item::Band {
        label: Some("gyro, min–max per bin".into()),
        colour: colour::SKY,
        points: g.iter().map(|b| (hours(b.t), deg_h(b.min), deg_h(b.max))).collect(),
    });
    p.items.push(line(
        Some("gyro, bin mean"),
        colour::BLUE,
        g.iter().map(|b| (hours(b.t), deg_h(b.mean))).collect(),
    ));
    let t = decimate(&d.run.series.table_time_s, &d.table_rate_rad_s, MAX_POINTS);
    p.items.push(Item::Line {
        label: Some("table rate".into()),
        colour: colour::BLACK,
        width: 1,
        dashed: false,
        points: t.iter().map(|b| (hours(b.t), deg_h(b.mean))).collect(),
    });
    if d.run.series.gyro_time_s.is_empty() {
        p.note = Some("no gyro samples".into());
    }
    Figure {
        name: "fig1-raw-rate",
        title: "Raw gyro rate",
        caption: format!(
            "Gyro output over the run ({} good samples), shown as means of {:.1} s bins with \
             each bin's min–max envelope; the measured table rate for reference. Shaded: record \
             windows by kind.",
            d.run.series.gyro_time_s.len(),
            width.max(0.0)
        ),
        panels: vec![p],
        size: ONE,
    }
}

fn temp_source(o: &CalibrationOutcome) -> &'static str {
    if o.data.run.gyro_sensor() {
        "gyro sensor"
    } else {
        "chamber air"
    }
}

/// Whether the calibration used a lagged model temperature.
fn lag_used(o: &CalibrationOutcome) -> Option<f64> {
    match &o.calibration.lag {
        Some(Ok(l)) if l.used_s > 0.0 => Some(l.used_s),
        _ => None,
    }
}

fn temperature(o: &CalibrationOutcome) -> Figure {
    let d = &o.data;
    let mut p =
        Plot::new("Temperature profile", Axis::linear("time, h"), Axis::linear("temperature, °C"));
    p.spans = window_spans(o);
    let air = decimate(&d.chamber.time_s, &d.chamber.temp_c, MAX_POINTS);
    p.items.push(line(
        Some("chamber air"),
        colour::RED,
        air.iter().map(|b| (hours(b.t), b.mean)).collect(),
    ));
    if d.run.gyro_sensor() {
        let g = decimate(&d.temperature.time_s, &d.temperature.temp_c, MAX_POINTS);
        p.items.push(line(
            Some("gyro sensor (model temperature)"),
            colour::BLUE,
            g.iter().map(|b| (hours(b.t), b.mean)).collect(),
        ));
    }
    let mut caption = format!(
        "Chamber air temperature{}. The calibration's model temperature is the {}",
        if d.run.gyro_sensor() { " and the gyro's own sensor" } else { "" },
        temp_source(o)
    );
    if let Some(tau) = lag_used(o) {
        let mut first = true;
        for w in &o.calibration.model_windows {
            let b = decimate(w.time_s(), w.temperature_c(), 400);
            p.items.push(line(
                first.then_some("model temperature (lagged) in windows"),
                colour::GREEN,
                b.iter().map(|b| (hours(b.t), b.mean)).collect(),
            ));
            first = false;
        }
        caption.push_str(&format!(
            " through the fitted first-order lag of {tau:.0} s (green, in the windows)."
        ));
    } else {
        caption.push('.');
    }
    Figure {
        name: "fig2-temperature",
        title: "Temperature profile",
        caption,
        panels: vec![p],
        size: ONE,
    }
}

fn temperature_rate(o: &CalibrationOutcome) -> Figure {
    let d = &o.data;
    let w = o.calibration.options.joint.rate_window_s;
    let mut p = Plot::new(
        "Rate of temperature change",
        Axis::linear("time, h"),
        Axis::linear("dT/dt, °C/min"),
    );
    p.spans = window_spans(o);
    match local_linear_rate(&d.temperature.time_s, &d.temperature.temp_c, w) {
        Ok(rate) => {
            let b = decimate(&d.temperature.time_s, &rate, MAX_POINTS);
            p.items.push(line(
                Some(&format!("{} dT/dt", temp_source(o))),
                colour::BLUE,
                b.iter().map(|b| (hours(b.t), display::TEMP_RATE.of(b.mean))).collect(),
            ));
        }
        Err(e) => p.note = Some(format!("no dT/dt: {e}")),
    }
    if lag_used(o).is_some() {
        let mut first = true;
        for mw in &o.calibration.model_windows {
            if let Ok(rate) = local_linear_rate(mw.time_s(), mw.temperature_c(), w) {
                let b = decimate(mw.time_s(), &rate, 400);
                p.items.push(line(
                    first.then_some("model temperature (lagged) dT/dt in windows"),
                    colour::GREEN,
                    b.iter().map(|b| (hours(b.t), display::TEMP_RATE.of(b.mean))).collect(),
                ));
                first = false;
            }
        }
    }
    Figure {
        name: "fig3-temperature-rate",
        title: "dT/dt profile",
        caption: format!(
            "Rate of change of the {} temperature: slope of a centred local linear regression \
             over {w} s (the filter the calibration uses).",
            temp_source(o)
        ),
        panels: vec![p],
        size: ONE,
    }
}

/// k_t(T) of a model: bias + temp_coeff·(T − T0), rad/s.
fn k_t(m: &GyroModel, t: f64) -> f64 {
    thermal_bias(m, t, 0.0)
}

/// k_dt·Ṫ of a model, rad/s, for Ṫ in °C/s.
fn k_dt(m: &GyroModel, rate_c_s: f64) -> f64 {
    thermal_bias(m, m.reference_temperature, rate_c_s)
        - thermal_bias(m, m.reference_temperature, 0.0)
}

fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| a + (b - a) * i as f64 / (n - 1).max(1) as f64).collect()
}

fn cw_ccw(o: &CalibrationOutcome) -> Figure {
    let e = earth(o);
    let y = if o.calibration.options.joint.latitude_deg.is_some() {
        "V − Ω_table − Ω_E, °/h"
    } else {
        "V − Ω_table, °/h"
    };
    let mut p = Plot::new("Plateaus: CW and CCW", Axis::linear("temperature, °C"), Axis::linear(y));
    let (mut cw, mut ccw) = (Vec::new(), Vec::new());
    let (mut tmin, mut tmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for (i, w) in o.calibration.model_windows.iter().enumerate() {
        if kind_of(o, i, w.label()) != Some(WindowKind::Plateau) {
            continue;
        }
        let n = w.len() as f64;
        let bias = w
            .gyro_rate_rad_s()
            .iter()
            .zip(w.table_rate_rad_s())
            .map(|(v, t)| v - t - e)
            .sum::<f64>()
            / n;
        let temp = w.temperature_c().iter().sum::<f64>() / n;
        tmin = tmin.min(temp);
        tmax = tmax.max(temp);
        let pt = (temp, deg_h(bias), None);
        match w.direction() {
            Direction::Cw => cw.push(pt),
            Direction::Ccw => ccw.push(pt),
            Direction::Rest => {}
        }
    }
    p.items.push(Item::Markers {
        label: Some("CW window mean".into()),
        colour: colour::BLUE,
        shape: Marker::Triangle,
        points: cw,
    });
    p.items.push(Item::Markers {
        label: Some("CCW window mean".into()),
        colour: colour::RED,
        shape: Marker::Circle,
        points: ccw,
    });
    let mut caption = String::from(
        "Mean of gyro rate minus table rate (and minus Earth's rate when the latitude is known) \
         over each constant-temperature window, CW and CCW, at the window's mean model \
         temperature. The CW/CCW gap is the scale-factor error times twice the table rate; the \
         seed method's K = (k1 + k2)/2 of each CW/CCW pair cancels it.",
    );
    match &o.calibration.seed {
        Ok(s) => {
            p.items.push(Item::Markers {
                label: Some("pair mean K".into()),
                colour: colour::BLACK,
                shape: Marker::Cross,
                points: s
                    .plateaus
                    .iter()
                    .map(|pl| (pl.temperature_c, deg_h(pl.k_rad_s), None))
                    .collect(),
            });
        }
        Err(err) => caption.push_str(&format!(" No pair means: {err}.")),
    }
    if tmin.is_finite() {
        let (a, b) = if tmax - tmin < 1.0 { (tmin - 1.0, tmax + 1.0) } else { (tmin, tmax) };
        let ts = linspace(a, b, 2);
        if let Some(m) = &o.model {
            p.items.push(line(
                Some("joint fit k_t(T)"),
                colour::GREEN,
                ts.iter().map(|&t| (t, deg_h(k_t(m, t)))).collect(),
            ));
        }
        if let Some(m) = &o.seed_model {
            p.items.push(dashed(
                Some("seed method k_t(T)"),
                colour::ORANGE,
                ts.iter().map(|&t| (t, deg_h(k_t(m, t)))).collect(),
            ));
        }
        if let Some(tr) = &o.truth {
            p.items.push(dashed(
                Some("true k_t(T)"),
                colour::BLACK,
                ts.iter().map(|&t| (t, deg_h(k_t(&tr.model, t)))).collect(),
            ));
        }
    } else {
        p.note = Some("no constant-temperature windows".into());
    }
    Figure { name: "fig4-cw-ccw", title: "CW vs CCW plateaus", caption, panels: vec![p], size: ONE }
}

fn error_functions(o: &CalibrationOutcome) -> Figure {
    let joint = o.calibration.joint.as_ref().ok();
    let truth = o.truth.as_ref().map(|t| &t.model);

    // k_t(T) over the windows' temperature range.
    let mut kt = Plot::new("k_t(T)", Axis::linear("temperature, °C"), Axis::linear("k_t, °/h"));
    let (t0, t1) = o.temp_range_c;
    if t0.is_finite() && t1.is_finite() {
        let (a, b) = if t1 - t0 < 1e-6 { (t0 - 1.0, t1 + 1.0) } else { (t0, t1) };
        let ts = linspace(a, b, 60);
        if let (Some(m), Some(j)) = (&o.model, joint) {
            let tref = m.reference_temperature;
            kt.items.push(Item::Band {
                label: Some("joint ±2σ".into()),
                colour: colour::BLUE,
                points: ts
                    .iter()
                    .map(|&t| {
                        let s = (j.bias.std_err.powi(2)
                            + ((t - tref) * j.temp_coeff.std_err).powi(2))
                        .sqrt();
                        let v = k_t(m, t);
                        (t, deg_h(v - 2.0 * s), deg_h(v + 2.0 * s))
                    })
                    .collect(),
            });
            kt.items.push(line(
                Some("joint fit"),
                colour::BLUE,
                ts.iter().map(|&t| (t, deg_h(k_t(m, t)))).collect(),
            ));
        }
        if let Some(m) = &o.seed_model {
            kt.items.push(dashed(
                Some("seed method"),
                colour::ORANGE,
                ts.iter().map(|&t| (t, deg_h(k_t(m, t)))).collect(),
            ));
        }
        if let Some(m) = truth {
            kt.items.push(line(
                Some("truth"),
                colour::BLACK,
                ts.iter().map(|&t| (t, deg_h(k_t(m, t)))).collect(),
            ));
        }
    } else {
        kt.note = Some("no windows".into());
    }

    // k_dt·Ṫ over the windows' dT/dt range.
    let mut kd =
        Plot::new("k_dt · dT/dt", Axis::linear("dT/dt, °C/min"), Axis::linear("k_dt · dT/dt, °/h"));
    let (r0, r1) = o.rate_range_c_s;
    if r0.is_finite() && r1.is_finite() && r1 > r0 {
        let rs = linspace(r0, r1, 60);
        if let (Some(m), Some(j)) = (&o.model, joint) {
            kd.items.push(Item::Band {
                label: Some("joint ±2σ".into()),
                colour: colour::BLUE,
                points: rs
                    .iter()
                    .map(|&r| {
                        let v = k_dt(m, r);
                        let s = 2.0 * (r * j.temp_rate_coeff.std_err).abs();
                        (display::TEMP_RATE.of(r), deg_h(v - s), deg_h(v + s))
                    })
                    .collect(),
            });
            kd.items.push(line(
                Some("joint fit"),
                colour::BLUE,
                rs.iter().map(|&r| (display::TEMP_RATE.of(r), deg_h(k_dt(m, r)))).collect(),
            ));
        }
        if let Some(m) = &o.seed_model {
            kd.items.push(dashed(
                Some("seed method"),
                colour::ORANGE,
                rs.iter().map(|&r| (display::TEMP_RATE.of(r), deg_h(k_dt(m, r)))).collect(),
            ));
        }
        if let Some(m) = truth {
            kd.items.push(line(
                Some("truth"),
                colour::BLACK,
                rs.iter().map(|&r| (display::TEMP_RATE.of(r), deg_h(k_dt(m, r)))).collect(),
            ));
        }
    } else {
        kd.note = Some("no temperature change in the windows".into());
    }
    let mut caption = String::from(
        "The fitted error functions over the windows' ranges: left, k_t(T) = bias + \
         temp_coeff·(T − T0); right, k_dt·dT/dt. Joint fit with a ±2σ band from its standard \
         errors (bias and temp_coeff taken as uncorrelated), the seed method",
    );
    caption.push_str(if truth.is_some() {
        ", and the recording's model (the truth of a simulated run)."
    } else {
        "; the recording has no model to compare with."
    });
    Figure {
        name: "fig5-error-functions",
        title: "Fitted error functions",
        caption,
        panels: vec![kt, kd],
        size: TWO,
    }
}

/// The gyro's true temperature at `time_s` for the truth model: the sensor when the gyro has
/// one, else chamber air through the model's thermal lag.
fn true_temperature(o: &CalibrationOutcome, m: &GyroModel, time_s: &[f64]) -> Vec<f64> {
    let d = &o.data;
    if d.run.gyro_sensor() {
        d.temperature.sample(time_s)
    } else {
        d.chamber.lagged(m.thermal_time_constant).sample(time_s)
    }
}

/// Per-sample `(uncalibrated, calibrated)` error of window `w` under `model`: gyro − Earth −
/// table·(1 + s), and that minus the model's thermal bias, rad/s.
fn window_errors(
    o: &CalibrationOutcome,
    w: &bench_analysis::RecordWindow,
    model: &GyroModel,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let e = earth(o);
    let temp = w.temperature_c();
    let rate =
        local_linear_rate(w.time_s(), temp, o.calibration.options.joint.rate_window_s).ok()?;
    let sf = model.scale_factor_error;
    let unc: Vec<f64> = w
        .gyro_rate_rad_s()
        .iter()
        .zip(w.table_rate_rad_s())
        .map(|(v, t)| v - e - t * (1.0 + sf))
        .collect();
    let cal = unc
        .iter()
        .zip(temp.iter().zip(&rate))
        .map(|(u, (t, r))| u - thermal_bias(model, *t, *r))
        .collect();
    Some((unc, cal))
}

fn thermal_error(o: &CalibrationOutcome) -> Figure {
    let mut p = Plot::new(
        "Thermal error in the ramp windows",
        Axis::linear("time, h"),
        Axis::linear("rate error, °/h"),
    );
    p.spans = window_spans(o).into_iter().filter(|s| s.label == "ramp window").collect();
    let mut first = [true; 3];
    let mut take = |k: usize| std::mem::replace(&mut first[k], false);
    let mut any = false;
    if let Some(model) = &o.model {
        for (i, w) in o.calibration.model_windows.iter().enumerate() {
            if kind_of(o, i, w.label()) != Some(WindowKind::Ramp) {
                continue;
            }
            let Some((unc, cal)) = window_errors(o, w, model) else { continue };
            any = true;
            let t = w.time_s();
            let pts = |v: &[f64]| -> Vec<(f64, f64)> {
                window_bins(t, v).iter().map(|b| (hours(b.t), deg_h(b.mean))).collect()
            };
            p.items.push(line(
                take(0).then_some("uncalibrated: V − Ω_E − Ω_table·(1+s)"),
                colour::RED,
                pts(&unc),
            ));
            p.items.push(line(
                take(1).then_some("calibrated: minus the joint model's k_t + k_dt·dT/dt"),
                colour::BLUE,
                pts(&cal),
            ));
            if let Some(tr) = &o.truth {
                let tt = true_temperature(o, &tr.model, t);
                if let Ok(rr) = local_linear_rate(t, &tt, o.calibration.options.joint.rate_window_s)
                {
                    let truth: Vec<f64> =
                        tt.iter().zip(&rr).map(|(a, b)| thermal_bias(&tr.model, *a, *b)).collect();
                    p.items.push(dashed(
                        take(2).then_some("true thermal error (bias included)"),
                        colour::BLACK,
                        pts(&truth),
                    ));
                }
            }
        }
    }
    if !any {
        p.note = Some(if o.model.is_none() {
            "no calibrated model (the joint fit failed)".into()
        } else {
            "no ramp windows".into()
        });
    }
    Figure {
        name: "fig6-thermal-error",
        title: "Calibrated vs uncalibrated vs true",
        caption: format!(
            "Ramp windows: the gyro rate minus Earth's rate and the table rate scaled by the \
             fitted scale factor (uncalibrated: bias and thermal error plus noise), the same \
             after subtracting the calibrated model's k_t(T) + k_dt·dT/dt, and{} the true \
             thermal error. Means over equal bins of at most {BIN_S:.0} s, at least 10 per \
             window.",
            if o.truth.is_some() { "" } else { " (no model in the recording, so not)" }
        ),
        panels: vec![p],
        size: ONE,
    }
}

fn residual(o: &CalibrationOutcome) -> Figure {
    let mut p =
        Plot::new("Calibration residual", Axis::linear("time, h"), Axis::linear("residual, °/h"));
    p.spans = window_spans(o);
    let mut all = Vec::new();
    let mut means = Vec::new();
    let mut first = true;
    if let Some(model) = &o.model {
        for w in &o.calibration.model_windows {
            let Some((_, cal)) = window_errors(o, w, model) else { continue };
            let t = w.time_s();
            let b = window_bins(t, &cal);
            means.extend(b.iter().map(|b| b.mean));
            p.items.push(line(
                first.then_some("bin mean"),
                colour::BLUE,
                b.iter().map(|b| (hours(b.t), deg_h(b.mean))).collect(),
            ));
            first = false;
            all.extend(cal);
        }
    }
    let rms_samples = deg_h(rms(all.iter().copied()));
    let rms_means = deg_h(rms(means.iter().copied()));
    p.note = Some(if all.is_empty() {
        "no calibrated model (the joint fit failed)".into()
    } else {
        format!(
            "RMS of samples {} °/h\nRMS of bin means {} °/h",
            crate::render::sig(rms_samples, 3),
            crate::render::sig(rms_means, 3)
        )
    });
    Figure {
        name: "fig7-residual",
        title: "Calibration residual",
        caption: format!(
            "Gyro rate minus Earth's rate, the scaled table rate and the calibrated model's \
             thermal bias, in every record window; means over equal bins of at most \
             {BIN_S:.0} s, at least 10 per window. RMS over all samples: {} °/h; over the bin means: {} °/h.",
            crate::render::sig(rms_samples, 3),
            crate::render::sig(rms_means, 3)
        ),
        panels: vec![p],
        size: ONE,
    }
}

/// The noise type whose slope is nearest the curve's local log-log slope at `j`.
fn dominant_noise(points: &[AdevPoint], j: usize) -> NoiseType {
    let a = j.saturating_sub(1);
    let b = (j + 1).min(points.len().saturating_sub(1));
    if a == b {
        return NoiseType::FlickerRate;
    }
    let slope = (points[b].adev / points[a].adev).ln() / (points[b].tau_s / points[a].tau_s).ln();
    if slope <= -0.25 {
        NoiseType::WhiteRate
    } else if slope >= 0.25 {
        NoiseType::RandomWalkRate
    } else {
        NoiseType::FlickerRate
    }
}

fn allan(o: &CalibrationOutcome) -> Figure {
    let mut p = Plot::new(
        "Allan deviation (constant-temperature windows pooled)",
        Axis::log("τ, s"),
        Axis::log("σ(τ), °/h"),
    );
    let mut caption = String::from(
        "Overlapping Allan deviation of gyro minus table rate, pooled over the \
         constant-temperature and static windows",
    );
    match &o.calibration.allan {
        Ok(a) => {
            let mut pts: Vec<AdevPoint> = a
                .points
                .iter()
                .copied()
                .filter(|p| p.adev.is_finite() && p.adev > 0.0 && p.tau_s > 0.0)
                .collect();
            pts.sort_by(|x, y| x.tau_s.total_cmp(&y.tau_s));
            let conf = a.fit.confidence;
            let marks: Vec<MarkerPoint> = pts
                .iter()
                .enumerate()
                .map(|(j, pt)| {
                    let (lo, hi) = pt.interval(dominant_noise(&pts, j), conf);
                    (pt.tau_s, deg_h(pt.adev), Some((deg_h(lo), deg_h(hi))))
                })
                .collect();
            // The ranges: whole decades around the points with their intervals; the fitted
            // lines are clipped to them rather than stretch them.
            let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &(_, y, bar) in &marks {
                let (lo, hi) = bar.unwrap_or((y, y));
                for v in [y, lo, hi].into_iter().filter(|v| v.is_finite() && *v > 0.0) {
                    ylo = ylo.min(v);
                    yhi = yhi.max(v);
                }
            }
            if let (Some(f), Some(l)) = (pts.first(), pts.last()) {
                let (t0, t1) = crate::render::plot::decades(f.tau_s, l.tau_s);
                let taus: Vec<f64> =
                    (0..=80).map(|i| t0 * (t1 / t0).powf(f64::from(i) / 80.0)).collect();
                if ylo.is_finite() {
                    let (ylo, yhi) = crate::render::plot::decades(ylo, yhi);
                    p.y.range = Some((ylo, yhi));
                    p.x.range = Some(crate::render::plot::decades(t0, t1));
                    let fit = &a.fit;
                    let floor = fit.flicker_floor();
                    let sig = crate::render::sig;
                    let lines = [
                        (
                            format!(
                                "N: slope −1/2, N = {} °/√h",
                                sig(fit.arw_deg_per_sqrt_h().value, 3)
                            ),
                            fit.arw.upper_bound,
                            colour::GREEN,
                            -0.5,
                            fit.arw.value,
                        ),
                        (
                            format!(
                                "B: floor 0.664·B, B = {} °/h",
                                sig(fit.bias_instability_deg_per_h().value, 3)
                            ),
                            floor.upper_bound,
                            colour::ORANGE,
                            0.0,
                            floor.value,
                        ),
                        (
                            format!(
                                "K: slope +1/2, K = {} °/h/√h",
                                sig(fit.rate_random_walk_deg_per_h_per_sqrt_h().value, 3)
                            ),
                            fit.rate_random_walk.upper_bound,
                            colour::PURPLE,
                            0.5,
                            // K·√(τ/3) = (K/√3)·τ^½
                            fit.rate_random_walk.value / 3f64.sqrt(),
                        ),
                    ];
                    for (label, bound, c, slope, coeff) in lines {
                        let pts: Vec<(f64, f64)> = taus
                            .iter()
                            .map(|&t| (t, deg_h(coeff * t.powf(slope))))
                            .filter(|&(_, y)| y >= ylo && y <= yhi)
                            .collect();
                        let label = if bound { format!("{label} (upper bound)") } else { label };
                        p.items.push(Item::Line {
                            label: Some(label),
                            colour: c,
                            width: 2,
                            dashed: bound,
                            points: pts,
                        });
                    }
                }
            }
            p.items.insert(
                0,
                Item::Markers {
                    label: Some(format!("ADEV, {:.0} % interval", conf * 100.0)),
                    colour: colour::BLUE,
                    shape: Marker::Circle,
                    points: marks,
                },
            );
            caption.push_str(&format!(
                ", with {:.0} % chi-square confidence intervals whose equivalent degrees of freedom \
                 use, at each τ, the noise type of the curve's local log-log slope there \
                 (white rate below −1/4, random-walk rate above +1/4, flicker rate between). \
                 Lines: the IEEE 952 terms read at their tangent points, N/√τ, the flicker \
                 floor 0.664·B and K·√(τ/3); dashed where the term never dominates the curve \
                 (an upper bound).",
                conf * 100.0,
            ));
        }
        Err(e) => {
            p.note = Some(format!("no Allan deviation: {e}"));
            caption.push_str(&format!(": not available ({e})."));
        }
    }
    Figure { name: "fig8-allan", title: "Allan deviation", caption, panels: vec![p], size: ONE }
}
