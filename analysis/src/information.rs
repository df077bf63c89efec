//! Identifiability before estimation: which coefficients a recording's procedure determines.
//!
//! Decided from the design alone — the regressors of every sample (`1`, `Ω_in`, `T − T0`,
//! `dT/dt`, and a fitted lag's sensitivity, [`crate::joint_fit::Nuisance`]) — and the noise
//! model, before any coefficient is estimated. The **Fisher information** of the coefficients
//! under the noise model is `I = XᵀΣ⁻¹X` (Σ: white noise, flicker as Gauss–Markov states, rate
//! random walk), computed by the Kalman whitening the GLS uses ([`crate::gls::whiten`]); its
//! inverse is the Cramér–Rao bound, the smallest σ any unbiased estimator reaches on this run.
//! Per coefficient:
//!
//! - **not excited**: its regressor is zero in every sample (no temperature change while
//!   recording, a table that never turns);
//! - **confounded**: the share of its information the others carry too, `ρ² = 1 − 1/(I_jj·C_jj)`
//!   (C = I⁻¹; the R² of its whitened regressor on theirs), above [`CONFOUNDED`]: the run
//!   cannot tell it from them;
//! - **too small to tell**: its expected size (a prior's, else the nominal model's) stands less
//!   than [`DETECTABLE_SIGMAS`] = `z(0.975) + z(0.80)` bound σ out — a two-sided test at 5 %
//!   would find a coefficient of that size with less than 80 % power, so an estimate would be
//!   mostly noise; with no expected size (nominal 0 and no prior) this test is not made.
//!
//! A coefficient not determined is **held** (not estimated): the one first in
//! [`HOLD_ORDER`] among those not determined is held, the information recomputed without it,
//! and so on — holding one can free another it was confounded with.

use bench_physics::ModelKey;
use nalgebra::{DMatrix, DVector};

use crate::error::AnalysisError;
use crate::joint_fit::{NoiseSpec, Nuisance};
use crate::timebase::median_interval;
use crate::windows::RecordWindow;

/// Above this share of its information carried by the others, a coefficient is confounded.
pub const CONFOUNDED: f64 = 0.99;

/// Expected size over bound σ below which a coefficient is too small for the run to tell:
/// `z(0.975) + z(0.80)` = 1.960 + 0.842.
pub const DETECTABLE_SIGMAS: f64 = 2.80;

/// The order in which undetermined coefficients are held: the temperature-rate term first (it
/// needs ramps), the scale factor (it needs the table turning both ways), the temperature term,
/// the bias last (any record window determines it).
pub const HOLD_ORDER: [ModelKey; 4] =
    [ModelKey::TempRateCoeff, ModelKey::ScaleFactorError, ModelKey::TempCoeff, ModelKey::Bias];

/// Why a coefficient is or is not determined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// The run determines it.
    Determined,
    /// Its regressor is zero everywhere.
    NotExcited,
    /// The others carry more than [`CONFOUNDED`] of its information.
    Confounded,
    /// Its expected size stands less than [`DETECTABLE_SIGMAS`] bound σ out.
    TooSmall,
}

impl Verdict {
    /// As written in the JSON.
    pub fn key(self) -> &'static str {
        match self {
            Verdict::Determined => "determined",
            Verdict::NotExcited => "not_excited",
            Verdict::Confounded => "confounded",
            Verdict::TooSmall => "too_small",
        }
    }
}

/// One coefficient's identifiability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Determination {
    /// The coefficient.
    pub key: ModelKey,
    /// Its Cramér–Rao σ on this run (contract unit; infinite when confounded outright, NaN
    /// when not excited), with the coefficients held before it fixed.
    pub sigma_bound: f64,
    /// Share of its information the others carry, 0–1.
    pub confounding: f64,
    /// The one it is most correlated with (a coefficient, or `None` for the nuisance).
    pub confounded_with: Option<ModelKey>,
    /// Its expected size (contract unit), when known.
    pub expected_size: Option<f64>,
    /// The verdict.
    pub verdict: Verdict,
    /// The information this run lacks to determine it: `(DETECTABLE_SIGMAS·σ/size)²` for one
    /// too small, else NaN.
    pub information_short_by: f64,
}

impl Determination {
    /// Whether the run determines it.
    pub fn determined(&self) -> bool {
        self.verdict == Verdict::Determined
    }
}

/// Settings of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub struct InformationOptions {
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Earth's rate along the axis, rad/s (0 without a latitude).
    pub earth_rad_s: f64,
    /// Window of the dT/dt filter, s.
    pub rate_window_s: f64,
    /// The noise model; `None`: no bound σ (the size test is not made).
    pub noise: Option<NoiseSpec>,
    /// Each coefficient's expected size, contract unit (`ModelKey::CALIBRATED` order).
    pub expected: [Option<f64>; 4],
}

