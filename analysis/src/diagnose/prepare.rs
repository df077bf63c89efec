//! Everything computed once per run: the recording's arrays, bins, the nominal residual and the noise model.

use super::*;
use crate::allan_sub::SubBlockSums;

/// Time-constant regressors by effect and τ's bits ([`candidate_columns`]).
pub(super) type DecayMemo =
    std::sync::Mutex<std::collections::BTreeMap<(EffectId, u64), Vec<Vec<f64>>>>;

/// The coil temperature's and its rate's bin means by lag τ's bits ([`coil_lag`]: the lag's
/// profiles and rivals read the same grid again).
pub(super) type LagMemo =
    std::sync::Mutex<std::collections::BTreeMap<u64, std::sync::Arc<[Vec<f64>; 2]>>>;

/// The bin-mean columns of accepted effects that read the coil's temperature, at another coil
/// lag, by (τ's bits, effect, grid value's bits) ([`coil_lag::Beside`]).
pub(super) type LagEffectMemo = std::sync::Mutex<
    std::collections::BTreeMap<(u64, EffectId, u64), std::sync::Arc<Vec<Vec<f64>>>>,
>;

/// Everything computed once per run.
pub(super) struct Prepared {
    pub(super) native: Native,
    pub(super) bins: Vec<Bin>,
    pub(super) axis: f64,
    pub(super) earth: f64,
    /// Earth's rate in the model's input (0 where the model leaves it out).
    pub(super) earth_in: f64,
    /// Temperature driving the model (°C) and its rate (°C/s), per sample.
    pub(super) temp: Vec<f64>,
    pub(super) temp_rate: Vec<f64>,
    /// The heating/cooling state per sample at the library's default threshold (a
    /// candidate hysteresis's regressor).
    pub(super) hysteresis: Vec<f64>,
    pub(super) t0: f64,
    /// Bin means.
    pub(super) y: Vec<f64>,
    pub(super) pred: Vec<f64>,
    pub(super) base: Vec<Vec<f64>>,
    pub(super) short_adev: Vec<AdevPoint>,
    /// Windows whose own scatter exceeds the rest of the run's ([`scatter`]): left out of
    /// `short_adev`, their bins deweighted by it.
    pub(super) scatter: scatter::Scatter,
    /// σ of a time offset from the table's angle readout ([`readout_offset_sigma_s`]), s.
    pub(super) readout_offset_sigma_s: f64,
    /// The table reference's error in the bins, for the noise model ([`noise::ReferenceLines`]).
    pub(super) reference: noise::ReferenceLines,
    /// The sinusoidal regressors computed so far ([`columns`]).
    pub(super) memo: columns::ColumnMemo,
    /// Threads for the parallel parts ([`DiagnoseOptions::threads`], at least 1).
    pub(super) threads: usize,
    /// Whether the coil's lag is the diagnosis's to refit ([`coil_lag`]): a gyro without its
    /// own temperature sensor whose nominal effects do not already lag the temperature.
    pub(super) lag_free: bool,
    /// The time-constant regressors (warm-up, lag) computed so far, by effect and τ's bits: the
    /// refinement between grid values asks for the same ones at every refit.
    pub(super) decays: DecayMemo,
    /// The coil-lag profile's thermal columns computed so far ([`LagMemo`]).
    pub(super) lag_thermal: LagMemo,
    /// The temperature-reading effects' columns at the lags profiled ([`LagEffectMemo`]).
    pub(super) lag_effects: LagEffectMemo,
}

impl Prepared {
    /// What the effects' regressors see at native sample `k` (the hysteresis state at the
    /// library's default threshold).
    pub(super) fn sample(&self, k: usize) -> EffectSample {
        let nat = &self.native;
        EffectSample {
            t_s: nat.t[k],
            input_rad_s: self.axis * nat.table_rate_rad_s[k] + self.earth_in,
            table_rate_rad_s: self.axis * nat.table_rate_rad_s[k],
            temp_minus_ref_c: self.temp[k] - self.t0,
            angle_mid_rad: nat.angle_mid_rad[k],
            hysteresis: self.hysteresis[k],
            earth_rad_s: self.earth,
        }
    }

