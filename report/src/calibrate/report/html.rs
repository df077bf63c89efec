//! The report page: one self-contained HTML document (inline CSS, figures as inline SVG, no
//! script, nothing fetched). Every text taken from the recording or from an error message is
//! escaped.

use std::fmt::Write as _;

use bench_analysis::allan_fit::{NoiseTerm, FLICKER_FLOOR_FACTOR};
use bench_analysis::calibrate::{thermal_bias, ThermalErrorRemoval, WindowKind};
use bench_analysis::Direction;
use bench_physics::GyroModel;

use super::figures::Figure;
use crate::calibrate::{CalibrationOutcome, FunctionErrors};
use crate::display::{
    Unit, ARW, HOURS, MILLISECONDS, MINUTES, PPM, RATE, TABLE_RATE, TEMP_COEFF, TEMP_RATE,
    TEMP_RATE_COEFF,
};
use crate::render::{escape, figures_html, sig, STYLE};

/// `value ± σ` (display units, the unit in its own column), digits set by σ.
fn pm(value: f64, sigma: f64) -> String {
    crate::display::value_sigma(value, sigma, "")
}

fn kind_text(k: WindowKind) -> &'static str {
    match k {
        WindowKind::Plateau => "plateau",
        WindowKind::Ramp => "ramp",
        WindowKind::Static => "static",
    }
}

fn direction_text(d: Direction) -> &'static str {
    match d {
        Direction::Cw => "CW",
        Direction::Ccw => "CCW",
        Direction::Rest => "rest",
    }
}

/// The coefficient rows: (name, unit, joint (value, σ), seed value, truth value).
fn coefficient_rows(o: &CalibrationOutcome) -> String {
    let joint = o.calibration.joint.as_ref().ok();
    let seed = o.calibration.seed.as_ref().ok();
    let t0 = o.calibration.options.joint.reference_temperature_c;
    let truth = o.truth.as_ref().map(|t| &t.model);
    // The truth's bias at the calibration's T0 (its own T0 may differ).
    let truth_bias = truth.map(|m| thermal_bias(m, t0, 0.0));
    let angle = o.calibration.angle.as_ref().and_then(|a| a.as_ref().ok()).map(|a| a.estimates());
    let angle_of = |j: usize| angle.map(|a| (a[j].value, a[j].std_err));
    // (name, unit, joint (value, σ), seed value, truth value), SI.
    type Row<'a> = (&'a str, Unit, Option<(f64, f64)>, Option<f64>, Option<f64>);
    let rows: [Row; 4] = [
        (
            "bias at T0",
            RATE,
            joint.map(|j| (j.bias.value, j.bias.std_err)),
            seed.map(|s| s.bias_rad_s),
            truth_bias,
        ),
        (
            "scale-factor error (k_sf − 1)",
            PPM,
            joint.map(|j| (j.scale_factor_error.value, j.scale_factor_error.std_err)),
            None,
            truth.map(|m| m.scale_factor_error),
        ),
        (
            "temp_coeff (k_t slope)",
            TEMP_COEFF,
            joint.map(|j| (j.temp_coeff.value, j.temp_coeff.std_err)),
            seed.map(|s| s.temp_coeff),
            truth.map(|m| m.temp_coeff),
        ),
        (
            "temp_rate_coeff (k_dt)",
            TEMP_RATE_COEFF,
            joint.map(|j| (j.temp_rate_coeff.value, j.temp_rate_coeff.std_err)),
            seed.and_then(|s| s.temp_rate_coeff),
            truth.map(|m| m.temp_rate_coeff),
        ),
    ];
    let mut out = String::new();
    for (row, (name, unit, j, s, t)) in rows.into_iter().enumerate() {
        let k = unit.per_si;
        let held = joint
            .and_then(|j| j.estimate(bench_physics::ModelKey::CALIBRATED[row]))
            .is_some_and(|e| e.held);
        let jt = match j {
            Some((v, _)) if held => format!("HELD at {} — not estimated", sig(v * k, 4)),
            _ => j.map_or("—".into(), |(v, e)| pm(v * k, e * k)),
        };
        let at = if held {
            "held".into()
        } else {
            angle_of(row).map_or("—".into(), |(v, e)| pm(v * k, e * k))
        };
        let st = s.map_or_else(
            || if name.starts_with("scale") { "not fitted".into() } else { "—".into() },
            |v| sig(v * k, 4),
        );
        let (tt, jd, sd) = match t {
            Some(t) => (
                sig(t * k, 4),
                j.map_or("—".into(), |(v, e)| {
                    let d = v - t;
                    let z = if e > 0.0 { format!(" ({:.1}σ)", d / e) } else { String::new() };
                    format!("{}{z}", sig(d * k, 3))
                }),
                s.map_or("—".into(), |v| sig((v - t) * k, 3)),
            ),
            None => ("—".into(), "—".into(), "—".into()),
        };
        let _ = writeln!(
            out,
            "<tr><td class=l>{}</td><td class=l>{}</td><td>{jt}</td><td>{at}</td><td>{st}</td>\
             <td>{tt}</td><td>{jd}</td><td>{sd}</td></tr>",
            escape(name),
            escape(unit.name)
        );
    }
    let _ = writeln!(
        out,
        "<tr><td class=l>reference temperature T0</td><td class=l>°C</td><td>{}</td><td>{}</td>\
         <td>{}</td><td>{}</td><td></td><td></td></tr>",
        sig(t0, 4),
        sig(t0, 4),
        seed.map_or("—".into(), |s| sig(s.reference_temperature_c, 4)),
        truth.map_or("—".into(), |m| sig(m.reference_temperature, 4)),
    );
    out
}

