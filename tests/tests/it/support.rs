//! What the tests of several subjects share that needs the `bench` crate (which the
//! `bench-tests` library cannot depend on: `bench`'s benchmarks use that library).

/// Run on the devices `config` names (the peers): connect them on a clock at the config's time
/// scale, make the plan from their capabilities with `plan` (the config's site replacing the
/// scenario's), and run it in real time under the config's fault policy into memory. Returns the
/// report, the recording's bytes and the clock (for what a test does after the run).
///
/// The run blocks its thread (`block_in_place`, so the runtime must be multi-threaded): the
/// runtime's other worker carries the drivers' I/O.
pub(crate) async fn run_connected(
    config: &bench::bench_config::BenchConfig,
    plan: impl FnOnce(&bench::scenario::Capabilities) -> bench::plan::RunPlan,
) -> (bench::runner::RunReport, Vec<u8>, bench_drivers::SystemClock) {
    use bench::runner::{run, run_info, Bench, Pace, RunOptions};
    let clock = bench_drivers::SystemClock::new(config.bench.time_scale);
    let shared: std::sync::Arc<dyn bench_drivers::Clock> = std::sync::Arc::new(clock.clone());
    let (devices, caps) = config.connect(shared).await.expect("every peer answers");
    let mut plan = plan(&caps);
    if let Some(site) = config.site() {
        plan.site = site;
    }
    let info = Box::new(run_info(&plan, 0));
    let bench = Bench::Connected { devices, clock: clock.clone(), info };
    let opts = RunOptions {
        pace: Pace::RealTime(config.bench.time_scale),
        policy: config.bench.policy(),
        ..RunOptions::default()
    };
    let (report, cur) =
        tokio::task::block_in_place(|| run(&plan, bench, std::io::Cursor::new(Vec::new()), opts))
            .expect("the run ends");
    (report, cur.into_inner(), clock)
}
