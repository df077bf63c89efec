//! End to end against the simulator's own truth model (`bench_physics::gyro::GyroSampler`):
//! a seed-style procedure at 59.94° N with a 300 s thermal lag, gyro temperature read in
//! 0.01 °C steps and chamber air in 0.1 °C steps.

use bench_analysis::joint_fit::{joint_fit, JointFitOptions};
use bench_analysis::seed_method::{seed_calibration, SeedOptions};
use bench_analysis::RecordWindow;
use bench_physics::gyro::{GyroSampler, Mounting};
use bench_physics::lag::FirstOrderLag;
use bench_physics::units::{quantise, DEG_PER_MIN};
use bench_physics::GyroModel;

const DT: f64 = 0.05;
const LAT: f64 = 59.94;
const OMEGA: f64 = 10.0 * DEG_PER_MIN;

/// One step: label (`None` = not recorded), table rate, air temperature at start and its
/// rate (°C/s), duration (s).
type Step = (Option<&'static str>, f64, f64, f64, f64);

fn run(model: &GyroModel, steps: &[Step]) -> Vec<RecordWindow> {
    let t_air0 = steps[0].2;
    let mut gyro = GyroSampler::new(
        model.clone(),
        DT,
        42,
        0,
        Mounting { latitude_deg: LAT, axis_up: true },
        t_air0,
    );
    let mut lag = FirstOrderLag::new(model.thermal_time_constant, t_air0);
    let (mut t, mut angle) = (0.0, 0.0);
    let mut out = Vec::new();
    for &(label, table, air0, air_rate, secs) in steps {
        let n = (secs / DT).round() as usize;
        let mut cols: [Vec<f64>; 5] = Default::default();
        for i in 0..n {
            let u0 = air0 + air_rate * i as f64 * DT;
            let u1 = air0 + air_rate * (i + 1) as f64 * DT;
            let temp = lag.step_linear(u0, u1, DT);
            t += DT;
            angle += table * DT;
            let v = gyro.sample(t, angle, temp).total();
            for (c, x) in cols.iter_mut().zip([
                t,
                v,
                table,
                GyroSampler::temperature_readout(temp),
                quantise(u1, 0.1),
            ]) {
                c.push(x);
            }
        }
        if let Some(label) = label {
            let [time, v, table, gyro_t, air] = cols;
            out.push(
                RecordWindow::new(label, time, v, table, Some(gyro_t), air).expect("valid window"),
            );
        }
    }
    out
}

/// The seed's gyro (`GyroModel::default()`) without the bias instability.
fn white_only() -> GyroModel {
    GyroModel { bias_instability: 0.0, ..GyroModel::default() }
}

fn procedure() -> Vec<Step> {
    let ramp = 2.0 / 60.0; // 2 °C/min, the seed's largest dT/dt
    vec![
        (Some("record cw 0C"), -OMEGA, 0.0, 0.0, 600.0),
        (Some("record ccw 0C"), OMEGA, 0.0, 0.0, 600.0),
        (Some("record cw ramp up"), -OMEGA, 0.0, ramp, 1200.0),
        (None, OMEGA, 40.0, 0.0, 1800.0), // soak: 6 thermal time constants
        (Some("record ccw 40C"), OMEGA, 40.0, 0.0, 600.0),
        (Some("record cw 40C"), -OMEGA, 40.0, 0.0, 600.0),
        (Some("record ccw ramp down"), OMEGA, 40.0, -ramp, 1200.0),
    ]
}

#[test]
fn joint_fit_recovers_the_simulators_model_and_the_seed_method_does_without_scale_factor() {
    // White noise only (the seed's ARW): the bootstrap's errors hold; see the flicker test
    // below for why the default bias instability is left out here.
    let model = GyroModel { bias: 2e-6, ..white_only() };
    let ws = run(&model, &procedure());
    let opts = JointFitOptions {
        latitude_deg: Some(LAT),
        reference_temperature_c: model.reference_temperature,
        replicates: 200,
        ..JointFitOptions::default()
    };
    let fit = joint_fit(&ws, &opts).expect("identifiable");
    let checks = [
        ("bias", fit.bias, model.bias),
        ("scale_factor_error", fit.scale_factor_error, model.scale_factor_error),
        ("temp_coeff", fit.temp_coeff, model.temp_coeff),
        ("temp_rate_coeff", fit.temp_rate_coeff, model.temp_rate_coeff),
    ];
    for (name, e, truth) in checks {
        // Three standard errors, plus the model mismatch of dT/dt from a lagged, quantised
        // temperature (0.07 % on temp_rate_coeff, 0.18 % on temp_coeff noise-free).
        let allowance = 3.0 * e.std_err + 2e-3 * truth.abs();
        assert!((e.value - truth).abs() <= allowance, "{name}: {e:?} vs {truth}");
        // White noise: the two agree up to the bootstrap's sampling error.
        assert!(e.std_err >= 0.8 * e.naive_std_err, "{name}: {e:?}");
    }
    assert!((fit.temp_rate_coeff.value / model.temp_rate_coeff - 1.0).abs() < 0.01);
    assert!((fit.temp_coeff.value / model.temp_coeff - 1.0).abs() < 0.2);

    let seed =
        seed_calibration(&ws, &SeedOptions { latitude_deg: Some(LAT), ..SeedOptions::default() })
            .expect("two plateaus");
    assert_eq!(seed.plateaus.len(), 2);
    assert!((seed.bias_rad_s - model.bias).abs() < 0.05 * model.bias);
    let kdt = seed.temp_rate_coeff.expect("ramps");
    assert!((kdt / model.temp_rate_coeff - 1.0).abs() < 0.05, "{kdt}");
}

/// The seed's slope through the origin leaves the scale-factor term `s·Ω` in the ramp
/// residual; with a CW ramp up and a CCW ramp down it does not cancel (Ω and dT/dt flip
/// together), so a scale-factor error of 100 ppm biases k_dt by `−s·ω·Σ|d|/Σd²`, at least
/// `s·ω/(dT/dt)_max` in size (the lagged gyro ramps more slowly than the air at first): about
/// −60 % here. The joint fit models it.
#[test]
fn scale_factor_error_biases_the_seed_k_dt_but_not_the_joint_fit() {
    let model = GyroModel { scale_factor_error: 1e-4, ..white_only() };
    let ws = run(&model, &procedure());
    let fit = joint_fit(
        &ws,
        &JointFitOptions { latitude_deg: Some(LAT), replicates: 100, ..JointFitOptions::default() },
    )
    .expect("identifiable");
    let e = fit.temp_rate_coeff;
    let allowance = 3.0 * e.std_err + 2e-3 * model.temp_rate_coeff;
    assert!((e.value - model.temp_rate_coeff).abs() <= allowance, "{e:?}");
    let sf = fit.scale_factor_error;
    assert!((sf.value - 1e-4).abs() <= 3.0 * sf.std_err, "{sf:?}");
    let seed =
        seed_calibration(&ws, &SeedOptions { latitude_deg: Some(LAT), ..SeedOptions::default() })
            .expect("two plateaus");
    let kdt = seed.temp_rate_coeff.expect("ramps");
    let least = 1e-4 * OMEGA / (2.0 / 60.0);
    let seed_err = kdt - model.temp_rate_coeff;
    assert!(
        -1.5 * least < seed_err && seed_err < -least,
        "seed k_dt {kdt}, truth {}, least bias {least}",
        model.temp_rate_coeff
    );
    assert!((e.value - model.temp_rate_coeff).abs() < 0.05 * seed_err.abs());
}

/// Known limit: the default model's bias instability (flicker floor 0.0019 °/h, synthesised
/// with correlation times up to 30 000 s) drifts over the whole 1.8 h procedure. A moving-block
/// bootstrap cannot see correlation longer than its blocks, so its standard errors are too
/// small here (the temp-rate error is several bootstrap SEs), though the fit itself stays within
/// a few per cent. This test pins both facts so a better error model shows up as a change.
#[test]
fn flicker_noise_longer_than_the_record_is_beyond_the_block_bootstrap() {
    let model = GyroModel::default();
    let ws = run(&model, &procedure());
    let fit = joint_fit(
        &ws,
        &JointFitOptions { latitude_deg: Some(LAT), replicates: 100, ..JointFitOptions::default() },
    )
    .expect("identifiable");
    let e = fit.temp_rate_coeff;
    let err = (e.value - model.temp_rate_coeff).abs();
    assert!(err < 0.05 * model.temp_rate_coeff, "{e:?}");
    assert!(err > 3.0 * e.std_err, "bootstrap SE now covers flicker drift: {e:?}, error {err}");
}
