//! Issue 27 through the binary: a calibration that holds what its run does not determine (exit
//! 5, `HELD …` on the terminal, `[held]` in `calibration.toml`, never among the measured
//! values), and `bench verify` applying it to another run (exit 0), or failing a file that
//! makes the gyro worse with the coefficient responsible named (exit 11).

use crate::common::{bench, scenario, text};

#[test]
fn a_soak_only_calibration_is_incomplete_and_verify_judges_it_on_a_ramp_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let r = bench(&["run", &scenario("soak-only.toml"), "-q", "-o", "soak.mcap"], d);
    assert_eq!(r.status.code(), Some(0), "{}", text(&r.stderr));
    let r =
        bench(&["calibrate", "soak.mcap", "-q", "--no-report", "-o", "cal", "--json", "c.json"], d);
    let err = text(&r.stderr);
    assert_eq!(r.status.code(), Some(5), "{err}");
    assert!(err.contains("HELD temp_rate_coeff at"), "{err}");
    assert!(err.contains("the run that would determine it: record windows while the chamber ramps"));
    let toml = std::fs::read_to_string(d.join("cal/calibration.toml")).expect("calibration.toml");
    let gyro = toml.split("[gyro_model]").nth(1).and_then(|t| t.split("\n[").next()).expect("");
    assert!(!gyro.contains("temp_rate_coeff"), "held, never among the measured: {toml}");
    assert!(toml.contains("[held.temp_rate_coeff_rad_s_per_c_s]") && toml.contains("[covariance]"));

    // The same simulated gyro on a run with ramps: not worse, within what the file states.
    let r = bench(
        &["run", &scenario("thermal-short.toml"), "-q", "--seed", "2", "-o", "ramps.mcap"],
        d,
    );
    assert_eq!(r.status.code(), Some(0), "{}", text(&r.stderr));
    let r = bench(
        &[
            "verify",
            "ramps.mcap",
            "--calibration",
            "cal/calibration.toml",
            "-o",
            "ver",
            "--json",
            "v.json",
        ],
        d,
    );
    let out = text(&r.stdout);
    assert_eq!(r.status.code(), Some(0), "{out}{}", text(&r.stderr));
    assert!(out.contains("held in the calibration: temp_rate_coeff_rad_s_per_c_s"), "{out}");
    assert!(out.contains("verification: PASS"), "{out}");
    assert!(d.join("ver/report.html").exists() && d.join("ver/fig1-window-errors.png").exists());
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("v.json")).expect("json")).expect("json");
    assert_eq!(v["verdict"], "pass");
    let c = &v["compensation"];
    assert!(c["rms_compensated"].as_f64() < c["rms_uncompensated"].as_f64(), "{c}");

    // The file with k_dt written as measured, of the wrong sign and 7× too large (the issue's
    // −0.37 °/h/(°C/min) for +0.05): verify fails it as worse and names k_dt.
    let held = toml.find("\n[held.").expect("held section");
    let cov = toml.find("\n[covariance]").expect("covariance");
    let wrong = format!("{}{}", &toml[..held], &toml[cov..])
        .replace("[gyro_model]\n", "[gyro_model]\ntemp_rate_coeff_rad_s_per_c_s = -1.06e-4\n");
    std::fs::write(d.join("wrong.toml"), wrong).expect("write");
    let r = bench(&["verify", "ramps.mcap", "-c", "wrong.toml", "--no-report"], d);
    let out = text(&r.stdout);
    assert_eq!(r.status.code(), Some(11), "{out}{}", text(&r.stderr));
    assert!(out.contains("`temp_rate_coeff` is responsible"), "{out}");
}
