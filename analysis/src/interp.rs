//! Linear interpolation of a sampled series: the one interpolator of the analysis (and of the
//! reports built on it).
//!
//! Inside the data the value is on the straight line between the two neighbouring samples;
//! outside it is held at the first or last value. Equal abscissae never divide by zero: the
//! later sample of a tie wins. A series with no samples gives NaN.

/// Value of `(xs, ys)` at `x` (xs non-decreasing, same length as ys).
pub fn interp(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let n = xs.len().min(ys.len());
    if n == 0 {
        return f64::NAN;
    }
    let k = xs[..n].partition_point(|v| *v <= x);
    segment(xs, ys, n, k, x)
}

/// Values of `(xs, ys)` at every point of `at`, in one pass when `at` increases (any order
/// works).
pub fn interp_at(xs: &[f64], ys: &[f64], at: &[f64]) -> Vec<f64> {
    let mut cursor = Cursor::new(xs, ys);
    at.iter().map(|&x| cursor.at(x)).collect()
}

/// Interpolation at increasing query points without searching from the start each time.
#[derive(Debug, Clone)]
pub struct Cursor<'a> {
    xs: &'a [f64],
    ys: &'a [f64],
    n: usize,
    /// Samples with abscissa ≤ the last query.
    k: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor over `(xs, ys)` (xs non-decreasing).
    pub fn new(xs: &'a [f64], ys: &'a [f64]) -> Self {
        Self { xs, ys, n: xs.len().min(ys.len()), k: 0 }
    }

    /// The value at `x`; a query below the previous one searches afresh.
    pub fn at(&mut self, x: f64) -> f64 {
        if self.n == 0 {
            return f64::NAN;
        }
        if self.k > 0 && self.xs[self.k - 1] > x {
            self.k = self.xs[..self.n].partition_point(|v| *v <= x);
        } else {
            while self.k < self.n && self.xs[self.k] <= x {
                self.k += 1;
            }
        }
        segment(self.xs, self.ys, self.n, self.k, x)
    }
}

/// The value at `x` given `k` = the number of samples with abscissa ≤ x.
fn segment(xs: &[f64], ys: &[f64], n: usize, k: usize, x: f64) -> f64 {
    if k == 0 {
        ys[0]
    } else if k >= n {
        ys[n - 1]
    } else {
        let (x0, x1) = (xs[k - 1], xs[k]);
        let f = if x1 > x0 { (x - x0) / (x1 - x0) } else { 1.0 };
        ys[k - 1] + f * (ys[k] - ys[k - 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_inside_held_outside() {
        let (xs, ys) = ([0.0, 1.0, 3.0], [0.0, 10.0, 30.0]);
        assert_eq!(interp(&xs, &ys, -1.0), 0.0);
        assert_eq!(interp(&xs, &ys, 0.5), 5.0);
        assert_eq!(interp(&xs, &ys, 2.0), 20.0);
        assert_eq!(interp(&xs, &ys, 5.0), 30.0);
        assert_eq!(
            interp_at(&xs, &ys, &[-1.0, 0.5, 2.0, 5.0, 0.5]),
            vec![0.0, 5.0, 20.0, 30.0, 5.0]
        );
        assert!(interp(&[], &[], 1.0).is_nan());
        assert_eq!(interp(&[2.0], &[7.0], 1.0), 7.0);
    }

    #[test]
    fn equal_times_never_divide_by_zero() {
        let (xs, ys) = ([0.0, 1.0, 1.0, 2.0], [0.0, 1.0, 5.0, 6.0]);
        for x in [0.999, 1.0, 1.001] {
            assert!(interp(&xs, &ys, x).is_finite(), "{x}");
        }
        assert_eq!(interp(&xs, &ys, 1.0), 5.0);
        assert_eq!(interp(&xs, &ys, 1.5), 5.5);
    }

    #[test]
    fn the_cursor_agrees_with_the_search_in_any_query_order() {
        let xs: Vec<f64> = (0..50).map(|i| (i * i) as f64 * 0.1).collect();
        let ys: Vec<f64> = xs.iter().map(|x| x.sin()).collect();
        let q = [3.3, 0.0, 100.0, 7.7, 7.8, 1.0, 250.0, -3.0];
        let mut c = Cursor::new(&xs, &ys);
        for x in q {
            assert_eq!(c.at(x), interp(&xs, &ys, x), "{x}");
        }
    }
}
