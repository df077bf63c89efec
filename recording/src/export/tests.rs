//! Export a recorder file to CSV and Parquet and read both back.

use std::collections::BTreeMap;
use std::io::Cursor;
use std::time::Duration;

use super::*;
use crate::message::{ChamberMsg, GyroMsg, LogLevel, Outcome, StepEvent};
use crate::site::Site;
use crate::writer::{Recorder, RunInfo};

const EPOCH: u64 = 1_800_000_000_000_000_000;

fn file() -> Vec<u8> {
    let info = RunInfo::new(EPOCH, "t", "", Site::at_latitude(1.0), BTreeMap::new());
    let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("start");
    r.step(Duration::ZERO, 0, "wait", StepEvent::Start, "record, \"quoted\"").expect("step");
    for i in 0..50u64 {
        let t = Duration::from_millis(50 * i);
        let g = GyroMsg {
            rate_rad_s: 0.5 + i as f64 / 1024.0,
            temperature_c: (i % 3 != 0).then_some(-12.5),
            seq: 1_000 + i,
            status: (i == 7) as u32,
        };
        r.gyro(t, Some(t + Duration::from_nanos(3)), &g).expect("gyro");
        let c = ChamberMsg { temperature_c: 20.0, setpoint_c: 21.25, status: 0 };
        r.chamber(t, None, &c).expect("chamber");
    }
    r.log(Duration::from_secs(1), LogLevel::Warning, "hot", "bench::x", "x.rs", 9).expect("log");
    r.finish(&Outcome::Completed).expect("finish").into_inner()
}

fn export_to(format: Format) -> (tempfile::TempDir, ExportReport) {
    let dir = tempfile::tempdir().expect("tempdir");
    let bytes = file();
    let report = export(RecordingReader::new(&bytes[..]), dir.path(), format).expect("exports");
    (dir, report)
}

#[test]
fn csv_tables_read_back() {
    let (dir, report) = export_to(Format::Csv);
    let topics: Vec<&str> = report.tables.iter().map(|t| t.topic.as_str()).collect();
    assert_eq!(topics, ["/bench/step", "/chamber/state", "/gyro/rate", "/log"]);
    let gyro = report.tables.iter().find(|t| t.topic == "/gyro/rate").expect("gyro");
    assert_eq!(gyro.path, dir.path().join("gyro_rate.csv"));
    assert_eq!(gyro.rows, 50);
    let mut rd = csv::Reader::from_path(&gyro.path).expect("csv");
    let header: Vec<String> = rd.headers().expect("header").iter().map(String::from).collect();
    assert_eq!(
        header,
        [
            "timestamp",
            "log_time_ns",
            "publish_time_ns",
            "sequence",
            "rate",
            "temperature",
            "seq",
            "status"
        ]
    );
    assert_eq!(gyro.columns, header);
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.expect("row")).collect();
    assert_eq!(rows.len(), 50);
    // The time stamp: the log time as RFC 3339 UTC text, to the nanosecond (EPOCH is
    // 2027-01-15T08:00:00 UTC).
    assert_eq!(&rows[7][0], "2027-01-15T08:00:00.350000000Z");
    let rows: Vec<Vec<String>> =
        rows.iter().map(|r| r.iter().skip(1).map(String::from).collect()).collect();
    let r7 = &rows[7];
    assert_eq!(r7[0].parse::<u64>().ok(), Some(EPOCH + 350_000_000));
    assert_eq!(r7[1].parse::<u64>().ok(), Some(EPOCH + 350_000_003));
    assert_eq!(&r7[2], "7");
    assert_eq!(r7[3].parse::<f64>().ok(), Some(0.5 + 7.0 / 1024.0));
    assert_eq!(&r7[4], "-12.5");
    assert_eq!((r7[5].as_str(), r7[6].as_str()), ("1007", "1"));
    // A gyro without a temperature reading: an empty cell.
    assert_eq!(&rows[6][4], "");
    // Nested fields are flattened; text with commas and quotes survives.
    let mut rd = csv::Reader::from_path(dir.path().join("log.csv")).expect("csv");
    let header: Vec<String> = rd.headers().expect("header").iter().map(String::from).collect();
    assert!(header.contains(&"timestamp.sec".to_string()), "{header:?}");
    // `timestamp.sec` does not clash with the time stamp column.
    assert_eq!(header[0], "timestamp");
    let mut rd = csv::Reader::from_path(dir.path().join("bench_step.csv")).expect("csv");
    let row = rd.records().next().expect("a row").expect("row");
    assert_eq!(row.iter().next_back(), Some("record, \"quoted\""));
}