fn function_error_row(name: &str, f: Option<&FunctionErrors>) -> String {
    match f {
        Some(f) => format!(
            "<tr><td class=l>{name}</td><td>{}</td><td>{}</td></tr>",
            sig(RATE.of(f.delta_k_t_rad_s), 3),
            sig(RATE.of(f.delta_k_dt_rad_s), 3)
        ),
        None => format!("<tr><td class=l>{name}</td><td>—</td><td>—</td></tr>"),
    }
}

fn removal_row(name: &str, r: Option<&ThermalErrorRemoval>) -> String {
    match r {
        Some(r) => format!(
            "<tr><td class=l>{name}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            sig(RATE.of(r.rms_uncalibrated_rad_s), 3),
            sig(RATE.of(r.rms_calibrated_rad_s), 3),
            format_args!("{:.1} %", 100.0 * r.removed())
        ),
        None => format!("<tr><td class=l>{name}</td><td>—</td><td>—</td><td>—</td></tr>"),
    }
}

fn noise_row(name: &str, unit: &str, t: &NoiseTerm, truth: Option<f64>) -> String {
    format!(
        "<tr><td class=l>{name}</td><td class=l>{unit}</td><td>{}</td><td>{} … {}</td><td>{}</td>\
         <td>{}</td><td>{}</td></tr>",
        sig(t.value, 3),
        sig(t.low, 3),
        sig(t.high, 3),
        sig(t.tau_s, 3),
        if t.upper_bound { "upper bound (never dominates)" } else { "tangent" },
        truth.map_or("—".into(), |v| sig(v, 3)),
    )
}

fn model_summary(m: &GyroModel) -> String {
    format!(
        "bias {} °/h, scale-factor error {} ppm, temp_coeff {} °/h per °C, temp_rate_coeff {} \
         °/h per °C/min at T0 = {} °C",
        sig(RATE.of(m.bias), 4),
        sig(PPM.of(m.scale_factor_error), 4),
        sig(TEMP_COEFF.of(m.temp_coeff), 4),
        sig(TEMP_RATE_COEFF.of(m.temp_rate_coeff), 4),
        sig(m.reference_temperature, 4)
    )
}

/// The whole page; `figures` pairs each figure with its SVG document.
/// The fit's verdict: each check, the residual's excursions, and what to do about a poor fit.
fn fit_quality(h: &mut String, o: &CalibrationOutcome, source: &str) {
    let q = &o.quality;
    let _ = writeln!(
        h,
        "<h2>Fit: {}</h2>",
        if q.poor() { "POOR — the coefficients below are not sound" } else { "sound" }
    );
    if q.poor() {
        let _ = writeln!(
            h,
            "<p class=note>The model does not fit these data: the numbers are for inspection, \
             not for use. <code>bench diagnose {}</code> looks for the physics the model leaves \
             out.</p>",
            escape(source)
        );
    }
    let _ = writeln!(
        h,
        "<table>\n<tr><th class=l>check</th><th>value</th><th>allowed</th><th class=l>result</th>\
         </tr>"
    );
    for c in &q.checks {
        let _ = writeln!(
            h,
            "<tr><td class=l>{}</td><td>{}</td><td>{}</td><td class=l>{}</td></tr>",
            escape(&c.text),
            sig(c.value, 3),
            escape(&c.allowed),
            if c.passed { "pass" } else { "FAIL" }
        );
    }
    let _ = writeln!(h, "</table>");
    if !q.excursions.is_empty() {
        let _ =
            writeln!(h, "<p>Where the residual strays most (block mean in noise units):</p>\n<ul>");
        for x in &q.excursions {
            let _ = writeln!(
                h,
                "<li>{:+.1}σ over {}–{} in <b>{}</b>: {}</li>",
                x.z,
                crate::display::hms(x.start_s),
                crate::display::hms(x.end_s),
                escape(&x.window),
                escape(&x.context)
            );
        }
        let _ = writeln!(h, "</ul>");
    }
}

