//! Record → replay → re-record: `scenarios/seed.toml` on the simulated bench, then the same
//! scenario against the replay of that recording in virtual time. The re-recorded device
//! streams must equal the original's, message for message (log time, publish time, sequence,
//! every field), and so must the step events.

use std::io::Cursor;
use std::path::PathBuf;
use std::sync::Arc;

use bench::replay::ReplayData;
use bench_recording::Recording;

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn record_seed() -> Vec<u8> {
    let path = workspace().join("scenarios/seed.toml");
    let plan = bench::scenario::load(&path, &bench::simulate::capabilities()).expect("valid");
    let (report, bytes) = bench::runner::simulate_in_memory(&plan, 3).expect("runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    bytes
}

#[test]
fn a_replayed_run_re_records_the_original_device_streams() {
    let original_bytes = record_seed();
    let original = Recording::from_bytes(&original_bytes).expect("readable");
    let data = Arc::new(ReplayData::from_recording(&original, "seed.mcap").expect("replayable"));
    assert_eq!(data.gyro_rate_hz(), 20.0);

    // The scenario validates against what the replay offers, and runs on it in virtual time.
    let path = workspace().join("scenarios/seed.toml");
    let plan = bench::scenario::load(&path, &data.capabilities()).expect("valid on the replay");
    let bench = bench::runner::Bench::Replay(data.clone());
    let (report, cursor) =
        bench::runner::run(&plan, bench, Cursor::new(Vec::new()), Default::default())
            .expect("replay runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    // Every command the scenario sent agrees with the recording.
    let c = report.replay.expect("a replay's checks");
    assert!(c.table_commands >= 4 && c.chamber_targets >= 4, "{c:?}");
    assert_eq!((c.table_mismatches, c.chamber_mismatches), (0, 0));

    let replayed = Recording::from_bytes(&cursor.into_inner()).expect("readable");
    assert!(replayed.complete);
    assert!(original.gyro.len() > 10_000, "{}", original.gyro.len());
    assert_eq!(replayed.gyro.len(), original.gyro.len());
    assert_eq!(replayed.table.len(), original.table.len());
    assert_eq!(replayed.chamber.len(), original.chamber.len());
    for (a, b) in original.gyro.iter().zip(&replayed.gyro) {
        assert_eq!(a, b, "/gyro/rate");
    }
    for (a, b) in original.table.iter().zip(&replayed.table) {
        assert_eq!(a, b, "/table/state");
    }
    for (a, b) in original.chamber.iter().zip(&replayed.chamber) {
        assert_eq!(a, b, "/chamber/state");
    }
    // The scenario took the same path through its steps, at the same times.
    assert_eq!(replayed.steps, original.steps);
    // The recording's metadata carries over: site and gyro model.
    assert_eq!(replayed.metadata("bench.site"), original.metadata("bench.site"));
    assert_eq!(replayed.metadata("bench.gyro_model"), original.metadata("bench.gyro_model"));
}