#[test]
fn parquet_tables_read_back_with_types_and_nulls() {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::Field;
    let (dir, report) = export_to(Format::Parquet);
    let gyro = report.tables.iter().find(|t| t.topic == "/gyro/rate").expect("gyro");
    assert_eq!(gyro.path, dir.path().join("gyro_rate.parquet"));
    let file = std::fs::File::open(&gyro.path).expect("file");
    let reader = SerializedFileReader::new(file).expect("parquet");
    assert_eq!(reader.metadata().file_metadata().num_rows(), 50);
    let rows: Vec<Vec<(String, Field)>> =
        reader.get_row_iter(None).expect("rows").map(|r| r.expect("row").into_columns()).collect();
    let r7 = &rows[7];
    let names: Vec<&str> = r7.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "timestamp",
            "log_time_ns",
            "publish_time_ns",
            "sequence",
            "rate",
            "temperature",
            "seq",
            "status"
        ]
    );
    let r7 = &r7[1..];
    assert_eq!(r7[0].1, Field::Long((EPOCH + 350_000_000) as i64));
    assert_eq!(r7[1].1, Field::Long((EPOCH + 350_000_003) as i64));
    assert_eq!(r7[2].1, Field::Long(7));
    assert_eq!(r7[3].1, Field::Double(0.5 + 7.0 / 1024.0));
    assert_eq!(r7[4].1, Field::Double(-12.5));
    assert_eq!(r7[5].1, Field::Long(1007));
    assert_eq!(r7[6].1, Field::Long(1));
    assert_eq!(rows[6][5].1, Field::Null);
    // The timestamp: the log time, nanoseconds, UTC; the units in the key-value metadata.
    let schema = reader.metadata().file_metadata().schema_descr();
    let ts = schema.column(0);
    assert_eq!(
        ts.logical_type_ref(),
        Some(&parquet::basic::LogicalType::timestamp(true, parquet::basic::TimeUnit::NANOS))
    );
    let kv: BTreeMap<String, Option<String>> = reader
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .expect("key-value metadata")
        .iter()
        .map(|k| (k.key.clone(), k.value.clone()))
        .collect();
    assert_eq!(kv.get("unit.rate"), Some(&Some("rad/s".to_owned())));
    assert_eq!(kv.get("unit.temperature"), Some(&Some("°C".to_owned())));
    assert_eq!(kv.get("unit.seq"), None);
    let chamber = report.tables.iter().find(|t| t.topic == "/chamber/state").expect("chamber");
    let reader =
        SerializedFileReader::new(std::fs::File::open(&chamber.path).expect("file")).expect("pq");
    let first = reader.get_row_iter(None).expect("rows").next().expect("row").expect("row");
    let cols = first.into_columns();
    assert_eq!(cols[5], ("setpoint".to_string(), Field::Double(21.25)));
    let log = report.tables.iter().find(|t| t.topic == "/log").expect("log");
    let reader =
        SerializedFileReader::new(std::fs::File::open(&log.path).expect("file")).expect("pq");
    let first = reader.get_row_iter(None).expect("rows").next().expect("row").expect("row");
    let cols: BTreeMap<String, Field> = first.into_columns().into_iter().collect();
    assert_eq!(cols.get("message"), Some(&Field::Str("hot".into())));
    assert_eq!(cols.get("level"), Some(&Field::Long(3)));
    assert_eq!(cols.get("timestamp.sec"), Some(&Field::Long(1_800_000_001)));
}

/// Units sidecar of a CSV table: column → unit.
fn units_of(path: &Path) -> BTreeMap<String, String> {
    let mut rd = csv::Reader::from_path(path).expect("units csv");
    let header: Vec<String> = rd.headers().expect("header").iter().map(String::from).collect();
    assert_eq!(header, ["column", "unit"]);
    rd.records().map(|r| r.expect("row")).map(|r| (r[0].to_owned(), r[1].to_owned())).collect()
}

