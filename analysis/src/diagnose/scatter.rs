//! Windows whose own scatter exceeds the noise model: a burst of noise, physics outside the
//! library.
//!
//! The noise model ([`super::noise`]) is one for the whole run. A stretch where the gyro's
//! white noise is several times larger (a burst: vibration, a failing source, electrical
//! interference) then shows in two wrong ways: its bins' means scatter beyond the model and a
//! library term that happens to fit them (a periodic bias, a drift) is named, or its samples
//! inflate the Allan deviation the model is fitted on and the rest of the run is judged
//! against too much noise. Neither is physics of the library.
//!
//! So before the noise model is fitted, each window of [`WINDOW_S`] is tested for its own
//! scatter: the first differences of the gyro's samples inside its settled bins (no table
//! acceleration, no gap, no lost sample between the two), which hold the white noise
//! (variance `2σ²` for samples of one length; each is scaled by the two samples' lengths, so
//! block means cut short count as they should) and nothing slower than a sample. Its variance
//! `s²` over `n` differences is compared with the quiet level of the run, the median window's
//! (or, when the windows below that are significantly lower — a burst longer than half the
//! run — theirs): `z = ln(s²/s²_quiet)/σ`, with `σ = √(3/n)` (white noise's first differences
//! are correlated, −½ between neighbours: the variance of `s²/σ²` is `3/n`), widened by the
//! windows' own robust spread where that is larger. A window is flagged when `z` exceeds the
//! one-sided normal quantile at `α / windows` (the number of windows tested is the look-
//! elsewhere). Flagged windows, merged where adjacent, are reported as unexplained ("noise
//! N× the model's from t1 to t2") where N ≥ [`REPORT_FACTOR`]; their samples are left out of
//! the noise model's Allan deviation, and each of their bins is deweighted by its own scatter
//! (its white variance times `s²/s²_quiet`) so that no library term is named from them.

use bench_physics::allan::normal_quantile;

use super::series::{Bin, Native, LOST};
use super::Unexplained;

/// Length of a window whose scatter is tested, s.
pub const WINDOW_S: f64 = 60.0;

/// Least ratio of a flagged window's noise to the quiet level (standard deviations) for it to
/// be reported as unexplained. Over a minute of a fast gyro (2400 differences at 40 Hz) the
/// test resolves a few per cent, and the loader's processing (block means cut at lost or
/// flagged frames, the device clock's fit) leaves that much: on a lab-writer null (diagnosis
/// study seed 13, 200 Hz, stationary noise) one window read 1.1×, significant. A burst that
/// matters to a diagnosis (vibration, a failing source) is several times the noise; a window
/// below this factor is still deweighted by its own scatter and left out of the Allan fit,
/// only not named.
pub const REPORT_FACTOR: f64 = 1.5;

/// Least first differences for a window to be tested.
const MIN_DIFFS: usize = 30;

/// The outcome of [`check`].
#[derive(Debug, Clone, Default)]
pub(super) struct Scatter {
    /// Per bin: the factor on its white variance (1 outside flagged windows).
    pub(super) scale: Vec<f64>,
    /// Flagged windows, merged: (start s, end s, noise over the quiet level as a ratio of
    /// standard deviations, the samples' white noise there in rad/s).
    pub(super) windows: Vec<(f64, f64, f64, f64)>,
    /// Windows tested.
    pub(super) tested: usize,
}

impl Scatter {
    /// Whether sample time `t` lies in a flagged window.
    pub(super) fn flagged_at(&self, t: f64) -> bool {
        self.windows.iter().any(|&(a, b, ..)| t >= a && t <= b)
    }

    /// The flagged windows as unexplained structure, one entry each.
    pub(super) fn unexplained(&self) -> Vec<Unexplained> {
        self.windows
            .iter()
            .filter(|w| w.2 >= REPORT_FACTOR)
            .map(|&(a, b, f, rms)| Unexplained {
                windows_s: vec![(a, b)],
                correlates_with: format!(
                    "noise {f:.1}× the model's from {a:.0} s to {b:.0} s (the samples' scatter \
                     in {:.0} s windows against the rest of the run; those bins deweighted by \
                     their own scatter)",
                    WINDOW_S
                ),
                rms,
            })
            .collect()
    }
}

