//! HTML for a compensation — the verification report of `bench verify`, and the section of the
//! calibration report that says what a calibration does to a run — and the figure of the
//! windows' errors before and after.

use std::fmt::Write as _;
use std::path::Path;

use bench_analysis::compensation::Compensation;
use bench_physics::units::DEG_PER_H;

use crate::render::plot::{colour, Axis, Item, Marker, Plot};
use crate::render::{escape, figures_html, io_err, sig, Figure, STYLE};
use crate::verify::{summary_lines, VerifyOutcome};
use crate::{ReportError, ReportFiles};

/// The figure: each window's mean error before and after compensation (°/h) at its mid-time,
/// the compensated one with ±2σ (calibration and noise).
pub(crate) fn figure(c: &Compensation, name: &'static str, run: &str) -> Figure {
    let mut p = Plot::new(
        format!("Error per record window, {run}"),
        Axis::linear("window mid-time, h"),
        Axis::linear("mean error, °/h"),
    );
    let mid =
        |w: &bench_analysis::compensation::WindowError| 0.5 * (w.span_s.0 + w.span_s.1) / 3600.0;
    p.items.push(Item::Markers {
        label: Some("uncompensated".into()),
        colour: colour::GREY,
        shape: Marker::Cross,
        points: c.windows.iter().map(|w| (mid(w), w.uncompensated / DEG_PER_H, None)).collect(),
    });
    p.items.push(Item::Markers {
        label: Some("compensated, ±2σ of what the calibration states".into()),
        colour: colour::BLUE,
        shape: Marker::Circle,
        points: c
            .windows
            .iter()
            .map(|w| {
                let s = 2.0 * w.sigma_calibration.hypot(w.sigma_noise) / DEG_PER_H;
                let y = w.compensated / DEG_PER_H;
                (mid(w), y, Some((y - s, y + s)))
            })
            .collect(),
    });
    p.note = Some(format!(
        "RMS {} → {} °/h",
        sig(c.rms_uncompensated / DEG_PER_H, 3),
        sig(c.rms_compensated / DEG_PER_H, 3)
    ));
    Figure {
        name,
        title: "Error per record window, before and after compensation",
        caption: format!(
            "The mean of gyro rate minus the table's rate (Earth's rate removed) over each record \
             window's steady part, without compensation and with the calibration applied; the \
             bars are ±2σ of what the calibration states there (its covariance through the \
             window's mean regressors, and the gyro's noise over the window). Run: {run}."
        ),
        panels: vec![p],
        size: (960, 540),
    }
}

/// The per-window table and the summary lines of `c`, as HTML.
pub(crate) fn compensation_html(h: &mut String, c: &Compensation) {
    let _ = writeln!(h, "<ul>");
    for l in summary_lines(c) {
        let _ = writeln!(h, "<li>{}</li>", escape(&l));
    }
    let _ = writeln!(
        h,
        "</ul>\n<table>\n<tr><th class=l>window</th><th>mean T, °C</th><th>dT/dt, °C/min</th>\
         <th>uncompensated, °/h</th><th>compensated, °/h</th><th>σ calibration, °/h</th>\
         <th>σ noise, °/h</th><th>z</th></tr>"
    );
    for (i, w) in c.windows.iter().enumerate() {
        let cls = if w.z.abs() > c.z_threshold { " class=bad" } else { "" };
        let _ = writeln!(
            h,
            "<tr{}><td class=l>{}</td><td>{:.2}</td><td>{:+.3}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{:+.2}</td></tr>",
            if i == c.worst { " style=\"font-weight:bold\"" } else { cls },
            escape(&w.label),
            w.mean_temp_c,
            w.mean_rate_c_s * 60.0,
            sig(w.uncompensated / DEG_PER_H, 3),
            sig(w.compensated / DEG_PER_H, 3),
            sig(w.sigma_calibration / DEG_PER_H, 2),
            sig(w.sigma_noise / DEG_PER_H, 2),
            w.z
        );
    }
    let _ = writeln!(h, "</table>");
}

/// Write `report.html` and its figure's PNG for a verification into `dir`.
pub fn write_verify_report(
    v: &VerifyOutcome,
    recording: &str,
    calibration: &str,
    dir: &Path,
) -> Result<ReportFiles, ReportError> {
    let svgs =
        crate::render::render(vec![figure(&v.compensation, "fig1-window-errors", recording)], dir)?;
    let pngs = svgs.iter().map(|(f, _)| dir.join(format!("{}.png", f.name))).collect();
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n\
         <meta name=viewport content=\"width=device-width, initial-scale=1\">\n\
         <title>Verification: {r}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n\
         <h1>Calibration verification</h1>\n<p>Run: <b>{r}</b>; calibration: <b>{c}</b> (made on \
         {on}).</p>\n<h2 class={cls}>{verdict}</h2>\n",
        r = escape(recording),
        c = escape(calibration),
        on = escape(&v.calibration.source.recording),
        cls = if v.verdict == crate::verify::VerifyVerdict::Pass { "ok" } else { "bad" },
        verdict = escape(v.verdict.text()),
    );
    if !v.calibration.held.is_empty() {
        let _ =
            writeln!(h, "<p>Held in the calibration (not determined when it was made):</p>\n<ul>");
        for (k, e) in &v.calibration.held {
            let _ = writeln!(h, "<li><b>{}</b>: {}</li>", escape(k), escape(&e.reason));
        }
        let _ = writeln!(h, "</ul>");
    }
    if let Some(a) = &v.acceptance {
        let _ = writeln!(
            h,
            "<p>Acceptance: the bias after compensation within {} °/h in every window: <b>{}</b> \
             (worst: {}).</p>",
            sig(a.limit / DEG_PER_H, 4),
            a.result.key(),
            escape(&a.window)
        );
    }
    compensation_html(&mut h, &v.compensation);
    h.push_str(&figures_html(&svgs));
    h.push_str("</body>\n</html>\n");
    let html = dir.join("report.html");
    std::fs::write(&html, h).map_err(io_err(&html))?;
    Ok(ReportFiles { html, pngs })
}
