//! `bench soak` through the binary, short: half an hour of bench time through the virtual ports
//! at the default 60× (≈ 30 s of wall time), faults injected at random. The 24 h soak is not a
//! test (`docs/soak.md`).

use std::process::Command;

#[test]
fn a_half_hour_soak_records_every_sample_that_arrived_and_gives_each_fault_an_outcome() {
    let t0 = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_bench"))
        .args(["soak", "--hours", "0.5", "--seed", "1", "--json", "-"])
        .output()
        .expect("bench runs");
    let wall = t0.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("JSON on stdout ({e}); stderr: {stderr}"));
    let code = out.status.code();
    let passed = v["passed"].as_bool().expect("passed");
    assert_eq!(code, Some(if passed { 0 } else { 10 }), "{:#}", v["problems"]);
    assert!(wall < 60.0, "took {wall:.1} s");

    // Shape.
    for key in ["seed", "bench_time_s", "wall_time_s", "time_scale", "achieved_time_scale"] {
        assert!(v[key].is_number(), "{key}: {}", v[key]);
    }
    assert!(v["bench_time_s"].as_f64().expect("bench time") >= 1800.0);
    assert_eq!(v["time_scale"].as_f64(), Some(60.0));
    let m = &v["memory"];
    assert!(m["samples"].as_array().is_some_and(|s| s.len() >= 3), "{m}");
    for key in ["start_mib", "end_mib", "peak_mib", "limit_mib_per_h"] {
        assert!(m[key].as_f64().is_some_and(|x| x > 0.0), "{key}: {m}");
    }
    assert_eq!(m["verdict"], "not judged", "half an hour is too short to judge");
    assert!(m["note"].as_str().is_some_and(|n| n.contains("too short to judge memory growth")));
    assert!(v["segments"].as_array().is_some_and(|s| !s.is_empty()));

    // Per channel: every sample sent intact was recorded, on every wire channel.
    let channels = v["channels"].as_array().expect("channels");
    let topics: Vec<&str> = channels.iter().filter_map(|c| c["topic"].as_str()).collect();
    for t in ["/gyro/rate", "/table/state", "/chamber/state", "/bench/step", "/log"] {
        assert!(topics.contains(&t), "{t} missing from {topics:?}");
    }
    for c in channels.iter().filter(|c| c["sent"].is_u64()) {
        let n = |k: &str| c[k].as_u64().unwrap_or_else(|| panic!("{k} in {c}"));
        assert!(n("sent") > 1000, "{c}");
        assert_eq!(n("recorded"), n("sent"), "recorded == sent intact: {c}");
        assert_eq!(c["lost"], 0, "{c}");
    }

    // At least one fault, each with its outcome.
    let faults = v["faults"].as_array().expect("faults");
    assert!(!faults.is_empty());
    for f in faults {
        assert!(f["at_s"].as_f64().is_some_and(|t| t >= 59.0), "{f}");
        assert!(f["kind"].is_string() && f["device"].is_string(), "{f}");
        let outcome = f["outcome"].as_str().expect("outcome");
        let known = ["recovered", "aborted_by_design", "overtaken", "unexpected"];
        assert!(known.contains(&outcome), "{f}");
        if ["aborted_by_design", "overtaken"].contains(&outcome) {
            assert!(f["abort"].is_string(), "{f}");
        }
    }
}
