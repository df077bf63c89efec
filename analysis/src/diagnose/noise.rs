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
//!
//! The residual is the gyro minus the model driven by the table's reference rate, so the
//! reference's error is in it too ([`ReferenceLines`]): a bin's reference is the step of the
//! fitted steady lines across it, `(L₁(end) − L₀(start))/S`, and each line is known only to
//! within its readings' scatter. Inside one segment only the line's rate error is left, common
//! to all its bins; across a rate change the two lines' angle errors at the bin's edges do not
//! cancel. A lab's table read at 10 Hz with jittered stamps leaves a line's end uncertain by
//! ~2e-7 rad, 2e-8 rad/s over a 10 s bin: several times a quiet FOG's own noise there.

use crate::joint_fit::NoiseSpec;
use crate::steady::TableMotion;

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
    reference: ReferenceLines,
}

/// The table reference's error in the bins (module docs): per steady segment, the fitted line's
/// angle at its mid time and its rate, independent (least squares about the mean time), each
/// with the σ its readings' scatter allows.
#[derive(Debug, Clone, Default)]
pub struct ReferenceLines {
    /// Per segment: variance of the line's angle at its mid time (rad²) and of its rate
    /// ((rad/s)²).
    var: Vec<[f64; 2]>,
    /// Per bin, the two ends: (segment, ∂reference/∂angle error, ∂reference/∂rate error).
    rows: Vec<[(usize, f64, f64); 2]>,
    /// Per segment, the group whose angle error it shares ([`Self::with_rounding`]: rests on one
    /// reading, turning lines of one rate and direction).
    group: Vec<Option<usize>>,
    /// Variance of each group's shared angle error, rad².
    group_var: Vec<f64>,
}

impl ReferenceLines {
    /// The error of `bins`' reference rates from `motion`'s segment lines. A segment's rate σ
    /// is its [`crate::steady::TableSegment::rate_sigma_rad_s`] (the larger of the white and
    /// the block estimate); its mid angle's σ is the larger of `scatter/√n` and the same
    /// estimate carried over from the rate's (`σ_rate·T/√12`, equal for white scatter). Bins
    /// with an end outside every segment get no reference error. The span stands for a bin's
    /// covered time (they differ by the few samples lost inside it, ≤ 1.5 % of a 10 s bin).
    pub fn new(motion: &TableMotion, bins: &[Bin]) -> Self {
        let var = motion
            .segments
            .iter()
            .map(|s| {
                let white = s.scatter_rad / (s.readings.max(1) as f64).sqrt();
                let mid = white.max(s.rate_sigma_rad_s * s.duration_s() / 12f64.sqrt());
                [mid * mid, s.rate_sigma_rad_s * s.rate_sigma_rad_s]
            })
            .collect();
        let mid = |i: usize| {
            let s = &motion.segments[i];
            0.5 * (s.start_s + s.end_s)
        };
        let rows = bins
            .iter()
            .map(|b| match (motion.segment_index_at(b.start_s), motion.segment_index_at(b.end_s)) {
                (Some(i0), Some(i1)) if b.span_s() > 0.0 => {
                    let span = b.span_s();
                    [
                        (i0, -1.0 / span, -(b.start_s - mid(i0)) / span),
                        (i1, 1.0 / span, (b.end_s - mid(i1)) / span),
                    ]
                }
                _ => [(0, 0.0, 0.0); 2],
            })
            .collect();
        let group = vec![None; motion.segments.len()];
        Self { var, rows, group, group_var: Vec::new() }
    }

