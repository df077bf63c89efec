//! The HTML reports of `bench calibrate` and `bench diagnose`, rendered by a real headless
//! browser (Debian's Chromium, installed pinned by scripts/browser.sh, which scripts/test.sh
//! runs and whose path it passes as `BENCH_CHROMIUM`): no markup or escaped HTML shown as text,
//! every figure drawn with a size, every PNG the page links decoded by the browser, no
//! horizontal overflow, no two texts of a figure overlapping as drawn (every axis's tick labels
//! measured by their boxes), the diagnosis's location figure holding every located step (over
//! time and by step), and a screenshot of the page that is the size asked and not blank.
//! Skips, saying why, only when no Chromium can be found.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{bench, json, text_of};

const CHECK_JS: &str = include_str!("report_check.js");
const WINDOW: (u32, u32) = (1400, 2200);

/// The browser: `BENCH_CHROMIUM`, else `chromium` on the PATH; `None` when neither runs.
fn chromium() -> Option<PathBuf> {
    let candidate = std::env::var_os("BENCH_CHROMIUM")
        .filter(|p| !p.is_empty())
        .map_or_else(|| PathBuf::from("chromium"), PathBuf::from);
    let ok = Command::new(&candidate).arg("--version").output().is_ok_and(|o| o.status.success());
    ok.then_some(candidate)
}

fn headless(browser: &Path, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        "--virtual-time-budget=10000",
        &format!("--window-size={},{}", WINDOW.0, WINDOW.1),
        &format!("--user-data-dir={}", profile.display()),
    ]);
    c
}

/// What the browser rendered of `page` (report_check.js's JSON).
fn rendered(browser: &Path, page: &Path, profile: &Path) -> serde_json::Value {
    let html = std::fs::read_to_string(page).expect("report.html");
    assert!(html.contains("</body>"), "{} has no </body>", page.display());
    let probe = page.with_file_name("browser-check.html");
    std::fs::write(&probe, html.replace("</body>", &format!("<script>{CHECK_JS}</script></body>")))
        .expect("write the probe page");
    let out = headless(browser, profile)
        .arg("--dump-dom")
        .arg(format!("file://{}", probe.display()))
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&out.stdout);
    let start = dom.rfind("<pre id=\"bench-check\">").unwrap_or_else(|| {
        panic!("no result from the page; stderr:\n{}", String::from_utf8_lossy(&out.stderr))
    });
    let body = &dom[start + "<pre id=\"bench-check\">".len()..];
    let body = &body[..body.find("</pre>").expect("</pre>")];
    let json = body.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&");
    serde_json::from_str(&json).expect("the page's JSON")
}

/// A screenshot of `page`: (width, height, distinct colours, fraction of non-white pixels).
fn screenshot(browser: &Path, page: &Path, profile: &Path) -> (u32, u32, usize, f64) {
    let shot = page.with_file_name("screenshot.png");
    let out = headless(browser, profile)
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs");
    assert!(shot.exists(), "no screenshot; stderr:\n{}", String::from_utf8_lossy(&out.stderr));
    let decoder =
        png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).expect("screenshot")));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG frame");
    let channels = info.color_type.samples();
    assert!(info.bit_depth == png::BitDepth::Eight && channels >= 3, "{info:?}");
    let mut colours = std::collections::HashSet::new();
    let mut ink = 0usize;
    let pixels = buf[..info.buffer_size()].chunks_exact(channels);
    let n = pixels.len();
    for px in pixels {
        let rgb = (px[0], px[1], px[2]);
        colours.insert(rgb);
        if rgb.0 < 240 || rgb.1 < 240 || rgb.2 < 240 {
            ink += 1;
        }
    }
    (info.width, info.height, colours.len(), ink as f64 / n as f64)
}

/// The texts of any figure that overlap as the browser drew them (tick labels of every axis,
/// turned ones included, axis names, titles, legends, marks), one line per pair.
fn text_overlaps(r: &serde_json::Value, what: &str) -> Vec<String> {
    let figures = r["figure_texts"].as_array().expect("figure_texts");
    let mut bad = Vec::new();
    for f in figures {
        let texts = f["texts"].as_array().map_or(0, Vec::len);
        assert!(texts >= 10, "{what}: figure {} has {texts} texts: is it drawn?", f["id"]);
        for pair in f["overlaps"].as_array().expect("overlaps") {
            bad.push(format!("{what} {}: {} overlaps {}", f["id"], pair[0], pair[1]));
        }
    }
    bad
}

/// The location figure holds the located windows: its two step panels, every step of the
/// diagnosis's `location.steps` named on the by-step axis (a name cut to fit ends in `…` and
/// keeps the step's index), one bar per step, and the record steps numbered over time.
fn check_location(r: &serde_json::Value, diagnosis: &serde_json::Value, what: &str) {
    let fig = r["figure_texts"]
        .as_array()
        .and_then(|f| f.iter().find(|f| f["id"] == "fig4-location"))
        .unwrap_or_else(|| panic!("{what}: no fig4-location"));
    let texts: Vec<&str> =
        fig["texts"].as_array().expect("texts").iter().filter_map(|t| t[0].as_str()).collect();
    for title in ["mismatch over time, by step", "by step", "temperature band", "table angle"] {
        assert!(texts.contains(&title), "{what}: no panel `{title}` in {texts:?}");
    }
    let steps = diagnosis["location"]["steps"].as_array().expect("location.steps");
    assert!(steps.len() >= 10, "{what}: {} steps", steps.len());
    for s in steps {
        let name = s["name"].as_str().expect("step name");
        let shown = texts.iter().any(|t| {
            *t == name
                || t.strip_suffix('…').is_some_and(|head| {
                    name.starts_with(head) && head.split(' ').next() == name.split(' ').next()
                })
        });
        assert!(shown, "{what}: step `{name}` not on the by-step axis: {texts:?}");
    }
    // Bars: the blue (within the noise) and red (departs) rectangles, legend swatches included.
    let fills = &fig["rect_fills"];
    let bars = fills["#0072B2"].as_u64().unwrap_or(0) + fills["#D55E00"].as_u64().unwrap_or(0);
    assert!(bars as usize > steps.len(), "{what}: {bars} bars for {} steps: {fills}", steps.len());
    let numbered = texts.iter().filter(|t| t.starts_with('#') && !t.contains(' ')).count();
    assert!(numbered >= 3, "{what}: {numbered} record steps numbered over time: {texts:?}");
}

