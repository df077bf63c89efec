//! The residual check of an accepted effect: is what it leaves free of structure of its own
//! kind, and does its fitted size hold when that kind is freed?
//!
//! A term that fits well is not yet the right term: over 120° arcs `sin θ` takes up most of a
//! `sin 2θ`, and a sinusoid takes up a sawtooth's fundamental. Each effect therefore has a
//! **family** of near relatives ([`members`]):
//!
//! | accepted | family |
//! | --- | --- |
//! | `once_per_revolution`, `angle_harmonic` k | the other angle harmonics 1..K, and the table's rate ripple at k (∝ rate) |
//! | `rate_ripple` N | the gyro's angle harmonic at N (independent of rate), ripple at N ± 1, 2N |
//! | `periodic_bias` P | periods P/2 … P/16 (down to four bins: a shape that is not a sinusoid) and 2P |
//! | `warm_up` τ | decays with τ/3 and 3τ, a linear drift |
//! | `bias_step` t_s | a second step (every grid instant), a ramp from t_s |
//! | temperature terms | (T − T0)², (T − T0)³, heating vs cooling, dT/dt while heating only, (T − T0)·Ω, the lag at τ/2 and 2τ, a kink in k_t at the recording's temperature deciles ([`super::hinge`]) |
//! | `rate_squared`, `scale_factor_asymmetry` | the other's shape (\|Ω\| or Ω²), Ω·(T − T0)² |
//! | `time_offset` | \|dΩ/dt\| (a bias at rate changes), dΩ/dt by direction |
//!
//! With the effect in the model each member is tested (Wald, noise model) at the effect's
//! share of the family-wise α, Bonferroni over the members; then the strongest member is freed
//! and the effect refitted: its size must not move by more than 3σ. An effect failing either
//! is not named: it is reported as unexplained structure, with the member that shows what the
//! effect does not explain, and its columns and the significant members stay in the design as
//! nuisance terms so that no other effect is named for what they hold.

use bench_physics::allan::{chi2_quantile, normal_quantile};
use bench_physics::effects::{Columns, EffectId, Family, Order};
use bench_physics::GyroModel;

use super::columns::Kind;
use super::fit::{Projector, TermTest};
use super::noise::BinNoise;
use super::series::bin_mean;
use super::{candidate_columns, grid, Prepared};

/// Most harmonics of a periodic bias's period in its family.
const PERIODIC_HARMONICS: u32 = 16;

/// Most family members kept as nuisance terms for an effect that fails its check.
const NUISANCE_MAX: usize = 16;

/// A near relative of an effect, as regressors.
#[derive(Debug, Clone)]
pub(super) struct Member {
    /// What it is, precisely ("table angle, 2 cycles/rev").
    pub name: String,
    /// Its columns (bin means); two for a sinusoid (sin, cos).
    pub cols: Vec<Vec<f64>>,
    /// Whether it is a rate-independent harmonic of the table angle.
    pub angle_harmonic: bool,
    /// How many grid values it is one of (a hinge's knots, [`super::hinge`]): the grid counts
    /// as one member of the family, each of its values tested at the member's share of the
    /// level over `looks` (its look-elsewhere). 1 for a member without a grid.
    pub looks: usize,
    /// Whether it is a kink in k_t ([`super::hinge`]): an effect must be told apart from it.
    pub kink: bool,
}

impl Member {
    /// A member without a grid, neither an angle harmonic nor a kink.
    fn plain(name: String, cols: Vec<Vec<f64>>) -> Self {
        Self { name, cols, angle_harmonic: false, looks: 1, kink: false }
    }
}

/// A member of the family found in the residual.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyMember {
    /// What it is ("table angle, 2 cycles/rev").
    pub name: String,
    /// Wald statistic with the effect in the model.
    pub wald: f64,
    /// The threshold it had to stay below.
    pub threshold: f64,
    /// Its fitted size: a sinusoid's amplitude, else the RMS of its contribution, rad/s.
    pub size_rad_s: f64,
}

/// The residual check of one effect ([module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyCheck {
    /// What the family is, in words.
    pub family: String,
    /// Members tested.
    pub members: usize,
    /// The strongest member (largest Wald over its threshold), if any was testable.
    pub strongest: Option<FamilyMember>,
    /// Change of the effect's fitted size when the strongest member is freed, in σ of the
    /// freed fit.
    pub size_change_z: f64,
    /// The change beyond which the size is not stable: the two-sided normal quantile at the
    /// strongest member's share of the level, the level its Wald is tested at (infinite with no
    /// member).
    pub size_change_limit: f64,
    /// Whether the effect passes: no member significant and its size stable.
    pub passed: bool,
}