    /// The same with each segment's angle error from the readout's rounding added where it does
    /// not average down ([`rounding_variance`]): the readings `(time_s, angle_rad)` of the
    /// table, on a grid of `motion.quantum_rad`. A table at rest reads one value for the whole
    /// segment, so its line's angle is known only to ±q/2 (σ = q/√12, 1.4e-6 rad for 1″: 1.4e-7
    /// rad/s over a 10 s bin, seven times a quiet FOG's bin noise) while the readings' scatter
    /// is 0; a turning table whose rate is near a whole number of steps per `m` readings
    /// repeats `m` rounding phases, σ = q/(m√12). Only the part beyond the white `q²/12n` that
    /// the scatter already carries is added.
    ///
    /// Rests on one reading share their error. A table that stops where it stopped before (a
    /// stop-start procedure turns the same arc each way, so every other rest is at one angle)
    /// reads the same value there, and the rounding is a function of the true angle: each rest
    /// is its own draw only if the true angles spread over the step. Both cases, and any
    /// between, are covered by an error shared by the rests on one reading (variance `q²/12`)
    /// beside each rest's own: the sum of rests on one reading, and the difference of two, are
    /// then never given less variance than they can have. Left out, a 5 h stop-start run's
    /// 26 rests on two readings (13 each) put one error `e/S` (σ = q/√12 over the bin's span)
    /// into 13 stops and `−e/S` into 13 starts, which the noise model took for 13 independent
    /// draws: the starts against the stops (the rival "dΩ/dt while speeding up only") were
    /// given √13 too small a σ.
    ///
    /// Turning lines of one rate, read at one interval in one direction, share theirs the same
    /// way (variance `2·q²·v`, `v` the least [`rounding_variance`] of the group). A procedure
    /// that turns one arc back and forth, its reversals on the readings' clock, reads the same
    /// angles on every pass: in a 2.6 h lab file at 27.77 and 17.68 °/min read at 2 Hz (833.1″
    /// and 530.4″ a reading, ten and five phases), the three CW lines at each rate had mean
    /// roundings within 0.016 q of each other (+0.047, +0.039, +0.031 q at 27.77 °/min; σ of one
    /// draw 0.029 q) and the CCW lines the opposite sign (−0.023, −0.031, −0.039 q). Each
    /// direction gets its own shared error, and twice `v`, so that a sum of both directions'
    /// lines and a difference are each given at least the variance they have whether the two
    /// directions' errors agree, oppose or are unrelated.
    ///
    /// Not for a readout that rounds coherently with the motion (every turning segment keeps
    /// one phase: [`super::prepare::reference_lines`] leaves the term out): every line's
    /// rounding is then fixed by the motion before it, one systematic in the time offset's σ,
    /// not a new draw per line. Bench's simulated table is such a readout (1″ steps; 10 °/min
    /// read at 2 Hz is 300″ a reading, a 1 °/s² start 50″): its readings lie on a 50″ grid, the
    /// only step [`crate::steady::TableMotion::quantum_rad`] can read off them, and `q²/12` of
    /// that is 2500 times the 1″ readout's — it hid the demo's 1/rev and a 0.2 ms time offset.
    pub fn with_rounding(
        mut self,
        motion: &TableMotion,
        time_s: &[f64],
        angle_rad: &[f64],
    ) -> Self {
        let q = motion.quantum_rad;
        if q <= 0.0 {
            return self;
        }
        // Resting segments by their reading, in steps.
        let mut rests: std::collections::BTreeMap<i64, Vec<usize>> = Default::default();
        // Turning segments: (advance a reading in steps, variance of the mean rounding in
        // steps², segment).
        let mut turning: Vec<(f64, f64, usize)> = Vec::new();
        for (j, (v, s)) in self.var.iter_mut().zip(&motion.segments).enumerate() {
            let lo = time_s.partition_point(|&t| t < s.start_s);
            let hi = time_s.partition_point(|&t| t <= s.end_s).min(angle_rad.len());
            if hi < lo + 2 {
                continue;
            }
            let (t, y) = (&time_s[lo..hi], &angle_rad[lo..hi]);
            let Some(dt) = crate::timebase::median_interval(t).filter(|d| *d > 0.0) else {
                continue;
            };
            // The readings' places on the sampling grid (a host's jitter moves stamps, not
            // values), and the advance per reading in readout steps from the angles themselves.
            let k: Vec<f64> = t.iter().map(|x| ((x - t[0]) / dt).round()).collect();
            let n = k.last().map_or(1.0, |l| l + 1.0);
            let per_reading =
                crate::stats::line(k.iter().copied().zip(y.iter().copied())).intercept_slope(0.0).1;
            let rounding = rounding_variance_near(per_reading / q, n);
            let extra = rounding - 1.0 / (12.0 * n);
            if extra > 0.0 {
                v[0] += q * q * extra;
            }
            if (per_reading / q * n).abs() < 1.0 {
                // The line moves less than a step over the segment: one reading, one rounding.
                let mid = y[y.len() / 2];
                rests.entry((mid / q).round() as i64).or_default().push(j);
            } else {
                turning.push((per_reading / q, rounding, j));
            }
        }
        for members in rests.into_values().filter(|m| m.len() > 1) {
            self.share(members, q * q / 12.0);
        }
        // Turning lines by their signed advance a reading: within a thousandth of a step, the
        // same rate read at the same interval in the same direction.
        turning.sort_by(|x, y| x.0.total_cmp(&y.0));
        for members in turning.chunk_by(|x, y| y.0 - x.0 < 1e-3).filter(|m| m.len() > 1) {
            let least = members.iter().map(|m| m.1).fold(f64::INFINITY, f64::min);
            self.share(members.iter().map(|m| m.2), 2.0 * q * q * least);
        }
        self
    }

