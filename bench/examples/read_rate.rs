//! Read rate of a recording, messages per second, three ways on the same bytes in memory:
//! bench's reader (`RecordingReader`: typed decoding of the contract's channels), the replay
//! path (`Recording` → `ReplayData`, ready to play), and the bare `mcap` crate
//! (`mcap::MessageStream`, no decoding; then with `serde_json::Value` parsing, like a generic
//! JSON consumer). Used by `scripts/replay_vs_python.sh`.
//!
//! ```sh
//! cargo run --release -p bench --example read_rate -- seed.mcap [repeats]
//! ```

use std::time::Instant;

fn best<F: FnMut() -> u64>(repeats: usize, mut f: F) -> (u64, f64) {
    let mut best = f64::INFINITY;
    let mut n = 0;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        n = f();
        best = best.min(t.elapsed().as_secs_f64());
    }
    (n, best)
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().ok_or_else(|| anyhow::anyhow!("usage: read_rate FILE [repeats]"))?;
    let repeats: usize = args.next().map(|r| r.parse()).transpose()?.unwrap_or(5);
    let bytes = std::fs::read(&path)?;

    let ours = best(repeats, || {
        bench_recording::RecordingReader::new(&bytes[..])
            .filter(|i| {
                matches!(
                    i,
                    Ok(bench_recording::Item::Gyro(_)
                        | bench_recording::Item::Table(_)
                        | bench_recording::Item::Chamber(_)
                        | bench_recording::Item::Step(_)
                        | bench_recording::Item::Other(_))
                )
            })
            .count() as u64
    });
    let replay = best(repeats, || {
        let rec = bench_recording::Recording::from_bytes(&bytes).expect("readable");
        let n = (rec.gyro.len() + rec.table.len() + rec.chamber.len() + rec.steps.len()) as u64
            + rec.other_counts.values().sum::<u64>();
        let data = bench::replay::ReplayData::from_recording(&rec, "x").expect("replayable");
        std::hint::black_box(&data);
        n
    });
    let bare = best(repeats, || {
        mcap::MessageStream::new(&bytes).expect("mcap").filter(|m| m.is_ok()).count() as u64
    });
    let bare_json = best(repeats, || {
        mcap::MessageStream::new(&bytes)
            .expect("mcap")
            .filter_map(Result::ok)
            .filter(|m| serde_json::from_slice::<serde_json::Value>(&m.data).is_ok())
            .count() as u64
    });
    println!("{path}: {} bytes, best of {repeats}", bytes.len());
    for (name, (n, s)) in [
        ("bench RecordingReader (typed)", ours),
        ("bench Recording + ReplayData", replay),
        ("mcap::MessageStream (raw)", bare),
        ("mcap::MessageStream + serde_json::Value", bare_json),
    ] {
        println!("{name:<42} {n:>9} msgs {:>8.3} s {:>12.0} msgs/s", s, n as f64 / s);
    }
    Ok(())
}
