//! What an effect declares about itself beyond its formula: whose physics it is, its
//! parameters, how the diagnosis builds its regressors and searches its non-linear parameter,
//! the shapes that test it and the effects it can be confused with. Plain data: the simulators
//! and the analysis each implement every variant once, so an effect made of known parts is one
//! file ([`super::Effect`]).

/// Whose physics an effect is: what travels with a gyro model from one recording to another.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Owner {
    /// The gyro's own behaviour: part of its model wherever it is tested.
    Gyro,
    /// Earth's rotation: every gyro senses it, so whether a model includes it travels with the
    /// model; its size is the site's of the recording at hand.
    Site,
    /// The rate table's own motion (its rate ripple): observed in each recording's table
    /// channel or stated by the recording itself, never carried by a gyro model.
    Table,
    /// The recording's clocks (the gyro's time tags against the table's): a property of one
    /// bench's acquisition, never of the gyro.
    Clock,
}

impl Owner {
    /// Whether an effect of this owner travels with a gyro model to another recording.
    pub fn travels_with_model(self) -> bool {
        matches!(self, Owner::Gyro | Owner::Site)
    }

    /// The owner in words ("the gyro", "the table" …).
    pub fn words(self) -> &'static str {
        match self {
            Owner::Gyro => "the gyro",
            Owner::Site => "the site (Earth's rotation)",
            Owner::Table => "the rate table",
            Owner::Clock => "the recording's clocks",
        }
    }
}

/// The values a parameter may take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Range {
    /// Any finite number.
    Finite,
    /// A finite number greater than zero.
    Positive,
}

/// What a parameter is to the effect's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Role {
    /// The coefficient of regressor `k` ([`super::Effect::regressors`]).
    Coefficient(usize),
    /// The amplitude `a` of `a·sin(x + φ)`: the coefficients of `sin x` and `cos x` are
    /// `a·cos φ` and `a·sin φ`.
    Amplitude,
    /// The phase `φ` of `a·sin(x + φ)`, rad.
    Phase,
    /// The non-linear parameter (a time constant, an instant, a period, cycles per
    /// revolution): the `p` of [`super::Effect::regressors`], searched over the effect's
    /// [`Grid`] by the diagnosis.
    Grid,
    /// A setting the diagnosis does not fit; a diagnosed effect takes this value.
    Setting(f64),
}

/// One parameter of an effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Param {
    /// Its name, SI with the unit in it (`time_constant_s`): scenario tables, model files and
    /// `bench.gyro_model` metadata keys (`effect.<key>.<name>`).
    pub name: &'static str,
    /// Its unit, in words (`s`, `rad/s`, `1/°C`).
    pub unit: &'static str,
    /// The values it may take.
    pub range: Range,
    /// What it is to the output.
    pub role: Role,
}

impl Param {
    /// A parameter that may be any finite number.
    pub const fn finite(name: &'static str, unit: &'static str, role: Role) -> Self {
        Self { name, unit, range: Range::Finite, role }
    }

    /// A parameter that must be greater than zero.
    pub const fn positive(name: &'static str, unit: &'static str, role: Role) -> Self {
        Self { name, unit, range: Range::Positive, role }
    }

    /// A valid value of it, for examples and for tests that cover every effect (an effect
    /// added later included): a phase 0.3, a positive one 123.5 (a time, a period, a number of
    /// cycles), any other 2.5e-8 (a size in SI units).
    pub fn example(&self) -> f64 {
        match (self.role, self.range) {
            (Role::Phase, _) => 0.3,
            (_, Range::Positive) => 123.5,
            _ => 2.5e-8,
        }
    }
}