impl FamilyCheck {
    /// Why the effect was not named, for people (only meaningful when it failed).
    pub fn reason(&self) -> String {
        match &self.strongest {
            Some(m) if m.wald > m.threshold => format!(
                "its residual still holds {} ({}, Wald {:.1} > {:.1})",
                m.name,
                deg_h(m.size_rad_s),
                m.wald,
                m.threshold
            ),
            Some(m) => {
                format!(
                    "its size moves by {:.1}σ (> {:.2}) when {} is freed",
                    self.size_change_z, self.size_change_limit, m.name
                )
            }
            None => "its family could not be tested".into(),
        }
    }
}

/// A rate for people in sentences: °/h to three significant digits.
pub(super) fn deg_h(rate_rad_s: f64) -> String {
    format!("{:.3} °/h", rate_rad_s / bench_physics::units::DEG_PER_H)
}

/// How a per-revolution term depends on the table's rate: the gyro's (independent of rate) or
/// the table's rate ripple (∝ rate), each tested with the other in the model.
#[derive(Debug, Clone, PartialEq)]
pub struct RateDependence {
    /// Cycles per revolution.
    pub cycles_per_rev: f64,
    /// Wald of the rate-independent (gyro) term with the ripple in the model.
    pub gyro_wald: f64,
    /// Wald of the rate-proportional (ripple) term with the gyro term in the model.
    pub ripple_wald: f64,
    /// χ²₂ threshold both are judged against.
    pub threshold: f64,
}

impl RateDependence {
    /// `gyro`, `table`, `both` or `undecided`.
    pub fn verdict(&self) -> &'static str {
        match (self.gyro_wald > self.threshold, self.ripple_wald > self.threshold) {
            (true, false) => "gyro",
            (false, true) => "table",
            (true, true) => "both",
            (false, false) => "undecided",
        }
    }
}

/// Most angle harmonics searched: a bin must not average a harmonic away (its angle span at
/// most a quarter of the harmonic's period: attenuation ≤ 10 %), and never beyond 64.
pub(super) fn harmonic_max(prep: &Prepared) -> u32 {
    let span = prep
        .bins
        .iter()
        .filter(|b| !b.transition && b.table_rate_rad_s.abs() > 1e-6)
        .map(|b| b.table_rate_rad_s.abs() * b.span_s())
        .fold(0.0f64, f64::max);
    if span <= 0.0 {
        return 1;
    }
    let k = (std::f64::consts::FRAC_PI_2 / span).floor();
    k.clamp(1.0, 64.0) as u32
}

fn sin_cos(prep: &Prepared, k: f64) -> Vec<Vec<f64>> {
    prep.sinusoid(Kind::Angle, k)
}

fn ripple(prep: &Prepared, k: f64) -> Vec<Vec<f64>> {
    prep.sinusoid(Kind::Ripple, k)
}

fn periodic(prep: &Prepared, period_s: f64) -> Vec<Vec<f64>> {
    prep.sinusoid(Kind::Periodic, period_s)
}

fn one(prep: &Prepared, f: impl Fn(usize) -> f64) -> Vec<Vec<f64>> {
    vec![bin_mean(&prep.bins, &prep.native.dt, f)]
}

