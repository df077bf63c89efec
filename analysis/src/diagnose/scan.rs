//! The significance threshold of a term whose nonlinear parameter is scanned over a grid.
//!
//! A bias step tried at 400 instants, or a time constant at 10 values, is judged by its Wald
//! statistic at the grid value that fits best. Under "no such term" that statistic is the
//! value of a correlated χ²₁ process at its least-squares peak, so its tail is far lighter
//! than Bonferroni's `α/grid` assumes (steps a bin apart test almost the same thing). The exact
//! tail follows from the noise model: with `aₚ` the candidate column at grid value `p`, the
//! design projected out, the scores `uₚ = aₚᵀr` are jointly normal with covariance
//! `Cₚq = aₚᵀΣa_q`; the grid value chosen is the one maximising `uₚ²/‖aₚ‖²` and the statistic is
//! `uₚ²/Cₚₚ` there. Drawing `u` from `N(0, C)` (seeded, so a diagnosis is reproducible) gives
//! the quantile directly.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::fit::Projector;
use super::noise::BinNoise;

/// Draws for a tail probability `p`: about 200 exceedances, between 4 000 and 40 000 draws.
fn draws_for(p: f64) -> usize {
    ((200.0 / p.max(1e-9)).ceil() as usize).clamp(4_000, 40_000)
}

