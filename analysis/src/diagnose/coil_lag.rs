//! The coil's lag behind the chamber air, for a gyro without its own temperature sensor: a
//! coefficient of the nominal model (`thermal_time_constant`), profiled here before the search.
//!
//! Without a sensor the model temperature is the chamber air through the model's first-order
//! lag ([`Native::build`]). A lab's model states that lag from a datasheet or an earlier run;
//! the coil's own may be twice or a third of it. The error is then no effect of its own: the
//! thermal terms follow the air early or late, `k_dt·dT/dt` leaves a transient of `τ`'s size
//! after every ramp's start and end (a ramp of 2 °C/min under the writer's k_dt: ≈ 1e-7 rad/s,
//! ten times the flicker), and on a 1 h run a transient decaying over 500–1000 s has the shape
//! of a bias step, a drift or a quadratic in temperature. Measured on the lab writer's random
//! nulls (seeds 17, 20, 26, 30, 36, 59 of `scripts/lab_diagnose_study.py random --hours
//! 0.75,1.5`: every false finding and two false unexplained, all on gyros without a sensor,
//! coil lags 499–1085 s against the lab's 300 s): with the true lag given, all six are clean.
//!
//! So the lag is refitted with the nominal parameters it acts through: the base design (bias,
//! scale factor, k_t, k_dt) is projected out at each τ of a log grid and the least-squares
//! residual profiled ([`profile`]); its minimum is refined by a parabola. The update is taken
//! only when the data determine it: the change it makes to the model, the base projected out,
//! tested as one column against the model lag's residual under the run's noise model (the
//! bins' covariance, flicker and reference lines included) at χ²₁(1 − α), as a term is. Its σ
//! is the linearised least-squares σ of τ under the same covariance. Otherwise the lab's lag is
//! held, as any coefficient the run does not determine.

use super::*;

/// The lag the profile reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CoilLag {
    /// The model's lag, s.
    pub(super) nominal_s: f64,
    /// The profile's minimum, s.
    pub(super) fitted_s: f64,
    /// Its 1σ under the noise model, s.
    pub(super) sigma_s: f64,
    /// Wald statistic of the change from the model's lag to the fitted one ([`profile`]).
    pub(super) wald: f64,
    /// χ²₁(1 − α).
    pub(super) threshold: f64,
}

impl CoilLag {
    /// Whether the run tells the coil's lag from the model's.
    pub(super) fn significant(&self) -> bool {
        self.wald > self.threshold
    }
}

