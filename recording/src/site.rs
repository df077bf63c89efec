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

    /// From the contract's text (`up` or `down`, nothing else); `Err` says what is wrong.
    pub fn parse(text: &str) -> Result<Axis, String> {
        match text {
            "up" => Ok(Axis::Up),
            "down" => Ok(Axis::Down),
            other => Err(format!("axis must be \"up\" or \"down\", got \"{other}\"")),
        }
    }
}

/// A number of `bench.site` — and of a scenario's or a bench config's `[site]` — with its
/// range: the one check of each, wherever a site comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiteNumber {
    /// Its key.
    pub key: &'static str,
    /// Lowest value allowed.
    pub low: f64,
    /// Highest value allowed.
    pub high: f64,
    /// What the contract allows, in words.
    pub expected: &'static str,
}

impl SiteNumber {
    /// `latitude_deg`: geodetic latitude, −90…90°.
    pub const LATITUDE_DEG: SiteNumber = SiteNumber {
        key: "latitude_deg",
        low: -90.0,
        high: 90.0,
        expected: "degrees north, -90 to 90",
    };
    /// `longitude_deg`: −180…360° east.
    pub const LONGITUDE_DEG: SiteNumber = SiteNumber {
        key: "longitude_deg",
        low: -180.0,
        high: 360.0,
        expected: "degrees east, -180 to 360",
    };
    /// `height_m`: any finite height.
    pub const HEIGHT_M: SiteNumber = SiteNumber {
        key: "height_m",
        low: f64::NEG_INFINITY,
        high: f64::INFINITY,
        expected: "a finite number of metres",
    };

    /// `x` if it is finite and in range; else what is wrong (`latitude_deg 95 is outside
    /// -90..90`).
    pub fn check(self, x: f64) -> Result<f64, String> {
        if x.is_finite() && (self.low..=self.high).contains(&x) {
            Ok(x)
        } else if self.low.is_finite() {
            Err(format!("{} {x} is outside {}..{}", self.key, self.low, self.high))
        } else {
            Err(format!("{} {x} is not a finite number", self.key))
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

    /// Every number out of its range ([`SiteNumber`]): (key, what is wrong).
    pub fn problems(&self) -> Vec<(&'static str, String)> {
        let numbers = [
            (SiteNumber::LATITUDE_DEG, Some(self.latitude_deg)),
            (SiteNumber::LONGITUDE_DEG, self.longitude_deg),
            (SiteNumber::HEIGHT_M, self.height_m),
        ];
        numbers.into_iter().filter_map(|(n, v)| n.check(v?).err().map(|e| (n.key, e))).collect()
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
        let num = |n: SiteNumber| {
            meta.get(n.key)
                .map(|v| {
                    v.trim().parse::<f64>().ok().and_then(|x| n.check(x).ok()).ok_or_else(|| {
                        MetadataError {
                            record: META_SITE,
                            key: n.key,
                            value: v.clone(),
                            expected: n.expected,
                        }
                    })
                })
                .transpose()
        };
        let latitude = num(SiteNumber::LATITUDE_DEG)?;
        let longitude_deg = num(SiteNumber::LONGITUDE_DEG)?;
        let height_m = num(SiteNumber::HEIGHT_M)?;
        let axis = match meta.get("axis").map(|a| a.trim()) {
            None => None,
            Some(text) => Some(Axis::parse(text).map_err(|_| MetadataError {
                record: META_SITE,
                key: "axis",
                value: text.to_owned(),
                expected: "`up` or `down`",
            })?),
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

    #[test]
    fn one_check_per_number_whatever_the_source() {
        assert_eq!(
            SiteNumber::LATITUDE_DEG.check(95.0),
            Err("latitude_deg 95 is outside -90..90".to_string())
        );
        assert_eq!(SiteNumber::LATITUDE_DEG.check(-90.0), Ok(-90.0));
        assert!(SiteNumber::LONGITUDE_DEG.check(f64::NAN).is_err());
        assert_eq!(
            SiteNumber::HEIGHT_M.check(f64::INFINITY),
            Err("height_m inf is not a finite number".to_string())
        );
        let s = Site {
            latitude_deg: 91.0,
            longitude_deg: Some(400.0),
            height_m: Some(12.0),
            axis: None,
        };
        let keys: Vec<&str> = s.problems().into_iter().map(|(k, _)| k).collect();
        assert_eq!(keys, ["latitude_deg", "longitude_deg"]);
        assert_eq!(Axis::parse("down"), Ok(Axis::Down));
        assert_eq!(
            Axis::parse("sideways"),
            Err("axis must be \"up\" or \"down\", got \"sideways\"".to_string())
        );
    }
}
