//! Record windows: the data of one `record …` step, as plain arrays.

use crate::error::AnalysisError;

/// Direction of table rotation, seen from above (the contract's angle is positive
/// counter-clockwise, so a positive table rate is CCW).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Clockwise: mean table rate negative.
    Cw,
    /// Counter-clockwise: mean table rate positive.
    Ccw,
    /// Table at rest: |mean table rate| below [`REST_RATE_RAD_S`].
    Rest,
}

/// Table rates whose magnitude is below this (rad/s, ≈ 0.2 °/h) count as rest.
pub const REST_RATE_RAD_S: f64 = 1e-6;

/// One record window: equal-length arrays sampled at the gyro's time stamps.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordWindow {
    label: String,
    time_s: Vec<f64>,
    gyro_rate_rad_s: Vec<f64>,
    table_rate_rad_s: Vec<f64>,
    gyro_temp_c: Option<Vec<f64>>,
    chamber_temp_c: Vec<f64>,
    /// The model temperature smoothed and its rate, from the whole run's series (no filter
    /// truncated at the window's edges), when given.
    smoothed: Option<(Vec<f64>, Vec<f64>)>,
    /// The table rate's error, when known: (the reference it comes from — windows with the
    /// same key share one error —, its σ in rad/s).
    reference_error: Option<(usize, f64)>,
    /// The Allan variance's sums below the block, where the gyro's samples are averaged in
    /// blocks ([`crate::allan_sub`]).
    sub_block: Option<crate::allan_sub::SubBlockAllan>,
}

fn check_finite(label: &str, array: &'static str, v: &[f64]) -> Result<(), AnalysisError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(AnalysisError::NonFinite { label: label.to_owned(), array, index }),
        None => Ok(()),
    }
}

impl RecordWindow {
    /// A window from its arrays (time in s, rates in rad/s, temperatures in °C), checked: all
    /// arrays as long as `time_s`, at least 2 samples, all values finite, time strictly
    /// increasing. `gyro_temp_c` is `None` for a gyro without an internal sensor.
    pub fn new(
        label: impl Into<String>,
        time_s: Vec<f64>,
        gyro_rate_rad_s: Vec<f64>,
        table_rate_rad_s: Vec<f64>,
        gyro_temp_c: Option<Vec<f64>>,
        chamber_temp_c: Vec<f64>,
    ) -> Result<Self, AnalysisError> {
        let label = label.into();
        let n = time_s.len();
        if n < 2 {
            return Err(AnalysisError::TooFewSamples {
                what: format!("window `{label}`"),
                got: n,
                min: 2,
            });
        }
        let mut arrays: Vec<(&'static str, &[f64])> = vec![
            ("time_s", &time_s),
            ("gyro_rate_rad_s", &gyro_rate_rad_s),
            ("table_rate_rad_s", &table_rate_rad_s),
            ("chamber_temp_c", &chamber_temp_c),
        ];
        if let Some(g) = &gyro_temp_c {
            arrays.push(("gyro_temp_c", g));
        }
        for (name, a) in arrays {
            if a.len() != n {
                return Err(AnalysisError::LengthMismatch {
                    label,
                    array: name,
                    got: a.len(),
                    expected: n,
                });
            }
            check_finite(&label, name, a)?;
        }
        if let Some(i) = time_s.windows(2).position(|w| w[1] <= w[0]) {
            return Err(AnalysisError::TimeNotIncreasing { label, index: i + 1 });
        }
        Ok(Self {
            label,
            time_s,
            gyro_rate_rad_s,
            table_rate_rad_s,
            gyro_temp_c,
            chamber_temp_c,
            smoothed: None,
            reference_error: None,
            sub_block: None,
        })
    }

    /// The same window with its table rate's error: one constant over the window, of σ
    /// `sigma_rad_s`, shared with every window of the same `reference` (e.g. one steady line
    /// of the table's angle). The joint fit adds it to its coefficients' covariance.
    pub fn with_reference_error(self, reference: usize, sigma_rad_s: f64) -> Self {
        Self { reference_error: Some((reference, sigma_rad_s)), ..self }
    }

    /// The same window with the Allan variance's sums below the block of its samples (block
    /// means: [`crate::allan_sub`]), pooled by the noise model with the block-level curve.
    pub fn with_sub_block(self, sub: crate::allan_sub::SubBlockAllan) -> Self {
        Self { sub_block: Some(sub), ..self }
    }

