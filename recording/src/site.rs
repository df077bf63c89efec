//! Where the bench stands (`bench.site`): written from a scenario, read back with the
//! contract's checks — the one definition used by the writer, the analysis and the replay.

use std::collections::BTreeMap;

use crate::schema::META_SITE;

/// Which way the gyro's sensing axis points (`bench.site` `axis`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// Sensing axis points up (along the local vertical, away from Earth).
    Up,
    /// Any other orientation ("down" in the contract).
    Down,
}

impl Axis {
    /// The contract's text: `up` or `down`.
    pub fn as_str(self) -> &'static str {
        match self {
            Axis::Up => "up",
            Axis::Down => "down",
        }
    }
}

/// Where the bench stands (`bench.site`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Site {
    /// Geodetic latitude, degrees, north positive.
    pub latitude_deg: f64,
    /// Longitude, degrees, east positive.
    pub longitude_deg: Option<f64>,
    /// Height above the ellipsoid, m.
    pub height_m: Option<f64>,
    /// Orientation of the sensing axis; `None` means up (the contract's default).
    pub axis: Option<Axis>,
}

/// A metadata value that is not what the contract says.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("metadata {record} `{key}`: `{value}` is not valid ({expected})")]
pub struct MetadataError {
    /// Record name, e.g. `bench.site`.
    pub record: &'static str,
    /// Key.
    pub key: &'static str,
    /// The value found.
    pub value: String,
    /// What the contract allows.
    pub expected: &'static str,
}

impl Site {
    /// A site known only by its latitude.
    pub fn at_latitude(latitude_deg: f64) -> Self {
        Self { latitude_deg, longitude_deg: None, height_m: None, axis: None }
    }

    /// Whether the sensing axis points up (`axis` absent or `up`).
    pub fn axis_up(&self) -> bool {
        self.axis != Some(Axis::Down)
    }

    /// As `bench.site` metadata: numbers as decimal text without exponent (`45.25`).
    pub fn to_metadata(&self) -> Result<BTreeMap<String, String>, MetadataError> {
        let mut m = BTreeMap::new();
        let mut put = |key: &'static str, value: f64| {
            if value.is_finite() {
                // `Display` of f64 is the shortest decimal text that round-trips, no exponent.
                m.insert(key.to_string(), value.to_string());
                Ok(())
            } else {
                Err(MetadataError {
                    record: META_SITE,
                    key,
                    value: value.to_string(),
                    expected: "a finite number",
                })
            }
        };
        put("latitude_deg", self.latitude_deg)?;
        if let Some(v) = self.longitude_deg {
            put("longitude_deg", v)?;
        }
        if let Some(v) = self.height_m {
            put("height_m", v)?;
        }
        if let Some(a) = self.axis {
            m.insert("axis".to_string(), a.as_str().to_string());
        }
        Ok(m)
    }

    /// From `bench.site` metadata, checked against the contract: numbers finite, latitude
    /// within ±90°, axis `up` or `down`. `Ok(None)` when the record has no latitude (nothing
    /// to place Earth's rotation with). Unknown keys are ignored.
    pub fn from_metadata(meta: &BTreeMap<String, String>) -> Result<Option<Site>, MetadataError> {
        let num = |key: &'static str, range: (f64, f64), expected: &'static str| {
            meta.get(key)
                .map(|v| {
                    v.trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|x| x.is_finite() && (range.0..=range.1).contains(x))
                        .ok_or_else(|| MetadataError {
                            record: META_SITE,
                            key,
                            value: v.clone(),
                            expected,
                        })
                })
                .transpose()
        };
        let any = (f64::NEG_INFINITY, f64::INFINITY);
        let latitude = num("latitude_deg", (-90.0, 90.0), "degrees north, -90 to 90")?;
        let longitude_deg = num("longitude_deg", (-180.0, 360.0), "degrees east, -180 to 360")?;
        let height_m = num("height_m", any, "a finite number of metres")?;
        let axis = match meta.get("axis").map(|a| a.trim()) {
            None => None,
            Some("up") => Some(Axis::Up),
            Some("down") => Some(Axis::Down),
            Some(other) => {
                return Err(MetadataError {
                    record: META_SITE,
                    key: "axis",
                    value: other.to_owned(),
                    expected: "`up` or `down`",
                })
            }
        };
        Ok(latitude.map(|latitude_deg| Site { latitude_deg, longitude_deg, height_m, axis }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_site_reads_back_as_written() {
        let s = Site {
            latitude_deg: 59.94,
            longitude_deg: Some(30.31),
            height_m: Some(10.0),
            axis: Some(Axis::Down),
        };
        let m = s.to_metadata().expect("finite");
        assert_eq!(m.get("latitude_deg").map(String::as_str), Some("59.94"));
        assert_eq!(Site::from_metadata(&m), Ok(Some(s)));
        assert!(!s.axis_up());
    }

    #[test]
    fn bad_values_are_named() {
        let m = BTreeMap::from([("latitude_deg".to_string(), "91".to_string())]);
        let e = Site::from_metadata(&m).expect_err("out of range");
        assert_eq!(e.key, "latitude_deg");
        let m = BTreeMap::from([
            ("latitude_deg".to_string(), "45".to_string()),
            ("axis".to_string(), "sideways".to_string()),
        ]);
        assert_eq!(Site::from_metadata(&m).expect_err("bad axis").key, "axis");
        assert_eq!(Site::from_metadata(&BTreeMap::new()), Ok(None));
        let nan = Site::at_latitude(f64::NAN).to_metadata().expect_err("NaN");
        assert_eq!(nan.key, "latitude_deg");
    }
}
