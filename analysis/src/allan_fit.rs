//! IEEE Std 952 noise terms from an overlapping Allan deviation, with confidence intervals.
//!
//! # Method (IEEE Std 952-1997, Annex C: slope lines tangent to the curve)
//!
//! An Allan variance with white rate noise, flicker rate noise and rate random walk is
//! `σ²(τ) = N²/τ + (0.664·B)² + K²·τ/3`, so the curve lies above each asymptote:
//!
//! - **N** (angle random walk): the slope −1/2 line `N/√τ`, read at τ = 1 s: `N ≤ σ(τ)·√τ`;
//! - **B** (bias instability): the flat line `0.664·B` (`√(2 ln 2/π)` ≈ 0.664): `B ≤ σ(τ)/0.664`;
//! - **K** (rate random walk): the slope +1/2 line `K·√(τ/3)`, read at τ = 3 s:
//!   `K ≤ σ(τ)·√(3/τ)`.
//!
//! Each term is read at its *tangent point*: among the τ where the curve's local log-log slope
//! (from the neighbouring points) is within [`SLOPE_TOLERANCE`] of the term's slope α
//! (−1/2, 0, +1/2) — where the term dominates — the one minimising the upper end of the
//! confidence interval of `σ(τ)·τ^{-α}`. Each point's interval comes from its chi-square
//! distribution with the equivalent degrees of freedom of the term's noise type
//! (`bench_physics::allan`). Minimising the upper bound rather than the estimate keeps a
//! long-τ point with few degrees of freedom that happens to fall low from setting the term.
//! The term's value and interval are that point's, scaled.
//!
//! Where no point has the term's slope, the term never dominates the curve: all points are
//! searched and the value is only an upper bound ([`NoiseTerm::upper_bound`]). Limits: at the
//! tangent point the neighbouring terms still add up to `(1 + x)` to the variance, with
//! `x ≤ 0.25` for the slope tolerance of 0.1, so a value can be high by up to ≈ 12 %; and where
//! the N and K lines cross, the curve is flat there and B reads the curve's minimum
//! `√(2NK/√3)/0.664` without being flagged — B is then an upper bound.
//!
//! The contract's `bias_instability` is the flicker *floor* (the ADEV value), i.e. `0.664·B`;
//! [`AllanFit::flicker_floor`] gives it.

use bench_physics::allan::{chi2_interval, AdevPoint, NoiseType};
use bench_physics::units::{DEG_PER_H, DEG_PER_SQRT_H};

use crate::error::AnalysisError;

/// `√(2 ln 2 / π)`: the ADEV floor of flicker rate noise divided by IEEE 952's B.
pub const FLICKER_FLOOR_FACTOR: f64 = 0.664_282_470_267_960_1;

/// Largest difference between the local log-log slope at a tangent point and the term's own
/// slope for the term to count as seen (not an upper bound).
pub const SLOPE_TOLERANCE: f64 = 0.1;

/// 1 °/h/√h in rad/s/√s (rate random walk).
pub const DEG_PER_H_PER_SQRT_H: f64 = DEG_PER_H / 60.0;

/// One noise coefficient with its confidence interval, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseTerm {
    /// Estimate.
    pub value: f64,
    /// Lower end of the confidence interval.
    pub low: f64,
    /// Upper end of the confidence interval.
    pub high: f64,
    /// τ of the tangent point, s.
    pub tau_s: f64,
    /// Local log-log slope of the ADEV at the tangent point.
    pub local_slope: f64,
    /// The term does not dominate anywhere on the curve: `value` is only an upper bound.
    pub upper_bound: bool,
}

impl NoiseTerm {
    fn scaled(&self, unit: f64) -> Self {
        Self { value: self.value / unit, low: self.low / unit, high: self.high / unit, ..*self }
    }
}

/// IEEE 952 noise terms of one Allan deviation curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanFit {
    /// N, angle random walk, rad/√s.
    pub arw: NoiseTerm,
    /// B, bias instability (IEEE 952: floor / 0.664), rad/s.
    pub bias_instability: NoiseTerm,
    /// K, rate random walk, rad/s/√s.
    pub rate_random_walk: NoiseTerm,
    /// Confidence level of the intervals.
    pub confidence: f64,
}

