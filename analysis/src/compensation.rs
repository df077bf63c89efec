//! A calibration applied to a run: per record window, the gyro's error against the table before
//! and after compensation, what the calibration's own uncertainty and the gyro's noise allow,
//! and which coefficient moves it most — the production step after calibration (`bench
//! verify`), and what a calibration does to the run it came from.
//!
//! The gyro's output is `V = (1 + s)·Ω_in + b + k_t·(T − T0) + k_dt·dT/dt + noise`. Its
//! **uncompensated error** is `V − Ω_in`; compensated with a calibration `(b̂, ŝ, k̂_t, k̂_dt)`,
//! the rate it reports is `Ω̂ = (V − b̂ − k̂_t·(T − T0) − k̂_dt·dT/dt)/(1 + ŝ)` and its error
//! `Ω̂ − Ω_in`. Both are averaged over each window (the noise averages; the thermal error is
//! what stays). A window's compensated error is expected within
//!
//! - the calibration's uncertainty through the window's mean regressors, `√(x̄ᵀ·C·x̄)` (C the
//!   calibration's covariance: its estimated coefficients', a held one's σ when it has one);
//! - the noise of a window mean under the noise model (white `N²/D`, each flicker Gauss–Markov
//!   component `σ_i²·2(x − 1 + e^{−x})/x²` with `x = D/T_i`, rate random walk `K²·D/3`);
//!
//! its `z` is the compensated error over their root sum of squares.
//!
//! **Worse**: the compensation makes the gyro worse when the RMS of the compensated window
//! errors exceeds the uncompensated one by more than three times what the calibration's
//! stated uncertainty could do (`RMS_c² − RMS_u² > 9·mean(σ_cal²)`): a compensation
//! consistent with its σ never fails so; one built on a wrong coefficient does. The coefficient
//! **responsible** is the one whose compensation, left out, lowers the compensated RMS most.

use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::ModelKey;

use crate::error::AnalysisError;
use crate::joint_fit::NoiseSpec;
use crate::windows::RecordWindow;

/// What is applied.
#[derive(Debug, Clone, PartialEq)]
pub struct CompensationOptions {
    /// Bias, scale-factor error, k_t, k_dt (`ModelKey::CALIBRATED` order), contract units.
    pub coefficients: [f64; 4],
    /// Their covariance, contract units (zeros where unknown).
    pub covariance: [[f64; 4]; 4],
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Site latitude, degrees north; `None`: Earth's rate is not removed.
    pub latitude_deg: Option<f64>,
    /// Sensing axis up.
    pub axis_up: bool,
    /// Window of the dT/dt filter, s (windows carry their whole-run rate when given).
    pub rate_window_s: f64,
    /// The gyro's noise, for the noise of a window mean; `None`: not counted.
    pub noise: Option<NoiseSpec>,
    /// Family-wise level of the windows' z test (Bonferroni over the windows).
    pub alpha: f64,
}

/// One window's errors, rad/s.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowError {
    /// The window's label.
    pub label: String,
    /// First and last sample time, s.
    pub span_s: (f64, f64),
    /// Samples.
    pub samples: usize,
    /// Mean model temperature, °C.
    pub mean_temp_c: f64,
    /// Mean dT/dt, °C/s.
    pub mean_rate_c_s: f64,
    /// Mean table rate, rad/s.
    pub mean_table_rate_rad_s: f64,
    /// Mean of `V − Ω_in`.
    pub uncompensated: f64,
    /// Mean of `Ω̂ − Ω_in`.
    pub compensated: f64,
    /// What each coefficient's term takes out, mean over the window (`ModelKey::CALIBRATED`).
    pub terms: [f64; 4],
    /// The calibration's uncertainty here.
    pub sigma_calibration: f64,
    /// The noise of the window mean.
    pub sigma_noise: f64,
    /// `compensated / √(σ_cal² + σ_noise²)`.
    pub z: f64,
}