    /// The (sin, cos) columns of a sinusoidal regressor at `p`, computed once ([`columns`]).
    pub(super) fn sinusoid(&self, kind: columns::Kind, p: f64) -> Vec<Vec<f64>> {
        self.memo.get(&self.native, &self.bins, self.axis, kind, p)
    }

    /// The sinusoidal regressors among the candidates' grid values `items` computed together,
    /// whole grids by rotation and in parallel ([`columns::ColumnMemo::prefill`]).
    pub(super) fn prefill_sinusoids(&self, items: &[(EffectId, f64)]) {
        let mut orders = Vec::new();
        let mut periods = Vec::new();
        for &(id, p) in items {
            match id.effect().columns() {
                Columns::Angle(Order::One) => orders.push(1.0),
                Columns::Angle(Order::Grid) | Columns::Ripple => orders.push(p),
                Columns::Periodic => periods.push(p),
                _ => {}
            }
        }
        if !orders.is_empty() || !periods.is_empty() {
            self.memo.prefill(&self.native, &self.bins, self.axis, &orders, &periods, self.threads);
        }
    }
}

pub(super) fn prepare(
    run: &RunSeries,
    model: &GyroModel,
    effects: &Effects,
    opts: &DiagnoseOptions,
) -> Result<Prepared, AnalysisError> {
    let motion =
        TableMotion::fit(&run.table_time_s, &run.table_angle_rad, &run.table_rate_command_rad_s);
    if motion.segments.is_empty() {
        return Err(AnalysisError::Insufficient(
            "diagnosis: the table never holds a constant rate long enough to fit its motion".into(),
        ));
    }
    let native = Native::build(run, &motion, model.thermal_time_constant)?;
    let (temp, temp_rate) = crate::nominal::effect_temperature(&native, effects);
    let bins = make_bins(&native, &motion, opts.bin_s);
    if bins.len() < 20 {
        return Err(AnalysisError::TooFewSamples {
            what: "diagnosis bins".into(),
            got: bins.len(),
            min: 20,
        });
    }
    let axis = if run.axis_up { 1.0 } else { -1.0 };
    let earth = run.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, run.axis_up));
    let t0 = model.reference_temperature;
    let earth_in = if model.earth_rate || effects.has(EffectId::EarthRate) { earth } else { 0.0 };
    let dt = &native.dt;
    let y = bin_mean(&bins, dt, |k| native.v[k]);
    let tmean = bin_mean(&bins, dt, |k| temp[k] - t0);
    let rmean = bin_mean(&bins, dt, |k| temp_rate[k]);
    let input: Vec<f64> = bins.iter().map(|b| axis * b.table_rate_rad_s + earth_in).collect();
    let scale = 1.0 + model.scale_factor_error;
    // Additive nominal effects, evaluated per sample and averaged.
    let eff_mean = if effects.any() {
        let hyst = HysteresisStateSeries::new(effects.hysteresis_threshold_c_s(), &temp_rate);
        // Earth through the effect is already in `input`: count it once, below.
        let additive = effects.without(EffectId::EarthRate);
        bin_mean(&bins, dt, |k| {
            let s = EffectSample {
                t_s: native.t[k],
                input_rad_s: axis * native.table_rate_rad_s[k] + earth_in,
                table_rate_rad_s: axis * native.table_rate_rad_s[k],
                temp_minus_ref_c: temp[k] - t0,
                angle_mid_rad: native.angle_mid_rad[k],
                hysteresis: hyst.0[k],
                earth_rad_s: earth,
            };
            additive.value(&s, scale)
        })
    } else {
        vec![0.0; bins.len()]
    };
    let offset = effects.offset_s();
    let pred: Vec<f64> = (0..bins.len())
        .map(|i| {
            scale * (input[i] - offset * axis * bins[i].table_accel_rad_s2)
                + model.bias
                + model.temp_coeff * tmean[i]
                + model.temp_rate_coeff * rmean[i]
                + eff_mean[i]
        })
        .collect();
    let base = vec![vec![1.0; bins.len()], input.clone(), tmean, rmean];
    let thermal: Vec<f64> = (0..native.t.len())
        .map(|k| model.temp_coeff * (temp[k] - t0) + model.temp_rate_coeff * temp_rate[k])
        .collect();
    let scatter = scatter::check(&native, &bins, opts.alpha);
    let short_adev =
        native_adev(&native, &motion, axis, &thermal, &scatter, run.gyro_sub_block.as_ref());
    let phases = TurnPhases::new(&motion, &run.table_time_s, &run.table_angle_rad);
    let readout_offset_sigma_s = readout_offset_sigma_s(&motion, &phases);
    let reference =
        reference_lines(&motion, &bins, &run.table_time_s, &run.table_angle_rad, &phases);
    let hysteresis = HysteresisStateSeries::new(HYST_C_S, &temp_rate).0;
    Ok(Prepared {
        lag_free: run.gyro_temp_c.is_none() && !effects.has(EffectId::ThermalLag),
        native,
        bins,
        axis,
        earth,
        earth_in,
        temp,
        temp_rate,
        hysteresis,
        t0,
        y,
        pred,
        base,
        short_adev,
        scatter,
        readout_offset_sigma_s,
        reference,
        memo: columns::ColumnMemo::default(),
        threads: opts.threads.max(1),
        decays: std::sync::Mutex::default(),
        lag_thermal: std::sync::Mutex::default(),
        lag_effects: std::sync::Mutex::default(),
    })
}

