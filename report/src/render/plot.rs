//! A small plot description and its renderer: one description drawn by `plotters` to an SVG
//! string (for the HTML page) and to an RGB bitmap (for the PNG), so both show the same figure.
//!
//! Text goes through `plotters`' `ab_glyph` path with DejaVu Sans embedded in the binary: no
//! system font, fontconfig or freetype is needed to lay out or rasterise a label.

use std::sync::OnceLock;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::ticks;

/// DejaVu Sans (Bitstream Vera licence, `report/assets/fonts/DejaVu-LICENSE.txt`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the embedded font under the family names `plotters` asks for. Idempotent; returns
/// whether the font could be read.
pub(crate) fn register_fonts() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        ["sans-serif", "serif", "monospace"]
            .iter()
            .all(|name| plotters::style::register_font(name, FontStyle::Normal, FONT).is_ok())
    })
}

/// Colours of the report (a colour-blind-safe set, Okabe–Ito).
pub(crate) mod colour {
    use plotters::style::RGBColor;
    /// Blue.
    pub const BLUE: RGBColor = RGBColor(0, 114, 178);
    /// Vermillion.
    pub const RED: RGBColor = RGBColor(213, 94, 0);
    /// Bluish green.
    pub const GREEN: RGBColor = RGBColor(0, 158, 115);
    /// Orange.
    pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
    /// Reddish purple.
    pub const PURPLE: RGBColor = RGBColor(204, 121, 167);
    /// Sky blue.
    pub const SKY: RGBColor = RGBColor(86, 180, 233);
    /// Near black.
    pub const BLACK: RGBColor = RGBColor(30, 30, 30);
    /// Grey.
    pub const GREY: RGBColor = RGBColor(120, 120, 120);
}

/// One axis.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    /// Description with unit.
    pub label: String,
    /// Logarithmic scale (only positive values are drawn).
    pub log: bool,
    /// Fixed range; `None` fits the data.
    pub range: Option<(f64, f64)>,
    /// Named categories at 0, 1, 2, …: a category axis, labelled by name at whole numbers only.
    pub categories: Vec<String>,
}

impl Axis {
    /// A linear axis fitted to the data.
    pub fn linear(label: impl Into<String>) -> Self {
        Self { label: label.into(), log: false, range: None, categories: Vec::new() }
    }
    /// A category axis: `names[i]` at `i`, nothing between.
    pub fn categories(label: impl Into<String>, names: Vec<String>) -> Self {
        let n = names.len().max(1) as f64;
        Self { label: label.into(), log: false, range: Some((-0.5, n - 0.5)), categories: names }
    }
    /// A logarithmic axis fitted to the data.
    pub fn log(label: impl Into<String>) -> Self {
        Self { label: label.into(), log: true, range: None, categories: Vec::new() }
    }
}

/// Marker shapes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Marker {
    /// Filled circle.
    Circle,
    /// Filled triangle.
    Triangle,
    /// Diagonal cross.
    Cross,
}

/// A marker at `(x, y)` with an optional vertical error bar `(low, high)`.
pub(crate) type MarkerPoint = (f64, f64, Option<(f64, f64)>);

/// Something drawn in a panel; points are `(x, y)` in axis units. Non-finite points (and, on a
/// log axis, non-positive ones) are skipped.
#[derive(Debug, Clone)]
pub(crate) enum Item {
    /// A polyline.
    Line {
        /// Legend entry.
        label: Option<String>,
        /// Colour.
        colour: RGBColor,
        /// Stroke width, px.
        width: u32,
        /// Dashed.
        dashed: bool,
        /// Points in drawing order.
        points: Vec<(f64, f64)>,
    },
    /// A filled band between two curves sampled at the same x.
    Band {
        /// Legend entry.
        label: Option<String>,
        /// Colour (drawn translucent).
        colour: RGBColor,
        /// `(x, low, high)`.
        points: Vec<(f64, f64, f64)>,
    },
    /// Vertical bars from zero to `y`, centred on `x`, `width` x units wide.
    Bars {
        /// Legend entry.
        label: Option<String>,
        /// Colour.
        colour: RGBColor,
        /// Bar width, x units.
        width: f64,
        /// `(x, y)`.
        points: Vec<(f64, f64)>,
    },
    /// Markers, optionally with vertical error bars.
    Markers {
        /// Legend entry.
        label: Option<String>,
        /// Colour.
        colour: RGBColor,
        /// Shape.
        shape: Marker,
        /// `(x, y, Some((low, high)))`.
        points: Vec<MarkerPoint>,
    },
}

