//! The overlapping Allan variance below a block, kept as the full-rate samples pass.
//!
//! Where the loader averages the gyro's samples in blocks of `n` (report's `GyroIntake`), the
//! block means give the Allan curve only at `τ = n·dt, 2n·dt, …`. The octaves below it
//! (`τ = m·dt`, `m = 1, 2, 4, …` with `2m ≤ n`, τ = dt among them, where the angle random walk
//! is read) are taken from the full-rate samples as they pass: for each block, the sums of the
//! squared second differences `d = θ_{k+2m} − 2θ_{k+m} + θ_k` (θ the cumulative sum of the
//! rate, [`bench_physics::allan`]) of the terms that end in the block — those wholly inside it
//! and those that start in the block before it, when that block is full and no lost, flagged
//! or stepped sample lies between them ("joined"). A window pools the sums of its blocks, the
//! cross terms of a block only when the block before it is in the window too
//! ([`SubBlockSums::pooled`]): over a window of joined blocks that is every term of the
//! full-rate overlapping estimator of that window, term for term; where a window's blocks are
//! not joined (a lost or flagged sample, a glitch left out) its runs are pooled as separate
//! records, never across the break. docs/calibrate.md, "Reduced samples", says where the
//! estimator differs from the full-rate one and by how much.
//!
//! The sums are of the gyro's rate alone, not of `gyro − table − model`: over `2m ≤ n`
//! samples (at most 25 ms) the second difference removes a constant, so a table turning at a
//! steady rate and a thermal model that moves over minutes add nothing a double-precision sum
//! can see. Each block keeps its sums as `f32` (relative rounding 6·10⁻⁸, far below any
//! Allan point's statistical error) and its sample count: `8·K + 3` bytes for `K` factors
//! (43 B at 2 kHz, `n = 50`, `K = 5`).

use bench_physics::allan::AdevPoint;

/// The factors `m` (samples) kept below a block of `n`: 1, 2, 4, … with `2m ≤ n` (a term then
/// spans at most two blocks). Empty for `n < 2`.
pub fn sub_block_factors(n: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut m = 1usize;
    while 2 * m <= n {
        out.push(m);
        m *= 2;
    }
    out
}

/// One block's sums, as [`SubBlockSums::push_block`] computes them: for each factor, the sum of
/// `d²` of the terms wholly inside `cur` and of those that start in `prev` (the block before,
/// when joined) and end in `cur`. `out` holds `2·factors.len()` values: inner, cross per factor.
pub fn block_sums(prev: &[f64], cur: &[f64], factors: &[usize], out: &mut [f64]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    let (p, c) = (prev.len(), cur.len());
    if c == 0 {
        return;
    }
    // Cumulative sum from a reference inside the span: the offset cancels in `d`, and the sums
    // stay small, so the differences lose no precision.
    let reference = cur[0];
    let mut theta = Vec::with_capacity(p + c + 1);
    let mut acc = 0.0;
    theta.push(0.0);
    for &y in prev.iter().chain(cur) {
        acc += y - reference;
        theta.push(acc);
    }
    for (j, &m) in factors.iter().enumerate() {
        let len = 2 * m;
        if p + c < len {
            continue;
        }
        let first = p.saturating_sub(len - 1);
        let (mut inner, mut cross) = (0.0, 0.0);
        for s in first..=(p + c - len) {
            let d = theta[s + len] - 2.0 * theta[s + m] + theta[s];
            if s < p {
                cross += d * d;
            } else {
                inner += d * d;
            }
        }
        out[2 * j] = inner;
        out[2 * j + 1] = cross;
    }
}

/// The sub-block sums of every usable block of a run, in the order of its gyro arrays (module
/// docs).
#[derive(Debug, Clone, PartialEq)]
pub struct SubBlockSums {
    factors: Vec<usize>,
    /// The full-rate sample interval, s.
    dt_s: f64,
    /// Per block: inner, cross sum per factor.
    sums: Vec<f32>,
    /// Per block: its samples.
    count: Vec<u16>,
    /// Per block: joined to the block before (that block full, nothing between them).
    joined: Vec<bool>,
}

impl SubBlockSums {
    /// Empty sums for blocks of `n` samples (factors: [`sub_block_factors`]).
    pub fn new(n: usize) -> Self {
        Self {
            factors: sub_block_factors(n),
            dt_s: f64::NAN,
            sums: Vec::new(),
            count: Vec::new(),
            joined: Vec::new(),
        }
    }

    /// The factors kept.
    pub fn factors(&self) -> &[usize] {
        &self.factors
    }