    /// One more group: `members` (segments) share an angle error of variance `var`, rad².
    fn share(&mut self, members: impl IntoIterator<Item = usize>, var: f64) {
        for j in members {
            self.group[j] = Some(self.group_var.len());
        }
        self.group_var.push(var);
    }

    /// The term as arrays, for another implementation to rebuild `J·D·Jᵀ` (the residual
    /// scan's inputs): per bin, `ref_seg0`, `ref_angle0`, `ref_rate0` (its start) and the same
    /// with `1` (its end); per segment, `ref_var_angle`, `ref_var_rate` and `ref_group` (the
    /// shared rounding's group, -1 for none); per group, `ref_var_group`.
    pub fn arrays(&self) -> Vec<(&'static str, Vec<f64>)> {
        let col = |end: usize, f: &dyn Fn(&(usize, f64, f64)) -> f64| {
            self.rows.iter().map(|r| f(&r[end])).collect::<Vec<f64>>()
        };
        vec![
            ("ref_seg0", col(0, &|r| r.0 as f64)),
            ("ref_angle0", col(0, &|r| r.1)),
            ("ref_rate0", col(0, &|r| r.2)),
            ("ref_seg1", col(1, &|r| r.0 as f64)),
            ("ref_angle1", col(1, &|r| r.1)),
            ("ref_rate1", col(1, &|r| r.2)),
            ("ref_var_angle", self.var.iter().map(|v| v[0]).collect()),
            ("ref_var_rate", self.var.iter().map(|v| v[1]).collect()),
            ("ref_group", self.group.iter().map(|g| g.map_or(-1.0, |g| g as f64)).collect()),
            ("ref_var_group", self.group_var.clone()),
        ]
    }

    /// `Σ_ref·b` added to `out`: `J·D·Jᵀ·b`, J the bins' sensitivities to the lines' errors.
    fn apply_into(&self, b: &[f64], out: &mut [f64]) {
        if self.var.is_empty() || self.rows.len() != b.len() {
            return;
        }
        let mut u = vec![[0.0; 2]; self.var.len()];
        for (row, bi) in self.rows.iter().zip(b) {
            for &(s, ca, cr) in row {
                u[s][0] += ca * bi;
                u[s][1] += cr * bi;
            }
        }
        // The groups' shared angle errors: Jₐᵀb summed over each group's segments.
        let mut ug = vec![0.0; self.group_var.len()];
        for (us, g) in u.iter().zip(&self.group) {
            if let Some(g) = g {
                ug[*g] += us[0];
            }
        }
        for (x, v) in ug.iter_mut().zip(&self.group_var) {
            *x *= v;
        }
        for ((us, v), g) in u.iter_mut().zip(&self.var).zip(&self.group) {
            us[0] = us[0] * v[0] + g.map_or(0.0, |g| ug[g]);
            us[1] *= v[1];
        }
        for (row, o) in self.rows.iter().zip(out.iter_mut()) {
            for &(s, ca, cr) in row {
                *o += ca * u[s][0] + cr * u[s][1];
            }
        }
    }
}

