//! [`Effects`]: which effects of the library are on, with their parameters — a simulator's
//! truth, a recording's nominal effects, or what a diagnosis found. Read and written as TOML
//! tables (`[effects]` of a model file, `[simulation.effects]`), as `bench.gyro_model`
//! metadata keys (`effect.<key>.<parameter>`), and evaluated sample by sample.

use std::collections::BTreeMap;
use std::fmt;
use std::sync::OnceLock;

use serde::de::{self, DeserializeSeed, MapAccess, Visitor};
use serde::ser::SerializeStruct;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{Columns, EffectId, EffectSample, Owner, Range, Role, COUNT, HYSTERESIS_THRESHOLD_C_S};

/// Prefix of the effects' keys in `bench.gyro_model` metadata (`effect.<id>.<parameter>`).
pub const METADATA_PREFIX: &str = "effect.";

/// Most parameters an effect has.
const MAX_PARAMS: usize = 3;

/// The effects switched on, each with its parameters in [`super::Effect::params`] order; all
/// off by default. An effect without parameters (`earth_rate`) is on or off.
#[derive(Clone, Copy, PartialEq, Default)]
pub struct Effects {
    on: [Option<[f64; MAX_PARAMS]>; COUNT],
}

impl fmt::Debug for Effects {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut m = f.debug_map();
        for id in self.ids() {
            let names = id.param_names();
            let values = self.get(id).unwrap_or(&[]);
            let params: BTreeMap<&str, f64> =
                names.into_iter().zip(values.iter().copied()).collect();
            m.entry(&id.key(), &params);
        }
        m.finish()
    }
}

impl Effects {
    /// Whether any effect is on.
    pub fn any(&self) -> bool {
        self.on.iter().any(Option::is_some)
    }

    /// The ids of the effects that are on, in library order.
    pub fn ids(&self) -> Vec<EffectId> {
        EffectId::ALL.into_iter().filter(|&e| self.has(e)).collect()
    }

    /// Whether effect `id` is on.
    pub fn has(&self, id: EffectId) -> bool {
        self.on[id as usize].is_some()
    }

    /// The parameters of effect `id` in [`super::Effect::params`] order, `None` when it is
    /// off (an effect without parameters that is on gives an empty slice).
    pub fn get(&self, id: EffectId) -> Option<&[f64]> {
        self.on[id as usize].as_ref().map(|v| &v[..id.params().len()])
    }

    /// [`Self::get`] as a vector.
    pub fn param_values(&self, id: EffectId) -> Option<Vec<f64>> {
        self.get(id).map(<[f64]>::to_vec)
    }

    /// Switch effect `id` on with `values` in [`super::Effect::params`] order (replacing it if
    /// it was on). Values are not checked here ([`Self::validate`] does); a wrong count is an
    /// error naming the effect.
    pub fn set(&mut self, id: EffectId, values: &[f64]) -> Result<(), String> {
        let names = id.param_names();
        if values.len() != names.len() {
            return Err(format!(
                "effect `{}` takes {} parameter(s) ({}), got {}",
                id.key(),
                names.len(),
                names.join(", "),
                values.len()
            ));
        }
        let mut v = [0.0; MAX_PARAMS];
        v[..values.len()].copy_from_slice(values);
        self.on[id as usize] = Some(v);
        Ok(())
    }

    /// These effects with `id` on at `values` ([`Self::set`]).
    pub fn with(mut self, id: EffectId, values: &[f64]) -> Result<Self, String> {
        self.set(id, values)?;
        Ok(self)
    }

    /// Switch effect `id` off.
    pub fn clear(&mut self, id: EffectId) {
        self.on[id as usize] = None;
    }

    /// These effects with `id` off.
    pub fn without(mut self, id: EffectId) -> Self {
        self.clear(id);
        self
    }

    /// The effects that travel with a gyro model to another recording ([`Owner`]): the gyro's
    /// and Earth's rate, without the table's motion and the recording's clocks.
    pub fn travelling(&self) -> Self {
        self.filtered(|o| o.travels_with_model())
    }

    /// The effects a recording states of its own bench: the table's motion and its clocks.
    pub fn of_the_bench(&self) -> Self {
        self.filtered(|o| !o.travels_with_model())
    }