/// A shaded x interval (e.g. a record window on a time axis).
#[derive(Debug, Clone)]
pub(crate) struct Span {
    /// Start, x units.
    pub x0: f64,
    /// End, x units.
    pub x1: f64,
    /// Colour (drawn translucent).
    pub colour: RGBColor,
    /// Legend entry; spans sharing a label share one entry.
    pub label: String,
}

/// A vertical line across a panel at `x` (e.g. a table reversal on a time axis).
#[derive(Debug, Clone)]
pub(crate) struct Rule {
    /// Where, x units.
    pub x: f64,
    /// Colour.
    pub colour: RGBColor,
    /// Legend entry; rules sharing a label share one entry.
    pub label: String,
}

/// One panel.
#[derive(Debug, Clone)]
pub(crate) struct Plot {
    /// Panel caption.
    pub title: String,
    /// x axis.
    pub x: Axis,
    /// y axis.
    pub y: Axis,
    /// Shaded x intervals, drawn under everything.
    pub spans: Vec<Span>,
    /// Contents, drawn in order.
    pub items: Vec<Item>,
    /// Text shown inside the panel (e.g. why it is empty, or an RMS).
    pub note: Option<String>,
    /// Vertical lines across the panel, drawn over the spans.
    pub rules: Vec<Rule>,
    /// Short texts along the bottom of the plotting area at x (e.g. each shaded span's name);
    /// one that would touch the one before is left out.
    pub marks: Vec<(f64, String)>,
    /// This panel starts a new row of the figure.
    pub new_row: bool,
    /// Width in its row, relative to the row's other panels.
    pub weight: u32,
}

impl Plot {
    /// An empty panel.
    pub fn new(title: impl Into<String>, x: Axis, y: Axis) -> Self {
        Self {
            title: title.into(),
            x,
            y,
            spans: Vec::new(),
            items: Vec::new(),
            note: None,
            rules: Vec::new(),
            marks: Vec::new(),
            new_row: false,
            weight: 1,
        }
    }
}

fn usable(v: f64, log: bool) -> bool {
    v.is_finite() && (!log || v > 0.0)
}

fn point_ok(p: (f64, f64), x: &Axis, y: &Axis) -> bool {
    usable(p.0, x.log) && usable(p.1, y.log)
}

