//! `bench calibrate` on short simulated runs with known truth: the joint fit recovers the
//! simulator's model within its stated errors and removes the thermal error; its files load
//! back; a recording lacking what calibration needs says what is missing.

use std::path::PathBuf;

use bench::runner::simulate_in_memory;
use bench::simulate::capabilities;
use bench_recording::model_file::{CalibrationFile, ModelKeys, Source, Uncertainty};
use bench_recording::Recording;
use bench_report::calibrate::{calibrate_recording, json, CalibrateError, CalibrateSettings};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn simulate(scenario: &str, seed: u64) -> Recording {
    let plan = bench::scenario::load(&workspace().join(scenario), &capabilities()).expect("valid");
    let (report, bytes) = simulate_in_memory(&plan, seed).expect("runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    Recording::from_bytes(&bytes).expect("reads back")
}

fn settings() -> CalibrateSettings {
    CalibrateSettings { replicates: Some(50), ..CalibrateSettings::default() }
}

#[test]
fn thermal_short_is_recovered_within_the_stated_errors_and_the_files_load_back() {
    let rec = simulate("scenarios/thermal-short.toml", 11);
    let out = calibrate_recording(&rec, &settings()).expect("calibrates");
    let cal = &out.calibration;
    assert_eq!(cal.windows.len(), 10, "6 plateaus + 4 ramps");
    assert!(cal.missing.is_empty(), "{:?}", cal.missing);
    let truth = out.truth.as_ref().expect("the recording holds the simulator's model");
    let joint = cal.joint.as_ref().expect("joint fit");
    for (name, e, t) in [
        ("bias", joint.bias, truth.model.bias),
        ("scale_factor_error", joint.scale_factor_error, truth.model.scale_factor_error),
        ("temp_coeff", joint.temp_coeff, truth.model.temp_coeff),
        ("temp_rate_coeff", joint.temp_rate_coeff, truth.model.temp_rate_coeff),
    ] {
        // 4σ: one seed, four coefficients; a miss here is a real miss, not bad luck.
        assert!((e.value - t).abs() <= 4.0 * e.std_err, "{name}: {e:?} vs truth {t}");
        assert!(e.std_err >= e.naive_std_err, "{name}: {e:?}");
    }
    // The temperature terms to a few per cent, and most of the thermal error removed.
    assert!((joint.temp_coeff.value / truth.model.temp_coeff - 1.0).abs() < 0.15);
    assert!((joint.temp_rate_coeff.value / truth.model.temp_rate_coeff - 1.0).abs() < 0.1);
    let removed = truth.joint_removal.expect("removal").removed();
    assert!(removed >= 0.9, "removed {removed}");
    // The noise terms: ARW within its interval of the truth's (white noise is exact in the sim).
    let allan = cal.allan.as_ref().expect("allan");
    assert!(
        allan.fit.arw.low <= truth.model.arw * 1.05 && truth.model.arw <= allan.fit.arw.high * 1.05,
        "{:?} vs {}",
        allan.fit.arw,
        truth.model.arw
    );
    // The seed method ran on the same windows.
    let seed = cal.seed.as_ref().expect("seed method");
    assert_eq!(seed.plateaus.len(), 3);
    assert!(seed.temp_rate_coeff.is_some());

    // The calibration file round-trips into the model `bench run --gyro-model` loads.
    let model = out.model.clone().expect("model");
    let file = CalibrationFile {
        source: Source::default(),
        gyro_model: ModelKeys::from(&model),
        uncertainty: Uncertainty::default(),
        effects: Default::default(),
        held: Default::default(),
        covariance: None,
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("calibration.toml");
    file.save(&path).expect("writes");
    assert_eq!(CalibrationFile::load(&path).expect("loads").model(), model);

    // The JSON holds the contract's keys with value and sigma, and the seed method beside.
    let j = serde_json::to_value(json::to_json(&out, "x.mcap")).expect("json");
    for key in ["bias", "scale_factor_error", "temp_coeff", "temp_rate_coeff"] {
        let c = &j["coefficients"][key];
        assert!(c["value"].is_f64() && c["sigma"].as_f64().is_some_and(|s| s > 0.0), "{key}: {c}");
    }
    assert_eq!(j["reference_temperature"], 20.0);
    assert_eq!(j["seed_method"]["temp_coeff"].as_f64(), Some(seed.temp_coeff));
    assert!(j["noise"]["arw"]["value"].as_f64().is_some());
}

#[test]
fn what_is_missing_is_said_and_what_remains_is_estimated() {
    let mut rec = simulate("scenarios/seed.toml", 3);
    // No latitude: Earth's rate stays in the bias, the rest is estimated.
    rec.metadata.retain(|m| m.name != "bench.site");
    let out = calibrate_recording(&rec, &settings()).expect("calibrates without a site");
    assert!(
        out.calibration.missing.iter().any(|m| m.contains("no latitude")),
        "{:?}",
        out.calibration.missing
    );
    assert!(out.calibration.joint.is_ok());

    // Only the plateau windows: no ramps, so no temperature-rate term.
    let mut plateaus = rec.clone();
    plateaus.steps.retain(|s| !s.msg.label.contains("ramp"));
    let out = calibrate_recording(&plateaus, &settings()).expect("plateaus alone");
    let missing = &out.calibration.missing;
    assert!(missing.iter().any(|m| m.contains("no ramp windows")), "{missing:?}");
    let seed = out.calibration.seed.as_ref().expect("two plateaus are enough for the seed's k_t");
    assert_eq!(seed.plateaus.len(), 2);
    assert_eq!(seed.temp_rate_coeff, None);

    // One turning direction (the CW steps): bias and scale factor are one column. The scale
    // factor is held and said so; the noise model is still measured (the thermal model's
    // residual is the same whichever split of that column is taken) and the rest is fitted
    // under it. (Before: no noise model, an OLS fit and a NaN whitened RMS.)
    let mut cw = rec.clone();
    cw.steps.retain(|s| !s.msg.label.contains("ccw"));
    let out = calibrate_recording(&cw, &settings()).expect("one direction");
    let cal = &out.calibration;
    assert_eq!(cal.windows.len(), 3);
    assert!(cal.held[1].is_some() && cal.held.iter().filter(|h| h.is_some()).count() == 1);
    assert!(cal.noise_model.is_some(), "{:?}", cal.missing);
    let j = cal.joint.as_ref().expect("joint fit of the rest");
    assert_eq!(j.estimator, bench_analysis::joint_fit::Estimator::Gls);
    assert!((0.8..1.25).contains(&j.whitened_residual_rms), "{}", j.whitened_residual_rms);
    let truth = out.truth.as_ref().expect("simulated").model.clone();
    for (e, t) in [(j.temp_coeff, truth.temp_coeff), (j.temp_rate_coeff, truth.temp_rate_coeff)] {
        assert!((e.value - t).abs() <= 4.0 * e.std_err, "{e:?} vs {t}");
    }
    assert_eq!(out.quality.verdict, "incomplete");

    // No record steps at all.
    let mut none = rec.clone();
    none.steps.retain(|s| !s.msg.label.starts_with("record"));
    match calibrate_recording(&none, &settings()) {
        Err(e @ CalibrateError::NoRecordWindows { .. }) => {
            assert!(e.to_string().contains("record"), "{e}")
        }
        other => panic!("expected NoRecordWindows, got {:?}", other.map(|o| o.calibration.missing)),
    }
}

/// Issue 27's soak-only case: plateaus and no ramps. k_dt is not determined by the run: held
/// at the nominal model's value, named with the reason and the run that would determine it,
/// never written as measured; the calibration is incomplete, and it does not make the gyro
/// worse on a ramp run of the same simulated gyro. (Before: k_dt −0.045 ± 0.051
/// °/h/(°C/min) for a true +0.0505, "sound", thermal error "removed" −67 %.)
#[test]
fn a_soak_only_run_holds_k_dt_says_why_and_does_not_make_a_ramp_run_worse() {
    let rec = simulate("scenarios/soak-only.toml", 1);
    let out = calibrate_recording(&rec, &settings()).expect("calibrates");
    let cal = &out.calibration;
    let truth = out.truth.as_ref().expect("simulated").model.clone();
    let held = cal.held[3].as_ref().expect("k_dt held");
    assert_eq!(held.value, truth.temp_rate_coeff, "held at the nominal (here the simulator's)");
    assert!(!held.determination.determined());
    assert!(cal.held[..3].iter().all(Option::is_none), "{:?}", cal.held);
    assert!(cal.incomplete());
    assert_eq!(out.quality.verdict, "incomplete");
    let j = cal.joint.as_ref().expect("joint fit of the rest");
    assert!(j.temp_rate_coeff.held && !j.temp_coeff.held);
    for (e, t) in [(j.bias, truth.bias), (j.temp_coeff, truth.temp_coeff)] {
        assert!((e.value - t).abs() <= 4.0 * e.std_err, "{e:?} vs {t}");
    }
    // The thermal error this calibration leaves is smaller than the one it takes out.
    let removed = out.truth.as_ref().and_then(|t| t.joint_removal).expect("removal").removed();
    assert!(removed > 0.8, "removed {removed}");
    // The JSON: held, with reason and determination, not among the coefficients.
    let js = serde_json::to_value(json::to_json(&out, "soak.mcap")).expect("json");
    assert_eq!(js["version"], 3);
    assert_eq!(js["fit"]["verdict"], "incomplete");
    assert!(js["coefficients"].get("temp_rate_coeff").is_none());
    let h = &js["held"]["temp_rate_coeff"];
    assert_eq!(h["source"], "nominal");
    assert!(h["reason"].as_str().is_some_and(|r| r.contains("2.80σ")), "{h}");
    assert!(h["determination"].as_str().is_some_and(|d| d.contains("ramps")), "{h}");
    assert_eq!(js["covariance_keys"].as_array().map(Vec::len), Some(3));
    assert_eq!(js["identifiability"]["temp_rate_coeff"]["verdict"], "too_small");

    // Verified on a ramp run (thermal-short, another seed) of the same simulated gyro.
    let model = out.model.clone().expect("model");
    let mut file = CalibrationFile::new(
        &model,
        &Default::default(),
        Source::default(),
        Uncertainty::default(),
    );
    file.held.insert(
        "temp_rate_coeff_rad_s_per_c_s".into(),
        bench_recording::model_file::HeldEntry {
            value: model.temp_rate_coeff,
            sigma: None,
            source: "nominal".into(),
            reason: String::new(),
            determination: String::new(),
        },
    );
    let ramps = simulate("scenarios/thermal-short.toml", 2);
    let v = bench_report::verify::verify_recording(&ramps, &file).expect("verifies");
    let c = &v.compensation;
    assert!(!c.worse, "{c:?}");
    assert!(c.rms_compensated < c.rms_uncompensated, "{c:?}");
}

/// `thermal-short`'s calibration applied to `thermal-full` with another seed: every window's
/// compensated error within what the calibration states (|z| ≤ 3), and a verification pass;
/// the same file with k_dt of the wrong sign and seven times too large makes the gyro worse,
/// and k_dt is named.
#[test]
fn thermal_shorts_calibration_holds_on_thermal_full_and_a_wrong_k_dt_is_named() {
    use bench_report::verify::{verify_recording, VerifyVerdict};
    let out = calibrate_recording(&simulate("scenarios/thermal-short.toml", 11), &settings())
        .expect("calibrates");
    assert!(!out.calibration.incomplete(), "{:?}", out.calibration.held);
    let model = out.model.clone().expect("model");
    let j = out.calibration.joint.as_ref().expect("joint");
    let mut file = CalibrationFile::new(
        &model,
        &Default::default(),
        Source::default(),
        Uncertainty::default(),
    );
    file.covariance = Some(bench_recording::model_file::CovarianceSection {
        keys: bench_recording::model_file::HOLDABLE_KEYS.iter().map(|k| k.1.to_owned()).collect(),
        matrix: j.covariance.iter().map(|r| r.to_vec()).collect(),
    });
    let full = simulate("scenarios/thermal-full.toml", 12);
    let v = verify_recording(&full, &file).expect("verifies");
    let c = &v.compensation;
    assert!(c.windows.len() >= 14, "{}", c.windows.len());
    assert!(c.max_abs_z <= 3.0, "worst |z| {}: {:?}", c.max_abs_z, c.windows);
    assert!(c.rms_compensated < 0.3 * c.rms_uncompensated, "{c:?}");
    assert_eq!(v.verdict, VerifyVerdict::Pass);
    // Loaded into the gyro with a wrong k_dt, the file would make it worse: FAIL, k_dt named.
    let mut wrong = file.clone();
    wrong.gyro_model.0.temp_rate_coeff = -7.0 * model.temp_rate_coeff;
    let v = verify_recording(&full, &wrong).expect("verifies");
    assert_eq!(v.verdict, VerifyVerdict::Worse);
    assert_eq!(
        v.compensation.responsible.map(|r| r.0),
        Some(bench_physics::ModelKey::TempRateCoeff)
    );
}