fn check_report(browser: &Path, dir: &Path, figures: usize) -> serde_json::Value {
    let page = dir.join("report.html");
    let profile = tempfile::tempdir().expect("profile dir");
    let r = rendered(browser, &page, profile.path());
    let what = page.display();
    assert_eq!(
        r["markup_in_text"].as_array().map(Vec::len),
        Some(0),
        "{what}: markup or escaped HTML shown as text: {}",
        r["markup_in_text"]
    );
    assert_eq!(r["figures"].as_u64(), Some(figures as u64), "{what}: {r}");
    let svgs = r["svgs"].as_array().expect("svgs");
    assert_eq!(svgs.len(), figures, "{what}: {r}");
    for s in svgs {
        let (w, h) = (s[0].as_f64().unwrap_or(0.0), s[1].as_f64().unwrap_or(0.0));
        assert!(w >= 300.0 && h >= 150.0 && w <= f64::from(WINDOW.0), "{what}: figure {w}×{h}");
    }
    let images = r["images"].as_array().expect("images");
    assert_eq!(images.len(), figures, "{what}: one PNG per figure: {r}");
    for i in images {
        let (w, h) = (i[1].as_u64().unwrap_or(0), i[2].as_u64().unwrap_or(0));
        assert!(w >= 300 && h >= 150 && w <= 4000 && h <= 2000, "{what}: image {i}");
    }
    let (sw, iw) = (r["scroll_width"].as_u64(), r["inner_width"].as_u64());
    assert!(sw <= iw, "{what}: the page overflows horizontally ({sw:?} > {iw:?})");

    let (w, h, colours, ink) = screenshot(browser, &page, profile.path());
    assert_eq!((w, h), WINDOW, "{what}: screenshot size");
    assert!(
        colours > 50 && ink > 0.02,
        "{what}: screenshot blank? {colours} colours, {ink:.3} ink"
    );
    eprintln!(
        "{what}: {figures} figures, {} PNGs loaded, screenshot {w}×{h} with {colours} colours, \
         {:.1} % ink",
        images.len(),
        100.0 * ink
    );
    r
}

#[test]
fn reports_render_in_a_headless_browser() {
    let Some(browser) = chromium() else {
        eprintln!(
            "SKIPPED reports_render_in_a_headless_browser: no chromium (set BENCH_CHROMIUM, or run \
             scripts/test.sh, which installs it with scripts/browser.sh)"
        );
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let recordings = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings");
    let null = recordings.join("demo-null.mcap");
    let opr = recordings.join("demo-once-per-revolution.mcap");

    let cal = bench(&["calibrate", null.to_str().expect("path"), "-o", "cal", "-q"], d);
    assert_eq!(cal.status.code(), Some(0), "{}", String::from_utf8_lossy(&cal.stderr));
    let diag = bench(
        &["diagnose", opr.to_str().expect("path"), "-o", "diag", "-q", "--json", "diag.json"],
        d,
    );
    assert_eq!(diag.status.code(), Some(7), "{}", String::from_utf8_lossy(&diag.stderr));

    let cal = check_report(&browser, &d.join("cal"), 9);
    let r = check_report(&browser, &d.join("diag"), 4);

    // A lab's run over -40..+60 °C (the independent writer's): ten temperature bands and 42
    // steps on the location figure's axes, none of their labels touching.
    let lab = bench_tests::lab_fixture("lab-null", 1, &[]);
    let diag = bench(
        &["diagnose", lab.to_str().expect("path"), "-o", "lab", "-q", "--json", "lab.json"],
        d,
    );
    assert!(matches!(diag.status.code(), Some(0 | 6 | 7)), "{}", text_of(&diag));
    let figures = std::fs::read_dir(d.join("lab"))
        .expect("lab report")
        .filter(|e| e.as_ref().is_ok_and(|e| e.path().extension().is_some_and(|x| x == "png")))
        .count();
    let lab_r = check_report(&browser, &d.join("lab"), figures);
    let j = json(&d.join("lab.json"));
    assert_eq!(j["location"]["temperature"].as_array().map(Vec::len), Some(10), "{j:#}");

    let mut bad = text_overlaps(&cal, "calibration report");
    bad.extend(text_overlaps(&r, "diagnosis report"));
    bad.extend(text_overlaps(&lab_r, "lab diagnosis report"));
    assert!(bad.is_empty(), "{} pairs of texts overlap:\n{}", bad.len(), bad.join("\n"));
    check_location(&r, &json(&d.join("diag.json")), "diagnosis report");
    check_location(&lab_r, &j, "lab diagnosis report");
}
