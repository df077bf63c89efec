//! Sampling jitter of a real-time run through virtual ports (issue 3's figure): the simulators
//! served on ptys at 1× real time, the real drivers, the orchestrator and the recorder; then
//! |Δt − 50 ms| of consecutive log times per device channel, p50 / p99 / max.
//!
//! `cargo bench -p bench --bench wire_jitter` (JITTER_SECONDS=60 by default).

use std::io::Cursor;
use std::sync::Arc;

use bench::bench_config::for_served_bench;
use bench::runner::{run, run_info, Bench, Pace, RunOptions};
use bench::simulate::{capabilities, sim_config, SIM_EPOCH_NS};
use bench_drivers::{Clock, SystemClock};
use bench_recording::Recording;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(i).copied().unwrap_or(f64::NAN)
}

fn main() -> anyhow::Result<()> {
    let seconds: u64 =
        std::env::var("JITTER_SECONDS").ok().and_then(|s| s.parse().ok()).unwrap_or(60);
    let scenario = format!(
        "[scenario]\nname = \"jitter\"\n[site]\nlatitude_deg = 48.0\n\
         [[step]]\nlabel = \"spin cw\"\nspin = \"10 °/min\"\ndirection = \"cw\"\naccel = \"1 °/s²\"\n\
         [[step]]\nlabel = \"record cw\"\nrecord = \"{seconds} s\"\n"
    );
    let plan = bench::scenario::parse(&scenario, "jitter.toml", &capabilities())?;
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    let clock = SystemClock::new(1.0);
    let (_served, devices) = rt.block_on(async {
        let sim_clock: Arc<dyn Clock> = Arc::new(SystemClock::new(1.0));
        let served = bench_sim::serve::bench::serve_bench(sim_config(&plan, 1), sim_clock).await?;
        let config = for_served_bench(&served.endpoints, 1.0, 48.0, true);
        let (devices, _) = config.connect(Arc::new(clock.clone())).await?;
        Ok::<_, anyhow::Error>((served, devices))
    })?;
    let _entered = rt.enter();
    let info = Box::new(run_info(&plan, SIM_EPOCH_NS));
    let opts = RunOptions { pace: Pace::RealTime(1.0), ..RunOptions::default() };
    let bench = Bench::Connected { devices, clock, info };
    let (report, cur) = run(&plan, bench, Cursor::new(Vec::new()), opts)?;
    anyhow::ensure!(report.completed(), "run {}", report.outcome);
    let rec = Recording::from_bytes(cur.get_ref())?;
    println!("20 Hz sampling jitter through virtual ports, {seconds} s at 1× real time");
    let channels: [(&str, Vec<u64>); 3] = [
        ("/gyro/rate (SLCAN)", rec.gyro.iter().map(|m| m.log_time_ns).collect()),
        ("/table/state (Actidyn pty)", rec.table.iter().map(|m| m.log_time_ns).collect()),
        ("/chamber/state (Modbus RTU pty)", rec.chamber.iter().map(|m| m.log_time_ns).collect()),
    ];
    for (name, t) in channels {
        let mut j: Vec<f64> =
            t.windows(2).map(|w| ((w[1] - w[0]) as f64 * 1e-6 - 50.0).abs()).collect();
        j.sort_by(f64::total_cmp);
        println!(
            "  {name:<34} n={:>6}  p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms",
            j.len(),
            percentile(&j, 0.5),
            percentile(&j, 0.99),
            j.last().copied().unwrap_or(f64::NAN)
        );
    }
    let gaps = rec.gyro.windows(2).filter(|w| w[1].msg.seq != w[0].msg.seq + 1).count();
    println!("  gyro device-counter gaps: {gaps}");
    Ok(())
}