/// Variance, in squared readout steps, of the mean rounding error of `n` consecutive readings
/// whose true angle advances `a` steps per reading, the rounding's phase at the first one
/// uniform: with `u − round(u) = Σ_h (−1)^{h+1} sin(2πhu)/(πh)`, the mean over the readings
/// has variance `Σ_h |c_h|²/(2π²h²)`, `c_h = (1/n)Σ_k e^{2πiha·k}` (a Dirichlet kernel). It is
/// `1/12` at rest or a whole number of steps per reading, `1/(12m²)` for `m` repeating phases,
/// and about `1/(12n)` (white) when the phase runs through every value.
pub fn rounding_variance(a: f64, n: f64) -> f64 {
    /// Harmonics summed: phases repeating every m ≤ 256 readings.
    const HARMONICS: u32 = 256;
    let n = n.max(1.0);
    (1..=HARMONICS)
        .map(|h| {
            let x = f64::from(h) * a;
            let x = x - x.round();
            let den = n * (std::f64::consts::PI * x).sin();
            let c2 = if den.abs() < 1e-12 {
                1.0
            } else {
                ((std::f64::consts::PI * x * n).sin() / den).powi(2)
            };
            c2 / (2.0 * std::f64::consts::PI.powi(2) * f64::from(h * h))
        })
        .sum()
}

