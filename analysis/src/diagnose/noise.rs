//! The noise model's covariance between bin means, applied as quadratic forms `aᵀ·Σ·b` in
//! O(n) per Gauss–Markov component — never as an n×n matrix.
//!
//! A bin of span `S` averages the gyro's noise:
//! - white rate noise of density `N` (ARW): variance `N²/S`, independent between bins;
//! - each first-order Gauss–Markov component (correlation time `T`, standard deviation `σ`)
//!   of the flicker synthesis ([`bench_physics::noise::bias_instability_components`]):
//!   between bins `a ≠ b` exactly `σ²·g_a·g_b·e^{−|c_a − c_b|/T}` with `g = (2T/S)·sinh(S/2T)`
//!   and centres `c`; within a bin `2σ²(T/S)·(1 − (T/S)(1 − e^{−S/T}))`;
//! - rate random walk `K`: `K²·(min(c_a, c_b) − c_0)`, bin centres standing for the bins.

use crate::joint_fit::NoiseSpec;

use super::series::Bin;

/// Beyond this `S/T` a component is white at the bin scale (its covariance between bins is
/// below `σ²·(T/S)²`, and `sinh` would overflow).
const WHITE_BEYOND: f64 = 40.0;

/// One Gauss–Markov component of the flicker over the bins.
#[derive(Debug, Clone)]
struct Component {
    /// σ².
    var: f64,
    /// g per bin.
    g: Vec<f64>,
    /// Diagonal correction per bin.
    corr: Vec<f64>,
    /// Decay from the bin before, `e^{−(c_i − c_{i−1})/T}` (0 for the first bin): computed
    /// once, not in every product.
    decay: Vec<f64>,
}

/// Covariance of the noise of bin means (module docs).
#[derive(Debug, Clone)]
pub struct BinNoise {
    centre: Vec<f64>,
    /// The Gauss–Markov components that are not white at the bin scale.
    comps: Vec<Component>,
    /// Independent variance per bin (white part and white-like components).
    diag: Vec<f64>,
    rrw2: f64,
    spec: NoiseSpec,
}

impl BinNoise {
    /// The covariance of `bins` under `spec`.
    pub fn new(bins: &[Bin], spec: NoiseSpec) -> Self {
        let centre: Vec<f64> = bins.iter().map(Bin::centre_s).collect();
        let mut diag: Vec<f64> = bins.iter().map(|b| spec.arw * spec.arw / b.span_s()).collect();
        let mut comps = Vec::new();
        if spec.flicker_floor > 0.0 {
            for (t, std) in bench_physics::noise::bias_instability_components(spec.flicker_floor) {
                let var = std * std;
                let mut g = Vec::with_capacity(bins.len());
                let mut corr = Vec::with_capacity(bins.len());
                let mut white = true;
                for (i, b) in bins.iter().enumerate() {
                    let x = b.span_s() / t;
                    let within = 2.0 * var / x * (1.0 - (-(-x).exp_m1()) / x);
                    if x > WHITE_BEYOND {
                        diag[i] += within;
                        g.push(0.0);
                        corr.push(0.0);
                    } else {
                        white = false;
                        let gi = 2.0 / x * (0.5 * x).sinh();
                        g.push(gi);
                        corr.push(within - var * gi * gi);
                    }
                }
                if !white {
                    let decay: Vec<f64> = (0..centre.len())
                        .map(
                            |i| if i == 0 { 0.0 } else { (-(centre[i] - centre[i - 1]) / t).exp() },
                        )
                        .collect();
                    comps.push(Component { var, g, corr, decay });
                }
            }
        }
        Self { centre, comps, diag, rrw2: spec.rrw * spec.rrw, spec }
    }

    /// The noise model.
    pub fn spec(&self) -> NoiseSpec {
        self.spec
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.centre.len()
    }

    /// Whether there are no bins.
    pub fn is_empty(&self) -> bool {
        self.centre.is_empty()
    }

    /// `aᵀ·Σ·b`.
    pub fn quad(&self, a: &[f64], b: &[f64]) -> f64 {
        self.apply(b).iter().zip(a).map(|(x, y)| x * y).sum()
    }

