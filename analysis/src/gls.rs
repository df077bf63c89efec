//! Generalised least squares under the gyro noise model, by Kalman-filter whitening.
//!
//! # Noise model
//!
//! The noise `e` of a sample at time `t_k` is the sum of
//!
//! - white rate noise of variance `R_k` (`N²/Δt` for angle random walk `N` and sample interval
//!   `Δt`);
//! - the flicker ("bias instability") as the simulator synthesises it
//!   ([`bench_physics::noise::bias_instability_components`]): `GM_COUNT` first-order
//!   Gauss–Markov processes `x_i`, stationary variance `σ_i²`, correlation time `T_i`;
//! - rate random walk `r` of strength `K`, zero at the first sample.
//!
//! Its covariance `Σ` is that of [`crate::joint_fit::NoiseSpec`]'s noise model. As a state-space
//! model with state `s = (x_1 … x_8, r)`: between samples `Δ` apart, `x_i ← e^{−Δ/T_i}·x_i` plus
//! a drive of variance `σ_i²·(1 − e^{−2Δ/T_i})`, `r ← r` plus a drive of variance `K²·Δ` — exact
//! for any `Δ`, so irregular sample times and gaps between windows cost nothing; each sample
//! observes `Σ_i x_i + r` plus the white noise.
//!
//! # Whitening
//!
//! A Kalman filter over that model turns any series `z` into its innovations `ν_k` with
//! variances `S_k`; `z̃_k = ν_k/√S_k` is `L⁻¹·z` for the Cholesky factor `Σ = L·Lᵀ` (the filter's
//! gains do not depend on the data, so the same pass whitens `y` and every column of `X`).
//! Ordinary least squares on the whitened problem, `min ‖L⁻¹(y − Xβ)‖²`, is the GLS estimator
//! `β̂ = (XᵀΣ⁻¹X)⁻¹XᵀΣ⁻¹y` — the best linear unbiased estimator under the model — and its
//! covariance `(XᵀΣ⁻¹X)⁻¹ = (X̃ᵀX̃)⁻¹` is the Cramér–Rao bound for Gaussian noise of that
//! model. The whitened problem is solved by nalgebra's SVD. Cost O(n·(m² + c·m)) for `m` states
//! and `c` series (here `m ≤ 9`, `c = 5`).

use nalgebra::{DMatrix, DVector};

use crate::error::AnalysisError;
use crate::joint_fit::NoiseSpec;