/// The drawn range of an axis from the values seen, padded; a fixed range wins.
fn fit_range(axis: &Axis, values: impl Iterator<Item = f64>) -> (f64, f64) {
    if let Some(r) = axis.range {
        return r;
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| usable(*v, axis.log)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if axis.log {
        if !(lo.is_finite() && hi.is_finite()) {
            return (0.1, 10.0);
        }
        if hi / lo >= 100.0 {
            return decades(lo, hi);
        }
        // Under two decades: the data with a margin, down to a power of ten at least so that
        // the axis has a labelled decade (its 1, 2, 5 labelled too, see `tick_label`).
        let decade = 10f64.powf(hi.log10().floor());
        ((lo / 1.2).min(decade), hi * 1.2)
    } else {
        if !(lo.is_finite() && hi.is_finite()) {
            return (0.0, 1.0);
        }
        let span = hi - lo;
        if span <= 1e-12 * lo.abs().max(hi.abs()).max(f64::MIN_POSITIVE) {
            let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
            return (lo - d, hi + d);
        }
        (lo - 0.04 * span, hi + 0.04 * span)
    }
}

impl Plot {
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for item in &self.items {
            match item {
                Item::Line { points, .. } => {
                    for &p in points.iter().filter(|p| point_ok(**p, &self.x, &self.y)) {
                        xs.push(p.0);
                        ys.push(p.1);
                    }
                }
                Item::Band { points, .. } => {
                    for &(x, lo, hi) in points {
                        if usable(x, self.x.log) {
                            xs.push(x);
                            ys.extend([lo, hi]);
                        }
                    }
                }
                Item::Bars { points, width, .. } => {
                    for &p in points.iter().filter(|p| point_ok(**p, &self.x, &self.y)) {
                        xs.extend([p.0 - 0.5 * width, p.0 + 0.5 * width]);
                        ys.extend([0.0, p.1]);
                    }
                }
                Item::Markers { points, .. } => {
                    for &(x, y, bar) in points {
                        if point_ok((x, y), &self.x, &self.y) {
                            xs.push(x);
                            ys.push(y);
                            if let Some((lo, hi)) = bar {
                                ys.extend([lo, hi]);
                            }
                        }
                    }
                }
            }
        }
        for s in &self.spans {
            xs.extend([s.x0, s.x1]);
        }
        let (y0, mut y1) = fit_range(&self.y, ys.into_iter());
        // Room at the top for the legend (upper left) and the note (upper right), so neither
        // covers the data.
        let mut entries: Vec<&str> = self.spans.iter().map(|s| s.label.as_str()).collect();
        entries.extend(self.rules.iter().map(|r| r.label.as_str()));
        entries.retain(|l| !l.is_empty());
        entries.sort_unstable();
        entries.dedup();
        let entries = entries.len()
            + self
                .items
                .iter()
                .filter(|i| match i {
                    Item::Line { label, .. }
                    | Item::Band { label, .. }
                    | Item::Bars { label, .. }
                    | Item::Markers { label, .. } => label.is_some(),
                })
                .count();
        if (entries > 0 || self.note.is_some()) && !self.y.log && self.y.range.is_none() {
            // Two lines' worth, more for a longer note or a legend of three entries or more.
            let lines = self.note.as_deref().map_or(0, |n| n.lines().count());
            let lines = lines.max(2).max(entries);
            y1 += (y1 - y0) * (0.06 * lines as f64 + 0.06);
        }
        (fit_range(&self.x, xs.into_iter()), (y0, y1))
    }
}

/// `(lo, hi)` widened to whole decades (at least one), so that a log axis has labels.
pub(crate) fn decades(lo: f64, hi: f64) -> (f64, f64) {
    let a = lo.log10().floor();
    let b = hi.log10().ceil().max(a + 1.0);
    (10f64.powf(a), 10f64.powf(b))
}

/// Tick label: up to 6 significant digits, trailing zeros trimmed, exponent form outside
/// 1e-3..1e6.
pub(crate) fn tick(v: &f64) -> String {
    let v = *v;
    if v == 0.0 || !v.is_finite() {
        return if v.is_finite() { "0".into() } else { v.to_string() };
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:.2e}");
        // 1.00e-5 → 1e-5, 2.50e4 → 2.5e4
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        let m = m.trim_end_matches('0').trim_end_matches('.');
        return format!("{m}e{e}");
    }
    let decimals = (5 - a.log10().floor() as i32).clamp(0, 9) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        s
    }
}