/// The whitened, unit-RMS columns of the four coefficients and the nuisance over `windows`,
/// their RMS before whitening (0: not excited), and whether they were whitened.
fn whitened_design(
    windows: &[RecordWindow],
    nuisance: Option<&Nuisance>,
    opts: &InformationOptions,
) -> Result<(DMatrix<f64>, [f64; 5], bool), AnalysisError> {
    let n: usize = windows.iter().map(RecordWindow::len).sum();
    let mut rows: Vec<(f64, f64, [f64; 5])> = Vec::with_capacity(n);
    for (wi, w) in windows.iter().enumerate() {
        let rate = w.temperature_rate_c_s(opts.rate_window_s)?;
        let dt = median_interval(w.time_s()).unwrap_or(f64::NAN);
        for (k, (((t, o), temp), d)) in w
            .time_s()
            .iter()
            .zip(w.table_rate_rad_s())
            .zip(w.temperature_c())
            .zip(&rate)
            .enumerate()
        {
            let nu = nuisance.map_or(0.0, |nu| nu.values[wi][k]);
            let x = [1.0, o + opts.earth_rad_s, temp - opts.reference_temperature_c, *d, nu];
            rows.push((*t, dt, x));
        }
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut scale = [0.0; 5];
    for (_, _, x) in &rows {
        for j in 0..5 {
            scale[j] += x[j] * x[j];
        }
    }
    for s in &mut scale {
        *s = (*s / n.max(1) as f64).sqrt();
    }
    let mut z =
        DMatrix::from_fn(n, 5, |i, j| if scale[j] > 0.0 { rows[i].2[j] / scale[j] } else { 0.0 });
    let whitened = match &opts.noise {
        Some(spec) if spec.arw > 0.0 => {
            let t: Vec<f64> = rows.iter().map(|r| r.0).collect();
            let r: Vec<f64> = rows.iter().map(|r| spec.arw * spec.arw / r.1).collect();
            crate::gls::whiten(&t, &r, spec, &mut z)?;
            true
        }
        _ => false,
    };
    Ok((z, scale, whitened))
}

/// Per coefficient: which are determined, holding undetermined ones one at a time in
/// [`HOLD_ORDER`] (module docs). `nuisance` (a fitted lag's sensitivity) is estimated beside
/// the coefficients and never held.
pub fn identify(
    windows: &[RecordWindow],
    nuisance: Option<&Nuisance>,
    opts: &InformationOptions,
) -> Result<[Determination; 4], AnalysisError> {
    let (z, scale, whitened) = whitened_design(windows, nuisance, opts)?;
    let info = z.transpose() * &z;
    let mut free: Vec<usize> = (0..4).collect();
    if nuisance.is_some() && scale[4] > 0.0 {
        free.push(4);
    }
    let mut held_order: Vec<Determination> = Vec::new();
    loop {
        let d = assess(&info, &scale, &free, whitened, opts);
        let undetermined = HOLD_ORDER.iter().find_map(|k| {
            let j = ModelKey::CALIBRATED.iter().position(|c| c == k)?;
            let dj = d.iter().find(|x| x.key == *k)?;
            (free.contains(&j) && !dj.determined()).then_some((j, *dj))
        });
        match undetermined {
            Some((j, dj)) => {
                held_order.push(dj);
                free.retain(|&c| c != j);
            }
            None => {
                let mut out = d;
                for h in held_order {
                    if let Some(o) = out.iter_mut().find(|o| o.key == h.key) {
                        *o = h;
                    }
                }
                return Ok(out);
            }
        }
    }
}

/// The determination of every coefficient in `free` (others keep a placeholder) from the
/// information matrix of the scaled columns.
fn assess(
    info: &DMatrix<f64>,
    scale: &[f64; 5],
    free: &[usize],
    whitened: bool,
    opts: &InformationOptions,
) -> [Determination; 4] {
    let excited: Vec<usize> = free.iter().copied().filter(|&j| scale[j] > 0.0).collect();
    let sub = DMatrix::from_fn(excited.len(), excited.len(), |a, b| info[(excited[a], excited[b])]);
    // Correlation form: unit diagonal, so shares compare like with like.
    let d: Vec<f64> =
        (0..excited.len()).map(|a| sub[(a, a)].max(f64::MIN_POSITIVE).sqrt()).collect();
    let r = DMatrix::from_fn(sub.nrows(), sub.ncols(), |a, b| sub[(a, b)] / (d[a] * d[b]));
    std::array::from_fn(|j| {
        let key = ModelKey::CALIBRATED[j];
        let expected_size = opts.expected[j].filter(|s| s.is_finite() && *s > 0.0);
        let mut det = Determination {
            key,
            sigma_bound: f64::NAN,
            confounding: f64::NAN,
            confounded_with: None,
            expected_size,
            verdict: Verdict::Determined,
            information_short_by: f64::NAN,
        };
        if !free.contains(&j) {
            return det;
        }
        let Some(a) = excited.iter().position(|&c| c == j) else {
            det.verdict = Verdict::NotExcited;
            return det;
        };
        let others: Vec<usize> = (0..excited.len()).filter(|&b| b != a).collect();
        let (share, with) = share_with_others(&r, a, &others);
        det.confounding = share;
        det.confounded_with = with.and_then(|b| ModelKey::CALIBRATED.get(excited[b]).copied());
        let var = 1.0 / (sub[(a, a)] * (1.0 - share).max(0.0));
        det.sigma_bound = if whitened { var.sqrt() / scale[j] } else { f64::NAN };
        if share > CONFOUNDED {
            det.verdict = Verdict::Confounded;
        } else if let (Some(size), true) = (expected_size, det.sigma_bound.is_finite()) {
            let ratio = size / det.sigma_bound;
            if ratio < DETECTABLE_SIGMAS {
                det.verdict = Verdict::TooSmall;
                det.information_short_by = (DETECTABLE_SIGMAS / ratio).powi(2);
            }
        }
        det
    })
}

/// The share of column `a`'s information the `others` carry (`r`: the information in
/// correlation form): `r_aoᵀ·r_oo⁺·r_oa`, the R² of its whitened regressor on theirs, in
/// 0–1; and the other it is most correlated with.
fn share_with_others(r: &DMatrix<f64>, a: usize, others: &[usize]) -> (f64, Option<usize>) {
    if others.is_empty() {
        return (0.0, None);
    }
    let roo = DMatrix::from_fn(others.len(), others.len(), |i, j| r[(others[i], others[j])]);
    let roa = DVector::from_fn(others.len(), |i, _| r[(others[i], a)]);
    let share = match roo.clone().svd(true, true).solve(&roa, 1e-12) {
        Ok(b) => roa.dot(&b).clamp(0.0, 1.0),
        Err(_) => 1.0,
    };
    let with = others.iter().copied().max_by(|&x, &y| r[(x, a)].abs().total_cmp(&r[(y, a)].abs()));
    (share, with)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::DEG_PER_MIN;

    /// CW/CCW windows at 20 and 40 °C, and (optionally) ramps between them, 2 Hz.
    fn windows(ramps: bool) -> Vec<RecordWindow> {
        let w = 10.0 * DEG_PER_MIN;
        let mut specs = vec![(-w, 20.0, 0.0, 0.0), (w, 20.0, 0.0, 700.0), (-w, 40.0, 0.0, 9000.0)];
        specs.push((w, 40.0, 0.0, 9700.0));
        if ramps {
            specs.push((-w, 20.0, 1.0 / 60.0, 2000.0));
            specs.push((w, 40.0, -1.0 / 60.0, 5000.0));
        }
        crate::windows::synthetic_windows(&specs, |_, _, _| 0.0)
    }

    fn opts(expected_kdt: f64) -> InformationOptions {
        InformationOptions {
            reference_temperature_c: 20.0,
            earth_rad_s: 0.0,
            rate_window_s: 60.0,
            noise: Some(NoiseSpec { arw: 3e-7, flicker_floor: 1e-8, rrw: 0.0 }),
            expected: [None, None, Some(5e-9), Some(expected_kdt)],
        }
    }

    #[test]
    fn plateaus_alone_do_not_excite_the_temperature_rate_term_and_ramps_do() {
        let d = identify(&windows(false), None, &opts(1.5e-5)).expect("identifies");
        assert_eq!(d[3].verdict, Verdict::NotExcited, "{:?}", d[3]);
        assert!(d[..3].iter().all(Determination::determined), "{d:?}");
        let d = identify(&windows(true), None, &opts(1.5e-5)).expect("identifies");
        assert!(d.iter().all(Determination::determined), "{d:?}");
        // The bias' bound σ: the flicker floor (1e-8 rad/s) wanders over the 3 h like a bias,
        // so about that floor, far above white noise's N/√(total time) ≈ 4e-9.
        assert!(d[0].sigma_bound > 5e-9 && d[0].sigma_bound < 5e-8, "{:?}", d[0]);
        // An expected size far below what the ramps resolve: too small, and by how much.
        let tiny = d[3].sigma_bound * 0.5;
        let d = identify(&windows(true), None, &opts(tiny)).expect("identifies");
        assert_eq!(d[3].verdict, Verdict::TooSmall, "{:?}", d[3]);
        assert!((d[3].information_short_by - (2.8f64 / 0.5).powi(2)).abs() < 0.5, "{:?}", d[3]);
    }

    #[test]
    fn a_table_that_never_turns_confounds_the_scale_factor_with_the_bias_and_holds_it_first() {
        let still: Vec<RecordWindow> = windows(true)
            .into_iter()
            .map(|w| {
                RecordWindow::new(
                    w.label(),
                    w.time_s().to_vec(),
                    w.gyro_rate_rad_s().to_vec(),
                    vec![3e-5; w.len()],
                    w.gyro_temp_c().map(<[f64]>::to_vec),
                    w.chamber_temp_c().to_vec(),
                )
                .expect("window")
            })
            .collect();
        let d = identify(&still, None, &opts(1.5e-5)).expect("identifies");
        assert_eq!(d[1].verdict, Verdict::Confounded, "{:?}", d[1]);
        assert_eq!(d[1].confounded_with, Some(ModelKey::Bias));
        assert!(d[1].confounding > 0.999, "{:?}", d[1]);
        // Held, it frees the bias: determined once the scale factor is out.
        assert!(d[0].determined(), "{:?}", d[0]);
    }
}