    /// A gyro model's effects (these, [`Self::travelling`]) on the bench of a recording whose
    /// own effects are `recording`: the table's motion and the clocks are the recording's
    /// (absent where it states none), never the model's.
    pub fn on_the_bench_of(&self, recording: &Effects) -> Self {
        self.travelling().overridden_by(&recording.of_the_bench())
    }

    fn filtered(&self, keep: impl Fn(Owner) -> bool) -> Self {
        let mut out = *self;
        for id in EffectId::ALL {
            if !keep(id.owner()) {
                out.clear(id);
            }
        }
        out
    }

    /// Check every parameter: finite, and positive where its range says so. The error names
    /// the parameter (`effect.parameter`) and says what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        for (id, p, v) in self.parameters() {
            let name = format!("{}.{}", id.key(), p.name);
            if !v.is_finite() {
                return Err(format!("`{name}` must be a finite number, got {v}"));
            }
            if p.range == Range::Positive && v <= 0.0 {
                return Err(format!("`{name}` must be positive, got {v}"));
            }
        }
        Ok(())
    }

    /// Every parameter of every effect that is on, in library order.
    pub fn parameters(&self) -> Vec<(EffectId, super::Param, f64)> {
        self.ids()
            .into_iter()
            .flat_map(|id| {
                let values = self.get(id).unwrap_or(&[]).to_vec();
                id.params().iter().zip(values).map(move |(p, v)| (id, *p, v))
            })
            .collect()
    }

    /// Lag time constant of the bias-driving temperature, s (0 without `thermal_lag`).
    pub fn lag_s(&self) -> f64 {
        self.get(EffectId::ThermalLag).map_or(0.0, |v| v[0])
    }

    /// Time-tag offset, s (0 without `time_offset`).
    pub fn offset_s(&self) -> f64 {
        self.get(EffectId::TimeOffset).map_or(0.0, |v| v[0])
    }

    /// Hysteresis threshold, °C/s (the default without `thermal_hysteresis`).
    pub fn hysteresis_threshold_c_s(&self) -> f64 {
        self.get(EffectId::ThermalHysteresis).map_or(HYSTERESIS_THRESHOLD_C_S, |v| v[1])
    }

    /// The additive effects' output for one sample, rad/s; `scale` is `1 + scale_factor_error`
    /// (Earth's rate passes through the scale factor like any input).
    pub fn value(&self, s: &EffectSample, scale: f64) -> f64 {
        let mut v = 0.0;
        let mut r = [0.0; 2];
        for id in EffectId::ALL {
            let Some(values) = self.get(id) else { continue };
            let e = id.effect();
            let n = e.linear_count();
            if n == 0 {
                continue;
            }
            let (p, coeffs) = coefficients(id, values, scale);
            e.regressors(s, p, &mut r);
            v += (0..n).map(|k| coeffs[k] * r[k]).sum::<f64>();
        }
        v
    }

    /// As extra `bench.gyro_model` metadata keys: `effect.<id>.<parameter>` for every parameter
    /// of every effect that is on, numbers as decimal text in the shortest form that reads back
    /// exactly (`{:e}`), and `effect.<id>` = `1` for an effect without parameters that is on.
    /// Effects that are off have no keys.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        for id in self.ids() {
            let values = self.get(id).unwrap_or(&[]);
            if values.is_empty() {
                m.insert(format!("{METADATA_PREFIX}{}", id.key()), "1".to_string());
            }
            for (p, v) in id.params().iter().zip(values) {
                m.insert(format!("{METADATA_PREFIX}{}.{}", id.key(), p.name), format!("{v:e}"));
            }
        }
        m
    }

    /// From `bench.gyro_model` metadata: reads exactly the keys [`Self::to_metadata`] writes and
    /// ignores every other key. An effect is on when any of its keys is present; then all of
    /// them must be. An effect without parameters takes `1`/`0` (or `true`/`false`). Errors name
    /// the key (unparsable value, missing sibling parameter). Values are not range-checked
    /// here; call [`Self::validate`] before simulating them.
    pub fn from_metadata(meta: &BTreeMap<String, String>) -> Result<Effects, String> {
        let mut out = Effects::default();
        for id in EffectId::ALL {
            let base = format!("{METADATA_PREFIX}{}", id.key());
            let names = id.param_names();
            if names.is_empty() {
                if let Some(v) = meta.get(&base) {
                    match v.trim() {
                        "1" | "true" => out.set(id, &[])?,
                        "0" | "false" => {}
                        other => {
                            return Err(format!(
                                "`{base}` must be 1 or 0 (true or false), got \"{other}\""
                            ))
                        }
                    }
                }
                continue;
            }
            let keys: Vec<String> = names.iter().map(|p| format!("{base}.{p}")).collect();
            if !keys.iter().any(|k| meta.contains_key(k)) {
                continue;
            }
            let mut values = Vec::with_capacity(keys.len());
            for k in &keys {
                let Some(text) = meta.get(k) else {
                    let given = keys.iter().find(|g| meta.contains_key(*g)).map_or("", |g| g);
                    return Err(format!("`{k}` is missing (`{given}` is given)"));
                };
                let v = text
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| format!("`{k}` must be a number, got \"{text}\""))?;
                values.push(v);
            }
            out.set(id, &values)?;
        }
        Ok(out)
    }

    /// These effects with each effect that is on in `over` replacing or adding to them (the
    /// rule for a simulator's truth: the nominal effects, overridden per effect).
    pub fn overridden_by(&self, over: &Effects) -> Effects {
        let mut out = *self;
        for id in over.ids() {
            out.on[id as usize] = over.on[id as usize];
        }
        out
    }

    /// The table of the library's effects in Markdown (`docs/diagnose.md`): key, whose
    /// physics, output added, parameters with units and ranges, non-linear parameter.
    pub fn table_markdown() -> String {
        let mut out = String::from(
            "| effect | whose | output added, rad/s | parameters | searched over |\n\
             | --- | --- | --- | --- | --- |\n",
        );
        for id in EffectId::ALL {
            let e = id.effect();
            let params: Vec<String> = e
                .params()
                .iter()
                .map(|p| {
                    let range = if p.range == Range::Positive { " > 0" } else { "" };
                    format!("`{}`{range}", p.name)
                })
                .collect();
            let params = if params.is_empty() { "— (on/off)".into() } else { params.join(", ") };
            let grid = match e.grid() {
                super::Grid::None => "—".to_string(),
                g => grid_words(g),
            };
            out.push_str(&format!(
                "| `{}` | {} | {} | {params} | {grid} |\n",
                id.key(),
                e.owner().words(),
                e.formula()
            ));
        }
        out
    }
}