/// Near the top: what the run determined, what was held and why, and what the compensation
/// does to this run and to a verification run.
fn summary(h: &mut String, o: &CalibrationOutcome) {
    let cal = &o.calibration;
    let verdict = match o.quality.verdict {
        "poor" => "<span class=bad>POOR</span>: the model does not fit these data",
        "incomplete" => {
            "<span class=bad>INCOMPLETE</span>: the run does not determine every coefficient"
        }
        _ => "<span class=ok>sound</span>: every coefficient determined, every check passed",
    };
    let _ = writeln!(h, "<h2>Summary</h2>\n<p>Calibration: {verdict}.</p>\n<ul>");
    let joint = cal.joint.as_ref().ok();
    let determined: Vec<String> = bench_physics::ModelKey::CALIBRATED
        .into_iter()
        .filter_map(|k| {
            let e = joint?.estimate(k).filter(|e| !e.held)?;
            let unit = crate::display::coefficient_unit(k)?;
            Some(format!(
                "{} {}",
                k.key(),
                crate::display::si_value_sigma(unit, e.value, e.std_err)
            ))
        })
        .collect();
    if !determined.is_empty() {
        let _ = writeln!(h, "<li>Determined: {}.</li>", escape(&determined.join("; ")));
    }
    for l in crate::calibrate::held::lines(cal) {
        let _ = writeln!(h, "<li class=bad>{}</li>", escape(&l));
    }
    if let Some(c) = &o.compensation {
        let _ = writeln!(
            h,
            "<li>On this run (the data it was fitted to): {}.</li>",
            escape(&crate::verify::summary_lines(c).join("; "))
        );
    }
    if let Some((name, v)) = &o.verification {
        let _ = writeln!(
            h,
            "<li>On the verification run <b>{}</b>: <b>{}</b>; {}.</li>",
            escape(name),
            escape(v.verdict.text()),
            escape(&crate::verify::summary_lines(&v.compensation).join("; "))
        );
    }
    let _ = writeln!(h, "</ul>");
}

/// The compensation's windows, on this run and on a verification run.
fn compensation_sections(h: &mut String, o: &CalibrationOutcome) {
    if let Some(c) = &o.compensation {
        let _ = writeln!(
            h,
            "<h2>Compensation on this run</h2>\n<p class=note>The calibration applied to the \
             windows it was fitted to: what it takes out of this run (not a verification).</p>"
        );
        crate::verify_html::compensation_html(h, c);
    }
    if let Some((name, v)) = &o.verification {
        let _ = writeln!(h, "<h2>Verification run: {}</h2>", escape(name));
        crate::verify_html::compensation_html(h, &v.compensation);
    }
}