/// Sum of squared first differences and their count over samples `first..end`, settled and
/// contiguous pairs only, each scaled to the white noise's density: a sample that is the mean
/// over `d` seconds has white variance `N²/d`, so a difference `v_k − v_{k−1}` has
/// `N²·(1/d_k + 1/d_{k−1})`, and `(v_k − v_{k−1})²/(1/d_k + 1/d_{k−1})` estimates `N²` whatever
/// the samples' lengths (block means cut short by a lost or flagged frame or a step, jittered
/// intervals).
fn diffs(native: &Native, first: usize, end: usize, nominal_dt: f64) -> (f64, usize) {
    let (mut ss, mut n) = (0.0, 0);
    for k in first + 1..end {
        if native.gap_before[k] || native.t[k] - native.t[k - 1] > LOST * nominal_dt {
            continue;
        }
        let d = native.v[k] - native.v[k - 1];
        ss += d * d / (1.0 / native.dt[k] + 1.0 / native.dt[k - 1]);
        n += 1;
    }
    (ss, n)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Test every window's scatter (module docs) at family-wise level `alpha`.
pub(super) fn check(native: &Native, bins: &[Bin], alpha: f64) -> Scatter {
    let nominal_dt = crate::timebase::median_interval(&native.t).unwrap_or(f64::NAN);
    let per_bin: Vec<(f64, usize)> = bins
        .iter()
        .map(|b| if b.transition { (0.0, 0) } else { diffs(native, b.first, b.end, nominal_dt) })
        .collect();
    // Windows: bins grouped by WINDOW_S of their centres.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut key = i64::MIN;
    for (i, b) in bins.iter().enumerate() {
        let k = (b.centre_s() / WINDOW_S).floor() as i64;
        if k != key {
            groups.push(Vec::new());
            key = k;
        }
        if let Some(g) = groups.last_mut() {
            g.push(i);
        }
    }
    // (bins, variance of one difference, differences).
    let windows: Vec<(&Vec<usize>, f64, usize)> = groups
        .iter()
        .filter_map(|g| {
            let (ss, n) =
                g.iter().fold((0.0, 0), |(s, m), &i| (s + per_bin[i].0, m + per_bin[i].1));
            (n >= MIN_DIFFS && ss > 0.0).then(|| (g, ss / n as f64, n))
        })
        .collect();
    let mut out = Scatter { scale: vec![1.0; bins.len()], windows: Vec::new(), tested: 0 };
    if windows.len() < 4 || !nominal_dt.is_finite() {
        return out;
    }
    out.tested = windows.len();
    let z_thr = normal_quantile(1.0 - alpha / windows.len() as f64);
    let z_of = |s2: f64, n: usize, quiet: f64, widen: f64| {
        (s2 / quiet).ln() / ((3.0 / n as f64).sqrt() * widen)
    };
    // The quiet level: the median window's; lowered to the windows significantly below it
    // when there are such (a burst over more than half the run).
    let mut quiet = median(&mut windows.iter().map(|w| w.1).collect::<Vec<_>>());
    for _ in 0..2 {
        let mut low: Vec<f64> =
            windows.iter().filter(|w| z_of(w.1, w.2, quiet, 1.0) < -z_thr).map(|w| w.1).collect();
        if low.len() < 2 {
            break;
        }
        quiet = median(&mut low);
    }
    // The windows' own robust spread of z about the quiet level, among those not above it by
    // the threshold (a burst's windows would widen it).
    let mut zs: Vec<f64> =
        windows.iter().map(|w| z_of(w.1, w.2, quiet, 1.0)).filter(|z| *z <= z_thr).collect();
    let centre = median(&mut zs.clone());
    let mut dev: Vec<f64> = zs.iter_mut().map(|z| (*z - centre).abs()).collect();
    let widen = (1.4826 * median(&mut dev)).max(1.0);
    let mut merged: Vec<(f64, f64, f64, usize)> = Vec::new();
    for &(g, s2, n) in &windows {
        if z_of(s2, n, quiet, widen) <= z_thr {
            continue;
        }
        let (a, b) = (bins[g[0]].start_s, bins[g[g.len() - 1]].end_s);
        for &i in g {
            // Each bin by its own scatter where it has enough differences, else its window's.
            let (ss, m) = per_bin[i];
            let own = if m >= MIN_DIFFS { ss / m as f64 } else { s2 };
            out.scale[i] = (own / quiet).max(1.0);
        }
        match merged.last_mut() {
            Some(last) if a - last.1 <= 1.0 => {
                last.1 = b;
                last.2 += s2 * n as f64;
                last.3 += n;
            }
            _ => merged.push((a, b, s2 * n as f64, n)),
        }
    }
    // `s2` is the white noise's density N² (rad²/s): a sample of the nominal length has
    // `N²/dt`.
    out.windows = merged
        .into_iter()
        .map(|(a, b, ss, n)| {
            let s2 = ss / n as f64;
            (a, b, (s2 / quiet).sqrt(), (s2 / nominal_dt).sqrt())
        })
        .collect();
    out
}
