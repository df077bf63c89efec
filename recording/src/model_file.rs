//! The calibration file: a gyro model in TOML with units in its key names, written by
//! `bench calibrate` and loaded by `bench run --gyro-model` (and by scenarios' `[gyro]
//! model_file`) as the gyro's model.
//!
//! ```toml
//! [gyro_model]
//! bias_rad_s = 1.2e-8
//! scale_factor_error = 3.0e-6
//! reference_temperature_c = 20.0
//! temp_coeff_rad_s_per_c = 4.85e-9
//! temp_rate_coeff_rad_s_per_c_s = 1.47e-5
//! arw_rad_per_sqrt_s = 2.9e-8
//! bias_instability_rad_s = 9.2e-9
//! earth_rate = true
//! thermal_time_constant_s = 0.0
//!
//! [uncertainty]                 # 1σ, same keys (optional, informative)
//! bias_rad_s = 3.1e-9
//!
//! [source]                      # where it came from (optional, informative)
//! recording = "run.mcap"
//!
//! [held.temp_rate_coeff_rad_s_per_c_s]   # not determined by the run: not estimated (optional)
//! value = 1.45e-5               # the nominal model's (or a prior's) value, used as it is
//! source = "nominal"
//! reason = "nothing in this run excites it: …"
//! determination = "record windows while the chamber ramps …"
//!
//! [covariance]                  # of the coefficients estimated (optional), SI, σ² on the diagonal
//! keys = ["bias_rad_s", "scale_factor_error", "temp_coeff_rad_s_per_c"]
//! matrix = [[…], […], […]]
//!
//! [effects]                     # effects beyond the model (optional; see docs/scenario.md)
//! earth_rate = false
//! warm_up = { amplitude_rad_s = 1e-7, time_constant_s = 900.0 }
//! ```
//!
//! `[gyro_model]` must hold every key, except a coefficient held (`[held.KEY]`, one of
//! [`HOLDABLE_KEYS`]): its value is there, never among the measured ones; a key in both is an
//! error. Unknown keys anywhere are errors (a typo must not silently fall back to zero). `[effects]` takes the ids of [`bench_physics::effects`], each
//! with every parameter of its struct. Errors name file, line and column.
//!
//! [`write_model_file`] / [`model_file_toml`] write a file from a model and effects (what
//! `bench calibrate` and `bench diagnose` produce).

use std::collections::BTreeMap;
use std::path::Path;

use bench_physics::effects::Effects;
use bench_physics::gyro_model::MODEL_FILE_KEYS;
use bench_physics::{GyroModel, ModelKey};
use serde::{Deserialize, Serialize};

use crate::toml_doc::line_col;

/// `[gyro_model]`: a [`GyroModel`] with units in the key names ([`ModelKey::file_key`], every
/// key of [`ModelKey::ALL`] in that order; `earth_rate` a boolean). Read and written through
/// the key table, so a key the model gains is a key of the file.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelKeys(pub GyroModel);

impl From<&GyroModel> for ModelKeys {
    fn from(m: &GyroModel) -> Self {
        Self(m.clone())
    }
}

impl From<&ModelKeys> for GyroModel {
    fn from(k: &ModelKeys) -> Self {
        k.0.clone()
    }
}

impl Serialize for ModelKeys {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        RawModelKeys { model: self.0.clone(), given: ModelKey::ALL.to_vec() }.serialize(s)
    }
}

/// A `[gyro_model]` key, read as serde reads a struct's field names: an unknown one is an
/// error located at the key, listing the known ones.
struct FileKey(ModelKey);

impl<'de> Deserialize<'de> for FileKey {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = FileKey;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a [gyro_model] key")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<FileKey, E> {
                ModelKey::from_file_key(v)
                    .map(FileKey)
                    .ok_or_else(|| E::unknown_field(v, &MODEL_FILE_KEYS))
            }
        }
        d.deserialize_identifier(V)
    }
}

impl<'de> Deserialize<'de> for ModelKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let raw = RawModelKeys::deserialize(d)?;
        match ModelKey::ALL.into_iter().find(|k| !raw.given.contains(k)) {
            Some(k) => Err(serde::de::Error::missing_field(k.file_key())),
            None => Ok(ModelKeys(raw.model)),
        }
    }
}

