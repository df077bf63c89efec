//! The calibration report of `bench calibrate`: one self-contained HTML page and a PNG per
//! figure.
//!
//! [`write_report`] writes into a directory:
//!
//! - `report.html`: title and recording, the setting (site, model temperature), the coefficient
//!   table (joint fit ± σ, the seed's method, the truth and the errors when the recording
//!   carries a model), the seed's function errors Δk_t and Δk_dt, the thermal error removed,
//!   the IEEE 952 noise terms with their intervals, the thermal-lag result, the record windows,
//!   what the data lack, and the figures as inline SVG. No script, no external asset; every
//!   text from the recording is escaped.
//! - one PNG per figure (`fig1-raw-rate.png` … `fig9-angle-misclosure.png`), the same drawing
//!   rasterised.
//!
//! Figures (units: °/h, °C, °C/min, hours, τ in s; record windows shaded on time axes):
//!
//! 1. raw gyro rate over the run (bin means, ≤ 4000 points, with min–max envelope), table rate;
//! 2. temperature profile: chamber air, the gyro's sensor, the lagged model temperature;
//! 3. dT/dt of the model-temperature source;
//! 4. CW vs CCW plateau window means vs temperature, the seed's pair means K, k_t lines;
//! 5. fitted error functions k_t(T) and k_dt·dT/dt: joint (±2σ band), seed method, truth;
//! 6. ramp windows: uncalibrated vs calibrated error and the true thermal error (60 s bins);
//! 7. calibration residual over every window (60 s bins) with its RMS;
//! 8. Allan deviation with confidence intervals and the fitted N, B and K lines;
//! 9. angle misclosure per steady stretch (″), before and after the angle-domain calibration.
//!
//! Above the coefficients: the fit's verdict ([`super::quality`]) with each check and where the
//! residual strays; below the windows: what the steady-motion rule left out, and the time bases.
//!
//! Drawing uses `plotters` with its SVG backend and its bitmap backend; text is laid out and
//! rasterised by `ab_glyph` with DejaVu Sans embedded (`report/assets/fonts/`), so no system
//! font library is needed. PNGs are encoded by the pure-Rust `png` crate.

mod figures;
mod html;
mod series;

use std::path::Path;

use crate::render::io_err;
pub use crate::render::{ReportError, ReportFiles};

