//! Reader tests: recorder output, files from other writers (unchunked, lz4, uncompressed,
//! unknown channels and fields), crashed and truncated files, garbage.

use std::{collections::BTreeMap, io::Cursor, time::Duration};

use mcap::{records::MessageHeader, Compression, WriteOptions};
use proptest::prelude::*;

use super::*;
use crate::info::{info, info_from_reader, Gap, StepReport};
use crate::message::{ChamberMsg, GyroMsg, LogLevel, StepEvent, TableMsg};
use crate::writer::{Recorder, RecorderOptions, RunInfo};

const EPOCH: u64 = 1_600_000_000_000_000_000;

fn run_info() -> RunInfo {
    RunInfo::new(EPOCH, "t", "name = \"t\"\n", Site::at_latitude(45.0), BTreeMap::new())
}

/// 20 Hz on three channels for `seconds`, two steps, a gap in the table stream between
/// 4 s and 5 s, and a step-end flush after each step (so the file has several chunks).
fn recorder_file(seconds: u64) -> Vec<u8> {
    let sink = Cursor::new(Vec::new());
    let opts = RecorderOptions { flush_interval: None, ..RecorderOptions::default() };
    let mut r = Recorder::with_options(sink, run_info(), opts).expect("start");
    let half = seconds * 20 / 2;
    for i in 0..seconds * 20 {
        let t = Duration::from_millis(50 * i);
        if i == 0 || i == half {
            let (idx, label) = if i == 0 { (0, "record cw") } else { (1, "") };
            r.step(t, idx, "s", StepEvent::Start, label).expect("step");
        }
        r.gyro(
            t,
            None,
            &GyroMsg {
                rate_rad_s: i as f64 * 1e-6,
                temperature_c: if i % 2 == 0 { Some(20.0 + i as f64 / 8.0) } else { None },
                seq: i,
                status: 0,
            },
        )
        .expect("gyro");
        if !(80..100).contains(&i) {
            r.table(
                t,
                None,
                &TableMsg {
                    angle_rad: i as f64 * 0.01,
                    rate_rad_s: 0.2,
                    rate_command_rad_s: 0.2,
                    status: 0,
                },
            )
            .expect("table");
        }
        r.chamber(t, None, &ChamberMsg { temperature_c: 20.0, setpoint_c: 21.0, status: 1 })
            .expect("chamber");
        if i + 1 == half {
            r.step(t, 0, "s", StepEvent::End, "record cw").expect("step");
        }
        if i + 1 == seconds * 20 {
            r.step(t, 1, "s", StepEvent::Abort, "").expect("step");
        }
        r.log(t, LogLevel::Info, "hello", "test", "tests.rs", 1).expect("log");
    }
    r.finish(&Outcome::Aborted("operator stop".into())).expect("finish").into_inner()
}

/// Byte offset where the data section ends (the DataEnd record) in a finished file.
fn data_end_offset(file: &[u8]) -> usize {
    let summary = mcap::Summary::read(file).expect("summary").expect("present");
    let last = summary
        .chunk_indexes
        .iter()
        .map(|c| c.chunk_start_offset + c.chunk_length)
        .max()
        .expect("chunks");
    let meta = summary.metadata_indexes.iter().map(|m| m.offset + m.length).max().unwrap_or(0);
    last.max(meta) as usize
}