/// Which of the table's turning segments keep one rounding phase ([`rounding_in_phase`]), read
/// once for the time offset's σ ([`readout_offset_sigma_s`]: any) and the reference lines'
/// rounding ([`reference_lines`]: all). Both false without a readout grid or a turn.
pub(super) struct TurnPhases {
    /// At least one turn keeps one phase.
    pub(super) any: bool,
    /// Every turn keeps one phase, and there is one.
    pub(super) all: bool,
}

impl TurnPhases {
    pub(super) fn new(motion: &TableMotion, time_s: &[f64], angle_rad: &[f64]) -> Self {
        let q = motion.quantum_rad;
        if q <= 0.0 {
            return Self { any: false, all: false };
        }
        let flags: Vec<bool> = motion
            .segments
            .iter()
            .filter(|s| s.command_rad_s != 0.0)
            .map(|s| rounding_in_phase(s, time_s, angle_rad, q))
            .collect();
        Self { any: flags.contains(&true), all: !flags.is_empty() && !flags.contains(&false) }
    }
}

/// σ that the table's angle readout leaves a time offset, s. The offset lives in the bins that
/// hold a rate change, as the angle step between the two steady lines; each line is known only
/// to within its readings' rounding. A readout whose rounding stays in phase along a segment
/// (the rate a whole number of steps per reading, e.g. 10 °/min read at 10 Hz in 1″ steps: 60
/// steps) puts one offset of up to ±q/2 on the whole segment, the same for every segment of
/// that rate and phase: at each reversal `(e_after − e_before)/Δω`, the same at every reversal,
/// so it does not average down. With the two offsets uniform in ±q/2: `σ = q/√6/|Δω|` (1″ at
/// ±10 °/min: 0.34 ms), Δω the largest step between consecutive segments' rates. 0 without a
/// grid or where no turn's rounding keeps its phase ([`TurnPhases::any`]).
pub(super) fn readout_offset_sigma_s(motion: &TableMotion, phases: &TurnPhases) -> f64 {
    if !phases.any {
        return 0.0;
    }
    let step = motion
        .segments
        .windows(2)
        .map(|w| (w[1].rate_rad_s - w[0].rate_rad_s).abs())
        .fold(0.0, f64::max);
    if step > 0.0 {
        motion.quantum_rad / 6f64.sqrt() / step
    } else {
        0.0
    }
}

/// The steady lines' reference term, with the readout's rounding
/// ([`noise::ReferenceLines::with_rounding`]) unless the readout rounds coherently with its
/// whole motion ([`TurnPhases::all`]), as on bench's simulated table (every rate a whole number
/// of steps a reading, every start and reversal timed on the readings' clock). Then each line's
/// rounding is fixed by the motion before it — a turn's by its rate and phase, a rest's by the
/// line it stopped from and the stopping distance — one systematic, which lives in the time
/// offset's σ ([`readout_offset_sigma_s`]), not a new draw per line. One turn whose phase runs
/// shows the starts are not on the readings' clock: each line's rounding is then its own.
pub(super) fn reference_lines(
    motion: &TableMotion,
    bins: &[Bin],
    time_s: &[f64],
    angle_rad: &[f64],
    phases: &TurnPhases,
) -> noise::ReferenceLines {
    let lines = noise::ReferenceLines::new(motion, bins);
    if phases.all {
        lines
    } else {
        lines.with_rounding(motion, time_s, angle_rad)
    }
}

