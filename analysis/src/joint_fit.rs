//! One joint least-squares fit of the thermal error model over all record windows, with
//! standard errors that respect coloured noise.
//!
//! # Model
//!
//! For every sample of every window (rotating or at rest, plateau or ramp):
//!
//! ```text
//! V − Ω_in = bias + scale_factor_error·Ω_in + temp_coeff·(T − T0) + temp_rate_coeff·dT/dt + e
//! Ω_in     = Ω_table + Ω_E·sin(latitude)      (sign of the Earth term flips for axis down)
//! ```
//!
//! which is the contract's `bench.gyro_model` output equation rearranged. `T` is the window's
//! model temperature ([`RecordWindow::temperature_c`]: the gyro's sensor, else chamber air) and
//! `dT/dt` comes from it by a local linear regression over `rate_window_s`
//! ([`RecordWindow::temperature_rate_c_s`]: over the whole run where the caller gave it). Without a latitude the
//! Earth term is zero and Earth's rotation (×(1 + s)) ends up in `bias`.
//!
//! The columns are scaled to unit RMS and the problem solved by nalgebra's SVD, which also
//! reports a design that cannot separate the four terms (e.g. no temperature change, or the
//! table never turned).
//!
//! # Estimator
//!
//! With a [`NoiseSpec`] that has white noise, the coefficients are the **generalised least
//! squares** estimate under that noise model ([`crate::gls`]: a Kalman filter whose states are
//! the flicker's Gauss–Markov components and the rate random walk whitens `y` and the columns
//! over the real sample times, gaps included): the best linear unbiased estimator, with
//! covariance `(XᵀΣ⁻¹X)⁻¹`, the Cramér–Rao bound for Gaussian noise of the model. Without one
//! they are ordinary least squares. The OLS values are kept in [`Estimate::ols_value`] for
//! comparison.
//!
//! # Standard errors
//!
//! For GLS: the Cramér–Rao σ `√((XᵀΣ⁻¹X)⁻¹)_jj`, scaled up by the RMS of the whitened
//! residual when that exceeds 1 (broadband noise the model lacks). A moving-block bootstrap
//! (below) of the *whitened* residuals through the whitened design's pseudo-inverse is
//! reported beside it as a misfit check ([`Estimate::bootstrap_std_err`]), not used: blocks
//! of a few seconds see narrow-band misfit such as the table's rate ripple as if it were
//! broadband and ran 5–15 % above the bound on `thermal-full.toml`, whose coverage the bound
//! alone meets. The rest of this section is the OLS case.
//!
//! Gyro noise is coloured (bias instability, thermal effects not in the model), so the naive
//! OLS covariance `σ̂²·(XᵀX)⁻¹`, which assumes independent residuals, is far too small. The
//! standard errors here come from a **moving-block residual bootstrap** with the design fixed:
//! the residuals (windows concatenated in order) are cut into blocks of `L` consecutive
//! samples starting at uniformly drawn positions (circularly wrapped), laid end to end to a
//! series `e*` of the original length, and each replicate's coefficients are
//! `β* = β̂ + X⁺·e*`. The standard error is the standard deviation of `β*` over the replicates
//! (ChaCha8, fixed seed: deterministic).
//!
//! Block-length rule (when not given): `k_e` = the first lag at which the residual's sample
//! autocorrelation falls below `1/e` (its correlation time in samples, searched up to `n/50`);
//! `L = max(10·k_e, ⌈n^{1/3}⌉)`, at most `n/5`. Ten correlation times keep the bootstrap
//! variance's downward bias near `k_e/L` ≈ 10 % for Gauss–Markov noise; a residual still
//! correlated at `n/50` means the record is too short for honest errors, and
//! [`JointFit::block_len`] at the cap says so.
//!
//! # Noise-model standard errors
//!
//! Noise correlated over times comparable to the whole record — bias instability (flicker),
//! whose synthesised form has correlation times up to 30 000 s — is invisible to any block
//! shorter than the record, so the bootstrap alone understates the errors then. With a
//! [`NoiseSpec`] (from the Allan deviation of the constant-temperature windows), the variance
//! of each coefficient `β_j = Σ_k P_jk·e_k` under that noise is computed exactly: white rate
//! noise `N²/Δt·Σ_k P_jk²`; flicker as the sum of the Gauss–Markov components of
//! `bench_physics::noise` (the simulator's own synthesis), each `σ²·Σ_a Σ_b P_ja P_jb
//! e^{−|t_a − t_b|/T}` by a forward and a backward exponential filter over the real sample
//! times, gaps between windows included; rate random walk `K²·Σ_k Δt_k·(Σ_{a≥k} P_ja)²`.
//! All O(n). The reported standard error is the larger of the bootstrap's and the noise
//! model's: the first sees misfit the noise model does not know, the second the long
//! correlations the blocks cannot.

use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::{GyroModel, ModelKey};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::error::AnalysisError;
use crate::gls::gls;
use crate::timebase::median_interval;
use crate::windows::RecordWindow;

/// Settings of the joint fit.
#[derive(Debug, Clone, PartialEq)]
pub struct JointFitOptions {
    /// Reference temperature T0, °C. Default 20.
    pub reference_temperature_c: f64,
    /// Site latitude, degrees north; `None` leaves Earth's rotation in the bias. Default `None`.
    pub latitude_deg: Option<f64>,
    /// Sensing axis points up. Default true.
    pub axis_up: bool,
    /// Window of the dT/dt filter, s. Default 60.
    pub rate_window_s: f64,
    /// Bootstrap replicates. Default 400.
    pub replicates: usize,
    /// Block length in samples; `None` applies the module's rule. Default `None`.
    pub block_len: Option<usize>,
    /// Seed of the bootstrap's random generator. Default 0.
    pub seed: u64,
    /// Noise model (e.g. from the Allan deviation of the plateaus) whose covariance is carried
    /// into the coefficients; `None` leaves the block bootstrap alone. Default `None`.
    pub noise: Option<NoiseSpec>,
    /// Coefficients held at a value instead of estimated (`ModelKey::CALIBRATED` order): a
    /// procedure that does not determine one ([`crate::information`]). Default none.
    pub held: [Option<Held>; 4],
    /// A regressor estimated beside the coefficients so that their σ carry its uncertainty
    /// (a fitted thermal lag's sensitivity). Default `None`.
    pub nuisance: Option<Nuisance>,
}

/// A coefficient held at a value instead of estimated: its column leaves the design and its
/// term `value·x_j` is taken out of `y`; `sigma` (1σ of the held value, e.g. a prior's; 0 when
/// taken as exact) goes through the estimator into the other coefficients' covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Held {
    /// The value, the contract's unit.
    pub value: f64,
    /// Its 1σ; 0 when it is taken as exact.
    pub sigma: f64,
}

/// A regressor estimated beside the four coefficients so that their σ carry its uncertainty:
/// the linearised effect of a fitted non-linear parameter (the thermal lag: `k_t·∂T/∂τ +
/// k_dt·∂Ṫ/∂τ`, [`crate::calibrate`]), one value per sample of each window.
#[derive(Debug, Clone, PartialEq)]
pub struct Nuisance {
    /// What it is, for messages.
    pub name: String,
    /// Per window, per sample.
    pub values: Vec<Vec<f64>>,
}

