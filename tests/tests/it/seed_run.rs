//! Runs `scenarios/seed.toml` on the in-process simulated bench and checks the MCAP it writes
//! against the recording contract (`recording/FORMAT.md`), reading it back with the bare
//! `mcap` crate and, independently, through the file's summary section.

use std::collections::BTreeMap;
use std::path::PathBuf;

use bench_physics::units::DEG_PER_MIN;
use serde_json::Value;

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[derive(Debug, PartialEq)]
struct Msg {
    topic: String,
    schema: String,
    encoding: String,
    schema_encoding: String,
    sequence: u32,
    log_time: u64,
    publish_time: u64,
    body: Value,
}

#[derive(Debug, PartialEq)]
struct Read {
    msgs: Vec<Msg>,
    metadata: BTreeMap<String, BTreeMap<String, String>>,
}

fn read_linear(bytes: &[u8]) -> Read {
    let mut msgs = Vec::new();
    for m in mcap::MessageStream::new(bytes).expect("valid mcap") {
        let m = m.expect("valid message");
        let schema = m.channel.schema.as_ref().expect("every channel has a schema");
        msgs.push(Msg {
            topic: m.channel.topic.clone(),
            schema: schema.name.clone(),
            schema_encoding: schema.encoding.clone(),
            encoding: m.channel.message_encoding.clone(),
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
            body: serde_json::from_slice(&m.data).expect("JSON body"),
        });
    }
    let mut metadata = BTreeMap::new();
    for rec in mcap::read::LinearReader::new(bytes).expect("records") {
        if let mcap::records::Record::Metadata(md) = rec.expect("record") {
            metadata.insert(md.name.clone(), md.metadata.clone());
        }
    }
    Read { msgs, metadata }
}

/// The seed scenario's recording with `seed`; `flush`: the run's kill-safety bound
/// (`RunOptions::flush_interval`), whose wall-clock flushes close chunks early.
fn run_seed_flushing(seed: u64, flush: std::time::Duration) -> Vec<u8> {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("seed.mcap");
    let plan = bench::scenario::load(
        &workspace().join("scenarios/seed.toml"),
        &bench::simulate::capabilities(),
    )
    .expect("valid");
    let file = std::fs::File::create(&out).expect("created");
    let bench = bench::runner::Bench::Simulated(bench::simulate::sim_config(&plan, seed));
    let opts = bench::runner::RunOptions { flush_interval: Some(flush), ..Default::default() };
    let (report, file) = bench::runner::run(&plan, bench, file, opts).expect("seed scenario runs");
    file.sync_all().expect("written");
    assert_eq!(report.outcome, bench_recording::Outcome::Completed);
    std::fs::read(&out).expect("recording written")
}

/// The seed scenario's recording with `seed`, with no wall-clock flush during the run: its bytes
/// depend on scenario and seed alone.
fn run_seed(seed: u64) -> Vec<u8> {
    run_seed_flushing(seed, bench::runner::IN_MEMORY_FLUSH_INTERVAL)
}

fn chunk_count(bytes: &[u8]) -> usize {
    let summary = mcap::Summary::read(bytes).expect("summary readable").expect("summary present");
    summary.chunk_indexes.len()
}