/// How the diagnosis builds an effect's regressors over a recording's bins (each variant is
/// implemented once, in `bench_analysis::diagnose`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Columns {
    /// The bin means of [`super::Effect::regressors`] over the gyro's samples.
    PerSample,
    /// [`super::Effect::regressors`] at each bin's start time (a step: exactly 0 before its
    /// bin, 1 from there on).
    AtBinStart,
    /// `sin(k·θ)`, `cos(k·θ)` of the table angle θ, at `k` of [`Order`].
    Angle(Order),
    /// The table's rate ripple `Ω_t·sin(k·θ)`, `Ω_t·cos(k·θ)` at the grid's `k`.
    Ripple,
    /// `sin(2π·t/P)`, `cos(2π·t/P)` at the grid's period `P`.
    Periodic,
    /// Earth's rate: a constant the bias column spans, tested as the bias correction being
    /// Earth's rate (through the scale factor, as any input).
    EarthRate,
    /// The model's thermal terms driven through a first-order lag of the grid's time
    /// constant, less the same terms without it.
    ThermalLag,
    /// The table's motion compared at the wrong instant: `−(1 + sf)·dΩ/dt` per bin.
    TimeOffset,
}

/// The angular order of an [`Columns::Angle`] regressor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Once per revolution.
    One,
    /// The grid's value.
    Grid,
}

/// The grid over which the diagnosis searches an effect's non-linear parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Grid {
    /// No non-linear parameter.
    None,
    /// These time constants, s (continuous: σ by linearisation).
    TimeConstants(&'static [f64]),
    /// Bin starts, at most `positions` of them, 2 % of the bins kept clear at either end.
    BinStarts {
        /// Most positions.
        positions: usize,
    },
    /// Periods evenly in frequency, half a cycle over the run apart, from `min_cycles` cycles
    /// over the run down to `min_s` (and never under four bins), at most `most` of them, the
    /// short-period end dropped first; longest first (continuous: σ by linearisation).
    Periods {
        /// Shortest period, s.
        min_s: f64,
        /// Fewest cycles over the run.
        min_cycles: f64,
        /// Most periods.
        most: usize,
    },
    /// Whole cycles per revolution `from..=to`.
    CyclesPerRev {
        /// First.
        from: u32,
        /// Last.
        to: u32,
    },
    /// Angle harmonics from 2 up to the highest the bins resolve.
    Harmonics,
}

impl Grid {
    /// Whether the parameter is continuous (its σ by linearisation), rather than a grid of
    /// discrete values (its σ from the Wald profile).
    pub fn is_continuous(self) -> bool {
        matches!(self, Grid::TimeConstants(_) | Grid::Periods { .. })
    }
}

/// How the diagnosis refines a grid value below the grid's spacing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refinement {
    /// Not refined.
    None,
    /// In the search: every bin start between the best grid value's neighbours.
    BinStarts,
    /// In the search: `each_side` values towards each neighbour, evenly in frequency.
    EvenInFrequency {
        /// Values on each side.
        each_side: usize,
    },
    /// In the final fit only: `each_side` values towards each neighbour, evenly in the
    /// logarithm.
    FinalEvenInLog {
        /// Values on each side.
        each_side: usize,
    },
}

/// The shapes that test an accepted effect: near relatives that must not be left in its
/// residual and must not move its size (`bench_analysis::diagnose::family`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// None.
    None,
    /// The other angle harmonics 1..K and the table's rate ripple at the effect's order.
    AngleHarmonics,
    /// The gyro's angle harmonic at the ripple's order, the ripple at N ± 1 and 2N.
    RippleOrders,
    /// The period's harmonics P/2 … and twice the period (the cycle's shape).
    PeriodShape,
    /// Decays with τ/3 and 3τ, a linear drift.
    Decay,
    /// A second step at every grid instant, a drift from the step.
    Step,
    /// The other temperature shapes ([`Family::Temperature`] effects with per-sample
    /// regressors, named by their [`super::Effect::shape`]), (T − T0)³, dT/dt while heating,
    /// and for a lag the lag at τ/2 and 2τ.
    Temperature,
    /// |Ω_in| and Ω_in·(T − T0)².
    RateShape,
    /// |dΩ/dt| and dΩ/dt while speeding up.
    RateChange,
}

