//! Recordings from the independent lab writer (`tests/fixtures/lab/labwriter.py`): its lab
//! traits are really in the file, read with the bare `mcap` crate (not bench's reader) against
//! the writer's truth file; and bench's own reader loads the files, a cut one up to its cut.

use std::collections::BTreeMap;
use std::path::Path;

use bench_recording::Recording;
use bench_recording::StepEvent;
use bench_tests::{lab_fixture, lab_truth};
use serde_json::Value;

/// One channel's messages as the bare `mcap` crate reads them.
#[derive(Default)]
struct Chan {
    schema: String,
    schema_encoding: String,
    message_encoding: String,
    log: Vec<u64>,
    publish: Vec<u64>,
    sequence: Vec<u32>,
    body: Vec<Value>,
}

fn read_bare(path: &Path) -> (BTreeMap<String, Chan>, BTreeMap<String, BTreeMap<String, String>>) {
    let buf = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut chans: BTreeMap<String, Chan> = BTreeMap::new();
    for m in mcap::MessageStream::new(&buf).expect("an MCAP file") {
        let m = m.expect("a message");
        let c = chans.entry(m.channel.topic.clone()).or_default();
        if let Some(s) = &m.channel.schema {
            c.schema = s.name.clone();
            c.schema_encoding = s.encoding.clone();
        }
        c.message_encoding = m.channel.message_encoding.clone();
        c.log.push(m.log_time);
        c.publish.push(m.publish_time);
        c.sequence.push(m.sequence);
        c.body.push(serde_json::from_slice(&m.data).expect("a JSON body"));
    }
    let mut meta = BTreeMap::new();
    for r in mcap::read::LinearReader::new(&buf).expect("an MCAP file") {
        if let mcap::records::Record::Metadata(m) = r.expect("a record") {
            meta.insert(m.name, m.metadata);
        }
    }
    (chans, meta)
}