/// Whiten the columns of `z` (rows are samples at `times`, non-decreasing, each with white
/// variance `white_var`) in place under `spec`'s noise (module docs): each becomes `L⁻¹·z`.
pub fn whiten(
    times: &[f64],
    white_var: &[f64],
    spec: &NoiseSpec,
    z: &mut DMatrix<f64>,
) -> Result<(), AnalysisError> {
    let n = times.len();
    if white_var.len() != n || z.nrows() != n {
        return Err(AnalysisError::LengthMismatch {
            label: "whitening".into(),
            array: if white_var.len() != n { "white_var" } else { "rows" },
            got: if white_var.len() != n { white_var.len() } else { z.nrows() },
            expected: n,
        });
    }
    if let Some(k) = (1..n).find(|&k| times[k] < times[k - 1] || !times[k].is_finite()) {
        return Err(AnalysisError::TimeNotIncreasing { label: "whitening".into(), index: k });
    }
    if white_var.iter().any(|&r| !(r.is_finite() && r > 0.0)) {
        return Err(AnalysisError::InvalidParameter {
            name: "white_var",
            value: white_var.iter().copied().fold(f64::INFINITY, f64::min),
            why: "the white-noise variance of every sample must be finite and positive",
        });
    }
    let gm: Vec<(f64, f64)> = if spec.flicker_floor > 0.0 {
        bench_physics::noise::bias_instability_components(spec.flicker_floor)
            .iter()
            .map(|&(t, s)| (t, s * s))
            .collect()
    } else {
        Vec::new()
    };
    let g = gm.len();
    let m = g + usize::from(spec.rrw > 0.0);
    let k2 = spec.rrw * spec.rrw;
    let c = z.ncols();
    // Covariance (row-major m×m), state means per series (c×m), work vectors.
    let mut p = vec![0.0; m * m];
    for (i, &(_, var)) in gm.iter().enumerate() {
        p[i * m + i] = var;
    }
    // (One dummy zero state per series when m = 0.)
    let mut s = vec![0.0; c * m.max(1)];
    let mut phi = vec![1.0; m];
    let mut q = vec![0.0; m];
    let mut h = vec![0.0; m];
    let mut gain = vec![0.0; m];
    let mut last_dt = f64::NAN;
    let zs = z.as_mut_slice();
    for k in 0..n {
        if k > 0 {
            let dt = times[k] - times[k - 1];
            if dt != last_dt {
                for ((ph, qi), &(t_corr, var)) in phi.iter_mut().zip(&mut q).zip(&gm) {
                    *ph = (-dt / t_corr).exp();
                    *qi = var * -(-2.0 * dt / t_corr).exp_m1();
                }
                if m > g {
                    q[g] = k2 * dt;
                }
                last_dt = dt;
            }
            for (row, &pi) in p.chunks_exact_mut(m.max(1)).zip(&phi) {
                for (pij, &pj) in row.iter_mut().zip(&phi) {
                    *pij *= pi * pj;
                }
            }
            for (i, qi) in q.iter().enumerate() {
                p[i * m + i] += qi;
            }
            for st in s.chunks_exact_mut(m.max(1)) {
                for (x, ph) in st.iter_mut().zip(&phi) {
                    *x *= ph;
                }
            }
        }
        // h = P·1, S = 1ᵀP1 + R.
        for (hi, row) in h.iter_mut().zip(p.chunks_exact(m.max(1))) {
            *hi = row.iter().sum();
        }
        let hs: f64 = h.iter().sum();
        let r = white_var[k];
        let sv = hs + r;
        let inv_sqrt = 1.0 / sv.sqrt();
        for (gi, hi) in gain.iter_mut().zip(&h) {
            *gi = hi / sv;
        }
        for (ch, st) in s.chunks_exact_mut(m.max(1)).enumerate() {
            let zk = &mut zs[ch * n + k];
            let pred: f64 = st.iter().sum();
            let nu = *zk - pred;
            *zk = nu * inv_sqrt;
            for (x, gi) in st.iter_mut().zip(&gain) {
                *x += gi * nu;
            }
        }
        // P⁺ = P − hhᵀ/S, written as P − K·hᵀ − h·Kᵀ + S·KKᵀ (the Joseph form expanded for
        // H = 1ᵀ): symmetric term by term, so P stays exactly symmetric.
        for (i, row) in p.chunks_exact_mut(m.max(1)).enumerate() {
            let (gi, hi) = (gain[i], h[i]);
            for ((pij, &gj), &hj) in row.iter_mut().zip(&gain).zip(&h) {
                *pij += -gi * hj - hi * gj + sv * gi * gj;
            }
        }
    }
    Ok(())
}

/// Result of [`gls`].
#[derive(Debug, Clone)]
pub struct Gls {
    /// Coefficients.
    pub beta: DVector<f64>,
    /// Their covariance `(XᵀΣ⁻¹X)⁻¹` (the Cramér–Rao bound under the model).
    pub cov: DMatrix<f64>,
    /// Pseudo-inverse of the whitened design (p×n, rows in time order): `β̂ = P·ỹ`.
    pub pinv_whitened: DMatrix<f64>,
    /// Whitened residuals `ỹ − X̃β̂` in time order: independent with unit variance when the
    /// noise model is right.
    pub whitened_residual: Vec<f64>,
    /// Largest over smallest singular value of the whitened design.
    pub condition: f64,
}