    /// The Allan variance's sums below the block ([`Self::with_sub_block`]), if any.
    pub fn sub_block(&self) -> Option<&crate::allan_sub::SubBlockAllan> {
        self.sub_block.as_ref()
    }

    /// The table rate's error ([`Self::with_reference_error`]), if known.
    pub fn reference_error(&self) -> Option<(usize, f64)> {
        self.reference_error
    }

    /// The same window with `temp_c` as the model temperature (in place of the gyro sensor's
    /// readings, e.g. a lagged temperature), checked like [`Self::new`].
    pub fn with_model_temperature(&self, temp_c: Vec<f64>) -> Result<Self, AnalysisError> {
        if temp_c.len() != self.len() {
            return Err(AnalysisError::LengthMismatch {
                label: self.label.clone(),
                array: "gyro_temp_c",
                got: temp_c.len(),
                expected: self.len(),
            });
        }
        check_finite(&self.label, "gyro_temp_c", &temp_c)?;
        Ok(Self { gyro_temp_c: Some(temp_c), smoothed: None, ..self.clone() })
    }

    /// The same window with its model temperature's smoothed value and rate (°C, °C/s) at its
    /// samples, computed over the whole run so that no filter is cut at the window's edges
    /// ([`crate::calibrate::TemperatureSeries::smoothed`]).
    pub fn with_smoothed_temperature(
        &self,
        temp_c: Vec<f64>,
        rate_c_s: Vec<f64>,
    ) -> Result<Self, AnalysisError> {
        for (name, v) in [("smoothed temperature", &temp_c), ("temperature rate", &rate_c_s)] {
            if v.len() != self.len() {
                return Err(AnalysisError::LengthMismatch {
                    label: self.label.clone(),
                    array: name,
                    got: v.len(),
                    expected: self.len(),
                });
            }
            check_finite(&self.label, name, v)?;
        }
        Ok(Self { smoothed: Some((temp_c, rate_c_s)), ..self.clone() })
    }

    /// The model temperature's rate of change, °C/s: the whole run's, when given
    /// ([`Self::with_smoothed_temperature`]), else a local linear regression over `window_s`
    /// within the window.
    pub fn temperature_rate_c_s(&self, window_s: f64) -> Result<Vec<f64>, AnalysisError> {
        match &self.smoothed {
            Some((_, rate)) => Ok(rate.clone()),
            None => crate::temperature_rate::local_linear_rate(
                &self.time_s,
                self.temperature_c(),
                window_s,
            ),
        }
    }

    /// The model temperature smoothed (the regression's value), °C: the whole run's when
    /// given, else within the window.
    pub fn smoothed_temperature_c(&self, window_s: f64) -> Result<Vec<f64>, AnalysisError> {
        match &self.smoothed {
            Some((temp, _)) => Ok(temp.clone()),
            None => crate::temperature_rate::local_linear_value(
                &self.time_s,
                self.temperature_c(),
                window_s,
            ),
        }
    }

    /// The step label (e.g. `record cw 20C`).
    pub fn label(&self) -> &str {
        &self.label
    }
    /// Sample times, s.
    pub fn time_s(&self) -> &[f64] {
        &self.time_s
    }
    /// Gyro output, rad/s.
    pub fn gyro_rate_rad_s(&self) -> &[f64] {
        &self.gyro_rate_rad_s
    }
    /// Measured table rate, rad/s.
    pub fn table_rate_rad_s(&self) -> &[f64] {
        &self.table_rate_rad_s
    }
    /// The gyro's own temperature readings, °C, if it has a sensor.
    pub fn gyro_temp_c(&self) -> Option<&[f64]> {
        self.gyro_temp_c.as_deref()
    }
    /// Chamber air temperature, °C.
    pub fn chamber_temp_c(&self) -> &[f64] {
        &self.chamber_temp_c
    }
    /// The temperature the error model uses: the gyro's own sensor where it has one, otherwise
    /// chamber air (right only when the gyro follows the air without lag).
    pub fn temperature_c(&self) -> &[f64] {
        self.gyro_temp_c.as_deref().unwrap_or(&self.chamber_temp_c)
    }
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }
    /// Always false: a window has at least 2 samples.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }
    /// Mean of [`Self::temperature_c`], °C.
    pub fn mean_temperature_c(&self) -> f64 {
        mean(self.temperature_c())
    }
    /// Spread (max − min) of [`Self::temperature_c`], °C.
    pub fn temperature_span_c(&self) -> f64 {
        let t = self.temperature_c();
        let max = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = t.iter().copied().fold(f64::INFINITY, f64::min);
        max - min
    }
    /// Spread (max − min) of the chamber air temperature, °C.
    pub fn chamber_span_c(&self) -> f64 {
        let t = &self.chamber_temp_c;
        let max = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = t.iter().copied().fold(f64::INFINITY, f64::min);
        max - min
    }
    /// Mean table rate, rad/s.
    pub fn mean_table_rate_rad_s(&self) -> f64 {
        mean(&self.table_rate_rad_s)
    }
    /// Direction from the sign of the mean table rate.
    pub fn direction(&self) -> Direction {
        let w = self.mean_table_rate_rad_s();
        if w.abs() < REST_RATE_RAD_S {
            Direction::Rest
        } else if w > 0.0 {
            Direction::Ccw
        } else {
            Direction::Cw
        }
    }
}