/// A tick's label: a category's name at a whole number (nothing between); on a log axis of a
/// few decades (`decades`, rounded: 0 under ≈ 3×) only 1, 2 and 5 of each decade, or every
/// whole mantissa when under one; else [`tick`].
fn tick_label(v: f64, span: f64, decades: Option<usize>, categories: &[String]) -> String {
    if !categories.is_empty() {
        let i = v.round();
        return match categories.get(i.max(0.0) as usize) {
            Some(name) if (v - i).abs() < 1e-6 && i >= 0.0 => name.clone(),
            _ => String::new(),
        };
    }
    if let (Some(n), true) = (decades, v > 0.0) {
        // Under a decade every whole mantissa, else 1, 2 and 5.
        let m = v / 10f64.powf(v.log10().floor());
        let whole = (m - m.round()).abs() < 1e-6 * m;
        if !(whole && (n == 0 || [1.0, 2.0, 5.0, 10.0].contains(&m.round()))) {
            return String::new();
        }
    }
    // Key points computed as multiples of a step can miss zero by rounding (1.7e-18).
    tick(&if v.abs() < 1e-9 * span { 0.0 } else { v })
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Draw `plot` into `area`.
fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, plot: &Plot) -> DrawResult<DB> {
    let ((mut x0, mut x1), (mut y0, mut y1)) = plot.ranges();
    // A log range from a power of ten: plotters finds its first key point as 10^ceil(log10
    // start), which rounding can put a decade up (log10(0.001) = -2.9999999999999996), losing
    // the labels of the first decade. A hair wider keeps the power of ten inside.
    if plot.x.log {
        (x0, x1) = (x0 * (1.0 - 1e-9), x1 * (1.0 + 1e-9));
    }
    if plot.y.log {
        (y0, y1) = (y0 * (1.0 - 1e-9), y1 * (1.0 + 1e-9));
    }
    // Category names too wide to stand side by side are turned: the label area grows to hold
    // them, up to a third of the panel's height (longer names are cut).
    let (w, h) = area.dim_in_pixel();
    let label_style = label_font();
    let width_of = |t: &str| area.estimate_text_size(t, &label_style).map_or(0, |(w, _)| w as i32);
    let x_names = ticks::category_labels(
        &plot.x.categories,
        w as i32 - MARGIN_PX - MARGIN_RIGHT_PX - Y_LABEL_AREA_PX,
        h as i32 / 3,
        &width_of,
    );
    let x_area = match &x_names {
        ticks::CategoryLabels::Upright => X_LABEL_AREA_PX,
        ticks::CategoryLabels::Turned { len_px, .. } => X_LABEL_AREA_PX - 16 + len_px,
    };
    let mut b = ChartBuilder::on(area);
    b.caption(&plot.title, ("sans-serif", 17))
        .margin(MARGIN_PX)
        .margin_right(MARGIN_RIGHT_PX)
        .x_label_area_size(x_area)
        .y_label_area_size(Y_LABEL_AREA_PX);
    let ys = (y0, y1);
    let log = |a: f64, b: f64| LogOnce((a..b).log_scale().into());
    match (plot.x.log, plot.y.log) {
        (false, false) => draw_in(b.build_cartesian_2d(x0..x1, y0..y1)?, area, plot, ys, &x_names),
        (true, true) => {
            draw_in(b.build_cartesian_2d(log(x0, x1), log(y0, y1))?, area, plot, ys, &x_names)
        }
        (true, false) => {
            draw_in(b.build_cartesian_2d(log(x0, x1), y0..y1)?, area, plot, ys, &x_names)
        }
        (false, true) => {
            draw_in(b.build_cartesian_2d(x0..x1, log(y0, y1))?, area, plot, ys, &x_names)
        }
    }
}

/// A log axis whose key points hold each value once: plotters' can list a decade twice (0.01
/// ending the 0.001 decade's points and starting the next), which drew its label twice in one
/// place.
struct LogOnce(LogCoord<f64>);

impl Ranged for LogOnce {
    type FormatOption = plotters::coord::ranged1d::NoDefaultFormatting;
    type ValueType = f64;
    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.0.map(value, limit)
    }
    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let mut points = self.0.key_points(hint);
        points.dedup();
        points
    }
    fn range(&self) -> std::ops::Range<f64> {
        self.0.range()
    }
}

impl ValueFormatter<f64> for LogOnce {
    fn format(value: &f64) -> String {
        tick(value)
    }
}

/// A panel's margin, px (its right margin is wider: a last x label centred on the edge).
const MARGIN_PX: i32 = 10;
const MARGIN_RIGHT_PX: i32 = 18;
/// The label areas: x below the plot (upright labels and the axis name), y left of it.
const X_LABEL_AREA_PX: i32 = 44;
const Y_LABEL_AREA_PX: i32 = 78;

/// The tick labels' font.
fn label_font() -> TextStyle<'static> {
    TextStyle::from(("sans-serif", ticks::LABEL_PX).into_font())
}

/// Each label's `(centre, extent)` in px along its axis for a label count hint `n`: the axis's
/// key points, labelled by `fmt`, placed by `spec` over `px`, measured by `extent`.
fn axis_labels<R: Ranged<ValueType = f64>>(
    spec: &R,
    n: usize,
    px: (i32, i32),
    fmt: &dyn Fn(&f64) -> String,
    extent: &dyn Fn(&str) -> i32,
) -> Vec<(i32, i32)> {
    labelled_points(spec, n, fmt).iter().map(|(v, t)| (spec.map(v, px), extent(t))).collect()
}

