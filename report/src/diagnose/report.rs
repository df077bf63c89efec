//! The diagnosis report: `report.html` (self-contained, figures as inline SVG) and one PNG per
//! figure, drawn with the shared renderer ([`crate::render`]).
//!
//! Figures (rates in °/h, time in hours from the first message, τ in s):
//! 1. the residual over the run: gyro minus the nominal simulation, after the parameter
//!    refit, and after the accepted effects, with the steps' record windows shaded;
//! 2. the residual's Allan deviation before and after the effects against the noise model;
//! 3. per accepted effect, the partial residual (final residual plus the effect's term)
//!    against the effect's fitted term: a slope-one line when the effect is right;
//! 4. where the refit residual sits: each step's z (mean over its noise-model σ) over time,
//!    with record steps shaded and the table's reversals marked, and step by step, against the
//!    level at which a step departs; means ± 2σ by direction, heating/cooling, temperature band
//!    and table-angle sector.

use std::fmt::Write as _;
use std::path::Path;

use bench_analysis::diagnose::Region;
use bench_physics::allan::AdevPoint;
use bench_physics::noise::bias_instability_adev;

use super::located::{located, Located};
use super::DiagnoseOutcome;
use crate::display;
use crate::render::plot::{colour, Axis, Item, Marker, Plot, Rule, Span};
use crate::render::{
    escape, figures_html, io_err, render, sig, Figure, ReportError, ReportFiles, STYLE,
};

fn deg_h(v: f64) -> f64 {
    display::RATE.of(v)
}

fn line(label: &str, c: plotters::style::RGBColor, points: Vec<(f64, f64)>) -> Item {
    Item::Line { label: Some(label.into()), colour: c, width: 1, dashed: false, points }
}

fn residual_figure(o: &DiagnoseOutcome) -> Figure {
    let d = &o.diagnosis;
    let s = &d.series;
    let h: Vec<f64> = s.time_s.iter().map(|t| display::HOURS.of(*t)).collect();
    let pts = |v: &[f64]| h.iter().zip(v).map(|(t, x)| (*t, deg_h(*x))).collect::<Vec<_>>();
    let mut p = Plot::new("Residual, bin means", Axis::linear("time, h"), Axis::linear("°/h"));
    p.spans = o
        .data
        .series
        .steps
        .iter()
        .filter(|st| bench_recording::message::is_record_label(&st.label))
        .map(|st| Span {
            x0: display::HOURS.of(st.start_s),
            x1: display::HOURS.of(st.end_s),
            colour: colour::GREY,
            label: "record windows".into(),
        })
        .collect();
    p.items.push(line("gyro − nominal simulation", colour::SKY, pts(&s.residual_nominal)));
    p.items.push(line("after the parameter refit", colour::ORANGE, pts(&s.residual_before)));
    p.items.push(line("after the effects", colour::BLUE, pts(&s.residual_after)));
    p.note = Some(format!(
        "RMS {} → {} → {} °/h",
        sig(deg_h(d.rms.nominal), 3),
        sig(deg_h(d.rms.before), 3),
        sig(deg_h(d.rms.after), 3)
    ));
    Figure {
        name: "fig1-residual",
        title: "Residual over the run",
        caption: "Gyro minus the nominal model driven by the recording's own table motion, \
                  temperatures and latitude (bin means), then after refitting the model's \
                  parameters, then after adding the effects found."
            .into(),
        panels: vec![p],
        size: (1280, 540),
    }
}

fn adev_points(pts: &[AdevPoint]) -> Vec<(f64, f64)> {
    pts.iter().map(|p| (p.tau_s, deg_h(p.adev))).collect()
}

