//! Calibration in the angle domain: the seed's navigation-solution method.
//!
//! A table specified to 1″ is there so that the gyro can be judged by the angle it would
//! integrate. Over each steady stretch the gyro's output is integrated and compared with the
//! table's angle readout; the thermal model is fitted to the **angle misclosures**.
//!
//! # Model
//!
//! The misclosures are taken at the gyro's sample boundaries nearest the table's readings
//! (each boundary once; the angle there read off the readings): between two boundaries the
//! gyro's integral holds whole samples, whose noise is the model's, while between two instants
//! inside one sample it is a straight piece carrying a fraction of it — a table read faster
//! than the gyro samples, or in bursts after a host's stall, would whiten below 1. For a
//! stretch starting at the boundary `j0`, at every later one `j` (time `τ_j`, angle `θ_j`):
//!
//! The table's angle `θ` is its readout through the steady motion ([`crate::steady`]: the
//! readings' straight line over the stretch, plus the ripple harmonics the readings resolve).
//! The raw readings carry the readout's quantisation, which on a table turning a near-whole
//! number of steps per reading is a slow sawtooth rather than white noise (it would pass for
//! gyro drift in the misclosure), and the host's stamp jitter at any time scale; through the
//! line they carry neither, and what the line's own slope may be off by — at most about one
//! step over the stretch — is modelled (`u` below).
//!
//! ```text
//! y_j = I(τ_j) − I(τ_j0) − Δθ_j − Ω_E·Δτ_j
//!     = bias·Δτ_j + scale_factor_error·(Δθ_j + Ω_E·Δτ_j) + temp_coeff·∫(T − T0)dt
//!       + temp_rate_coeff·(T(τ_j) − T(τ_j0)) + c + W(τ_j) − q_j
//! ```
//!
//! with `I` the integral of the gyro's mean-rate samples, `Δ` differences from `j0`, `W` the
//! gyro's noise integrated since `τ_j0` (a random walk for white rate noise, integrated
//! Gauss–Markov components for flicker, an integrated random walk for rate random walk), `q_j`
//! the reference's own error at the reading (white, small through the line), `u·Δτ_j` the
//! reference's error that builds up over the stretch (the line's slope error: a random rate, one
//! per stretch, of σ one readout step over the stretch's duration or what the readings' scatter
//! gives, whichever is larger) and `c` one offset per stretch (the first
//! reading's error and a constant lag between the table's and the gyro's clocks), free. The
//! temperature-rate term needs no derivative: it is the temperature's change. A temperature
//! *readout* (the gyro's sensor, the chamber's readings) is smoothed by the same local linear
//! regression the rate domain differentiates ([`crate::temperature_rate::local_linear_value`]):
//! its quantisation steps (0.01 °C for a gyro's sensor), taken raw into the regressors, would be
//! errors in the variables that the fit, weighting short-term increments under white noise,
//! would take as most of the regressor's variation — biasing the temperature-rate coefficient
//! towards zero. A model temperature that is a thermal lag's output is taken as it is
//! ([`AngleFitOptions::temp_window_s`] `None`): the lag has smoothed the readout already, and a
//! second smoothing bends it wherever the coil's rate changes, an error of the temperature-rate
//! column that the flicker's weighting (which leaves the stretches' slow parts to the noise)
//! turns into a bias of k_t and k_dt along the lag's direction.
//!
//! # Estimator
//!
//! Generalised least squares under that noise: a Kalman filter whose state is the flicker's
//! Gauss–Markov rates, the rate random walk, `W` and `c` (exact transitions between readings,
//! `W` restarting and `c` diffuse at each stretch) whitens `y` and the four columns; least
//! squares on the whitened problem is the GLS estimate, `(X̃ᵀX̃)⁻¹` its covariance (the
//! Cramér–Rao bound under the model), and the whitened residual's RMS (≈ 1 when the noise
//! model fits) scales σ up when above 1, as in the rate domain ([`crate::joint_fit`]).
//! Lost gyro samples inside a stretch are bridged with their neighbours' mean (their error is
//! the integrated noise over the gap, which `W` already carries). Samples the rate domain left
//! out for a glitch of the table's readings are integrated ([`AngleWindow::left_out`]): the
//! table is back on its line after the glitch, whatever it was.

use nalgebra::{DMatrix, DVector};

use bench_physics::earth::vertical_rate_rad_s;

use crate::error::AnalysisError;
use crate::joint_fit::NoiseSpec;
use crate::windows::RecordWindow;

/// The table's angle over one calibration window — its readout through the steady motion, at
/// the reading times — and its errors.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TableReadings {
    /// Reading times, s (increasing).
    pub time_s: Vec<f64>,
    /// Reference angle at those times, rad.
    pub angle_rad: Vec<f64>,
    /// The reference's error at each reading, 1σ, rad.
    pub sigma_rad: f64,
    /// σ of the reference's rate error over the window, rad/s.
    pub drift_sigma_rad_s: f64,
    /// Gyro samples (time s, rate rad/s) inside the window's span that its rate-domain
    /// window left out for a glitch of the table's readings: the angle domain integrates them
    /// (see [`AngleWindow::left_out`]). The readings inside the glitches are not in
    /// `time_s`.
    pub left_out: Vec<(f64, f64)>,
}

