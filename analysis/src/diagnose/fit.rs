//! Least squares on bin means with errors from the noise model.
//!
//! Estimates are ordinary least squares (SVD on unit-RMS columns, nalgebra); their covariance
//! is the exact sandwich `P·Σ·Pᵀ` for the rows `P` of the pseudo-inverse and `Σ` the noise
//! model's covariance ([`super::noise::BinNoise`]) — not `σ²·(XᵀX)⁻¹`, which treats slow
//! flicker wander as independent per bin and overstates significance tens of times.
//!
//! A candidate term `G` (k columns) is tested against the current design `X` by projecting it
//! out of `X`: `G⊥ = G − X·X⁺G`, `θ = (G⊥ᵀG⊥)⁻¹G⊥ᵀr` with `r` the current residual, and the
//! Wald statistic `W = θᵀ·V⁻¹·θ`, `V = P_θ·Σ·P_θᵀ`, which is χ²_k under "no such term".

use nalgebra::{DMatrix, DVector};

use crate::error::AnalysisError;

use super::noise::BinNoise;

/// A least-squares fit of `y` on columns `x` over the selected rows.
#[derive(Debug, Clone)]
pub struct Projector {
    /// Rows used (indices into the bins), in order.
    pub rows: Vec<usize>,
    /// Design, rows × p (unscaled).
    x: DMatrix<f64>,
    /// Pseudo-inverse, p × rows (unscaled: β = pinv·y).
    pinv: DMatrix<f64>,
    /// Columns that were kept (excited and separable), indices into the given columns.
    pub kept: Vec<usize>,
}

impl Projector {
    /// Fit design `cols` (each as long as the bins) over `rows`; columns that the rows never
    /// excite, or that repeat others (relative singular value below 1e-9), are dropped and
    /// named in [`Projector::kept`]'s complement.
    pub fn new(cols: &[Vec<f64>], rows: &[usize]) -> Result<Projector, AnalysisError> {
        let n = rows.len();
        let mut kept: Vec<usize> = Vec::new();
        let mut scale = Vec::new();
        for (j, c) in cols.iter().enumerate() {
            let rms = (rows.iter().map(|&i| c[i] * c[i]).sum::<f64>() / n.max(1) as f64).sqrt();
            if rms > 0.0 && rms.is_finite() {
                kept.push(j);
                scale.push(rms);
            }
        }
        loop {
            let p = kept.len();
            let mut x = DMatrix::<f64>::zeros(n, p);
            for (r, &i) in rows.iter().enumerate() {
                for (c, &j) in kept.iter().enumerate() {
                    x[(r, c)] = cols[j][i] / scale[c];
                }
            }
            if p == 0 {
                return Ok(Projector { rows: rows.to_vec(), x, pinv: DMatrix::zeros(0, n), kept });
            }
            let svd = x.clone().svd(true, true);
            let sv = &svd.singular_values;
            let smax = sv.max();
            if sv.min() <= 1e-9 * smax && p > 1 {
                // Drop the column most aligned with the weakest direction.
                let v_t = svd.v_t.as_ref().ok_or_else(|| {
                    AnalysisError::Insufficient("diagnosis: SVD without V".into())
                })?;
                let (kmin, _) = sv.argmin();
                let drop = (0..p)
                    .max_by(|&a, &b| v_t[(kmin, a)].abs().total_cmp(&v_t[(kmin, b)].abs()))
                    .unwrap_or(p - 1);
                kept.remove(drop);
                scale.remove(drop);
                continue;
            }
            let pinv = svd
                .pseudo_inverse(1e-12 * smax)
                .map_err(|e| AnalysisError::Insufficient(format!("diagnosis: {e}")))?;
            // Undo the column scaling: x_unscaled = x·diag(scale), pinv_unscaled = diag(1/s)·pinv.
            let mut pinv = pinv;
            for (c, s) in scale.iter().enumerate() {
                pinv.row_mut(c).scale_mut(1.0 / s);
                x.column_mut(c).scale_mut(*s);
            }
            return Ok(Projector { rows: rows.to_vec(), x, pinv, kept });
        }
    }

    /// Coefficients of the kept columns for `y` (full length, read at the rows).
    pub fn beta(&self, y: &[f64]) -> Vec<f64> {
        let yv = DVector::from_iterator(self.rows.len(), self.rows.iter().map(|&i| y[i]));
        (&self.pinv * yv).iter().copied().collect()
    }

    /// Residual of `y` at the rows (full length; zero off the rows).
    pub fn residual(&self, y: &[f64], len: usize) -> Vec<f64> {
        let beta = DVector::from_vec(self.beta(y));
        let fitted = &self.x * beta;
        let mut out = vec![0.0; len];
        for (r, &i) in self.rows.iter().enumerate() {
            out[i] = y[i] - fitted[r];
        }
        out
    }

    /// Row `j` of the pseudo-inverse as a full-length weight vector.
    pub fn weights(&self, j: usize, len: usize) -> Vec<f64> {
        let mut w = vec![0.0; len];
        for (r, &i) in self.rows.iter().enumerate() {
            w[i] = self.pinv[(j, r)];
        }
        w
    }

