//! Writer tests: read the output back with the plain `mcap` crate, independently of
//! [`crate::reader`].

use std::{collections::BTreeMap, io::Cursor, time::Duration};

use super::*;
use crate::site::Axis;
use crate::writer::TomlAttachment;

const EPOCH: u64 = 1_700_000_000_123_456_789;

fn info() -> RunInfo {
    let mut model = BTreeMap::new();
    model.insert("bias".to_string(), "1.5e-8".to_string());
    model.insert("earth_rate".to_string(), "1".to_string());
    let mut i = RunInfo::new(
        EPOCH,
        "thermal",
        "name = \"thermal\"\n",
        Site {
            latitude_deg: 45.25,
            longitude_deg: Some(-1.5),
            height_m: None,
            axis: Some(Axis::Up),
        },
        model,
    );
    i.config = Some(TomlAttachment { name: "bench.toml".into(), text: "[gyro]\n".into() });
    i
}

fn opts() -> RecorderOptions {
    RecorderOptions { flush_interval: None, ..RecorderOptions::default() }
}

fn gyro(seq: u64, temp: Option<f64>) -> GyroMsg {
    GyroMsg { rate_rad_s: 0.1 + seq as f64 * 1e-7, temperature_c: temp, seq, status: 0 }
}

/// Writes 3 gyro, 2 table, 2 chamber, 2 step and 1 log messages.
fn small_recording(outcome: &Outcome) -> Vec<u8> {
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info(), opts()).expect("start");
    let ms = Duration::from_millis;
    r.step(ms(0), 0, "soak", StepEvent::Start, "record cw 20C").expect("step");
    r.gyro(ms(50), None, &gyro(7, Some(20.5))).expect("gyro");
    r.gyro(ms(100), Some(ms(99)), &gyro(8, None)).expect("gyro");
    r.table(
        ms(50),
        None,
        &TableMsg {
            angle_rad: 7.0,
            rate_rad_s: 0.0029088820866572155,
            rate_command_rad_s: 0.0029088820866572155,
            status: status::table::SLEWING,
        },
    )
    .expect("table");
    r.table(
        ms(100),
        None,
        &TableMsg { angle_rad: -1e-300, rate_rad_s: 1.0, rate_command_rad_s: 0.1, status: 0 },
    )
    .expect("table");
    for (i, t) in [50u64, 100].iter().enumerate() {
        r.chamber(
            ms(*t),
            None,
            &ChamberMsg { temperature_c: 20.0 + i as f64, setpoint_c: 21.5, status: 0 },
        )
        .expect("chamber");
    }
    r.log(ms(120), LogLevel::Warning, "door \"A\" ajar", "bench::run", "run.rs", 42).expect("log");
    r.gyro(ms(150), None, &gyro(10, Some(20.625))).expect("gyro");
    r.step(ms(150), 0, "soak", StepEvent::End, "record cw 20C").expect("step");
    r.finish(outcome).expect("finish").into_inner()
}

fn messages(file: &[u8]) -> Vec<mcap::Message<'static>> {
    mcap::MessageStream::new(file).expect("stream").collect::<Result<_, _>>().expect("messages")
}

fn bodies(file: &[u8], topic: &str) -> Vec<String> {
    messages(file)
        .into_iter()
        .filter(|m| m.channel.topic == topic)
        .map(|m| String::from_utf8(m.data.into_owned()).expect("utf8"))
        .collect()
}

#[test]
fn channels_schemas_and_encodings_follow_the_contract() {
    let file = small_recording(&Outcome::Completed);
    let summary = mcap::Summary::read(&file).expect("summary").expect("has summary");
    let mut seen: Vec<(String, String, String, String)> = summary
        .channels
        .values()
        .map(|c| {
            let s = c.schema.as_ref().expect("schema");
            let doc: serde_json::Value = serde_json::from_slice(&s.data).expect("schema is JSON");
            assert_eq!(doc["title"], s.name.as_str());
            (c.topic.clone(), s.name.clone(), s.encoding.clone(), c.message_encoding.clone())
        })
        .collect();
    seen.sort();
    let want =
        |t: &str, s: &str| (t.to_string(), s.to_string(), "jsonschema".into(), "json".into());
    assert_eq!(
        seen,
        vec![
            want("/bench/step", "bench.Step"),
            want("/chamber/state", "bench.ChamberState"),
            want("/gyro/rate", "bench.GyroSample"),
            want("/log", "foxglove.Log"),
            want("/table/state", "bench.TableState"),
        ]
    );
}

