//! FOG effects beyond the nominal error model ([`crate::GyroModel`]): the library that the
//! simulator switches on as hidden truth and that `bench diagnose` fits to a recording's
//! residual. One definition serves both: the simulator adds [`Effects::value`], the analysis
//! builds its regressors from [`Effect::regressors`] and the effect's [`Columns`] — the same
//! functions.
//!
//! **One file per effect, one registry.** Each effect is a type implementing [`Effect`] (or
//! [`LinearEffect`], for one without a non-linear parameter) in its own file of this folder,
//! and one line of [`registry!`] below gives it its [`EffectId`]. The trait has no default
//! methods: an effect that leaves one out does not compile. Everything else — the simulators,
//! the nominal model, the diagnosis, its identifiability check, the suggested scenario, the
//! model file, scenario parsing and the docs' effect table — reads the registry.
//!
//! Every effect is a sum of linear parameters times regressors, given its non-linear parameter
//! (a time constant, a time, a period); the regressors are functions of an [`EffectSample`].
//! Two effects transform the inputs instead (the thermal lag, the time offset). The table of
//! effects, formulas and parameters is [`Effects::table_markdown`] (`docs/diagnose.md`).
//!
//! `Ω_in` is the input rate the gyro sees (table plus Earth along the sensing axis), `T` the
//! temperature that drives the bias (°C), `t` seconds since power-on (the start of the run; in
//! a recording, the first message).

mod describe;
mod set;

pub use describe::{
    Columns, Family, Grid, Order, Owner, Param, Procedure, Range, Refinement, Reported, Rival, Role,
};
pub use set::{Effects, METADATA_PREFIX};
pub use thermal_hysteresis::HYSTERESIS_THRESHOLD_C_S;

use crate::lag::FirstOrderLag;

/// An effect of the library: its physics and everything the simulators and the diagnosis need
/// to know of it. No method has a default, so an effect that forgets one does not compile.
pub trait Effect: Sync {
    /// The stable id, snake case (JSON, TOML, `effect.<key>.*` metadata keys).
    fn key(&self) -> &'static str;
    /// Whose physics it is: what travels with a gyro model to another recording.
    fn owner(&self) -> Owner;
    /// One line of physics, for an engineer.
    fn description(&self) -> &'static str;
    /// Its regressor's shape in a few words ("(T − T0)²"), where the effect is named as
    /// another's relative.
    fn shape(&self) -> &'static str;
    /// The output it adds, as a formula in words (the docs' table).
    fn formula(&self) -> &'static str;
    /// Its parameters, in file order, with units, ranges and roles.
    fn params(&self) -> &'static [Param];
    /// How many regressors [`Self::regressors`] writes (0 for an effect that transforms the
    /// inputs).
    fn linear_count(&self) -> usize;
    /// The regressors for one sample given the non-linear parameter `p` (ignored by an effect
    /// without one); writes [`Self::linear_count`] values.
    fn regressors(&self, s: &EffectSample, p: f64, out: &mut [f64]);
    /// How the diagnosis builds its regressors over bins.
    fn columns(&self) -> Columns;
    /// The grid of its non-linear parameter.
    fn grid(&self) -> Grid;
    /// The grid it is fitted on when judged as another accepted effect's rival, where that is
    /// wider than the grid it is searched on (the same by default).
    fn rival_grid(&self) -> Grid {
        self.grid()
    }
    /// How a grid value is refined below the grid.
    fn refinement(&self) -> Refinement;
    /// The shapes that test it once accepted.
    fn family(&self) -> Family;
    /// The terms it can be confused with, and when.
    fn rivals(&self) -> &'static [Rival];
    /// The run that separates it from its rivals.
    fn separated_by(&self) -> Procedure;
    /// Its parameters as a diagnosis reports them.
    fn reported(&self) -> &'static [Reported];
}

/// An effect without a non-linear parameter: everything of [`Effect`] but the grid and its
/// refinement (none). Every method is still required.
pub trait LinearEffect: Sync {
    /// [`Effect::key`].
    fn key(&self) -> &'static str;
    /// [`Effect::owner`].
    fn owner(&self) -> Owner;
    /// [`Effect::description`].
    fn description(&self) -> &'static str;
    /// [`Effect::shape`].
    fn shape(&self) -> &'static str;
    /// [`Effect::formula`].
    fn formula(&self) -> &'static str;
    /// [`Effect::params`].
    fn params(&self) -> &'static [Param];
    /// [`Effect::linear_count`].
    fn linear_count(&self) -> usize;
    /// [`Effect::regressors`] (no non-linear parameter).
    fn regressors(&self, s: &EffectSample, out: &mut [f64]);
    /// [`Effect::columns`].
    fn columns(&self) -> Columns;
    /// [`Effect::family`].
    fn family(&self) -> Family;
    /// [`Effect::rivals`].
    fn rivals(&self) -> &'static [Rival];
    /// [`Effect::separated_by`].
    fn separated_by(&self) -> Procedure;
    /// [`Effect::reported`].
    fn reported(&self) -> &'static [Reported];
}