/// Result of [`compensate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Compensation {
    /// Per window.
    pub windows: Vec<WindowError>,
    /// RMS of the windows' uncompensated errors, rad/s.
    pub rms_uncompensated: f64,
    /// RMS of their compensated errors, rad/s.
    pub rms_compensated: f64,
    /// Index of the window with the largest |compensated error|.
    pub worst: usize,
    /// Largest |z|.
    pub max_abs_z: f64,
    /// The |z| a window of a calibration that holds exceeds with probability `alpha` over all
    /// windows (Bonferroni).
    pub z_threshold: f64,
    /// Whether the compensation makes the gyro worse (module docs).
    pub worse: bool,
    /// The coefficient whose compensation, left out, lowers the compensated RMS most, and that
    /// RMS (rad/s); `None` when leaving any out makes it worse.
    pub responsible: Option<(ModelKey, f64)>,
}

impl Compensation {
    /// Whether every window's compensated error is within what the calibration and the noise
    /// allow (`|z| ≤ z_threshold`).
    pub fn within_sigma(&self) -> bool {
        self.max_abs_z <= self.z_threshold
    }
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// Variance of the mean of the noise over `duration_s` (module docs).
pub fn window_mean_variance(spec: &NoiseSpec, duration_s: f64) -> f64 {
    let d = duration_s.max(f64::MIN_POSITIVE);
    let mut v = spec.arw * spec.arw / d + spec.rrw * spec.rrw * d / 3.0;
    if spec.flicker_floor > 0.0 {
        for (t, sd) in bench_physics::noise::bias_instability_components(spec.flicker_floor) {
            let x = d / t;
            let g = if x < 1e-6 { 1.0 - x / 3.0 } else { 2.0 * (x - 1.0 + (-x).exp()) / (x * x) };
            v += sd * sd * g;
        }
    }
    v
}

/// One window's errors under `opts`.
fn window_error(
    w: &RecordWindow,
    earth: f64,
    opts: &CompensationOptions,
) -> Result<WindowError, AnalysisError> {
    let [b, s, kt, kdt] = opts.coefficients;
    let t0 = opts.reference_temperature_c;
    let rate = w.temperature_rate_c_s(opts.rate_window_s)?;
    let temp = w.temperature_c();
    let n = w.len();
    let omega: Vec<f64> = w.table_rate_rad_s().iter().map(|o| o + earth).collect();
    let v = w.gyro_rate_rad_s();
    let uncompensated = mean((0..n).map(|i| v[i] - omega[i]));
    let compensated = mean(
        (0..n).map(|i| (v[i] - b - kt * (temp[i] - t0) - kdt * rate[i]) / (1.0 + s) - omega[i]),
    );
    let xbar = [
        1.0,
        mean(omega.iter().copied()),
        mean(temp.iter().map(|t| t - t0)),
        mean(rate.iter().copied()),
    ];
    let terms: [f64; 4] = std::array::from_fn(|j| opts.coefficients[j] * xbar[j]);
    let mut var_cal = 0.0;
    for i in 0..4 {
        for j in 0..4 {
            let c = opts.covariance[i][j];
            if c.is_finite() {
                var_cal += xbar[i] * c * xbar[j];
            }
        }
    }
    let span_s = (w.time_s()[0], w.time_s()[n - 1]);
    let sigma_noise =
        opts.noise.map_or(0.0, |spec| window_mean_variance(&spec, span_s.1 - span_s.0).sqrt());
    let sigma_calibration = var_cal.max(0.0).sqrt();
    let total = sigma_calibration.hypot(sigma_noise);
    Ok(WindowError {
        label: w.label().to_owned(),
        span_s,
        samples: n,
        mean_temp_c: mean(temp.iter().copied()),
        mean_rate_c_s: xbar[3],
        mean_table_rate_rad_s: mean(w.table_rate_rad_s().iter().copied()),
        uncompensated,
        compensated,
        terms,
        sigma_calibration,
        sigma_noise,
        z: if total > 0.0 { compensated / total } else { f64::NAN },
    })
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    mean(v.map(|x| x * x)).sqrt()
}

/// Apply the calibration of `opts` to `windows` (each with its model temperature, ideally its
/// whole-run smoothed rate) and judge it (module docs).
pub fn compensate(
    windows: &[RecordWindow],
    opts: &CompensationOptions,
) -> Result<Compensation, AnalysisError> {
    if windows.is_empty() {
        return Err(AnalysisError::Insufficient("compensation: no record windows".into()));
    }
    let earth = opts.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, opts.axis_up));
    let errors: Vec<WindowError> =
        windows.iter().map(|w| window_error(w, earth, opts)).collect::<Result<_, _>>()?;
    let rms_u = rms(errors.iter().map(|e| e.uncompensated));
    let rms_c = rms(errors.iter().map(|e| e.compensated));
    let worst = (0..errors.len())
        .max_by(|&a, &b| errors[a].compensated.abs().total_cmp(&errors[b].compensated.abs()))
        .unwrap_or(0);
    let max_abs_z = errors.iter().map(|e| e.z.abs()).filter(|z| z.is_finite()).fold(0.0, f64::max);
    let z_threshold =
        bench_physics::allan::normal_quantile(1.0 - opts.alpha / (2.0 * errors.len() as f64));
    let cal_var = mean(errors.iter().map(|e| e.sigma_calibration * e.sigma_calibration));
    let worse = rms_c * rms_c - rms_u * rms_u > 9.0 * cal_var;
    // Each term left uncompensated: its take added back (first order in s).
    let responsible = (0..4)
        .map(|j| (ModelKey::CALIBRATED[j], rms(errors.iter().map(|e| e.compensated + e.terms[j]))))
        .filter(|(_, r)| *r < rms_c)
        .min_by(|a, b| a.1.total_cmp(&b.1));
    Ok(Compensation {
        windows: errors,
        rms_uncompensated: rms_u,
        rms_compensated: rms_c,
        worst,
        max_abs_z,
        z_threshold,
        worse,
        responsible,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::DEG_PER_MIN;

    /// Windows of a gyro following `truth` exactly, at 20, 40 °C and on a 1 °C/min ramp.
    fn windows(truth: [f64; 4]) -> Vec<RecordWindow> {
        let w = 10.0 * DEG_PER_MIN;
        let specs = [(w, 20.0, 0.0, 0.0), (-w, 40.0, 0.0, 5000.0), (w, 20.0, 1.0 / 60.0, 9000.0)];
        crate::windows::synthetic_windows(&specs, |rate, tc, slope| {
            (1.0 + truth[1]) * rate + truth[0] + truth[2] * (tc - 20.0) + truth[3] * slope
        })
    }

    fn opts(coefficients: [f64; 4], sigma: f64) -> CompensationOptions {
        let mut covariance = [[0.0; 4]; 4];
        for (j, row) in covariance.iter_mut().enumerate() {
            row[j] = (sigma * coefficients[j].abs().max(1e-9)).powi(2);
        }
        CompensationOptions {
            coefficients,
            covariance,
            reference_temperature_c: 20.0,
            latitude_deg: None,
            axis_up: true,
            rate_window_s: 60.0,
            noise: None,
            alpha: 0.01,
        }
    }

    #[test]
    fn the_true_model_takes_the_error_out_and_a_wrong_rate_term_is_named() {
        let truth = [1e-7, 5e-5, 5e-9, 1.5e-5];
        let ws = windows(truth);
        let c = compensate(&ws, &opts(truth, 0.01)).expect("compensates");
        assert!(c.rms_compensated < 1e-6 * c.rms_uncompensated, "{c:?}");
        assert!(!c.worse && c.within_sigma(), "{c:?}");
        // k_dt with the wrong sign and 7× too large: worse, and k_dt is the one to blame.
        let wrong = [truth[0], truth[1], truth[2], -7.0 * truth[3]];
        let c = compensate(&ws, &opts(wrong, 0.01)).expect("compensates");
        assert!(c.worse, "{c:?}");
        assert_eq!(c.responsible.map(|r| r.0), Some(ModelKey::TempRateCoeff), "{c:?}");
        assert!(!c.within_sigma());
        // The same wrong k_dt stated with a σ that covers it: not worse than it says.
        let c = compensate(&ws, &opts(wrong, 10.0)).expect("compensates");
        assert!(!c.worse, "{c:?}");
    }

    #[test]
    fn the_noise_of_a_window_mean_is_white_over_its_length_and_flicker_at_its_floor() {
        let white = NoiseSpec { arw: 3e-7, flicker_floor: 0.0, rrw: 0.0 };
        assert!((window_mean_variance(&white, 100.0) - 9e-16).abs() < 1e-24);
        // Flicker over an hour: of the order of the floor squared.
        let f = NoiseSpec { arw: 0.0, flicker_floor: 1e-8, rrw: 0.0 };
        let v = window_mean_variance(&f, 3600.0).sqrt();
        assert!(v > 2e-9 && v < 3e-8, "{v}");
    }
}
