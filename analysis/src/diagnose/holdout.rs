//! The held-out check: the shape fitted on alternate blocks predicts the others.

use super::*;

/// Held-out check (module docs): combined z of the gain with which the shape fitted on one
/// set of alternate blocks explains the other.
///
/// Blocks alternate on the clock. A term that lives at a few instants on a schedule (the
/// reversals of a time offset, every 720 s) can fall wholly into one set of clock blocks (60 s
/// blocks: 720 s is 12 of them, every reversal lands in the same set). Where the clock's blocks
/// leave either set less than [`HOLDOUT_MIN_SHARE`] of the term's information, the bins on the
/// term's support are placed by the support time before them instead (the time off the support
/// left out, so its instants alternate between the sets whatever their schedule), the others by
/// the clock as before; on the support the blocks are a quarter of it, down to one bin (four
/// rate changes of a 40-minute run are four bins of support: their blocks alternate bin by bin,
/// where six-bin blocks would put all four in one set). Where neither does, the support is that
/// of the columns with the design projected out (a rate² term's information lies in the
/// table's rests, where its column is smallest). The choice reads the columns only, never the
/// data. A fold whose test set holds none of the term (its shape zero there) is no fold: a term
/// no fold can test is not judged (NaN), never "not confirmed" with z = 0.
pub(super) fn holdout_z(
    design: &[Vec<f64>],
    g: &[Vec<f64>],
    y: &[f64],
    bins: &[Bin],
    noise: &BinNoise,
    block_s: f64,
) -> f64 {
    let mag: Vec<f64> = (0..bins.len()).map(|i| g.iter().map(|c| c[i].abs()).sum()).collect();
    let HoldoutBlocks { clock_s: block, support_s, on_support } =
        holdout_blocks(bins, &mag, block_s);
    // What each set knows of the term: the variance of its coefficients fitted on all bins
    // over that fitted on the set alone (noise model). A set holding less than
    // HOLDOUT_MIN_SHARE of the information is never the fitting set: its fit would be noise of
    // either sign, then "tested" against the other set's full signal.
    let mut cols_all = design.to_vec();
    cols_all.extend(g.iter().cloned());
    let all: Vec<usize> = (0..bins.len()).collect();
    let term_var = |rows: &[usize]| -> Option<f64> {
        let p = Projector::new(&cols_all, rows).ok()?;
        let cov = p.covariance(noise);
        let mut v = 0.0;
        for j in design.len()..cols_all.len() {
            let c = p.kept.iter().position(|&k| k == j)?;
            v += cov[(c, c)];
        }
        Some(v)
    };
    let full_var = term_var(&all);
    let share = |rows: &[usize]| -> f64 {
        match (full_var, term_var(rows)) {
            (Some(f), Some(v)) if v > 0.0 => f / v,
            _ => 0.0,
        }
    };
    // Each set's share, computed once per partition (a fit and its covariance each).
    let shares = |(a, b): &(Vec<usize>, Vec<usize>)| (share(a), share(b));
    let least = |s: (f64, f64)| s.0.min(s.1);
    let on_clock: Vec<f64> = bins.iter().map(Bin::centre_s).collect();
    let mut sets = holdout_sets(&on_clock, block);
    let mut sets_share = shares(&sets);
    if least(sets_share) < HOLDOUT_MIN_SHARE {
        let other = holdout_sets(&on_support, support_s);
        let other_share = shares(&other);
        if least(other_share) > least(sets_share) {
            (sets, sets_share) = (other, other_share);
        }
    }
    if least(sets_share) < HOLDOUT_MIN_SHARE {
        // The term's information may lie where its columns are small: a rate² term is a
        // constant the bias takes while the table turns, and is known only from the rests.
        // The support of what the design cannot take (the columns with the design projected
        // out) places those bins in both sets.
        if let Ok(pd) = Projector::new(design, &all) {
            let free = pd.orthogonalise(g);
            let mut info = vec![0.0; bins.len()];
            for col in &free {
                for (r, &i) in pd.rows.iter().enumerate() {
                    info[i] += col[r].abs();
                }
            }
            let on_info = holdout_blocks(bins, &info, block_s);
            let other = holdout_sets(&on_info.on_support, on_info.support_s);
            let other_share = shares(&other);
            if least(other_share) > least(sets_share) {
                (sets, sets_share) = (other, other_share);
            }
        }
    }
    let (a, b) = sets;
    let mut num = 0.0;
    let mut den = 0.0;
    let mut folds = 0;
    for (fit_rows, fit_share, test_rows) in [(&a, sets_share.0, &b), (&b, sets_share.1, &a)] {
        if fit_rows.len() < 10 || test_rows.len() < 10 || fit_share < HOLDOUT_MIN_SHARE {
            continue;
        }
        let mut cols = design.to_vec();
        cols.extend(g.iter().cloned());
        let Ok(pf) = Projector::new(&cols, fit_rows) else { continue };
        let beta = pf.beta(y);
        let mut shape = vec![0.0; bins.len()];
        for (c, &j) in pf.kept.iter().enumerate() {
            if j >= design.len() {
                for (i, s) in shape.iter_mut().enumerate() {
                    *s += beta[c] * g[j - design.len()][i];
                }
            }
        }
        let Ok(pt) = Projector::new(design, test_rows) else { continue };
        if let Some(t) = pt.test(&[shape], y, noise) {
            let var = t.cov[(0, 0)];
            if var > 0.0 {
                folds += 1;
                num += t.theta[0] / var;
                den += 1.0 / var;
            }
        }
    }
    if folds == 0 {
        // The term lives within one set of blocks: held-out blocks cannot judge it.
        f64::NAN
    } else {
        num / den.sqrt()
    }
}