/// The `1 − p` quantile of the Wald statistic at the least-squares peak of the single-column
/// candidates `grid_cols` (one column per grid value) against the design of `proj`, under the
/// noise model `noise`. `None` when fewer than two grid columns survive the projection.
pub fn peak_wald_quantile(
    proj: &Projector,
    grid_cols: &[Vec<f64>],
    noise: &BinNoise,
    p: f64,
    seed: u64,
) -> Option<f64> {
    let n = noise.len();
    let mut a: Vec<Vec<f64>> = Vec::with_capacity(grid_cols.len());
    for col in grid_cols {
        let o = proj.orthogonalise(std::slice::from_ref(col)).pop()?;
        // Back to full length (the projector's rows are a subset in general).
        let mut full = vec![0.0; n];
        for (r, &i) in proj.rows.iter().enumerate() {
            full[i] = o[r];
        }
        let norm2: f64 = full.iter().map(|x| x * x).sum();
        let orig: f64 = proj.rows.iter().map(|&i| col[i] * col[i]).sum();
        if norm2 > 1e-12 * orig && norm2.is_finite() {
            a.push(full);
        }
    }
    let g = a.len();
    if g < 2 {
        return None;
    }
    let norm2: Vec<f64> = a.iter().map(|v| v.iter().map(|x| x * x).sum()).collect();
    let sa: Vec<Vec<f64>> = a.iter().map(|v| noise.apply(v)).collect();
    let amat = DMatrix::from_fn(n, g, |i, j| a[j][i]);
    let samat = DMatrix::from_fn(n, g, |i, j| sa[j][i]);
    let mut c = amat.transpose() * samat;
    // Symmetrise (rounding) before the eigen-decomposition.
    for i in 0..g {
        for j in 0..i {
            let m = 0.5 * (c[(i, j)] + c[(j, i)]);
            c[(i, j)] = m;
            c[(j, i)] = m;
        }
    }
    let diag: Vec<f64> = (0..g).map(|i| c[(i, i)]).collect();
    if diag.iter().any(|d| !(*d > 0.0 && d.is_finite())) {
        return None;
    }
    let eig = SymmetricEigen::new(c);
    // Keep the directions that carry all but 1e-9 of the variance: the rest changes u by
    // less than 3e-5 of its scale.
    let mut order: Vec<usize> = (0..g).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let total: f64 = eig.eigenvalues.iter().map(|l| l.max(0.0)).sum();
    let mut kept = Vec::new();
    let mut acc = 0.0;
    for &i in &order {
        let l = eig.eigenvalues[i].max(0.0);
        if l <= 0.0 || acc >= (1.0 - 1e-9) * total {
            break;
        }
        acc += l;
        kept.push(i);
    }
    let r = kept.len();
    let factor = DMatrix::from_fn(g, r, |i, k| {
        eig.eigenvectors[(i, kept[k])] * eig.eigenvalues[kept[k]].max(0.0).sqrt()
    });
    let draws = draws_for(p);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut stats = Vec::with_capacity(draws);
    let mut z = DVector::<f64>::zeros(r);
    for _ in 0..draws {
        for v in z.iter_mut() {
            *v = StandardNormal.sample(&mut rng);
        }
        let u = &factor * &z;
        let (best, _) = (0..g).fold((0, f64::NEG_INFINITY), |(bi, bv), i| {
            let v = u[i] * u[i] / norm2[i];
            if v > bv {
                (i, v)
            } else {
                (bi, bv)
            }
        });
        stats.push(u[best] * u[best] / diag[best]);
    }
    stats.sort_by(f64::total_cmp);
    let k = (((1.0 - p) * draws as f64).ceil() as usize).clamp(1, draws) - 1;
    Some(stats[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::series::test_bins as bins;
    use crate::joint_fit::NoiseSpec;
    use bench_physics::allan::chi2_quantile;

    #[test]
    fn one_distinct_column_gives_the_chi2_quantile() {
        // Two identical columns: the peak is that one column, W is χ²₁ exactly.
        let b = bins(200);
        let noise = BinNoise::new(&b, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 });
        let rows: Vec<usize> = (0..200).collect();
        let proj = Projector::new(&[vec![1.0; 200]], &rows).expect("design");
        let col: Vec<f64> = (0..200).map(|i| f64::from(u8::from(i >= 80))).collect();
        let q =
            peak_wald_quantile(&proj, &[col.clone(), col], &noise, 0.01, 7).expect("two columns");
        let want = chi2_quantile(0.99, 1.0);
        assert!((q - want).abs() < 0.08 * want, "{q} vs {want}");
    }

    #[test]
    fn independent_columns_follow_the_maximum_of_chi2() {
        // g orthogonal columns under white noise: P(max > x) = 1 − F(x)^g.
        let n = 400;
        let g = 20;
        let b = bins(n);
        let noise = BinNoise::new(&b, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 });
        let rows: Vec<usize> = (0..n).collect();
        let proj = Projector::new(&[], &rows).expect("design");
        let cols: Vec<Vec<f64>> =
            (0..g).map(|j| (0..n).map(|i| f64::from(u8::from(i % g == j))).collect()).collect();
        let p = 0.01;
        let q = peak_wald_quantile(&proj, &cols, &noise, p, 11).expect("columns");
        let want = chi2_quantile((1.0 - p).powf(1.0 / g as f64), 1.0);
        assert!((q - want).abs() < 0.06 * want, "{q} vs {want}");
        // Far below Bonferroni would be wrong here (independent tests): the two agree.
        let bonf = chi2_quantile(1.0 - p / g as f64, 1.0);
        assert!((q - bonf).abs() < 0.06 * bonf, "{q} vs Bonferroni {bonf}");
    }

    #[test]
    fn correlated_step_positions_need_less_than_bonferroni() {
        let n = 300;
        let b = bins(n);
        let noise = BinNoise::new(&b, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 });
        let rows: Vec<usize> = (0..n).collect();
        let proj = Projector::new(&[vec![1.0; n]], &rows).expect("design");
        let cols: Vec<Vec<f64>> =
            (10..290).map(|k| (0..n).map(|i| f64::from(u8::from(i >= k))).collect()).collect();
        let p = 0.005;
        let q = peak_wald_quantile(&proj, &cols, &noise, p, 3).expect("columns");
        let bonf = chi2_quantile(1.0 - p / cols.len() as f64, 1.0);
        let single = chi2_quantile(1.0 - p, 1.0);
        assert!(q < bonf - 1.0 && q > single + 1.0, "{single} < {q} < {bonf}");
    }
}