/// Arithmetic mean; NaN for an empty slice.
pub(crate) fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Synthetic record windows for tests: per `(table rate rad/s, temperature °C at the start,
/// its slope °C/s, start time s)` a window of 1200 samples at 2 Hz whose gyro sensor and
/// chamber air both follow that temperature, and whose output is `output(rate, temp, slope)`.
#[cfg(test)]
pub(crate) fn synthetic_windows(
    specs: &[(f64, f64, f64, f64)],
    output: impl Fn(f64, f64, f64) -> f64,
) -> Vec<RecordWindow> {
    specs
        .iter()
        .enumerate()
        .map(|(k, &(rate, temp0, slope, start))| {
            let n = 1200;
            let t: Vec<f64> = (0..n).map(|i| start + i as f64 * 0.5).collect();
            let temp: Vec<f64> = (0..n).map(|i| temp0 + slope * i as f64 * 0.5).collect();
            let v: Vec<f64> = temp.iter().map(|&tc| output(rate, tc, slope)).collect();
            RecordWindow::new(format!("w{k}"), t, v, vec![rate; n], Some(temp.clone()), temp)
                .expect("window")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(table: f64) -> Result<RecordWindow, AnalysisError> {
        RecordWindow::new(
            "w",
            vec![0.0, 0.05, 0.1],
            vec![0.0; 3],
            vec![table; 3],
            None,
            vec![20.0, 20.0, 21.0],
        )
    }

    #[test]
    fn direction_follows_the_table_rate_sign() {
        assert_eq!(w(-2.9e-3).map(|w| w.direction()), Ok(Direction::Cw));
        assert_eq!(w(2.9e-3).map(|w| w.direction()), Ok(Direction::Ccw));
        assert_eq!(w(0.0).map(|w| w.direction()), Ok(Direction::Rest));
    }

    #[test]
    fn temperature_falls_back_to_chamber_air_and_spans() {
        let w = w(1.0).expect("valid window");
        assert!((w.mean_temperature_c() - 61.0 / 3.0).abs() < 1e-12);
        assert_eq!(w.temperature_span_c(), 1.0);
        assert_eq!(w.len(), 3);
    }

    #[test]
    fn bad_arrays_are_rejected_with_what_is_wrong() {
        let e = RecordWindow::new("x", vec![0.0, 1.0], vec![0.0], vec![0.0; 2], None, vec![0.0; 2]);
        assert!(matches!(
            e,
            Err(AnalysisError::LengthMismatch {
                array: "gyro_rate_rad_s",
                got: 1,
                expected: 2,
                ..
            })
        ));
        let e =
            RecordWindow::new("x", vec![0.0, 0.0], vec![0.0; 2], vec![0.0; 2], None, vec![0.0; 2]);
        assert!(matches!(e, Err(AnalysisError::TimeNotIncreasing { index: 1, .. })));
        let e = RecordWindow::new(
            "x",
            vec![0.0, 1.0],
            vec![0.0, f64::NAN],
            vec![0.0; 2],
            Some(vec![0.0; 2]),
            vec![0.0; 2],
        );
        assert!(matches!(e, Err(AnalysisError::NonFinite { index: 1, .. })));
        let e = RecordWindow::new("x", vec![0.0], vec![0.0], vec![0.0], None, vec![0.0]);
        assert!(matches!(e, Err(AnalysisError::TooFewSamples { got: 1, .. })));
    }
}