fn allan_figure(o: &DiagnoseOutcome) -> Figure {
    let d = &o.diagnosis;
    let mut p = Plot::new("Residual Allan deviation", Axis::log("τ, s"), Axis::log("σ(τ), °/h"));
    p.items.push(line("before the effects", colour::ORANGE, adev_points(&d.adev_before)));
    p.items.push(line("after the effects", colour::BLUE, adev_points(&d.adev_after)));
    let taus: Vec<f64> =
        d.adev_before.iter().chain(&d.adev_after).map(|p| p.tau_s).fold(Vec::new(), |mut v, t| {
            if !v.iter().any(|x: &f64| (x - t).abs() < 1e-9 * t) {
                v.push(t);
            }
            v
        });
    let mut taus = taus;
    taus.sort_by(f64::total_cmp);
    let n = d.noise_after;
    let model = taus
        .iter()
        .map(|&t| {
            let avar = n.arw * n.arw / t
                + bias_instability_adev(t, n.flicker_floor).powi(2)
                + n.rrw * n.rrw * t / 3.0;
            (t, deg_h(avar.sqrt()))
        })
        .collect();
    p.items.push(Item::Line {
        label: Some("noise model".into()),
        colour: colour::BLACK,
        width: 1,
        dashed: true,
        points: model,
    });
    Figure {
        name: "fig2-allan",
        title: "Residual Allan deviation against the noise model",
        caption: "Overlapping Allan deviation of the bin-mean residual before and after the \
                  effects; the dashed line is the noise model (white + flicker) every test is \
                  judged against."
            .into(),
        panels: vec![p],
        size: (960, 540),
    }
}

fn effect_figures(o: &DiagnoseOutcome) -> Vec<Figure> {
    let d = &o.diagnosis;
    let s = &d.series;
    let mut panels = Vec::new();
    for (id, c) in &s.contributions {
        let mut p = Plot::new(
            id.key(),
            Axis::linear("effect's fitted term, °/h"),
            Axis::linear("residual + term, °/h"),
        );
        let points: Vec<_> =
            c.iter().zip(&s.residual_after).map(|(x, r)| (deg_h(*x), deg_h(r + x), None)).collect();
        let (lo, hi) = c.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(deg_h(*v)), b.max(deg_h(*v)))
        });
        p.items.push(Item::Markers {
            label: Some("bins".into()),
            colour: colour::SKY,
            shape: Marker::Circle,
            points,
        });
        p.items.push(line("slope one", colour::RED, vec![(lo, lo), (hi, hi)]));
        panels.push(p);
    }
    if panels.is_empty() {
        return Vec::new();
    }
    let w = 640 * panels.len().min(3) as u32;
    vec![Figure {
        name: "fig3-effects",
        title: "Residual against each effect's term",
        caption: "For each effect found, the final residual with the effect's own term added \
                  back, against that term: points along the slope-one line are explained by it."
            .into(),
        panels,
        size: (w.max(640), 540),
    }]
}

fn region_panel(title: &str, rs: &[Region]) -> Plot {
    // The class names on the axis, without the prefix they share (`angle 0..45°` → `0..45°`).
    let names =
        rs.iter().map(|r| r.name.strip_prefix("angle ").unwrap_or(&r.name).to_owned()).collect();
    let mut p =
        Plot::new(title, Axis::categories(title, names), Axis::linear("mean residual ± 2σ, °/h"));
    p.items.push(Item::Markers {
        label: None,
        colour: colour::BLUE,
        shape: Marker::Circle,
        points: rs
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let (m, s) = (deg_h(r.mean), deg_h(r.sigma));
                (i as f64, m, Some((m - 2.0 * s, m + 2.0 * s)))
            })
            .collect(),
    });
    p
}

/// The dashed ±threshold lines of a z axis from `x0` to `x1`.
fn z_threshold_lines(l: &Located, x0: f64, x1: f64) -> Item {
    let t = l.z_threshold;
    Item::Line {
        label: Some(format!("|z| = {} (α {} over the steps)", sig(t, 3), sig(l.alpha, 2))),
        colour: colour::BLACK,
        width: 1,
        dashed: true,
        points: vec![(x0, t), (x1, t), (f64::NAN, f64::NAN), (x0, -t), (x1, -t)],
    }
}