impl<T: LinearEffect> Effect for T {
    fn key(&self) -> &'static str {
        LinearEffect::key(self)
    }
    fn owner(&self) -> Owner {
        LinearEffect::owner(self)
    }
    fn description(&self) -> &'static str {
        LinearEffect::description(self)
    }
    fn shape(&self) -> &'static str {
        LinearEffect::shape(self)
    }
    fn formula(&self) -> &'static str {
        LinearEffect::formula(self)
    }
    fn params(&self) -> &'static [Param] {
        LinearEffect::params(self)
    }
    fn linear_count(&self) -> usize {
        LinearEffect::linear_count(self)
    }
    fn regressors(&self, s: &EffectSample, _p: f64, out: &mut [f64]) {
        LinearEffect::regressors(self, s, out);
    }
    fn columns(&self) -> Columns {
        LinearEffect::columns(self)
    }
    fn grid(&self) -> Grid {
        Grid::None
    }
    fn refinement(&self) -> Refinement {
        Refinement::None
    }
    fn family(&self) -> Family {
        LinearEffect::family(self)
    }
    fn rivals(&self) -> &'static [Rival] {
        LinearEffect::rivals(self)
    }
    fn separated_by(&self) -> Procedure {
        LinearEffect::separated_by(self)
    }
    fn reported(&self) -> &'static [Reported] {
        LinearEffect::reported(self)
    }
}

/// The registry: one line per effect, `Id => module::Type`, in library order (the order of
/// reports, files and metadata; an id's position also seeds its scan, so new effects go last).
/// The line declares the effect's module (`module.rs` in this folder) too.
macro_rules! registry {
    ($($id:ident => $module:ident::$ty:ident),* $(,)?) => {
        $(mod $module;)*

        /// The effects of the library, by their place in the registry.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum EffectId {
            $(
                #[doc = concat!("See [`", stringify!($module), "`]'s effect.")]
                $id,
            )*
        }

        /// How many effects the library has.
        pub const COUNT: usize = [$(stringify!($id)),*].len();

        impl EffectId {
            /// Every effect, in library order.
            pub const ALL: [EffectId; COUNT] = [$(EffectId::$id),*];

            /// The effect itself.
            pub fn effect(self) -> &'static dyn Effect {
                match self {
                    $(EffectId::$id => &$module::$ty,)*
                }
            }
        }
    };
}

registry! {
    EarthRate => earth_rate::EarthRate,
    ThermalLag => thermal_lag::ThermalLag,
    TemperatureQuadratic => temperature_quadratic::TemperatureQuadratic,
    ScaleFactorTemperature => scale_factor_temperature::ScaleFactorTemperature,
    ThermalHysteresis => thermal_hysteresis::ThermalHysteresis,
    OncePerRevolution => once_per_revolution::OncePerRevolution,
    TimeOffset => time_offset::TimeOffset,
    WarmUp => warm_up::WarmUp,
    BiasStep => bias_step::BiasStep,
    RateSquared => rate_squared::RateSquared,
    PeriodicBias => periodic_bias::PeriodicBias,
    RateRipple => rate_ripple::RateRipple,
    AngleHarmonic => angle_harmonic::AngleHarmonic,
    BiasDrift => bias_drift::BiasDrift,
    ScaleFactorAsymmetry => scale_factor_asymmetry::ScaleFactorAsymmetry,
}