impl AllanFit {
    /// N in °/√h.
    pub fn arw_deg_per_sqrt_h(&self) -> NoiseTerm {
        self.arw.scaled(DEG_PER_SQRT_H)
    }
    /// B in °/h.
    pub fn bias_instability_deg_per_h(&self) -> NoiseTerm {
        self.bias_instability.scaled(DEG_PER_H)
    }
    /// K in °/h/√h.
    pub fn rate_random_walk_deg_per_h_per_sqrt_h(&self) -> NoiseTerm {
        self.rate_random_walk.scaled(DEG_PER_H_PER_SQRT_H)
    }
    /// The flicker floor `0.664·B` (the contract's `bias_instability`), rad/s, with its interval.
    pub fn flicker_floor(&self) -> NoiseTerm {
        self.bias_instability.scaled(1.0 / FLICKER_FLOOR_FACTOR)
    }
}

/// Local log-log slope of the curve at index `j` (neighbours on both sides where present).
fn local_slope(points: &[AdevPoint], j: usize) -> f64 {
    let a = j.saturating_sub(1);
    let b = (j + 1).min(points.len() - 1);
    if a == b {
        return f64::NAN;
    }
    let (pa, pb) = (&points[a], &points[b]);
    (pb.adev / pa.adev).ln() / (pb.tau_s / pa.tau_s).ln()
}

/// Tangent point of the line of log-log slope `alpha` (module docs), as a term `σ·τ^{-α}·c`.
fn tangent(
    points: &[AdevPoint],
    alpha: f64,
    noise: NoiseType,
    confidence: f64,
    c: f64,
) -> NoiseTerm {
    let slopes: Vec<f64> = (0..points.len()).map(|j| local_slope(points, j)).collect();
    let on_slope: Vec<usize> =
        (0..points.len()).filter(|&j| (slopes[j] - alpha).abs() <= SLOPE_TOLERANCE).collect();
    let upper_bound = on_slope.is_empty();
    let candidates: Vec<usize> = if upper_bound { (0..points.len()).collect() } else { on_slope };
    let mut best: Option<(usize, f64, f64)> = None;
    for j in candidates {
        let p = &points[j];
        let (lo, hi) = chi2_interval(p.adev, p.edf(noise), confidence);
        let f = p.tau_s.powf(-alpha) * c;
        if best.is_none_or(|(_, _, h)| hi * f < h) {
            best = Some((j, lo * f, hi * f));
        }
    }
    // `points` is non-empty (checked by the caller), so `best` is set.
    let (j, low, high) = best.unwrap_or((0, f64::NAN, f64::NAN));
    let p = &points[j];
    NoiseTerm {
        value: p.adev * p.tau_s.powf(-alpha) * c,
        low,
        high,
        tau_s: p.tau_s,
        local_slope: slopes[j],
        upper_bound,
    }
}