/// 1σ uncertainties of the fitted coefficients (same keys as [`ModelKeys`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Uncertainty {
    /// rad/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bias_rad_s: Option<f64>,
    /// 1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_factor_error: Option<f64>,
    /// rad/s per °C.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temp_coeff_rad_s_per_c: Option<f64>,
    /// rad/s per °C/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temp_rate_coeff_rad_s_per_c_s: Option<f64>,
}

/// Where a calibration came from.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// Recording file name.
    #[serde(default)]
    pub recording: String,
    /// Writer and version.
    #[serde(default)]
    pub software: String,
    /// Estimator.
    #[serde(default)]
    pub method: String,
}

/// The calibrated coefficients a calibration may hold instead of estimating, with their keys
/// in `[gyro_model]`.
pub const HOLDABLE_KEYS: [(ModelKey, &str); 4] = {
    let k = ModelKey::HOLDABLE;
    [
        (k[0], k[0].file_key()),
        (k[1], k[1].file_key()),
        (k[2], k[2].file_key()),
        (k[3], k[3].file_key()),
    ]
};

/// A coefficient the calibration held (the run does not determine it): the value used, never
/// written among the measured ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldEntry {
    /// The value used, SI.
    pub value: f64,
    /// Its 1σ (a prior's), when stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// `nominal`, `prior` or `none`.
    #[serde(default)]
    pub source: String,
    /// Why the run does not determine it.
    #[serde(default)]
    pub reason: String,
    /// The run that would determine it.
    #[serde(default)]
    pub determination: String,
}

/// The covariance of the coefficients estimated, SI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CovarianceSection {
    /// Rows and columns: `[gyro_model]` keys of [`HOLDABLE_KEYS`].
    pub keys: Vec<String>,
    /// The matrix, σ² on its diagonal.
    pub matrix: Vec<Vec<f64>>,
}

/// The whole calibration file.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationFile {
    /// Where it came from.
    pub source: Source,
    /// The model (a held coefficient at its held value).
    pub gyro_model: ModelKeys,
    /// 1σ of the fitted coefficients.
    pub uncertainty: Uncertainty,
    /// Effects beyond the model (none when the section is absent): recorded as `effect.*`
    /// keys of `bench.gyro_model` and, on the simulated bench, simulated.
    pub effects: Effects,
    /// Coefficients held, not estimated, by their `[gyro_model]` key ([`HOLDABLE_KEYS`]).
    pub held: BTreeMap<String, HeldEntry>,
    /// The covariance of the coefficients estimated, when known.
    pub covariance: Option<CovarianceSection>,
}

fn no_effects(e: &Effects) -> bool {
    !e.any()
}

/// `[gyro_model]` as written: a held coefficient's key absent. Read and written through the key
/// table as [`ModelKeys`] is, the keys given in `given`.
#[derive(Debug, Clone, PartialEq)]
struct RawModelKeys {
    model: GyroModel,
    given: Vec<ModelKey>,
}

impl RawModelKeys {
    /// A holdable coefficient by its file key.
    fn holdable(key: &str) -> Option<ModelKey> {
        HOLDABLE_KEYS.iter().find(|h| h.1 == key).map(|h| h.0)
    }
}

impl Serialize for RawModelKeys {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap as _;
        let mut st = s.serialize_map(Some(self.given.len()))?;
        for k in ModelKey::ALL.into_iter().filter(|k| self.given.contains(k)) {
            match k {
                ModelKey::EarthRate => st.serialize_entry(k.file_key(), &self.model.earth_rate)?,
                _ => st.serialize_entry(k.file_key(), &self.model.get(k))?,
            }
        }
        st.end()
    }
}

impl<'de> Deserialize<'de> for RawModelKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = RawModelKeys;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("the [gyro_model] table")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<RawModelKeys, A::Error> {
                let mut model = GyroModel::zero();
                let mut given = Vec::with_capacity(ModelKey::ALL.len());
                while let Some(FileKey(k)) = map.next_key()? {
                    if given.contains(&k) {
                        return Err(serde::de::Error::duplicate_field(k.file_key()));
                    }
                    match k {
                        ModelKey::EarthRate => model.earth_rate = map.next_value()?,
                        _ => model.set(k, map.next_value()?),
                    }
                    given.push(k);
                }
                Ok(RawModelKeys { model, given })
            }
        }
        d.deserialize_struct("ModelKeys", &MODEL_FILE_KEYS, V)
    }
}

