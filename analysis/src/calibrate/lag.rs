//! The thermal lag of a gyro without its own sensor: the model temperature is the chamber air
//! through a first-order lag τ, profiled over 0..3000 s by the joint model's residual
//! ([`fit_lag`], the module docs of [`crate::calibrate`]).

use super::{CalibrateOptions, TemperatureSeries};
use crate::error::AnalysisError;
use crate::joint_fit::correlation_lag;
use crate::temperature_rate::local_linear_rate;
use crate::windows::RecordWindow;

/// The thermal-lag profile.
#[derive(Debug, Clone, PartialEq)]
pub struct LagFit {
    /// τ of least residual, s.
    pub best_s: f64,
    /// The τ the model temperature and the nuisance are taken at: `best_s` when significant
    /// (else 0), moved by the joint fit's Gauss–Newton steps ([`super::calibrate`]).
    pub used_s: f64,
    /// Confidence interval of τ from the profile (s): where `n_eff·ΔRSS/RSS` ≤ χ²₁.
    pub interval_s: (f64, f64),
    /// `n_eff·(RSS(0) − RSS(τ̂))/RSS(τ̂)`: the test statistic against τ = 0.
    pub statistic: f64,
    /// χ²₁ quantile at the confidence level.
    pub threshold: f64,
    /// Effective sample count of the residual.
    pub n_eff: f64,
    /// `(τ, RSS)` pairs evaluated, in τ order.
    pub profile: Vec<(f64, f64)>,
    /// The joint GLS fit's correction to `used_s` (its nuisance coefficient, [`lag_nuisance`]),
    /// s; 0 until fitted.
    pub gls_shift_s: f64,
    /// 1σ of the lag from the joint fit (its uncertainty, carried into every coefficient's σ),
    /// s; NaN until fitted or when not significant.
    pub sigma_s: f64,
}

impl LagFit {
    /// Whether the data tell τ from 0.
    pub fn significant(&self) -> bool {
        self.statistic > self.threshold
    }

    /// The lag fitted: `used_s` refined by the joint fit (0 when not significant).
    pub fn fitted_s(&self) -> f64 {
        if self.used_s > 0.0 && self.gls_shift_s.is_finite() {
            (self.used_s + self.gls_shift_s).max(0.0)
        } else {
            self.used_s
        }
    }
}

/// Residual sum of squares of the joint model (normal equations, columns scaled) and the
/// residual's correlation lag.
fn joint_rss(
    windows: &[RecordWindow],
    earth: f64,
    t0: f64,
    rate_window_s: f64,
) -> Result<(f64, usize, usize), AnalysisError> {
    let mut rows: Vec<[f64; 5]> = Vec::new();
    for w in windows {
        let temp = w.temperature_c();
        let rate = local_linear_rate(w.time_s(), temp, rate_window_s)?;
        for (((v, o), t), d) in
            w.gyro_rate_rad_s().iter().zip(w.table_rate_rad_s()).zip(temp).zip(&rate)
        {
            let om = o + earth;
            rows.push([1.0, om, t - t0, *d, v - om]);
        }
    }
    let n = rows.len();
    let mut scale = [0.0; 4];
    for r in &rows {
        for j in 0..4 {
            scale[j] += r[j] * r[j];
        }
    }
    for s in &mut scale {
        *s = (*s / n as f64).sqrt().max(f64::MIN_POSITIVE);
    }
    let mut xtx = nalgebra::Matrix4::<f64>::zeros();
    let mut xty = nalgebra::Vector4::<f64>::zeros();
    for r in &rows {
        let x = nalgebra::Vector4::new(
            r[0] / scale[0],
            r[1] / scale[1],
            r[2] / scale[2],
            r[3] / scale[3],
        );
        xtx += x * x.transpose();
        xty += x * r[4];
    }
    let beta = xtx
        .cholesky()
        .ok_or_else(|| AnalysisError::Insufficient("thermal lag: singular design".into()))?
        .solve(&xty);
    let resid: Vec<f64> = rows
        .iter()
        .map(|r| r[4] - (0..4).map(|j| beta[j] * r[j] / scale[j]).sum::<f64>())
        .collect();
    let rss = resid.iter().map(|e| e * e).sum();
    Ok((rss, n, correlation_lag(&resid, (n / 50).max(1))))
}

/// `windows` with the model temperature replaced by `series` lagged by `tau_s`.
fn with_lag(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
    tau_s: f64,
) -> Result<Vec<RecordWindow>, AnalysisError> {
    with_model_series(windows, &series.lagged(tau_s))
}

