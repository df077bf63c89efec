//! The plan's estimate against the run: every shipped scenario simulated in virtual time ends
//! within 5 % of the bench time `RunPlan::estimated_duration` predicted (what `bench validate`
//! prints and the progress bar counts down).

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// A recording sink that keeps nothing (the run's length is all this test wants).
#[derive(Default)]
struct Discard {
    pos: u64,
    len: u64,
}

impl Write for Discard {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.pos += buf.len() as u64;
        self.len = self.len.max(self.pos);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for Discard {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = match to {
            SeekFrom::Start(n) => n,
            SeekFrom::End(d) => self.len.saturating_add_signed(d),
            SeekFrom::Current(d) => self.pos.saturating_add_signed(d),
        };
        Ok(self.pos)
    }
}

#[test]
fn every_shipped_scenario_runs_within_5_percent_of_its_estimate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .expect("scenarios/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    paths.sort();
    assert!(paths.len() >= 4, "{paths:?}");
    // Two at a time (CI has two cores).
    let results: Vec<(String, f64, f64)> = std::thread::scope(|s| {
        let chunks: Vec<Vec<_>> =
            paths.chunks(paths.len().div_ceil(2)).map(<[_]>::to_vec).collect();
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|path| {
                            let plan =
                                bench::scenario::load(path, &bench::simulate::capabilities())
                                    .expect("shipped scenarios validate");
                            let estimate = plan.estimated_duration().as_secs_f64();
                            let (report, _) = bench::runner::run(
                                &plan,
                                bench::runner::Bench::Simulated(bench::simulate::sim_config(
                                    &plan, 1,
                                )),
                                Discard::default(),
                                bench::runner::RunOptions::default(),
                            )
                            .expect("runs");
                            assert!(report.completed(), "{}: {}", path.display(), report.outcome);
                            let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
                            (name.unwrap_or_default(), estimate, report.bench_time.as_secs_f64())
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().expect("no panic")).collect()
    });
    for (name, estimate, actual) in &results {
        let err = (estimate - actual).abs() / actual;
        eprintln!(
            "{name}: estimate {estimate:.0} s, run {actual:.0} s ({:+.2} %)",
            100.0 * (estimate - actual) / actual
        );
        assert!(err <= 0.05, "{name}: estimate {estimate} s vs run {actual} s");
    }
}
