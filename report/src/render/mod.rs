//! Report drawing shared by `bench calibrate` and `bench diagnose`: figures described as
//! [`plot::Plot`] panels, each drawn by `plotters` to an SVG string (inlined in the HTML page)
//! and to a PNG file, in parallel.
//!
//! Text is laid out and rasterised by `ab_glyph` with DejaVu Sans embedded
//! (`report/assets/fonts/`), so no system font library is needed; PNGs are encoded by the
//! pure-Rust `png` crate.

pub(crate) mod plot;
mod ticks;

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use plot::Plot;

/// `s` with `& < > " '` replaced by entities, safe in text and attribute values.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `x` to `digits` significant digits: plain between 1e-3 and 1e5, else `1.23e-5`; `n/a`
/// when not finite.
pub(crate) fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return "n/a".into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let digits = digits.max(1);
    let a = x.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{x:.prec$e}", prec = digits - 1);
    }
    // The exponent after rounding to `digits` (9.9996 → 1.000e1), so the digits are right.
    let e = format!("{a:.prec$e}", prec = digits - 1);
    let exp: i32 = e.split_once('e').and_then(|(_, p)| p.parse().ok()).unwrap_or(0);
    let decimals = (digits as i32 - 1 - exp).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The pages' style sheet.
pub(crate) const STYLE: &str = "\
body{font-family:'DejaVu Sans',Verdana,Arial,sans-serif;margin:2em auto;max-width:1320px;\
padding:0 1em;color:#1e1e1e;line-height:1.4}\
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.25em;margin-top:1.6em;\
border-bottom:1px solid #ccc}\
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}\
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right;vertical-align:top}\
th{background:#f2f2f2}td.l,th.l{text-align:left}\
.note{color:#555;font-size:.9em}.bad{color:#b00}.ok{color:#070}\
figure{margin:1.5em 0}figure svg{max-width:100%;height:auto;border:1px solid #ddd}\
figcaption{font-size:.9em;color:#333;max-width:70em}\
ul.missing li{margin:.2em 0}";

/// The figures as HTML: a numbered `<figure>` each, its SVG inline and a link to its PNG.
pub(crate) fn figures_html(figures: &[(Figure, String)]) -> String {
    use std::fmt::Write as _;
    let mut h = String::new();
    for (i, (f, svg)) in figures.iter().enumerate() {
        let _ = writeln!(
            h,
            "<figure id=\"{name}\">\n<h3>Figure {n}. {title}</h3>\n{svg}<figcaption>{caption} \
             (<a href=\"{name}.png\">PNG</a>)</figcaption>\n</figure>",
            name = f.name,
            n = i + 1,
            title = escape(f.title),
            caption = escape(&f.caption),
        );
    }
    h
}

/// One figure of a report.
#[derive(Debug, Clone)]
pub(crate) struct Figure {
    /// File stem of the PNG (e.g. `fig1-raw-rate`).
    pub name: &'static str,
    /// Heading.
    pub title: &'static str,
    /// What the figure shows, plain text.
    pub caption: String,
    /// Panels, left to right.
    pub panels: Vec<Plot>,
    /// Pixel size.
    pub size: (u32, u32),
}

/// Files written by a report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReportFiles {
    /// The HTML page.
    pub html: PathBuf,
    /// One PNG per figure, in figure order.
    pub pngs: Vec<PathBuf>,
}

/// Why a report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file or the directory could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A PNG could not be encoded.
    #[error("cannot encode {path}: {source}")]
    Png {
        /// The PNG's path.
        path: PathBuf,
        /// The cause.
        #[source]
        source: png::EncodingError,
    },
    /// The embedded font could not be loaded for drawing text.
    #[error("the report's embedded font (DejaVu Sans) could not be loaded")]
    Font,
    /// A figure could not be drawn.
    #[error("figure `{figure}` ({format}): {source}")]
    Plot {
        /// The figure's file stem.
        figure: &'static str,
        /// `svg` or `png`.
        format: &'static str,
        /// The drawing backend's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> ReportError + '_ {
    move |source| ReportError::Io { path: path.to_path_buf(), source }
}

/// Encode packed RGB pixels as a PNG file at `path`.
fn write_png(path: &Path, rgb: &[u8], (w, h): (u32, u32)) -> Result<(), ReportError> {
    let file = File::create(path).map_err(io_err(path))?;
    let mut out = BufWriter::new(file);
    let png_err = |source| ReportError::Png { path: path.to_path_buf(), source };
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        let mut writer = enc.write_header().map_err(png_err)?;
        writer.write_image_data(rgb).map_err(png_err)?;
        writer.finish().map_err(png_err)?;
    }
    out.flush().map_err(io_err(path))
}

/// Draw `figs` into `dir` (created if missing): one PNG each; returns each figure with its
/// SVG text, for the page.
pub(crate) fn render(figs: Vec<Figure>, dir: &Path) -> Result<Vec<(Figure, String)>, ReportError> {
    if !plot::register_fonts() {
        return Err(ReportError::Font);
    }
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    // Draw every figure twice (SVG text, RGB pixels) in parallel: rasterising dominates.
    type Drawn = Result<(String, Vec<u8>), ReportError>;
    let drawn: Vec<Drawn> = std::thread::scope(|s| {
        let handles: Vec<_> = figs
            .iter()
            .map(|f| {
                s.spawn(move || -> Drawn {
                    let svg = plot::to_svg(&f.panels, f.size).map_err(|source| {
                        ReportError::Plot { figure: f.name, format: "svg", source }
                    })?;
                    let rgb = plot::to_rgb(&f.panels, f.size).map_err(|source| {
                        ReportError::Plot { figure: f.name, format: "png", source }
                    })?;
                    Ok((svg, rgb))
                })
            })
            .collect();
        handles
            .into_iter()
            .zip(&figs)
            .map(|(h, f)| {
                h.join().unwrap_or_else(|_| {
                    Err(ReportError::Plot {
                        figure: f.name,
                        format: "svg/png",
                        source: "the drawing thread panicked".into(),
                    })
                })
            })
            .collect()
    });

    let mut svgs = Vec::with_capacity(figs.len());
    for (f, d) in figs.into_iter().zip(drawn) {
        let (svg, rgb) = d?;
        let path = dir.join(format!("{}.png", f.name));
        write_png(&path, &rgb, f.size)?;
        svgs.push((f, svg));
    }
    Ok(svgs)
}