/// The family of effect `id` at grid value `p` ([module docs](self)): its description and
/// members.
pub(super) fn members(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    model: &GyroModel,
) -> (String, Vec<Member>) {
    let m = Member::plain;
    let nat = &prep.native;
    let t0 = prep.t0;
    let dtemp = |i: usize| prep.temp[i] - t0;
    let input = |i: usize| prep.axis * nat.table_rate_rad_s[i] + prep.earth_in;
    match id.effect().family() {
        Family::AngleHarmonics => {
            let k = if id.effect().columns() == Columns::Angle(Order::One) { 1.0 } else { p };
            let kmax = harmonic_max(prep);
            let mut v: Vec<Member> = (1..=kmax)
                .map(f64::from)
                .filter(|&j| j != k)
                .map(|j| Member {
                    name: format!("table angle, {j} cycles/rev"),
                    cols: sin_cos(prep, j),
                    angle_harmonic: true,
                    looks: 1,
                    kink: false,
                })
                .collect();
            v.push(m(format!("table rate ripple, {k} cycles/rev (∝ rate)"), ripple(prep, k)));
            (format!("angle harmonics 1..{kmax} and the table's rate ripple at {k}"), v)
        }
        Family::RippleOrders => {
            let mut v = vec![m(
                format!("table angle, {p} cycles/rev (independent of rate)"),
                sin_cos(prep, p),
            )];
            for j in [p - 1.0, p + 1.0, 2.0 * p] {
                if j >= 1.0 {
                    v.push(m(format!("table rate ripple, {j} cycles/rev"), ripple(prep, j)));
                }
            }
            (
                format!(
                    "the gyro's angle harmonic at {p}, ripple at {}, {}, {}",
                    p - 1.0,
                    p + 1.0,
                    2.0 * p
                ),
                v,
            )
        }
        Family::PeriodShape => {
            // The cycle's harmonics down to four bins a period (a sawtooth has them all), and
            // twice the period.
            let bin_s = prep.bins.first().map_or(10.0, |b| b.span_s());
            let hmax = ((p / (4.0 * bin_s)).floor() as u32).clamp(2, PERIODIC_HARMONICS);
            let mut v: Vec<Member> = (2..=hmax)
                .map(|h| {
                    let q = p / f64::from(h);
                    m(format!("time, period {q:.0} s (P/{h})"), periodic(prep, q))
                })
                .collect();
            v.push(m(format!("time, period {:.0} s (2P)", 2.0 * p), periodic(prep, 2.0 * p)));
            (format!("the harmonics P/2..P/{hmax} and 2P of a {p:.0} s cycle (its shape)"), v)
        }
        Family::Decay => {
            let tm = nat.t.iter().sum::<f64>() / nat.t.len().max(1) as f64;
            let v = vec![
                m(
                    format!("a decay with τ = {:.0} s", p / 3.0),
                    one(prep, |i| (-nat.t[i] * 3.0 / p).exp()),
                ),
                m(
                    format!("a decay with τ = {:.0} s", 3.0 * p),
                    one(prep, |i| (-nat.t[i] / (3.0 * p)).exp()),
                ),
                m("a linear drift in time".into(), one(prep, |i| nat.t[i] - tm)),
            ];
            (format!("decays at τ/3 and 3τ of {p:.0} s, a drift"), v)
        }
        Family::Step => {
            let mut v: Vec<Member> = grid(prep, id)
                .into_iter()
                .filter(|&q| (q - p).abs() > 2.0 * prep.bins.first().map_or(10.0, |b| b.span_s()))
                .map(|q| {
                    m(
                        format!("a second bias step at {q:.0} s"),
                        vec![prep
                            .bins
                            .iter()
                            .map(|b| f64::from(u8::from(b.start_s >= q)))
                            .collect()],
                    )
                })
                .collect();
            v.push(m(format!("a drift from {p:.0} s"), one(prep, |i| (nat.t[i] - p).max(0.0))));
            ("a second step, a drift after the step".into(), v)
        }
        Family::Temperature => temperature_members(prep, id, p, model),
        Family::RateShape => {
            // The library's other rate shapes, by their own regressors (|Ω_in| for rate², Ω_in²
            // for the asymmetry), and Ω·(T − T0)².
            let mut v: Vec<Member> = EffectId::ALL
                .into_iter()
                .filter(|&o| o != id && o.effect().family() == Family::RateShape)
                .filter(|&o| o.effect().columns() == Columns::PerSample)
                .map(|o| m(o.effect().shape().into(), candidate_columns(prep, o, f64::NAN, model)))
                .collect();
            v.push(m("Ω_in·(T − T0)²".into(), one(prep, |i| input(i) * dtemp(i).powi(2))));
            ("|Ω|, Ω², Ω·(T − T0)²".into(), v)
        }
        Family::RateChange => {
            let bins = &prep.bins;
            let v = vec![
                m(
                    "|dΩ/dt| (a bias at every rate change)".into(),
                    vec![bins.iter().map(|b| b.table_accel_rad_s2.abs()).collect()],
                ),
                m(
                    "dΩ/dt while speeding up only".into(),
                    vec![bins
                        .iter()
                        .map(|b| {
                            let speeding = b.table_accel_rad_s2 * b.table_rate_rad_s > 0.0;
                            if speeding {
                                b.table_accel_rad_s2
                            } else {
                                0.0
                            }
                        })
                        .collect()],
                ),
            ];
            ("|dΩ/dt|, dΩ/dt while speeding up".into(), v)
        }
        Family::None => (String::new(), Vec::new()),
    }
}