    /// Blocks held.
    pub fn len(&self) -> usize {
        self.count.len()
    }

    /// No block held.
    pub fn is_empty(&self) -> bool {
        self.count.is_empty()
    }

    /// The full-rate sample interval, s (NaN until set).
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Set the full-rate sample interval, s (known once the time base is fitted).
    pub fn set_dt_s(&mut self, dt_s: f64) {
        self.dt_s = dt_s;
    }

    /// Add a block of samples `cur`, `prev` the block before it when joined (else empty);
    /// `scratch` holds `2·factors` values.
    pub fn push_block(&mut self, prev: &[f64], cur: &[f64], scratch: &mut Vec<f64>) {
        scratch.resize(2 * self.factors.len(), 0.0);
        block_sums(prev, cur, &self.factors, scratch);
        self.sums.extend(scratch.iter().map(|&v| v as f32));
        self.count.push(cur.len().min(usize::from(u16::MAX)) as u16);
        self.joined.push(!prev.is_empty());
    }

    /// Move block `from` to place `to` (`to ≤ from`), as a filter of the arrays does; `after`
    /// is the block (its old index) kept just before it. A block whose own predecessor was
    /// left out is no longer joined to the one now before it.
    pub fn move_block(&mut self, from: usize, to: usize, after: Option<usize>) {
        let k = 2 * self.factors.len();
        self.sums.copy_within(from * k..(from + 1) * k, to * k);
        self.count[to] = self.count[from];
        self.joined[to] = self.joined[from] && from > 0 && after == Some(from - 1);
    }

    /// Keep the first `len` blocks.
    pub fn truncate(&mut self, len: usize) {
        self.sums.truncate(len * 2 * self.factors.len());
        self.count.truncate(len);
        self.joined.truncate(len);
    }

    /// The sums of a window made of the blocks `blocks` (increasing indices): a block's cross
    /// terms count only when the block before it is the window's previous block and joined.
    pub fn pooled(&self, blocks: &[usize]) -> SubBlockAllan {
        let k = self.factors.len();
        let mut points: Vec<SubPoint> = self
            .factors
            .iter()
            .map(|&m| SubPoint { m, sum_sq: 0.0, terms: 0, samples: 0 })
            .collect();
        let mut before: Option<usize> = None;
        for &b in blocks {
            let Some(&c) = self.count.get(b) else { continue };
            let c = usize::from(c);
            let with_cross = self.joined[b] && b > 0 && before == Some(b - 1);
            for (j, p) in points.iter_mut().enumerate() {
                let len = 2 * p.m;
                p.samples += c;
                if c + 1 > len {
                    p.sum_sq += f64::from(self.sums[b * 2 * k + 2 * j]);
                    p.terms += c + 1 - len;
                }
                if with_cross {
                    p.sum_sq += f64::from(self.sums[b * 2 * k + 2 * j + 1]);
                    p.terms += (len - 1).min(c);
                }
            }
            before = Some(b);
        }
        SubBlockAllan { dt_s: self.dt_s, points }
    }
}

/// One factor's pooled sums.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubPoint {
    /// Averaging factor, samples.
    pub m: usize,
    /// Sum of `d²` (rate² · samples²).
    pub sum_sq: f64,
    /// Terms in the sum.
    pub terms: usize,
    /// Samples of the records pooled.
    pub samples: usize,
}

/// The Allan variance below the block of one window (or of windows pooled): per factor, the
/// sums of its terms ([`SubBlockSums::pooled`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SubBlockAllan {
    /// The full-rate sample interval, s.
    pub dt_s: f64,
    /// Per factor.
    pub points: Vec<SubPoint>,
}