/// N, B and K (module docs) from overlapping ADEV points (e.g.
/// `bench_physics::allan::adev_octaves`) at `confidence` (e.g. 0.95). Points with a
/// non-positive or non-finite deviation or τ are ignored; at least 3 must remain.
pub fn allan_fit(points: &[AdevPoint], confidence: f64) -> Result<AllanFit, AnalysisError> {
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(AnalysisError::InvalidParameter {
            name: "confidence",
            value: confidence,
            why: "must lie strictly between 0 and 1",
        });
    }
    let mut pts: Vec<AdevPoint> = points
        .iter()
        .copied()
        .filter(|p| p.adev.is_finite() && p.adev > 0.0 && p.tau_s.is_finite() && p.tau_s > 0.0)
        .collect();
    if pts.len() < 3 {
        return Err(AnalysisError::TooFewSamples {
            what: "Allan deviation fit (usable τ points)".into(),
            got: pts.len(),
            min: 3,
        });
    }
    pts.sort_by(|a, b| a.tau_s.total_cmp(&b.tau_s));
    Ok(AllanFit {
        arw: tangent(&pts, -0.5, NoiseType::WhiteRate, confidence, 1.0),
        bias_instability: tangent(
            &pts,
            0.0,
            NoiseType::FlickerRate,
            confidence,
            1.0 / FLICKER_FLOOR_FACTOR,
        ),
        rate_random_walk: tangent(&pts, 0.5, NoiseType::RandomWalkRate, confidence, 3f64.sqrt()),
        confidence,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::allan::adev_octaves;
    use bench_physics::noise::GyroNoise;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    const DT: f64 = 0.05;

    fn rrw(k: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let step = k * DT.sqrt();
        let mut x = 0.0;
        (0..n)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                x += step * w;
                x
            })
            .collect()
    }

    fn contains(t: &NoiseTerm, truth: f64) -> bool {
        t.low <= truth && truth <= t.high
    }

    #[test]
    fn the_flicker_factor_is_sqrt_2ln2_over_pi() {
        let want = (2.0 * 2f64.ln() / std::f64::consts::PI).sqrt();
        assert!((FLICKER_FLOOR_FACTOR - want).abs() < 1e-15);
        // 1 °/h/√h = (π/180)/3600 rad/s per 60 √s.
        assert!(
            (DEG_PER_H_PER_SQRT_H - std::f64::consts::PI / 180.0 / 3600.0 / 60.0).abs() < 1e-20
        );
    }

    #[test]
    fn white_noise_gives_n_and_only_upper_bounds_for_b_and_k() {
        let n_arw = 0.05 * DEG_PER_SQRT_H; // 0.05 °/√h
        let mut g = GyroNoise::new(n_arw, 0.0, DT, 11, 0);
        let mut rate = vec![0.0; 144_000]; // 2 h at 20 Hz
        g.fill(&mut rate);
        let fit = allan_fit(&adev_octaves(&rate, DT), 0.95).expect("enough points");
        assert!(contains(&fit.arw, n_arw), "{:?}", fit.arw);
        assert!((fit.arw.value / n_arw - 1.0).abs() < 0.02);
        assert!(!fit.arw.upper_bound);
        assert!((fit.arw_deg_per_sqrt_h().value - 0.05).abs() < 0.001);
        assert!(fit.bias_instability.upper_bound && fit.rate_random_walk.upper_bound);
    }

    #[test]
    fn white_plus_bias_instability_gives_n_and_the_floor() {
        // Floor 0.2 °/h; white noise crossing it at τ = 0.5 s; 3 h at 20 Hz.
        let floor = 0.2 * DEG_PER_H;
        let n_arw = floor * 0.5f64.sqrt();
        let mut g = GyroNoise::new(n_arw, floor, DT, 5, 1);
        let mut rate = vec![0.0; 216_000];
        g.fill(&mut rate);
        let fit = allan_fit(&adev_octaves(&rate, DT), 0.95).expect("enough points");
        assert!((fit.arw.value / n_arw - 1.0).abs() < 0.05, "N {:?}", fit.arw);
        let f = fit.flicker_floor();
        assert!(!f.upper_bound, "{f:?}");
        assert!((f.value / floor - 1.0).abs() < 0.12, "floor {f:?}");
        assert!(f.low < f.value && f.value < f.high);
        // B in IEEE terms is the floor / 0.664, reported in °/h.
        let b = fit.bias_instability_deg_per_h();
        assert!((b.value * FLICKER_FLOOR_FACTOR / 0.2 - 1.0).abs() < 0.12);
    }

    #[test]
    fn white_plus_rate_random_walk_gives_n_and_k() {
        // K = 1 °/h/√h; N crossing K's line at τ = 10 s: N²/10 = K²·10/3.
        let k = DEG_PER_H_PER_SQRT_H;
        let n_arw = k * (100.0f64 / 3.0).sqrt();
        let n = 144_000;
        let mut g = GyroNoise::new(n_arw, 0.0, DT, 3, 2);
        let mut rate = vec![0.0; n];
        g.fill(&mut rate);
        for (r, w) in rate.iter_mut().zip(rrw(k, n, 99)) {
            *r += w;
        }
        let fit = allan_fit(&adev_octaves(&rate, DT), 0.95).expect("enough points");
        let kk = fit.rate_random_walk;
        assert!(!kk.upper_bound, "{kk:?}");
        assert!(contains(&kk, k), "{kk:?}");
        assert!((kk.value / k - 1.0).abs() < 0.3, "{kk:?}");
        assert!((fit.rate_random_walk_deg_per_h_per_sqrt_h().value - 1.0).abs() < 0.3);
        assert!((fit.arw.value / n_arw - 1.0).abs() < 0.03, "N {:?}", fit.arw);
        // No flicker noise here, but where the N and K lines cross the curve is flat, so a
        // "floor" is read there: the curve's own minimum √(2NK/√3), an upper bound of B.
        let min = (2.0 * n_arw * k / 3f64.sqrt()).sqrt();
        let f = fit.flicker_floor();
        assert!((f.value / min - 1.0).abs() < 0.15, "{f:?} vs {min}");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(allan_fit(&[], 0.95).is_err());
        let pts = adev_octaves(&[1.0, 2.0, 1.5, 0.5, 1.0, 2.0, 1.0, 0.0, 1.0, 2.0], 1.0);
        assert!(allan_fit(&pts, 1.0).is_err());
        assert!(allan_fit(&pts, f64::NAN).is_err());
    }
}