#[test]
fn csv_tables_have_a_units_sidecar_naming_every_column() {
    let (dir, report) = export_to(Format::Csv);
    let gyro = report.tables.iter().find(|t| t.topic == "/gyro/rate").expect("gyro");
    let path = gyro.units.clone().expect("a sidecar");
    assert_eq!(path, dir.path().join("gyro_rate.units.csv"));
    let units = units_of(&path);
    assert_eq!(units.keys().count(), gyro.columns.len(), "{units:?}");
    assert_eq!(units["rate"], "rad/s");
    assert_eq!(units["temperature"], "°C");
    assert_eq!(units["log_time_ns"], "ns");
    assert_eq!(units["timestamp"], "RFC 3339, UTC");
    assert_eq!(units["seq"], "");
    let chamber = report.tables.iter().find(|t| t.topic == "/chamber/state").expect("chamber");
    assert_eq!(units_of(chamber.units.as_deref().expect("sidecar"))["setpoint"], "°C");
}

/// A gyro with no temperature sensor, a record window from 0.5 s to 1.5 s of a 2.5 s run.
fn no_temperature_file() -> Vec<u8> {
    let info = RunInfo::new(EPOCH, "t", "", Site::at_latitude(1.0), BTreeMap::new());
    let mut r = Recorder::new(Cursor::new(Vec::new()), info).expect("start");
    for i in 0..50u64 {
        let t = Duration::from_millis(50 * i);
        if i == 10 {
            r.step(t, 0, "record", StepEvent::Start, "record cw").expect("step");
        }
        if i == 30 {
            r.step(t, 0, "record", StepEvent::End, "record cw").expect("step");
        }
        // Whole numbers in a float field: still a float column.
        let g = GyroMsg { rate_rad_s: 1.0, temperature_c: None, seq: i, status: 0 };
        r.gyro(t, None, &g).expect("gyro");
        let c = ChamberMsg { temperature_c: 20.0, setpoint_c: 20.0, status: 0 };
        r.chamber(t, None, &c).expect("chamber");
    }
    r.finish(&Outcome::Completed).expect("finish").into_inner()
}

#[test]
fn parquet_columns_have_the_contracts_types_whatever_the_values() {
    use parquet::basic::Type as Physical;
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::Field;
    let dir = tempfile::tempdir().expect("tempdir");
    let bytes = no_temperature_file();
    let report = export_with(RecordingReader::new(&bytes[..]), dir.path(), Format::Parquet, true)
        .expect("exports");
    let physical = |path: &Path| -> BTreeMap<String, Physical> {
        let r = SerializedFileReader::new(std::fs::File::open(path).expect("file")).expect("pq");
        let schema = r.metadata().file_metadata().schema_descr_ptr();
        (0..schema.num_columns())
            .map(|i| (schema.column(i).name().to_owned(), schema.column(i).physical_type()))
            .collect()
    };
    let gyro = report.tables.iter().find(|t| t.topic == "/gyro/rate").expect("gyro");
    let types = physical(&gyro.path);
    assert_eq!(types["temperature"], Physical::DOUBLE, "{types:?}");
    assert_eq!(types["rate"], Physical::DOUBLE, "{types:?}");
    assert_eq!(types["seq"], Physical::INT64, "{types:?}");
    let merged = report.tables.iter().find(|t| t.topic == MERGED).expect("merged");
    let types = physical(&merged.path);
    assert_eq!(types["gyro_temperature"], Physical::DOUBLE, "{types:?}");
    assert_eq!(types["chamber_setpoint"], Physical::DOUBLE, "{types:?}");
    assert_eq!(types["record_window"], Physical::BYTE_ARRAY, "{types:?}");
    // Read back: temperature null everywhere, the record window null outside [0.5 s, 1.5 s).
    let r = SerializedFileReader::new(std::fs::File::open(&merged.path).expect("f")).expect("pq");
    let rows: Vec<BTreeMap<String, Field>> = r
        .get_row_iter(None)
        .expect("rows")
        .map(|row| row.expect("row").into_columns().into_iter().collect())
        .collect();
    assert_eq!(rows.len(), 50);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row["gyro_temperature"], Field::Null, "row {i}");
        assert_eq!(row["gyro_rate"], Field::Double(1.0), "row {i}");
        let want = if (10..30).contains(&i) { Field::Str("record cw".into()) } else { Field::Null };
        assert_eq!(row["record_window"], want, "row {i}");
    }
}

