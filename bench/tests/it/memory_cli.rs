//! `bench memory`, the analyses' memory benchmark: each analysis from the file as its command
//! runs it (read as a stream with the gyro reduced, arrays, analysis), every phase measured, the
//! peak per gyro message computed from the peak and the file's gyro messages.

use crate::common::{bench, json, recording, text_of};

#[test]
fn the_memory_benchmark_measures_every_phase_of_both_analyses() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rec = recording("demo-null.mcap");
    let rec = rec.to_str().expect("utf-8 path");
    let out =
        bench(&["memory", rec, "--quiet", "--replicates", "20", "--json", "m.json"], dir.path());
    assert!(out.status.success(), "{}", text_of(&out));
    let j = json(&dir.path().join("m.json"));
    let messages =
        bench_recording::Recording::load(std::path::Path::new(rec)).expect("reads").gyro.len();
    assert_eq!(j["gyro_messages"].as_u64(), Some(messages as u64));
    assert!(j["usable_samples"].as_u64().is_some_and(|n| n > 0 && n <= messages as u64));
    // A 20 Hz file: every sample kept as it is.
    assert_eq!(j["gyro_block_len"].as_u64(), Some(1));
    let phases = j["phases"].as_array().expect("phases");
    let names: Vec<&str> = phases.iter().filter_map(|p| p["phase"].as_str()).collect();
    assert_eq!(
        names,
        ["read and reduce", "load", "calibrate", "read and reduce", "load", "diagnose"]
    );
    for p in phases {
        let peak = p["peak_rss_mib"].as_f64().expect("Linux reports VmHWM");
        let per = p["peak_bytes_per_gyro_message"].as_f64().expect("per message");
        assert!(peak > 1.0 && p["wall_s"].as_f64().is_some_and(|w| w >= 0.0), "{p}");
        assert!((per - peak * 1048576.0 / messages as f64).abs() <= 1e-6 * per, "{p}");
    }
    let table = text_of(&out);
    assert!(table.contains("| calibrate |") && table.contains("| diagnose |"), "{table}");
}
