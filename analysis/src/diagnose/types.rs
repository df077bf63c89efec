//! The diagnosis's settings and results.

use super::*;

/// Settings of a diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseOptions {
    /// Bin length, s (default 10).
    pub bin_s: f64,
    /// Family-wise false-finding probability over every effect and grid point (default 0.01).
    pub alpha: f64,
    /// Hold-out block length, s (default 600): blocks alternate between fit and test.
    pub holdout_block_s: f64,
    /// Most effects to add (default 4).
    pub max_effects: usize,
    /// Grid values at which the identifiability of these effects is judged, instead of their
    /// best fit (e.g. a recording's, to predict a new run's separation of the same term).
    pub identify_at: Vec<(EffectId, f64)>,
    /// Sets of terms (as a [`Collinearity::with`] lists them) whose collinearity with these
    /// effects is measured as well (a recording's set, measured again on another run).
    pub identify_with: Vec<(EffectId, Vec<String>)>,
    /// Threads for the parallel parts (default [`default_threads`]; 1: serial). The results
    /// do not depend on it.
    pub threads: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            bin_s: 10.0,
            alpha: 0.01,
            holdout_block_s: 600.0,
            max_effects: 4,
            identify_at: Vec::new(),
            identify_with: Vec::new(),
            threads: columns::default_threads(),
        }
    }
}

/// A Wald statistic and the threshold it is judged against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaldTest {
    /// The statistic under the noise model.
    pub value: f64,
    /// Its threshold (χ² at the test's level).
    pub threshold: f64,
}

/// Residual RMS of bin means at the diagnosis's three stages, rad/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualRms {
    /// Against the nominal model.
    pub nominal: f64,
    /// After the nominal parameters' refit.
    pub before: f64,
    /// After the effects as well.
    pub after: f64,
}

/// BIC-like score, RSS/σ̄² + p·ln n_eff, of the refit-only and the final model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bic {
    /// The nominal parameters refitted only.
    pub before: f64,
    /// With the effects.
    pub after: f64,
}

/// One of the nominal model's parameters, refitted.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterUpdate {
    /// Which parameter.
    pub key: ModelKey,
    /// Nominal value.
    pub nominal: f64,
    /// Fitted value.
    pub fitted: f64,
    /// 1σ of the fitted value (noise model).
    pub sigma: f64,
    /// Why the parameter is held at its nominal value rather than refitted (`fitted` is then
    /// the nominal value and `sigma` the σ it would have had): the effects and unexplained
    /// structure in the model carry more than [`crate::information::CONFOUNDED`] of its
    /// information.
    pub held: Option<String>,
}

/// A fitted parameter of an effect.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectParameter {
    /// Name (the effect's TOML key).
    pub name: &'static str,
    /// Value.
    pub value: f64,
    /// 1σ.
    pub sigma: f64,
    /// Unit.
    pub unit: &'static str,
}

/// An effect of the library tested against the residual.
#[derive(Debug, Clone, PartialEq)]
pub struct Finding {
    /// Which effect.
    pub effect: EffectId,
    /// Its parameters.
    pub parameters: Vec<EffectParameter>,
    /// Wald statistic under the noise model.
    pub wald: f64,
    /// The Wald threshold it had to pass.
    pub threshold: f64,
    /// W − (k + q)·ln n_eff.
    pub delta_bic: f64,
    /// Residual RMS before adding it, rad/s (bin means).
    pub rms_before: f64,
    /// Residual RMS after, rad/s.
    pub rms_after: f64,
    /// Combined z of the held-out blocks' agreement with the shape (≈ z of a unit gain).
    pub holdout_z: f64,
    /// Where the term is largest (its contribution above half its peak), s from the first
    /// message, merged.
    pub windows_s: Vec<(f64, f64)>,
    /// Accepted into the model.
    pub accepted: bool,
    /// Why not, when not.
    pub rejected_because: Option<String>,
    /// The residual check against the effect's family ([`family`]), for effects that passed
    /// the search.
    pub family: Option<FamilyCheck>,
    /// For a per-revolution term: whether it belongs to the gyro or to the table's rate.
    pub rate_dependence: Option<RateDependence>,
    /// What names it beyond its fit, in words (Earth's rate: the bias shift against the site's
    /// Ω_E·sin(latitude)).
    pub remark: Option<String>,
}

/// Structure no effect explains.
#[derive(Debug, Clone, PartialEq)]
pub struct Unexplained {
    /// Where, s.
    pub windows_s: Vec<(f64, f64)>,
    /// The signal the residual correlates with best, with the correlation.
    pub correlates_with: String,
    /// Residual RMS in those windows, rad/s.
    pub rms: f64,
}