/// Whether segment `s`'s readings keep one rounding phase: read off the angles themselves, not
/// their stamps (a host's jitter moves the stamps, not the values). Each step between
/// consecutive readings, in readout steps, is a whole number of the segment's usual step `m`
/// (one reading interval, more after a lost reading) plus a slip where the rounding's phase
/// crossed a step; the phase stays put while the slips add up to less than one step over the
/// segment and nine steps in ten are whole intervals (readings taken at jittered instants
/// scatter the steps and dither the rounding). Steps that are not 1–4 intervals (a wrap, a
/// glitch) are left out.
pub(super) fn rounding_in_phase(
    s: &TableSegment,
    time_s: &[f64],
    angle_rad: &[f64],
    q: f64,
) -> bool {
    let lo = time_s.partition_point(|&t| t < s.start_s);
    let hi = time_s.partition_point(|&t| t <= s.end_s).min(angle_rad.len());
    if hi < lo + 3 {
        return false;
    }
    let steps: Vec<i64> =
        angle_rad[lo..hi].windows(2).map(|w| ((w[1] - w[0]) / q).round() as i64).collect();
    // The usual step: the most frequent one.
    let mut sorted = steps.clone();
    sorted.sort_unstable();
    let mut m = 0;
    let mut best = 0;
    for run in sorted.chunk_by(|a, b| a == b) {
        if run.len() > best {
            (best, m) = (run.len(), run[0]);
        }
    }
    if m == 0 {
        return false;
    }
    let slips: Vec<i64> = steps
        .iter()
        .filter_map(|&d| {
            let intervals = (d as f64 / m as f64).round() as i64;
            (1..=4).contains(&intervals).then_some(d - m * intervals)
        })
        .collect();
    let whole = slips.iter().filter(|&&x| x == 0).count();
    slips.iter().sum::<i64>() == 0 && whole * 10 >= slips.len() * 9
}

pub(super) struct HysteresisStateSeries(Vec<f64>);

impl HysteresisStateSeries {
    pub(super) fn new(threshold: f64, rate: &[f64]) -> Self {
        Self(bench_physics::effects::HysteresisState::series(threshold, rate))
    }
}

/// Allan deviation of the gyro minus the nominal model (table rate and thermal terms) over the
/// settled table segments of at least 60 s, pooled: the noise model's data. The refitted
/// bin residual is not used for it: the refit absorbs slow wander and would understate the
/// flicker floor several times over on a short run. Where the samples are block means, each
/// stretch carries the full-rate sums below the block (`sub`, [`crate::allan_sub`]), so the
/// curve starts at τ = dt as at full rate.
pub(super) fn native_adev(
    native: &Native,
    motion: &TableMotion,
    axis: f64,
    thermal: &[f64],
    scatter: &scatter::Scatter,
    sub: Option<&SubBlockSums>,
) -> Vec<AdevPoint> {
    let mut windows = Vec::new();
    for seg in &motion.segments {
        if seg.end_s - seg.start_s < 60.0 {
            continue;
        }
        let a = native.t.partition_point(|t| *t - 0.05 < seg.start_s);
        let b = native.t.partition_point(|t| *t <= seg.end_s);
        // Split at gaps, and around windows whose scatter exceeds the rest's (left out).
        let out = |k: usize| scatter.flagged_at(native.t[k]);
        let mut s = a;
        for k in a..=b {
            if k == b || (k > s && (native.gap_before[k] || out(k) != out(s))) {
                if k - s >= 256 && !out(s) {
                    let t = native.t[s..k].to_vec();
                    let v: Vec<f64> = (s..k)
                        .map(|i| native.v[i] - axis * native.table_rate_rad_s[i] - thermal[i])
                        .collect();
                    let zeros = vec![0.0; k - s];
                    if let Ok(w) = RecordWindow::new("segment", t, v, zeros.clone(), None, zeros) {
                        windows.push(match sub {
                            Some(sub) => w.with_sub_block(sub.pooled(&(s..k).collect::<Vec<_>>())),
                            None => w,
                        });
                    }
                }
                s = k;
            }
        }
    }
    let refs: Vec<&RecordWindow> = windows.iter().collect();
    pooled_adev(&refs)
}