/// What the record steps hold outside the windows, and each channel's time base.
fn exclusions(h: &mut String, o: &CalibrationOutcome) {
    let d = &o.data;
    let _ = writeln!(
        h,
        "<h2>Left out of the record steps</h2>\n<p class=note>Decided from the table's own \
         readings (its steady motion), not from the step events.</p>\n<table>\n<tr><th class=l>step</th>\
         <th>from, h</th><th>length, s</th><th class=l>why</th><th>gyro samples</th></tr>"
    );
    for x in &d.exclusions {
        let _ = writeln!(
            h,
            "<tr><td class=l>{}</td><td>{:.3}</td><td>{:.1}</td><td class=l>{}</td><td>{}</td></tr>",
            escape(&x.label),
            HOURS.of(x.start_s),
            x.end_s - x.start_s,
            x.why.key().replace('_', " "),
            x.samples
        );
    }
    let _ = writeln!(h, "</table>");
    for (label, n) in &d.empty_windows {
        let _ = writeln!(
            h,
            "<p class=note>Step {} ({n} gyro samples) has no steady part long enough to use.</p>",
            escape(label)
        );
    }
    let _ = writeln!(h, "<h2>Time bases</h2>\n<ul>");
    for b in &d.run.time_bases {
        let text = match &b.fit {
            // A counter is a number of samples, not a clock: its time base is s per count.
            Some(f) if b.source == crate::load::TimeSource::DeviceCounter => format!(
                "{}: device counter, {} s per count on the host clock ({} Hz), host stamps' \
                 jitter {} ms, latest {} ms",
                b.topic,
                sig(f.rate, 6),
                sig(1.0 / f.rate, 6),
                sig(MILLISECONDS.of(f.jitter_s), 3),
                sig(MILLISECONDS.of(f.max_late_s), 3)
            ),
            Some(f) => format!(
                "{}: {}; host clock {:+.1} ppm against it, host stamps' jitter {} ms, latest {} ms",
                b.topic,
                b.source.key().replace('_', " "),
                PPM.of(f.rate - 1.0),
                sig(MILLISECONDS.of(f.jitter_s), 3),
                sig(MILLISECONDS.of(f.max_late_s), 3)
            ),
            None => format!("{}: {}", b.topic, b.source.key().replace('_', " ")),
        };
        let _ = writeln!(h, "<li>{}</li>", escape(&text));
    }
    let _ = writeln!(h, "</ul>");
}

pub(super) fn page(o: &CalibrationOutcome, source: &str, figures: &[(Figure, String)]) -> String {
    let src = escape(source);
    let mut h = String::with_capacity(64 * 1024 + figures.iter().map(|f| f.1.len()).sum::<usize>());
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n\
         <meta name=viewport content=\"width=device-width, initial-scale=1\">\n\
         <title>Calibration report: {src}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n\
         <h1>FOG thermal calibration report</h1>\n<p>Recording: <b>{src}</b></p>\n"
    );
    setting(&mut h, o);
    summary(&mut h, o);
    fit_quality(&mut h, o, source);
    coefficients(&mut h, o);
    against_truth(&mut h, o);
    noise_terms(&mut h, o);
    thermal_lag(&mut h, o);
    windows(&mut h, o);
    exclusions(&mut h, o);
    compensation_sections(&mut h, o);
    lacking(&mut h, o);
    let _ = writeln!(h, "<h2>Figures</h2>");
    h.push_str(&figures_html(figures));
    h.push_str("</body>\n</html>\n");
    h
}