/// The hold-out's blocks for a term ([`holdout_blocks`]).
pub(super) struct HoldoutBlocks {
    /// Length of the clock's blocks, s: a quarter of the time the term is above a tenth of its
    /// peak (a warm-up lives in the first few τ), at most the option's, at least six bins.
    pub(super) clock_s: f64,
    /// Length of the blocks on the term's support, s: a quarter of the support, at most the
    /// option's, at least one bin (the support's bins lie apart on the clock: neighbours there
    /// are not neighbours in time).
    pub(super) support_s: f64,
    /// Each bin's time on the term's support: its centre less the span of the bins off the
    /// support before it.
    pub(super) on_support: Vec<f64>,
}

/// The hold-out's blocks for a term of magnitude `mag` per bin ([`holdout_z`]); a bin's length
/// is the bins' median span (the first bin may be cut short by a gap).
pub(super) fn holdout_blocks(bins: &[Bin], mag: &[f64], block_s: f64) -> HoldoutBlocks {
    let peak = mag.iter().fold(0.0f64, |m, v| m.max(*v));
    let support: f64 =
        bins.iter().zip(mag).filter(|(_, m)| **m > 0.1 * peak).map(|(b, _)| b.span_s()).sum();
    let mut spans: Vec<f64> = bins.iter().map(Bin::span_s).collect();
    spans.sort_by(f64::total_cmp);
    let bin_s = spans.get(spans.len() / 2).copied().unwrap_or(1.0);
    let quarter = (0.25 * support).min(block_s);
    let mut off_s = 0.0;
    let on_support: Vec<f64> = bins
        .iter()
        .zip(mag)
        .map(|(b, m)| {
            if *m > 0.1 * peak {
                b.centre_s() - off_s
            } else {
                off_s += b.span_s();
                b.centre_s()
            }
        })
        .collect();
    HoldoutBlocks { clock_s: quarter.max(6.0 * bin_s), support_s: quarter.max(bin_s), on_support }
}

/// The bins in even and in odd blocks of `block_s` of their time `clock`.
pub(super) fn holdout_sets(clock: &[f64], block_s: f64) -> (Vec<usize>, Vec<usize>) {
    (0..clock.len()).partition(|&i| ((clock[i] / block_s).floor() as i64).rem_euclid(2) == 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::series::test_bins;
    use crate::joint_fit::NoiseSpec;

    /// 240 bins of 10 s (a 40-minute run), the first cut short by a gap, and a time offset's
    /// column: non-zero in the four bins that hold a rate change (a start, two reversals, a
    /// stop, 720 s apart: all in odd 60 s clock blocks but the last).
    fn run() -> (Vec<Bin>, Vec<f64>) {
        let mut bins = test_bins(240);
        bins[0].start_s = 9.9;
        let mut g = vec![0.0; bins.len()];
        for (i, v) in [(11, 1.0), (83, -2.0), (155, 2.0), (227, -1.0)] {
            g[i] = v;
        }
        (bins, g)
    }

    #[test]
    fn the_blocks_are_the_median_bins_and_the_support_alternates_bin_by_bin() {
        let (bins, g) = run();
        let mag: Vec<f64> = g.iter().map(|v| v.abs()).collect();
        let b = holdout_blocks(&bins, &mag, 600.0);
        // A quarter of the 40 s support, at least six median bins on the clock (the first
        // bin's 0.1 s does not shorten them) and one on the support.
        assert_eq!((b.clock_s, b.support_s), (60.0, 10.0));
        let (a, c) = holdout_sets(&b.on_support, b.support_s);
        let on = |set: &[usize]| set.iter().filter(|&&i| g[i] != 0.0).count();
        assert_eq!((on(&a), on(&c)), (2, 2), "the four rate changes split between the sets");
    }

    #[test]
    fn a_term_at_four_scheduled_instants_is_confirmed_by_the_held_out_blocks() {
        let (bins, g) = run();
        let noise = BinNoise::new(&bins, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 });
        // The bins' noise (σ ≈ 0.32 each), a bias, and the term at 100σ.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let y: Vec<f64> = g
            .iter()
            .map(|v| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                0.5 + 32.0 * v + u * 1.1
            })
            .collect();
        let z = holdout_z(&[vec![1.0; bins.len()]], &[g], &y, &bins, &noise, 600.0);
        // Six-bin blocks on the support put all four instants in one set: the other held none
        // of the term, and its empty test counted as a fold of z = 0 ("not confirmed").
        assert!(z > 50.0, "held-out z {z}");
    }
}