    /// Noise-model covariance of the kept coefficients.
    pub fn covariance(&self, noise: &BinNoise) -> DMatrix<f64> {
        let len = noise.len();
        let p = self.kept.len();
        let w: Vec<Vec<f64>> = (0..p).map(|j| self.weights(j, len)).collect();
        quad_matrix(&w, noise)
    }

    /// `G` (columns, full length) with the design projected out, at the rows.
    pub(crate) fn orthogonalise(&self, g: &[Vec<f64>]) -> Vec<Vec<f64>> {
        g.iter()
            .map(|col| {
                let gv = DVector::from_iterator(self.rows.len(), self.rows.iter().map(|&i| col[i]));
                let coef = &self.pinv * &gv;
                let fitted = &self.x * coef;
                (0..self.rows.len()).map(|r| gv[r] - fitted[r]).collect()
            })
            .collect()
    }

    /// Test candidate columns `g` against this design for residual `r` (module docs).
    pub fn test(&self, g: &[Vec<f64>], r: &[f64], noise: &BinNoise) -> Option<TermTest> {
        let k = g.len();
        let gp = self.orthogonalise(g);
        let len = noise.len();
        let mut gtg = DMatrix::<f64>::zeros(k, k);
        let mut gtr = DVector::<f64>::zeros(k);
        for a in 0..k {
            for b in a..k {
                let s: f64 = gp[a].iter().zip(&gp[b]).map(|(x, y)| x * y).sum();
                gtg[(a, b)] = s;
                gtg[(b, a)] = s;
            }
            gtr[a] = gp[a].iter().zip(&self.rows).map(|(x, &i)| x * r[i]).sum();
        }
        // A column the design already spans (to 1e-9 of its norm) carries no new information.
        for a in 0..k {
            let norm: f64 = self.rows.iter().map(|&i| g[a][i] * g[a][i]).sum();
            if gtg[(a, a)].is_nan() || gtg[(a, a)] <= 1e-12 * norm {
                return None;
            }
        }
        let inv = gtg.clone().try_inverse()?;
        let theta = &inv * &gtr;
        // P_θ rows at full length.
        let p_rows: Vec<Vec<f64>> = (0..k)
            .map(|a| {
                let mut w = vec![0.0; len];
                for (r, &i) in self.rows.iter().enumerate() {
                    w[i] = (0..k).map(|b| inv[(a, b)] * gp[b][r]).sum();
                }
                w
            })
            .collect();
        let cov = quad_matrix(&p_rows, noise);
        let wald = cov.clone().try_inverse().map(|ci| (theta.transpose() * ci * &theta)[(0, 0)])?;
        let drss = (theta.transpose() * &gtg * &theta)[(0, 0)];
        Some(TermTest { theta: theta.iter().copied().collect(), cov, wald, delta_rss: drss })
    }
}

/// The symmetric matrix `wₐᵀ·Σ·w_b` of the rows `w`, from one `Σ·w_b` per row (each product
/// is [`BinNoise::quad`]'s, term for term: `Σ·w_b` computed once serves every `a ≤ b`).
fn quad_matrix(w: &[Vec<f64>], noise: &BinNoise) -> DMatrix<f64> {
    let p = w.len();
    let applied: Vec<Vec<f64>> = w.iter().map(|b| noise.apply(b)).collect();
    let mut v = DMatrix::zeros(p, p);
    for a in 0..p {
        for b in a..p {
            let q: f64 = applied[b].iter().zip(&w[a]).map(|(x, y)| x * y).sum();
            v[(a, b)] = q;
            v[(b, a)] = q;
        }
    }
    v
}

/// The result of testing one candidate term.
#[derive(Debug, Clone)]
pub struct TermTest {
    /// Fitted linear parameters.
    pub theta: Vec<f64>,
    /// Their noise-model covariance.
    pub cov: DMatrix<f64>,
    /// Wald statistic (χ²_k under no term).
    pub wald: f64,
    /// Drop of the residual sum of squares.
    pub delta_rss: f64,
}

impl TermTest {
    /// 1σ of parameter `a`.
    pub fn sigma(&self, a: usize) -> f64 {
        self.cov[(a, a)].max(0.0).sqrt()
    }

    /// The term's size and its 1σ: for a sinusoid's two coefficients (`a·sin x + b·cos x`) the
    /// amplitude `hypot(a, b)` with σ by the delta method, else `|θ₀|`.
    pub fn size(&self) -> (f64, f64) {
        if self.theta.len() != 2 {
            return (self.theta.first().map_or(0.0, |v| v.abs()), self.sigma(0));
        }
        let (a, b) = (self.theta[0], self.theta[1]);
        let amp = a.hypot(b);
        let c = &self.cov;
        let var = if amp > 0.0 {
            (a * a * c[(0, 0)] + b * b * c[(1, 1)] + 2.0 * a * b * c[(0, 1)]) / (amp * amp)
        } else {
            c[(0, 0)].max(c[(1, 1)])
        };
        (amp, var.max(0.0).sqrt())
    }
}
