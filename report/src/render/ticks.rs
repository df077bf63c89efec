//! Tick labels laid out from their measured size, so that no two labels of an axis touch:
//! a numeric axis gets as many labels as fit (fewer when they are wide or the panel narrow);
//! a category axis keeps every name upright when the names fit side by side, else writes them
//! turned a quarter (reading upwards), every k-th when even that is too tight, each cut to a
//! length the panel has room for (`…`). Sizes come from the embedded font's layout
//! (`ab_glyph`, the same one that draws the PNG); the browser draws the SVG's text at 1/1.24 of
//! that size, so what fits here fits there.

/// Clear space between two labels along their axis, px.
pub(crate) const GAP_PX: i32 = 6;

/// The height a label takes across its baseline, px (the font's size: glyphs with ascenders
/// and descenders).
pub(crate) const LABEL_PX: i32 = 13;

/// Whether labels along an axis touch: each is `(centre, extent)` in px along the axis; they
/// touch when two neighbours' half-extents and [`GAP_PX`] do not fit between their centres.
pub(crate) fn touching(labels: &[(i32, i32)]) -> bool {
    let mut v = labels.to_vec();
    v.sort_by_key(|l| l.0);
    v.windows(2).any(|w| (w[1].0 - w[0].0) * 2 < w[0].1 + w[1].1 + 2 * GAP_PX)
}

/// How a category x axis's names are drawn.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum CategoryLabels {
    /// Upright, side by side, by the chart's own mesh.
    Upright,
    /// Turned a quarter, reading upwards, ending at the axis: every `every`-th name (the first
    /// included), as cut to fit; `len_px` is the longest, for the label area's size.
    Turned {
        /// Label every this many categories.
        every: usize,
        /// The names as drawn (cut with `…` where longer than the room).
        names: Vec<String>,
        /// Length of the longest drawn name, px.
        len_px: i32,
    },
}

/// The layout of `names` on an x axis `width_px` wide, turned names at most `room_px` long;
/// `width_of` measures a text's width in px.
pub(crate) fn category_labels(
    names: &[String],
    width_px: i32,
    room_px: i32,
    width_of: &dyn Fn(&str) -> i32,
) -> CategoryLabels {
    if names.is_empty() {
        return CategoryLabels::Upright;
    }
    let slot = width_px / names.len() as i32;
    let widest = names.iter().map(|n| width_of(n)).max().unwrap_or(0);
    if widest + GAP_PX <= slot {
        return CategoryLabels::Upright;
    }
    let every = ((LABEL_PX + GAP_PX) as f64 / slot.max(1) as f64).ceil().max(1.0) as usize;
    let names: Vec<String> = names.iter().map(|n| cut(n, room_px, width_of)).collect();
    let len_px = names.iter().map(|n| width_of(n)).max().unwrap_or(0);
    CategoryLabels::Turned { every, names, len_px }
}

/// `text`, or as much of it as fits in `room_px` followed by `…`.
pub(crate) fn cut(text: &str, room_px: i32, width_of: &dyn Fn(&str) -> i32) -> String {
    if width_of(text) <= room_px {
        return text.to_owned();
    }
    let chars: Vec<char> = text.chars().collect();
    for n in (1..chars.len()).rev() {
        let s: String = chars[..n].iter().collect::<String>().trim_end().to_owned() + "…";
        if width_of(&s) <= room_px {
            return s;
        }
    }
    "…".into()
}

/// The largest label count hint, from `start` down to 2, whose labels do not touch: `labels(n)`
/// gives each label's `(centre, extent)` px along the axis for hint `n`.
pub(crate) fn fitting_count(start: usize, labels: &dyn Fn(usize) -> Vec<(i32, i32)>) -> usize {
    let mut n = start;
    while n > 2 && touching(&labels(n)) {
        n -= 1;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 7 px a character.
    fn w(s: &str) -> i32 {
        7 * s.chars().count() as i32
    }

    #[test]
    fn neighbours_touch_within_the_gap() {
        // Centres 50 px apart, 40 px wide each: 10 px clear, more than the gap.
        assert!(!touching(&[(0, 40), (50, 40)]));
        // 44 px wide: 6 px clear, just the gap.
        assert!(!touching(&[(50, 44), (0, 44)]));
        assert!(touching(&[(0, 46), (50, 46)]));
        assert!(touching(&[(0, 10), (100, 10), (105, 10)]));
    }

    #[test]
    fn names_stay_upright_when_they_fit_else_turn_and_thin() {
        let bands: Vec<String> =
            (0..10).map(|i| format!("{}..{} °C", i * 10, i * 10 + 10)).collect();
        // 10 names of 10 characters (70 px) in 800 px: 80 px each, upright.
        assert_eq!(category_labels(&bands, 800, 100, &w), CategoryLabels::Upright);
        // In 400 px (40 px each) they turn, every one (13 + 6 px < 40).
        let turned = category_labels(&bands, 400, 100, &w);
        assert_eq!(turned, CategoryLabels::Turned { every: 1, names: bands.clone(), len_px: 70 });
        // In 150 px (15 px each) every second one.
        let CategoryLabels::Turned { every, .. } = category_labels(&bands, 150, 100, &w) else {
            panic!("upright in 15 px");
        };
        assert_eq!(every, 2);
        // Longer than the room: cut, the index kept.
        let CategoryLabels::Turned { names, len_px, .. } =
            category_labels(&["#26 record ccw ramp 40C to 0C".to_owned()], 10, 70, &w)
        else {
            panic!("upright");
        };
        assert_eq!(names, ["#26 recor…"]);
        assert!(len_px <= 70);
    }

    #[test]
    fn fewer_labels_until_they_fit() {
        // n labels spread over 300 px, each 40 px wide: 7 fit (50 px apart, 10 px clear).
        let labels = |n: usize| -> Vec<(i32, i32)> {
            (0..n).map(|i| (i as i32 * 300 / (n as i32 - 1).max(1), 40)).collect()
        };
        assert_eq!(fitting_count(10, &labels), 7);
        assert_eq!(fitting_count(4, &labels), 4);
    }
}
