//! Recordings written by an independent writer — the Python `mcap` package
//! (`tests/fixtures/make_python_mcap.py`: zstd chunks, lz4 chunks, unchunked) — load, replay a
//! scenario and export; so does the same file cut short (no summary, no footer).

use std::io::Cursor;
use std::path::PathBuf;
use std::sync::Arc;

use bench::replay::ReplayData;
use bench_recording::Recording;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(name)
}

/// The steps the Python file's data were shaped for.
const SCENARIO: &str = r#"
[scenario]
name = "python-fixture"

[site]
latitude_deg = 48.85

[gyro]
sample_rate = "20 Hz"

[safe]
decel = "1 °/s²"
temperature = "25 °C"

[[step]]
label = "to 25C"
chamber = "25 °C"
ramp = "15 °C/min"

[[step]]
label = "record ramp 20C to 25C"
record = "ramp end"
timeout = "1 min"

[[step]]
label = "spin cw"
spin = "10 °/min"
direction = "cw"
accel = "1 °/s²"

[[step]]
label = "record cw 25C"
record = "20 s"

[[step]]
label = "stop"
stop = "table"
"#;

#[test]
fn python_files_load_whatever_their_compression_and_chunking() {
    let zstd = Recording::load(&fixture("python_zstd.mcap")).expect("zstd chunks");
    let lz4 = Recording::load(&fixture("python_lz4.mcap")).expect("lz4 chunks");
    let flat = Recording::load(&fixture("python_unchunked.mcap")).expect("unchunked");
    assert!(zstd.complete && lz4.complete && flat.complete);
    assert_eq!(
        (zstd.gyro.len(), zstd.table.len(), zstd.chamber.len(), zstd.steps.len()),
        (1200, 300, 300, 10)
    );
    assert_eq!(zstd.other_counts.get("/log"), Some(&1));
    assert_eq!(zstd.outcome(), Some(bench_recording::Outcome::Completed));
    // Unknown keys of bench.gyro_model are kept; the attachment is there.
    assert_eq!(
        zstd.metadata("bench.gyro_model").and_then(|m| m.get("vendor_key")).map(String::as_str),
        Some("kept")
    );
    assert_eq!(zstd.attachments.len(), 1);
    assert_eq!(zstd.attachments[0].media_type, "application/toml");
    // The same data whatever the container: the shorter files are prefixes.
    assert_eq!(lz4.gyro.len(), 600);
    assert_eq!(flat.gyro.len(), 300);
    assert_eq!(lz4.gyro[..], zstd.gyro[..600]);
    assert_eq!(flat.gyro[..], zstd.gyro[..300]);
    assert_eq!(flat.chamber[..], zstd.chamber[..75]);
    // Values as Python wrote them: publish time 0.2 ms before log time, seq from 1.
    let g = &zstd.gyro[0];
    assert_eq!(g.log_time_ns, 1_750_000_000_050_000_000);
    assert_eq!(g.publish_time_ns, g.log_time_ns - 200_000);
    assert_eq!((g.msg.seq, g.sequence), (1, 0));
    assert_eq!(
        bench_recording::summary_counts(&fixture("python_zstd.mcap"))
            .ok()
            .flatten()
            .and_then(|c| c.get("/gyro/rate").copied()),
        Some(1200)
    );
}