/// The Allan points of `windows`' sub-block sums pooled (each factor's sums and counts added),
/// as [`bench_physics::allan::overlapping_adev`] states them: `σ² = Σd²/(2m²·terms)`; a
/// point's `n_samples` is the pooled samples, as the block-level pooling counts them. Empty
/// where no window has sums.
pub fn sub_block_points<'a>(
    windows: impl IntoIterator<Item = &'a SubBlockAllan>,
) -> Vec<AdevPoint> {
    let mut acc: Vec<SubPoint> = Vec::new();
    let mut dt = f64::NAN;
    for w in windows {
        if !dt.is_finite() {
            dt = w.dt_s;
        }
        for (j, p) in w.points.iter().enumerate() {
            if acc.len() <= j {
                acc.push(SubPoint { m: p.m, sum_sq: 0.0, terms: 0, samples: 0 });
            }
            acc[j].sum_sq += p.sum_sq;
            acc[j].terms += p.terms;
            acc[j].samples += p.samples;
        }
    }
    if !(dt.is_finite() && dt > 0.0) {
        return Vec::new();
    }
    acc.iter()
        .filter(|p| p.terms >= 8)
        .map(|p| AdevPoint {
            tau_s: p.m as f64 * dt,
            m: p.m,
            adev: (p.sum_sq / (2.0 * (p.m * p.m) as f64 * p.terms as f64)).sqrt(),
            n_terms: p.terms,
            n_samples: p.samples,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::allan::overlapping_adev;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn noise(len: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..len)
            .map(|_| {
                let e: f64 = StandardNormal.sample(&mut rng);
                1.7e-3 + 3e-7 * e
            })
            .collect()
    }

    fn sums_of(rate: &[f64], n: usize, breaks: &[usize]) -> SubBlockSums {
        let mut s = SubBlockSums::new(n);
        s.set_dt_s(0.0005);
        let mut scratch = Vec::new();
        let mut prev: Vec<f64> = Vec::new();
        let mut start = 0;
        while start < rate.len() {
            let next_break = breaks.iter().copied().find(|&b| b > start).unwrap_or(usize::MAX);
            let end = (start + n).min(rate.len()).min(next_break);
            let cur = &rate[start..end];
            s.push_block(&prev, cur, &mut scratch);
            prev = if cur.len() == n && end != next_break { cur.to_vec() } else { Vec::new() };
            start = end;
        }
        s
    }

    /// Over joined blocks the pooled sums are the full-rate overlapping estimator's, term for
    /// term: the same variance to rounding, the same term count.
    #[test]
    fn joined_blocks_pool_to_the_full_rate_estimator() {
        let (n, len) = (50, 10_007);
        let rate = noise(len, 3);
        let s = sums_of(&rate, n, &[]);
        let blocks: Vec<usize> = (0..s.len()).collect();
        let pts = sub_block_points([&s.pooled(&blocks)]);
        let full = overlapping_adev(&rate, 0.0005, &sub_block_factors(n));
        assert_eq!(pts.len(), 5);
        for (p, f) in pts.iter().zip(&full) {
            assert_eq!((p.m, p.n_terms, p.n_samples), (f.m, f.n_terms, f.n_samples));
            assert!((p.adev / f.adev - 1.0).abs() < 1e-6, "m {}: {} vs {}", p.m, p.adev, f.adev);
            assert!((p.tau_s - f.tau_s).abs() < 1e-15);
        }
    }

    /// A break (a lost sample) splits the record: the terms are those of the two runs, each
    /// full-rate, never one across the break; a window that leaves a block out does the same.
    #[test]
    fn a_break_or_a_block_left_out_pools_the_runs_apart() {
        let n = 8;
        let rate = noise(1_000, 4);
        let s = sums_of(&rate, n, &[403]);
        let blocks: Vec<usize> = (0..s.len()).collect();
        let pts = sub_block_points([&s.pooled(&blocks)]);
        let (a, b) = rate.split_at(403);
        for p in &pts {
            let fa = overlapping_adev(a, 0.0005, &[p.m])[0];
            let fb = overlapping_adev(b, 0.0005, &[p.m])[0];
            assert_eq!(p.n_terms, fa.n_terms + fb.n_terms, "m {}", p.m);
            let var = (fa.adev.powi(2) * fa.n_terms as f64 + fb.adev.powi(2) * fb.n_terms as f64)
                / p.n_terms as f64;
            assert!((p.adev.powi(2) / var - 1.0).abs() < 1e-6, "m {}", p.m);
        }
        // Blocks 0..10 and 20..: samples 0..80 and 160..403, 403..
        let some: Vec<usize> = (0..10).chain(20..s.len()).collect();
        let pts = sub_block_points([&s.pooled(&some)]);
        let runs = [&rate[0..80], &rate[160..403], &rate[403..]];
        for p in &pts {
            let f: Vec<AdevPoint> =
                runs.iter().map(|r| overlapping_adev(r, 0.0005, &[p.m])[0]).collect();
            assert_eq!(p.n_terms, f.iter().map(|f| f.n_terms).sum::<usize>());
        }
    }

    #[test]
    fn factors_stop_where_a_term_would_span_three_blocks() {
        assert!(sub_block_factors(1).is_empty());
        assert_eq!(sub_block_factors(2), vec![1]);
        assert_eq!(sub_block_factors(5), vec![1, 2]);
        assert_eq!(sub_block_factors(50), vec![1, 2, 4, 8, 16]);
    }
}