/// The located windows over time: each step's z as a level across its span, record steps
/// shaded and named by index, the table's reversals marked.
fn steps_over_time(o: &DiagnoseOutcome, l: &Located) -> Plot {
    let mut p = Plot::new(
        "mismatch over time, by step",
        Axis::linear("time, h"),
        Axis::linear("z (step mean / σ)"),
    );
    p.weight = 2;
    let h = |t: f64| display::HOURS.of(t);
    let records = l.windows.iter().filter(|w| w.record);
    p.spans = records
        .clone()
        .map(|w| Span {
            x0: h(w.start_s),
            x1: h(w.end_s),
            colour: colour::GREY,
            label: "record steps".into(),
        })
        .collect();
    p.marks = records.map(|w| (h(0.5 * (w.start_s + w.end_s)), format!("#{}", w.index))).collect();
    p.rules = l
        .reversals_s
        .iter()
        .map(|&t| Rule { x: h(t), colour: colour::PURPLE, label: "table reversals".into() })
        .collect();
    let levels = |departs: bool| -> Vec<(f64, f64)> {
        l.windows
            .iter()
            .filter(|w| l.departs(w) == departs)
            .flat_map(|w| [(h(w.start_s), w.z()), (h(w.end_s), w.z()), (f64::NAN, f64::NAN)])
            .collect()
    };
    for (departs, label, c) in
        [(false, "within the noise", colour::BLUE), (true, "departs", colour::RED)]
    {
        let points = levels(departs);
        if !points.is_empty() {
            p.items.push(Item::Line {
                label: Some(label.into()),
                colour: c,
                width: 3,
                dashed: false,
                points,
            });
        }
        // A dot at each window's middle: a step of a few seconds stays visible.
        let dots: Vec<_> = l
            .windows
            .iter()
            .filter(|w| l.departs(w) == departs)
            .map(|w| (h(0.5 * (w.start_s + w.end_s)), w.z(), None))
            .collect();
        p.items.push(Item::Markers { label: None, colour: c, shape: Marker::Circle, points: dots });
    }
    let end = o.data.series.steps.iter().map(|s| s.end_s).fold(0.0, f64::max);
    p.items.push(z_threshold_lines(l, 0.0, h(end)));
    if l.windows.is_empty() {
        p.note = Some("no steps in this recording".into());
    }
    p
}

/// The located windows by step: one bar of z per step, in time order.
fn steps_bars(l: &Located) -> Plot {
    let names = l.windows.iter().map(|w| w.name.clone()).collect();
    let mut p = Plot::new("by step", Axis::categories("step", names), Axis::linear("z"));
    p.weight = 2;
    for (departs, label, c) in
        [(false, "within the noise", colour::BLUE), (true, "departs", colour::RED)]
    {
        let points: Vec<(f64, f64)> = l
            .windows
            .iter()
            .enumerate()
            .filter(|(_, w)| l.departs(w) == departs)
            .map(|(i, w)| (i as f64, w.z()))
            .collect();
        if !points.is_empty() {
            p.items.push(Item::Bars { label: Some(label.into()), colour: c, width: 0.7, points });
        }
    }
    let n = l.windows.len() as f64;
    p.items.push(z_threshold_lines(l, -0.5, n - 0.5));
    p
}

fn location_figure(o: &DiagnoseOutcome) -> Figure {
    let l = &o.diagnosis.location;
    let located = located(o);
    let mut direction = region_panel("direction", &l.direction);
    direction.new_row = true;
    Figure {
        name: "fig4-location",
        title: "Where the refit residual sits",
        caption: format!(
            "Top: the residual after the parameter refit (before any effect) by step, as z = \
             the step's mean over its 1σ from the noise model: over time (record steps shaded \
             and numbered, the table's reversals dashed) and step by step; beyond the dashed \
             |z| = {} a step departs from the noise model ({} of {}). Bottom: its mean by \
             class, with 2σ bars: bars that miss zero locate the mismatch.",
            sig(located.z_threshold, 3),
            located.windows.iter().filter(|w| located.departs(w)).count(),
            located.windows.len()
        ),
        panels: vec![
            steps_over_time(o, &located),
            steps_bars(&located),
            direction,
            region_panel("thermal", &l.thermal),
            region_panel("temperature band", &l.temperature),
            region_panel("table angle", &l.angle),
        ],
        size: (2000, 1000),
    }
}

