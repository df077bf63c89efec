//! The candidates' regressors and grids, read from each effect's registry entry.

use super::*;

/// A candidate's columns for one grid value (a time constant's memoised in [`Prepared`]).
pub(super) fn candidate_columns(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    model: &GyroModel,
) -> Vec<Vec<f64>> {
    if matches!(id.effect().grid(), Grid::TimeConstants(_)) {
        let key = (id, p.to_bits());
        // A poisoned lock only means another thread panicked mid-insert: the map is still valid.
        let hit = prep.decays.lock().unwrap_or_else(|e| e.into_inner()).get(&key).cloned();
        if let Some(cols) = hit {
            return cols;
        }
        let cols = regressor_columns(prep, id, p, model);
        prep.decays.lock().unwrap_or_else(|e| e.into_inner()).insert(key, cols.clone());
        return cols;
    }
    regressor_columns(prep, id, p, model)
}

/// [`candidate_columns`] computed (no memo), as the effect's [`Columns`] say.
pub(super) fn regressor_columns(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    model: &GyroModel,
) -> Vec<Vec<f64>> {
    let nat = &prep.native;
    let dt = &nat.dt;
    let bins = &prep.bins;
    let axis = prep.axis;
    match id.effect().columns() {
        Columns::ThermalLag => {
            let lagged = lag_temperature(&nat.t, &prep.temp, p);
            let col = bin_mean(bins, dt, |k| {
                let rate_lag = (prep.temp[k] - lagged[k]) / p;
                model.temp_coeff * (lagged[k] - prep.temp[k])
                    + model.temp_rate_coeff * (rate_lag - prep.temp_rate[k])
            });
            vec![col]
        }
        Columns::TimeOffset => {
            let scale = 1.0 + model.scale_factor_error;
            vec![bins.iter().map(|b| -scale * axis * b.table_accel_rad_s2).collect()]
        }
        Columns::EarthRate => vec![vec![prep.earth; bins.len()]],
        Columns::Angle(order) => {
            let h = if order == Order::One { 1.0 } else { p };
            prep.sinusoid(columns::Kind::Angle, h)
        }
        Columns::Ripple => prep.sinusoid(columns::Kind::Ripple, p),
        Columns::Periodic => prep.sinusoid(columns::Kind::Periodic, p),
        // At the bins' starts: a step is exactly 0 before its bin and 1 from there on.
        Columns::AtBinStart => (0..id.linear_count())
            .map(|j| {
                bins.iter()
                    .map(|b| {
                        let mut out = [0.0; 2];
                        let s = EffectSample { t_s: b.start_s, ..EffectSample::default() };
                        id.regressors(&s, p, &mut out);
                        out[j]
                    })
                    .collect()
            })
            .collect(),
        Columns::PerSample => per_sample(prep, id, p, |k| prep.sample(k)),
    }
}

/// A per-sample effect's columns: bin means of its regressors at each native sample as
/// `sample(k)` describes it.
fn per_sample(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    sample: impl Fn(usize) -> EffectSample,
) -> Vec<Vec<f64>> {
    (0..id.linear_count())
        .map(|j| {
            bin_mean(&prep.bins, &prep.native.dt, |k| {
                let mut out = [0.0; 2];
                id.regressors(&sample(k), p, &mut out);
                out[j]
            })
        })
        .collect()
}

/// Whether effect `id`'s regressors (at grid value `p`) read the coil's temperature or its
/// hysteresis state: a per-sample effect probed at one sample with every input non-zero,
/// then with the temperature and the state changed (a scale factor vs T, a quadratic in T,
/// hysteresis do; a rate², a drift do not).
pub(super) fn reads_temperature(id: EffectId, p: f64) -> bool {
    if !matches!(id.effect().columns(), Columns::PerSample) {
        return false;
    }
    let one = EffectSample {
        t_s: 1000.0,
        input_rad_s: 0.01,
        table_rate_rad_s: 0.01,
        temp_minus_ref_c: 5.0,
        angle_mid_rad: 0.7,
        hysteresis: 1.0,
        earth_rad_s: 7e-5,
    };
    let other = EffectSample { temp_minus_ref_c: 7.0, hysteresis: -1.0, ..one };
    let n = id.linear_count().min(2);
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    id.regressors(&one, p, &mut a[..n]);
    id.regressors(&other, p, &mut b[..n]);
    a != b
}

