//! Does a fit fit? Tests of a residual in units of its noise against the noise model alone.
//!
//! A least-squares fit always returns numbers; they mean what their σ says only when the
//! residual is what the noise model predicts. The fit's residual in noise units (`z`: the GLS
//! whitened residual, independent N(0, 1) under the model) is tested two ways:
//!
//! - its RMS against 1 ([`rms_in_band`]);
//! - its **block means** at several time scales: a block of `m` samples has mean · √m ~ N(0, 1)
//!   under the model, so an unmodelled transient (a reversal inside a window), a slow drift the
//!   model lacks, or a periodic error shows as a block far outside. The threshold is the
//!   two-sided normal quantile at `α / K` for `K` blocks over every scale (Bonferroni): the
//!   chance that any block of a sound fit exceeds it is at most `α`. The noise model decides
//!   what is significant, not a tuned constant.

use bench_physics::allan::normal_quantile;

/// Scales of the block-mean test, s: a transient (10 s), a minute, a slow error (5 min).
pub const BLOCK_SCALES_S: [f64; 3] = [10.0, 60.0, 300.0];

/// A whitened RMS inside this band is consistent with the noise model: the model's own terms
/// come from an Allan fit whose intervals are a few % wide, and a residual up to 25 % above it
/// is absorbed by scaling σ (the fit's σ is the bound times max(1, RMS)); beyond, the data hold
/// something that scaling does not describe.
pub const RMS_BAND: (f64, f64) = (0.8, 1.25);

/// Whether a whitened residual RMS lies inside [`RMS_BAND`].
pub fn rms_in_band(rms: f64) -> bool {
    rms.is_finite() && (RMS_BAND.0..=RMS_BAND.1).contains(&rms)
}

/// A block of the residual far outside what the noise model allows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Excursion {
    /// Index of the window (run of samples) it lies in.
    pub window: usize,
    /// First sample's time, s.
    pub start_s: f64,
    /// Last sample's time, s.
    pub end_s: f64,
    /// Block mean · √m: N(0, 1) under the model.
    pub z: f64,
    /// The block scale it was found at, s.
    pub scale_s: f64,
}

/// Result of [`block_excursions`].
#[derive(Debug, Clone, PartialEq)]
pub struct BlockTest {
    /// Blocks tested over every scale.
    pub blocks: usize,
    /// |z| threshold (Bonferroni over `blocks` at the level given).
    pub threshold: f64,
    /// Largest |z| of any block.
    pub max_abs_z: f64,
    /// Blocks beyond the threshold, largest |z| first; an excursion found at several scales
    /// is kept once, at the scale where it stands out most.
    pub excursions: Vec<Excursion>,
}

/// Test block means of `z` (time `time_s`, split into windows of `lens` samples each, in
/// order) at [`BLOCK_SCALES_S`], at family-wise level `alpha`. A block is the samples of one
/// window within one scale-long interval; partial blocks shorter than half the scale are
/// merged into the previous block.
pub fn block_excursions(z: &[f64], time_s: &[f64], lens: &[usize], alpha: f64) -> BlockTest {
    struct Block {
        window: usize,
        first: usize,
        last: usize,
        z: f64,
        scale_s: f64,
    }
    let mut blocks = Vec::new();
    for &scale in &BLOCK_SCALES_S {
        let mut start = 0;
        for (w, &len) in lens.iter().enumerate() {
            let end = (start + len).min(z.len()).min(time_s.len());
            let mut edges = vec![start];
            let mut i = start;
            while i < end {
                let t0 = time_s[*edges.last().unwrap_or(&start)];
                while i < end && time_s[i] - t0 < scale {
                    i += 1;
                }
                if i < end {
                    edges.push(i);
                }
            }
            edges.push(end);
            // Merge a short last block into the one before.
            if edges.len() > 2 {
                let k = edges.len();
                let (a, b) = (edges[k - 2], edges[k - 1]);
                if b > a && time_s[b - 1] - time_s[a] < 0.5 * scale {
                    edges.remove(k - 2);
                }
            }
            for e in edges.windows(2) {
                let (a, b) = (e[0], e[1]);
                if b > a + 1 {
                    let m = (b - a) as f64;
                    let s: f64 = z[a..b].iter().sum();
                    blocks.push(Block {
                        window: w,
                        first: a,
                        last: b - 1,
                        z: s / m.sqrt(),
                        scale_s: scale,
                    });
                }
            }
            start = end;
        }
    }
    let k = blocks.len().max(1);
    let threshold = normal_quantile(1.0 - alpha / (2.0 * k as f64));
    let max_abs_z = blocks.iter().map(|b| b.z.abs()).fold(0.0, f64::max);
    let mut over: Vec<&Block> = blocks.iter().filter(|b| b.z.abs() > threshold).collect();
    over.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
    let mut excursions: Vec<Excursion> = Vec::new();
    for b in over {
        let (s, e) = (time_s[b.first], time_s[b.last]);
        if excursions.iter().any(|x| x.start_s <= e && s <= x.end_s) {
            continue;
        }
        excursions.push(Excursion {
            window: b.window,
            start_s: s,
            end_s: e,
            z: b.z,
            scale_s: b.scale_s,
        });
    }
    BlockTest { blocks: blocks.len(), threshold, max_abs_z, excursions }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
    }

    #[test]
    fn white_residuals_pass_at_the_stated_rate() {
        // Two windows of 30 min at 20 Hz; 200 seeds at α = 0.05: about 10 false alarms.
        let n = 36_000;
        let time: Vec<f64> =
            (0..2 * n).map(|i| (i % n) as f64 * 0.05 + (i / n) as f64 * 4000.0).collect();
        let alarms = (0..200)
            .filter(|&s| {
                !block_excursions(&white(2 * n, s), &time, &[n, n], 0.05).excursions.is_empty()
            })
            .count();
        assert!(alarms <= 20, "{alarms} false alarms in 200 at α = 0.05");
        let t = block_excursions(&white(2 * n, 1), &time, &[n, n], 0.01);
        // 360 + 60 + 12 blocks per window, two windows.
        assert_eq!(t.blocks, 2 * (180 + 30 + 6));
        assert!((t.threshold - normal_quantile(1.0 - 0.01 / (2.0 * 432.0))).abs() < 1e-12);
    }

    #[test]
    fn a_transient_is_found_where_it_is() {
        let n = 36_000;
        let time: Vec<f64> = (0..n).map(|i| i as f64 * 0.05).collect();
        let mut z = white(n, 7);
        // A 5 s step of 1.5σ at t = 600 s: √100·1.5 = 15σ over a 10 s block.
        for v in &mut z[12_000..12_100] {
            *v += 1.5;
        }
        let t = block_excursions(&z, &time, &[n], 0.01);
        let x = t.excursions.first().expect("found");
        assert!(x.start_s <= 600.0 && 605.0 <= x.end_s + 0.05, "{x:?}");
        assert!(x.z > 8.0, "{x:?}");
        assert_eq!(x.window, 0);
    }

    #[test]
    fn the_band_holds_one_and_not_a_misfit() {
        assert!(rms_in_band(1.0) && rms_in_band(0.95) && rms_in_band(1.2));
        assert!(!rms_in_band(1.4) && !rms_in_band(29.7) && !rms_in_band(f64::NAN));
    }
}
