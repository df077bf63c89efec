//! `bench sim serve`: the simulated bench on virtual ports, for the real drivers (ours or a
//! third party's) to talk to.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

use super::say::say;
use anyhow::Context as _;
use bench::bench_config::for_served_bench;
use bench_drivers::{Clock, SystemClock};
use bench_sim::faults::Fault;
use bench_sim::serve::bench::{serve_bench, BenchFaults};
use bench_sim::SimConfig;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};

/// `bench sim …`.
#[derive(clap::Subcommand, Debug)]
pub enum SimCommand {
    /// Serve the simulated table, chamber and gyro on pseudo-terminals and loopback TCP, print
    /// where each listens, and write a bench config that points at them.
    Serve(ServeArgs),
}

/// Arguments of `bench sim serve`.
#[derive(clap::Args, Debug)]
pub struct ServeArgs {
    /// Bench time per wall time (the bench run against it must use the same; the written
    /// config says so).
    #[arg(long, default_value_t = 1.0)]
    pub time_scale: f64,
    /// Seed of the simulator's random streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Take the simulator's settings (site, gyro rate and true model, initial temperature)
    /// from this scenario.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Take the site and the `[simulation]` settings (effects beyond the gyro's model,
    /// concealed from the recording) from this bench config; its drivers are not used.
    #[arg(long)]
    pub bench: Option<PathBuf>,
    /// Where to write the bench config.
    #[arg(long, default_value = "bench-sim.toml")]
    pub config_out: PathBuf,
}

/// Dispatch `bench sim …`.
pub fn run(cmd: SimCommand) -> anyhow::Result<ExitCode> {
    match cmd {
        SimCommand::Serve(a) => serve(a),
    }
}

fn serve(args: ServeArgs) -> anyhow::Result<ExitCode> {
    if !(args.time_scale.is_finite() && args.time_scale > 0.0) {
        anyhow::bail!("--time-scale must be a positive number, got {}", args.time_scale);
    }
    let mut config = match &args.scenario {
        Some(path) => {
            let plan = bench::scenario::load(path, &bench::simulate::capabilities())?;
            bench::simulate::sim_config(&plan, args.seed)
        }
        None => SimConfig { seed: args.seed, ..SimConfig::default() },
    };
    if let Some(path) = &args.bench {
        let bench = bench::bench_config::BenchConfig::load(path)?;
        apply_bench_config(&mut config, &bench);
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?;
    rt.block_on(async move {
        let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(args.time_scale));
        let (lat, up) = (config.latitude_deg, config.axis_up);
        let served = serve_bench(config, clock).await?;
        let e = &served.endpoints;
        let bench = for_served_bench(e, args.time_scale, lat, up);
        super::write_served_config(
            &args.config_out,
            "`bench sim serve` for the simulated bench it serves",
            e,
            &bench,
        )?;
        let control = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
        say!("simulated bench at {}× real time (seed {})", args.time_scale, args.seed);
        super::print_endpoints(e);
        say!("  faults   JSON lines on tcp {}", control.local_addr()?);
        say!(
            "           e.g. {{\"device\":\"table\",\"fault\":\"silence\"}}, \
             {{\"device\":\"gyro\",\"fault\":\"drop\",\"every\":10}}, {{\"device\":\"table\",\"clear\":true}}"
        );
        say!("bench config written to {}; Ctrl-C stops", args.config_out.display());
        let faults = served.faults.clone();
        tokio::select! {
            r = control_loop(control, faults) => r?,
            r = tokio::signal::ctrl_c() => r?,
        }
        drop(served);
        Ok::<_, anyhow::Error>(())
    })?;
    Ok(ExitCode::SUCCESS)
}

/// A bench config's site and `[simulation.effects]` applied to the served simulator's
/// configuration: the site replaces the scenario's, each effect replaces or adds to the truth.
pub fn apply_bench_config(config: &mut SimConfig, bench: &bench::bench_config::BenchConfig) {
    if let Some(site) = bench.site() {
        config.latitude_deg = site.latitude_deg;
        config.axis_up = site.axis_up();
    }
    config.gyro_effects = config.gyro_effects.overridden_by(&bench.sim_effects());
}

/// Apply one control command; the reply line.
pub fn apply_fault_command(faults: &BenchFaults, line: &str) -> String {
    let mut v: serde_json::Value = match serde_json::from_str(line) {
        Ok(v) => v,
        Err(e) => return format!("error: not JSON: {e}"),
    };
    let Some(obj) = v.as_object_mut() else {
        return "error: expected a JSON object".into();
    };
    let device = obj.remove("device").and_then(|d| d.as_str().map(str::to_string));
    let Some(switch) = device.as_deref().and_then(|d| faults.device(d)) else {
        return "error: \"device\" must be \"table\", \"chamber\" or \"gyro\"".into();
    };
    if obj.remove("clear").is_some_and(|c| c == serde_json::Value::Bool(true)) {
        switch.clear();
        return "ok: cleared".into();
    }
    match serde_json::from_value::<Fault>(v) {
        Ok(f) => {
            switch.inject(f);
            format!("ok: {f:?}")
        }
        Err(e) => format!("error: {e}"),
    }
}

async fn control_loop(
    listener: tokio::net::TcpListener,
    faults: BenchFaults,
) -> anyhow::Result<()> {
    loop {
        let (stream, _) = listener.accept().await?;
        let faults = faults.clone();
        tokio::spawn(async move {
            let (r, mut w) = stream.into_split();
            let mut lines = BufReader::new(r).lines();
            while let Ok(Some(line)) = lines.next_line().await {
                let reply = apply_fault_command(&faults, &line);
                if w.write_all(format!("{reply}\n").as_bytes()).await.is_err() {
                    break;
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::effects::EffectId;

    #[test]
    fn a_bench_config_adds_its_site_and_effects_to_the_served_simulator() {
        let bench = bench::bench_config::BenchConfig::parse(
            "[site]\nlatitude_deg = -33.9\naxis = \"down\"\n[simulation.effects]\n\
             rate_squared = { coeff_s_per_rad = 1e-3 }\n",
            "sim.toml",
        )
        .expect("valid");
        let mut config = SimConfig::default();
        config.gyro_effects.set(EffectId::EarthRate, &[]).expect("a flag");
        apply_bench_config(&mut config, &bench);
        assert_eq!(config.latitude_deg, -33.9);
        assert!(!config.axis_up);
        assert!(config.gyro_effects.has(EffectId::EarthRate), "kept");
        assert_eq!(config.gyro_effects.get(EffectId::RateSquared), Some(&[1e-3][..]));
        assert!(config.validate().is_ok());
    }

    #[test]
    fn control_commands_switch_faults() {
        let f = BenchFaults::default();
        assert_eq!(
            apply_fault_command(&f, r#"{"device":"table","fault":"silence"}"#),
            "ok: Silence"
        );
        assert!(f.table.silent());
        let r = apply_fault_command(&f, r#"{"device":"gyro","fault":"drop","every":10}"#);
        assert_eq!(r, "ok: Drop { every: 10 }");
        assert_eq!(f.gyro.active(), vec![Fault::Drop { every: 10 }]);
        assert_eq!(apply_fault_command(&f, r#"{"device":"table","clear":true}"#), "ok: cleared");
        assert!(!f.table.silent());
        assert!(
            apply_fault_command(&f, r#"{"device":"oven","fault":"silence"}"#).starts_with("error")
        );
        assert!(
            apply_fault_command(&f, r#"{"device":"table","fault":"melt"}"#).starts_with("error")
        );
        assert!(apply_fault_command(&f, "nonsense").starts_with("error: not JSON"));
    }
}