fn page(o: &DiagnoseOutcome, source: &str, figures: &[(Figure, String)]) -> String {
    let d = &o.diagnosis;
    let src = escape(source);
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=en>\n<head>\n<meta charset=utf-8>\n<title>Diagnosis: {src}\
         </title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>Diagnosis</h1>\n<p>Recording: \
         <b>{src}</b>; nominal model: {}; verdict: <b>{}</b>.</p>\n",
        escape(&o.nominal.2),
        d.verdict.key()
    );
    let _ = writeln!(
        h,
        "<ul><li>{} bins of {} s; noise model: ARW {} °/√h, flicker floor {} °/h; effective \
         independent bins n_eff = {}.</li><li>Residual RMS (bin means): nominal {} °/h, after \
         the parameter refit {} °/h, after the effects {} °/h{}.</li></ul>",
        d.n_bins,
        sig(o.options.bin_s, 3),
        sig(display::ARW.of(d.noise_after.arw), 3),
        sig(deg_h(d.noise_after.flicker_floor), 3),
        sig(d.n_eff, 3),
        sig(deg_h(d.rms.nominal), 3),
        sig(deg_h(d.rms.before), 3),
        sig(deg_h(d.rms.after), 3),
        match &o.resimulated {
            Some(r) => format!(
                "; re-simulated with the updated model {} °/h ({})",
                sig(deg_h(r.rms.nominal), 3),
                r.verdict.key()
            ),
            None => String::new(),
        }
    );
    h.push_str("<h2>Parameters</h2>\n<table><tr><th class=l>key</th><th>nominal</th><th>fitted ± 1σ</th><th>z</th></tr>\n");
    for u in &d.parameter_updates {
        let unit = display::model_key_unit(u.key);
        let nominal = escape(&display::value_like(unit.of(u.nominal), unit.of(u.sigma), unit.name));
        let _ = match &u.held {
            Some(reason) => writeln!(
                h,
                "<tr><td class=l>{}</td><td>{nominal}</td><td>held: {}</td><td>—</td></tr>",
                u.key.key(),
                escape(reason)
            ),
            None => writeln!(
                h,
                "<tr><td class=l>{}</td><td>{nominal}</td><td>{}</td><td>{}</td></tr>",
                u.key.key(),
                escape(&display::si_value_sigma(unit, u.fitted, u.sigma)),
                sig((u.fitted - u.nominal) / u.sigma, 2)
            ),
        };
    }
    let _ = writeln!(
        h,
        "</table><p class=note>Joint Wald statistic of the corrections {} (threshold {}).</p>",
        sig(d.parameters_wald.value, 3),
        sig(d.parameters_wald.threshold, 3)
    );
    h.push_str("<h2>Effects tested</h2>\n<table><tr><th class=l>effect</th><th class=l>parameters</th><th>W</th><th>threshold</th><th>ΔBIC</th><th>held-out z</th><th class=l>verdict</th></tr>\n");
    for f in &d.findings {
        // One line per parameter: each escaped, joined by real line breaks.
        let params = f
            .parameters
            .iter()
            .map(|p| {
                escape(&format!(
                    "{} = {}",
                    display::parameter_name(p.name),
                    display::si_value_sigma(display::for_si(p.unit), p.value, p.sigma)
                ))
            })
            .collect::<Vec<_>>()
            .join("<br>");
        let _ = writeln!(
            h,
            "<tr><td class=l title=\"{}\">{}</td><td class=l>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td class=l>{}</td></tr>",
            escape(f.effect.description()),
            f.effect.key(),
            params,
            sig(f.wald, 3),
            sig(f.threshold, 3),
            sig(f.delta_bic, 3),
            sig(f.holdout_z, 2),
            match &f.rejected_because {
                None if f.accepted => "<b class=ok>found</b>".to_owned(),
                None => "not needed".to_owned(),
                Some(why) => escape(why),
            }
        );
    }
    h.push_str("</table>\n");
    if !d.unexplained.is_empty() {
        h.push_str("<h2>Unexplained</h2><ul>");
        for u in &d.unexplained {
            let w: Vec<String> = u
                .windows_s
                .iter()
                .map(|(a, b)| format!("{}–{} s", sig(*a, 5), sig(*b, 5)))
                .collect();
            let _ = write!(
                h,
                "<li class=bad>{}: RMS {} °/h, correlates with {}</li>",
                escape(&w.join(", ")),
                sig(deg_h(u.rms), 3),
                escape(&u.correlates_with)
            );
        }
        h.push_str("</ul>\n");
    }
    h.push_str(&figures_html(figures));
    h.push_str("</body>\n</html>\n");
    h
}

/// Write `report.html` and the PNGs into `dir`.
pub fn write_report(
    o: &DiagnoseOutcome,
    source: &str,
    dir: &Path,
) -> Result<ReportFiles, ReportError> {
    let mut figs = vec![residual_figure(o), allan_figure(o)];
    figs.extend(effect_figures(o));
    figs.push(location_figure(o));
    let svgs = render(figs, dir)?;
    let pngs = svgs.iter().map(|(f, _)| dir.join(format!("{}.png", f.name))).collect();
    let html_path = dir.join("report.html");
    std::fs::write(&html_path, page(o, source, &svgs)).map_err(io_err(&html_path))?;
    Ok(ReportFiles { html: html_path, pngs })
}