/// The run, the site, the model temperature and the error model.
fn setting(h: &mut String, o: &CalibrationOutcome) {
    let opts = &o.calibration.options;
    let d = &o.data;
    let duration = match (d.run.series.gyro_time_s.first(), d.run.series.gyro_time_s.last()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    let _ = writeln!(
        h,
        "<ul>\n<li>Run: {} h, {} good gyro samples, {} record window(s).</li>\n\
         <li>Site: {}; sensing axis {}.</li>\n\
         <li>Model temperature: {}{}; dT/dt by local linear regression over {} s.</li>\n\
         <li>Error model: V − Ω_in = bias + s·Ω_in + temp_coeff·(T − T0) + temp_rate_coeff·dT/dt, \
         Ω_in = table rate + Earth's rate along the axis.</li>\n</ul>",
        sig(HOURS.of(duration), 3),
        d.run.series.gyro_time_s.len(),
        d.spans.len(),
        match d.run.series.latitude_deg.or(opts.joint.latitude_deg) {
            Some(l) => format!("latitude {} °, Earth's rate removed", sig(l, 5)),
            None => "no latitude: Earth's rate stays in the bias".into(),
        },
        if opts.joint.axis_up { "up" } else { "down" },
        if d.run.gyro_sensor() { "the gyro's own sensor" } else { "chamber air" },
        match &o.calibration.lag {
            Some(Ok(l)) if l.used_s > 0.0 => format!(" through a {} s lag", sig(l.used_s, 3)),
            _ => String::new(),
        },
        sig(opts.joint.rate_window_s, 3)
    );
}

/// The coefficients in both domains, with the seed method and the truth, and their notes.
fn coefficients(h: &mut String, o: &CalibrationOutcome) {
    let _ = writeln!(
        h,
        "<h2>Coefficients</h2>\n<table>\n<tr><th class=l>coefficient</th><th class=l>unit</th>\
         <th>joint fit, rate domain (±1σ)</th><th>angle domain (±1σ)</th><th>seed method</th>\
         <th>truth</th><th>joint − truth</th><th>seed − truth</th></tr>\n{}</table>",
        coefficient_rows(o)
    );
    let mut notes = Vec::new();
    if let Err(e) = &o.calibration.joint {
        notes.push(format!("Joint fit failed: {e}"));
    }
    if let Err(e) = &o.calibration.seed {
        notes.push(format!("Seed method failed: {e}"));
    }
    if o.truth.is_none() {
        notes.push(
            "No truth to compare with: the recording's bench.gyro_model is nominal (the lab's \
             belief, or absent), not a simulator's model (bench.run gyro_model_role)."
                .into(),
        );
    } else {
        notes.push(
            "Truth: the recording's bench.gyro_model (the simulator's model for a simulated run); \
             its bias is given at the calibration's T0. The joint − truth column gives the \
             error in units of the joint fit's σ in brackets."
                .into(),
        );
    }
    notes.push(
        "σ: the joint fit's stated standard error (it accounts for coloured noise; see the \
         analysis' joint-fit docs). The seed method states no uncertainty and does not fit the \
         scale factor."
            .into(),
    );
    for n in &notes {
        let _ = writeln!(h, "<p class=note>{}</p>", escape(n));
    }
    if let Some(m) = &o.model {
        let _ = writeln!(
            h,
            "<p class=note>Calibrated model (joint): {}.</p>",
            escape(&model_summary(m))
        );
    }
}

/// Where the recording carries its simulator's truth: the error functions and the thermal error removed.
fn against_truth(h: &mut String, o: &CalibrationOutcome) {
    if let Some(t) = &o.truth {
        let _ = writeln!(
            h,
            "<h2>Error functions against the truth</h2>\n<p class=note>The seed's Δk_t = \
             max |k_t,true(T) − k_t,fit(T)| over the windows' temperature range {} … {} °C (bias \
             included) and Δk_dt = max |(k_dt,true − k_dt,fit)·dT/dt| over their dT/dt range \
             {} … {} °C/min.</p>\n<table>\n<tr><th class=l>method</th><th>Δk_t, °/h</th>\
             <th>Δk_dt, °/h</th></tr>\n{}\n{}\n</table>",
            sig(o.temp_range_c.0, 3),
            sig(o.temp_range_c.1, 3),
            sig(TEMP_RATE.of(o.rate_range_c_s.0), 3),
            sig(TEMP_RATE.of(o.rate_range_c_s.1), 3),
            function_error_row("joint fit", t.joint.as_ref()),
            function_error_row("seed method", t.seed.as_ref()),
        );
        let _ = writeln!(
            h,
            "<h2>Thermal error removed</h2>\n<p class=note>Over the whole run's model \
             temperature: RMS of the true thermal error k_t·(T − T0) + k_dt·dT/dt, and of what \
             remains after subtracting the fitted bias and thermal terms from the true ones.</p>\n\
             <table>\n<tr><th class=l>method</th><th>RMS before, °/h</th><th>RMS after, °/h</th>\
             <th>removed</th></tr>\n{}\n{}\n</table>",
            removal_row("joint fit", t.joint_removal.as_ref()),
            removal_row("seed method", t.seed_removal.as_ref()),
        );
    }
}

/// IEEE 952's noise terms read off the Allan deviation.
fn noise_terms(h: &mut String, o: &CalibrationOutcome) {
    let _ = writeln!(h, "<h2>Noise terms (IEEE 952, from the Allan deviation)</h2>");
    match &o.calibration.allan {
        Ok(a) => {
            let f = &a.fit;
            let truth = o.truth.as_ref().map(|t| &t.model);
            let _ = writeln!(
                h,
                "<table>\n<tr><th class=l>term</th><th class=l>unit</th><th>value</th>\
                 <th>{:.0} % interval</th><th>τ read, s</th><th class=l>read at</th>\
                 <th>truth</th></tr>\n{}\n{}\n{}\n</table>\n<p class=note>B is IEEE 952's bias \
                 instability (the flicker floor of the ADEV divided by 0.664); the contract's \
                 bias_instability is the floor itself. The truth has no rate random walk.</p>",
                f.confidence * 100.0,
                noise_row(
                    "N, angle random walk",
                    "°/√h",
                    &f.arw_deg_per_sqrt_h(),
                    truth.map(|m| ARW.of(m.arw))
                ),
                noise_row(
                    "B, bias instability",
                    "°/h",
                    &f.bias_instability_deg_per_h(),
                    truth.map(|m| RATE.of(m.bias_instability / FLICKER_FLOOR_FACTOR))
                ),
                noise_row(
                    "K, rate random walk",
                    "°/h/√h",
                    &f.rate_random_walk_deg_per_h_per_sqrt_h(),
                    truth.map(|_| 0.0)
                ),
            );
        }
        Err(e) => {
            let _ = writeln!(h, "<p class=bad>Not available: {}</p>", escape(&e.to_string()));
        }
    }
}

/// The thermal lag's profile, or why it was not profiled.
fn thermal_lag(h: &mut String, o: &CalibrationOutcome) {
    let _ = writeln!(h, "<h2>Thermal lag</h2>");
    let truth_tau = o.truth.as_ref().map(|t| t.model.thermal_time_constant);
    match &o.calibration.lag {
        None => {
            let why = if o.data.run.gyro_sensor() {
                "the model temperature is the gyro's own sensor"
            } else if !o.calibration.windows.iter().any(|w| w.kind == WindowKind::Ramp) {
                "no ramp window to tell it from"
            } else {
                "turned off"
            };
            let _ = writeln!(h, "<p>Not profiled: {why}; τ = 0.</p>");
        }
        Some(Err(e)) => {
            let _ = writeln!(h, "<p class=bad>Profile failed: {}</p>", escape(&e.to_string()));
        }
        Some(Ok(l)) => {
            let _ = writeln!(
                h,
                "<p>Best τ = {} s (interval {} … {} s); test statistic {} against the χ²₁ \
                 threshold {} (n_eff = {}): {}. τ used: <b>{} s</b>{}.</p>",
                sig(l.best_s, 3),
                sig(l.interval_s.0, 3),
                sig(l.interval_s.1, 3),
                sig(l.statistic, 3),
                sig(l.threshold, 3),
                sig(l.n_eff, 3),
                if l.significant() {
                    "<span class=ok>the data tell the lag from zero</span>"
                } else {
                    "<span class=bad>the data cannot tell the lag from zero</span>"
                },
                sig(l.used_s, 3),
                truth_tau.map_or(String::new(), |t| format!(" (truth {} s)", sig(t, 3))),
            );
        }
    }
}

/// The record windows.
fn windows(h: &mut String, o: &CalibrationOutcome) {
    let _ = writeln!(
        h,
        "<h2>Record windows</h2>\n<table>\n<tr><th class=l>label</th><th class=l>kind</th>\
         <th class=l>direction</th><th>start, h</th><th>duration, min</th><th>samples</th>\
         <th>mean T, °C</th><th>T span, °C</th><th>table rate, °/min</th></tr>"
    );
    for (i, w) in o.calibration.windows.iter().enumerate() {
        let start = match o.data.spans.get(i) {
            Some(s) if s.label == w.label => Some(s.start_s),
            _ => o.data.spans.iter().find(|s| s.label == w.label).map(|s| s.start_s),
        };
        let _ = writeln!(
            h,
            "<tr><td class=l>{}</td><td class=l>{}</td><td class=l>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&w.label),
            kind_text(w.kind),
            direction_text(w.direction),
            start.map_or("—".into(), |s| format!("{:.3}", HOURS.of(s))),
            format_args!("{:.2}", MINUTES.of(w.duration_s)),
            w.samples,
            format_args!("{:.2}", w.mean_temp_c),
            format_args!("{:.2}", w.temp_span_c),
            sig(TABLE_RATE.of(w.mean_table_rate_rad_s), 4),
        );
    }
    let _ = writeln!(h, "</table>");
}

/// What the data lack.
fn lacking(h: &mut String, o: &CalibrationOutcome) {
    let _ = writeln!(h, "<h2>What the data lack</h2>");
    if o.calibration.missing.is_empty() {
        let _ = writeln!(h, "<p>Nothing: every term could be estimated.</p>");
    } else {
        let _ = writeln!(h, "<ul class=missing>");
        for m in &o.calibration.missing {
            let _ = writeln!(h, "<li>{}</li>", escape(m));
        }
        let _ = writeln!(h, "</ul>");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping_covers_markup() {
        assert_eq!(escape("a<b & \"c\" 'd'>"), "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(1234.5678, 4), "1235");
        assert_eq!(sig(0.012345, 3), "0.0123");
        assert_eq!(sig(-2.5, 2), "-2.5");
        assert_eq!(sig(1.5e-7, 3), "1.50e-7");
        assert_eq!(sig(f64::NAN, 3), "n/a");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(-9.99999, 4), "-10.00");
        assert_eq!(sig(0.099996, 3), "0.100");
    }
}