/// [`members`] of a temperature effect: the library's other temperature shapes, (T − T0)³,
/// dT/dt while heating, and for a lag the lag at τ/2 and 2τ.
fn temperature_members(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    model: &GyroModel,
) -> (String, Vec<Member>) {
    let m = Member::plain;
    let dtemp = |i: usize| prep.temp[i] - prep.t0;
    let mut v = Vec::new();
    // The other temperature shapes of the library, by their own regressors.
    let shapes = EffectId::ALL.into_iter().filter(|&o| {
        o.effect().family() == Family::Temperature && o.effect().columns() == Columns::PerSample
    });
    for other in shapes.filter(|&o| o != id) {
        v.push(m(other.effect().shape().into(), candidate_columns(prep, other, f64::NAN, model)));
    }
    v.push(m("(T − T0)³".into(), one(prep, |i| dtemp(i).powi(3))));
    v.push(m("dT/dt while heating only".into(), one(prep, |i| prep.temp_rate[i].max(0.0))));
    if id.effect().columns() == Columns::ThermalLag {
        for q in [0.5 * p, 2.0 * p] {
            v.push(m(
                format!("the thermal terms through a {q:.0} s lag"),
                candidate_columns(prep, id, q, model),
            ));
        }
    }
    // A kink in k_t (outside the library), at knots on the recording's temperatures.
    v.extend(super::hinge::members(prep));
    ("(T − T0)², (T − T0)³, heating vs cooling, dT/dt while heating, T·Ω, a kink in k_t".into(), v)
}

/// Fitted size of a member in rad/s: a sinusoid's amplitude, else its contribution's RMS.
fn member_size(cols: &[Vec<f64>], t: &TermTest) -> f64 {
    let n = cols.first().map_or(0, Vec::len);
    let c: Vec<f64> =
        (0..n).map(|i| cols.iter().zip(&t.theta).map(|(col, th)| col[i] * th).sum()).collect();
    let rms = (c.iter().map(|x| x * x).sum::<f64>() / n.max(1) as f64).sqrt();
    if cols.len() == 2 {
        std::f64::consts::SQRT_2 * rms
    } else {
        rms
    }
}

/// The outcome of [`gate`]: the check, and the members to keep as nuisance terms when it
/// failed (the significant ones, strongest first).
pub(super) struct Gate {
    pub check: FamilyCheck,
    pub nuisance: Vec<Member>,
}