impl TableReadings {
    /// The angle-domain stretch of `window` with these readings.
    pub fn for_window<'a>(&'a self, window: &'a RecordWindow) -> AngleWindow<'a> {
        AngleWindow {
            window,
            table_time_s: &self.time_s,
            table_angle_rad: &self.angle_rad,
            reading_sigma_rad: self.sigma_rad,
            drift_sigma_rad_s: self.drift_sigma_rad_s,
            nuisance: None,
            left_out: &self.left_out,
        }
    }
}

/// One steady stretch for the angle-domain fit: a calibration window and the table's angle
/// readings over it.
#[derive(Debug, Clone, Copy)]
pub struct AngleWindow<'a> {
    /// The window (gyro samples, model temperature).
    pub window: &'a RecordWindow,
    /// Table reading times within the window, s (increasing).
    pub table_time_s: &'a [f64],
    /// Table angle readings, rad.
    pub table_angle_rad: &'a [f64],
    /// The reference's error at each reading, 1σ, rad.
    pub reading_sigma_rad: f64,
    /// σ of the reference's rate error over the stretch, rad/s.
    pub drift_sigma_rad_s: f64,
    /// The rate-domain nuisance regressor at the window's samples
    /// ([`crate::joint_fit::Nuisance`]), when one is fitted: its integral over the stretch is
    /// fitted beside the coefficients ([`AngleFitOptions::nuisance`]).
    pub nuisance: Option<&'a [f64]>,
    /// Gyro samples (time s, rate rad/s) the window left out for a glitch of the table's
    /// readings (late host stamps, a readout error, a jolt), sorted by time. The rate domain
    /// cannot use them (the table's rate is unknown there); the angle domain can, and does:
    /// the table is back on its line after the glitch, so the gyro's integral across it is
    /// compared with the line's angle whatever the glitch was, and leaving the samples out
    /// would put a bridged stretch without noise in their place.
    pub left_out: &'a [(f64, f64)],
}

/// Settings of [`angle_fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct AngleFitOptions {
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Site latitude, degrees north; `None` leaves Earth's rotation in the bias.
    pub latitude_deg: Option<f64>,
    /// Sensing axis up.
    pub axis_up: bool,
    /// The gyro's noise (from the Allan deviation).
    pub noise: NoiseSpec,
    /// Window of the temperature's smoothing, s (the rate domain's dT/dt window): `Some` for
    /// a readout, `None` to take the windows' model temperature as it is (a thermal lag's
    /// output, smooth already: module docs).
    pub temp_window_s: Option<f64>,
    /// Coefficients held at a value (`ModelKey::CALIBRATED` order), as in the rate domain.
    pub held: [Option<f64>; 4],
    /// Fit the windows' nuisance regressor ([`AngleWindow::nuisance`]) beside the coefficients.
    pub nuisance: bool,
}

/// One coefficient of the angle-domain fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngleEstimate {
    /// Value, the contract's unit.
    pub value: f64,
    /// Standard error: the Cramér–Rao bound times max(1, whitened residual RMS).
    pub std_err: f64,
    /// The Cramér–Rao bound under the noise model.
    pub bound: f64,
    /// Held at `value`, not estimated (`std_err` and `bound` NaN).
    pub held: bool,
}

/// The angle misclosure of one stretch, for plots: times, before calibration (only Earth's
/// rate removed), after (the fitted model and the stretch's offset removed), rad.
#[derive(Debug, Clone, PartialEq)]
pub struct Misclosure {
    /// The window's label.
    pub label: String,
    /// Reading times, s.
    pub time_s: Vec<f64>,
    /// Before calibration, rad.
    pub before_rad: Vec<f64>,
    /// After calibration, rad.
    pub after_rad: Vec<f64>,
}

/// Result of [`angle_fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct AngleFit {
    /// Bias at T0, rad/s.
    pub bias: AngleEstimate,
    /// k_sf − 1.
    pub scale_factor_error: AngleEstimate,
    /// rad/s per °C.
    pub temp_coeff: AngleEstimate,
    /// rad/s per (°C/s).
    pub temp_rate_coeff: AngleEstimate,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Covariance of (bias, scale factor, k_t, k_dt), contract units.
    pub covariance: [[f64; 4]; 4],
    /// RMS of the whitened residual (≈ 1 when the noise model fits).
    pub whitened_residual_rms: f64,
    /// Misclosures used (the gyro sample boundaries nearest the readings, after each
    /// stretch's first).
    pub readings: usize,
    /// Stretches used.
    pub stretches: usize,
    /// Gyro samples bridged inside stretches (lost; those left out for a table glitch are
    /// integrated, [`AngleWindow::left_out`]).
    pub bridged_samples: usize,
    /// Per stretch, the misclosure before and after calibration.
    pub misclosure: Vec<Misclosure>,
}

impl AngleFit {
    /// The estimate of coefficient `j` in (bias, scale factor, k_t, k_dt) order.
    pub fn estimates(&self) -> [AngleEstimate; 4] {
        [self.bias, self.scale_factor_error, self.temp_coeff, self.temp_rate_coeff]
    }