/// The key points for hint `n` that `fmt` labels, each text once: a log axis's key points can
/// hold one value twice by rounding (0.01 as a decade and as ten times 0.001), which would draw
/// its label twice in one place.
fn labelled_points<R: Ranged<ValueType = f64>>(
    spec: &R,
    n: usize,
    fmt: &dyn Fn(&f64) -> String,
) -> Vec<(f64, String)> {
    let mut out: Vec<(f64, String)> = Vec::new();
    for v in spec.key_points(n) {
        let t = fmt(&v);
        if !t.is_empty() && !out.iter().any(|(_, seen)| *seen == t) {
            out.push((v, t));
        }
    }
    out
}

/// The legend swatch of a line.
fn swatch(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style)
}

fn draw_in<'a, DB, X, Y>(
    mut chart: ChartContext<'a, DB, Cartesian2d<X, Y>>,
    panel: &DrawingArea<DB, Shift>,
    plot: &Plot,
    (y0, y1): (f64, f64),
    x_names: &ticks::CategoryLabels,
) -> DrawResult<DB>
where
    DB: DrawingBackend + 'a,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let (xr, yr) = (chart.x_range(), chart.y_range());
    // A log axis over one or two decades: labels at 1, 2 and 5 of each decade too (plotters
    // labels only the decades, which leaves one or two labels).
    let few_decades = |log: bool, r: &std::ops::Range<f64>| {
        let n = (r.end / r.start).abs().log10().round();
        (log && n <= 2.0).then_some(n as usize)
    };
    let (x_dec, y_dec) = (few_decades(plot.x.log, &xr), few_decades(plot.y.log, &yr));
    let label_count = |dec: Option<usize>, categories: usize| match (dec, categories) {
        (Some(n), _) => 10 * n.max(1) + 1,
        (None, 0) => 10,
        (None, c) => c + 1,
    };
    let x_span = (xr.end - xr.start).abs();
    let y_span = (yr.end - yr.start).abs();
    let turned = matches!(x_names, ticks::CategoryLabels::Turned { .. });
    // Turned names are drawn below, not by the mesh (which cannot turn a label about its end).
    let x_text = |v: &f64| {
        if turned {
            String::new()
        } else {
            tick_label(*v, x_span, x_dec, &plot.x.categories)
        }
    };
    let y_text = |v: &f64| tick_label(*v, y_span, y_dec, &plot.y.categories);
    // As many labels as fit, measured: x labels by their width, y labels by their height.
    let style = label_font();
    let width_of = |t: &str| panel.estimate_text_size(t, &style).map_or(0, |(w, _)| w as i32);
    let height_of = |_: &str| ticks::LABEL_PX;
    let (px, py) = chart.plotting_area().get_pixel_range();
    let spec = chart.as_coord_spec();
    let x_count = ticks::fitting_count(label_count(x_dec, plot.x.categories.len()), &|n| {
        axis_labels(spec.x_spec(), n, (px.start, px.end), &x_text, &width_of)
    });
    let y_count = ticks::fitting_count(label_count(y_dec, plot.y.categories.len()), &|n| {
        axis_labels(spec.y_spec(), n, (py.end, py.start), &y_text, &height_of)
    });
    // Each label once, at the first key point that has it.
    let x_keep: Vec<u64> =
        labelled_points(spec.x_spec(), x_count, &x_text).iter().map(|p| p.0.to_bits()).collect();
    let y_keep: Vec<u64> =
        labelled_points(spec.y_spec(), y_count, &y_text).iter().map(|p| p.0.to_bits()).collect();
    let x_tick = |v: &f64| if x_keep.contains(&v.to_bits()) { x_text(v) } else { String::new() };
    let y_tick = |v: &f64| if y_keep.contains(&v.to_bits()) { y_text(v) } else { String::new() };
    chart
        .configure_mesh()
        .x_desc(plot.x.label.as_str())
        .y_desc(plot.y.label.as_str())
        .x_labels(x_count)
        .y_labels(y_count)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .label_style(label_font())
        .axis_desc_style(("sans-serif", 14))
        .max_light_lines(4)
        .draw()?;
    if let ticks::CategoryLabels::Turned { every, names, .. } = x_names {
        let style = label_font()
            .color(&BLACK)
            .transform(FontTransform::Rotate270)
            .pos(Pos::new(HPos::Right, VPos::Center));
        let base = panel.get_base_pixel();
        for (i, name) in names.iter().enumerate().step_by((*every).max(1)) {
            let (x, y) = chart.backend_coord(&(i as f64, y0));
            let at = (x - base.0, y - base.1 + 10);
            panel.draw(&Text::new(name.clone(), at, style.clone()))?;
        }
    }
    let (xa, ya) = (&plot.x, &plot.y);
    let mut legend = false;

    // Shaded spans, one legend entry per label.
    let mut labels: Vec<(&str, RGBColor)> = Vec::new();
    for s in &plot.spans {
        if !labels.iter().any(|(l, _)| *l == s.label) {
            labels.push((&s.label, s.colour));
        }
    }
    for (label, colour) in labels {
        let fill = colour.mix(0.18).filled();
        let rects = plot
            .spans
            .iter()
            .filter(|s| s.label == label && usable(s.x0, xa.log) && usable(s.x1, xa.log))
            .map(|s| Rectangle::new([(s.x0, y0), (s.x1, y1)], fill));
        chart
            .draw_series(rects)?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], fill));
        legend = true;
    }

    // Vertical rules, one legend entry per label.
    let mut labels: Vec<(&str, RGBColor)> = Vec::new();
    for r in &plot.rules {
        if !labels.iter().any(|(l, _)| *l == r.label) {
            labels.push((&r.label, r.colour));
        }
    }
    for (label, colour) in labels {
        let style = colour.stroke_width(1);
        let mut first = true;
        for r in plot.rules.iter().filter(|r| r.label == label && usable(r.x, xa.log)) {
            let anno = chart.draw_series(DashedLineSeries::new(
                vec![(r.x, y0), (r.x, y1)],
                4,
                4,
                style,
            ))?;
            if first {
                anno.label(label).legend(swatch(style));
                legend = true;
                first = false;
            }
        }
    }

    for item in &plot.items {
        match item {
            Item::Bars { label, colour, width, points } => {
                let fill = colour.filled();
                let anno = chart.draw_series(
                    points.iter().filter(|p| point_ok(**p, xa, ya)).map(|&(x, y)| {
                        Rectangle::new([(x - 0.5 * width, 0.0), (x + 0.5 * width, y)], fill)
                    }),
                )?;
                if let Some(l) = label {
                    anno.label(l.as_str())
                        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], fill));
                    legend = true;
                }
            }
            Item::Band { label, colour, points } => {
                let fill = colour.mix(0.22).filled();
                let pts: Vec<(f64, f64, f64)> = points
                    .iter()
                    .copied()
                    .filter(|&(x, lo, hi)| {
                        usable(x, xa.log) && usable(lo, ya.log) && usable(hi, ya.log)
                    })
                    .collect();
                if pts.len() < 2 {
                    continue;
                }
                let poly: Vec<(f64, f64)> = pts
                    .iter()
                    .map(|&(x, lo, _)| (x, lo))
                    .chain(pts.iter().rev().map(|&(x, _, hi)| (x, hi)))
                    .collect();
                let anno = chart.draw_series(std::iter::once(Polygon::new(poly, fill)))?;
                if let Some(l) = label {
                    anno.label(l.as_str())
                        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], fill));
                    legend = true;
                }
            }
            Item::Line { label, colour, width, dashed, points } => {
                let style = colour.stroke_width(*width);
                // Split at unusable points so a gap stays a gap.
                let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                for &p in points {
                    if point_ok(p, xa, ya) {
                        if let Some(run) = runs.last_mut() {
                            run.push(p);
                        }
                    } else if runs.last().is_some_and(|r| !r.is_empty()) {
                        runs.push(Vec::new());
                    }
                }
                let mut first = true;
                for run in runs.into_iter().filter(|r| !r.is_empty()) {
                    let anno = if *dashed {
                        chart.draw_series(DashedLineSeries::new(run, 8, 5, style))?
                    } else {
                        chart.draw_series(LineSeries::new(run, style))?
                    };
                    if let (true, Some(l)) = (first, label) {
                        anno.label(l.as_str()).legend(swatch(style));
                        legend = true;
                    }
                    first = false;
                }
            }
            Item::Markers { label, colour, shape, points } => {
                let line = colour.stroke_width(1);
                let bars: Vec<(f64, f64, f64)> = points
                    .iter()
                    .filter_map(|&(x, _, bar)| bar.map(|(lo, hi)| (x, lo, hi)))
                    .filter(|&(x, lo, hi)| {
                        usable(x, xa.log) && usable(lo, ya.log) && usable(hi, ya.log)
                    })
                    .collect();
                chart.draw_series(
                    bars.iter().map(|&(x, lo, hi)| PathElement::new(vec![(x, lo), (x, hi)], line)),
                )?;
                let cap = |p: (f64, f64)| {
                    EmptyElement::at(p) + PathElement::new(vec![(-4, 0), (4, 0)], line)
                };
                chart.draw_series(bars.iter().map(|&(x, lo, _)| cap((x, lo))))?;
                chart.draw_series(bars.iter().map(|&(x, _, hi)| cap((x, hi))))?;
                let pts: Vec<(f64, f64)> = points
                    .iter()
                    .map(|&(x, y, _)| (x, y))
                    .filter(|p| point_ok(*p, xa, ya))
                    .collect();
                let fill = colour.filled();
                let cross = colour.stroke_width(2);
                match shape {
                    Marker::Circle => {
                        let anno =
                            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, fill)))?;
                        if let Some(l) = label {
                            anno.label(l.as_str())
                                .legend(move |(x, y)| Circle::new((x + 10, y), 4, fill));
                        }
                    }
                    Marker::Triangle => {
                        let anno = chart
                            .draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 6, fill)))?;
                        if let Some(l) = label {
                            anno.label(l.as_str())
                                .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 6, fill));
                        }
                    }
                    Marker::Cross => {
                        let anno =
                            chart.draw_series(pts.iter().map(|&p| Cross::new(p, 5, cross)))?;
                        if let Some(l) = label {
                            anno.label(l.as_str())
                                .legend(move |(x, y)| Cross::new((x + 10, y), 5, cross));
                        }
                    }
                }
                legend |= label.is_some();
            }
        }
    }

    // Marks along the bottom, each centred on its x; one that would touch the last one drawn
    // is left out.
    let style = TextStyle::from(("sans-serif", 12).into_font()).color(&colour::BLACK);
    let base = panel.get_base_pixel();
    let mut right = i32::MIN;
    let (px, _) = chart.plotting_area().get_pixel_range();
    let mut marks: Vec<&(f64, String)> =
        plot.marks.iter().filter(|m| usable(m.0, xa.log)).collect();
    marks.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (x, text) in marks {
        let (cx, cy) = chart.backend_coord(&(*x, y0));
        let w = panel.estimate_text_size(text, &style).map_or(0, |(w, _)| w as i32);
        let left = cx - w / 2;
        if left < right + ticks::GAP_PX || left < px.start || left + w > px.end {
            continue;
        }
        let at = (left - base.0, cy - base.1 - 18);
        panel.draw(&Text::new(text.clone(), at, style.clone()))?;
        right = left + w;
    }

    if let Some(note) = &plot.note {
        let area = chart.plotting_area().strip_coord_spec();
        let (w, _) = area.dim_in_pixel();
        let style = TextStyle::from(("sans-serif", 14).into_font()).color(&colour::BLACK);
        let lines: Vec<&str> = note.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let y = 8 + 18 * i as i32;
            let text_w = area.estimate_text_size(line, &style).map_or(0, |(w, _)| w as i32);
            area.draw(&Text::new(*line, (w as i32 - text_w - 10, y), style.clone()))?;
        }
    }

    if legend {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(colour::GREY)
            .label_font(("sans-serif", 13))
            .draw()?;
    }
    Ok(())
}