/// `windows` with the model temperature sampled from `series`.
pub(super) fn with_model_series(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
) -> Result<Vec<RecordWindow>, AnalysisError> {
    windows.iter().map(|w| w.with_model_temperature(series.sample(w.time_s()))).collect()
}

/// `eval` at every point of `grid`, split over the machine's cores: (point, RSS) in grid order.
fn eval_all<F>(grid: &[f64], eval: &F) -> Result<Vec<(f64, f64)>, AnalysisError>
where
    F: Fn(f64) -> Result<(f64, usize, usize), AnalysisError> + Sync,
{
    let threads =
        std::thread::available_parallelism().map_or(1, |n| n.get()).min(grid.len()).max(1);
    let chunk = grid.len().div_ceil(threads);
    let parts: Vec<Result<Vec<(f64, f64)>, AnalysisError>> = std::thread::scope(|s| {
        let handles: Vec<_> = grid
            .chunks(chunk.max(1))
            .map(|c| s.spawn(move || c.iter().map(|&t| eval(t).map(|r| (t, r.0))).collect()))
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(AnalysisError::Insufficient(
                        "thermal lag: a profile worker panicked".into(),
                    ))
                })
            })
            .collect()
    });
    let mut out = Vec::with_capacity(grid.len());
    for p in parts {
        out.extend(p?);
    }
    Ok(out)
}

/// Profile the thermal lag (module docs) over `series`.
pub fn fit_lag(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
    opts: &CalibrateOptions,
) -> Result<LagFit, AnalysisError> {
    if series.time_s.len() < 2 {
        return Err(AnalysisError::TooFewSamples {
            what: "thermal lag: temperature series".into(),
            got: series.time_s.len(),
            min: 2,
        });
    }
    let earth = opts
        .joint
        .latitude_deg
        .map_or(0.0, |lat| bench_physics::earth::vertical_rate_rad_s(lat, opts.joint.axis_up));
    let t0 = opts.joint.reference_temperature_c;
    let eval = |tau: f64| -> Result<(f64, usize, usize), AnalysisError> {
        joint_rss(&with_lag(windows, series, tau)?, earth, t0, opts.joint.rate_window_s)
    };
    // Coarse grid 0, 10·1.33^k .. 3000 s, then a fine grid between the best point's
    // neighbours and a parabola through the fine minimum; each grid evaluated on every core
    // (the points are independent).
    let mut grid = vec![0.0];
    let mut t = 10.0;
    while t <= 3000.0 {
        grid.push(t);
        t *= 1.33;
    }
    let mut profile = eval_all(&grid, &eval)?;
    let ibest =
        profile.iter().enumerate().min_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).map_or(0, |(i, _)| i);
    let (a, b) =
        (profile[ibest.saturating_sub(1)].0, profile[(ibest + 1).min(profile.len() - 1)].0);
    const FINE: usize = 16;
    let fine: Vec<f64> = (1..FINE).map(|k| a + (b - a) * k as f64 / FINE as f64).collect();
    profile.extend(eval_all(&fine, &eval)?);
    profile.sort_by(|x, y| x.0.total_cmp(&y.0));
    let k =
        profile.iter().enumerate().min_by(|x, y| x.1 .1.total_cmp(&y.1 .1)).map_or(0, |(i, _)| i);
    if k > 0 && k + 1 < profile.len() {
        // Vertex of the parabola through the minimum and its neighbours.
        let ((x0, y0), (x1, y1), (x2, y2)) = (profile[k - 1], profile[k], profile[k + 1]);
        let den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
        if den.abs() > 0.0 {
            let v =
                x1 - 0.5 * ((x1 - x0).powi(2) * (y1 - y2) - (x1 - x2).powi(2) * (y1 - y0)) / den;
            if v > x0 && v < x2 {
                profile.push((v, eval(v)?.0));
            }
        }
    }
    profile.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (best_s, _) =
        profile.iter().copied().min_by(|x, y| x.1.total_cmp(&y.1)).unwrap_or((0.0, f64::NAN));
    let (rss_best, n, k_e) = eval(best_s)?;
    let rss0 = profile[0].1;
    let n_eff = n as f64 / (2.0 * k_e as f64).max(1.0);
    let threshold = {
        let z = bench_physics::allan::normal_quantile(0.5 + opts.confidence / 2.0);
        z * z
    };
    let stat = |rss: f64| n_eff * (rss - rss_best) / rss_best;
    let inside: Vec<f64> =
        profile.iter().filter(|(_, r)| stat(*r) <= threshold).map(|(t, _)| *t).collect();
    let interval_s = (
        inside.iter().copied().fold(f64::INFINITY, f64::min),
        inside.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let statistic = stat(rss0);
    Ok(LagFit {
        best_s,
        used_s: if statistic > threshold { best_s } else { 0.0 },
        interval_s,
        statistic,
        threshold,
        n_eff,
        profile,
        gls_shift_s: 0.0,
        sigma_s: f64::NAN,
    })
}