#[test]
fn csv_merged_leaves_the_record_window_empty_outside_windows() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bytes = no_temperature_file();
    let report = export_with(RecordingReader::new(&bytes[..]), dir.path(), Format::Csv, true)
        .expect("exports");
    let merged = report.tables.iter().find(|t| t.topic == MERGED).expect("merged");
    let mut rd = csv::Reader::from_path(&merged.path).expect("csv");
    let header: Vec<String> = rd.headers().expect("header").iter().map(String::from).collect();
    let w = header.iter().position(|h| h == "record_window").expect("column");
    let t = header.iter().position(|h| h == "gyro_temperature").expect("column");
    let rows: Vec<csv::StringRecord> = rd.records().map(|r| r.expect("row")).collect();
    assert_eq!((&rows[9][w], &rows[10][w], &rows[30][w]), ("", "record cw", ""));
    assert!(rows.iter().all(|r| r[t].is_empty()));
    let units = units_of(merged.units.as_deref().expect("sidecar"));
    assert_eq!(units["gyro_temperature"], "°C");
    assert_eq!(units["bench_time_s"], "s");
    assert_eq!(units["record_window"], "");
}

#[test]
fn column_types_widen() {
    use serde_json::json;
    let t = |vs: &[serde_json::Value]| {
        vs.iter().fold(ColumnType::Null, |t, v| t.widen(&Cell::from_value(v.clone())))
    };
    assert_eq!(t(&[json!(1), json!(null), json!(2)]), ColumnType::Int);
    assert_eq!(t(&[json!(1), json!(2.5)]), ColumnType::Float);
    assert_eq!(t(&[json!(u64::MAX)]), ColumnType::Float);
    assert_eq!(t(&[json!(true), json!(1)]), ColumnType::Text);
    assert_eq!(t(&[json!([1, 2])]), ColumnType::Text);
    assert_eq!(t(&[json!(null)]), ColumnType::Null);
    assert_eq!(table_name("/gyro/rate"), "gyro_rate");
}

#[test]
fn the_merged_table_takes_the_latest_prior_readings_and_the_record_window() {
    // Gyro and chamber every 50 ms from 0 to 2.45 s; the chamber slowed to every 150 ms (from
    // 50 ms) by keeping one reading in three. The record step opened at 0 never ends here, so
    // it runs to the end.
    let bytes = file();
    let mut channels = collect(RecordingReader::new(&bytes[..])).expect("collect").0;
    let chamber = channels.get_mut("/chamber/state").expect("chamber");
    let mut kept = Channel::new("json".into());
    (kept.columns, kept.index) = (chamber.columns.clone(), chamber.index.clone());
    for r in (0..chamber.rows()).filter(|r| r % 3 == 1) {
        kept.cells.extend(chamber.row(r).iter().cloned());
        kept.end_row(chamber.log[r], chamber.publish[r], chamber.sequence[r]);
    }
    *chamber = kept;
    let m = merge(&channels);
    assert_eq!(m.rows(), 50);
    let get = |r: usize, name: &str| m.field(r, name).cloned();
    // Sample 0 (t = 0) is before the first kept chamber reading (50 ms): none.
    assert_eq!(get(0, "chamber_log_time_ns"), None);
    // Sample 3 (150 ms): the reading of 50 ms, held (the next is at 200 ms).
    assert_eq!(get(3, "chamber_log_time_ns"), Some(Cell::Int(EPOCH as i64 + 50_000_000)));
    // Sample 4 (200 ms): the reading of 200 ms itself (at or before).
    assert_eq!(get(4, "chamber_log_time_ns"), Some(Cell::Int(EPOCH as i64 + 200_000_000)));
    assert_eq!(get(4, "chamber_setpoint"), Some(Cell::Float(21.25)));
    assert_eq!(get(4, "gyro_seq"), Some(Cell::Int(1004)));
    assert_eq!(get(4, "bench_time_s"), Some(Cell::Float(0.2)));
    // The step labelled `record, "quoted"` started at 0 and has no end: every sample is in it.
    assert_eq!(get(49, "record_window"), Some(Cell::Str("record, \"quoted\"".into())));
    assert_eq!(column_unit(MERGED, "chamber_setpoint"), Some("°C"));
    assert_eq!(column_unit(MERGED, "gyro_rate"), Some("rad/s"));
    assert_eq!(column_unit(MERGED, "record_window"), None);
}