/// Long-τ Allan deviation of a bin-level residual over runs of adjacent bins.
pub(super) fn bin_adev(bins: &[Bin], r: &[f64]) -> Vec<AdevPoint> {
    let mut windows = Vec::new();
    let mut s = 0;
    for k in 0..=bins.len() {
        let breaks = k == bins.len() || (k > s && bins[k].start_s > bins[k - 1].end_s + 1e-6);
        if breaks {
            if k - s >= 16 {
                let t: Vec<f64> = bins[s..k].iter().map(Bin::centre_s).collect();
                let zeros = vec![0.0; k - s];
                if let Ok(w) =
                    RecordWindow::new("bins", t, r[s..k].to_vec(), zeros.clone(), None, zeros)
                {
                    windows.push(w);
                }
            }
            s = k;
        }
    }
    let refs: Vec<&RecordWindow> = windows.iter().collect();
    pooled_adev(&refs)
}

/// Noise model from the settled segments' Allan deviation ([`native_adev`]).
pub(super) fn noise_model(prep: &Prepared) -> Result<NoiseSpec, AnalysisError> {
    fit_noise_spec_all_points(&prep.short_adev, false).ok_or_else(|| {
        AnalysisError::Insufficient(
            "diagnosis: too little steady data for an Allan-deviation noise model".into(),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 7200 readings at 10 Hz of a table turning `steps_per_reading` readout steps of 1″ per
    /// reading, read at instants jittered by `sample_jitter_s`, stamped with `stamp_jitter_s`
    /// more (deterministic pseudo-noise), reading 500 lost.
    fn readings(
        steps_per_reading: f64,
        sample_jitter_s: f64,
        stamp_jitter_s: f64,
    ) -> (TableSegment, Vec<f64>, Vec<f64>) {
        let q = bench_physics::units::ARCSEC;
        let rate = steps_per_reading * q / 0.1;
        let noise = |k: usize, salt: f64| ((k as f64 * 12.9898 + salt).sin() * 43758.5453).fract();
        let (mut t, mut a) = (Vec::new(), Vec::new());
        for k in (0..7200).filter(|&k| k != 500) {
            let ts = 0.1 * k as f64 + sample_jitter_s * (noise(k, 1.0) - 0.5) * 3.46;
            a.push(((0.3 * q + rate * ts) / q).round() * q);
            t.push(0.1 * k as f64 + stamp_jitter_s * (noise(k, 7.0) - 0.5) * 3.46);
        }
        let seg = TableSegment {
            start_s: t[0],
            end_s: t[t.len() - 1],
            angle0_rad: a[0],
            rate_rad_s: rate,
            command_rad_s: rate,
            scatter_rad: q,
            readings: t.len(),
            rate_sigma_rad_s: 0.0,
        };
        (seg, t, a)
    }

    #[test]
    fn the_rounding_phase_is_read_off_the_angles_not_their_stamps() {
        let q = bench_physics::units::ARCSEC;
        // 60 steps a reading, stamps jittered by 10 ms (the angle's duration over the stamps
        // would be off by several steps): in phase, a lost reading notwithstanding.
        let (s, t, a) = readings(60.0, 0.0, 0.010);
        assert!(rounding_in_phase(&s, &t, &a, q));
        // 60.001 steps a reading: the phase crosses 7 steps over the segment.
        let (s, t, a) = readings(60.001, 0.0, 0.0);
        assert!(!rounding_in_phase(&s, &t, &a, q));
        // 60.00001: a tenth of a step over the segment, in phase.
        let (s, t, a) = readings(60.00001, 0.0, 0.0);
        assert!(rounding_in_phase(&s, &t, &a, q));
        // Read at instants jittered by 2 ms (±1.2 steps): the rounding is dithered.
        let (s, t, a) = readings(60.0, 0.002, 0.0);
        assert!(!rounding_in_phase(&s, &t, &a, q));
    }
}