/// A gyro noise model in the terms of IEEE Std 952, for the coefficient covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseSpec {
    /// Angle random walk N, rad/√s.
    pub arw: f64,
    /// Flicker floor of the Allan deviation (the contract's `bias_instability`), rad/s.
    pub flicker_floor: f64,
    /// Rate random walk K, rad/s/√s.
    pub rrw: f64,
}

impl Default for JointFitOptions {
    fn default() -> Self {
        Self {
            reference_temperature_c: 20.0,
            latitude_deg: None,
            axis_up: true,
            rate_window_s: 60.0,
            replicates: 400,
            block_len: None,
            seed: 0,
            noise: None,
            held: [None; 4],
            nuisance: None,
        }
    }
}

/// The estimator behind [`JointFit`]'s values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// Generalised least squares under the noise model ([`crate::gls`]).
    Gls,
    /// Ordinary least squares (no usable noise model).
    Ols,
}

impl Estimator {
    /// `"gls"` or `"ols"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Estimator::Gls => "gls",
            Estimator::Ols => "ols",
        }
    }
}

/// One fitted coefficient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Estimated value ([`JointFit::estimator`]).
    pub value: f64,
    /// Standard error to use. GLS: `noise_model_std_err` (the Cramér–Rao bound) times
    /// `max(1, whitened residual RMS)`; OLS: the larger of `bootstrap_std_err` and
    /// `noise_model_std_err`.
    pub std_err: f64,
    /// Naive OLS standard error `σ̂·√((XᵀX)⁻¹)_jj`, for comparison; too small for coloured noise.
    pub naive_std_err: f64,
    /// Moving-block-bootstrap standard error: of the whitened residuals for GLS, of the
    /// residuals for OLS.
    pub bootstrap_std_err: f64,
    /// Standard error under the noise model ([`JointFitOptions::noise`]): for GLS the
    /// Cramér–Rao bound `√((XᵀΣ⁻¹X)⁻¹)_jj`; NaN without a noise model.
    pub noise_model_std_err: f64,
    /// The OLS value, for comparison (equal to `value` for OLS).
    pub ols_value: f64,
    /// The OLS value's standard error under the noise model, for comparison; NaN without one.
    pub ols_noise_model_std_err: f64,
    /// Held at a value, not estimated ([`JointFitOptions::held`]): `value` is the held value,
    /// `std_err` its σ (NaN when taken as exact), every other σ NaN.
    pub held: bool,
}

impl Estimate {
    /// The estimate of a coefficient held at `h`.
    pub fn held(h: Held) -> Self {
        let nan = f64::NAN;
        Estimate {
            value: h.value,
            std_err: if h.sigma > 0.0 { h.sigma } else { nan },
            naive_std_err: nan,
            bootstrap_std_err: nan,
            noise_model_std_err: nan,
            ols_value: h.value,
            ols_noise_model_std_err: nan,
            held: true,
        }
    }
}

/// Result of [`joint_fit`]; coefficients in `bench.gyro_model` units.
#[derive(Debug, Clone, PartialEq)]
pub struct JointFit {
    /// GLS when a noise model with white noise was given, else OLS.
    pub estimator: Estimator,
    /// RMS of the whitened residual (GLS; ≈ 1 when the noise model fits), NaN for OLS.
    pub whitened_residual_rms: f64,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Bias at T0, rad/s.
    pub bias: Estimate,
    /// k_sf − 1.
    pub scale_factor_error: Estimate,
    /// rad/s per °C.
    pub temp_coeff: Estimate,
    /// rad/s per (°C/s).
    pub temp_rate_coeff: Estimate,
    /// The nuisance regressor's coefficient ([`JointFitOptions::nuisance`]), when given.
    pub nuisance: Option<Estimate>,
    /// RMS of the residual, rad/s.
    pub residual_rms_rad_s: f64,
    /// Samples used.
    pub n_samples: usize,
    /// Correlation time `k_e` in samples (first lag with autocorrelation < 1/e) of the
    /// bootstrapped residual (whitened for GLS).
    pub correlation_lag: usize,
    /// Bootstrap block length, samples.
    pub block_len: usize,
    /// Bootstrap replicates.
    pub replicates: usize,
    /// Covariance of (bias, scale factor error, temp_coeff, temp_rate_coeff), contract units:
    /// GLS, the Cramér–Rao bound scaled by max(1, whitened RMS)² (the nuisance regressor
    /// marginalised), a held coefficient's σ² and its covariance with the others through the
    /// estimator (0 when held exactly); OLS, NaN. Its diagonal is each [`Estimate::std_err`]²
    /// for GLS.
    pub covariance: [[f64; 4]; 4],
    /// Each sample's residual in units of its noise: the GLS whitened residual (white, unit
    /// variance when the noise model fits), or for OLS the residual over its RMS; in the
    /// windows' sample order.
    pub residual_z: Vec<f64>,
}

impl JointFit {
    /// The estimate of a calibrated coefficient (`None` for the model's other keys).
    pub fn estimate(&self, key: ModelKey) -> Option<&Estimate> {
        match key {
            ModelKey::Bias => Some(&self.bias),
            ModelKey::ScaleFactorError => Some(&self.scale_factor_error),
            ModelKey::TempCoeff => Some(&self.temp_coeff),
            ModelKey::TempRateCoeff => Some(&self.temp_rate_coeff),
            _ => None,
        }
    }

    /// The fitted coefficients written over `base` (noise terms, `earth_rate` and the thermal
    /// time constant kept).
    pub fn to_model(&self, base: &GyroModel) -> GyroModel {
        GyroModel {
            bias: self.bias.value,
            scale_factor_error: self.scale_factor_error.value,
            reference_temperature: self.reference_temperature_c,
            temp_coeff: self.temp_coeff.value,
            temp_rate_coeff: self.temp_rate_coeff.value,
            ..base.clone()
        }
    }
}

/// The fitted coefficients, in column order.
const NAMES: [&str; 4] = {
    let k = ModelKey::CALIBRATED;
    [k[0].key(), k[1].key(), k[2].key(), k[3].key()]
};

/// The design of one fit: the free columns (the coefficients not held, then the nuisance
/// regressor if any) scaled to unit RMS, `y` with the held coefficients' terms taken out, and
/// the raw columns of the held ones.
struct Design {
    x: DMatrix<f64>,
    y: DVector<f64>,
    /// Each free column's RMS (the scale it was divided by).
    scale: Vec<f64>,
    /// Each free column's index: 0–3 a coefficient (`NAMES` order), 4 the nuisance.
    cols: Vec<usize>,
    /// Held coefficients with a σ: (index, σ, raw column).
    held: Vec<(usize, f64, DVector<f64>)>,
}

/// The four regressors of one sample: bias, input rate, T − T0, dT/dt.
fn regressors(omega_in: f64, t: f64, t0: f64, d: f64) -> [f64; 4] {
    [1.0, omega_in, t - t0, d]
}