/// The file as written and read.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    #[serde(default)]
    source: Source,
    gyro_model: RawModelKeys,
    #[serde(default)]
    uncertainty: Uncertainty,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    held: BTreeMap<String, HeldEntry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    covariance: Option<CovarianceSection>,
    #[serde(default, skip_serializing_if = "no_effects")]
    effects: Effects,
}

/// A calibration file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// The file cannot be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: String,
        /// I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Not valid TOML, or not a calibration file.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// File.
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Effects that cannot be written: a file with them would not load back.
    #[error("{path}: not written: [effects] {message}")]
    BadEffects {
        /// File.
        path: String,
        /// Which parameter and what is wrong.
        message: String,
    },
    /// A `[held]` or `[covariance]` entry that cannot be used, located.
    #[error("{path}:{line}:{column}: {message}")]
    BadSection {
        /// File.
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A value out of range, located at the value (at `[gyro_model]`, or 1:1, when the key is
    /// absent and its default is out of range).
    #[error("{path}:{line}:{column}: [gyro_model] {key} = {value}: {why}")]
    Invalid {
        /// File.
        path: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Key.
        key: &'static str,
        /// Value.
        value: f64,
        /// Requirement.
        why: &'static str,
    },
}

impl CalibrationFile {
    /// A file holding `model` and `effects`, with where it came from and the 1σ uncertainties.
    pub fn new(
        model: &GyroModel,
        effects: &Effects,
        source: Source,
        uncertainty: Uncertainty,
    ) -> Self {
        Self {
            source,
            gyro_model: ModelKeys::from(model),
            uncertainty,
            effects: *effects,
            held: BTreeMap::new(),
            covariance: None,
        }
    }

    /// The file as written: a held coefficient's key absent from `[gyro_model]`.
    fn raw(&self) -> RawFile {
        let given: Vec<ModelKey> =
            ModelKey::ALL.into_iter().filter(|k| !self.held.contains_key(k.file_key())).collect();
        let keys = RawModelKeys { model: self.gyro_model.0.clone(), given };
        RawFile {
            source: self.source.clone(),
            gyro_model: keys,
            uncertainty: self.uncertainty.clone(),
            held: self.held.clone(),
            covariance: self.covariance.clone(),
            effects: self.effects,
        }
    }

    /// Whether a coefficient (of [`HOLDABLE_KEYS`]) is held, not estimated.
    pub fn is_held(&self, key: ModelKey) -> bool {
        HOLDABLE_KEYS.iter().any(|(k, name)| *k == key && self.held.contains_key(*name))
    }

    /// The gyro model.
    pub fn model(&self) -> GyroModel {
        GyroModel::from(&self.gyro_model)
    }

    /// As TOML text, with a header comment.
    pub fn to_toml(&self) -> String {
        let body = toml::to_string_pretty(&self.raw()).unwrap_or_default();
        format!(
            "# Gyro model written by bench. SI units, named in the keys; [uncertainty] holds 1σ\n\
             # standard errors, [effects] effects beyond the model. Load with\n\
             # `bench run --gyro-model FILE`.\n{}\n{body}",
            if self.held.is_empty() && self.covariance.is_none() {
                ""
            } else {
                "# [held]: coefficients the run did not determine, not estimated (the value used, \
                 why,\n# and the run that would determine it); [covariance]: of the estimated \
                 ones.\n"
            }
        )
    }

    /// Parse `text` (from `path`, for messages).
    pub fn parse(text: &str, path: &str) -> Result<Self, ModelFileError> {
        let raw: RawFile = toml::from_str(text).map_err(|e| {
            let (line, column) = e.span().map(|s| line_col(text, s.start)).unwrap_or((1, 1));
            ModelFileError::Parse {
                path: path.to_owned(),
                line,
                column,
                message: e.message().to_owned(),
            }
        })?;
        let file = Self::from_raw(raw, text, path)?;
        if let Err((key, why)) = file.gyro_model.0.validate() {
            let span = crate::toml_doc::value_span(text, &["gyro_model", key.file_key()])
                .or_else(|| crate::toml_doc::value_span(text, &["gyro_model"]));
            let (line, column) = span.map_or((1, 1), |s| line_col(text, s.start));
            return Err(ModelFileError::Invalid {
                path: path.to_owned(),
                line,
                column,
                key: key.file_key(),
                value: file.gyro_model.0.get(key),
                why,
            });
        }
        crate::effects_toml::check_located(&file.effects, text, &["effects"]).map_err(
            |(line, column, message)| ModelFileError::Parse {
                path: path.to_owned(),
                line,
                column,
                message,
            },
        )?;
        Ok(file)
    }

    /// The file from what was read: every `[gyro_model]` key given once, in `[gyro_model]` or,
    /// for a held coefficient, in `[held]`; the covariance over estimated keys.
    fn from_raw(mut raw: RawFile, text: &str, path: &str) -> Result<Self, ModelFileError> {
        let at = |keys: &[&str], message: String| {
            let span = crate::toml_doc::value_span(text, keys);
            let (line, column) = span.map_or((1, 1), |s| line_col(text, s.start));
            ModelFileError::BadSection { path: path.to_owned(), line, column, message }
        };
        for (key, h) in &raw.held {
            let Some(k) = RawModelKeys::holdable(key) else {
                return Err(at(
                    &["held", key],
                    format!(
                        "[held] {key}: only a calibrated coefficient can be held ({})",
                        HOLDABLE_KEYS.map(|k| k.1).join(", ")
                    ),
                ));
            };
            if raw.gyro_model.given.contains(&k) {
                return Err(at(
                    &["gyro_model", key],
                    format!("[gyro_model] {key}: the coefficient is held ([held.{key}]): not both"),
                ));
            }
            let sigma_ok = h.sigma.is_none_or(|s| s.is_finite() && s >= 0.0);
            if !h.value.is_finite() || !sigma_ok {
                return Err(at(
                    &["held", key],
                    format!("[held.{key}]: value and sigma must be finite, sigma not negative"),
                ));
            }
            raw.gyro_model.model.set(k, h.value);
            raw.gyro_model.given.push(k);
        }
        if let Some(k) = ModelKey::ALL.into_iter().find(|k| !raw.gyro_model.given.contains(k)) {
            return Err(at(
                &["gyro_model"],
                format!("missing field `{}` in [gyro_model]", k.file_key()),
            ));
        }
        let gyro_model = ModelKeys(raw.gyro_model.model.clone());
        if let Some(c) = &raw.covariance {
            let n = c.keys.len();
            let bad_key = c.keys.iter().find(|k| {
                !HOLDABLE_KEYS.iter().any(|h| h.1 == k.as_str()) || raw.held.contains_key(*k)
            });
            if let Some(k) = bad_key {
                return Err(at(
                    &["covariance", "keys"],
                    format!("[covariance] keys: `{k}` is not an estimated coefficient"),
                ));
            }
            let square = c.matrix.len() == n && c.matrix.iter().all(|r| r.len() == n);
            let finite = c.matrix.iter().flatten().all(|v| v.is_finite());
            let diag = (0..n).all(|i| !square || c.matrix[i][i] >= 0.0);
            if !(square && finite && diag) {
                return Err(at(
                    &["covariance", "matrix"],
                    format!(
                        "[covariance] matrix: must be {n}×{n} (one row and column per key), \
                         finite, variances not negative"
                    ),
                ));
            }
        }
        Ok(Self {
            source: raw.source,
            gyro_model,
            uncertainty: raw.uncertainty,
            effects: raw.effects,
            held: raw.held,
            covariance: raw.covariance,
        })
    }

    /// Read a calibration file.
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path)
            .map_err(|source| ModelFileError::Io { path: name.clone(), source })?;
        let text = crate::toml_doc::utf8_text(bytes).map_err(|(_, line, column, message)| {
            ModelFileError::Parse { path: name.clone(), line, column, message }
        })?;
        Self::parse(&text, &name)
    }

    /// Write the file. Effects that [`CalibrationFile::parse`] would reject (not finite, a
    /// time constant not positive) are refused, naming the parameter.
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        self.effects.validate().map_err(|message| ModelFileError::BadEffects {
            path: path.display().to_string(),
            message,
        })?;
        std::fs::write(path, self.to_toml())
            .map_err(|source| ModelFileError::Io { path: path.display().to_string(), source })
    }
}