/// Profile the coil's lag on `prep` (prepared with `model`'s lag, `noise_spec` its noise
/// model); `None` where the gyro has its own sensor, the nominal effects already lag the
/// temperature, or the profile is flat.
pub(super) fn profile(
    prep: &Prepared,
    noise_spec: NoiseSpec,
    run: &RunSeries,
    model: &GyroModel,
    effects: &Effects,
    alpha: f64,
) -> Result<Option<CoilLag>, AnalysisError> {
    if run.gyro_temp_c.is_some() || effects.has(EffectId::ThermalLag) {
        return Ok(None);
    }
    let nat = &prep.native;
    let (bins, dt, t0) = (&prep.bins, &nat.dt, prep.t0);
    let n = bins.len();
    // The nominal residual with the model's thermal terms added back: they lie in the base's
    // span at the model's lag, and at any other lag the base refits them.
    let y: Vec<f64> = (0..n)
        .map(|i| {
            prep.y[i] - prep.pred[i]
                + model.temp_coeff * prep.base[2][i]
                + model.temp_rate_coeff * prep.base[3][i]
        })
        .collect();
    // Bins that hold a rate change carry the time offset and the reference lines' ends: left
    // out of the profile (they do not depend on the lag).
    let rows: Vec<usize> = (0..n).filter(|&i| !bins[i].transition).collect();
    if rows.len() < 20 {
        return Ok(None);
    }
    let thermal = |tau: f64| -> Result<[Vec<f64>; 2], AnalysisError> {
        let (temp, rate) = series::coil_temperature(&nat.t, &nat.air_c, tau)?;
        Ok([bin_mean(bins, dt, |k| temp[k] - t0), bin_mean(bins, dt, |k| rate[k])])
    };
    let design = |tau: f64| -> Result<Vec<Vec<f64>>, AnalysisError> {
        let [tm, rm] = thermal(tau)?;
        Ok(vec![prep.base[0].clone(), prep.base[1].clone(), tm, rm])
    };
    let rss = |tau: f64| -> Result<f64, AnalysisError> {
        let r = Projector::new(&design(tau)?, &rows)?.residual(&y, n);
        Ok(r.iter().map(|x| x * x).sum())
    };
    // Log grid 30..4000 s (×1.25) and the model's own lag.
    let nominal = model.thermal_time_constant;
    let mut grid: Vec<f64> = std::iter::successors(Some(30.0), |t| Some(t * 1.25))
        .take_while(|t| *t <= 4000.0)
        .collect();
    if nominal > 0.0 {
        grid.push(nominal);
        grid.sort_by(f64::total_cmp);
    }
    let prof: Vec<(f64, f64)> =
        grid.iter().map(|&t| rss(t).map(|v| (t, v))).collect::<Result<_, _>>()?;
    let k = prof.iter().enumerate().min_by(|a, b| a.1 .1.total_cmp(&b.1 .1)).map_or(0, |(i, _)| i);
    let mut best = prof[k].0;
    if k > 0 && k + 1 < prof.len() {
        // The parabola's vertex in ln τ through the minimum and its neighbours.
        let (x0, x1, x2) = (prof[k - 1].0.ln(), prof[k].0.ln(), prof[k + 1].0.ln());
        let (y0, y1, y2) = (prof[k - 1].1, prof[k].1, prof[k + 1].1);
        let den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
        if den.abs() > 0.0 {
            let v =
                x1 - 0.5 * ((x1 - x0).powi(2) * (y1 - y2) - (x1 - x2).powi(2) * (y1 - y0)) / den;
            if v.is_finite() && v > x0 && v < x2 && rss(v.exp())? < prof[k].1 {
                best = v.exp();
            }
        }
    }
    // σ of τ: the model's response to τ (at the fitted k_t, k_dt), the base projected out,
    // its least-squares coefficient's variance under the noise model.
    let base_at = Projector::new(&design(best)?, &rows)?;
    let beta = base_at.beta(&y);
    let coef = |j: usize| base_at.kept.iter().position(|&c| c == j).map_or(0.0, |c| beta[c]);
    let (kt, kdt) = (coef(2), coef(3));
    let h = 0.02 * best;
    let [tp, rp] = thermal(best + h)?;
    let [tmn, rmn] = thermal(best - h)?;
    let d: Vec<f64> =
        (0..n).map(|i| (kt * (tp[i] - tmn[i]) + kdt * (rp[i] - rmn[i])) / (2.0 * h)).collect();
    let c = base_at.residual(&d, n);
    let cc: f64 = c.iter().map(|x| x * x).sum();
    if cc.is_nan() || cc <= 0.0 {
        return Ok(None);
    }
    let noise = BinNoise::new(bins, noise_spec).with_reference(prep.reference.clone());
    let sigma = noise.quad(&c, &c).sqrt() / cc;
    // The test: the change the fitted lag makes to the model (at the fitted k_t, k_dt), the
    // model lag's base projected out, as one column against the model lag's residual under
    // the noise model — the Wald statistic of a term, as every effect is tested; a linearised
    // `((τ̂ − τ₀)/σ)²` would understate a long lag, whose response saturates.
    let wald = if nominal > 0.0 {
        let base0 = Projector::new(&design(nominal)?, &rows)?;
        let [t0m, r0m] = thermal(nominal)?;
        let [t1m, r1m] = thermal(best)?;
        let u: Vec<f64> =
            (0..n).map(|i| kt * (t1m[i] - t0m[i]) + kdt * (r1m[i] - r0m[i])).collect();
        let u = base0.residual(&u, n);
        let r0 = base0.residual(&y, n);
        let uu = noise.quad(&u, &u);
        let ur: f64 = u.iter().zip(&r0).map(|(a, b)| a * b).sum();
        if uu > 0.0 {
            ur * ur / uu
        } else {
            0.0
        }
    } else {
        f64::INFINITY
    };
    Ok(Some(CoilLag {
        nominal_s: nominal,
        fitted_s: best,
        sigma_s: sigma,
        wald,
        threshold: chi2_quantile(1.0 - alpha, 1.0),
    }))
}
