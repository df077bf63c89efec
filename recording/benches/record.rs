//! Recorder throughput: messages per second of wall time for a realistic stream (gyro, table
//! and chamber at 20 Hz each, a step event every 1000 samples), against the bare mcap writer
//! writing the same JSON bodies (pre-serialised) with the same options. The ratio of the two
//! times is the recorder's overhead (JSON encoding, checks, bookkeeping).
//!
//! Run: `cargo bench -p bench-recording --bench record`. Goal: the recorder sustains > 1.5 M messages/s.
#![allow(missing_docs)] // criterion's macros generate undocumented items

use std::{collections::BTreeMap, hint::black_box, io::Cursor, time::Duration};

use bench_recording::{
    schema, ChamberMsg, GyroMsg, Outcome, Recorder, RecorderOptions, RunInfo, Site, StepEvent,
    TableMsg,
};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use mcap::{records::MessageHeader, Compression};

/// Bench seconds per iteration: 3 × 20 Hz × 200 s = 12 000 messages.
const SECONDS: u64 = 200;
const HZ: u64 = 20;
const EPOCH: u64 = 1_700_000_000_000_000_000;

enum Msg {
    Gyro(GyroMsg),
    Table(TableMsg),
    Chamber(ChamberMsg),
    Step(u64, StepEvent),
}

fn stream() -> Vec<(Duration, Msg)> {
    let mut out = Vec::new();
    let period_ns = 1_000_000_000 / HZ;
    let rate = 10f64.to_radians() / 60.0;
    for i in 0..SECONDS * HZ {
        let t = Duration::from_nanos(i * period_ns);
        let ts = t.as_secs_f64();
        if i % 1000 == 0 {
            out.push((t, Msg::Step(i / 1000, StepEvent::Start)));
        }
        out.push((
            t,
            Msg::Gyro(GyroMsg {
                rate_rad_s: rate + 7.27e-5 * 0.7 + 1e-6 * (ts * 1.7).sin(),
                temperature_c: Some(20.0 + 0.01 * ts + 0.001 * (ts * 3.1).cos()),
                seq: i,
                status: 0,
            }),
        ));
        out.push((
            t,
            Msg::Table(TableMsg {
                angle_rad: rate * ts + 1e-6 * (ts * 0.3).sin(),
                rate_rad_s: rate + 1e-7 * (ts * 5.0).sin(),
                rate_command_rad_s: rate,
                status: 0,
            }),
        ));
        out.push((
            t,
            Msg::Chamber(ChamberMsg {
                temperature_c: 20.0 + 0.01 * ts + 0.05 * (ts * 0.1).sin(),
                setpoint_c: 20.0 + 0.01 * ts,
                status: 2,
            }),
        ));
        if i % 1000 == 999 {
            out.push((t, Msg::Step(i / 1000, StepEvent::End)));
        }
    }
    out
}

fn info() -> RunInfo {
    RunInfo::new(EPOCH, "bench", "name = \"bench\"\n", Site::at_latitude(45.0), BTreeMap::new())
}

fn options() -> RecorderOptions {
    RecorderOptions { flush_interval: None, ..RecorderOptions::default() }
}

fn record(stream: &[(Duration, Msg)], capacity: usize, options: RecorderOptions) -> Vec<u8> {
    let sink = Cursor::new(Vec::with_capacity(capacity));
    let mut r = Recorder::with_options(sink, info(), options).expect("start");
    for (t, m) in stream {
        match m {
            Msg::Gyro(s) => r.gyro(*t, None, s),
            Msg::Table(s) => r.table(*t, None, s),
            Msg::Chamber(s) => r.chamber(*t, None, s),
            Msg::Step(i, e) => r.step(*t, *i, "step", *e, "record cw"),
        }
        .expect("write");
    }
    r.finish(&Outcome::Completed).expect("finish").into_inner()
}

/// The same messages as (channel index, log_time, JSON body), for the bare writer.
fn pre_serialised(file: &[u8]) -> Vec<(usize, u64, Vec<u8>)> {
    let topics =
        [schema::TOPIC_GYRO, schema::TOPIC_TABLE, schema::TOPIC_CHAMBER, schema::TOPIC_STEP];
    mcap::MessageStream::new(file)
        .expect("stream")
        .map(|m| {
            let m = m.expect("message");
            let ch = topics.iter().position(|t| *t == m.channel.topic).expect("known topic");
            (ch, m.log_time, m.data.into_owned())
        })
        .collect()
}

fn bare(msgs: &[(usize, u64, Vec<u8>)], capacity: usize) -> Vec<u8> {
    let sink = Cursor::new(Vec::with_capacity(capacity));
    let mut w = options().write_options().create(sink).expect("start");
    let no_meta = BTreeMap::new();
    let mut ids = Vec::new();
    for (topic, name, doc) in [
        (schema::TOPIC_GYRO, schema::SCHEMA_GYRO, schema::GYRO_SCHEMA_JSON),
        (schema::TOPIC_TABLE, schema::SCHEMA_TABLE, schema::TABLE_SCHEMA_JSON),
        (schema::TOPIC_CHAMBER, schema::SCHEMA_CHAMBER, schema::CHAMBER_SCHEMA_JSON),
        (schema::TOPIC_STEP, schema::SCHEMA_STEP, schema::STEP_SCHEMA_JSON),
    ] {
        let s = w.add_schema(name, "jsonschema", doc.as_bytes()).expect("schema");
        ids.push(w.add_channel(s, topic, "json", &no_meta).expect("channel"));
    }
    let mut seq = [0u32; 4];
    for (ch, t, data) in msgs {
        let header = MessageHeader {
            channel_id: ids[*ch],
            sequence: seq[*ch],
            log_time: *t,
            publish_time: *t,
        };
        seq[*ch] += 1;
        w.write_to_known_channel(&header, data).expect("write");
    }
    w.finish().expect("finish");
    w.into_inner().into_inner()
}

fn throughput(c: &mut Criterion) {
    let stream = stream();
    let file = record(&stream, 0, options());
    let capacity = file.len() * 2;
    let msgs = pre_serialised(&file);
    assert_eq!(msgs.len(), stream.len());
    let mut g = c.benchmark_group("record");
    g.throughput(Throughput::Elements(stream.len() as u64));
    eprintln!("recorder (default options): {} bytes", file.len());
    g.bench_function("recorder", |b| {
        b.iter(|| black_box(record(black_box(&stream), capacity, options())))
    });
    let variants = [
        ("recorder_zstd3", Some(Compression::Zstd), 3, 0),
        ("recorder_zstd1_1thread", Some(Compression::Zstd), 1, 1),
        ("recorder_lz4", Some(Compression::Lz4), 0, 0),
        ("recorder_uncompressed", None, 0, 0),
    ];
    for (name, compression, compression_level, compression_threads) in variants {
        let o =
            RecorderOptions { compression, compression_level, compression_threads, ..options() };
        let size = record(&stream, capacity, o.clone()).len();
        eprintln!("{name}: {size} bytes for {} messages", stream.len());
        g.bench_function(name, |b| {
            b.iter(|| black_box(record(black_box(&stream), capacity, o.clone())))
        });
    }
    g.bench_function("bare_mcap_writer", |b| {
        b.iter(|| black_box(bare(black_box(&msgs), capacity)))
    });
    g.finish();
}

criterion_group!(benches, throughput);
criterion_main!(benches);