/// Write `report.html` (figures as embedded inline SVG) and one PNG per figure into `dir`
/// (created if missing). `source` is the recording's file name, for the title.
pub fn write_report(
    outcome: &super::CalibrationOutcome,
    source: &str,
    dir: &Path,
) -> Result<ReportFiles, ReportError> {
    let svgs = crate::render::render(figures::figures(outcome), dir)?;
    let pngs = svgs.iter().map(|(f, _)| dir.join(format!("{}.png", f.name))).collect();
    let page = html::page(outcome, source, &svgs);
    let html_path = dir.join("report.html");
    std::fs::write(&html_path, page).map_err(io_err(&html_path))?;
    Ok(ReportFiles { html: html_path, pngs })
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;
    use std::sync::OnceLock;

    use super::*;
    use crate::calibrate::{calibrate_recording, CalibrateSettings, CalibrationOutcome};

    /// The calibrated synthetic run ([`crate::testutil::short_run`]), shared by the tests.
    fn outcome() -> &'static CalibrationOutcome {
        static OUT: OnceLock<CalibrationOutcome> = OnceLock::new();
        OUT.get_or_init(|| {
            let rec = crate::testutil::short_run();
            let settings = CalibrateSettings { replicates: Some(40), ..Default::default() };
            let mut out = calibrate_recording(&rec, &settings).expect("calibrates");
            // A label with markup, as a recording may hold: it must come out escaped.
            let evil = "record <cw> & \"20C\"";
            out.data.spans[0].label = evil.into();
            out.calibration.windows[0].label = evil.into();
            out
        })
    }

    /// Width and height from a PNG's IHDR chunk, after checking the signature.
    fn png_size(bytes: &[u8]) -> (u32, u32) {
        assert!(bytes.len() > 33, "PNG too short");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR");
        let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
        (be(&bytes[16..20]), be(&bytes[20..24]))
    }

    #[test]
    fn report_holds_every_figure_and_the_coefficients() {
        let out = outcome();
        let dir = tempfile::tempdir().expect("tempdir");
        let target = dir.path().join("nested/report");
        let files = write_report(out, "short <run>.mcap", &target).expect("report written");

        let html = std::fs::read_to_string(&files.html).expect("html readable");
        assert_eq!(files.html, target.join("report.html"));
        let figs = figures::figures(out);
        assert_eq!(figs.len(), 9);
        assert_eq!(html.matches("<svg ").count(), figs.len(), "one inline SVG per figure");
        assert_eq!(html.matches("</svg>").count(), figs.len());
        for f in &figs {
            assert!(html.contains(&format!("<figure id=\"{}\">", f.name)), "{}", f.name);
        }
        // Self-contained: no script and nothing loaded from elsewhere.
        assert!(!html.contains("<script") && !html.contains("src=") && !html.contains("@import"));

        // Recording text is escaped, in the title and in the windows table.
        assert!(html.contains("short &lt;run&gt;.mcap"));
        assert!(!html.contains("short <run>"));
        assert!(html.contains("record &lt;cw&gt; &amp; &quot;20C&quot;"));
        assert!(!html.contains("record <cw>"));

        // The coefficient table holds the joint values in report units.
        let j = out.calibration.joint.as_ref().expect("joint fit on the short run");
        // Digits set by σ (display::value_sigma).
        use crate::display::{si_value_sigma, PPM, RATE, TEMP_COEFF};
        for (e, unit) in [(j.bias, RATE), (j.temp_coeff, TEMP_COEFF), (j.scale_factor_error, PPM)] {
            if e.held {
                // Held (this short, noisy run does not determine it): said so, not as measured.
                let v = crate::render::sig(e.value * unit.per_si, 4);
                assert!(html.contains(&format!("HELD at {v} — not estimated")), "held {v}");
                continue;
            }
            let v = si_value_sigma(unit, e.value, e.std_err);
            let v = v.trim_end_matches(unit.name).trim_end();
            assert!(html.contains(&format!("<td>{v}</td>")), "joint value {v} in the table");
        }
        // The summary near the top: what was determined and what held.
        assert!(html.contains("<h2>Summary</h2>") && html.contains("Determined: bias"));
        assert!(html.contains("On this run (the data it was fitted to)"));
        assert!(html.contains("°/h/(°C/min)"));

        // One PNG per figure, decodable header, the figure's pixel size.
        assert_eq!(files.pngs.len(), figs.len());
        for (p, f) in files.pngs.iter().zip(&figs) {
            assert_eq!(p, &target.join(format!("{}.png", f.name)));
            let bytes = std::fs::read(p).expect("png readable");
            assert_eq!(png_size(&bytes), f.size, "{}", p.display());
            // The whole image decodes to that many RGB pixels.
            let dec = png::Decoder::new(Cursor::new(&bytes));
            let mut reader = dec.read_info().expect("png header");
            let mut buf = vec![0; reader.output_buffer_size()];
            let info = reader.next_frame(&mut buf).expect("png data");
            assert_eq!((info.width, info.height), f.size);
            let px = &buf[..info.buffer_size()];
            // Not blank: some pixels are far from white (axes, text, curves).
            assert!(px.chunks(3).filter(|c| c.iter().all(|&v| v < 128)).count() > 500);
        }
    }

    #[test]
    fn figures_carry_the_expected_data() {
        let out = outcome();
        let figs = figures::figures(out);
        let names: Vec<&str> = figs.iter().map(|f| f.name).collect();
        assert_eq!(
            names,
            [
                "fig1-raw-rate",
                "fig2-temperature",
                "fig3-temperature-rate",
                "fig4-cw-ccw",
                "fig5-error-functions",
                "fig6-thermal-error",
                "fig7-residual",
                "fig8-allan",
                "fig9-angle-misclosure"
            ]
        );
        let points = |item: &crate::render::plot::Item| match item {
            crate::render::plot::Item::Line { points, .. } => points.len(),
            crate::render::plot::Item::Band { points, .. } => points.len(),
            crate::render::plot::Item::Markers { points, .. } => points.len(),
            crate::render::plot::Item::Bars { points, .. } => points.len(),
        };
        // Raw rate decimated to ≤ 4000 points, windows shaded.
        let raw = &figs[0].panels[0];
        assert!(raw.items.iter().all(|i| points(i) <= 4000 && points(i) > 100));
        assert_eq!(raw.spans.len(), out.data.spans.len());
        // Four plateau windows and two pair means.
        let cw_ccw = &figs[3].panels[0];
        let marks: Vec<usize> = cw_ccw
            .items
            .iter()
            .filter(|i| matches!(i, crate::render::plot::Item::Markers { .. }))
            .map(points)
            .collect();
        assert_eq!(marks, [2, 2, 2]);
        // Truth, joint and seed in both error-function panels.
        assert_eq!(figs[4].panels.len(), 2);
        assert!(out.truth.is_some());
        for p in &figs[4].panels {
            assert!(p.note.is_none(), "{:?}", p.note);
            assert_eq!(p.items.len(), 4);
        }
        // Thermal error: ramp windows only, three curves each.
        let ramps = out
            .calibration
            .windows
            .iter()
            .filter(|w| w.kind == bench_analysis::calibrate::WindowKind::Ramp)
            .count();
        assert_eq!(ramps, 2);
        assert_eq!(figs[5].panels[0].items.len(), 3 * ramps);
        // Residual RMS stated; Allan points with intervals and three lines.
        assert!(figs[6].panels[0].note.as_deref().is_some_and(|n| n.contains("RMS")));
        let allan = &figs[7].panels[0];
        match &allan.items[0] {
            crate::render::plot::Item::Markers { points, .. } => {
                assert!(points.len() >= 3);
                assert!(points
                    .iter()
                    .all(|(_, y, b)| b.is_some_and(|(lo, hi)| lo < *y && *y < hi)));
            }
            other => panic!("Allan points first, got {other:?}"),
        }
        assert_eq!(allan.items.len(), 4);
        // Angle misclosure: before and after, one line per stretch, the after RMS smaller.
        let mis = &figs[8];
        let a = out.calibration.angle.as_ref().expect("readings").as_ref().expect("angle fit");
        assert_eq!(mis.panels.len(), 2);
        for p in &mis.panels {
            assert_eq!(p.items.len(), a.misclosure.len());
        }
        let rms_of = |p: &crate::render::plot::Plot| -> f64 {
            let n = p.note.as_deref().expect("RMS note");
            n.trim_start_matches("RMS ").trim_end_matches(" ″").parse().expect("a number")
        };
        assert!(rms_of(&mis.panels[1]) < rms_of(&mis.panels[0]), "{:?}", mis.panels[1].note);
    }

    #[test]
    fn failed_analyses_still_give_every_figure() {
        use bench_analysis::AnalysisError;
        let mut out = outcome().clone();
        let err = || AnalysisError::Insufficient("test <failure>".into());
        out.truth = None;
        out.model = None;
        out.seed_model = None;
        out.calibration.joint = Err(err());
        out.calibration.seed = Err(err());
        out.calibration.allan = Err(err());
        out.calibration.lag = Some(Err(err()));
        out.calibration.missing.push("a note with <markup>".into());
        let dir = tempfile::tempdir().expect("tempdir");
        let files = write_report(&out, "x.mcap", dir.path()).expect("report written");
        let html = std::fs::read_to_string(&files.html).expect("html readable");
        assert_eq!(html.matches("<svg ").count(), 9);
        assert_eq!(files.pngs.len(), 9);
        assert!(html.contains("test &lt;failure&gt;") && !html.contains("test <failure>"));
        assert!(html.contains("<li>a note with &lt;markup&gt;</li>"));
        assert!(html.contains("No truth to compare with"));
    }

    #[test]
    fn an_unwritable_directory_is_an_io_error_with_its_path() {
        let out = outcome();
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("not-a-dir");
        std::fs::write(&file, b"x").expect("file");
        let err = write_report(out, "x.mcap", &file.join("sub")).expect_err("cannot create");
        match &err {
            ReportError::Io { path, .. } => assert_eq!(path, &file.join("sub")),
            other => panic!("expected Io, got {other:?}"),
        }
        assert!(err.to_string().contains("not-a-dir"));
    }
}