/// A per-sample effect's columns ([`regressor_columns`]) with the coil's temperature `temp_c`
/// and hysteresis state `hysteresis` (native samples) in place of the prepared ones: the
/// effect at another coil lag ([`coil_lag`]).
pub(super) fn per_sample_columns_at(
    prep: &Prepared,
    id: EffectId,
    p: f64,
    temp_c: &[f64],
    hysteresis: &[f64],
) -> Vec<Vec<f64>> {
    per_sample(prep, id, p, |k| EffectSample {
        temp_minus_ref_c: temp_c[k] - prep.t0,
        hysteresis: hysteresis[k],
        ..prep.sample(k)
    })
}

/// The grid of a candidate's nonlinear parameter (a single NaN for none).
pub(super) fn grid(prep: &Prepared, id: EffectId) -> Vec<f64> {
    grid_values(prep, id.effect().grid())
}

/// The values of effect `id`'s rival grid ([`bench_physics::effects::Effect::rival_grid`]) on
/// this recording.
pub(super) fn rival_grid(prep: &Prepared, id: EffectId) -> Vec<f64> {
    grid_values(prep, id.effect().rival_grid())
}

/// The values of grid `g` on this recording.
fn grid_values(prep: &Prepared, g: Grid) -> Vec<f64> {
    match g {
        Grid::None => vec![f64::NAN],
        Grid::TimeConstants(values) => values.to_vec(),
        Grid::BinStarts { positions } => {
            let n = prep.bins.len();
            let lo = n / 50 + 1;
            let hi = n - n / 50 - 1;
            let stride = ((hi - lo) / positions).max(1);
            (lo..hi).step_by(stride).map(|i| prep.bins[i].start_s).collect()
        }
        Grid::Periods { min_s, min_cycles, most } => {
            period_grid(&prep.bins, min_s, min_cycles, most)
        }
        Grid::CyclesPerRev { from, to } => (from..=to).map(f64::from).collect(),
        Grid::Harmonics => (2..=family::harmonic_max(prep)).map(f64::from).collect(),
    }
}

/// Periods tried for a periodic bias: evenly in frequency, half a cycle over the run apart, from
/// `min_cycles` cycles in the run up to the shortest period (`min_s`, four bins), at most `most`
/// of them (the short-period end is dropped first). Longest first.
pub(super) fn period_grid(bins: &[Bin], min_s: f64, min_cycles: f64, most: usize) -> Vec<f64> {
    let (Some(first), Some(last)) = (bins.first(), bins.last()) else { return Vec::new() };
    let span_s = last.end_s - first.start_s;
    let p_min = min_s.max(4.0 * first.span_s());
    if span_s.is_nan() || span_s <= min_cycles * p_min {
        return Vec::new();
    }
    let f_lo = min_cycles / span_s;
    let df = 0.5 / span_s;
    let f_hi = (1.0 / p_min).min(f_lo + df * (most - 1) as f64);
    let n = ((f_hi - f_lo) / df).floor() as usize + 1;
    (0..n).map(|j| 1.0 / (f_lo + df * j as f64)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_effects_that_read_the_coils_temperature_are_found_by_probing() {
        let reading: Vec<EffectId> =
            EffectId::ALL.into_iter().filter(|&id| reads_temperature(id, 100.0)).collect();
        assert_eq!(
            reading,
            vec![
                EffectId::TemperatureQuadratic,
                EffectId::ScaleFactorTemperature,
                EffectId::ThermalHysteresis
            ]
        );
    }
}