/// [`rounding_variance`] at the largest the fitted advance `a` allows. Its peaks at `m`
/// repeating phases are `1/(h·n)` wide at harmonic `h`, narrower than a line's advance is known
/// from `n` rounded readings (σ ≈ `n^{-3/2}` steps): 266.1 steps a reading fitted 1.6e-4 off over
/// 196 readings gave 0.48 of the ten phases' `1/1200`. So also every `p/m` within
/// `2n^{-3/2}` of `a` whose `m` phases give more than the white `1/(12n)` (`m < √n`).
pub fn rounding_variance_near(a: f64, n: f64) -> f64 {
    let n = n.max(1.0);
    let half = 2.0 * n.powf(-1.5);
    let most = (n.sqrt().ceil() as u32).min(256);
    (1..=most)
        .filter_map(|m| {
            let p = (a * f64::from(m)).round() / f64::from(m);
            ((p - a).abs() <= half).then(|| rounding_variance(p, n))
        })
        .fold(rounding_variance(a, n), f64::max)
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
        let reference = ReferenceLines::default();
        Self { centre, comps, diag, rrw2: spec.rrw * spec.rrw, spec, reference }
    }

    /// The same covariance with the table reference's error added ([`ReferenceLines`]).
    pub fn with_reference(mut self, reference: ReferenceLines) -> Self {
        self.reference = reference;
        self
    }

    /// The same covariance with each bin's white variance times `scale` (a bin in a window
    /// whose own scatter exceeds the model's, [`super::scatter`]: 1 elsewhere).
    pub fn with_white_scale(mut self, bins: &[Bin], scale: &[f64]) -> Self {
        let white = self.spec.arw * self.spec.arw;
        for ((d, b), s) in self.diag.iter_mut().zip(bins).zip(scale) {
            if *s > 1.0 {
                *d += (s - 1.0) * white / b.span_s();
            }
        }
        self
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
        self.reference.apply_into(b, &mut out);
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

    /// Two steady lines (a CW one 0..100 s, a CCW one 110..200 s) and 10 s bins between them:
    /// nine inside the first line, one across the reversal, nine inside the second.
    fn two_lines() -> (TableMotion, Vec<Bin>) {
        let seg = |start_s: f64, end_s: f64, rate: f64, scatter_rad: f64, readings: usize| {
            let t = end_s - start_s;
            crate::steady::TableSegment {
                start_s,
                end_s,
                angle0_rad: 0.0,
                rate_rad_s: rate,
                command_rad_s: rate,
                scatter_rad,
                readings,
                rate_sigma_rad_s: scatter_rad * (12.0 / readings as f64).sqrt() / t,
            }
        };
        let motion = TableMotion {
            segments: vec![seg(0.0, 100.0, -3e-3, 6e-6, 1000), seg(110.0, 200.0, 3e-3, 4e-6, 900)],
            ..TableMotion::default()
        };
        let b: Vec<Bin> = (0..19)
            .map(|i| {
                let start_s =
                    if i < 9 { 5.0 + 10.0 * i as f64 } else { 95.0 + 10.0 * (i - 9) as f64 };
                let end_s = if i == 9 { 115.0 } else { start_s + 10.0 };
                Bin {
                    first: i,
                    end: i + 1,
                    start_s,
                    end_s,
                    table_rate_rad_s: 0.0,
                    table_accel_rad_s2: 0.0,
                    transition: i == 9,
                }
            })
            .collect();
        (motion, b)
    }

    #[test]
    fn a_bin_across_a_reversal_carries_both_lines_errors_and_a_steady_bin_only_its_rate() {
        let (motion, b) = two_lines();
        let spec = NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 };
        let m = BinNoise::new(&b, spec).with_reference(ReferenceLines::new(&motion, &b));
        let e = |i: usize| {
            let mut v = vec![0.0; b.len()];
            v[i] = 1.0;
            v
        };
        // A line fitted to n evenly spread readings of scatter σ over T: the angle at the mid
        // time σ/√n, the rate σ·√(12/n)/T, independent.
        let (a0, r0) = (6e-6 / 1000f64.sqrt(), 6e-6 * (12.0f64 / 1000.0).sqrt() / 100.0);
        let (a1, r1) = (4e-6 / 900f64.sqrt(), 4e-6 * (12.0f64 / 900.0).sqrt() / 90.0);
        // Steady bins: the line's rate error, the same in every bin of the line.
        assert!((m.quad(&e(2), &e(2)) / (r0 * r0) - 1.0).abs() < 1e-12);
        assert!((m.quad(&e(2), &e(7)) / (r0 * r0) - 1.0).abs() < 1e-12);
        assert!((m.quad(&e(12), &e(17)) / (r1 * r1) - 1.0).abs() < 1e-12);
        assert_eq!(m.quad(&e(2), &e(12)), 0.0);
        // The reversal's bin, 95..115 s: (L₁(115) − L₀(95))/20 with the lines' mid times at
        // 50 and 155 s.
        let want = (a0 * a0 + (45.0 * r0).powi(2) + a1 * a1 + (40.0 * r1).powi(2)) / 400.0;
        assert!((m.quad(&e(9), &e(9)) / want - 1.0).abs() < 1e-12);
        // It shares the first line's rate error with that line's bins: −(95 − 50)/20·r0²·1.
        let cross = -(45.0 / 20.0) * r0 * r0;
        assert!((m.quad(&e(9), &e(3)) / cross - 1.0).abs() < 1e-12);
        // An order of magnitude above a steady bin's: the angle errors at its edges.
        assert!(m.quad(&e(9), &e(9)) > 10.0 * m.quad(&e(2), &e(2)));
    }

    #[test]
    fn the_reference_term_matches_its_dense_covariance() {
        let (motion, b) = two_lines();
        let r = ReferenceLines::new(&motion, &b);
        let n = b.len();
        // Dense J·D·Jᵀ from the rows.
        let mut j = vec![vec![0.0; 4]; n];
        for (i, row) in r.rows.iter().enumerate() {
            for &(s, ca, cr) in row {
                j[i][2 * s] += ca;
                j[i][2 * s + 1] += cr;
            }
        }
        let d = [r.var[0][0], r.var[0][1], r.var[1][0], r.var[1][1]];
        let a: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
        let c: Vec<f64> = (0..n).map(|i| 0.3 + (i as f64 * 0.2).sin()).collect();
        let want: f64 = (0..n)
            .flat_map(|i| (0..n).map(move |k| (i, k)))
            .map(|(i, k)| a[i] * c[k] * (0..4).map(|q| j[i][q] * d[q] * j[k][q]).sum::<f64>())
            .sum();
        let m = BinNoise::new(&b, NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 })
            .with_reference(r);
        let got = m.quad(&a, &c);
        assert!((got - want).abs() < 1e-12 * want.abs(), "{got:e} vs {want:e}");
    }

    #[test]
    fn the_rounding_of_a_stepped_readout_is_whole_at_rest_and_white_when_its_phase_runs() {
        // At rest (or a whole number of steps per reading) every reading has one rounding (the
        // sum stops at 256 harmonics: 0.24 % short).
        assert!((rounding_variance(0.0, 1000.0) * 12.0 - 1.0).abs() < 4e-3);
        assert!((rounding_variance(60.0, 1000.0) * 12.0 - 1.0).abs() < 4e-3);
        // 8.87 °/min read at 2 Hz in 1″ steps: 266.1 steps a reading, ten phases that repeat.
        let m10 = rounding_variance(266.1, 1600.0) * 12.0 * 100.0;
        assert!((m10 - 1.0).abs() < 0.05, "{m10}");
        // A phase that runs through every value evenly (a golden-ratio advance): the
        // roundings cancel, below the white 1/(12n) the scatter already carries.
        let golden = 0.5 * (5f64.sqrt() - 1.0);
        let w = rounding_variance(123.0 + golden, 1000.0) * 12.0 * 1000.0;
        assert!(w < 0.1, "{w}");
    }

    #[test]
    fn a_table_at_rest_read_in_steps_leaves_its_angle_known_to_a_step() {
        // Rest until 100 s read at 2 Hz as one value of a 1″ grid, then 8.87 °/min from 102 s
        // (266.1 steps a reading: ten phases that repeat, σ = q/(10√12)); the bin 95..105 s
        // spans the start.
        let q = 4.848_136_811_095_36e-6;
        let w = 8.87 * std::f64::consts::PI / 180.0 / 60.0;
        let (time, angle, motion, bins) = rest_then_turning(q, w);
        let spec = NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 };
        // Without the rounding the readings' scatter (0) says the lines are exact.
        let bare = BinNoise::new(&bins, spec).with_reference(ReferenceLines::new(&motion, &bins));
        assert_eq!(bare.quad(&[1.0], &[1.0]), 0.0);
        // With it the rest line's angle is uniform over a step, the turning line's over a tenth
        // of one: (q²/12 + q²/1200)/S².
        let r = ReferenceLines::new(&motion, &bins).with_rounding(&motion, &time, &angle);
        let m = BinNoise::new(&bins, spec).with_reference(r);
        let want = q * q / 12.0 * 1.01 / 100.0;
        let got = m.quad(&[1.0], &[1.0]);
        assert!((got / want - 1.0).abs() < 0.02, "{got:e} vs {want:e}");
    }

    #[test]
    fn a_readout_that_rounds_in_phase_with_the_motion_adds_no_bin_noise() {
        // The same at 10 °/min: 300″ a reading, one phase for the whole turn. Each line's
        // rounding is then set by the motion before it (the time offset's systematic,
        // `prepare::readout_offset_sigma_s`), not drawn anew per line.
        let q = 4.848_136_811_095_36e-6;
        let w = 10.0 * std::f64::consts::PI / 180.0 / 60.0;
        let (time, angle, motion, bins) = rest_then_turning(q, w);
        let spec = NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 };
        let phases = super::super::prepare::TurnPhases::new(&motion, &time, &angle);
        let r = super::super::prepare::reference_lines(&motion, &bins, &time, &angle, &phases);
        assert_eq!(BinNoise::new(&bins, spec).with_reference(r).quad(&[1.0], &[1.0]), 0.0);
    }

    #[test]
    fn rests_on_one_reading_share_their_rounding_and_a_rest_of_its_own_does_not() {
        // Stop-start at 8.87 °/min read at 2 Hz on a 1″ grid: rest, CW, rest, CCW back over the
        // same arc, rest on the first reading again; a 10 s bin across each rate change.
        let q = 4.848_136_811_095_36e-6;
        let w = 8.87 * std::f64::consts::PI / 180.0 / 60.0;
        let time: Vec<f64> = (0..1000).map(|i| f64::from(i) * 0.5).collect();
        let truth = |t: f64| {
            let up = (t - 101.0).clamp(0.0, 99.0);
            let down = (t - 301.0).clamp(0.0, 99.0);
            7.3 * q + w * (up - down)
        };
        let angle: Vec<f64> = time.iter().map(|&t| (truth(t) / q).round() * q).collect();
        let command: Vec<f64> = time
            .iter()
            .map(|&t| match t {
                t if (101.0..200.0).contains(&t) => w,
                t if (301.0..400.0).contains(&t) => -w,
                _ => 0.0,
            })
            .collect();
        let motion = TableMotion::fit(&time, &angle, &command);
        let rests: Vec<usize> = (0..motion.segments.len())
            .filter(|&j| motion.segments[j].command_rad_s == 0.0)
            .collect();
        assert_eq!(rests.len(), 3, "{:?}", motion.segments);
        let bins = bins_across_changes(&motion);
        let r = ReferenceLines::new(&motion, &bins).with_rounding(&motion, &time, &angle);
        // The first and last rests read one value: one group; the middle one is alone.
        let (a, b, c) = (rests[0], rests[1], rests[2]);
        assert_eq!(r.group[a], Some(0));
        assert_eq!(r.group[c], Some(0));
        assert_eq!(r.group[b], None);
        assert_eq!(r.group_var, vec![q * q / 12.0]);
        let own_b = r.var[b][0];
        let spec = NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 };
        let m = BinNoise::new(&bins, spec).with_reference(r);
        let e = |i: usize| -> Vec<f64> { (0..4).map(|k| f64::from(u8::from(k == i))).collect() };
        let span = |i: usize| bins[i].span_s();
        // The first start (leaves rest a) and the last stop (onto rest c): −e_a/S₀ and +e_c/S₃
        // share the group's error and nothing else.
        let want = -(q * q / 12.0) / (span(0) * span(3));
        let got = m.quad(&e(0), &e(3));
        assert!((got / want - 1.0).abs() < 1e-12, "{got:e} vs {want:e}");
        // The stop onto rest b and the start from it share only b's own error.
        let want = -own_b / (span(1) * span(2));
        let got = m.quad(&e(1), &e(2));
        assert!((got / want - 1.0).abs() < 1e-12, "{got:e} vs {want:e}");
        assert!(own_b > 0.9 * q * q / 12.0, "{own_b:e}");
    }

    #[test]
    fn turning_lines_over_one_arc_share_their_rounding_one_group_a_direction() {
        // 8.87 °/min back and forth over one arc, read at 2 Hz on a 1″ grid (266.1 steps a
        // reading: ten phases), reversing every 100 s on the readings' clock: each pass reads
        // the angles the pass before it in that direction read.
        let q = 4.848_136_811_095_36e-6;
        let w = 8.87 * std::f64::consts::PI / 180.0 / 60.0;
        let time: Vec<f64> = (0..800).map(|i| f64::from(i) * 0.5).collect();
        let truth = |t: f64| {
            let p = t % 200.0;
            3.3 * q + w * if p < 100.0 { p } else { 200.0 - p }
        };
        let angle: Vec<f64> = time.iter().map(|&t| (truth(t) / q).round() * q).collect();
        let command: Vec<f64> =
            time.iter().map(|&t| if t % 200.0 < 100.0 { w } else { -w }).collect();
        let motion = TableMotion::fit(&time, &angle, &command);
        let lines: Vec<usize> = (0..motion.segments.len())
            .filter(|&j| motion.segments[j].command_rad_s != 0.0)
            .collect();
        assert_eq!(lines.len(), 4, "{:?}", motion.segments);
        // The premise: a pass's mean rounding is the one before it in its direction.
        let mean_rounding = |j: usize| {
            let s = &motion.segments[j];
            let (n, sum) = time
                .iter()
                .zip(&angle)
                .filter(|(t, _)| (s.start_s..=s.end_s).contains(*t))
                .fold((0.0, 0.0), |(n, sum), (&t, &a)| (n + 1.0, sum + a - truth(t)));
            sum / n
        };
        let e: Vec<f64> = lines.iter().map(|&j| mean_rounding(j)).collect();
        assert!((e[0] - e[2]).abs() < 0.05 * (e[0] - e[1]).abs(), "{e:?}");
        assert!((e[1] - e[3]).abs() < 0.05 * (e[0] - e[1]).abs(), "{e:?}");
        let bins = bins_across_changes(&motion);
        let r = ReferenceLines::new(&motion, &bins).with_rounding(&motion, &time, &angle);
        let (cw, ccw) = (r.group[lines[0]], r.group[lines[1]]);
        assert!(cw.is_some() && ccw.is_some() && cw != ccw, "{:?}", r.group);
        assert_eq!(r.group[lines[2]], cw);
        assert_eq!(r.group[lines[3]], ccw);
        // Each group twice the rounding of one line with ten phases, q²/1200.
        for g in &r.group_var {
            assert!((g / (2.0 * q * q / 1200.0) - 1.0).abs() < 0.05, "{g:e}");
        }
        let gv = r.group_var.clone();
        let spec = NoiseSpec { arw: 0.0, flicker_floor: 0.0, rrw: 0.0 };
        let m = BinNoise::new(&bins, spec).with_reference(r);
        let unit = |i: usize| -> Vec<f64> { (0..3).map(|k| f64::from(u8::from(k == i))).collect() };
        // The first and third reversals (CW onto CCW) share both groups' errors and no line.
        let want = (gv[0] + gv[1]) / (bins[0].span_s() * bins[2].span_s());
        let got = m.quad(&unit(0), &unit(2));
        assert!((got / want - 1.0).abs() < 1e-9, "{got:e} vs {want:e}");
    }

    /// A bin across each change between `motion`'s lines, from 5 s before the one's end to 5 s
    /// after the next one's start.
    fn bins_across_changes(motion: &TableMotion) -> Vec<Bin> {
        motion
            .segments
            .windows(2)
            .enumerate()
            .map(|(i, p)| Bin {
                first: i,
                end: i + 1,
                start_s: p[0].end_s - 5.0,
                end_s: p[1].start_s + 5.0,
                table_rate_rad_s: 0.0,
                table_accel_rad_s2: 0.0,
                transition: true,
            })
            .collect()
    }

    /// A table at rest until 100 s, then turning at `w` from 101 s, read at 2 Hz on a grid of
    /// `q` (its readings, its two steady lines), and one 10 s bin across the start.
    fn rest_then_turning(q: f64, w: f64) -> (Vec<f64>, Vec<f64>, TableMotion, Vec<Bin>) {
        let time: Vec<f64> = (0..400).map(|i| f64::from(i) * 0.5).collect();
        let angle: Vec<f64> = time
            .iter()
            .map(
                |&t| if t <= 101.0 { 7.0 * q } else { 7.0 * q + (w * (t - 101.0) / q).round() * q },
            )
            .collect();
        let seg =
            |start_s: f64, end_s: f64, rate: f64, readings: usize| crate::steady::TableSegment {
                start_s,
                end_s,
                angle0_rad: 7.0 * q + rate * (start_s - 101.0),
                rate_rad_s: rate,
                command_rad_s: rate,
                scatter_rad: 0.0,
                readings,
                rate_sigma_rad_s: 0.0,
            };
        let motion = TableMotion {
            segments: vec![seg(0.0, 100.0, 0.0, 201), seg(102.0, 199.5, w, 196)],
            quantum_rad: q,
            ..TableMotion::default()
        };
        let bins = vec![Bin {
            first: 0,
            end: 1,
            start_s: 95.0,
            end_s: 105.0,
            table_rate_rad_s: 0.0,
            table_accel_rad_s2: 0.0,
            transition: true,
        }];
        (time, angle, motion, bins)
    }
}