#[test]
fn bodies_are_exact_json_with_the_contract_field_names() {
    let file = small_recording(&Outcome::Completed);
    assert_eq!(
        bodies(&file, "/gyro/rate"),
        vec![
            r#"{"rate":0.10000070000000001,"temperature":20.5,"seq":7,"status":0}"#,
            r#"{"rate":0.1000008,"temperature":null,"seq":8,"status":0}"#,
            r#"{"rate":0.100001,"temperature":20.625,"seq":10,"status":2}"#,
        ]
    );
    assert_eq!(
        bodies(&file, "/table/state"),
        vec![
            r#"{"angle":7.0,"rate":0.0029088820866572155,"rate_command":0.0029088820866572155,"status":8}"#,
            r#"{"angle":-1e-300,"rate":1.0,"rate_command":0.1,"status":0}"#,
        ]
    );
    assert_eq!(
        bodies(&file, "/chamber/state"),
        vec![
            r#"{"temperature":20.0,"setpoint":21.5,"status":0}"#,
            r#"{"temperature":21.0,"setpoint":21.5,"status":0}"#,
        ]
    );
    assert_eq!(
        bodies(&file, "/bench/step"),
        vec![
            r#"{"index":0,"name":"soak","event":"start","label":"record cw 20C"}"#,
            r#"{"index":0,"name":"soak","event":"end","label":"record cw 20C"}"#,
        ]
    );
    let log_ns = EPOCH + 120_000_000;
    assert_eq!(
        bodies(&file, "/log"),
        vec![format!(
            r#"{{"timestamp":{{"sec":{},"nsec":{}}},"level":3,"message":"door \"A\" ajar","name":"bench::run","file":"run.rs","line":42}}"#,
            log_ns / 1_000_000_000,
            log_ns % 1_000_000_000
        )]
    );
}

#[test]
fn numbers_round_trip_exactly() {
    let file = small_recording(&Outcome::Completed);
    for b in bodies(&file, "/table/state") {
        let v: serde_json::Value = serde_json::from_str(&b).expect("json");
        let rate = v["rate"].as_f64().expect("number");
        assert!(rate == 0.0029088820866572155 || rate == 1.0);
    }
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info(), opts()).expect("start");
    let values = [f64::MIN_POSITIVE, f64::MAX, -0.1 - 0.2, 1.0 / 3.0, 5e-324, 123456789.0];
    for (i, v) in values.iter().enumerate() {
        let s = GyroMsg { rate_rad_s: *v, ..gyro(i as u64, Some(-*v)) };
        r.gyro(Duration::from_millis(i as u64), None, &s).expect("gyro");
    }
    let file = r.finish(&Outcome::Completed).expect("finish").into_inner();
    let got: Vec<(f64, f64)> = bodies(&file, "/gyro/rate")
        .iter()
        .map(|b| {
            let v: serde_json::Value = serde_json::from_str(b).expect("json");
            (v["rate"].as_f64().expect("n"), v["temperature"].as_f64().expect("n"))
        })
        .collect();
    let want: Vec<(f64, f64)> = values.iter().map(|v| (*v, -*v)).collect();
    assert_eq!(got, want);
}

#[test]
fn sequences_count_per_channel_and_times_are_epoch_plus_bench_time() {
    let file = small_recording(&Outcome::Completed);
    let msgs = messages(&file);
    let mut per_topic: BTreeMap<String, Vec<&mcap::Message>> = BTreeMap::new();
    for m in &msgs {
        per_topic.entry(m.channel.topic.clone()).or_default().push(m);
    }
    for (topic, ms) in &per_topic {
        let seqs: Vec<u32> = ms.iter().map(|m| m.sequence).collect();
        assert_eq!(seqs, (0..ms.len() as u32).collect::<Vec<_>>(), "{topic}");
        assert!(ms.windows(2).all(|w| w[0].log_time <= w[1].log_time), "{topic}");
    }
    let g = &per_topic["/gyro/rate"];
    let ms = 1_000_000u64;
    assert_eq!(
        g.iter().map(|m| (m.log_time, m.publish_time)).collect::<Vec<_>>(),
        vec![
            (EPOCH + 50 * ms, EPOCH + 50 * ms),
            (EPOCH + 100 * ms, EPOCH + 99 * ms),
            (EPOCH + 150 * ms, EPOCH + 150 * ms),
        ]
    );
}