/// Build the [`Design`] of `windows` (module docs), refusing a free column that is zero
/// everywhere.
fn design(windows: &[RecordWindow], opts: &JointFitOptions) -> Result<Design, AnalysisError> {
    let earth = opts.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, opts.axis_up));
    let t0 = opts.reference_temperature_c;
    let n: usize = windows.iter().map(RecordWindow::len).sum();
    if let Some(nu) = &opts.nuisance {
        let lens: Vec<usize> = nu.values.iter().map(Vec::len).collect();
        let want: Vec<usize> = windows.iter().map(RecordWindow::len).collect();
        if lens != want {
            return Err(AnalysisError::Insufficient(format!(
                "joint fit: the nuisance column `{}` does not match the windows",
                nu.name
            )));
        }
    }
    let mut cols: Vec<usize> = (0..4).filter(|&j| opts.held[j].is_none()).collect();
    if opts.nuisance.is_some() {
        cols.push(4);
    }
    let held: Vec<(usize, Held)> = (0..4).filter_map(|j| opts.held[j].map(|h| (j, h))).collect();
    let mut x = DMatrix::<f64>::zeros(n, cols.len());
    let mut y = DVector::<f64>::zeros(n);
    let mut raw_held: Vec<DVector<f64>> = held.iter().map(|_| DVector::zeros(n)).collect();
    let mut row = 0;
    for (wi, w) in windows.iter().enumerate() {
        let temp = w.temperature_c();
        let rate = w.temperature_rate_c_s(opts.rate_window_s)?;
        for (k, (((v, o), t), d)) in
            w.gyro_rate_rad_s().iter().zip(w.table_rate_rad_s()).zip(temp).zip(&rate).enumerate()
        {
            let omega_in = o + earth;
            let r = regressors(omega_in, *t, t0, *d);
            y[row] = v - omega_in;
            for (c, &j) in cols.iter().enumerate() {
                x[(row, c)] = match (j, &opts.nuisance) {
                    (4, Some(nu)) => nu.values[wi][k],
                    _ => r[j],
                };
            }
            for (h, (j, hv)) in held.iter().enumerate() {
                y[row] -= hv.value * r[*j];
                raw_held[h][row] = r[*j];
            }
            row += 1;
        }
    }
    // Scale columns to unit RMS so the SVD's rank test compares like with like.
    let mut scale = Vec::with_capacity(cols.len());
    for (c, &j) in cols.iter().enumerate() {
        let rms = (x.column(c).norm_squared() / n as f64).sqrt();
        if rms == 0.0 || !rms.is_finite() {
            let name = if j < 4 { NAMES[j] } else { "nuisance" };
            return Err(AnalysisError::Insufficient(format!(
                "joint fit: the data never excite `{name}` (its regressor is zero everywhere)"
            )));
        }
        scale.push(rms);
        x.column_mut(c).scale_mut(1.0 / rms);
    }
    let held = held
        .iter()
        .zip(raw_held)
        .filter(|((_, h), _)| h.sigma.is_finite() && h.sigma > 0.0)
        .map(|((j, h), col)| (*j, h.sigma, col))
        .collect();
    Ok(Design { x, y, scale, cols, held })
}

/// The ordinary least-squares solution of a [`Design`] by SVD.
struct Ols {
    pinv: DMatrix<f64>,
    beta: DVector<f64>,
    resid: DVector<f64>,
    rss: f64,
}

/// Singular values below this share of the largest are a direction the design does not
/// determine.
const RANK_TOLERANCE: f64 = 1e-9;

/// [`Design`]'s least-squares solution; an error when a direction of it is not determined,
/// unless `any_rank` (then the minimum-norm solution, whose residual, the data's projection
/// off the columns' span, is the same for every solution).
fn ols(d: &Design, any_rank: bool) -> Result<Ols, AnalysisError> {
    let (n, p) = (d.x.nrows(), d.x.ncols());
    if n < 8 || n <= p {
        return Err(AnalysisError::TooFewSamples { what: "joint fit".into(), got: n, min: 8 });
    }
    let svd = d.x.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let degenerate = !(smax.is_finite() && smax > 0.0);
    if degenerate || (!any_rank && (smin.is_nan() || smin <= RANK_TOLERANCE * smax)) {
        return Err(AnalysisError::Insufficient(format!(
            "joint fit: the windows cannot separate bias, scale factor, temperature and \
             temperature-rate terms (condition number {:.3e})",
            smax / smin
        )));
    }
    let pinv = svd
        // A design that passed the check above has no singular value this small: its
        // inverse is whole; one that may lack rank (`any_rank`) drops what it does not hold.
        .pseudo_inverse(RANK_TOLERANCE * smax)
        .map_err(|e| AnalysisError::Insufficient(format!("joint fit: {e}")))?;
    let beta = &pinv * &d.y;
    let resid = &d.y - &d.x * &beta;
    let rss = resid.norm_squared();
    Ok(Ols { pinv, beta, resid, rss })
}

/// An ordinary least-squares fit without errors ([`ols_fit`]).
#[derive(Debug, Clone, PartialEq)]
pub struct OlsFit {
    /// The coefficients (`ModelKey::CALIBRATED` order; a held one's held value).
    pub coefficients: [f64; 4],
    /// The residual, one value per sample in the windows' order, rad/s.
    pub residual: Vec<f64>,
}

/// The OLS fit of the model over `windows` (held coefficients and the nuisance as in `opts`;
/// no bootstrap, no noise model): the residual the noise model is measured on, and starting
/// values ([`crate::calibrate`]). It runs before the run's identifiability is known, so a
/// design that cannot separate some coefficients (one turning direction: bias and scale
/// factor are one column) is solved by its minimum-norm solution: the residual is the one every
/// solution leaves, and the coefficients along the undetermined direction are that split, not
/// measurements.
pub fn ols_fit(windows: &[RecordWindow], opts: &JointFitOptions) -> Result<OlsFit, AnalysisError> {
    let d = design(windows, opts)?;
    let o = ols(&d, true)?;
    let mut coefficients: [f64; 4] = std::array::from_fn(|j| opts.held[j].map_or(0.0, |h| h.value));
    for (c, &j) in d.cols.iter().enumerate().filter(|(_, &j)| j < 4) {
        coefficients[j] = o.beta[c] / d.scale[c];
    }
    Ok(OlsFit { coefficients, residual: o.resid.as_slice().to_vec() })
}

/// The noise model's view of a design: sample times and white variances, the GLS fit and the
/// OLS estimate's variance under the model.
struct NoiseStage {
    spec: Option<NoiseSpec>,
    times: Vec<f64>,
    white: Vec<f64>,
    gls: Option<crate::gls::Gls>,
    ols_model_var: Vec<f64>,
}

fn noise_stage(
    windows: &[RecordWindow],
    d: &Design,
    o: &Ols,
    opts: &JointFitOptions,
) -> Result<NoiseStage, AnalysisError> {
    let p = d.x.ncols();
    // Sample times and white-noise variances (per-window median interval) for the noise model.
    let spec = opts
        .noise
        .filter(|s| [s.arw, s.flicker_floor, s.rrw].iter().all(|v| v.is_finite() && *v >= 0.0));
    let (times, dts): (Vec<f64>, Vec<f64>) = if spec.is_some() {
        windows
            .iter()
            .flat_map(|w| {
                let dt = median_interval(w.time_s()).unwrap_or(f64::NAN);
                w.time_s().iter().map(move |&t| (t, dt))
            })
            .unzip()
    } else {
        (Vec::new(), Vec::new())
    };
    let ols_model_var = match &spec {
        Some(spec) => noise_model_variance(&o.pinv, &times, &dts, spec),
        None => vec![f64::NAN; p],
    };
    // Each sample's white-noise variance, for the GLS (and the reference errors through it).
    let white: Vec<f64> = match &spec {
        Some(spec) if spec.arw > 0.0 => dts.iter().map(|dt| spec.arw * spec.arw / dt).collect(),
        _ => Vec::new(),
    };
    let gls = match &spec {
        Some(spec) if spec.arw > 0.0 => Some(gls(&d.x, &d.y, &times, &white, spec)?),
        _ => None,
    };
    Ok(NoiseStage { spec, times, white, gls, ols_model_var })
}