#[test]
fn seed_scenario_recording_follows_the_contract() {
    let bytes = run_seed(7);
    let read = read_linear(&bytes);

    // Required channels with their schemas and encodings.
    let expected = [
        ("/gyro/rate", "bench.GyroSample"),
        ("/table/state", "bench.TableState"),
        ("/chamber/state", "bench.ChamberState"),
        ("/bench/step", "bench.Step"),
        ("/log", "foxglove.Log"),
    ];
    for (topic, schema) in expected {
        let m = read.msgs.iter().find(|m| m.topic == topic).unwrap_or_else(|| panic!("{topic}"));
        assert_eq!(m.schema, schema);
        assert_eq!(m.encoding, "json");
        assert_eq!(m.schema_encoding, "jsonschema");
    }

    // Per channel: sequence 0.. without gaps, log_time non-decreasing.
    let mut by_topic: BTreeMap<&str, Vec<&Msg>> = BTreeMap::new();
    for m in &read.msgs {
        by_topic.entry(m.topic.as_str()).or_default().push(m);
    }
    for (topic, ms) in &by_topic {
        for (i, m) in ms.iter().enumerate() {
            assert_eq!(m.sequence as usize, i, "{topic} sequence");
        }
        assert!(ms.windows(2).all(|w| w[0].log_time <= w[1].log_time), "{topic} order");
    }

    // 20 Hz with no gaps on every device channel; gyro seq counts up by one.
    for topic in ["/gyro/rate", "/table/state", "/chamber/state"] {
        let ms = &by_topic[topic];
        for w in ms.windows(2) {
            let dt = w[1].log_time - w[0].log_time;
            assert!((49_000_000..=51_000_000).contains(&dt), "{topic}: step {dt} ns");
        }
    }
    let gyro = &by_topic["/gyro/rate"];
    for w in gyro.windows(2) {
        assert_eq!(w[1].body["seq"].as_u64(), w[0].body["seq"].as_u64().map(|s| s + 1));
    }
    assert!(gyro.iter().all(|m| m.body["status"] == 0 && m.body["temperature"].is_number()));
    // The simulated gyro stamps its samples at the sample instant: publish_time = log_time.
    assert!(gyro.iter().all(|m| m.publish_time == m.log_time));

    // Steps: every start has a matching end, record windows are bracketed.
    let steps = &by_topic["/bench/step"];
    let mut open: BTreeMap<u64, u64> = BTreeMap::new();
    let mut windows = Vec::new();
    for s in steps {
        let idx = s.body["index"].as_u64().expect("index");
        match s.body["event"].as_str() {
            Some("start") => {
                open.insert(idx, s.log_time);
            }
            Some("end") => {
                let t0 = open.remove(&idx).expect("end follows start");
                let label = s.body["label"].as_str().unwrap_or_default().to_string();
                if label.starts_with("record") {
                    windows.push((label, t0, s.log_time));
                }
            }
            other => panic!("unexpected step event {other:?}"),
        }
    }
    assert!(open.is_empty(), "steps without end: {open:?}");
    assert!(windows.len() >= 4, "seed has plateau windows CW and CCW: {windows:?}");
    assert!(
        windows.iter().any(|w| w.0.contains("cw")) && windows.iter().any(|w| w.0.contains("ccw"))
    );

    // Inside record windows the table turns at ±10 °/min, CW negative.
    let seed_rate = 10.0 * DEG_PER_MIN;
    let table = &by_topic["/table/state"];
    for (label, t0, t1) in &windows {
        let inside: Vec<_> =
            table.iter().filter(|m| m.log_time > *t0 && m.log_time < *t1).collect();
        assert!(!inside.is_empty());
        let sign = if label.contains("ccw") { 1.0 } else { -1.0 };
        for m in inside {
            let cmd = m.body["rate_command"].as_f64().expect("rate_command");
            let rate = m.body["rate"].as_f64().expect("rate");
            assert!((cmd - sign * seed_rate).abs() < 1e-12, "{label}: command {cmd}");
            // Readout noise of the simulated table: 1e-6 rad/s RMS; 6σ.
            assert!((rate - sign * seed_rate).abs() < 6e-6, "{label}: rate {rate}");
        }
        // The table angle advances by rate × window length within the 1″ readout.
        let first = table.iter().find(|m| m.log_time > *t0).expect("first");
        let last = table.iter().rev().find(|m| m.log_time < *t1).expect("last");
        let dt = (last.log_time - first.log_time) as f64 * 1e-9;
        let dangle = last.body["angle"].as_f64().unwrap_or(f64::NAN)
            - first.body["angle"].as_f64().unwrap_or(f64::NAN);
        assert!(
            (dangle - sign * seed_rate * dt).abs() < 1e-4 * seed_rate * dt + 1e-5,
            "{label}: Δangle {dangle}"
        );
    }

    // Chamber follows the profile: the 20 °C and 40 °C plateau windows sit at their temperature.
    let chamber = &by_topic["/chamber/state"];
    for (label, t0, t1) in &windows {
        if label.contains("ramp") {
            continue;
        }
        let want = if label.contains("40") {
            40.0
        } else if label.contains("20") {
            20.0
        } else {
            continue;
        };
        for m in chamber.iter().filter(|m| m.log_time > *t0 && m.log_time < *t1) {
            let t = m.body["temperature"].as_f64().expect("temperature");
            assert!((t - want).abs() < 0.5, "{label}: air {t} °C");
            assert_eq!(m.body["setpoint"].as_f64(), Some(want), "{label}: set point");
        }
    }
    let max_air =
        chamber.iter().filter_map(|m| m.body["temperature"].as_f64()).fold(f64::MIN, f64::max);
    assert!((39.5..=41.0).contains(&max_air), "chamber peaks near 40 °C: {max_air}");

    // Metadata.
    let run = &read.metadata["bench.run"];
    assert_eq!(run["format_version"], "1");
    assert_eq!(run["outcome"], "completed");
    assert!(run["started"].ends_with('Z') && run["software"].starts_with("bench"));
    assert!(read.metadata["bench.site"]["latitude_deg"].parse::<f64>().is_ok());
    assert_eq!(
        read.metadata["bench.scenario"]["text"],
        std::fs::read_to_string(workspace().join("scenarios/seed.toml")).expect("scenario")
    );
    let model = &read.metadata["bench.gyro_model"];
    for key in bench_physics::gyro_model::GYRO_MODEL_KEYS {
        assert!(model.contains_key(key), "bench.gyro_model lacks {key}");
    }

    // Second, independent path: the summary section's statistics and index.
    let summary = mcap::Summary::read(&bytes).expect("summary readable").expect("summary present");
    let stats = summary.stats.expect("statistics record");
    assert_eq!(stats.message_count as usize, read.msgs.len());
    for (id, ch) in &summary.channels {
        let n = stats.channel_message_counts.get(id).copied().unwrap_or(0) as usize;
        assert_eq!(n, by_topic.get(ch.topic.as_str()).map_or(0, Vec::len), "{}", ch.topic);
    }
    assert!(summary.chunk_indexes.iter().all(|c| c.compression == "zstd"));
    assert!(!summary.chunk_indexes.is_empty());
}

#[test]
fn same_seed_same_bytes_other_seed_other_noise() {
    let a = run_seed(3);
    let b = run_seed(3);
    let c = run_seed(4);
    assert_eq!(a, b, "a simulated run is a pure function of scenario and seed");
    // Kill-safety flushes follow the wall clock, so they move chunk boundaries, never content.
    let d = run_seed_flushing(3, std::time::Duration::from_millis(2));
    assert!(chunk_count(&d) > chunk_count(&a), "{} vs {}", chunk_count(&d), chunk_count(&a));
    assert!(read_linear(&d) == read_linear(&a), "the same messages and metadata");
    let rates = |bytes: &[u8]| -> Vec<f64> {
        read_linear(bytes)
            .msgs
            .iter()
            .filter(|m| m.topic == "/gyro/rate")
            .filter_map(|m| m.body["rate"].as_f64())
            .collect()
    };
    let (ra, rc) = (rates(&a), rates(&c));
    // Soak times depend on the noise, so lengths may differ; the samples must.
    assert!(ra.len() > 40_000 && rc.len() > 40_000);
    let differing = ra.iter().zip(&rc).filter(|(x, y)| x != y).count();
    assert!(differing > ra.len().min(rc.len()) * 9 / 10, "{differing}");
}