    /// RMS angle misclosure over every reading, before and after calibration, rad; NaN
    /// without readings.
    pub fn misclosure_rms(&self) -> (f64, f64) {
        let n: usize = self.misclosure.iter().map(|m| m.time_s.len()).sum();
        let rms = |f: fn(&Misclosure) -> &[f64]| {
            let s: f64 = self.misclosure.iter().flat_map(|m| f(m).iter()).map(|v| v * v).sum();
            if n == 0 {
                f64::NAN
            } else {
                (s / n as f64).sqrt()
            }
        };
        (rms(|m| &m.before_rad), rms(|m| &m.after_rad))
    }
}

/// The observations of one stretch: per reading after the first, `y` and the four columns.
struct Stretch {
    label: String,
    /// The reference reading's time, s: `W` is zero there.
    ref_s: f64,
    time_s: Vec<f64>,
    y: Vec<f64>,
    /// The four coefficients' columns and the nuisance's (0 without one).
    x: Vec<[f64; 5]>,
    reading_var: f64,
    /// Prior variance of the reference's rate error `u`, (rad/s)².
    drift_var: f64,
    bridged: usize,
}

/// Cumulative integral of a window's gyro samples (with the `left_out` ones put back) at
/// their boundaries: (boundary times, integrals), a lost sample bridged by its neighbours'
/// mean; and how many samples were bridged.
fn gyro_integral(w: &RecordWindow, left_out: &[(f64, f64)]) -> (Vec<f64>, Vec<f64>, usize) {
    let (merged_t, merged_v): (Vec<f64>, Vec<f64>);
    let (t, v) = if left_out.is_empty() {
        (w.time_s(), w.gyro_rate_rad_s())
    } else {
        let mut all: Vec<(f64, f64)> =
            w.time_s().iter().copied().zip(w.gyro_rate_rad_s().iter().copied()).collect();
        all.extend_from_slice(left_out);
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        all.dedup_by(|a, b| a.0 == b.0);
        (merged_t, merged_v) = all.into_iter().unzip();
        (&merged_t[..], &merged_v[..])
    };
    let mut d: Vec<f64> = t.windows(2).map(|p| p[1] - p[0]).collect();
    d.sort_by(f64::total_cmp);
    let dt = d.get(d.len() / 2).copied().unwrap_or(0.05);
    let mut times = Vec::with_capacity(t.len() + 1);
    let mut integral = Vec::with_capacity(t.len() + 1);
    times.push(t[0] - dt);
    integral.push(0.0);
    let mut bridged = 0;
    for k in 0..t.len() {
        let (prev_t, prev_i) = (times[times.len() - 1], integral[integral.len() - 1]);
        let span = t[k] - prev_t;
        let rate = if span > 1.5 * dt && k > 0 {
            // Samples lost before this one: their rate is bridged.
            let missing = (span / dt).round() as usize - 1;
            bridged += missing;
            let bridge = 0.5 * (v[k - 1] + v[k]);
            (bridge * (span - dt) + v[k] * dt) / span
        } else {
            v[k]
        };
        times.push(t[k]);
        integral.push(prev_i + rate * span);
    }
    (times, integral, bridged)
}

/// Linear interpolation in increasing `xs` (clamped).
fn at(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    crate::interp::interp(xs, ys, x)
}

fn stretch(
    aw: &AngleWindow<'_>,
    earth: f64,
    t0: f64,
    temp_window_s: Option<f64>,
) -> Option<Stretch> {
    let w = aw.window;
    let (gt, gi, bridged) = gyro_integral(w, aw.left_out);
    let (first, last) = (gt[0], gt[gt.len() - 1]);
    // Readings inside the gyro's span.
    let readings: Vec<f64> = (0..aw.table_time_s.len().min(aw.table_angle_rad.len()))
        .map(|j| aw.table_time_s[j])
        .filter(|&tau| tau >= first && tau <= last)
        .collect();
    let (&r_first, &r_last) = (readings.first()?, readings.last()?);
    // The misclosures are taken at the gyro's sample boundaries nearest the readings (each
    // boundary once), the table's angle there read off its readings (the steady motion's
    // angle, so interpolating between them is the motion). Between two boundaries the
    // integral holds whole samples, whose noise is what the model says; between two instants
    // inside one sample it is that sample's rate times their distance — a fraction of the
    // noise the model gives it, so a table read faster than the gyro samples (or in bursts,
    // after a host's stall) would whiten to less than 1 and look like a fit that does not fit.
    let (lo_b, hi_b) = (gt.partition_point(|&t| t < r_first), gt.partition_point(|&t| t <= r_last));
    if hi_b < lo_b + 3 {
        return None;
    }
    let mut bounds: Vec<usize> = Vec::with_capacity(readings.len());
    for &tau in &readings {
        let k = gt.partition_point(|&t| t < tau);
        let k = if k > 0 && (k == gt.len() || tau - gt[k - 1] < gt[k] - tau) { k - 1 } else { k };
        let k = k.clamp(lo_b, hi_b - 1);
        if bounds.last() != Some(&k) {
            bounds.push(k);
        }
    }
    if bounds.len() < 3 {
        return None;
    }
    let angle_at = |tau: f64| at(aw.table_time_s, aw.table_angle_rad, tau);
    // Model temperature (a readout smoothed) and its integral at the gyro's times.
    let ts = w.time_s();
    let smoothed;
    let temp = match temp_window_s {
        Some(window_s) => {
            smoothed = w.smoothed_temperature_c(window_s).ok()?;
            &smoothed
        }
        None => w.temperature_c(),
    };
    let mut temp_int = Vec::with_capacity(ts.len());
    let mut nu_int = Vec::with_capacity(ts.len());
    let (mut acc, mut acc_nu) = (0.0, 0.0);
    for k in 0..ts.len() {
        if k > 0 {
            acc += 0.5 * (temp[k] + temp[k - 1] - 2.0 * t0) * (ts[k] - ts[k - 1]);
            if let Some(nu) = aw.nuisance {
                acc_nu += 0.5 * (nu[k] + nu[k - 1]) * (ts[k] - ts[k - 1]);
            }
        }
        temp_int.push(acc);
        nu_int.push(acc_nu);
    }
    let (tau0, theta0) = (gt[bounds[0]], angle_at(gt[bounds[0]]));
    let (i0, temp0, int0) = (gi[bounds[0]], at(ts, temp, tau0), at(ts, &temp_int, tau0));
    let nu0 = at(ts, &nu_int, tau0);
    let mut s = Stretch {
        label: w.label().to_owned(),
        ref_s: tau0,
        time_s: Vec::with_capacity(bounds.len()),
        y: Vec::with_capacity(bounds.len()),
        x: Vec::with_capacity(bounds.len()),
        reading_var: aw.reading_sigma_rad * aw.reading_sigma_rad,
        drift_var: aw.drift_sigma_rad_s * aw.drift_sigma_rad_s,
        bridged,
    };
    for &b in &bounds[1..] {
        let tau = gt[b];
        let dtau = tau - tau0;
        let dtheta = angle_at(tau) - theta0;
        let input = dtheta + earth * dtau;
        s.time_s.push(tau);
        s.y.push(gi[b] - i0 - input);
        s.x.push([
            dtau,
            input,
            at(ts, &temp_int, tau) - int0,
            at(ts, temp, tau) - temp0,
            at(ts, &nu_int, tau) - nu0,
        ]);
    }
    Some(s)
}

