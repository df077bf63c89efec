//! The residual scan alone, timed (a benchmark and the NumPy cross-check's inputs).

use super::*;

/// The best grid value of one candidate in the residual scan ([`residual_scan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ScanBest {
    /// Which effect.
    pub effect: EffectId,
    /// Grid values tried (1 for an effect without a grid).
    pub grid_values: usize,
    /// The grid value that fits best (least squares; NaN for none).
    pub value: f64,
    /// Its Wald statistic under the noise model.
    pub wald: f64,
    /// Its drop of the residual sum of squares, (rad/s)².
    pub delta_rss: f64,
}

/// The inputs of the residual scan, for an independent implementation of it
/// (`scripts/diagnose_numpy.py`): per-sample and per-bin arrays, scalars, the grids.
#[derive(Debug, Clone, Default)]
pub struct ScanInputs {
    /// Named arrays (per sample, per bin, or the noise model's components).
    pub arrays: Vec<(&'static str, Vec<f64>)>,
    /// Named numbers.
    pub scalars: Vec<(&'static str, f64)>,
    /// Each scanned effect's grid.
    pub grids: Vec<(EffectId, Vec<f64>)>,
}

/// The residual scan alone, timed: the first round of the effect search (every candidate's
/// regressors binned over its grid, each tested against the refitted nominal design by its
/// Wald statistic under the noise model, the least-squares best kept), without thresholds,
/// refinements, hold-out, family or identifiability checks.
#[derive(Debug, Clone)]
pub struct ResidualScan {
    /// Each scanned effect's best grid value, in library order.
    pub best: Vec<ScanBest>,
    /// Bins.
    pub bins: usize,
    /// Gyro samples.
    pub samples: usize,
    /// Time to prepare (table motion, per-sample arrays, bins, nominal residual, parameter
    /// refit, noise model), s.
    pub prepare_s: f64,
    /// Time of the scan itself (regressors binned and tested), s.
    pub scan_s: f64,
    /// The scan's inputs.
    pub inputs: ScanInputs,
}

/// The effects of the residual scan: every candidate of the search except Earth's rate (a test
/// of the bias correction, not a regressor) and the thermal lag (its regressor is a
/// first-order filter of the temperature per time constant, a sequential recursion).
pub fn residual_scan_effects(effects: &Effects) -> Vec<EffectId> {
    EffectId::ALL
        .into_iter()
        .filter(|&id| !effects.has(id))
        .filter(|&id| !matches!(id.effect().columns(), Columns::EarthRate | Columns::ThermalLag))
        .collect()
}

/// Run the residual scan ([`ResidualScan`]) of `run` against the nominal `model`.
pub fn residual_scan(
    run: &RunSeries,
    model: &GyroModel,
    effects: &Effects,
    opts: &DiagnoseOptions,
) -> Result<ResidualScan, AnalysisError> {
    let started = std::time::Instant::now();
    let prep = prepare(run, model, effects, opts)?;
    let n = prep.bins.len();
    let all: Vec<usize> = (0..n).collect();
    let y: Vec<f64> = prep.y.iter().zip(&prep.pred).map(|(a, b)| a - b).collect();
    let proj = Projector::new(&prep.base, &all)?;
    let spec = noise_model(&prep)?;
    let noise = BinNoise::new(&prep.bins, spec)
        .with_reference(prep.reference.clone())
        .with_white_scale(&prep.bins, &prep.scatter.scale);
    let prepare_s = started.elapsed().as_secs_f64();
    let ids = residual_scan_effects(effects);
    let started = std::time::Instant::now();
    let items: Vec<(EffectId, f64)> =
        ids.iter().flat_map(|&id| grid(&prep, id).into_iter().map(move |p| (id, p))).collect();
    prep.prefill_sinusoids(&items);
    let best_of = |(id, p): &(EffectId, f64)| {
        let cols = candidate_columns(&prep, *id, *p, model);
        proj.test(&cols, &y, &noise).map(|t| (t.wald, t.delta_rss))
    };
    let tests = columns::par_map(prep.threads, &items, best_of);
    let mut best: Vec<ScanBest> = Vec::new();
    for (&(id, p), t) in items.iter().zip(tests) {
        let Some((wald, delta_rss)) = t else { continue };
        match best.iter_mut().find(|b| b.effect == id) {
            Some(b) => {
                b.grid_values += 1;
                if delta_rss > b.delta_rss {
                    (b.value, b.wald, b.delta_rss) = (p, wald, delta_rss);
                }
            }
            None => best.push(ScanBest { effect: id, grid_values: 1, value: p, wald, delta_rss }),
        }
    }
    let scan_s = started.elapsed().as_secs_f64();
    let nat = &prep.native;
    let hyst = prep.hysteresis.clone();
    let bins = &prep.bins;
    let per_bin = |f: &dyn Fn(&Bin) -> f64| bins.iter().map(f).collect::<Vec<f64>>();
    let mut arrays: Vec<(&'static str, Vec<f64>)> = vec![
        ("t", nat.t.clone()),
        ("dt", nat.dt.clone()),
        ("v", nat.v.clone()),
        ("angle_mid", nat.angle_mid_rad.clone()),
        ("table_rate", nat.table_rate_rad_s.clone()),
        ("temp", prep.temp.clone()),
        ("hysteresis", hyst),
        ("bin_first", per_bin(&|b| b.first as f64)),
        ("bin_end", per_bin(&|b| b.end as f64)),
        ("bin_start_s", per_bin(&|b| b.start_s)),
        ("bin_end_s", per_bin(&|b| b.end_s)),
        ("bin_accel", per_bin(&|b| b.table_accel_rad_s2)),
        ("y", y.clone()),
    ];
    for (j, name) in ["base_0", "base_1", "base_2", "base_3"].into_iter().enumerate() {
        if let Some(c) = prep.base.get(j) {
            arrays.push((name, c.clone()));
        }
    }
    let comps = if spec.flicker_floor > 0.0 {
        bench_physics::noise::bias_instability_components(spec.flicker_floor).to_vec()
    } else {
        Vec::new()
    };
    arrays.push(("noise_t", comps.iter().map(|c| c.0).collect()));
    arrays.push(("noise_var", comps.iter().map(|c| c.1 * c.1).collect()));
    arrays.extend(prep.reference.arrays());
    let inputs = ScanInputs {
        arrays,
        scalars: vec![
            ("axis", prep.axis),
            ("earth_in", prep.earth_in),
            ("t0", prep.t0),
            ("scale", 1.0 + model.scale_factor_error),
            ("arw", spec.arw),
            ("rrw", spec.rrw),
        ],
        grids: ids.iter().map(|&id| (id, grid(&prep, id))).collect(),
    };
    Ok(ResidualScan { best, bins: n, samples: nat.t.len(), prepare_s, scan_s, inputs })
}