/// A grid in words (the docs' table).
fn grid_words(g: super::Grid) -> String {
    use super::Grid;
    match g {
        Grid::None => "—".into(),
        Grid::TimeConstants(v) => {
            let v: Vec<String> = v.iter().map(|x| format!("{x}")).collect();
            format!("τ ∈ {{{}}} s, refined in the final fit", v.join(", "))
        }
        Grid::BinStarts { positions } => {
            format!("up to {positions} bin starts, refined to the bin")
        }
        Grid::Periods { min_s, min_cycles, most } => format!(
            "up to {most} periods evenly in frequency, {min_cycles} cycles per run to {min_s} s, \
             refined"
        ),
        Grid::CyclesPerRev { from, to } => format!("{from}..{to} cycles/rev"),
        Grid::Harmonics => "2..K cycles/rev (K: what a bin resolves)".into(),
    }
}

/// Effect `id`'s non-linear parameter and coefficients at parameter `values` (`scale` is
/// `1 + scale_factor_error`, Earth's coefficient).
fn coefficients(id: EffectId, values: &[f64], scale: f64) -> (f64, [f64; 2]) {
    let mut p = 0.0;
    let mut coeffs = [0.0; 2];
    let (mut amp, mut phase, mut wave) = (0.0, 0.0, false);
    for (param, &v) in id.params().iter().zip(values) {
        match param.role {
            Role::Coefficient(k) => coeffs[k] = v,
            Role::Grid => p = v,
            Role::Amplitude => (amp, wave) = (v, true),
            Role::Phase => phase = v,
            Role::Setting(_) => {}
        }
    }
    if wave {
        // `A·sin(x + φ)` = `A cos φ·sin x + A sin φ·cos x`.
        let (sp, cp) = phase.sin_cos();
        coeffs = [amp * cp, amp * sp];
    }
    if id.effect().columns() == Columns::EarthRate {
        coeffs[0] = scale;
    }
    (p, coeffs)
}