#[test]
fn reads_recorder_output_with_everything_decoded() {
    let file = recorder_file(10);
    let rec = Recording::from_bytes(&file).expect("reads");
    assert!(rec.damage.is_empty(), "{:?}", rec.damage);
    assert!(rec.complete);
    assert_eq!(rec.cut, None);
    assert_eq!(rec.gyro.len(), 200);
    assert_eq!(rec.table.len(), 180);
    assert_eq!(rec.chamber.len(), 200);
    assert_eq!(rec.steps.len(), 4);
    assert_eq!(rec.other_counts.get("/log"), Some(&200));
    let g = &rec.gyro[3];
    assert_eq!(g.sequence, 3);
    assert_eq!(g.log_time_ns, EPOCH + 150_000_000);
    assert_eq!(g.publish_time_ns, g.log_time_ns);
    assert_eq!(g.msg, GyroMsg { rate_rad_s: 3e-6, temperature_c: None, seq: 3, status: 0 });
    assert_eq!(rec.gyro[4].msg.temperature_c, Some(20.5));
    assert_eq!(
        rec.table[1].msg,
        TableMsg { angle_rad: 0.01, rate_rad_s: 0.2, rate_command_rad_s: 0.2, status: 0 }
    );
    assert_eq!(rec.chamber[0].msg, ChamberMsg { temperature_c: 20.0, setpoint_c: 21.0, status: 1 });
    assert_eq!(
        rec.steps.iter().map(|s| (s.msg.index, s.msg.event)).collect::<Vec<_>>(),
        vec![
            (0, StepEvent::Start),
            (0, StepEvent::End),
            (1, StepEvent::Start),
            (1, StepEvent::Abort)
        ]
    );
    assert_eq!(rec.outcome(), Some(Outcome::Aborted("operator stop".into())));
    assert_eq!(
        Outcome::parse("aborted: operator stop"),
        Some(Outcome::Aborted("operator stop".into()))
    );
    assert_eq!(
        rec.metadata("bench.site").and_then(|m| m.get("latitude_deg")).map(String::as_str),
        Some("45")
    );
    assert_eq!(rec.metadata("bench.scenario").map(|m| m["text"].as_str()), Some("name = \"t\"\n"));
    assert_eq!(rec.attachments.len(), 1);
    assert_eq!(rec.attachments[0].media_type, "application/toml");
}