/// Check effect `id` (grid value `p`, columns `cols`) against its family with the rest of the
/// model `others` (design without the effect) in; `base` is the design without any effect (the
/// parameters and earlier nuisance terms); `level` is the effect's share of α.
#[allow(clippy::too_many_arguments)]
pub(super) fn gate(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    cols: &[Vec<f64>],
    others: &[Vec<f64>],
    base: &[Vec<f64>],
    y: &[f64],
    noise: &BinNoise,
    level: f64,
    model: &GyroModel,
) -> Option<Gate> {
    let (family, members) = members(prep, id, p, model);
    let all: Vec<usize> = (0..prep.bins.len()).collect();
    if members.is_empty() {
        let check = FamilyCheck {
            family,
            members: 0,
            strongest: None,
            size_change_z: 0.0,
            size_change_limit: f64::INFINITY,
            passed: true,
        };
        return Some(Gate { check, nuisance: Vec::new() });
    }
    let mut with: Vec<Vec<f64>> = others.to_vec();
    with.extend(cols.iter().cloned());
    let p_with = Projector::new(&with, &all).ok()?;
    // Members with a grid count once ([`Member::looks`]); each value at its share over the grid.
    let m: f64 = members.iter().map(|x| 1.0 / x.looks.max(1) as f64).sum();
    let thr_of =
        |x: &Member| chi2_quantile(1.0 - level / (m * x.looks.max(1) as f64), x.cols.len() as f64);
    // Each member: Wald with the effect in, its threshold at level / members.
    let mut tested: Vec<(usize, FamilyMember)> = Vec::new();
    for (j, mem) in members.iter().enumerate() {
        let Some(t) = p_with.test(&mem.cols, y, noise) else { continue };
        let thr = thr_of(mem);
        tested.push((
            j,
            FamilyMember {
                name: mem.name.clone(),
                wald: t.wald,
                threshold: thr,
                size_rad_s: member_size(&mem.cols, &t),
            },
        ));
    }
    tested.sort_by(|a, b| (b.1.wald / b.1.threshold).total_cmp(&(a.1.wald / a.1.threshold)));
    let mut strongest = tested.first().cloned();
    // Stability: the effect refitted with the strongest member freed.
    let p_o = Projector::new(others, &all).ok()?;
    // The size's change is the freed member's coefficient seen through the effect: under the
    // null its z is at most the member's own (|Δθ|/σ_f ≤ |γ|/σ_γ), so it is judged at the
    // member's level, two-sided. A fixed 3σ asked more of it than of the member's Wald and
    // named a lab's time offset unexplained at 3.3σ where the member's limit is 3.57.
    let mut size_change_z = 0.0;
    let mut size_change_limit = f64::INFINITY;
    if let Some((j, _)) = &strongest {
        let looks = members[*j].looks.max(1) as f64;
        size_change_limit = normal_quantile(1.0 - level / (2.0 * m * looks));
        let mut freed = others.to_vec();
        freed.extend(members[*j].cols.iter().cloned());
        let p_f = Projector::new(&freed, &all).ok()?;
        if let (Some(t0), Some(tf)) = (p_o.test(cols, y, noise), p_f.test(cols, y, noise)) {
            let (s0, _) = t0.size();
            let (sf, sigf) = tf.size();
            if sigf > 0.0 {
                size_change_z = (sf - s0).abs() / sigf;
            }
        }
    }
    let significant = strongest.as_ref().is_some_and(|(_, s)| s.wald > s.threshold);
    // Told apart from each relative: with member j in the model the effect must stay
    // significant (one test at `level`) whenever j alone explains the data too (its own
    // threshold); else the data cannot say which of the two it is.
    let mut rival: Option<(usize, f64, f64)> = None;
    let thr_effect = chi2_quantile(1.0 - level, cols.len() as f64);
    // Only between the gyro's angle harmonics: other families' members are the same term at
    // another grid value (a lag's τ/2) or shapes one run may not separate by design (rate² and
    // |rate| at one speed), which identifiability states instead.
    // A kink in k_t is outside the library: a temperature effect must be told from it too,
    // unless the kink is significant beside the effect (then that is what is reported). As for
    // a harmonic, an effect that keeps nothing beside a knot that alone explains the data is
    // not told from it: which of the two explains more (each over its own threshold) is a
    // guess where neither holds beside the other, and named a kink near a range's end a
    // quadratic.
    let harmonic = matches!(id.effect().columns(), Columns::Angle(_));
    let beside_significant = |j: usize| tested.iter().any(|(i, t)| *i == j && t.wald > t.threshold);
    let rivalling = |(j, x): &(usize, &Member)| {
        (harmonic && x.angle_harmonic) || (x.kink && !beside_significant(*j))
    };
    for (j, mem) in members.iter().enumerate().filter(rivalling) {
        let thr_j = thr_of(mem);
        let Some(alone) = p_o.test(&mem.cols, y, noise) else { continue };
        if alone.wald <= thr_j {
            continue;
        }
        let mut with_j = others.to_vec();
        with_j.extend(mem.cols.iter().cloned());
        let Ok(p_j) = Projector::new(&with_j, &all) else { continue };
        let w = p_j.test(cols, y, noise).map_or(0.0, |t| t.wald);
        // A harmonic: the one beside which the effect keeps least; a kink: the knot that
        // explains the data best.
        let score = if mem.kink { alone.wald } else { -w };
        if w <= thr_effect && rival.is_none_or(|(_, _, best)| score > best) {
            rival = Some((j, w, score));
        }
    }
    let rival = rival.map(|(j, w, _)| (j, w));
    if let Some((j, w)) = rival {
        // The rival is the member to report.
        let thr = thr_of(&members[j]);
        let alone = p_o.test(&members[j].cols, y, noise);
        strongest = Some((
            j,
            FamilyMember {
                name: format!(
                    "{} (not told apart: the effect's Wald with it in is {w:.1})",
                    members[j].name
                ),
                wald: alone.as_ref().map_or(0.0, |t| t.wald),
                threshold: thr,
                size_rad_s: alone.as_ref().map_or(0.0, |t| member_size(&members[j].cols, t)),
            },
        ));
    }
    let passed = !significant && rival.is_none() && size_change_z <= size_change_limit;
    // Nuisance when it fails: the significant members, added greedily (each tested with the
    // effect, the earlier ones and `base` in: not the other effects, which may hold part of
    // this structure only because it was left out).
    let mut nuisance = Vec::new();
    if !passed {
        let mut design = base.to_vec();
        design.extend(cols.iter().cloned());
        let mut left: Vec<usize> = (0..members.len()).collect();
        // A kink not told apart from the effect holds the structure as well as it does: kept
        // beside it.
        if let Some((j, _)) = rival.filter(|(j, _)| members[*j].kink) {
            design.extend(members[j].cols.iter().cloned());
            nuisance.push(members[j].clone());
            left.retain(|&x| x != j);
        }
        for _ in 0..members.len().min(NUISANCE_MAX) {
            let Ok(pd) = Projector::new(&design, &all) else { break };
            let best = left
                .iter()
                .filter_map(|&j| {
                    let t = pd.test(&members[j].cols, y, noise)?;
                    let thr = thr_of(&members[j]);
                    (t.wald > thr).then_some((j, t.wald / thr))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            let Some((j, _)) = best else { break };
            left.retain(|&x| x != j);
            design.extend(members[j].cols.iter().cloned());
            nuisance.push(members[j].clone());
        }
    }
    let check = FamilyCheck {
        family,
        members: tested.len(),
        strongest: strongest.map(|(_, s)| s),
        size_change_z,
        size_change_limit,
        passed,
    };
    Some(Gate { check, nuisance })
}

/// Rate dependence of a per-revolution term at `k` cycles per revolution against `others`
/// (the design without it).
pub(super) fn rate_dependence(
    prep: &Prepared,
    k: f64,
    others: &[Vec<f64>],
    y: &[f64],
    noise: &BinNoise,
    level: f64,
) -> Option<RateDependence> {
    let all: Vec<usize> = (0..prep.bins.len()).collect();
    let g = sin_cos(prep, k);
    let q = ripple(prep, k);
    let mut with_q = others.to_vec();
    with_q.extend(q.iter().cloned());
    let mut with_g = others.to_vec();
    with_g.extend(g.iter().cloned());
    let tg = Projector::new(&with_q, &all).ok()?.test(&g, y, noise);
    let tq = Projector::new(&with_g, &all).ok()?.test(&q, y, noise);
    Some(RateDependence {
        cycles_per_rev: k,
        gyro_wald: tg.map_or(0.0, |t| t.wald),
        ripple_wald: tq.map_or(0.0, |t| t.wald),
        threshold: chi2_quantile(1.0 - level, 2.0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::series::test_bins;
    use crate::joint_fit::NoiseSpec;

    /// The premise of the size-change limit: freeing a member moves the effect's size by at
    /// most the member's own z (white noise, least squares: `θ_f = θ_0 − b·γ̂` with `θ_0` and
    /// `γ̂` uncorrelated, so `|Δθ|/σ_f ≤ |γ̂|/σ_γ`), whatever the two columns share.
    #[test]
    fn freeing_a_member_moves_the_effect_by_at_most_the_members_z() {
        const N: usize = 300;
        let bins = test_bins(N);
        let noise = BinNoise::new(&bins, NoiseSpec { arw: 1.0, flicker_floor: 0.0, rrw: 0.0 });
        let all: Vec<usize> = (0..N).collect();
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut draw = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut worst = 0.0f64;
        for trial in 0..40 {
            let share = f64::from(trial) / 40.0;
            let effect: Vec<f64> = (0..N).map(|_| draw()).collect();
            let member: Vec<f64> = effect.iter().map(|e| share * e + draw()).collect();
            let y: Vec<f64> = effect.iter().map(|e| 0.3 * e + 0.2 * draw()).collect();
            let bias = vec![1.0; N];
            let p_o = Projector::new(std::slice::from_ref(&bias), &all).expect("design");
            let p_f = Projector::new(&[bias.clone(), member.clone()], &all).expect("design");
            let p_w = Projector::new(&[bias, effect.clone()], &all).expect("design");
            let t0 = p_o.test(std::slice::from_ref(&effect), &y, &noise).expect("fit");
            let tf = p_f.test(std::slice::from_ref(&effect), &y, &noise).expect("fit");
            let tm = p_w.test(std::slice::from_ref(&member), &y, &noise).expect("fit");
            let change = (tf.theta[0] - t0.theta[0]).abs() / tf.sigma(0);
            let member_z = tm.wald.sqrt();
            assert!(change <= member_z * (1.0 + 1e-9), "{change} > {member_z} at {share}");
            worst = worst.max(change / member_z);
        }
        // Not vacuous: a strongly shared member moves the effect by most of its own z.
        assert!(worst > 0.5, "{worst}");
    }
}