/// Generalised least squares of `y` on `x` (rows are samples at `times`, any order) under
/// `spec`'s noise, each sample with white variance `white_var` (module docs).
pub fn gls(
    x: &DMatrix<f64>,
    y: &DVector<f64>,
    times: &[f64],
    white_var: &[f64],
    spec: &NoiseSpec,
) -> Result<Gls, AnalysisError> {
    let (n, p) = (x.nrows(), x.ncols());
    if y.len() != n || times.len() != n || white_var.len() != n {
        return Err(AnalysisError::Insufficient(format!(
            "GLS: {n} design rows but {} observations, {} times, {} white variances",
            y.len(),
            times.len(),
            white_var.len()
        )));
    }
    if n <= p {
        return Err(AnalysisError::TooFewSamples { what: "GLS".into(), got: n, min: p + 1 });
    }
    let mut order: Vec<usize> = (0..n).collect();
    if times.windows(2).any(|w| w[1] < w[0]) {
        order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    }
    let mut z = DMatrix::<f64>::zeros(n, p + 1);
    for (k, &i) in order.iter().enumerate() {
        for j in 0..p {
            z[(k, j)] = x[(i, j)];
        }
        z[(k, p)] = y[i];
    }
    let t: Vec<f64> = order.iter().map(|&i| times[i]).collect();
    let r: Vec<f64> = order.iter().map(|&i| white_var[i]).collect();
    whiten(&t, &r, spec, &mut z)?;
    let yw = z.column(p).clone_owned();
    let xw = z.columns(0, p).clone_owned();
    drop(z);
    let svd = xw.clone().svd(true, true);
    let sv = svd.singular_values.clone();
    let (smax, smin) = (sv.max(), sv.min());
    if smin.is_nan() || smin <= 1e-12 * smax {
        return Err(AnalysisError::Insufficient(format!(
            "GLS: the whitened design is singular (condition number {:.3e})",
            smax / smin
        )));
    }
    let v_t = svd.v_t.clone().ok_or_else(|| AnalysisError::Insufficient("GLS: no SVD".into()))?;
    let mut w = v_t.clone();
    for (i, s) in sv.iter().enumerate() {
        w.row_mut(i).scale_mut(1.0 / (s * s));
    }
    let cov = v_t.transpose() * w;
    let pinv =
        svd.pseudo_inverse(0.0).map_err(|e| AnalysisError::Insufficient(format!("GLS: {e}")))?;
    let beta = &pinv * &yw;
    let resid = &yw - &xw * &beta;
    Ok(Gls {
        beta,
        cov,
        pinv_whitened: pinv,
        whitened_residual: resid.as_slice().to_vec(),
        condition: smax / smin,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dense covariance of `spec`'s noise at `t` with white variances `r`.
    fn dense_cov(t: &[f64], r: &[f64], spec: &NoiseSpec) -> DMatrix<f64> {
        let comps = bench_physics::noise::bias_instability_components(spec.flicker_floor);
        let n = t.len();
        DMatrix::from_fn(n, n, |a, b| {
            let mut c = if a == b { r[a] } else { 0.0 };
            if spec.flicker_floor > 0.0 {
                for (tc, sd) in comps {
                    c += sd * sd * (-(t[a] - t[b]).abs() / tc).exp();
                }
            }
            c + spec.rrw * spec.rrw * (t[a].min(t[b]) - t[0])
        })
    }

    /// Three windows with gaps and jittered, irregular times; per-window white variance.
    fn problem() -> (DMatrix<f64>, DVector<f64>, Vec<f64>, Vec<f64>) {
        let mut t = Vec::new();
        let mut r = Vec::new();
        let mut tk = 0.0;
        for (w, (count, dt)) in [(60usize, 0.5), (50, 1.0), (70, 0.25)].into_iter().enumerate() {
            if w > 0 {
                tk += 900.0 * w as f64;
            }
            for i in 0..count {
                tk += dt * (1.0 + 0.3 * (((i * 7919 + w * 31) % 17) as f64 / 17.0 - 0.5));
                t.push(tk);
                r.push((3e-7f64).powi(2) / dt);
            }
        }
        let n = t.len();
        let x = DMatrix::from_fn(n, 4, |k, j| match j {
            0 => 1.0,
            1 => {
                if (k / 25) % 2 == 0 {
                    1.0
                } else {
                    -1.0
                }
            }
            2 => (t[k] / 1000.0).sin() * 10.0,
            _ => ((k * 37) % 11) as f64 / 11.0 - 0.5 + (t[k] / 300.0).cos(),
        });
        let y = DVector::from_fn(n, |k, _| {
            1e-6 + 2e-7 * x[(k, 1)]
                + 1e-8 * x[(k, 2)]
                + 3e-7 * x[(k, 3)]
                + 4e-7 * (((k * 104_729) % 97) as f64 / 97.0 - 0.5)
                + 5e-7 * (t[k] / 2000.0).sin()
        });
        (x, y, t, r)
    }

    #[test]
    fn whitening_gls_equals_dense_gls() {
        let (x, y, t, r) = problem();
        for spec in [
            NoiseSpec { arw: 3e-7, flicker_floor: 2e-7, rrw: 1e-9 },
            NoiseSpec { arw: 3e-7, flicker_floor: 2e-7, rrw: 0.0 },
            NoiseSpec { arw: 3e-7, flicker_floor: 0.0, rrw: 3e-9 },
        ] {
            let sigma = dense_cov(&t, &r, &spec);
            let chol = sigma.cholesky().expect("positive definite");
            let si_x = chol.solve(&x);
            let si_y = chol.solve(&y);
            let info = x.transpose() * &si_x;
            let cov = info.clone().try_inverse().expect("invertible");
            let beta = &cov * (x.transpose() * si_y);
            let got = gls(&x, &y, &t, &r, &spec).expect("gls");
            for j in 0..4 {
                let rel = (got.beta[j] - beta[j]).abs() / cov[(j, j)].sqrt();
                assert!(rel < 1e-9, "{spec:?} β{j}: {} vs {} ({rel})", got.beta[j], beta[j]);
                assert!((got.beta[j] / beta[j] - 1.0).abs() < 1e-9, "{spec:?} β{j}");
                for i in 0..4 {
                    let d = (got.cov[(i, j)] - cov[(i, j)]).abs();
                    assert!(d < 1e-9 * (cov[(i, i)] * cov[(j, j)]).sqrt(), "{spec:?} cov {i}{j}");
                }
            }
            // Whitened residuals: RSS = rᵀΣ⁻¹r.
            let res = &y - &x * &beta;
            let want = res.dot(&chol.solve(&res));
            let rss: f64 = got.whitened_residual.iter().map(|e| e * e).sum();
            assert!((rss / want - 1.0).abs() < 1e-9, "{rss} vs {want}");
            // Not a trivial check: GLS differs from OLS here.
            let ols = x.clone().svd(true, true).solve(&y, 1e-14).expect("ols");
            assert!((ols[0] - beta[0]).abs() > 1e-3 * cov[(0, 0)].sqrt(), "{spec:?}");
        }
    }

    #[test]
    fn row_order_does_not_matter_and_bad_inputs_are_refused() {
        let (x, y, t, r) = problem();
        let spec = NoiseSpec { arw: 3e-7, flicker_floor: 2e-7, rrw: 1e-9 };
        let a = gls(&x, &y, &t, &r, &spec).expect("gls");
        let n = t.len();
        let rev: Vec<usize> = (0..n).rev().collect();
        let xr = DMatrix::from_fn(n, 4, |k, j| x[(rev[k], j)]);
        let yr = DVector::from_fn(n, |k, _| y[rev[k]]);
        let tr: Vec<f64> = rev.iter().map(|&k| t[k]).collect();
        let rr: Vec<f64> = rev.iter().map(|&k| r[k]).collect();
        let b = gls(&xr, &yr, &tr, &rr, &spec).expect("gls");
        assert!((a.beta - b.beta).norm() < 1e-12 * a.cov.diagonal().map(f64::sqrt).norm());
        let mut z = DMatrix::zeros(3, 1);
        assert!(whiten(&[0.0, 1.0, 0.5], &[1.0; 3], &spec, &mut z).is_err());
        assert!(whiten(&[0.0, 1.0, 2.0], &[1.0, 0.0, 1.0], &spec, &mut z).is_err());
    }

    /// 400 000 samples of the simulator's noise (20 Hz, ≈ 5.6 h, white + flicker) whitened
    /// under its own model: unit variance, no correlation left at short or long lags.
    #[test]
    fn the_simulators_noise_whitens_to_white_over_a_long_record() {
        let (arw, floor, dt) = (2.9e-8, 1.44e-8, 0.05);
        let n = 400_000;
        let mut gen = bench_physics::noise::GyroNoise::new(arw, floor, dt, 3, 0);
        let mut z = DMatrix::zeros(n, 1);
        gen.fill(z.as_mut_slice());
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let spec = NoiseSpec { arw, flicker_floor: floor, rrw: 0.0 };
        whiten(&t, &vec![arw * arw / dt; n], &spec, &mut z).expect("whitens");
        let e = z.as_slice();
        let var = e.iter().map(|v| v * v).sum::<f64>() / n as f64;
        assert!((var - 1.0).abs() < 0.01, "variance {var}");
        for lag in [1, 20, 1000] {
            let c = e.iter().zip(&e[lag..]).map(|(a, b)| a * b).sum::<f64>() / n as f64;
            assert!(c.abs() < 4.0 / (n as f64).sqrt(), "lag {lag}: {c}");
        }
        // Means of 100 blocks of 4000 samples (200 s): variance 1/4000 each if white.
        let means: Vec<f64> = e.chunks(4000).map(|b| b.iter().sum::<f64>() / 4000.0).collect();
        let v = means.iter().map(|m| m * m).sum::<f64>() / means.len() as f64 * 4000.0;
        assert!((0.6..1.5).contains(&v), "block-mean variance ratio {v}");
    }
}
