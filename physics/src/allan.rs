//! Overlapping Allan deviation of a rate series, with equivalent degrees of freedom and
//! chi-square confidence intervals (NIST SP 1065, §5.2.4 and Table 5).
//!
//! For rate samples `y_i` every `dt`, the angle is `θ_k = dt·Σ_{i<k} y_i` (`N = n + 1` phase
//! points) and for `τ = m·dt`
//!
//! ```text
//! σ²(τ) = Σ_{k=0}^{N−2m−1} (θ_{k+2m} − 2θ_{k+m} + θ_k)² / (2τ²·(N − 2m))
//! ```
//!
//! computed from the cumulative sum in O(N) per τ.

/// Power-law noise type that sets the equivalent degrees of freedom of an Allan variance
/// estimate (gyro names: white rate = ARW, flicker rate = bias instability, random-walk rate =
/// rate random walk).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseType {
    /// White angle noise (quantisation).
    WhiteAngle,
    /// White rate noise (angle random walk); ADEV slope −1/2.
    WhiteRate,
    /// Flicker rate noise (bias instability); ADEV slope 0.
    FlickerRate,
    /// Random-walk rate noise; ADEV slope +1/2.
    RandomWalkRate,
}

/// One point of an Allan deviation curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdevPoint {
    /// Averaging time, s.
    pub tau_s: f64,
    /// Averaging factor (τ = m·dt).
    pub m: usize,
    /// Overlapping Allan deviation, in the unit of the rate series.
    pub adev: f64,
    /// Number of terms in the sum (`N − 2m` with `N = n + 1` phase points).
    pub n_terms: usize,
    /// Number of rate samples `n` of the series.
    pub n_samples: usize,
}

impl AdevPoint {
    /// Equivalent degrees of freedom of this point for a given dominant noise type.
    pub fn edf(&self, noise: NoiseType) -> f64 {
        edf_overlapping(noise, self.n_samples, self.m)
    }

    /// Confidence interval `(low, high)` of the ADEV at `confidence` (e.g. 0.95) for a given
    /// dominant noise type.
    pub fn interval(&self, noise: NoiseType, confidence: f64) -> (f64, f64) {
        chi2_interval(self.adev, self.edf(noise), confidence)
    }
}

/// Averaging factors 1, 2, 4, … (octave spacing) up to the largest `m` that leaves at least
/// `min_terms` terms in the overlapping sum of `n_samples` rate samples.
pub fn octave_factors(n_samples: usize, min_terms: usize) -> Vec<usize> {
    let n_phase = n_samples + 1;
    let mut out = Vec::new();
    let mut m = 1usize;
    while n_phase > 2 * m && n_phase - 2 * m >= min_terms.max(1) {
        out.push(m);
        match m.checked_mul(2) {
            Some(v) => m = v,
            None => break,
        }
    }
    out
}

/// Overlapping Allan deviation of `rate` (sampled every `dt_s`) at each averaging factor in
/// `factors`; factors of 0 or too large for the series are skipped.
pub fn overlapping_adev(rate: &[f64], dt_s: f64, factors: &[usize]) -> Vec<AdevPoint> {
    let n = rate.len();
    if n == 0 || dt_s.is_nan() || dt_s <= 0.0 {
        return Vec::new();
    }
    // Remove the mean first: it cancels in the second difference and keeps the cumulative sum
    // small, so the differences lose no precision.
    let mean = rate.iter().sum::<f64>() / n as f64;
    let mut theta = Vec::with_capacity(n + 1);
    let mut acc = 0.0;
    theta.push(0.0);
    for &y in rate {
        acc += y - mean;
        theta.push(acc);
    }
    let n_phase = n + 1;
    let mut out = Vec::with_capacity(factors.len());
    for &m in factors {
        if m == 0 || n_phase <= 2 * m {
            continue;
        }
        let terms = n_phase - 2 * m;
        let mut s = 0.0;
        for ((a, b), c) in theta.iter().zip(&theta[m..]).zip(&theta[2 * m..]) {
            let d = c - 2.0 * b + a;
            s += d * d;
        }
        // θ is in rate·samples; τ in samples is m.
        let avar = s / (2.0 * (m * m) as f64 * terms as f64);
        out.push(AdevPoint {
            tau_s: m as f64 * dt_s,
            m,
            adev: avar.sqrt(),
            n_terms: terms,
            n_samples: n,
        });
    }
    out
}

/// Overlapping Allan deviation at octave-spaced τ, keeping points with at least 8 terms.
pub fn adev_octaves(rate: &[f64], dt_s: f64) -> Vec<AdevPoint> {
    overlapping_adev(rate, dt_s, &octave_factors(rate.len(), 8))
}