/// The lag's linearised effect on the model at `tau_s`, one value per sample of each of
/// `model_windows` (the windows at the lagged model temperature): `k_t·∂T/∂τ + k_dt·∂Ṫ/∂τ`,
/// `T` and `Ṫ` the lagged series smoothed and differentiated as the windows' are
/// ([`super::model_series_windows`]), by central differences of ±max(1 s, 1 %) (at most τ/2),
/// with `coefficients` the OLS estimates at `tau_s`. Fitted as a fifth column beside the four
/// coefficients, its coefficient is the correction to τ and the fit's σ carry τ's
/// uncertainty. `None` when the series cannot be smoothed.
pub fn lag_nuisance(
    model_windows: &[RecordWindow],
    series: &TemperatureSeries,
    tau_s: f64,
    coefficients: [f64; 4],
    rate_window_s: f64,
) -> Option<crate::joint_fit::Nuisance> {
    let h = (0.01 * tau_s).max(1.0).min(0.5 * tau_s);
    if h <= 0.0 || !h.is_finite() {
        return None;
    }
    let (tp, rp) = series.lagged(tau_s + h).smoothed(rate_window_s).ok()?;
    let (tm, rm) = series.lagged(tau_s - h).smoothed(rate_window_s).ok()?;
    let dtemp: Vec<f64> = tp.iter().zip(&tm).map(|(a, b)| (a - b) / (2.0 * h)).collect();
    let drate: Vec<f64> = rp.iter().zip(&rm).map(|(a, b)| (a - b) / (2.0 * h)).collect();
    let (k_t, k_dt) = (coefficients[2], coefficients[3]);
    let values = model_windows
        .iter()
        .map(|w| {
            let at = w.time_s();
            let a = crate::interp::interp_at(&series.time_s, &dtemp, at);
            let b = crate::interp::interp_at(&series.time_s, &drate, at);
            a.iter().zip(&b).map(|(x, y)| k_t * x + k_dt * y).collect()
        })
        .collect();
    Some(crate::joint_fit::Nuisance { name: "thermal lag".into(), values })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::thermal_bias;
    use bench_physics::units::DEG_PER_MIN;
    use bench_physics::GyroModel;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// A gyro without a temperature sensor whose coil lags the air by `tau` s: air ramps ±1
    /// °C/min with holds, table CW then CCW, white noise only.
    fn lagged_run(tau: f64, seed: u64) -> (Vec<RecordWindow>, TemperatureSeries) {
        let dt = 0.5;
        let n = (4.0 * 3600.0 / dt) as usize;
        let time_s: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        // Air: hold 20 min, down 60 min, hold 40, up 60, hold ... (period 3 h 20 min).
        let air = |t: f64| -> f64 {
            let p = t % 12_000.0;
            let r = 1.0 / 60.0;
            if p < 1200.0 {
                20.0
            } else if p < 4800.0 {
                20.0 - r * (p - 1200.0)
            } else if p < 7200.0 {
                -40.0
            } else if p < 10_800.0 {
                -40.0 + r * (p - 7200.0)
            } else {
                20.0
            }
        };
        let series = TemperatureSeries { temp_c: time_s.iter().map(|&t| air(t)).collect(), time_s };
        let coil = series.lagged(tau);
        let rate = local_linear_rate(&coil.time_s, &coil.temp_c, 1.0).expect("rate");
        let m = GyroModel { temp_coeff: 5e-9, temp_rate_coeff: 1.5e-5, ..GyroModel::zero() };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut windows = Vec::new();
        for (k, (a, b)) in [(0usize, n / 2), (n / 2, n)].into_iter().enumerate() {
            let omega = if k == 0 { -10.0 * DEG_PER_MIN } else { 10.0 * DEG_PER_MIN };
            let t = series.time_s[a..b].to_vec();
            let v: Vec<f64> = (a..b)
                .map(|i| {
                    let e: f64 = StandardNormal.sample(&mut rng);
                    omega + thermal_bias(&m, coil.temp_c[i], rate[i]) + 2e-9 * e
                })
                .collect();
            windows.push(
                RecordWindow::new(
                    format!("record {k}"),
                    t,
                    v,
                    vec![omega; b - a],
                    None,
                    series.temp_c[a..b].to_vec(),
                )
                .expect("window"),
            );
        }
        (windows, series)
    }

    /// The lag's nuisance column is its first-order effect: taken at a τ 20 % short of the
    /// truth (a profile τ̂ that far off is ≈ 1.5σ(τ) on the lab writer's 2–3 h files with
    /// lags of 1000 s), one fit leaves k_t and k_dt biased by many σ, since the column carries
    /// the coefficients only part of the way. Re-linearised at the τ it fits (Gauss–Newton,
    /// [`super::super::relinearised`]), τ, k_t and k_dt come back to the truth within 2σ.
    #[test]
    fn the_lag_is_fitted_at_the_lag_it_finds_not_at_the_profile_start() {
        use super::super::{joint_options, relinearised, windows_at_lag};
        use crate::joint_fit::{joint_fit, ols_fit, Estimate, JointFitOptions, NoiseSpec};
        let mut opts = CalibrateOptions::default();
        opts.joint.rate_window_s = 30.0;
        let tau = 600.0;
        let (w, s) = lagged_run(tau, 3);
        let start = 0.8 * tau;
        let mw = windows_at_lag(&w, &s, start, &opts).expect("windows");
        let o = ols_fit(&mw, &joint_options(&opts)).expect("ols");
        let nuisance = lag_nuisance(&mw, &s, start, o.coefficients, opts.joint.rate_window_s);
        // The run's white noise: 2e-9 rad/s per 0.5 s sample.
        let noise = NoiseSpec { arw: 2e-9 * 0.5f64.sqrt(), flicker_floor: 0.0, rrw: 0.0 };
        let jo = JointFitOptions { noise: Some(noise), nuisance, ..joint_options(&opts) };
        let first = joint_fit(&mw, &jo).expect("fit");
        let mut l = LagFit {
            best_s: start,
            used_s: start,
            interval_s: (start, start),
            statistic: f64::INFINITY,
            threshold: 3.84,
            n_eff: 1.0,
            profile: Vec::new(),
            gls_shift_s: 0.0,
            sigma_s: f64::NAN,
        };
        let (_, _, after) = relinearised(&w, &s, &mut l, mw, jo, Ok(first.clone()), &opts);
        let after = after.expect("fit");
        let z = |e: &Estimate, truth: f64| (e.value - truth) / e.std_err;
        let (k_t, k_dt) = (5e-9, 1.5e-5);
        let before = z(&first.temp_coeff, k_t).abs().max(z(&first.temp_rate_coeff, k_dt).abs());
        assert!(before > 5.0, "one linearisation 20 % off: {before:.1}σ");
        assert!(z(&after.temp_coeff, k_t).abs() < 2.0, "{:?}", after.temp_coeff);
        assert!(z(&after.temp_rate_coeff, k_dt).abs() < 2.0, "{:?}", after.temp_rate_coeff);
        let step = after.nuisance.as_ref().expect("the lag's column");
        assert!(step.value.abs() <= 0.05 * step.std_err, "converged: {step:?}");
        assert!(
            (l.used_s + step.value - tau).abs() < 2.0 * step.std_err,
            "{} ± {}",
            l.used_s,
            step.std_err
        );
    }

    #[test]
    fn the_lag_profile_finds_a_real_lag_and_calls_none_when_there_is_none() {
        let mut opts = CalibrateOptions::default();
        opts.joint.rate_window_s = 30.0;
        let (w, s) = lagged_run(300.0, 1);
        let l = fit_lag(&w, &s, &opts).expect("profile");
        assert!(l.significant(), "{l:?}");
        assert!((l.used_s - 300.0).abs() < 3.0, "{l:?}");
        assert!(l.interval_s.0 <= l.best_s && l.best_s <= l.interval_s.1, "{l:?}");
        let (w, s) = lagged_run(0.0, 2);
        let l = fit_lag(&w, &s, &opts).expect("profile");
        assert!(l.used_s < 15.0, "{l:?}");
    }
}