#[test]
fn metadata_records_and_attachments() {
    let file = small_recording(&Outcome::Aborted("door open".into()));
    let summary = mcap::Summary::read(&file).expect("summary").expect("has summary");
    let mut meta = BTreeMap::new();
    for idx in &summary.metadata_indexes {
        let m = mcap::read::metadata(&file, idx).expect("metadata");
        assert!(meta.insert(m.name.clone(), m.metadata).is_none(), "one {} record", m.name);
    }
    let run = &meta["bench.run"];
    assert_eq!(run["format_version"], "1");
    assert_eq!(run["started"], "2023-11-14T22:13:20.123456789Z");
    assert_eq!(run["software"], format!("bench {}", env!("CARGO_PKG_VERSION")));
    assert_eq!(run["outcome"], "aborted: door open");
    // RunInfo::new's default: the model is nominal, not the data's truth.
    assert_eq!(run["gyro_model_role"], "nominal");
    assert_eq!(run.len(), 5);
    let site = &meta["bench.site"];
    assert_eq!(
        site,
        &BTreeMap::from([
            ("latitude_deg".to_string(), "45.25".to_string()),
            ("longitude_deg".to_string(), "-1.5".to_string()),
            ("axis".to_string(), "up".to_string()),
        ])
    );
    assert_eq!(meta["bench.scenario"]["name"], "thermal");
    assert_eq!(meta["bench.scenario"]["text"], "name = \"thermal\"\n");
    assert_eq!(meta["bench.gyro_model"]["bias"], "1.5e-8");
    assert_eq!(meta.len(), 4);

    let mut att: Vec<(String, String, Vec<u8>)> = summary
        .attachment_indexes
        .iter()
        .map(|i| {
            let a = mcap::read::attachment(&file, i).expect("attachment");
            (a.name.clone(), a.media_type.clone(), a.data.into_owned())
        })
        .collect();
    att.sort();
    assert_eq!(
        att,
        vec![
            ("bench.toml".into(), "application/toml".into(), b"[gyro]\n".to_vec()),
            ("scenario.toml".into(), "application/toml".into(), b"name = \"thermal\"\n".to_vec()),
        ]
    );
}

#[test]
fn summary_statistics_match_what_was_written_and_chunks_are_zstd() {
    let file = small_recording(&Outcome::Completed);
    let summary = mcap::Summary::read(&file).expect("summary").expect("has summary");
    let stats = summary.stats.as_ref().expect("statistics");
    assert_eq!(stats.message_count, 10);
    assert_eq!(stats.channel_count, 5);
    assert_eq!(stats.schema_count, 5);
    assert_eq!(stats.metadata_count, 4);
    assert_eq!(stats.attachment_count, 2);
    assert_eq!(stats.message_start_time, EPOCH);
    assert_eq!(stats.message_end_time, EPOCH + 150_000_000);
    let by_topic: BTreeMap<&str, u64> = stats
        .channel_message_counts
        .iter()
        .map(|(id, n)| (summary.channels[id].topic.as_str(), *n))
        .collect();
    assert_eq!(
        by_topic,
        BTreeMap::from([
            ("/bench/step", 2),
            ("/chamber/state", 2),
            ("/gyro/rate", 3),
            ("/log", 1),
            ("/table/state", 2)
        ])
    );
    assert!(!summary.chunk_indexes.is_empty());
    for c in &summary.chunk_indexes {
        assert_eq!(c.compression, "zstd");
    }
    // The chunk records themselves say zstd, too.
    let chunks: Vec<String> = mcap::read::LinearReader::new(&file)
        .expect("reader")
        .filter_map(|r| match r.expect("record") {
            mcap::records::Record::Chunk { header, .. } => Some(header.compression),
            _ => None,
        })
        .collect();
    assert!(!chunks.is_empty());
    assert!(chunks.iter().all(|c| c == "zstd"), "{chunks:?}");
}

#[test]
fn counter_gaps_are_flagged_and_wrap_is_not_a_gap() {
    let o = RecorderOptions { gyro_seq_bits: 8, ..opts() };
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info(), o).expect("start");
    let seqs = [253u64, 254, 255, 0, 1, 3, 4, 4, 5];
    for (i, s) in seqs.iter().enumerate() {
        let st = if i == 1 { status::gyro::INVALID } else { 0 };
        r.gyro(Duration::from_millis(i as u64), None, &GyroMsg { status: st, ..gyro(*s, None) })
            .expect("gyro");
    }
    assert_eq!(r.gyro_seq_gaps(), 2);
    let file = r.finish(&Outcome::Completed).expect("finish").into_inner();
    let st: Vec<u64> = bodies(&file, "/gyro/rate")
        .iter()
        .map(|b| {
            serde_json::from_str::<serde_json::Value>(b).expect("json")["status"]
                .as_u64()
                .expect("n")
        })
        .collect();
    let g = u64::from(status::gyro::SEQ_GAP);
    let inv = u64::from(status::gyro::INVALID);
    // 253 first; 254 ok (invalid kept); 255, 0 (wrap), 1 ok; 3 gap; 4 ok; 4 repeat gap; 5 ok.
    assert_eq!(st, vec![0, inv, 0, 0, 0, g, 0, g, 0]);

    // With the default 64-bit counter the same wrap is a gap.
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info(), opts()).expect("start");
    r.gyro(Duration::ZERO, None, &gyro(255, None)).expect("gyro");
    r.gyro(Duration::from_millis(1), None, &gyro(0, None)).expect("gyro");
    assert_eq!(r.gyro_seq_gaps(), 1);
}

