//! `bench diagnose` end to end through the binary: a scenario conceals a warm-up in
//! `[simulation.truth.effects]`, `bench run` records it, `bench diagnose` names it (exit code 7,
//! JSON per docs/diagnose.md) — the simulated table's ripple is recorded as nominal physics, so
//! it is not named — and writes a model file (the ripple in it); the simulator loads that file
//! (the ripple going to its table), and the run it simulates diagnoses clean.

use std::path::Path;
use std::process::Command;

fn bench(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("bench runs")
}

fn scenario_with(effects: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/diagnose-demo.toml");
    let text = std::fs::read_to_string(path).expect("diagnose-demo.toml");
    format!("{text}\n{effects}\n")
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("json written")).expect("json")
}

#[test]
fn a_concealed_warm_up_is_named_modelled_and_the_updated_model_simulates_clean() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::write(
        d.join("s.toml"),
        scenario_with(
            "[simulation.truth.effects]\nwarm_up = { amplitude_rad_s = 2e-7, time_constant_s = 600 }",
        ),
    )
    .expect("write scenario");
    let run = bench(&["run", "s.toml", "--seed", "31", "--quiet", "--out", "rec.mcap"], d);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));

    let diag =
        bench(&["diagnose", "rec.mcap", "--out", "out", "--json", "d.json", "--no-report"], d);
    assert_eq!(diag.status.code(), Some(7), "{}", String::from_utf8_lossy(&diag.stderr));
    let j = json(&d.join("d.json"));
    assert_eq!(j["verdict"], "missing_physics");
    let all = j["findings"].as_array().expect("findings");
    let mut named: Vec<_> = all.iter().filter_map(|f| f["effect"].as_str()).collect();
    named.sort_unstable();
    assert_eq!(named, ["warm_up"], "{all:#?}");
    let findings: Vec<_> = all.iter().filter(|f| f["effect"] == "warm_up").collect();
    let amp = &findings[0]["parameters"]["amplitude_rad_s"];
    let (v, s) = (amp["value"].as_f64().expect("value"), amp["sigma"].as_f64().expect("sigma"));
    assert!((v - 2e-7).abs() < 3.0 * s, "amplitude {v:e} ± {s:e}");
    let ev = &findings[0]["evidence"];
    assert!(ev["delta_bic"].as_f64().is_some_and(|x| x > 0.0));
    assert!(ev["rms_after"].as_f64() < ev["rms_before"].as_f64());
    assert!(j["unexplained"].as_array().is_some_and(Vec::is_empty), "{:#}", j["unexplained"]);
    let model = std::fs::read_to_string(d.join("out/model.toml")).expect("model.toml");
    assert!(model.contains("[effects.warm_up]"), "{model}");
    assert!(model.contains("[effects.rate_ripple]"), "{model}");

    // The simulator loads the updated model (its [effects] included): the run it simulates
    // records the warm-up in bench.gyro_model, shows it, and diagnoses clean against it.
    std::fs::write(d.join("plain.toml"), scenario_with("")).expect("write scenario");
    let rerun = bench(
        &[
            "run",
            "plain.toml",
            "--seed",
            "32",
            "--quiet",
            "--gyro-model",
            "out/model.toml",
            "--out",
            "again.mcap",
        ],
        d,
    );
    assert!(rerun.status.success(), "{}", String::from_utf8_lossy(&rerun.stderr));
    let again = bench(&["diagnose", "again.mcap", "--json", "a.json", "--no-report"], d);
    let a = json(&d.join("a.json"));
    // The table ripples as the model says, no more: nothing is left to find.
    assert_ne!(a["verdict"], "missing_physics", "{:#}", a["findings"]);
    assert_ne!(again.status.code(), Some(7));
}