    /// `Σ·b`, in O(n) per component: white and within-bin parts on the diagonal, each
    /// Gauss–Markov component by a forward and a backward exponential recursion
    /// (`Σ_j v_j e^{−|c_i − c_j|/T} = F_i + B_i − v_i`), rate random walk by tail sums.
    pub fn apply(&self, b: &[f64]) -> Vec<f64> {
        let n = self.centre.len();
        let c = &self.centre;
        let mut out: Vec<f64> = (0..n).map(|i| b[i] * self.diag[i]).collect();
        let mut v = vec![0.0; n];
        let mut fwd = vec![0.0; n];
        for Component { var, g, corr, decay } in &self.comps {
            for i in 0..n {
                v[i] = b[i] * g[i];
                out[i] += b[i] * corr[i];
            }
            let mut f = 0.0;
            for i in 0..n {
                f = v[i] + decay[i] * f;
                fwd[i] = f;
            }
            let mut bsum = 0.0;
            for i in (0..n).rev() {
                let d = if i + 1 == n { 0.0 } else { decay[i + 1] };
                bsum = v[i] + d * bsum;
                out[i] += var * g[i] * (fwd[i] + bsum - v[i]);
            }
        }
        if self.rrw2 > 0.0 && n > 1 {
            // (Σb)_i = Σ_{k=1..i} (c_k − c_{k−1})·Σ_{j≥k} b_j.
            let mut tail = vec![0.0; n + 1];
            for k in (0..n).rev() {
                tail[k] = tail[k + 1] + b[k];
            }
            let mut acc = 0.0;
            for i in 1..n {
                acc += (c[i] - c[i - 1]) * tail[i];
                out[i] += self.rrw2 * acc;
            }
        }
        out
    }

    /// Variance of one bin mean, averaged over the bins.
    pub fn mean_bin_variance(&self) -> f64 {
        let n = self.len();
        let mut e = vec![0.0; n];
        let mut s = 0.0;
        // Exact diagonal: white + each component's within-bin variance.
        for i in 0..n {
            e[i] = 1.0;
            s += self.quad(&e, &e);
            e[i] = 0.0;
            if i >= 64 {
                // The diagonal barely varies (bins are alike): average the first 64.
                return s / 64.0;
            }
        }
        s / n.max(1) as f64
    }

    /// Effective number of independent bins: the variance of one bin mean over the variance
    /// of the mean of all bins (n for white noise; far fewer when flicker dominates).
    pub fn n_eff(&self) -> f64 {
        let n = self.len();
        if n == 0 {
            return 0.0;
        }
        let w = vec![1.0 / n as f64; n];
        (self.mean_bin_variance() / self.quad(&w, &w)).clamp(1.0, n as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bins(n: usize, span: f64) -> Vec<Bin> {
        (0..n)
            .map(|i| Bin {
                first: i,
                end: i + 1,
                start_s: i as f64 * span,
                end_s: (i + 1) as f64 * span,
                table_rate_rad_s: 0.0,
                table_accel_rad_s2: 0.0,
                transition: false,
            })
            .collect()
    }

    #[test]
    fn white_noise_gives_n_over_s_and_n_eff_n() {
        let b = bins(100, 10.0);
        let m = BinNoise::new(&b, NoiseSpec { arw: 2.0, flicker_floor: 0.0, rrw: 0.0 });
        let mut e = vec![0.0; 100];
        e[3] = 1.0;
        assert!((m.quad(&e, &e) - 0.4).abs() < 1e-12);
        assert!((m.n_eff() - 100.0).abs() < 1e-9);
    }

    #[test]
    fn quad_matches_the_dense_covariance() {
        // Dense reference for the flicker components between bin means (module docs).
        let b = bins(40, 10.0);
        let spec = NoiseSpec { arw: 1e-8, flicker_floor: 1e-8, rrw: 1e-10 };
        let m = BinNoise::new(&b, spec);
        let n = b.len();
        let mut dense = vec![vec![0.0; n]; n];
        for i in 0..n {
            dense[i][i] += spec.arw * spec.arw / 10.0;
            for j in 0..n {
                let (ci, cj) = (b[i].centre_s(), b[j].centre_s());
                dense[i][j] += spec.rrw * spec.rrw * (ci.min(cj) - b[0].centre_s());
            }
        }
        for (t, std) in bench_physics::noise::bias_instability_components(spec.flicker_floor) {
            let (var, x) = (std * std, 10.0 / t);
            for i in 0..n {
                for j in 0..n {
                    dense[i][j] += if i == j {
                        2.0 * var / x * (1.0 - (-(-x).exp_m1()) / x)
                    } else {
                        let gap = (b[i].centre_s() - b[j].centre_s()).abs() - 10.0;
                        var / (x * x) * (-(-x).exp_m1()).powi(2) * (-gap / t).exp()
                    };
                }
            }
        }
        let a: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let c: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.11).cos()).collect();
        let want: f64 =
            (0..n).map(|i| (0..n).map(|j| a[i] * dense[i][j] * c[j]).sum::<f64>()).sum();
        let got = m.quad(&a, &c);
        assert!((got - want).abs() < 1e-9 * want.abs(), "{got:e} vs {want:e}");
        let applied: f64 = m.apply(&c).iter().zip(&a).map(|(x, y)| x * y).sum();
        assert!((applied - want).abs() < 1e-9 * want.abs(), "apply: {applied:e} vs {want:e}");
    }
}