#[test]
fn time_going_back_on_a_channel_and_non_finite_numbers_are_errors() {
    let mut r = Recorder::with_options(Cursor::new(Vec::new()), info(), opts()).expect("start");
    r.gyro(Duration::from_secs(2), None, &gyro(0, None)).expect("gyro");
    // Another channel may be earlier.
    let c = ChamberMsg { temperature_c: 1.0, setpoint_c: 1.0, status: 0 };
    r.chamber(Duration::from_secs(1), None, &c).expect("chamber");
    let e = r.gyro(Duration::from_secs(1), None, &gyro(1, None)).expect_err("went back");
    assert!(matches!(e, RecordError::TimeWentBack { topic: "/gyro/rate", .. }), "{e}");
    let e = r
        .chamber(Duration::from_secs(3), None, &ChamberMsg { setpoint_c: f64::NAN, ..c })
        .expect_err("nan");
    assert!(matches!(e, RecordError::NonFinite { field: "setpoint", .. }), "{e}");
    // Failed writes use no sequence number.
    r.chamber(Duration::from_secs(3), None, &c).expect("chamber");
    let file = r.finish(&Outcome::Completed).expect("finish").into_inner();
    let seqs: Vec<u32> = messages(&file)
        .iter()
        .filter(|m| m.channel.topic == "/chamber/state")
        .map(|m| m.sequence)
        .collect();
    assert_eq!(seqs, vec![0, 1]);
}

/// A sink whose bytes the test can see while the recorder still owns it.
#[derive(Clone, Default)]
struct SharedBuf(std::rc::Rc<std::cell::RefCell<Cursor<Vec<u8>>>>);

impl std::io::Write for SharedBuf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl std::io::Seek for SharedBuf {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.0.borrow_mut().seek(pos)
    }
}

#[test]
fn flushed_chunks_survive_a_crash() {
    let sink = SharedBuf::default();
    let mut r = Recorder::with_options(sink.clone(), info(), opts()).expect("start");
    for i in 0..100u64 {
        r.gyro(Duration::from_millis(50 * i), None, &gyro(i, Some(20.0))).expect("gyro");
    }
    r.flush().expect("flush");
    for i in 100..150u64 {
        r.gyro(Duration::from_millis(50 * i), None, &gyro(i, Some(20.0))).expect("gyro");
    }
    // The process dies here: the file holds what was written so far, an open chunk at its end.
    let crashed = sink.0.borrow().get_ref().clone();
    drop(r);
    assert!(mcap::Summary::read(&crashed).is_err(), "no footer in a crashed file");
    let mut got = 0;
    let mut failed = false;
    for m in mcap::MessageStream::new(&crashed).expect("stream") {
        match m {
            Ok(m) => {
                assert_eq!(m.sequence, got);
                got += 1;
            }
            Err(_) => {
                failed = true;
                break;
            }
        }
    }
    assert!(failed, "a crashed file ends in an error");
    assert!(got >= 100, "only {got} messages survived");
}

#[test]
fn the_flush_interval_is_bench_time_and_bounds_what_a_crash_loses() {
    let sink = SharedBuf::default();
    let o = RecorderOptions { flush_interval: Some(Duration::from_secs(1)), ..opts() };
    let mut r = Recorder::with_options(sink.clone(), info(), o).expect("start");
    // 20 Hz for 10.3 s of bench time, written as fast as the CPU goes (as in virtual time).
    let n = 207u64;
    for i in 0..n {
        r.gyro(Duration::from_millis(50 * i), None, &gyro(i, Some(20.0))).expect("gyro");
    }
    let crashed = sink.0.borrow().get_ref().clone();
    drop(r);
    let mut survived = 0u64;
    for m in mcap::MessageStream::new(&crashed).expect("stream") {
        match m {
            Ok(_) => survived += 1,
            Err(_) => break,
        }
    }
    // The last flush came with the sample at 10.0 s: samples 0..=200 are in the file.
    assert_eq!(survived, 201, "{survived} of {n} samples survived");
    let lost_s = (n - survived) as f64 * 0.05;
    assert!(lost_s <= 1.0, "{lost_s} s of bench time lost");

    // Without an interval nothing is flushed before the chunk fills.
    let sink = SharedBuf::default();
    let mut r = Recorder::with_options(sink.clone(), info(), opts()).expect("start");
    for i in 0..n {
        r.gyro(Duration::from_millis(50 * i), None, &gyro(i, Some(20.0))).expect("gyro");
    }
    let crashed = sink.0.borrow().get_ref().clone();
    drop(r);
    let kept =
        mcap::MessageStream::new(&crashed).expect("stream").take_while(Result::is_ok).count();
    assert_eq!(kept, 0);
}
