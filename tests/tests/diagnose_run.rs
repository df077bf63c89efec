//! `bench diagnose` on recordings of the simulated bench: a run whose truth is the nominal
//! model gives no finding; the files it writes load back.

use std::io::Cursor;
use std::path::PathBuf;

use bench::diagnose::{diagnose_recording, json};
use bench::recording::Recording;
use bench::simulate::{capabilities, run_plan, SimOptions};
use bench_analysis::diagnose::{DiagnoseOptions, Verdict};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn simulate_text(text: &str, seed: u64) -> Recording {
    let plan = bench::scenario::parse(text, "test.toml", &capabilities()).expect("valid");
    let (report, cursor) = run_plan(
        &plan,
        Cursor::new(Vec::new()),
        &SimOptions { seed, ..SimOptions::default() },
        None,
    )
    .expect("runs");
    assert_eq!(report.outcome, "completed");
    Recording::from_bytes(cursor.get_ref()).expect("reads back")
}

fn scenario(name: &str) -> String {
    std::fs::read_to_string(workspace().join("scenarios").join(name)).expect("scenario")
}

#[test]
fn a_run_whose_truth_is_the_nominal_model_has_no_finding() {
    let rec = simulate_text(&scenario("thermal-short.toml"), 21);
    let started = std::time::Instant::now();
    let out = diagnose_recording(&rec, None, &DiagnoseOptions::default()).expect("diagnoses");
    eprintln!("diagnosed in {:.2} s", started.elapsed().as_secs_f64());
    let d = &out.diagnosis;
    let found: Vec<_> = d.findings.iter().filter(|f| f.accepted).map(|f| f.effect.key()).collect();
    assert!(found.is_empty(), "{found:?}");
    assert!(d.unexplained.is_empty(), "{:?}", d.unexplained);
    assert_ne!(d.verdict, Verdict::MissingPhysics);
    // The JSON carries the contract's fields.
    let j = json::to_json(&out, "null.mcap");
    assert_eq!(j["version"], 1);
    assert!(j["verdict"] == "consistent" || j["verdict"] == "parameters_only");
    assert!(j["parameter_updates"]["bias"]["sigma"].as_f64().is_some_and(|s| s > 0.0));
    assert_eq!(j["findings"].as_array().map(Vec::len), Some(0));
}