fn parse(body: &str) -> Part {
    let info = ChannelInfo {
        id: 1,
        topic: "/x".into(),
        schema_name: String::new(),
        schema_encoding: String::new(),
        message_encoding: "json".into(),
    };
    let mut parts = Vec::new();
    part(&mut parts, &Arc::new(info)).message(5, 6, 7, body.as_bytes());
    parts.pop().expect("one part")
}

#[test]
fn bodies_parse_into_cells_as_serde_json_values_flatten() {
    // Members in body order, repeats kept; a nested object's members sorted and flattened
    // with dots (as `serde_json::Map`), arrays as JSON text, integers above i64 apart.
    let p = parse(
        r#"{"b":1,"a":{"z":2,"y":[1,{"q":null}],"x":{}},"c":-5,"d":18446744073709551615,"e":"x\"\u00e9","b":2.5,"f":true,"g":null}"#,
    );
    assert!(p.bad.is_none(), "{:?}", p.bad);
    let got: Vec<(&str, Cell)> =
        p.cells.iter().map(|(k, c)| (&*p.keys[*k as usize], c.clone())).collect();
    let want = vec![
        ("b", Cell::Int(1)),
        ("a.y", Cell::Json("[1,{\"q\":null}]".into())),
        ("a.z", Cell::Int(2)),
        ("c", Cell::Int(-5)),
        ("d", Cell::Big(u64::MAX)),
        ("e", Cell::Str("x\"é".into())),
        ("b", Cell::Float(2.5)),
        ("f", Cell::Bool(true)),
        ("g", Cell::Null),
    ];
    assert_eq!(got, want);
    assert_eq!((p.log, p.publish, p.sequence, p.row_end), (vec![5], vec![6], vec![7], vec![9]));
    // Not an object, or trailing bytes: the decoder's words, no row.
    for (body, words) in [("[1]", "expected a JSON object"), (r#"{"a":1} x"#, "trailing")] {
        let p = parse(body);
        let (at, _, _, detail) = p.bad.expect("bad");
        assert!(at == 0 && detail.contains(words) && p.row_end.is_empty(), "{body}: {detail}");
    }
}

#[test]
fn time_stamps_formatted_once_a_second_read_as_each_one_formatted_alone() {
    let mut stamps = Stamps::default();
    let ns = [
        1_764_000_000_000_000_000,
        1_764_000_000_050_000_000,
        1_764_000_000_999_999_999,
        1_764_000_001_000_000_007,
        1_764_000_001_000_000_007,
        0,
        -1,
        -1_000_000_001,
        i64::MIN,
        i64::MAX,
    ];
    for t in ns {
        let (mut got, mut want) = (Vec::new(), String::new());
        stamps.push(t, &mut got);
        rfc3339_into(t, &mut want);
        assert_eq!(String::from_utf8(got).expect("utf-8"), want, "{t}");
    }
}

#[test]
fn a_float_cell_is_the_shortest_text_that_reads_back_bit_for_bit() {
    let cases = [
        (2.3e-5, "0.000023"),
        (1e-5, "0.00001"),
        (1e-6, "1e-6"),
        (20.5, "20.5"),
        (1.0, "1.0"),
        (-0.0, "-0.0"),
        (1e16, "1e16"),
        (2.0434831538589747e-7, "2.0434831538589747e-7"),
    ];
    for (f, want) in cases {
        let text = cell(&Cell::Float(f));
        assert_eq!(text, want);
        assert_eq!(text.parse::<f64>().expect("reads back").to_bits(), f.to_bits(), "{f}");
    }
}