/// Residual statistics over a class of bins.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// What (a step label, `cw`, `heating`, `-20..-10 °C`, `angle 45..90°`).
    pub name: String,
    /// Bins in it.
    pub bins: usize,
    /// Mean residual, rad/s.
    pub mean: f64,
    /// Its 1σ under the noise model.
    pub sigma: f64,
}

impl Region {
    /// mean / σ.
    pub fn z(&self) -> f64 {
        self.mean / self.sigma
    }
}

/// Where the residual (after the parameter refit, before any effect) sits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Location {
    /// Per step.
    pub steps: Vec<Region>,
    /// CW, CCW, rest.
    pub direction: Vec<Region>,
    /// Heating, cooling, steady.
    pub thermal: Vec<Region>,
    /// 10 °C bands.
    pub temperature: Vec<Region>,
    /// 45° sectors of the table angle (rotating bins).
    pub angle: Vec<Region>,
    /// Bins holding a table acceleration (starts, stops, reversals).
    pub transitions: Option<Region>,
    /// Strongest change point of the bias: (time s, Wald).
    pub change_point: Option<(f64, f64)>,
    /// Once- and twice-per-revolution amplitude (rad/s) and Wald.
    pub harmonics: Vec<(u32, f64, f64)>,
}

/// Verdict of a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The recording matches the nominal model within its noise.
    Consistent,
    /// Only the nominal parameters' values differ.
    ParametersOnly,
    /// Physics is missing: effects found, or structure left unexplained.
    MissingPhysics,
}

impl Verdict {
    /// JSON spelling.
    pub fn key(self) -> &'static str {
        match self {
            Verdict::Consistent => "consistent",
            Verdict::ParametersOnly => "parameters_only",
            Verdict::MissingPhysics => "missing_physics",
        }
    }
}

/// Bin-level series for figures.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Bin centres, s.
    pub time_s: Vec<f64>,
    /// Gyro minus the nominal simulation, rad/s.
    pub residual_nominal: Vec<f64>,
    /// After the parameter refit.
    pub residual_before: Vec<f64>,
    /// After the parameter refit and the accepted effects.
    pub residual_after: Vec<f64>,
    /// Model temperature, °C.
    pub temp_c: Vec<f64>,
    /// dT/dt, °C/s.
    pub temp_rate_c_s: Vec<f64>,
    /// Table rate, rad/s.
    pub table_rate_rad_s: Vec<f64>,
    /// Table angle (bin mean), rad.
    pub angle_rad: Vec<f64>,
    /// Each accepted effect's fitted contribution, rad/s.
    pub contributions: Vec<(EffectId, Vec<f64>)>,
}

/// The result of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// The verdict.
    pub verdict: Verdict,
    /// Parameter refit.
    pub parameter_updates: Vec<ParameterUpdate>,
    /// Wald test of the parameter corrections (all jointly).
    pub parameters_wald: WaldTest,
    /// Effects accepted (in order) and then those tested but not accepted that came closest.
    pub findings: Vec<Finding>,
    /// Structure left over.
    pub unexplained: Vec<Unexplained>,
    /// Where the mismatch is.
    pub location: Location,
    /// Noise model of the residual after the parameters' refit (the one every test uses).
    pub noise_before: NoiseSpec,
    /// Noise model with the effects (as the search left it).
    pub noise_after: NoiseSpec,
    /// Effective number of independent bins (after).
    pub n_eff: f64,
    /// Bins used.
    pub n_bins: usize,
    /// Residual RMS of bin means.
    pub rms: ResidualRms,
    /// ADEV of the residual after the parameters' refit only.
    pub adev_before: Vec<AdevPoint>,
    /// ADEV of the residual with the effects as well.
    pub adev_after: Vec<AdevPoint>,
    /// BIC-like score of the refit-only and the final model.
    pub bic: Bic,
    /// The updated model: nominal with refitted parameters and the accepted effects.
    pub model: GyroModel,
    /// The updated model's effects.
    pub effects: Effects,
    /// Figures' data.
    pub series: Series,
    /// Every effect against every term of the final model ([`identify`]); the pairs this
    /// recording cannot tell apart are [`Diagnosis::identifiability`].
    pub collinearity: Vec<Collinearity>,
}

impl Diagnosis {
    /// The pairs of terms this recording cannot tell apart: collinearity at or above
    /// [`identify::COLLINEAR_RHO`], most collinear first.
    pub fn identifiability(&self) -> Vec<Collinearity> {
        self.collinearity.iter().filter(|c| c.rho >= identify::COLLINEAR_RHO).cloned().collect()
    }
}