#[test]
fn a_scenario_replays_on_the_python_file_and_re_records_its_gyro() {
    let rec = Recording::load(&fixture("python_zstd.mcap")).expect("loads");
    let data = Arc::new(ReplayData::from_recording(&rec, "python_zstd.mcap").expect("replays"));
    assert_eq!(data.epoch_ns, 1_750_000_000_000_000_000, "from bench.run started");
    let plan = bench::scenario::parse(SCENARIO, "python_fixture.toml", &data.capabilities())
        .expect("valid on the replay");
    let (report, out) = bench::runner::run(
        &plan,
        bench::runner::Bench::Replay(data.clone()),
        Cursor::new(Vec::new()),
        Default::default(),
    )
    .expect("runs");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    // The waits were satisfied by the recorded data, at the recorded times: ramp end at 20 s,
    // the record window 20 s long, the stop settled; then safe state and 1 s of tail.
    let end = report.bench_time.as_secs_f64();
    assert!((41.0..43.0).contains(&end), "run ended at {end} s");
    let again = Recording::from_bytes(&out.into_inner()).expect("re-recorded");
    let labels: Vec<(u64, &str, &str)> = again
        .steps
        .iter()
        .map(|s| (s.msg.index, s.msg.event.as_str(), s.msg.label.as_str()))
        .collect();
    assert_eq!(labels.len(), 10, "{labels:?}");
    let ramp_end = again.steps.iter().find(|s| s.msg.index == 1 && s.msg.event.as_str() == "end");
    let t = ramp_end.map(|s| (s.log_time_ns - data.epoch_ns) as f64 / 1e9).expect("ramp end");
    assert!((20.0..20.3).contains(&t), "ramp end at {t} s");
    // Every gyro sample of the replayed span, exactly as Python wrote it.
    let n = again.gyro.len();
    assert!(n >= 800, "{n}");
    assert_eq!(again.gyro[..], rec.gyro[..n]);
    // Every command agreed with the recording (spin CW = negative rate, stop, safe state).
    let c = report.replay.expect("a replay's checks");
    assert!(c.table_commands >= 3 && c.chamber_targets >= 2, "{c:?}");
    assert_eq!((c.table_mismatches, c.chamber_mismatches), (0, 0));
}

#[test]
fn a_python_file_cut_short_still_loads_replays_and_exports() {
    let bytes = std::fs::read(fixture("python_zstd.mcap")).expect("fixture");
    let cut = &bytes[..bytes.len() * 7 / 10];
    let rec = Recording::from_bytes(cut).expect("cut file loads");
    assert!(!rec.complete);
    let (at, _reason) = rec.cut.clone().expect("cut reported");
    assert!(at <= cut.len() as u64);
    assert!(rec.gyro.len() > 300 && rec.gyro.len() < 1200, "{}", rec.gyro.len());
    let data = ReplayData::from_recording(&rec, "cut").expect("replayable");
    // No bench.run in a cut file: bench time zero is the earliest message (the step at 0).
    assert_eq!(data.epoch_ns, 1_750_000_000_000_000_000);
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = bench_recording::RecordingReader::new(cut);
    let report =
        bench_recording::export::export(reader, dir.path(), bench_recording::export::Format::Csv)
            .expect("exports");
    assert!(report.cut.is_some());
    let gyro = report.tables.iter().find(|t| t.topic == "/gyro/rate").expect("gyro table");
    assert_eq!(gyro.rows, rec.gyro.len());
}

#[test]
fn a_python_file_exports_to_parquet() {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    let dir = tempfile::tempdir().expect("tempdir");
    let report = bench_recording::export::export_file(
        &fixture("python_zstd.mcap"),
        dir.path(),
        bench_recording::export::Format::Parquet,
    )
    .expect("exports");
    let rows: Vec<(String, usize)> =
        report.tables.iter().map(|t| (t.topic.clone(), t.rows)).collect();
    assert_eq!(
        rows,
        [
            ("/bench/step".to_string(), 10),
            ("/chamber/state".to_string(), 300),
            ("/gyro/rate".to_string(), 1200),
            ("/log".to_string(), 1),
            ("/table/state".to_string(), 300)
        ]
    );
    let f = std::fs::File::open(dir.path().join("chamber_state.parquet")).expect("file");
    let r = SerializedFileReader::new(f).expect("parquet");
    assert_eq!(r.metadata().file_metadata().num_rows(), 300);
    let last = r.get_row_iter(None).expect("rows").last().expect("row").expect("row");
    let cols = last.into_columns();
    assert_eq!(cols[0].0, "timestamp");
    assert_eq!(cols[4].0, "temperature");
    assert_eq!(cols[5], ("setpoint".to_string(), parquet::record::Field::Double(25.0)));
}