/// Every effect key and, as a field name, `&'static` for serde's messages.
fn keys() -> &'static [&'static str] {
    static KEYS: OnceLock<Vec<&'static str>> = OnceLock::new();
    KEYS.get_or_init(|| EffectId::ALL.iter().map(|id| id.key()).collect())
}

/// Each effect's parameter names, `&'static` for serde's messages.
fn names(id: EffectId) -> &'static [&'static str] {
    static NAMES: OnceLock<Vec<Vec<&'static str>>> = OnceLock::new();
    &NAMES.get_or_init(|| EffectId::ALL.iter().map(|id| id.param_names()).collect())[id as usize]
}

/// One effect's parameters, serialized as a table of `name = value`.
struct ParamsOf<'a>(EffectId, &'a [f64]);

impl Serialize for ParamsOf<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let params = self.0.params();
        let mut st = s.serialize_struct(self.0.key(), params.len())?;
        for (p, v) in params.iter().zip(self.1) {
            st.serialize_field(p.name, v)?;
        }
        st.end()
    }
}

/// As a table: an effect without parameters as `key = true/false` (always written), every
/// other effect that is on as a table of its parameters, in library order.
impl Serialize for Effects {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("Effects", COUNT)?;
        for id in EffectId::ALL {
            if id.params().is_empty() {
                st.serialize_field(id.key(), &self.has(id))?;
            } else if let Some(values) = self.get(id) {
                st.serialize_field(id.key(), &ParamsOf(id, values))?;
            } else {
                st.skip_field(id.key())?;
            }
        }
        st.end()
    }
}

/// The inverse of [`Serialize`]: unknown effects and parameters, missing parameters and
/// values of the wrong type are errors (as serde's derived `deny_unknown_fields` words them),
/// at the offending key or value.
impl<'de> Deserialize<'de> for Effects {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_struct("Effects", keys(), EffectsVisitor)
    }
}

struct EffectsVisitor;

impl<'de> Visitor<'de> for EffectsVisitor {
    type Value = Effects;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("struct Effects")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Effects, A::Error> {
        let mut out = Effects::default();
        let mut seen = [false; COUNT];
        while let Some(Key(k)) = map.next_key_seed(KeySeed(None))? {
            let id = EffectId::ALL[k];
            if std::mem::replace(&mut seen[id as usize], true) {
                return Err(de::Error::duplicate_field(id.key()));
            }
            if id.params().is_empty() {
                if map.next_value::<bool>()? {
                    out.on[id as usize] = Some([0.0; MAX_PARAMS]);
                }
            } else {
                let values = map.next_value_seed(ParamsSeed(id))?;
                out.on[id as usize] = Some(values);
            }
        }
        Ok(out)
    }
}

/// A key of the effects' table (`None`) or of effect `id`'s parameters: its index.
struct Key(usize);

struct KeySeed(Option<EffectId>);

impl<'de> DeserializeSeed<'de> for KeySeed {
    type Value = Key;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Key, D::Error> {
        d.deserialize_identifier(self)
    }
}

impl<'de> Visitor<'de> for KeySeed {
    type Value = Key;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("field identifier")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<Key, E> {
        let known = match self.0 {
            None => keys(),
            Some(id) => names(id),
        };
        known.iter().position(|k| *k == v).map(Key).ok_or_else(|| E::unknown_field(v, known))
    }
}

/// Effect `id`'s table of parameters.
struct ParamsSeed(EffectId);

impl<'de> DeserializeSeed<'de> for ParamsSeed {
    type Value = [f64; MAX_PARAMS];

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_struct(self.0.key(), names(self.0), self)
    }
}

impl<'de> Visitor<'de> for ParamsSeed {
    type Value = [f64; MAX_PARAMS];

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "the parameters of effect `{}`", self.0.key())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let names = names(self.0);
        let mut values: [Option<f64>; MAX_PARAMS] = [None; MAX_PARAMS];
        while let Some(Key(k)) = map.next_key_seed(KeySeed(Some(self.0)))? {
            if values[k].is_some() {
                return Err(de::Error::duplicate_field(names[k]));
            }
            values[k] = Some(map.next_value()?);
        }
        let mut out = [0.0; MAX_PARAMS];
        for (k, name) in names.iter().enumerate() {
            out[k] = values[k].ok_or_else(|| de::Error::missing_field(name))?;
        }
        Ok(out)
    }
}
