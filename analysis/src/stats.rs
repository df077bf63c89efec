//! The two small statistics every part of the analysis needs: the root mean square and the
//! least-squares line, written once.

/// Root mean square of `values`; NaN when there are none. (Filter non-finite values first if
/// they are to be skipped.)
pub fn rms(values: impl IntoIterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in values {
        s += x * x;
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

/// A least-squares line `y = mean_y + slope·(x − mean_x)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Mean of the x values.
    pub mean_x: f64,
    /// Mean of the y values.
    pub mean_y: f64,
    /// The slope; `None` when the x values do not spread (fewer than two distinct, or none).
    pub slope: Option<f64>,
}

impl Line {
    /// The line's value at `x`, with `slope` standing in for a slope the points do not give.
    pub fn at(&self, x: f64, slope: f64) -> f64 {
        self.mean_y + self.slope.unwrap_or(slope) * (x - self.mean_x)
    }

    /// (value at x = 0, slope), with `slope` standing in for a slope the points do not give.
    pub fn intercept_slope(&self, slope: f64) -> (f64, f64) {
        let b = self.slope.unwrap_or(slope);
        (self.mean_y - b * self.mean_x, b)
    }
}

/// The least-squares line through `points` (x, y), two passes: the means, then the centred
/// sums (precise for large x such as times; shift x first for more). Read twice, so the
/// iterator is cloned.
pub fn line<I>(points: I) -> Line
where
    I: IntoIterator<Item = (f64, f64)>,
    I::IntoIter: Clone,
{
    let points = points.into_iter();
    let n = points.clone().count() as f64;
    let mean_x = points.clone().map(|p| p.0).sum::<f64>() / n;
    let mean_y = points.clone().map(|p| p.1).sum::<f64>() / n;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (x, y) in points {
        let dx = x - mean_x;
        sxx += dx * dx;
        sxy += dx * (y - mean_y);
    }
    Line { mean_x, mean_y, slope: (sxx > 0.0).then(|| sxy / sxx) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_of_known_values() {
        assert_eq!(rms([3.0, -4.0]), (12.5f64).sqrt());
        assert_eq!(rms([2.0; 5]), 2.0);
        assert!(rms(std::iter::empty()).is_nan());
    }

    #[test]
    fn a_line_through_exact_points_is_recovered() {
        let pts: Vec<(f64, f64)> =
            (0..11).map(|i| (1e6 + f64::from(i), 3.0 - 0.5 * f64::from(i))).collect();
        let l = line(pts.iter().copied());
        assert_eq!(l.slope, Some(-0.5));
        assert!((l.at(1e6, 0.0) - 3.0).abs() < 1e-9);
        let (a, b) = line([(1.0, 3.0), (3.0, 7.0)]).intercept_slope(0.0);
        assert_eq!((a, b), (1.0, 2.0));
        // No spread in x: no slope; the fallback stands in.
        let flat = line([(2.0, 1.0), (2.0, 3.0)]);
        assert_eq!(flat.slope, None);
        assert_eq!(flat.at(5.0, 0.0), 2.0);
        assert_eq!(line(std::iter::empty()).slope, None);
    }
}