impl EffectId {
    /// The stable id (snake case).
    pub fn key(self) -> &'static str {
        self.effect().key()
    }

    /// The effect with id `key`.
    pub fn from_key(key: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.key() == key)
    }

    /// One line of physics.
    pub fn description(self) -> &'static str {
        self.effect().description()
    }

    /// Whose physics it is.
    pub fn owner(self) -> Owner {
        self.effect().owner()
    }

    /// Its parameters.
    pub fn params(self) -> &'static [Param] {
        self.effect().params()
    }

    /// Its parameters' names, in order (empty for an effect that is on or off).
    pub fn param_names(self) -> Vec<&'static str> {
        self.params().iter().map(|p| p.name).collect()
    }

    /// Whether parameter `name` must be greater than zero (the rest must only be finite).
    pub fn param_must_be_positive(self, name: &str) -> bool {
        self.params().iter().any(|p| p.name == name && p.range == Range::Positive)
    }

    /// How many regressors it has ([`Effect::linear_count`]).
    pub fn linear_count(self) -> usize {
        self.effect().linear_count()
    }

    /// Its regressors for one sample ([`Effect::regressors`]).
    pub fn regressors(self, s: &EffectSample, p: f64, out: &mut [f64]) {
        self.effect().regressors(s, p, out);
    }

    /// The effects it can be confused with: those its [`Effect::rivals`] name and those that
    /// name it (a rivalry is declared once, by either effect), in library order.
    pub fn rival_effects(self) -> Vec<EffectId> {
        let names =
            |a: EffectId, b: EffectId| a.effect().rivals().iter().any(|r| r.with == b.key());
        Self::ALL.into_iter().filter(|&o| o != self && (names(self, o) || names(o, self))).collect()
    }

    /// The declared rivalry of this effect with term `with` (an effect's or a nominal
    /// parameter's key), by either side: when the two cannot be told apart, in words.
    pub fn rivalry_with(self, with: &str) -> Option<&'static str> {
        let own = self.effect().rivals().iter().find(|r| r.with == with).map(|r| r.when);
        own.or_else(|| {
            let other = EffectId::from_key(with)?;
            other.effect().rivals().iter().find(|r| r.with == self.key()).map(|r| r.when)
        })
    }
}

/// What the additive effects depend on, for one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EffectSample {
    /// End of the sample interval, s since power-on.
    pub t_s: f64,
    /// Input rate along the sensing axis (table plus Earth), rad/s.
    pub input_rad_s: f64,
    /// The table's rate along the sensing axis (no Earth), rad/s.
    pub table_rate_rad_s: f64,
    /// `T − T0` of the temperature that drives the bias, °C.
    pub temp_minus_ref_c: f64,
    /// Table angle at the middle of the sample interval, rad.
    pub angle_mid_rad: f64,
    /// Hysteresis state (see [`HysteresisState`]): +1, −1 or 0.
    pub hysteresis: f64,
    /// Earth's rate along the sensing axis, rad/s.
    pub earth_rad_s: f64,
}

/// Heating/cooling memory: +1 once dT/dt rose above the threshold, −1 once it fell below minus
/// the threshold, unchanged in between (0 before either).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HysteresisState {
    threshold_c_s: f64,
    state: f64,
}

impl HysteresisState {
    /// A virgin state with threshold `threshold_c_s` (°C/s, > 0).
    pub fn new(threshold_c_s: f64) -> Self {
        Self { threshold_c_s: threshold_c_s.abs(), state: 0.0 }
    }

    /// Update with the rate of temperature change now (°C/s); returns the state.
    #[inline]
    pub fn update(&mut self, rate_c_s: f64) -> f64 {
        if rate_c_s > self.threshold_c_s {
            self.state = 1.0;
        } else if rate_c_s < -self.threshold_c_s {
            self.state = -1.0;
        }
        self.state
    }

    /// The state over a whole series of rates.
    pub fn series(threshold_c_s: f64, rates_c_s: &[f64]) -> Vec<f64> {
        let mut h = Self::new(threshold_c_s);
        rates_c_s.iter().map(|&r| h.update(r)).collect()
    }
}

/// The temperature series `temp_c` at times `time_s` through a first-order lag of `tau_s`,
/// linear between samples, starting in equilibrium with the first value.
pub fn lag_temperature(time_s: &[f64], temp_c: &[f64], tau_s: f64) -> Vec<f64> {
    let Some(&first) = temp_c.first() else { return Vec::new() };
    let mut lag = FirstOrderLag::new(tau_s, first);
    let mut out = Vec::with_capacity(temp_c.len());
    out.push(first);
    let mut memo = (f64::NAN, 0.0);
    for k in 1..temp_c.len() {
        let dt = time_s[k] - time_s[k - 1];
        out.push(lag.step_linear_memo(temp_c[k - 1], temp_c[k], dt, &mut memo));
    }
    out
}

/// `a·sin x + b·cos x` as the regressors `sin x`, `cos x` of angle `x`.
fn sin_cos(x: f64, out: &mut [f64]) {
    let (sin, cos) = x.sin_cos();
    out[0] = sin;
    out[1] = cos;
}

#[cfg(test)]
mod tests;