/// A file as another program might write it: custom options, ids, an extra channel, extra
/// fields, no metadata.
fn foreign_file(options: WriteOptions) -> Vec<u8> {
    let mut w = options.create(Cursor::new(Vec::new())).expect("create");
    let none = BTreeMap::new();
    let extra = w.add_schema("x.Thing", "jsonschema", b"{}").expect("schema");
    let extra_ch = w.add_channel(extra, "/gyro/extra", "json", &none).expect("channel");
    let cbor_ch = w.add_channel(0, "/other/raw", "cbor", &none).expect("channel");
    let gs = w.add_schema("bench.GyroSample", "jsonschema", b"{\"type\":\"object\"}").expect("s");
    let gyro = w.add_channel(gs, "/gyro/rate", "json", &none).expect("channel");
    let ss = w.add_schema("bench.Step", "jsonschema", b"{}").expect("s");
    let step = w.add_channel(ss, "/bench/step", "json", &none).expect("channel");
    let mut write = |ch: u16, seq: u32, t: u64, body: &str| {
        let h = MessageHeader { channel_id: ch, sequence: seq, log_time: t, publish_time: t + 1 };
        w.write_to_known_channel(&h, body.as_bytes()).expect("write");
    };
    write(step, 0, 10, r#"{"index":2,"name":"n","event":"start","label":"record x","new":[1]}"#);
    for i in 0..50u32 {
        let t = 1_000 + u64::from(i) * 1_000_000;
        write(extra_ch, i, t, "{\"anything\":true}");
        write(cbor_ch, i, t, "\u{1}\u{2}");
        write(
            gyro,
            i,
            t,
            &format!(
                r#"{{"status":0,"seq":{i},"rate":-1.5e-7,"temperature":null,"vendor":{{"a":1}}}}"#
            ),
        );
    }
    write(step, 1, 60_000_000, r#"{"index":2,"name":"n","event":"end","label":"record x"}"#);
    w.finish().expect("finish");
    w.into_inner().into_inner()
}

#[test]
fn reads_files_from_other_writers_unchunked_lz4_and_uncompressed() {
    let variants = [
        ("zstd", WriteOptions::new().compression(Some(Compression::Zstd))),
        ("lz4", WriteOptions::new().compression(Some(Compression::Lz4)).chunk_size(Some(512))),
        ("uncompressed", WriteOptions::new().compression(None)),
        ("unchunked", WriteOptions::new().use_chunks(false)),
        ("no summary", WriteOptions::new().emit_summary_records(false).emit_statistics(false)),
    ];
    for (name, opts) in variants {
        let file = foreign_file(opts);
        let rec = Recording::from_bytes(&file).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(rec.complete, "{name}");
        assert_eq!(rec.gyro.len(), 50, "{name}");
        assert_eq!(
            rec.gyro[7].msg,
            GyroMsg { rate_rad_s: -1.5e-7, temperature_c: None, seq: 7, status: 0 }
        );
        assert_eq!(rec.gyro[7].publish_time_ns, rec.gyro[7].log_time_ns + 1, "{name}");
        assert_eq!(rec.steps.len(), 2, "{name}");
        assert_eq!(rec.steps[0].msg.label, "record x");
        assert_eq!(rec.other_counts.get("/gyro/extra"), Some(&50), "{name}");
        assert_eq!(rec.other_counts.get("/other/raw"), Some(&50), "{name}");
        assert!(rec.table.is_empty() && rec.chamber.is_empty());
        assert_eq!(rec.outcome(), None);
    }
}

#[test]
fn bad_bodies_and_encodings_on_required_channels_are_named() {
    let mut w = WriteOptions::new().create(Cursor::new(Vec::new())).expect("create");
    let none = BTreeMap::new();
    let ch = w.add_channel(0, "/table/state", "json", &none).expect("channel");
    let h = MessageHeader { channel_id: ch, sequence: 4, log_time: 99, publish_time: 99 };
    w.write_to_known_channel(&h, br#"{"angle":1.0,"rate":"fast","rate_command":0,"status":0}"#)
        .expect("write");
    w.finish().expect("finish");
    let file = w.into_inner().into_inner();
    // The bad message is skipped, named and counted; the file reads.
    let rec = Recording::from_bytes(&file).expect("a bad body is damage, not an error");
    assert!(rec.table.is_empty());
    assert_eq!(rec.damage.bad_messages.get("/table/state"), Some(&1));
    let d = &rec.damage.entries[0];
    assert!(
        matches!(&d.kind, DamageKind::Message { sequence: 4, log_time_ns: 99, detail, .. }
            if detail.contains("rate")),
        "{d}"
    );
    let text = d.to_string();
    assert!(text.contains("/table/state") && text.contains("sequence 4"), "{text}");

    let mut w = WriteOptions::new().create(Cursor::new(Vec::new())).expect("create");
    w.add_channel(0, "/gyro/rate", "cbor", &none).expect("channel");
    w.finish().expect("finish");
    let file = w.into_inner().into_inner();
    let e = Recording::from_bytes(&file).expect_err("cbor");
    assert!(matches!(e, RecordingError::UnsupportedEncoding { .. }), "{e}");

    let e = Recording::from_bytes(b"PK\x03\x04 not an mcap file at all").expect_err("garbage");
    assert!(matches!(e, RecordingError::NotMcap { at_byte: 8, .. }), "{e}");
    assert!(matches!(Recording::from_bytes(b""), Err(RecordingError::NotMcap { .. })));
}

#[test]
fn truncated_files_yield_a_prefix_and_say_where_they_stop() {
    let file = recorder_file(10);
    let full = Recording::from_bytes(&file).expect("full");
    let data_end = data_end_offset(&file);
    let mut last_count = 0;
    let mut seen_partial = false;
    assert!(matches!(Recording::from_bytes(&file[..40]), Err(RecordingError::NotMcap { .. })));
    for cut in [300, 2_000, 4_000, 6_000, data_end / 2, data_end - 1, data_end, file.len() - 1] {
        let cut = cut.min(file.len() - 1);
        let part = &file[..cut];
        let rec = Recording::from_bytes(part).unwrap_or_else(|e| panic!("cut {cut}: {e}"));
        assert!(!rec.complete, "cut {cut}");
        let (at, reason) = rec.cut.clone().expect("cut reported");
        // Where the last complete record ends: at the cut, or at most one record before it.
        assert!(at <= cut as u64 && at + 70_000 > cut as u64, "cut {cut}: {at} {reason}");
        assert!(rec.damage.is_empty(), "cut {cut}: {:?}", rec.damage);
        assert_eq!(rec.gyro[..], full.gyro[..rec.gyro.len()], "cut {cut}");
        assert_eq!(rec.steps[..], full.steps[..rec.steps.len()], "cut {cut}");
        assert!(rec.gyro.len() >= last_count, "cut {cut}");
        if !rec.gyro.is_empty() && rec.gyro.len() < full.gyro.len() {
            seen_partial = true;
        }
        last_count = rec.gyro.len();
    }
    assert!(seen_partial, "some cut fell inside the data");
    assert_eq!(last_count, full.gyro.len(), "a file cut in its summary has all messages");
}

#[test]
fn info_reports_channels_rates_gaps_steps_metadata_and_outcome() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("run.mcap");
    let file = recorder_file(10);
    std::fs::write(&path, &file).expect("write");
    let i = info(&path).expect("info");
    assert_eq!(i.end, End::Complete);
    assert_eq!(i.outcome.as_deref(), Some("aborted: operator stop"));
    assert_eq!(i.start_ns, Some(EPOCH));
    assert!((i.duration_s - 9.95).abs() < 1e-9, "{}", i.duration_s);
    let ch = |t: &str| i.channels.iter().find(|c| c.topic == t).expect(t);
    let g = ch("/gyro/rate");
    assert_eq!((g.count, g.schema_name.as_str()), (200, "bench.GyroSample"));
    assert!((g.mean_rate_hz.expect("rate") - 20.0).abs() < 1e-9);
    assert!(g.gaps.is_empty());
    let t = ch("/table/state");
    assert_eq!(t.count, 180);
    assert_eq!(t.gaps, vec![Gap { from_s: 3.95, to_s: 5.0 }]);
    assert_eq!(ch("/log").count, 200);
    assert_eq!(ch("/bench/step").count, 4);
    // Device streams are periodic; step events are not, and have no gaps to report.
    assert!(g.periodic && t.periodic);
    assert!(!ch("/bench/step").periodic && ch("/bench/step").gaps.is_empty());
    assert_eq!(i.steps.len(), 2);
    assert_eq!(
        i.steps[0],
        StepReport {
            index: 0,
            name: "s".into(),
            label: "record cw".into(),
            start_s: Some(0.0),
            end_s: Some(4.95),
            abort_s: None
        }
    );
    assert_eq!((i.steps[1].start_s, i.steps[1].end_s), (Some(5.0), None));
    assert!((i.steps[1].abort_s.expect("abort") - 9.95).abs() < 1e-9);
    let names: Vec<&str> = i.metadata.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, vec!["bench.site", "bench.scenario", "bench.gyro_model", "bench.run"]);
    assert_eq!(
        i.attachments,
        vec![("scenario.toml".to_string(), "application/toml".to_string(), 11)]
    );
    let text = i.to_string();
    for needle in [
        "/gyro/rate",
        "20.000 Hz",
        "gap 3.950 s .. 5.000 s",
        "aborted: operator stop",
        "ABORT",
        "label \"record cw\"",
        "latitude_deg = 45",
        "scenario.toml",
    ] {
        assert!(text.contains(needle), "missing {needle:?} in\n{text}");
    }

    // Both count paths agree on a finished file.
    let linear: BTreeMap<String, u64> =
        i.channels.iter().map(|c| (c.topic.clone(), c.count)).collect();
    assert_eq!(summary_counts(&path).expect("summary"), Some(linear));

    // A crashed file: info still works, the summary path has nothing.
    std::fs::write(&path, &file[..data_end_offset(&file) - 1]).expect("write");
    let i = info(&path).expect("info without summary");
    assert!(matches!(i.end, End::Cut { .. }));
    assert_eq!(i.outcome, None);
    assert!(i.channels.iter().any(|c| c.topic == "/gyro/rate" && c.count == 200));
    assert!(i.to_string().contains("FILE INCOMPLETE"));
    assert_eq!(summary_counts(&path).expect("no summary"), None);
}

fn small_file() -> Vec<u8> {
    recorder_file(2)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn truncation_never_panics_and_yields_a_prefix(cut in 0usize..20_000) {
        let file = small_file();
        let full = Recording::from_bytes(&file).expect("full");
        let cut = cut.min(file.len());
        match Recording::from_bytes(&file[..cut]) {
            Ok(rec) => {
                prop_assert_eq!(&rec.gyro[..], &full.gyro[..rec.gyro.len()]);
                prop_assert_eq!(&rec.table[..], &full.table[..rec.table.len()]);
                prop_assert_eq!(rec.complete, cut == file.len());
            }
            Err(e) => prop_assert!(matches!(e, RecordingError::NotMcap { .. }), "{}", e),
        }
    }

    #[test]
    fn garbage_never_panics(
        pos in 0usize..20_000,
        bytes in proptest::collection::vec(any::<u8>(), 1..64),
        truncate in any::<bool>(),
    ) {
        let mut file = small_file();
        let pos = pos.min(file.len());
        for (i, b) in bytes.iter().enumerate() {
            if let Some(x) = file.get_mut(pos + i) {
                *x = *b;
            }
        }
        if truncate {
            file.truncate(pos + bytes.len());
        }
        // Any result is fine as long as it is a result; the info path too.
        let _ = Recording::from_bytes(&file);
        let _ = info_from_reader(RecordingReader::new(&file[..]));
    }
}

/// A file of several decoding batches: other channels, metadata and a bad body in the middle
/// come out in file order, the error names its message and reading goes on after it, and a reader
/// dropped part-way returns.
/// Top-level messages batched per decoding job (the engine's `LOOSE_BATCH`).
const BATCH_MESSAGES: usize = 2048;

/// A file of many chunks: other channels, metadata and a bad body in the middle come out in
/// file order, the bad body is skipped and named and reading goes on after it, and a reader
/// dropped part-way returns.
#[test]
fn files_of_many_chunks_decode_in_file_order_with_damage_in_place() {
    let n = (3 * BATCH_MESSAGES + 100) as u32;
    let bad = 2 * BATCH_MESSAGES as u32 + 7;
    let write = |options: WriteOptions| {
        let mut w = options.create(Cursor::new(Vec::new())).expect("create");
        let none = BTreeMap::new();
        let gyro = w.add_channel(0, "/gyro/rate", "json", &none).expect("channel");
        let log = w.add_channel(0, "/log", "json", &none).expect("channel");
        for i in 0..n {
            let h = MessageHeader {
                channel_id: gyro,
                sequence: i,
                log_time: i.into(),
                publish_time: 0,
            };
            let body = if i == bad {
                r#"{"rate":"x","seq":0,"status":0}"#.to_string()
            } else {
                let rate = f64::from(i) * 0.1;
                format!(r#"{{"rate":{rate},"temperature":null,"seq":{i},"status":0}}"#)
            };
            w.write_to_known_channel(&h, body.as_bytes()).expect("write");
            if i % 1000 == 0 {
                let h = MessageHeader {
                    channel_id: log,
                    sequence: i,
                    log_time: i.into(),
                    publish_time: 0,
                };
                w.write_to_known_channel(&h, b"{}").expect("write");
                let meta =
                    mcap::records::Metadata { name: format!("m{i}"), metadata: BTreeMap::new() };
                w.write_metadata(&meta).expect("metadata");
            }
        }
        w.finish().expect("finish");
        w.into_inner().into_inner()
    };
    let chunked = write(WriteOptions::new().chunk_size(Some(16 * 1024)));
    let unchunked = write(WriteOptions::new().use_chunks(false));

    for (unchunked, file) in [(false, chunked), (true, unchunked)] {
        let mut reader = RecordingReader::new(&file[..]);
        let mut expected_gyro = 0u32;
        let mut others = Vec::new();
        for item in reader.by_ref() {
            match item.expect("no error") {
                Item::Gyro(g) => {
                    if expected_gyro == bad {
                        expected_gyro += 1;
                    }
                    assert_eq!(g.sequence, expected_gyro);
                    assert_eq!(g.msg.seq, u64::from(expected_gyro));
                    assert_eq!(g.msg.rate_rad_s, f64::from(expected_gyro) * 0.1);
                    expected_gyro += 1;
                }
                Item::Other(o) => others.push(format!("log{}@{expected_gyro}", o.sequence)),
                Item::Metadata(m) => others.push(format!("{}@{expected_gyro}", m.name)),
                other => panic!("unexpected {other:?}"),
            }
        }
        assert_eq!(expected_gyro, n);
        assert_eq!(*reader.end(), End::Complete);
        let damage = reader.damage();
        assert_eq!(damage.bad_message_count(), 1, "{damage:?}");
        let text = damage.entries[0].to_string();
        assert!(text.contains("field `rate` must be a number"), "{text}");
        assert!(text.contains(&format!("sequence {bad}")), "{text}");
        let (chunks, checked) = reader.chunks_read();
        if !unchunked {
            assert!(chunks > 10 && checked == chunks, "{chunks} {checked}");
        }
        // Each log message and metadata record right after gyro message i (i % 1000 == 0).
        let want: Vec<String> = (0..n)
            .step_by(1000)
            .flat_map(|i| [format!("log{i}@{}", i + 1), format!("m{i}@{}", i + 1)])
            .collect();
        assert_eq!(others, want, "unchunked {unchunked}");

        // Dropping a reader with chunks in flight returns (the decoding threads end).
        let first: Vec<_> = RecordingReader::new(&file[..]).take(10).collect();
        assert_eq!(first.len(), 10);
    }
}

#[test]
fn the_model_role_round_trips_and_an_unsaid_one_is_nominal() {
    for role in [crate::ModelRole::Simulation, crate::ModelRole::Nominal] {
        let mut info = run_info();
        info.gyro_model_role = role;
        let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("start");
        r.chamber(
            Duration::ZERO,
            None,
            &ChamberMsg { temperature_c: 20.0, setpoint_c: 20.0, status: 0 },
        )
        .expect("chamber");
        let bytes = r.finish(&Outcome::Completed).expect("finish").into_inner();
        assert_eq!(Recording::from_bytes(&bytes).expect("reads").gyro_model_role(), role);
    }
    // A file from another writer without the key (or a crashed one, without bench.run).
    assert_eq!(crate::ModelRole::from_key(None), crate::ModelRole::Nominal);
    assert_eq!(crate::ModelRole::from_key(Some("truth")), crate::ModelRole::Nominal);
}

/// Found by the `recording` fuzz target: in an uncompressed chunk, a record whose length runs
/// past the chunk's end made mcap 0.26's chunk reader subtract with overflow
/// (`sans_io/linear_reader.rs:745`; a panic with overflow checks). The reader reads an
/// uncompressed chunk's records as top-level records instead: the chunk is damage.
#[test]
fn an_uncompressed_chunk_whose_record_overruns_it_is_damage() {
    let bytes = include_bytes!("../../../fuzz/regressions/mcap-uncompressed-chunk-record-overrun");
    let rec = Recording::from_bytes(bytes).expect("reads");
    let chunk = rec.damage.entries.iter().find(|d| matches!(d.kind, DamageKind::Chunk { .. }));
    assert!(chunk.is_some() || rec.cut.is_some(), "{:?} {:?}", rec.damage, rec.cut);
}

/// Found by the `run_data` fuzz target: mcap 0.26 panics (release builds too) parsing an
/// Attachment record too short for its own fields; the reader checks it first.
#[test]
fn an_attachment_shorter_than_its_fields_is_damage_not_a_panic() {
    let bytes = include_bytes!("../../../fuzz/regressions/mcap-attachment-shorter-than-its-fields");
    if let Ok(rec) = Recording::from_bytes(bytes) {
        // Skipped as damage (reading goes on after it), or the file is cut there.
        let named = rec.damage.entries.iter().any(|d| d.to_string().contains("Attachment"))
            || rec.cut.as_ref().is_some_and(|(_, r)| r.contains("Attachment"));
        assert!(named, "{:?} {:?}", rec.damage, rec.cut);
        if let Some((at, _)) = &rec.cut {
            assert!(*at <= bytes.len() as u64);
        }
    }
    assert!(parse_record(mcap::records::op::ATTACHMENT, &[0u8; 20]).is_err());
    assert!(parse_record(mcap::records::op::ATTACHMENT, &[0xFF; 40]).is_err());
}