/// Equivalent degrees of freedom of the overlapping Allan variance of `n_samples` rate samples
/// at averaging factor `m` (NIST SP 1065 Table 5, with `N = n_samples + 1` phase points).
pub fn edf_overlapping(noise: NoiseType, n_samples: usize, m: usize) -> f64 {
    let n = (n_samples + 1) as f64;
    let m = m.max(1) as f64;
    let v = match noise {
        NoiseType::WhiteAngle => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        NoiseType::WhiteRate => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n) * 4.0 * m * m / (4.0 * m * m + 5.0)
        }
        NoiseType::FlickerRate => {
            if m == 1.0 {
                2.0 * (n - 2.0).powi(2) / (2.3 * n - 4.9)
            } else {
                5.0 * n * n / (4.0 * m * (n + 3.0 * m))
            }
        }
        NoiseType::RandomWalkRate => {
            (n - 2.0) / m * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
                / (n - 3.0).powi(2)
        }
    };
    v.max(1.0)
}

/// Two-sided confidence interval of an Allan deviation `adev` with `edf` degrees of freedom:
/// `(adev·√(edf/χ²_{(1+c)/2}), adev·√(edf/χ²_{(1−c)/2}))`, chi-square quantiles by the
/// Wilson–Hilferty approximation (relative error < 1 % for edf ≥ 3).
pub fn chi2_interval(adev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    let c = confidence.clamp(1e-9, 1.0 - 1e-12);
    let hi_q = chi2_quantile((1.0 + c) / 2.0, edf);
    let lo_q = chi2_quantile((1.0 - c) / 2.0, edf);
    (adev * (edf / hi_q).sqrt(), adev * (edf / lo_q).sqrt())
}

/// Quantile `p` of the chi-square distribution with `nu` degrees of freedom (Wilson–Hilferty).
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let a = 2.0 / (9.0 * nu);
    (nu * (1.0 - a + z * a.sqrt()).powi(3)).max(0.0)
}

/// Quantile of the standard normal distribution (Acklam's rational approximation, relative
/// error < 1.2e-9); `p` is clamped to (0, 1).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let p_low = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < p_low {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - p_low {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adev_of_a_square_wave_matches_hand_computation() {
        // Rate +1 for 4 samples, −1 for 4, repeated: at m = 4 every second difference of the
        // angle is ±8 except where the window straddles in phase; compute by brute force.
        let rate: Vec<f64> = (0..64).map(|i| if (i / 4) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let dt = 0.5;
        for m in [1usize, 2, 3, 4, 8] {
            let mut s = 0.0;
            let mut k = 0;
            while k + 2 * m <= rate.len() {
                let a: f64 = rate[k..k + m].iter().sum::<f64>() / m as f64;
                let b: f64 = rate[k + m..k + 2 * m].iter().sum::<f64>() / m as f64;
                s += (b - a).powi(2);
                k += 1;
            }
            let want = (s / (2.0 * k as f64)).sqrt();
            let got = overlapping_adev(&rate, dt, &[m]);
            assert_eq!(got.len(), 1);
            assert!((got[0].adev - want).abs() < 1e-12, "m={m}: {} vs {want}", got[0].adev);
            assert_eq!(got[0].n_terms, k);
            assert_eq!(got[0].tau_s, m as f64 * dt);
        }
    }

    #[test]
    fn constant_rate_has_zero_adev_and_octaves_stop_at_min_terms() {
        let rate = vec![2.9e-3; 1000];
        let pts = adev_octaves(&rate, 0.05);
        assert!(pts.iter().all(|p| p.adev < 1e-15));
        let ms: Vec<usize> = pts.iter().map(|p| p.m).collect();
        assert_eq!(ms, vec![1, 2, 4, 8, 16, 32, 64, 128, 256]);
        assert!(overlapping_adev(&[], 1.0, &[1]).is_empty());
        assert!(overlapping_adev(&rate, 1.0, &[0, 600]).is_empty());
    }

    #[test]
    fn chi_square_quantiles_and_normal_quantiles_match_tables() {
        assert!((normal_quantile(0.975) - 1.959_963_985).abs() < 1e-8);
        assert!((normal_quantile(0.001) + 3.090_232_306).abs() < 1e-8);
        // χ²(10): 2.5 % = 3.247, 97.5 % = 20.483.
        assert!((chi2_quantile(0.025, 10.0) - 3.247).abs() < 0.03);
        assert!((chi2_quantile(0.975, 10.0) - 20.483).abs() < 0.05);
        let (lo, hi) = chi2_interval(1.0, 100.0, 0.95);
        assert!(lo < 1.0 && hi > 1.0 && (hi - lo - 0.28).abs() < 0.02, "{lo} {hi}");
    }

    #[test]
    fn edf_matches_sp1065_examples() {
        // White FM, N = 1025 phase points, m = 10: (3·1024/20 − 2·1023/1025)·400/405.
        let want = (3.0 * 1024.0 / 20.0 - 2.0 * 1023.0 / 1025.0) * 400.0 / 405.0;
        assert!((edf_overlapping(NoiseType::WhiteRate, 1024, 10) - want).abs() < 1e-9);
        // Flicker FM, m ≥ 2: 5N²/(4m(N+3m)).
        let want = 5.0 * 1025.0f64.powi(2) / (40.0 * (1025.0 + 30.0));
        assert!((edf_overlapping(NoiseType::FlickerRate, 1024, 10) - want).abs() < 1e-9);
    }
}