/// The model file for `model` and `effects` (with `source` and the 1σ `uncertainty`) as TOML
/// text, the format [`CalibrationFile::parse`] and `bench run --gyro-model` read back exactly.
pub fn model_file_toml(
    model: &GyroModel,
    effects: &Effects,
    source: &Source,
    uncertainty: &Uncertainty,
) -> String {
    CalibrationFile::new(model, effects, source.clone(), uncertainty.clone()).to_toml()
}

/// Write the model file for `model` and `effects` (with `source` and the 1σ `uncertainty`)
/// to `path`; refuses effects that would not load back (see [`CalibrationFile::save`]).
pub fn write_model_file(
    path: &Path,
    model: &GyroModel,
    effects: &Effects,
    source: &Source,
    uncertainty: &Uncertainty,
) -> Result<(), ModelFileError> {
    CalibrationFile::new(model, effects, source.clone(), uncertainty.clone()).save(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_a_model_exactly() {
        let m = GyroModel { thermal_time_constant: 123.5, ..GyroModel::default() };
        let f = CalibrationFile {
            source: Source { recording: "x.mcap".into(), ..Source::default() },
            gyro_model: ModelKeys::from(&m),
            uncertainty: Uncertainty { bias_rad_s: Some(1e-9), ..Uncertainty::default() },
            effects: Effects::default(),
            held: BTreeMap::new(),
            covariance: None,
        };
        let back = CalibrationFile::parse(&f.to_toml(), "cal.toml").expect("parses");
        assert_eq!(back, f);
        assert_eq!(back.model(), m);
    }

    #[test]
    fn a_typo_is_an_error_with_line_and_column() {
        let m = GyroModel::default();
        let f = CalibrationFile {
            source: Source::default(),
            gyro_model: ModelKeys::from(&m),
            uncertainty: Uncertainty::default(),
            effects: Effects::default(),
            held: BTreeMap::new(),
            covariance: None,
        };
        let text = f.to_toml().replace("temp_coeff_rad_s_per_c =", "temp_cof_rad_s_per_c =");
        let e = CalibrationFile::parse(&text, "cal.toml").expect_err("rejects");
        let line = text.lines().position(|l| l.starts_with("temp_cof")).expect("line") + 1;
        let msg = e.to_string();
        assert!(msg.starts_with(&format!("cal.toml:{line}:1: ")), "{msg}");
        assert!(msg.contains("temp_cof_rad_s_per_c"), "{msg}");
    }

    #[test]
    fn a_missing_key_and_a_negative_noise_are_errors() {
        let e = CalibrationFile::parse("[gyro_model]\nbias_rad_s = 0.0\n", "c.toml")
            .expect_err("incomplete");
        assert!(e.to_string().contains("missing field `scale_factor_error`"), "{e}");
        let m = GyroModel { arw: -1.0, ..GyroModel::default() };
        let f = CalibrationFile {
            source: Source::default(),
            gyro_model: ModelKeys::from(&m),
            uncertainty: Uncertainty::default(),
            effects: Effects::default(),
            held: BTreeMap::new(),
            covariance: None,
        };
        let text = f.to_toml();
        let e = CalibrationFile::parse(&text, "c.toml").expect_err("negative");
        // Located at the value, like every other error of the file.
        let at = text.find("arw_rad_per_sqrt_s = -1").map(|i| i + "arw_rad_per_sqrt_s = ".len());
        let (line, column) = line_col(&text, at.unwrap_or(0));
        assert_eq!(
            e.to_string(),
            format!(
                "c.toml:{line}:{column}: [gyro_model] arw_rad_per_sqrt_s = -1: must be finite \
                 and not negative"
            )
        );
    }

    #[test]
    fn a_held_coefficient_is_written_apart_and_reads_back_into_the_model() {
        let m = GyroModel::default();
        let mut f = CalibrationFile::new(
            &m,
            &Effects::default(),
            Source::default(),
            Uncertainty::default(),
        );
        f.held.insert(
            "temp_rate_coeff_rad_s_per_c_s".into(),
            HeldEntry {
                value: m.temp_rate_coeff,
                sigma: None,
                source: "nominal".into(),
                reason: "nothing in this run excites it".into(),
                determination: "record windows while the chamber ramps".into(),
            },
        );
        f.covariance = Some(CovarianceSection {
            keys: vec!["bias_rad_s".into(), "temp_coeff_rad_s_per_c".into()],
            matrix: vec![vec![1e-16, 1e-19], vec![1e-19, 4e-20]],
        });
        let text = f.to_toml();
        // Never among the measured values.
        let gyro = text.split("[gyro_model]").nth(1).and_then(|t| t.split("\n[").next());
        assert!(gyro.is_some_and(|g| !g.contains("temp_rate_coeff")), "{text}");
        assert!(text.contains("[held.temp_rate_coeff_rad_s_per_c_s]"), "{text}");
        let back = CalibrationFile::parse(&text, "cal.toml").expect("parses");
        assert_eq!(back, f);
        assert_eq!(back.model(), m);
        assert!(back.is_held(ModelKey::TempRateCoeff) && !back.is_held(ModelKey::Bias));
        // In both places: refused, at the measured one.
        let both =
            text.replace("[gyro_model]\n", "[gyro_model]\ntemp_rate_coeff_rad_s_per_c_s = 1.0\n");
        let e = CalibrationFile::parse(&both, "cal.toml").expect_err("both");
        assert!(e.to_string().contains("not both"), "{e}");
        // A covariance over a held key, or of the wrong shape: refused.
        let mut bad = f.clone();
        if let Some(c) = &mut bad.covariance {
            c.keys[1] = "temp_rate_coeff_rad_s_per_c_s".into();
        }
        let e = CalibrationFile::parse(&bad.to_toml(), "cal.toml").expect_err("held key");
        assert!(e.to_string().contains("not an estimated coefficient"), "{e}");
        if let Some(c) = &mut bad.covariance {
            c.keys[1] = "temp_coeff_rad_s_per_c".into();
            c.matrix[1].pop();
        }
        let e = CalibrationFile::parse(&bad.to_toml(), "cal.toml").expect_err("not square");
        assert!(e.to_string().contains("must be 2×2"), "{e}");
    }

    #[test]
    fn the_file_keys_are_the_model_key_tables() {
        // [gyro_model] holds every key of the table, in its order; [uncertainty] only its keys.
        let f = CalibrationFile::new(
            &GyroModel::default(),
            &Effects::default(),
            Source::default(),
            Uncertainty {
                bias_rad_s: Some(1.0),
                scale_factor_error: Some(1.0),
                temp_coeff_rad_s_per_c: Some(1.0),
                temp_rate_coeff_rad_s_per_c_s: Some(1.0),
            },
        );
        let doc: toml::Table = toml::from_str(&f.to_toml()).expect("TOML");
        let keys = |section: &str| -> Vec<String> {
            let mut k: Vec<String> =
                doc[section].as_table().expect("table").keys().cloned().collect();
            k.sort();
            k
        };
        let mut expected: Vec<String> = MODEL_FILE_KEYS.iter().map(|k| k.to_string()).collect();
        expected.sort();
        assert_eq!(keys("gyro_model"), expected);
        let text = f.to_toml();
        let order: Vec<usize> =
            MODEL_FILE_KEYS.iter().map(|k| text.find(&format!("\n{k} = ")).expect(k)).collect();
        assert!(order.windows(2).all(|w| w[0] < w[1]), "contract order");
        for k in keys("uncertainty") {
            assert!(ModelKey::from_file_key(&k).is_some(), "{k}");
        }
        // A scale factor of zero or less is refused, as everywhere a model is read.
        let text = text.replace("scale_factor_error = 0.0", "scale_factor_error = -1.0");
        let e = CalibrationFile::parse(&text, "m.toml").expect_err("k_sf = 0");
        assert!(
            e.to_string().contains("scale_factor_error = -1: must be finite and above -1"),
            "{e}"
        );
    }

    #[test]
    fn an_out_of_range_value_is_located() {
        // Found by scripts/bad_inputs.py: the range errors named the file only.
        let text = "[gyro_model]\nbias_rad_s = 0.0\nscale_factor_error = -2.0\n\
                    reference_temperature_c = 20.0\ntemp_coeff_rad_s_per_c = 0.0\n\
                    temp_rate_coeff_rad_s_per_c_s = 0.0\narw_rad_per_sqrt_s = 0.0\n\
                    bias_instability_rad_s = 0.0\nearth_rate = true\n\
                    thermal_time_constant_s = 0.0\n";
        let e = CalibrationFile::parse(text, "m.toml").expect_err("scale factor below -1");
        assert!(e.to_string().starts_with("m.toml:3:22: [gyro_model] scale_factor_error"), "{e}");
    }
}

#[cfg(test)]
mod effects_tests {
    use bench_physics::effects::EffectId;

    use super::*;

    fn fitted() -> Effects {
        let on: [(EffectId, &[f64]); 5] = [
            (EffectId::EarthRate, &[]),
            (EffectId::ThermalLag, &[412.25]),
            (EffectId::OncePerRevolution, &[2.0000000000000004e-8, -0.1 - 0.2]),
            (EffectId::WarmUp, &[1e-7, 900.0]),
            (EffectId::BiasStep, &[3600.5, -3e-9]),
        ];
        let mut e = Effects::default();
        for (id, v) in on {
            e.set(id, v).expect("count fits");
        }
        e
    }

    #[test]
    fn the_writer_round_trips_model_and_effects_exactly() {
        let model = GyroModel { temp_coeff: 4.67e-9, ..GyroModel::default() };
        let source = Source {
            recording: "run.mcap".into(),
            software: "bench test".into(),
            method: "diagnose".into(),
        };
        let unc = Uncertainty { bias_rad_s: Some(1.25e-8), ..Uncertainty::default() };
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("model.toml");
        write_model_file(&path, &model, &fitted(), &source, &unc).expect("writes");
        let back = CalibrationFile::load(&path).expect("loads");
        assert_eq!(back.model(), model);
        assert_eq!(back.effects, fitted());
        assert_eq!(back.source, source);
        assert_eq!(back.uncertainty, unc);
        let text = model_file_toml(&model, &fitted(), &source, &unc);
        assert!(text.contains("[effects]"), "{text}");
        assert!(text.contains("[effects.warm_up]") || text.contains("warm_up = {"), "{text}");
        // Without effects there is no [effects] section, and it reads back as none.
        let plain = model_file_toml(&model, &Effects::default(), &source, &unc);
        assert!(!plain.contains("\n[effects"), "{plain}");
        let back = CalibrationFile::parse(&plain, "plain.toml").expect("parses");
        assert_eq!(back.effects, Effects::default());
    }

    #[test]
    fn an_effects_section_written_by_hand_is_read() {
        let base = model_file_toml(
            &GyroModel::default(),
            &Effects::default(),
            &Source::default(),
            &Uncertainty::default(),
        );
        let text = format!(
            "{base}\n[effects]\nearth_rate = true\nwarm_up = {{ amplitude_rad_s = 1e-7, \
             time_constant_s = 900 }}\n"
        );
        let f = CalibrationFile::parse(&text, "m.toml").expect("parses");
        assert!(f.effects.has(EffectId::EarthRate));
        assert_eq!(f.effects.get(EffectId::WarmUp), Some(&[1e-7, 900.0][..]));
    }

    #[test]
    fn bad_effects_are_located_and_refused_by_the_writer() {
        let base = model_file_toml(
            &GyroModel::default(),
            &Effects::default(),
            &Source::default(),
            &Uncertainty::default(),
        );
        // The effect's line: right after the `[effects]` header appended below.
        let line = format!("{base}\n[effects]\n").lines().count() + 1;
        let bad = |effects: &str| {
            CalibrationFile::parse(&format!("{base}\n[effects]\n{effects}\n"), "m.toml")
                .expect_err("rejected")
                .to_string()
        };
        assert_eq!(
            bad("warm_up = { amplitude_rad_s = 1e-7, time_constant_s = 0 }"),
            format!(
                "m.toml:{line}:55: [effects] warm_up.time_constant_s = 0: must be greater than zero"
            )
        );
        assert_eq!(
            bad("bias_step = { time_s = inf, step_rad_s = 1e-9 }"),
            format!("m.toml:{line}:24: [effects] bias_step.time_s = inf: must be a finite number")
        );
        let e = bad("warmup = { amplitude_rad_s = 1e-7, time_constant_s = 9 }");
        assert!(e.starts_with(&format!("m.toml:{line}:1: unknown field `warmup`")), "{e}");
        assert!(e.contains("`warm_up`"), "{e}");
        let e = bad("warm_up = { amplitude_rad_s = 1e-7 }");
        assert!(
            e.starts_with(&format!("m.toml:{line}:11: missing field `time_constant_s`")),
            "{e}"
        );
        let e = bad("warm_up = { amplitude_rad_s = 1e-7, time_constant_s = 9, tau_s = 1 }");
        assert!(
            e.starts_with(&format!("m.toml:{line}:")) && e.contains("unknown field `tau_s`"),
            "{e}"
        );

        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("bad.toml");
        let mut effects = fitted();
        effects.set(EffectId::ThermalLag, &[-1.0]).expect("fits");
        let e = write_model_file(
            &path,
            &GyroModel::default(),
            &effects,
            &Source::default(),
            &Uncertainty::default(),
        )
        .expect_err("refused");
        assert!(e.to_string().contains("thermal_lag.time_constant_s"), "{e}");
        assert!(!path.exists());
    }
}
