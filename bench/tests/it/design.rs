//! `bench design`: a designed scenario validates, and its predicted σ is what a Monte Carlo of
//! the calibration on it achieves.

use bench::design::{self, Goal, Grid, Limits, Subject};
use bench_physics::GyroModel;

use crate::common::{bench, text, text_of};

/// The two-sided χ² quantile with `n` degrees of freedom at standard-normal `z`
/// (Wilson–Hilferty).
fn chi2(n: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * n);
    n * (1.0 - a + z * a.sqrt()).powi(3)
}

#[test]
fn a_designed_short_run_achieves_its_predicted_sigma_over_seeds() {
    let caps = bench::simulate::capabilities();
    let limits = Limits::of(&caps);
    let subject = Subject { model: GyroModel::default(), latitude_deg: 59.94, initial_c: 20.0 };
    // Targets a run of about an hour reaches (the bias, held by the flicker floor, is free).
    let targets = [None, Some(1.5e-6), Some(3e-10), Some(1.5e-5)];
    let grid = Grid {
        ramps_c_min: vec![2.0, 3.0],
        table_deg_min: vec![10.0, 30.0],
        reversal_min: vec![5.0, 10.0],
        hold_min: vec![0.0],
        max_legs: 4,
        dt_s: 5.0,
    };
    let found = design::search(&subject, &limits, &grid, Goal::Targets(targets)).expect("reaches");
    let tl = found.procedure.timeline().expect("timeline");
    let setup = design::ScenarioSetup {
        latitude_deg: 59.94,
        axis_up: true,
        sample_rate_hz: 20.0,
        model: subject.model.clone(),
    };
    let text = tl.scenario(&found.procedure, "designed", "a test design", &setup);
    let plan = bench::scenario::parse(&text, "designed", &caps).expect("validates");
    let predicted = design::predict_plan(&plan, &subject.model, false).expect("predicts");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("designed.toml");
    std::fs::write(&path, &text).expect("write");
    let n = 16;
    let mc = bench::study::calibrate::run(
        &path,
        1,
        n,
        2,
        &bench_report::calibrate::CalibrateSettings::default(),
        None,
        |_| {},
    )
    .expect("monte carlo");
    // n·(RMS error / σ)² is χ²(n) when σ is right: its two-sided 99.9 % interval, Bonferroni
    // over the coefficients checked.
    let z = 3.48; // z(1 − 0.001/8)
    let (lo, hi) = ((chi2(n as f64, -z) / n as f64).sqrt(), (chi2(n as f64, z) / n as f64).sqrt());
    for (j, key) in ["scale_factor_error", "temp_coeff", "temp_rate_coeff"].iter().enumerate() {
        let c = mc.coefficients.iter().find(|c| c.key == *key).expect("coefficient");
        let gls = c.of("rate_gls").expect("rate gls");
        let ratio = gls.rms_error / predicted.sigma[j + 1];
        assert!(
            ratio > lo && ratio < hi,
            "{key}: RMS error / predicted σ {ratio:.3} outside {lo:.2}..{hi:.2}"
        );
        // And what the calibration states is the bound it was designed for.
        let stated = gls.rms_sigma / predicted.sigma[j + 1];
        assert!((stated - 1.0).abs() < 0.25, "{key}: stated σ / predicted {stated:.3}");
    }
}

#[test]
fn bench_design_writes_a_scenario_that_validates_and_refuses_what_cannot_be_reached() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let o = bench(&["design", "--sigma", "sf=2ppm,k_t=3e-10,k_dt=1.5e-5", "--out", "d.toml"], d);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text_of(&o));
    assert!(out.contains("flicker floor") && out.contains("of chamber time"), "{out}");
    let v = bench(&["validate", "d.toml"], d);
    assert!(v.status.success(), "{}", text_of(&v));
    // The same output again without --force: refused, the file kept.
    let again = bench(&["design", "--sigma", "sf=2ppm", "--out", "d.toml"], d);
    assert_eq!(again.status.code(), Some(1), "{}", text_of(&again));
    // A bias far below the flicker floor: no procedure reaches it; the bound is shown.
    let never = bench(&["design", "--sigma", "bias=1e-6°/h"], d);
    assert_eq!(never.status.code(), Some(13), "{}", text_of(&never));
    assert!(text(&never.stdout).contains("the bound"), "{}", text_of(&never));
    // Bad targets and budgets are usage errors.
    for bad in
        [["--sigma", "k_x=1"], ["--sigma", "sf=2furlongs"], ["--sigma", "sf=-1"], ["--hours", "0"]]
    {
        let o = bench(&["design", bad[0], bad[1]], d);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", text_of(&o));
    }
}