/// Fit the model (module docs) over all `windows`.
pub fn joint_fit(
    windows: &[RecordWindow],
    opts: &JointFitOptions,
) -> Result<JointFit, AnalysisError> {
    if opts.replicates < 2 {
        return Err(AnalysisError::InvalidParameter {
            name: "replicates",
            value: opts.replicates as f64,
            why: "need at least 2 bootstrap replicates",
        });
    }
    let d = design(windows, opts)?;
    let o = ols(&d, false)?;
    let ns = noise_stage(windows, &d, &o, opts)?;
    let (n, p) = (d.x.nrows(), d.x.ncols());
    // The bootstrap resamples the residual that should be closest to white: whitened for GLS.
    let (boot_pinv, boot_resid) = match &ns.gls {
        Some(g) => (&g.pinv_whitened, g.whitened_residual.as_slice()),
        None => (&o.pinv, o.resid.as_slice()),
    };
    let correlation_lag = correlation_lag(boot_resid, (n / 50).max(1));
    let block_len = match opts.block_len {
        Some(l) if l >= 1 => l.min(n),
        Some(_) => {
            return Err(AnalysisError::InvalidParameter {
                name: "block_len",
                value: 0.0,
                why: "must be at least 1 sample",
            })
        }
        None => block_len_rule(correlation_lag, n),
    };
    let boot_var = block_bootstrap_variance(boot_pinv, boot_resid, block_len, opts);
    let whitened_rms = ns.gls.as_ref().map_or(f64::NAN, |g| {
        (g.whitened_residual.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt()
    });
    // The table rate's own error (one constant per reference line) and the held values' σ:
    // their variance through the estimator's linear map, added to the noise model's.
    let (refs, ref_sigma) = reference_columns(windows);
    let mut added = through_estimator(&o.pinv, ns.gls.as_ref(), &ns, &refs, &ref_sigma)?;
    let held_map = if d.held.is_empty() {
        DMatrix::zeros(p, 0)
    } else {
        let cols: Vec<DVector<f64>> = d.held.iter().map(|h| h.2.clone()).collect();
        map_columns(&o.pinv, ns.gls.as_ref(), &ns, &DMatrix::from_columns(&cols))?
    };
    for (c, h) in d.held.iter().enumerate() {
        let col = held_map.column(c);
        added += col * col.transpose() * (h.1 * h.1);
    }
    let sigma2 = o.rss / (n - p) as f64;
    let est = |c: usize| {
        let sc = d.scale[c];
        let naive = (sigma2 * o.pinv.row(c).norm_squared()).sqrt() / sc;
        let boot = boot_var[c].max(0.0).sqrt() / sc;
        let ols_model = ns.ols_model_var[c].max(0.0).sqrt() / sc;
        let ols_value = o.beta[c] / sc;
        let (value, model) = match &ns.gls {
            Some(g) => (g.beta[c] / sc, g.cov[(c, c)].max(0.0).sqrt() / sc),
            None => (ols_value, ols_model),
        };
        let std_err = if ns.gls.is_some() {
            model * whitened_rms.max(1.0)
        } else if model.is_nan() {
            boot
        } else {
            boot.max(model)
        };
        let std_err = std_err.hypot(added[(c, c)].max(0.0).sqrt() / sc);
        Estimate {
            value,
            std_err,
            naive_std_err: naive,
            bootstrap_std_err: boot,
            noise_model_std_err: model,
            ols_value,
            ols_noise_model_std_err: ols_model,
            held: false,
        }
    };
    let mut coef: [Estimate; 4] = std::array::from_fn(|j| {
        let h = opts.held[j].unwrap_or(Held { value: f64::NAN, sigma: f64::NAN });
        Estimate::held(h)
    });
    let mut nuisance = None;
    for (c, &j) in d.cols.iter().enumerate() {
        if j < 4 {
            coef[j] = est(c);
        } else {
            nuisance = Some(est(c));
        }
    }
    let covariance = match &ns.gls {
        Some(g) => {
            full_covariance(&d, &(&g.cov * whitened_rms.max(1.0).powi(2) + &added), &held_map)
        }
        None => [[f64::NAN; 4]; 4],
    };
    Ok(JointFit {
        estimator: if ns.gls.is_some() { Estimator::Gls } else { Estimator::Ols },
        whitened_residual_rms: whitened_rms,
        reference_temperature_c: opts.reference_temperature_c,
        bias: coef[0],
        scale_factor_error: coef[1],
        temp_coeff: coef[2],
        temp_rate_coeff: coef[3],
        nuisance,
        residual_rms_rad_s: (o.rss / n as f64).sqrt(),
        n_samples: n,
        correlation_lag,
        block_len,
        replicates: opts.replicates,
        covariance,
        residual_z: match ns.gls {
            Some(g) => g.whitened_residual,
            None => {
                let rms = (o.rss / n as f64).sqrt();
                o.resid.iter().map(|e| if rms > 0.0 { e / rms } else { 0.0 }).collect()
            }
        },
    })
}

/// The 4×4 covariance of the coefficients in contract units (GLS): the free ones' from
/// `cov_free` (scaled units: the bound × max(1, whitened RMS)², plus what references and held
/// values add), a held one's σ² on its diagonal and its covariance with the free ones through
/// the estimator (`−P·x_h·σ_h²`); 0 for a held value taken as exact. Held values are
/// independent of each other.
fn full_covariance(d: &Design, cov_free: &DMatrix<f64>, held_map: &DMatrix<f64>) -> [[f64; 4]; 4] {
    let mut c = [[0.0; 4]; 4];
    let coef: Vec<(usize, usize)> =
        d.cols.iter().copied().enumerate().filter(|&(_, j)| j < 4).collect();
    for &(a, i) in &coef {
        for &(b, j) in &coef {
            c[i][j] = cov_free[(a, b)] / (d.scale[a] * d.scale[b]);
        }
    }
    for (h, &(j, s, _)) in d.held.iter().enumerate() {
        c[j][j] = s * s;
        for &(a, i) in &coef {
            let v = -held_map[(a, h)] * s * s / d.scale[a];
            c[i][j] = v;
            c[j][i] = v;
        }
    }
    c
}

/// The table rate's errors as columns: per reference line ([`RecordWindow::reference_error`])
/// its indicator over the samples it serves, and its σ.
fn reference_columns(windows: &[RecordWindow]) -> (DMatrix<f64>, Vec<f64>) {
    let mut keys: Vec<(usize, f64)> = windows
        .iter()
        .filter_map(RecordWindow::reference_error)
        .filter(|(_, s)| s.is_finite() && *s > 0.0)
        .collect();
    keys.sort_by_key(|k| k.0);
    keys.dedup_by_key(|k| k.0);
    let n: usize = windows.iter().map(RecordWindow::len).sum();
    let mut z = DMatrix::<f64>::zeros(n, keys.len());
    let mut row = 0;
    for w in windows {
        let col = w.reference_error().and_then(|(r, _)| keys.iter().position(|k| k.0 == r));
        for _ in 0..w.len() {
            if let Some(c) = col {
                z[(row, c)] = 1.0;
            }
            row += 1;
        }
    }
    (z, keys.iter().map(|k| k.1).collect())
}

/// `P·Z` for the estimator's linear map `P` (scaled columns' units): GLS, the whitened design's
/// pseudo-inverse applied to `Z` whitened in time order; OLS, the pseudo-inverse.
fn map_columns(
    pinv: &DMatrix<f64>,
    gls_fit: Option<&crate::gls::Gls>,
    ns: &NoiseStage,
    z: &DMatrix<f64>,
) -> Result<DMatrix<f64>, AnalysisError> {
    match (gls_fit, &ns.spec) {
        (Some(g), Some(spec)) => {
            let n = z.nrows();
            let mut order: Vec<usize> = (0..n).collect();
            order.sort_by(|&a, &b| ns.times[a].total_cmp(&ns.times[b]));
            let t: Vec<f64> = order.iter().map(|&i| ns.times[i]).collect();
            let r: Vec<f64> = order.iter().map(|&i| ns.white[i]).collect();
            let mut zs = DMatrix::<f64>::zeros(n, z.ncols());
            for (k, &i) in order.iter().enumerate() {
                zs.row_mut(k).copy_from(&z.row(i));
            }
            crate::gls::whiten(&t, &r, spec, &mut zs)?;
            Ok(&g.pinv_whitened * zs)
        }
        _ => Ok(pinv * z),
    }
}

/// Covariance (scaled columns' units) that independent errors `σ_c·z_c` in `y` add to the
/// coefficients: `Σ_c (P·z_c)(P·z_c)ᵀ σ_c²` ([`RecordWindow::with_reference_error`]: each
/// reference's error is one constant over its samples).
fn through_estimator(
    pinv: &DMatrix<f64>,
    gls_fit: Option<&crate::gls::Gls>,
    ns: &NoiseStage,
    z: &DMatrix<f64>,
    sigma: &[f64],
) -> Result<DMatrix<f64>, AnalysisError> {
    let p = pinv.nrows();
    let mut out = DMatrix::<f64>::zeros(p, p);
    if z.ncols() == 0 {
        return Ok(out);
    }
    let v = map_columns(pinv, gls_fit, ns, z)?;
    for (c, s) in sigma.iter().enumerate() {
        let col = v.column(c);
        out += col * col.transpose() * (s * s);
    }
    Ok(out)
}

/// Variances of `β* − β̂ = P·e*` over moving-block bootstrap replicates `e*` of `resid`
/// (module docs), in the units of `pinv`'s rows.
fn block_bootstrap_variance(
    pinv: &DMatrix<f64>,
    resid: &[f64],
    block_len: usize,
    opts: &JointFitOptions,
) -> Vec<f64> {
    let n = resid.len();
    let p = pinv.nrows();
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    let mut sum = vec![0.0; p];
    let mut sum2 = vec![0.0; p];
    let mut d = vec![0.0; p];
    for _ in 0..opts.replicates {
        d.fill(0.0);
        let mut pos = 0;
        while pos < n {
            let start = rng.random_range(0..n);
            let len = block_len.min(n - pos);
            for k in 0..len {
                let e = resid[(start + k) % n];
                for (j, dj) in d.iter_mut().enumerate() {
                    *dj += pinv[(j, pos + k)] * e;
                }
            }
            pos += len;
        }
        for j in 0..p {
            sum[j] += d[j];
            sum2[j] += d[j] * d[j];
        }
    }
    let b = opts.replicates as f64;
    (0..p).map(|j| (sum2[j] - sum[j] * sum[j] / b) / (b - 1.0)).collect()
}

/// Variances of the coefficients `β = P·e` (rows of `pinv`, scaled units) for noise `e` from
/// `spec`, exactly, in O(n) per term (module docs): white `N²/Δt·Σ P²`, each Gauss–Markov
/// component of the flicker synthesis by a forward–backward exponential filter over the
/// (irregular) sample times, rate random walk from the tail sums of `P`.
fn noise_model_variance(
    pinv: &DMatrix<f64>,
    times: &[f64],
    dts: &[f64],
    spec: &NoiseSpec,
) -> Vec<f64> {
    let n = times.len();
    let p = pinv.nrows();
    // Sample order in time (windows are normally given in time order already).
    let mut order: Vec<usize> = (0..n).collect();
    if times.windows(2).any(|w| w[1] < w[0]) {
        order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    }
    // Weights in time order, and the gaps between successive samples.
    let w: Vec<Vec<f64>> = (0..p).map(|j| order.iter().map(|&i| pinv[(j, i)]).collect()).collect();
    let gaps: Vec<f64> = (1..n).map(|k| times[order[k]] - times[order[k - 1]]).collect();
    let mut out = vec![0.0; p];
    // White rate noise.
    for (j, o) in out.iter_mut().enumerate() {
        for (k, &i) in order.iter().enumerate() {
            *o += spec.arw * spec.arw / dts[i] * w[j][k] * w[j][k];
        }
    }
    // Flicker: Σ_a Σ_b w_a w_b σ² e^{−|t_a − t_b|/T} = σ²·Σ_a w_a (F_a + B_a − w_a).
    if spec.flicker_floor > 0.0 {
        let mut decay = vec![0.0; n.saturating_sub(1)];
        let mut fwd = vec![0.0; n];
        for (t_corr, std) in bench_physics::noise::bias_instability_components(spec.flicker_floor) {
            for (d, g) in decay.iter_mut().zip(&gaps) {
                *d = (-g / t_corr).exp();
            }
            for (j, o) in out.iter_mut().enumerate() {
                let wj = &w[j];
                let mut f = 0.0;
                for k in 0..n {
                    f = wj[k] + if k == 0 { 0.0 } else { decay[k - 1] * f };
                    fwd[k] = f;
                }
                let mut bsum = 0.0;
                let mut acc = 0.0;
                for k in (0..n).rev() {
                    bsum = wj[k] + if k + 1 == n { 0.0 } else { decay[k] * bsum };
                    acc += wj[k] * (fwd[k] + bsum - wj[k]);
                }
                *o += std * std * acc;
            }
        }
    }
    // Rate random walk from the first sample: cov = K²·min(t_a, t_b) − t_first.
    if spec.rrw > 0.0 {
        for (j, o) in out.iter_mut().enumerate() {
            let mut tail = 0.0;
            let mut acc = 0.0;
            for k in (1..n).rev() {
                tail += w[j][k];
                acc += gaps[k - 1] * tail * tail;
            }
            *o += spec.rrw * spec.rrw * acc;
        }
    }
    out
}

/// First lag `k ≥ 1` at which the sample autocorrelation of `r` drops below `1/e`, searched up
/// to `max_lag` (returned if never). The search doubles the lag until the autocorrelation is
/// below `1/e`, then bisects between the last two lags: `O(n·log k)` rather than `O(n·k)` (a
/// residual with a slow component keeps its correlation for thousands of lags). It assumes the
/// autocorrelation decreases between those two lags, as it does for the noise processes here;
/// a lag where it crosses back above `1/e` inside that bracket is not looked for.
pub fn correlation_lag(r: &[f64], max_lag: usize) -> usize {
    let n = r.len();
    if n < 2 {
        return 1;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    let c: Vec<f64> = r.iter().map(|v| v - m).collect();
    let c0: f64 = c.iter().map(|v| v * v).sum();
    if c0 == 0.0 {
        return 1;
    }
    let limit = (-1.0f64).exp();
    let below = |k: usize| -> bool {
        let ck: f64 = c.iter().zip(&c[k..]).map(|(a, b)| a * b).sum();
        ck / c0 < limit
    };
    let top = max_lag.min(n - 1).max(1);
    // Doubling: `lo` is above the limit (or 0), `hi` the first power of two below it.
    let (mut lo, mut hi) = (0usize, 1usize);
    loop {
        if below(hi) {
            break;
        }
        if hi >= top {
            return top;
        }
        lo = hi;
        hi = (2 * hi).min(top);
    }
    // Bisect (lo, hi]: the first lag below the limit.
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if below(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// Block length from a correlation lag (module docs): `max(10·k_e, ⌈n^{1/3}⌉)`, at most `n/5`,
/// at least 1.
pub fn block_len_rule(correlation_lag: usize, n: usize) -> usize {
    let floor = (n as f64).cbrt().ceil() as usize;
    (10 * correlation_lag).max(floor).min(n / 5).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::{quantise, DEG_PER_MIN};
    use rand_distr::{Distribution, StandardNormal};

    /// Brute-force `Σ_a Σ_b w_a w_b C(a, b)` for the covariance `C` of `spec`'s noise.
    fn brute_variance(w: &[f64], t: &[f64], dt: f64, spec: &NoiseSpec) -> f64 {
        let comps = bench_physics::noise::bias_instability_components(spec.flicker_floor);
        let mut v = 0.0;
        for a in 0..w.len() {
            for b in 0..w.len() {
                let mut c = 0.0;
                if a == b {
                    c += spec.arw * spec.arw / dt;
                }
                for (tc, sd) in comps {
                    c += sd * sd * (-(t[a] - t[b]).abs() / tc).exp();
                }
                c += spec.rrw * spec.rrw * (t[a].min(t[b]) - t[0]);
                v += w[a] * w[b] * c;
            }
        }
        v
    }

    #[test]
    fn noise_model_variance_matches_the_covariance_summed_by_brute_force() {
        // Two windows with a gap; weights: a mean, a trend, an odd pattern, a step.
        let dt = 0.5;
        let t: Vec<f64> =
            (0..120).map(|i| if i < 60 { i as f64 * dt } else { 400.0 + i as f64 * dt }).collect();
        let n = t.len();
        let mut p = DMatrix::<f64>::zeros(4, n);
        for k in 0..n {
            p[(0, k)] = 1.0 / n as f64;
            p[(1, k)] = (t[k] - 200.0) * 1e-3;
            p[(2, k)] = ((k * 7919) % 13) as f64 - 6.0;
            p[(3, k)] = if k < 60 { -1.0 } else { 1.0 };
        }
        let spec = NoiseSpec { arw: 3e-7, flicker_floor: 2e-8, rrw: 1e-9 };
        let got = noise_model_variance(&p, &t, &vec![dt; n], &spec);
        for (j, g) in got.iter().enumerate() {
            let row: Vec<f64> = (0..n).map(|k| p[(j, k)]).collect();
            let want = brute_variance(&row, &t, dt, &spec);
            assert!((g / want - 1.0).abs() < 1e-9, "row {j}: {g} vs {want}");
        }
        // White alone: the variance of a mean is N²/(Δt·n).
        let white = NoiseSpec { arw: 3e-7, flicker_floor: 0.0, rrw: 0.0 };
        let v = noise_model_variance(&p, &t, &vec![dt; n], &white)[0];
        assert!((v / (9e-14 / (dt * n as f64)) - 1.0).abs() < 1e-12);
    }

    const DT: f64 = 0.05;
    const OMEGA: f64 = 10.0 * DEG_PER_MIN;
    const TRUE: [f64; 4] = [3e-6, 2e-4, -1e-7, 5e-5];
    const T0: f64 = 20.0;

    /// Six windows: CW/CCW at 20 °C, CW/CCW on a 2 °C/min ramp, CW/CCW at 40 °C; the gyro
    /// output follows the model with the *true* dT/dt plus `noise(i)`; temperatures quantised to
    /// `q` (0 = exact).
    fn windows(earth: f64, q: f64, mut noise: impl FnMut() -> f64) -> Vec<RecordWindow> {
        let ramp_rate = 2.0 / 60.0;
        let specs: [(&str, f64, f64, f64, f64); 6] = [
            ("record cw 20C", -OMEGA, 20.0, 0.0, 180.0),
            ("record ccw 20C", OMEGA, 20.0, 0.0, 180.0),
            ("record cw ramp", -OMEGA, 20.0, ramp_rate, 600.0),
            ("record ccw ramp", OMEGA, 40.0, -ramp_rate, 600.0),
            ("record cw 40C", -OMEGA, 40.0, 0.0, 180.0),
            ("record ccw 40C", OMEGA, 40.0, 0.0, 180.0),
        ];
        specs
            .iter()
            .map(|&(label, table, temp0, rate, secs)| {
                let n = (secs / DT) as usize;
                let t: Vec<f64> = (0..n).map(|i| i as f64 * DT).collect();
                let temp: Vec<f64> = t.iter().map(|&t| temp0 + rate * t).collect();
                let v: Vec<f64> = temp
                    .iter()
                    .map(|&tc| {
                        let w_in = table + earth;
                        w_in * (1.0 + TRUE[1])
                            + TRUE[0]
                            + TRUE[2] * (tc - T0)
                            + TRUE[3] * rate
                            + noise()
                    })
                    .collect();
                let read: Vec<f64> = temp.iter().map(|&x| quantise(x, q)).collect();
                RecordWindow::new(label, t, v, vec![table; n], Some(read.clone()), read)
                    .expect("valid synthetic window")
            })
            .collect()
    }

    fn values(f: &JointFit) -> [Estimate; 4] {
        [f.bias, f.scale_factor_error, f.temp_coeff, f.temp_rate_coeff]
    }

    #[test]
    fn noise_free_data_give_the_model_back_with_earth_rate_removed() {
        let lat = 59.94;
        let earth = vertical_rate_rad_s(lat, true);
        let ws = windows(earth, 0.0, || 0.0);
        let opts = JointFitOptions {
            latitude_deg: Some(lat),
            replicates: 10,
            ..JointFitOptions::default()
        };
        let fit = joint_fit(&ws, &opts).expect("identifiable");
        for (e, want) in values(&fit).iter().zip(TRUE) {
            assert!((e.value / want - 1.0).abs() < 1e-6, "{} vs {want}", e.value);
        }
        assert!(fit.residual_rms_rad_s < 1e-15);
        // Without the latitude, Earth's rotation (×(1 + s)) lands in the bias.
        let fit = joint_fit(&ws, &JointFitOptions { replicates: 10, ..JointFitOptions::default() })
            .expect("identifiable");
        assert!((fit.bias.value - TRUE[0] - earth * (1.0 + TRUE[1])).abs() < 1e-12);
    }

    #[test]
    fn the_table_rates_error_is_in_the_standard_errors() {
        // Each window's table rate is off by its own constant δ_s (σ = 2e-8 rad/s, 7 ppm of
        // 10 °/min) that the fit cannot see: the coefficients scatter by what the windows'
        // reference errors predict, through the estimator's map.
        let sigma = 2e-8;
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let opts = JointFitOptions { replicates: 10, ..JointFitOptions::default() };
        let runs = 100;
        let mut sf = Vec::new();
        for _ in 0..runs {
            let mut noise = || 1e-10 * rng.sample::<f64, _>(StandardNormal);
            let mut ws = windows(0.0, 0.0, &mut noise);
            for w in &mut ws {
                let d: f64 = sigma * rng.sample::<f64, _>(StandardNormal);
                // The gyro saw the true rate; the reference says it was `d` more.
                let t: Vec<f64> = w.table_rate_rad_s().iter().map(|o| o + d).collect();
                *w = RecordWindow::new(
                    w.label(),
                    w.time_s().to_vec(),
                    w.gyro_rate_rad_s().to_vec(),
                    t,
                    w.gyro_temp_c().map(<[f64]>::to_vec),
                    w.chamber_temp_c().to_vec(),
                )
                .expect("valid");
            }
            sf.push(joint_fit(&ws, &opts).expect("fit").scale_factor_error.value);
        }
        let mean = sf.iter().sum::<f64>() / runs as f64;
        let sd = (sf.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
        let told: Vec<RecordWindow> = windows(0.0, 0.0, || 0.0)
            .into_iter()
            .enumerate()
            .map(|(k, w)| w.with_reference_error(k, sigma))
            .collect();
        let blind = joint_fit(&windows(0.0, 0.0, || 0.0), &opts).expect("fit");
        let fit = joint_fit(&told, &opts).expect("fit");
        assert!(blind.scale_factor_error.std_err < 0.01 * sd);
        // 100 runs: the sample σ is good to about 7 %.
        let ratio = fit.scale_factor_error.std_err / sd;
        assert!((0.8..1.25).contains(&ratio), "predicted σ over observed: {ratio}");
        // Windows sharing one reference share its error: one δ in every window's signed rate
        // is a constant in `y`, which the bias takes and the scale factor does not see.
        let shared: Vec<RecordWindow> = windows(0.0, 0.0, || 0.0)
            .into_iter()
            .map(|w| w.with_reference_error(0, sigma))
            .collect();
        let one = joint_fit(&shared, &opts).expect("fit");
        assert!(one.scale_factor_error.std_err < 0.5 * fit.scale_factor_error.std_err);
    }

    #[test]
    fn a_design_without_temperature_change_is_refused() {
        let ws: Vec<RecordWindow> = windows(0.0, 0.0, || 0.0)
            .into_iter()
            .filter(|w| w.temperature_span_c() == 0.0)
            .collect();
        // Plateaus only: dT/dt is zero everywhere.
        let e = joint_fit(&ws, &JointFitOptions::default());
        assert!(
            matches!(e, Err(AnalysisError::Insufficient(ref m)) if m.contains("temp_rate_coeff"))
        );
        // One plateau only: T − T0 is zero everywhere too.
        let e = joint_fit(&ws[..2], &JointFitOptions::default());
        assert!(matches!(e, Err(AnalysisError::Insufficient(_))));
    }

    #[test]
    fn one_turning_direction_leaves_the_ols_residual_the_noise_model_is_measured_on() {
        // CW windows only: bias and scale factor are one column. The joint fit refuses; the
        // OLS fit the noise stage runs first still leaves the residual, the same as with the
        // scale factor held (the bias then takes both).
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let ws: Vec<RecordWindow> =
            windows(0.0, 0.0, || 1e-7 * rng.sample::<f64, _>(StandardNormal))
                .into_iter()
                .filter(|w| w.label().contains(" cw"))
                .collect();
        assert_eq!(ws.len(), 3);
        assert!(matches!(
            joint_fit(&ws, &JointFitOptions::default()),
            Err(AnalysisError::Insufficient(_))
        ));
        let free = ols_fit(&ws, &JointFitOptions::default()).expect("any rank");
        let mut held = [None; 4];
        held[1] = Some(Held { value: 0.0, sigma: 0.0 });
        let fixed = ols_fit(&ws, &JointFitOptions { held, ..Default::default() }).expect("ols");
        assert_eq!(free.residual.len(), fixed.residual.len());
        let rms = (fixed.residual.iter().map(|r| r * r).sum::<f64>() / ws.len() as f64).sqrt();
        assert!(rms > 1e-8, "{rms}");
        for (a, b) in free.residual.iter().zip(&fixed.residual) {
            assert!((a - b).abs() < 1e-6 * rms, "{a} vs {b}");
        }
        // The determined coefficients agree too; the split of the undetermined direction is
        // the minimum-norm one, not a measurement.
        for j in [2, 3] {
            let (a, b) = (free.coefficients[j], fixed.coefficients[j]);
            assert!((a - b).abs() <= 1e-9 * b.abs(), "{j}: {a} vs {b}");
        }
    }

    #[test]
    fn the_bisected_correlation_lag_is_the_first_lag_below_1_over_e() {
        let linear = |r: &[f64], max: usize| {
            let m = r.iter().sum::<f64>() / r.len() as f64;
            let c: Vec<f64> = r.iter().map(|v| v - m).collect();
            let c0: f64 = c.iter().map(|v| v * v).sum();
            (1..=max)
                .find(|&k| {
                    c.iter().zip(&c[k..]).map(|(a, b)| a * b).sum::<f64>() / c0 < (-1f64).exp()
                })
                .unwrap_or(max)
        };
        for (seed, tau) in [(1u64, 0.3), (2, 5.0), (3, 77.0), (4, 600.0)] {
            let phi = (-1.0f64 / tau).exp();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut x = 0.0;
            let r: Vec<f64> = (0..50_000)
                .map(|_| {
                    let w: f64 = StandardNormal.sample(&mut rng);
                    x = phi * x + w;
                    x
                })
                .collect();
            assert_eq!(correlation_lag(&r, 2000), linear(&r, 2000), "τ = {tau}");
        }
        // Never below the limit within max_lag: max_lag.
        let ramp: Vec<f64> = (0..1000).map(f64::from).collect();
        assert_eq!(correlation_lag(&ramp, 10), 10);
    }

    #[test]
    fn block_rule_and_correlation_lag_of_ar1() {
        // AR(1) with φ = e^{−1/40}: correlation lag 40 samples.
        let phi = (-1.0f64 / 40.0).exp();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut x = 0.0;
        let r: Vec<f64> = (0..200_000)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                x = phi * x + w;
                x
            })
            .collect();
        let k = correlation_lag(&r, 4000);
        assert!((30..=50).contains(&k), "lag {k}");
        assert_eq!(block_len_rule(40, 200_000), 400);
        assert_eq!(block_len_rule(1, 1_000_000), 100);
        assert_eq!(block_len_rule(10_000, 1000), 200);
        assert_eq!(block_len_rule(0, 3), 1);
    }

    /// Gauss–Markov noise (τ = 2 s, σ = 1 µrad/s ≈ 0.2 °/h) at 20 Hz: the naive OLS errors are
    /// about √((1+φ)/(1−φ)) ≈ 9 times too small and miss the truth; the block-bootstrap errors
    /// cover it and match the scatter over realisations.
    #[test]
    fn bootstrap_errors_cover_the_truth_under_gauss_markov_noise_where_naive_ones_do_not() {
        let sigma = 1e-6;
        let phi = (-DT / 2.0f64).exp();
        let drive = sigma * (1.0 - phi * phi).sqrt();
        let runs = 16;
        let mut est = vec![[0.0; 4]; runs];
        let (mut cover_boot, mut cover_naive, mut ratio_sum) = (0, 0, 0.0);
        let mut boot_se_mean = [0.0; 4];
        for (run, est_run) in est.iter_mut().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + run as u64);
            let n0: f64 = StandardNormal.sample(&mut rng);
            let mut x = sigma * n0;
            let ws = windows(0.0, 0.01, || {
                let w: f64 = StandardNormal.sample(&mut rng);
                x = phi * x + drive * w;
                x
            });
            let opts = JointFitOptions { replicates: 200, seed: run as u64, ..Default::default() };
            let fit = joint_fit(&ws, &opts).expect("identifiable");
            for (j, e) in values(&fit).iter().enumerate() {
                let err = (e.value - TRUE[j]).abs();
                cover_boot += usize::from(err <= 2.0 * e.std_err);
                cover_naive += usize::from(err <= 2.0 * e.naive_std_err);
                ratio_sum += e.std_err / e.naive_std_err;
                boot_se_mean[j] += e.std_err / runs as f64;
                est_run[j] = e.value;
            }
        }
        let cases = 4 * runs;
        let ratio = ratio_sum / cases as f64;
        assert!(ratio > 5.0 && ratio < 14.0, "bootstrap/naive ratio {ratio}");
        // 95 % nominal: expect ≈ 61 of 64; naive at ±2σ_naive ≈ ±0.22σ_true covers ≈ 18 %.
        assert!(cover_boot >= 54, "bootstrap covered {cover_boot}/{cases}");
        assert!(cover_naive <= 32, "naive covered {cover_naive}/{cases}");
        // Bootstrap SE against the empirical scatter over realisations (16 runs: ±18 % 1σ).
        for j in 0..4 {
            let m = est.iter().map(|e| e[j]).sum::<f64>() / runs as f64;
            let sd =
                (est.iter().map(|e| (e[j] - m).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
            let q = boot_se_mean[j] / sd;
            assert!((0.55..1.8).contains(&q), "{}: boot SE / scatter = {q}", NAMES[j]);
        }
    }

    /// Plateaus at 20 and −20 °C and ±1 °C/min ramps between them with gaps, the table at
    /// ±10 °/min, 2 Hz; the noise is the simulator's own (white + flicker) generated over the
    /// whole time line, gaps included, so the fit sees gaps of correlated noise.
    fn gls_run(seed: u64, arw: f64, floor: f64) -> Vec<RecordWindow> {
        let dt = 0.5;
        let r = 1.0 / 60.0;
        // (label, table rate, start time, duration, start temperature, rate)
        let specs: [(&str, f64, f64, f64, f64, f64); 6] = [
            ("record cw 20C", -OMEGA, 0.0, 600.0, 20.0, 0.0),
            ("record ccw 20C", OMEGA, 660.0, 600.0, 20.0, 0.0),
            ("record cw ramp", -OMEGA, 3000.0, 2400.0, 20.0, -r),
            ("record ccw ramp", OMEGA, 6000.0, 2400.0, -20.0, r),
            ("record cw -20C", -OMEGA, 9600.0, 600.0, -20.0, 0.0),
            ("record ccw -20C", OMEGA, 10_260.0, 600.0, -20.0, 0.0),
        ];
        let total = ((10_260.0 + 600.0) / dt) as usize;
        let mut gen = bench_physics::noise::GyroNoise::new(arw, floor, dt, seed, 0);
        let mut noise = vec![0.0; total];
        gen.fill(&mut noise);
        specs
            .iter()
            .map(|&(label, table, start, secs, temp0, rate)| {
                let k0 = (start / dt) as usize;
                let len = (secs / dt) as usize;
                let t: Vec<f64> = (0..len).map(|i| start + i as f64 * dt).collect();
                let temp: Vec<f64> = (0..len).map(|i| temp0 + rate * i as f64 * dt).collect();
                let v: Vec<f64> = (0..len)
                    .map(|i| {
                        table * (1.0 + TRUE[1])
                            + TRUE[0]
                            + TRUE[2] * (temp[i] - T0)
                            + TRUE[3] * rate
                            + noise[k0 + i]
                    })
                    .collect();
                RecordWindow::new(label, t, v, vec![table; len], Some(temp.clone()), temp)
                    .expect("valid synthetic window")
            })
            .collect()
    }

    /// With the true noise model, GLS intervals cover the truth at their nominal rate, its σ
    /// match the scatter over realisations, and they are never worse than OLS's σ under the
    /// same model (the Cramér–Rao bound).
    #[test]
    fn gls_errors_match_the_scatter_and_beat_ols_under_flicker_noise() {
        let (arw, floor) = (3e-7, 3e-7);
        let spec = NoiseSpec { arw, flicker_floor: floor, rrw: 0.0 };
        let runs = 60;
        let mut covered = 0;
        let mut err2 = [0.0; 4];
        let mut ols_err2 = [0.0; 4];
        let mut sigma2 = [0.0; 4];
        for run in 0..runs {
            let ws = gls_run(500 + run as u64, arw, floor);
            let opts = JointFitOptions {
                replicates: 50,
                seed: run as u64,
                noise: Some(spec),
                rate_window_s: 20.0,
                ..Default::default()
            };
            let fit = joint_fit(&ws, &opts).expect("identifiable");
            assert_eq!(fit.estimator, Estimator::Gls);
            for (j, e) in values(&fit).iter().enumerate() {
                assert!(
                    e.noise_model_std_err <= e.ols_noise_model_std_err * (1.0 + 1e-9),
                    "{}: GLS σ {} > OLS σ {}",
                    NAMES[j],
                    e.noise_model_std_err,
                    e.ols_noise_model_std_err
                );
                let err = e.value - TRUE[j];
                covered += usize::from(err.abs() <= 1.959_964 * e.std_err);
                err2[j] += err * err / runs as f64;
                ols_err2[j] += (e.ols_value - TRUE[j]).powi(2) / runs as f64;
                sigma2[j] += e.std_err * e.std_err / runs as f64;
            }
            assert!(
                (0.9..1.1).contains(&fit.whitened_residual_rms),
                "{}",
                fit.whitened_residual_rms
            );
        }
        // 240 cases at 95 %: 228 expected, binomial sd 3.4.
        assert!((216..=239).contains(&covered), "covered {covered}/240");
        for j in 0..4 {
            let q = (sigma2[j] / err2[j]).sqrt();
            assert!((0.75..1.35).contains(&q), "{}: RMS σ / RMS error = {q}", NAMES[j]);
            eprintln!(
                "{}: GLS RMS error {:.3e}, OLS {:.3e}, RMS σ {:.3e}",
                NAMES[j],
                err2[j].sqrt(),
                ols_err2[j].sqrt(),
                sigma2[j].sqrt()
            );
        }
    }
}