/// Draw `panels` side by side on `root`, white background.
pub(crate) fn draw_figure<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Plot],
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    // Rows start at each panel marked `new_row`; a row's width is shared by weight.
    let mut rows: Vec<&[Plot]> = Vec::new();
    let mut start = 0;
    for (i, p) in panels.iter().enumerate() {
        if p.new_row && i > start {
            rows.push(&panels[start..i]);
            start = i;
        }
    }
    rows.push(&panels[start..]);
    let row_areas = root.split_evenly((rows.len(), 1));
    for (row_area, row) in row_areas.iter().zip(rows) {
        let total: u32 = row.iter().map(|p| p.weight.max(1)).sum();
        let areas = if row.iter().all(|p| p.weight <= 1) {
            row_area.split_evenly((1, row.len().max(1)))
        } else {
            let (w, _) = row_area.dim_in_pixel();
            let mut at = 0;
            let breaks: Vec<i32> = row[..row.len() - 1]
                .iter()
                .map(|p| {
                    at += p.weight.max(1);
                    (u64::from(w) * u64::from(at) / u64::from(total)) as i32
                })
                .collect();
            row_area.split_by_breakpoints(breaks, [0i32; 0])
        };
        for (area, plot) in areas.iter().zip(row) {
            draw_panel(area, plot)?;
        }
    }
    root.present()
}