fn truth(mcap: &Path) -> Value {
    let p = lab_truth(mcap);
    serde_json::from_slice(&std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
        .expect("truth JSON")
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not an integer: {v}"))
}

fn median_period_s(t: &[u64]) -> f64 {
    let mut d: Vec<u64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_unstable();
    d[d.len() / 2] as f64 * 1e-9
}

fn mean_std(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    (m, (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n).sqrt())
}

#[test]
fn lab_traits_are_in_the_file_and_bench_loads_it() {
    // More lost and bad frames than the preset's defaults, so their counts mean something.
    let lost_rate = 1e-3;
    let bad_rate = 5e-4;
    let path = lab_fixture(
        "short-lab-null",
        7,
        &[("traits.lost_frames.rate", "1e-3"), ("traits.bad_frames.rate", "5e-4")],
    );
    let t = truth(&path);
    let tr = &t["traits"];
    let (ch, meta) = read_bare(&path);

    // Contract: channels, schemas, encodings, sequences, time order.
    for (topic, schema) in [
        ("/gyro/rate", "bench.GyroSample"),
        ("/table/state", "bench.TableState"),
        ("/chamber/state", "bench.ChamberState"),
        ("/bench/step", "bench.Step"),
    ] {
        let c = &ch[topic];
        assert_eq!((c.schema.as_str(), c.schema_encoding.as_str()), (schema, "jsonschema"));
        assert_eq!(c.message_encoding, "json", "{topic}");
        assert!(c.sequence.iter().enumerate().all(|(i, s)| *s as usize == i), "{topic} sequence");
        assert!(c.log.windows(2).all(|w| w[0] <= w[1]), "{topic} log_time order");
        assert_eq!(c.log.len() as u64, u(&t["counts"][topic]), "{topic} count");
    }
    for name in ["bench.run", "bench.site", "bench.scenario", "bench.gyro_model"] {
        assert!(meta.contains_key(name), "{name}");
    }
    assert_eq!(meta["bench.run"]["outcome"], "completed");

    // Rates: gyro 20 Hz, table 10 Hz, chamber 1 Hz.
    let (g, tb, cb) = (&ch["/gyro/rate"], &ch["/table/state"], &ch["/chamber/state"]);
    for (c, hz) in [(g, 20.0), (tb, 10.0), (cb, 1.0)] {
        let p = median_period_s(&c.log);
        assert!((p * hz - 1.0).abs() < 0.01, "median period {p} s, want {} s", 1.0 / hz);
    }

    // Table angles on the 1″ grid; the measured rate is not the command (an encoder difference).
    let q = std::f64::consts::PI / 648_000.0;
    assert!((f(&tr["angle_quantum_rad"]) - q).abs() < 1e-18);
    for b in &tb.body {
        let k = f(&b["angle"]) / q;
        assert!((k - k.round()).abs() < 1e-6, "angle {} off the 1″ grid", b["angle"]);
    }
    let steady: Vec<f64> = tb
        .body
        .iter()
        .filter(|b| f(&b["rate_command"]) != 0.0)
        .map(|b| f(&b["rate"]) - f(&b["rate_command"]))
        .collect();
    let (_, rate_noise) = mean_std(&steady);
    assert!(rate_noise > 1e-6, "measured rate {rate_noise} rad/s from the command: too clean");

    // Host stamps: latency per channel and Gaussian jitter around each device's sample grid.
    let epoch_ns = u(&t["start_epoch_ns"]);
    // Seconds since the start epoch, subtracted in integers (an f64 holds 1.8e18 ns to 256 ns).
    let since = |ns: u64| (ns as i64 - epoch_ns as i64) as f64 * 1e-9;
    let period = f(&tr["gyro_sample_period_s"]);
    let seq0 = f(&tr["gyro_seq_start"]);
    let phase = f(&t["config"]["gyro"]["phase_s"]);
    let g_off: Vec<f64> = g
        .log
        .iter()
        .zip(&g.body)
        .map(|(l, b)| since(*l) - ((f(&b["seq"]) - seq0 + 1.0) * period + phase))
        .collect();
    let grid_off = |c: &Chan, hz: f64, ph: f64| -> Vec<f64> {
        c.log.iter().enumerate().map(|(j, l)| since(*l) - (ph + j as f64 / hz)).collect()
    };
    let cfg_tr = &t["config"]["traits"];
    let t_off = grid_off(tb, 10.0, f(&cfg_tr["table_phase_s"]));
    let c_off = grid_off(cb, 1.0, f(&cfg_tr["chamber_phase_s"]));
    let mut means = BTreeMap::new();
    for (name, off) in [("gyro", &g_off), ("table", &t_off), ("chamber", &c_off)] {
        let (m, s) = mean_std(off);
        let lat = f(&tr["latency_s"][name]);
        let jit = f(&tr["jitter_s"][name]);
        assert!(
            (m - lat).abs() < 0.1e-3 + 3.0 * jit / (off.len() as f64).sqrt(),
            "{name} latency {m} s, configured {lat} s"
        );
        assert!((s / jit - 1.0).abs() < 0.1, "{name} jitter {s} s, configured {jit} s");
        means.insert(name, m);
    }
    // The table is stamped 9 ms later than the gyro, the chamber 37 ms later.
    assert!((means["table"] - means["gyro"] - 0.009).abs() < 0.3e-3);
    assert!((means["chamber"] - means["gyro"] - 0.037).abs() < 0.5e-3);
    // The device's own stamps: the gyro's from its counter (no jitter), the table's own clock.
    let pub_off: Vec<f64> = g
        .publish
        .iter()
        .zip(&g.body)
        .map(|(p, b)| since(*p) - ((f(&b["seq"]) - seq0 + 1.0) * period + phase))
        .collect();
    assert!(pub_off.iter().all(|o| (o - f(&cfg_tr["gyro_device_offset_s"])).abs() < 2e-9));
    assert!(tb.publish.iter().zip(&tb.log).any(|(p, l)| p != l));

    // Lost frames (sequence gaps, some flagged with SEQ_GAP on the next sample), bad frames.
    let seqs: Vec<u64> = g.body.iter().map(|b| u(&b["seq"])).collect();
    let status: Vec<u64> = g.body.iter().map(|b| u(&b["status"])).collect();
    let lf = &tr["lost_frames"];
    let gap_bits = u(&lf["status_bits"]);
    let (mut gaps, mut lost, mut flagged) = (0u64, 0u64, 0u64);
    for i in 1..seqs.len() {
        let d = seqs[i] - seqs[i - 1];
        assert!(d >= 1, "device counter went back");
        if d > 1 {
            gaps += 1;
            lost += d - 1;
            flagged += u64::from(status[i] & gap_bits != 0);
        }
    }
    assert_eq!(
        (gaps, lost, flagged),
        (u(&lf["gap_count"]), u(&lf["lost_count"]), u(&lf["flagged_gap_count"]))
    );
    let n_dev = (seqs[seqs.len() - 1] - seqs[0] + 1) as f64;
    let expect_gaps = lost_rate * n_dev;
    assert!(
        (gaps as f64 - expect_gaps).abs() < 5.0 * expect_gaps.sqrt() + 2.0,
        "{gaps} gaps, ~{expect_gaps} configured"
    );
    assert!(flagged > 0 && flagged < gaps, "some gaps flagged, some not: {flagged} of {gaps}");
    let bf = &tr["bad_frames"];
    let bad: Vec<&Value> =
        g.body.iter().filter(|b| u(&b["status"]) & u(&bf["status"]) != 0).collect();
    assert_eq!(bad.len() as u64, u(&bf["count"]));
    let expect_bad = bad_rate * n_dev;
    assert!((bad.len() as f64 - expect_bad).abs() < 5.0 * expect_bad.sqrt() + 2.0);
    for b in &bad {
        assert!([12.3, 0.0].contains(&f(&b["rate"])), "garbage rate {}", b["rate"]);
        assert!([-273.15, 0.0, 327.67].contains(&f(&b["temperature"])), "garbage temperature");
    }
    let good_temps =
        g.body.iter().filter(|b| u(&b["status"]) == 0).all(|b| b["temperature"].is_number());
    assert!(good_temps, "this gyro has a temperature sensor");

    // Record steps span whole segments: start and end on the table's reversal commands, the
    // table still turning the old way in the window's first moments.
    let commands: Vec<u64> = t["procedure"]["table_commands"]
        .as_array()
        .expect("commands")
        .iter()
        .map(|c| epoch_ns + (f(&c["command_s"]) * 1e9).round() as u64)
        .collect();
    let steps = &ch["/bench/step"];
    let mut starts = BTreeMap::new();
    let mut ends = BTreeMap::new();
    for (l, b) in steps.log.iter().zip(&steps.body) {
        if b["label"].as_str().is_some_and(|s| s.starts_with("record")) {
            let i = u(&b["index"]);
            match b["event"].as_str() {
                Some("start") => starts.insert(i, *l),
                Some("end") => ends.insert(i, *l),
                e => panic!("unexpected event {e:?}"),
            };
        }
    }
    assert_eq!(starts.len(), t["procedure"]["windows"].as_array().map(Vec::len).unwrap_or(0));
    let mut turned_late = 0;
    for (i, s) in &starts {
        let e = ends[i];
        assert!(commands.contains(s) && commands.contains(&e), "record step {i} not on reversals");
        let k = commands.iter().position(|c| c == s).expect("a command");
        if k == 0 {
            continue; // the first window starts with the spin-up from rest
        }
        // Table readings in the window's first 2 s: the angle first moves the old way.
        let first: Vec<(f64, f64)> = tb
            .log
            .iter()
            .zip(&tb.body)
            .filter(|(l, _)| **l >= *s && **l < s + 2_000_000_000)
            .map(|(_, b)| (f(&b["angle"]), f(&b["rate_command"])))
            .collect();
        let new_dir = first.last().map(|x| x.1.signum()).unwrap_or(0.0);
        if (first[1].0 - first[0].0) * new_dir < 0.0 {
            turned_late += 1;
        }
    }
    assert!(
        turned_late >= starts.len() - 2,
        "{turned_late} of {} windows open with the old direction",
        starts.len()
    );

    // Bench's own reader agrees.
    let rec = Recording::load(&path).expect("bench loads a lab recording");
    assert!(rec.complete && rec.cut.is_none());
    assert_eq!(
        (rec.gyro.len(), rec.table.len(), rec.chamber.len(), rec.steps.len()),
        (g.log.len(), tb.log.len(), cb.log.len(), steps.log.len())
    );
    assert_eq!(rec.outcome(), Some(bench_recording::Outcome::Completed));
    assert!(rec.metadata("bench.gyro_model").is_some());
    assert!(rec.gyro.iter().zip(&g.log).all(|(a, l)| a.log_time_ns == *l));
}

#[test]
fn a_cut_lab_file_loads_up_to_its_cut() {
    let path = lab_fixture("short-lab-cut", 7, &[]);
    let t = truth(&path);
    let cut = &t["cut"];
    let rec = Recording::load(&path).expect("bench loads a cut lab recording");
    assert!(!rec.complete);
    let (at, _) = rec.cut.as_ref().expect("the file is cut");
    assert!(*at <= u(&cut["byte"]));
    assert_eq!(rec.outcome(), None, "a cut run has no bench.run");
    // Everything of the complete chunks, at most the damaged chunk's messages more.
    for (topic, n) in [
        ("/gyro/rate", rec.gyro.len()),
        ("/table/state", rec.table.len()),
        ("/chamber/state", rec.chamber.len()),
        ("/bench/step", rec.steps.len()),
    ] {
        let lo = u(&cut["surviving_counts"][topic]) as usize;
        let hi = lo + u(&cut["damaged_chunk_counts"][topic]) as usize;
        assert!((lo..=hi).contains(&n), "{topic}: {n} read, {lo}..={hi} expected");
    }
    // The record step open at the cut has its start and no end.
    let open: Vec<u64> =
        cut["record_steps_without_end"].as_array().expect("list").iter().map(u).collect();
    assert!(!open.is_empty());
    for i in open {
        let ev: Vec<StepEvent> =
            rec.steps.iter().filter(|s| s.msg.index == i).map(|s| s.msg.event).collect();
        assert_eq!(ev, vec![StepEvent::Start], "record step {i}");
    }
}

#[test]
fn lab_files_load_whatever_their_container() {
    for (preset, complete) in
        [("short-lab-crashed", false), ("short-lab-unchunked", true), ("short-lab-lz4", true)]
    {
        let path = lab_fixture(preset, 3, &[]);
        let t = truth(&path);
        let rec = Recording::load(&path).unwrap_or_else(|e| panic!("{preset}: {e}"));
        assert_eq!(rec.complete, complete, "{preset}");
        assert_eq!(rec.gyro.len() as u64, u(&t["counts"]["/gyro/rate"]), "{preset}");
        assert_eq!(rec.table.len() as u64, u(&t["counts"]["/table/state"]), "{preset}");
        assert_eq!(rec.steps.len() as u64, u(&t["counts"]["/bench/step"]), "{preset}");
        assert_eq!(
            rec.outcome(),
            complete.then_some(bench_recording::Outcome::Completed),
            "{preset}"
        );
    }
}