/// A term an effect can be confused with on some procedures: another effect of the library
/// or a nominal parameter (its key), and on what kind of run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rival {
    /// The other term's key: an effect's or a nominal parameter's (`bias`, `temp_rate_coeff`).
    pub with: &'static str,
    /// When the two cannot be told apart, in words ("on a run at one |rate|").
    pub when: &'static str,
}

/// The run that separates an effect from its rivals (`bench diagnose --suggest-scenario`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Procedure {
    /// Chamber ramps at two rates, each followed by a hold, in both directions of rotation.
    ThermalRamps,
    /// Full revolutions in both directions at two table rates at one temperature.
    TurnsAtTwoRates,
    /// A longer run: time is the only axis it lives on.
    LongerRun,
    /// The sensing axis turned over (down instead of up): Earth's rate changes sign, a bias
    /// does not.
    AxisTurnedOver,
}

impl Procedure {
    /// The run in words, for a diagnosis that names two rivals ("the run that separates
    /// them: …").
    pub fn words(self) -> &'static str {
        match self {
            Procedure::ThermalRamps => {
                "chamber ramps at two rates (0.5 and 2 °C/min), each followed by a hold, in both \
                 directions of rotation"
            }
            Procedure::TurnsAtTwoRates => {
                "full revolutions in both directions at two table rates (10 and 30 °/min), with \
                 rests at zero rate"
            }
            Procedure::LongerRun => "a longer run (time is the only axis these live on)",
            Procedure::AxisTurnedOver => {
                "the sensing axis turned over (Earth's rate changes sign, a bias does not)"
            }
        }
    }
}

/// A parameter of a diagnosed effect as the diagnosis reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reported {
    /// The fitted coefficient of regressor `index`.
    Linear {
        /// Name.
        name: &'static str,
        /// Unit.
        unit: &'static str,
        /// Which coefficient.
        index: usize,
    },
    /// The amplitude of the two sinusoid coefficients (`a·sin x + b·cos x` as `A·sin(x + φ)`).
    Amplitude {
        /// Name.
        name: &'static str,
        /// Unit.
        unit: &'static str,
    },
    /// The phase of the two sinusoid coefficients, rad.
    Phase,
    /// The grid value (σ from the search's Wald profile, or by linearisation).
    GridValue {
        /// Name.
        name: &'static str,
        /// Unit.
        unit: &'static str,
    },
    /// A fixed value of the effect's form (once per revolution's one cycle per revolution).
    Fixed {
        /// Name.
        name: &'static str,
        /// Value.
        value: f64,
        /// Unit.
        unit: &'static str,
    },
    /// Earth's rate as the bias correction found, rad/s.
    EarthRate,
    /// The latitude that rate puts the bench at, degrees.
    Latitude,
}

impl Reported {
    /// The reported name.
    pub fn name(self) -> &'static str {
        match self {
            Reported::Linear { name, .. }
            | Reported::Amplitude { name, .. }
            | Reported::GridValue { name, .. }
            | Reported::Fixed { name, .. } => name,
            Reported::Phase => "phase_rad",
            Reported::EarthRate => "rate_rad_s",
            Reported::Latitude => "latitude_deg",
        }
    }

    /// The unit.
    pub fn unit(self) -> &'static str {
        match self {
            Reported::Linear { unit, .. }
            | Reported::Amplitude { unit, .. }
            | Reported::GridValue { unit, .. }
            | Reported::Fixed { unit, .. } => unit,
            Reported::Phase => "rad",
            Reported::EarthRate => "rad/s",
            Reported::Latitude => "deg",
        }
    }

    /// Whether it is the grid's value (or its fixed stand-in), not a fitted coefficient.
    pub fn is_grid(self) -> bool {
        matches!(self, Reported::GridValue { .. } | Reported::Fixed { .. })
    }

    /// Whether it is the effect's size (a coefficient or an amplitude): the first such is the
    /// one an identifiability bound is given for.
    pub fn is_size(self) -> bool {
        matches!(self, Reported::Linear { .. } | Reported::Amplitude { .. } | Reported::EarthRate)
    }
}