/// The Kalman filter of the module's noise model over the readings of `stretches` (in time
/// order). Each series is whitened as it goes; `row(k, values)` gets the k-th reading's
/// whitened values of every series, where series `j` is `value(k, j)` before whitening.
fn whiten_rows(
    stretches: &[Stretch],
    spec: &NoiseSpec,
    series: usize,
    value: impl Fn(usize, usize) -> f64,
    mut row: impl FnMut(&[f64]),
) {
    let gm: Vec<(f64, f64)> = if spec.flicker_floor > 0.0 {
        bench_physics::noise::bias_instability_components(spec.flicker_floor)
            .iter()
            .map(|&(t, sd)| (t, sd * sd))
            .collect()
    } else {
        Vec::new()
    };
    let g = gm.len();
    let has_r = spec.rrw > 0.0;
    let ir = g; // index of r, when present
    let iw = g + usize::from(has_r);
    // The reference's rate error over the stretch.
    let iu = iw + 1;
    let m = iu + 1;
    let (n2, k2) = (spec.arw * spec.arw, spec.rrw * spec.rrw);
    let mut p = vec![0.0; m * m];
    for (i, &(_, var)) in gm.iter().enumerate() {
        p[i * m + i] = var;
    }
    let mut x = vec![vec![0.0; m]; series];
    let mut whitened = vec![0.0; series];
    let mut last_time = f64::NAN;
    let mut k = 0;
    let mut phi = vec![0.0; m * m];
    let mut q = vec![0.0; m * m];
    let mut tmp = vec![0.0; m * m];
    let mut h = vec![0.0; m];
    let mut old = vec![0.0; m];
    for s in stretches {
        // Reference reading first (W restarts there, u is new), then the readings.
        let times = std::iter::once((true, s.ref_s)).chain(s.time_s.iter().map(|&t| (false, t)));
        for (is_ref, tau) in times {
            // Propagate from the previous time (across the gap from the last stretch too).
            if last_time.is_finite() {
                let dt = (tau - last_time).max(0.0);
                phi.iter_mut().for_each(|v| *v = 0.0);
                q.iter_mut().for_each(|v| *v = 0.0);
                for i in 0..m {
                    phi[i * m + i] = 1.0;
                }
                for (i, &(tc, var)) in gm.iter().enumerate() {
                    let e = (-dt / tc).exp();
                    phi[i * m + i] = e;
                    phi[iw * m + i] = tc * (1.0 - e);
                    q[i * m + i] = var * (1.0 - e * e);
                    let cross = var * tc * (1.0 - e) * (1.0 - e);
                    q[i * m + iw] = cross;
                    q[iw * m + i] = cross;
                    q[iw * m + iw] += var * tc * (2.0 * dt - tc * (1.0 - e) * (3.0 - e));
                }
                if has_r {
                    phi[iw * m + ir] = dt;
                    q[ir * m + ir] = k2 * dt;
                    q[ir * m + iw] = 0.5 * k2 * dt * dt;
                    q[iw * m + ir] = 0.5 * k2 * dt * dt;
                    q[iw * m + iw] += k2 * dt * dt * dt / 3.0;
                }
                q[iw * m + iw] += n2 * dt;
                // P ← Φ P Φᵀ + Q.
                for i in 0..m {
                    for j in 0..m {
                        tmp[i * m + j] = (0..m).map(|l| phi[i * m + l] * p[l * m + j]).sum();
                    }
                }
                for i in 0..m {
                    for j in 0..m {
                        p[i * m + j] = q[i * m + j]
                            + (0..m).map(|l| tmp[i * m + l] * phi[j * m + l]).sum::<f64>();
                    }
                }
                for xs in x.iter_mut() {
                    old.copy_from_slice(xs);
                    for i in 0..m {
                        xs[i] = (0..m).map(|l| phi[i * m + l] * old[l]).sum();
                    }
                }
            }
            last_time = tau;
            if is_ref {
                for i in 0..m {
                    for j in [iw, iu] {
                        p[i * m + j] = 0.0;
                        p[j * m + i] = 0.0;
                    }
                }
                p[iu * m + iu] = s.drift_var;
                for xs in x.iter_mut() {
                    xs[iw] = 0.0;
                    xs[iu] = 0.0;
                }
                continue;
            }
            // Observe W + u·Δτ, with the reading's white error.
            let lever = tau - s.ref_s;
            for i in 0..m {
                h[i] = p[i * m + iw] + lever * p[i * m + iu];
            }
            let sv = h[iw] + lever * h[iu] + s.reading_var.max(1e-24);
            let inv_sqrt = 1.0 / sv.sqrt();
            for (col, xs) in x.iter_mut().enumerate() {
                let nu = value(k, col) - xs[iw] - lever * xs[iu];
                whitened[col] = nu * inv_sqrt;
                for i in 0..m {
                    xs[i] += h[i] / sv * nu;
                }
            }
            // P⁺ = P − h·hᵀ/S, symmetric term by term.
            for i in 0..m {
                for j in i..m {
                    let v = p[i * m + j] - h[i] * h[j] / sv;
                    p[i * m + j] = v;
                    p[j * m + i] = v;
                }
            }
            row(&whitened);
            k += 1;
        }
    }
}

