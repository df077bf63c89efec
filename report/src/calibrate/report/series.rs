//! Series helpers for the figures: time bins, interpolation and a first-order lag, over plain
//! arrays.

/// The samples of one time bin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bin {
    /// Mean time, s.
    pub t: f64,
    /// Mean value.
    pub mean: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
}

/// Means (and extremes) of `v` over consecutive bins of `width` seconds of `t` (increasing),
/// starting at `t[0]`; empty bins are left out. Non-finite values are skipped.
pub(super) fn bins(t: &[f64], v: &[f64], width: f64) -> Vec<Bin> {
    let n = t.len().min(v.len());
    let mut out = Vec::new();
    if n == 0 || !(width.is_finite() && width > 0.0) {
        return out;
    }
    let t0 = t[0];
    let mut cur: Option<(i64, f64, f64, f64, f64, usize)> = None; // (index, Σt, Σv, min, max, n)
    let flush = |c: (i64, f64, f64, f64, f64, usize), out: &mut Vec<Bin>| {
        let (_, st, sv, mn, mx, k) = c;
        if k > 0 {
            out.push(Bin { t: st / k as f64, mean: sv / k as f64, min: mn, max: mx });
        }
    };
    for i in 0..n {
        let (ti, vi) = (t[i], v[i]);
        if !(ti.is_finite() && vi.is_finite()) {
            continue;
        }
        let k = ((ti - t0) / width).floor() as i64;
        match &mut cur {
            Some(c) if c.0 == k => {
                c.1 += ti;
                c.2 += vi;
                c.3 = c.3.min(vi);
                c.4 = c.4.max(vi);
                c.5 += 1;
            }
            _ => {
                if let Some(c) = cur.take() {
                    flush(c, &mut out);
                }
                cur = Some((k, ti, vi, vi, vi, 1));
            }
        }
    }
    if let Some(c) = cur {
        flush(c, &mut out);
    }
    out
}

/// [`bins`] with the width chosen to give at most `max_bins` bins over the span of `t`.
pub(super) fn decimate(t: &[f64], v: &[f64], max_bins: usize) -> Vec<Bin> {
    let (Some(&a), Some(&b)) = (t.first(), t.last()) else {
        return Vec::new();
    };
    let span = (b - a).max(0.0);
    let width = if span > 0.0 { span / max_bins.max(1) as f64 * (1.0 + 1e-9) } else { 1.0 };
    bins(t, v, width)
}

/// Root mean square of the finite values ([`bench_analysis::stats::rms`]); NaN for none.
pub(super) fn rms(v: impl Iterator<Item = f64>) -> f64 {
    bench_analysis::stats::rms(v.filter(|x| x.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_average_and_skip_gaps() {
        let t = [0.0, 0.5, 1.0, 1.5, 5.0, 5.5];
        let v = [1.0, 3.0, 10.0, f64::NAN, 4.0, 6.0];
        let b = bins(&t, &v, 1.0);
        assert_eq!(b.len(), 3);
        assert_eq!(b[0], Bin { t: 0.25, mean: 2.0, min: 1.0, max: 3.0 });
        assert_eq!(b[1].mean, 10.0);
        assert_eq!((b[2].t, b[2].mean), (5.25, 5.0));
    }

    #[test]
    fn decimation_keeps_at_most_the_bins_asked_for() {
        let t: Vec<f64> = (0..100_000).map(|i| i as f64 * 0.05).collect();
        let v: Vec<f64> = t.iter().map(|x| x.sin()).collect();
        let b = decimate(&t, &v, 4000);
        assert!(b.len() <= 4000 && b.len() > 3900, "{}", b.len());
        assert!(decimate(&[], &[], 10).is_empty());
        assert_eq!(decimate(&[1.0], &[2.0], 10).len(), 1);
    }

    #[test]
    fn rms_skips_missing_values() {
        assert!((rms([3.0, -3.0, f64::NAN].into_iter()) - 3.0).abs() < 1e-12);
        assert!(rms(std::iter::empty()).is_nan());
    }
}