/// Boxed drawing error (the backends' error types differ).
pub(crate) type PlotError = Box<dyn std::error::Error + Send + Sync>;

/// The figure as an SVG document.
pub(crate) fn to_svg(panels: &[Plot], size: (u32, u32)) -> Result<String, PlotError> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        draw_figure(root, panels).map_err(|e| Box::new(e) as PlotError)?;
    }
    Ok(out)
}

/// The figure as packed 8-bit RGB pixels, row by row.
pub(crate) fn to_rgb(panels: &[Plot], size: (u32, u32)) -> Result<Vec<u8>, PlotError> {
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw_figure(root, panels).map_err(|e| Box::new(e) as PlotError)?;
    }
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(&0.0), "0");
        assert_eq!(tick(&0.5), "0.5");
        assert_eq!(tick(&100.0), "100");
        assert_eq!(tick(&1e-5), "1e-5");
        assert_eq!(tick(&2.5e7), "2.5e7");
        assert_eq!(tick(&-0.25), "-0.25");
        assert_eq!(tick(&0.30000000000000004), "0.3");
    }

    #[test]
    fn ranges_pad_and_survive_degenerate_data() {
        let a = Axis::linear("x");
        assert_eq!(fit_range(&a, [1.0, 1.0].into_iter()), (0.9, 1.1));
        assert_eq!(fit_range(&a, std::iter::empty()), (0.0, 1.0));
        let (lo, hi) = fit_range(&a, [0.0, 10.0, f64::NAN].into_iter());
        assert!((lo + 0.4).abs() < 1e-12 && (hi - 10.4).abs() < 1e-12);
        let l = Axis::log("x");
        assert_eq!(fit_range(&l, [-1.0, 2.0, 1000.0].into_iter()), (1.0, 1000.0));
        let close =
            |a: (f64, f64), b: (f64, f64)| (a.0 / b.0 - 1.0).abs() + (a.1 / b.1 - 1.0).abs() < 1e-9;
        // Under two decades: the data with a margin, a power of ten always inside.
        assert!(close(fit_range(&l, [0.002, 0.04].into_iter()), (0.002 / 1.2, 0.048)));
        assert!(close(fit_range(&l, [0.003, 0.008].into_iter()), (0.001, 0.0096)));
        assert!(close(fit_range(&l, [1.0].into_iter()), (1.0 / 1.2, 1.2)));
    }

    #[test]
    fn category_and_short_log_axes_are_labelled() {
        let names = vec!["cw".to_owned(), "ccw".to_owned()];
        assert_eq!(tick_label(1.0, 2.0, None, &names), "ccw");
        assert_eq!(tick_label(0.5, 2.0, None, &names), "");
        assert_eq!(tick_label(2.0, 2.0, None, &names), "");
        assert_eq!(tick_label(0.002, 0.01, Some(1), &[]), "0.002");
        assert_eq!(tick_label(0.005, 0.01, Some(1), &[]), "0.005");
        assert_eq!(tick_label(0.003, 0.01, Some(1), &[]), "");
        assert_eq!(tick_label(0.003, 0.01, Some(0), &[]), "0.003");
        assert_eq!(tick_label(0.0035, 0.01, Some(0), &[]), "");
        assert_eq!(tick_label(0.003, 0.01, None, &[]), "0.003");
    }
}