/// The normal equations of the whitened problem over `cols` (free columns of a stretch's `x`,
/// each divided by its `scale`) and one offset per stretch: (XᵀX, Xᵀy, yᵀy), `y` with the held
/// coefficients' terms taken out.
fn normal_equations(
    stretches: &[Stretch],
    rows: &[(usize, usize)],
    opts: &AngleFitOptions,
    cols: &[usize],
    scale: &[f64],
) -> (DMatrix<f64>, DVector<f64>, f64) {
    let (nc, ns) = (cols.len(), stretches.len());
    let p = nc + ns;
    let value = |k: usize, col: usize| {
        let (si, r) = rows[k];
        let s = &stretches[si];
        if col < nc {
            s.x[r][cols[col]] / scale[col]
        } else if col < p {
            f64::from(u8::from(col - nc == si))
        } else {
            let held: f64 = (0..4).filter_map(|j| opts.held[j].map(|h| h * s.x[r][j])).sum();
            s.y[r] - held
        }
    };
    let mut xtx = DMatrix::<f64>::zeros(p, p);
    let mut xty = DVector::<f64>::zeros(p);
    let mut yty = 0.0;
    whiten_rows(stretches, &opts.noise, p + 1, value, |w| {
        let y = w[p];
        for i in 0..p {
            if w[i] != 0.0 {
                xty[i] += w[i] * y;
                for j in i..p {
                    xtx[(i, j)] += w[i] * w[j];
                }
            }
        }
        yty += y * y;
    });
    for i in 0..p {
        for j in 0..i {
            xtx[(i, j)] = xtx[(j, i)];
        }
    }
    (xtx, xty, yty)
}

/// Fit the thermal model to the angle misclosures of `windows` (module docs).
pub fn angle_fit(
    windows: &[AngleWindow<'_>],
    opts: &AngleFitOptions,
) -> Result<AngleFit, AnalysisError> {
    let earth = opts.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, opts.axis_up));
    let t0 = opts.reference_temperature_c;
    let mut stretches: Vec<Stretch> =
        windows.iter().filter_map(|w| stretch(w, earth, t0, opts.temp_window_s)).collect();
    stretches.sort_by(|a, b| a.time_s[0].total_cmp(&b.time_s[0]));
    let n: usize = stretches.iter().map(|s| s.y.len()).sum();
    let ns = stretches.len();
    if n < 20 + ns {
        return Err(AnalysisError::TooFewSamples {
            what: "angle-domain fit".into(),
            got: n,
            min: 20 + ns,
        });
    }
    if opts.noise.arw.is_nan() || opts.noise.arw <= 0.0 {
        return Err(AnalysisError::Insufficient(
            "angle-domain fit: no white noise in the noise model".into(),
        ));
    }
    // Rows in time order, with the stretch each belongs to.
    let mut rows: Vec<(usize, usize)> = Vec::with_capacity(n);
    for (si, s) in stretches.iter().enumerate() {
        rows.extend((0..s.y.len()).map(|k| (si, k)));
    }
    // Free columns (the coefficients not held, the nuisance), scaled to unit RMS.
    let mut cols: Vec<usize> = (0..4).filter(|&j| opts.held[j].is_none()).collect();
    if opts.nuisance {
        cols.push(4);
    }
    let mut scale = vec![0.0; cols.len()];
    for &(si, k) in &rows {
        for (c, sc) in scale.iter_mut().enumerate() {
            *sc += stretches[si].x[k][cols[c]] * stretches[si].x[k][cols[c]];
        }
    }
    for (c, sc) in scale.iter_mut().enumerate() {
        *sc = (*sc / n as f64).sqrt();
        if *sc == 0.0 {
            return Err(AnalysisError::Insufficient(format!(
                "angle-domain fit: the data never excite coefficient {} (its regressor is zero)",
                cols[c]
            )));
        }
    }
    let (xtx, xty, yty) = normal_equations(&stretches, &rows, opts, &cols, &scale);
    let cov_s = xtx.try_inverse().ok_or_else(|| {
        AnalysisError::Insufficient(
            "angle-domain fit: the stretches cannot separate bias, scale factor, temperature and \
             temperature-rate terms"
                .into(),
        )
    })?;
    let beta = &cov_s * &xty;
    let rss = (yty - beta.dot(&xty)).max(0.0);
    let rms = (rss / n as f64).sqrt();
    Ok(assemble(&stretches, opts, &cols, &scale, &cov_s, &beta, rms, n))
}

/// The [`AngleFit`] from the solved normal equations.
#[allow(clippy::too_many_arguments)]
fn assemble(
    stretches: &[Stretch],
    opts: &AngleFitOptions,
    cols: &[usize],
    scale: &[f64],
    cov_s: &DMatrix<f64>,
    beta: &DVector<f64>,
    rms: f64,
    n: usize,
) -> AngleFit {
    let nc = cols.len();
    let mut covariance = [[0.0; 4]; 4];
    let mut coef: [AngleEstimate; 4] = std::array::from_fn(|j| AngleEstimate {
        value: opts.held[j].unwrap_or(f64::NAN),
        std_err: f64::NAN,
        bound: f64::NAN,
        held: true,
    });
    let mut fitted = [0.0; 5];
    for (a, &i) in cols.iter().enumerate() {
        fitted[i] = beta[a] / scale[a];
        if i < 4 {
            for (b, &j) in cols.iter().enumerate().filter(|(_, &j)| j < 4) {
                covariance[i][j] = cov_s[(a, b)] / (scale[a] * scale[b]);
            }
            let bound = covariance[i][i].max(0.0).sqrt();
            coef[i] = AngleEstimate {
                value: fitted[i],
                std_err: bound * rms.max(1.0),
                bound,
                held: false,
            };
        }
    }
    for (j, h) in opts.held.iter().enumerate() {
        if let Some(h) = h {
            fitted[j] = *h;
        }
    }
    // Misclosures before and after (the fitted model and the stretch's offset removed).
    let misclosure = stretches
        .iter()
        .enumerate()
        .map(|(si, s)| Misclosure {
            label: s.label.clone(),
            time_s: s.time_s.clone(),
            before_rad: s.y.clone(),
            after_rad: s
                .y
                .iter()
                .zip(&s.x)
                .map(|(y, x)| y - (0..5).map(|j| fitted[j] * x[j]).sum::<f64>() - beta[nc + si])
                .collect(),
        })
        .collect();
    AngleFit {
        bias: coef[0],
        scale_factor_error: coef[1],
        temp_coeff: coef[2],
        temp_rate_coeff: coef[3],
        reference_temperature_c: opts.reference_temperature_c,
        covariance,
        whitened_residual_rms: rms,
        readings: n,
        stretches: stretches.len(),
        bridged_samples: stretches.iter().map(|s| s.bridged).sum(),
        misclosure,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::lag::FirstOrderLag;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    const ARCSEC: f64 = 4.848_136_811_095_36e-6;

    /// Windows, table readings (times, angles) per window, the truth, the ARW.
    type Run = (Vec<RecordWindow>, Tables, [f64; 4], f64);

    /// Per window, the table's reading times and angles.
    type Tables = Vec<(Vec<f64>, Vec<f64>)>;

    /// Eight 10-minute stretches alternating CW/CCW at 10 °/min over a temperature profile
    /// that ramps at ±1 °C/min and holds; gyro at 20 Hz with white noise only (and every 500th
    /// sample lost), table readings at 10 Hz on the 1″ grid, stamped 9 ms late with 1 ms of
    /// jitter in the instant each reading is taken.
    fn run(seed: u64) -> Run {
        let truth = [2e-7, 5e-5, 5e-9, 3e-5];
        let arw = 3e-7;
        let w = 10f64.to_radians() / 60.0;
        let temp = |t: f64| {
            let p = t % 2400.0;
            if p < 600.0 {
                20.0 + p / 60.0
            } else if p < 1200.0 {
                30.0
            } else if p < 1800.0 {
                30.0 - (p - 1200.0) / 60.0
            } else {
                20.0
            }
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut windows = Vec::new();
        let mut tables = Vec::new();
        let mut angle_at_start = 0.0;
        for k in 0..8 {
            let omega = if k % 2 == 0 { -w } else { w };
            let t_start = 700.0 * k as f64;
            let n = 12_000;
            let (mut gt, mut gv, mut tc, mut air) = (vec![], vec![], vec![], vec![]);
            for i in 1..=n {
                let t = t_start + i as f64 * 0.05;
                if i % 500 == 0 {
                    continue;
                }
                let (tm, t0) = (temp(t - 0.025), 20.0);
                let dtdt = (temp(t) - temp(t - 0.05)) / 0.05;
                let e: f64 = StandardNormal.sample(&mut rng);
                let v = (1.0 + truth[1]) * omega
                    + truth[0]
                    + truth[2] * (tm - t0)
                    + truth[3] * dtdt
                    + arw / 0.05f64.sqrt() * e;
                gt.push(t);
                gv.push(v);
                tc.push(tm);
                air.push(tm);
            }
            let ws =
                RecordWindow::new(format!("w{k}"), gt, gv, vec![omega; n - n / 500], Some(tc), air)
                    .expect("window");
            let (mut tt, mut ta) = (vec![], vec![]);
            for j in 0..6000 {
                let tau = t_start + 0.2 + j as f64 * 0.1;
                let jitter: f64 = StandardNormal.sample(&mut rng);
                let true_angle = angle_at_start + omega * (tau - 0.009 + 1e-3 * jitter - t_start);
                tt.push(tau);
                ta.push((true_angle / ARCSEC).round() * ARCSEC);
            }
            angle_at_start += omega * 700.0;
            windows.push(ws);
            tables.push((tt, ta));
        }
        (windows, tables, truth, arw)
    }

    /// The fit's settings for [`run`]'s data: T0 20 °C, no Earth rate, white noise of `arw`,
    /// the readout smoothed over 60 s.
    fn white_noise_options(arw: f64) -> AngleFitOptions {
        AngleFitOptions {
            reference_temperature_c: 20.0,
            latitude_deg: None,
            axis_up: true,
            noise: NoiseSpec { arw, flicker_floor: 0.0, rrw: 0.0 },
            temp_window_s: Some(60.0),
            held: [None; 4],
            nuisance: false,
        }
    }

    /// The stretches of `windows` with their table readings, each reading's σ and the
    /// reference rate's σ.
    fn angle_windows<'a>(
        windows: &'a [RecordWindow],
        tables: &'a Tables,
        reading_sigma_rad: f64,
        drift_sigma_rad_s: f64,
    ) -> Vec<AngleWindow<'a>> {
        windows
            .iter()
            .zip(tables)
            .map(|(w, (t, a))| AngleWindow {
                window: w,
                table_time_s: t,
                table_angle_rad: a,
                reading_sigma_rad,
                drift_sigma_rad_s,
                nuisance: None,
                left_out: &[],
            })
            .collect()
    }

    /// Eight 700 s stretches (CW/CCW at 10 °/min, 20 Hz) of a gyro without noise whose coil
    /// follows the air through a first-order lag of 300 s, the air ramping at ±3 °C/min
    /// with holds between (so the coil's rate bends inside the stretches); the table read
    /// exactly at 10 Hz. The windows' model temperature is the coil's, as the calibration's
    /// lag stage makes it. (windows, table readings, truth)
    fn lagged_run() -> (Vec<RecordWindow>, Tables, [f64; 4]) {
        let truth = [2e-7, 5e-5, 5e-9, 1.5e-5];
        let (tau, dt, w) = (300.0, 0.05, 10f64.to_radians() / 60.0);
        let air = |t: f64| {
            let p = t % 2000.0;
            if p < 500.0 {
                20.0 + 0.05 * p
            } else if p < 1000.0 {
                45.0
            } else if p < 1500.0 {
                45.0 - 0.05 * (p - 1000.0)
            } else {
                20.0
            }
        };
        // The coil on a 1 ms grid (exact for the piecewise-linear air), read at mid-sample.
        let fine = 0.001;
        let total = 8.0 * 700.0;
        let mut lag = FirstOrderLag::new(tau, 20.0);
        let coil: Vec<f64> = std::iter::once(20.0)
            .chain((1..=(total / fine) as usize).map(|i| {
                let t = i as f64 * fine;
                lag.step_linear(air(t - fine), air(t), fine)
            }))
            .collect();
        let coil_at = |t: f64| coil[(t / fine).round() as usize];
        let (mut windows, mut tables) = (Vec::new(), Vec::new());
        let mut angle_at_start = 0.0;
        for k in 0..8 {
            let omega = if k % 2 == 0 { -w } else { w };
            let t_start = 700.0 * k as f64;
            let (mut gt, mut gv, mut tc) = (vec![], vec![], vec![]);
            for i in 1..=12_000 {
                let t = t_start + i as f64 * dt;
                let mid = coil_at(t - 0.5 * dt);
                let rate = (air(t - 0.5 * dt) - mid) / tau;
                gt.push(t);
                gv.push(
                    (1.0 + truth[1]) * omega + truth[0] + truth[2] * (mid - 20.0) + truth[3] * rate,
                );
                tc.push(coil_at(t));
            }
            let chamber: Vec<f64> = gt.iter().map(|&t| air(t)).collect();
            let n = gt.len();
            windows.push(
                RecordWindow::new(format!("w{k}"), gt, gv, vec![omega; n], Some(tc), chamber)
                    .expect("window"),
            );
            let tt: Vec<f64> = (0..6000).map(|j| t_start + 0.2 + j as f64 * 0.1).collect();
            let ta = tt.iter().map(|&tau| angle_at_start + omega * (tau - t_start)).collect();
            angle_at_start += omega * 700.0;
            tables.push((tt, ta));
        }
        (windows, tables, truth)
    }

    #[test]
    fn a_lagged_coil_temperature_is_taken_as_it_is_not_smoothed_again() {
        let (windows, tables, truth) = lagged_run();
        let aws = angle_windows(&windows, &tables, 1e-9, ARCSEC / 700.0);
        // The noise model of the lab writer's gyros: the flicker leaves each stretch's slow
        // part to the noise, so the fit reads the temperature columns' shape within it.
        let fit = |temp_window_s| {
            let opts = AngleFitOptions {
                reference_temperature_c: 20.0,
                latitude_deg: None,
                axis_up: true,
                noise: NoiseSpec { arw: 3e-8, flicker_floor: 1e-8, rrw: 0.0 },
                temp_window_s,
                held: [None; 4],
                nuisance: false,
            };
            let f = angle_fit(&aws, &opts).expect("fits");
            let z: Vec<f64> =
                f.estimates().iter().zip(truth).map(|(e, t)| (e.value - t) / e.bound).collect();
            z
        };
        let as_is = fit(None);
        assert!(as_is.iter().all(|z| z.abs() < 0.05), "as it is: z {as_is:?}");
        // Smoothed again over 60 s the coil bends where its rate changes: k_dt moves (z 0.63).
        let smoothed = fit(Some(60.0));
        assert!(smoothed[3].abs() > 0.4, "smoothed: z {smoothed:?}");
    }

    #[test]
    fn the_angle_misclosures_give_the_model_back_with_honest_errors() {
        let mut z2 = [0.0; 4];
        let seeds = 6;
        for seed in 0..seeds {
            let (windows, tables, truth, arw) = run(seed);
            let reading_sigma_rad = (ARCSEC * ARCSEC / 12.0 + (2.909e-3 * 1e-3f64).powi(2)).sqrt();
            let aws = angle_windows(&windows, &tables, reading_sigma_rad, ARCSEC / 600.0);
            let f = angle_fit(&aws, &white_noise_options(arw)).expect("fits");
            assert_eq!(f.stretches, 8);
            assert_eq!(f.bridged_samples, 8 * 23, "{}", f.bridged_samples);
            assert!((f.whitened_residual_rms - 1.0).abs() < 0.05, "{}", f.whitened_residual_rms);
            for (j, e) in f.estimates().iter().enumerate() {
                let z = (e.value - truth[j]) / e.bound;
                assert!(z.abs() < 4.0, "seed {seed} coefficient {j}: {e:?} vs {}", truth[j]);
                z2[j] += z * z;
            }
            // Misclosure after calibration is flat: within a few of the readings' errors and the
            // gyro's angle random walk over a stretch (600 s).
            let sigma = (aws[0].reading_sigma_rad.powi(2) + arw * arw * 600.0).sqrt();
            let worst = f
                .misclosure
                .iter()
                .flat_map(|m| m.after_rad.iter())
                .fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(worst < 7.0 * sigma, "{worst} vs σ {sigma}");
        }
        // The stated σ is the scatter: mean z² near 1 (6 seeds × 4 coefficients).
        let mean = z2.iter().sum::<f64>() / (4 * seeds) as f64;
        assert!((0.3..2.0).contains(&mean), "mean z² {mean}");
    }

    /// A table read faster than the gyro samples (50 Hz readings of a 20 Hz gyro, here exactly
    /// on the line): the misclosures are taken at the gyro's sample boundaries, so the noise
    /// whitens to 1 and the errors stay honest. Taken at every reading instead, each sample's
    /// integral would be cut into straight pieces carrying a fraction of the noise the model
    /// gives them (whitened RMS ≈ 0.6), and a sound fit would be called poor.
    #[test]
    fn a_table_read_faster_than_the_gyro_samples_whitens_to_one() {
        let w = 10f64.to_radians() / 60.0;
        let mut rms = Vec::new();
        for seed in 0..3 {
            let (windows, _, truth, arw) = run(seed);
            let tables: Tables = windows
                .iter()
                .enumerate()
                .map(|(k, win)| {
                    let omega = if k % 2 == 0 { -w } else { w };
                    let (a, b) = (win.time_s()[0], win.time_s()[win.len() - 1]);
                    let t: Vec<f64> =
                        (0..).map(|j| a + 0.013 + j as f64 * 0.02).take_while(|&t| t < b).collect();
                    let angle = t.iter().map(|&t| omega * t).collect();
                    (t, angle)
                })
                .collect();
            let aws = angle_windows(&windows, &tables, 1e-9, ARCSEC / 600.0);
            let f = angle_fit(&aws, &white_noise_options(arw)).expect("fits");
            // One misclosure per gyro sample boundary, not per reading.
            assert!(f.readings < 8 * 12_000, "{}", f.readings);
            for (j, e) in f.estimates().iter().enumerate() {
                let z = (e.value - truth[j]) / e.bound;
                assert!(z.abs() < 4.0, "seed {seed} coefficient {j}: {e:?} vs {}", truth[j]);
            }
            rms.push(f.whitened_residual_rms);
        }
        assert!(rms.iter().all(|r| (r - 1.0).abs() < 0.05), "{rms:?}");
    }
}
