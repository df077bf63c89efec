//! `bench replay REC.mcap --serve | --live`: put a recording back on the bench — its devices
//! served over the real wire protocols (like `bench sim serve`), and/or its streams shown live
//! in Foxglove — in real time × `--speed`.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use super::say::say;
use bench::bench_config::for_served_bench;
use bench::live_view::LiveView;
use bench::replay::ReplayData;
use bench_drivers::{Clock, HeldClock};
use bench_recording::{Item, RecordingReader};

/// Arguments of `bench replay`.
#[derive(clap::Args, Debug)]
pub struct ReplayArgs {
    /// The recording (any conforming MCAP file, with or without summary).
    pub recording: PathBuf,
    /// Serve the recorded table, chamber and gyro over their wire protocols on virtual ports
    /// (table serial/TCP, chamber Modbus RTU/TCP, gyro SLCAN/KVH) and write a bench config
    /// that points a second bench at them.
    #[arg(long)]
    pub serve: bool,
    /// Show every channel live in Foxglove (WebSocket server).
    #[arg(long)]
    pub live: bool,
    /// Address of the live view's server (only loopback unless you say otherwise).
    #[arg(long, default_value = "127.0.0.1:8765")]
    pub live_addr: SocketAddr,
    /// Replay speed, × real time.
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Start replaying at once. By default `--serve` holds the replay at its first sample until
    /// a client's first request to the table or chamber, so a bench that connects later misses
    /// nothing (a program that only listens to a gyro stream needs this flag).
    #[arg(long)]
    pub start_now: bool,
    /// Where `--serve` writes the bench config.
    #[arg(long, default_value = "bench-replay.toml")]
    pub config_out: PathBuf,
}

/// Run `bench replay`.
pub fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    super::kind::expect(&args.recording, &[super::kind::Kind::Recording])?;
    if !(args.speed.is_finite() && args.speed > 0.0) {
        anyhow::bail!("--speed must be a positive number, got {}", args.speed);
    }
    if !args.serve && !args.live {
        anyhow::bail!(
            "nothing to do: say --serve (devices on virtual ports) and/or --live (Foxglove); \
             to re-run a scenario on the recording, use `bench run SCENARIO --bench replay:{}`",
            args.recording.display()
        );
    }
    let rt = super::run::runtime()?;
    let live = super::start_live(&rt, args.live, args.live_addr)?;
    rt.block_on(async move {
        let clock = HeldClock::new(args.speed);
        if !args.serve || args.start_now {
            clock.start();
        }
        let shared: Arc<dyn Clock> = Arc::new(clock.clone());
        let mut served = None;
        let mut data = None;
        if args.serve {
            let d = Arc::new(ReplayData::load(&args.recording)?);
            let s = d.serve(&clock).await?;
            let site = d.site;
            let (lat, up) = site.map_or((0.0, true), |s| (s.latitude_deg, s.axis_up()));
            let cfg = for_served_bench(&s.endpoints, args.speed, lat, up);
            let e = &s.endpoints;
            super::write_served_config(
                &args.config_out,
                &format!(
                    "`bench replay --serve` for the replay of {} it serves",
                    args.recording.display()
                ),
                e,
                &cfg,
            )?;
            say!(
                "replaying {} ({:.1} s of bench time) at {}× real time",
                args.recording.display(),
                d.duration().as_secs_f64(),
                args.speed
            );
            super::print_endpoints(e);
            say!("bench config written to {}; Ctrl-C stops", args.config_out.display());
            if !clock.is_started() {
                say!(
                    "held at the first sample until the first request to the table or chamber \
                     (--start-now starts at once)"
                );
            }
            served = Some(s);
            data = Some(d);
        }
        let player = async {
            match &live {
                Some(live) => play(&args.recording, live, shared.as_ref()).await,
                None => {
                    let end = data.as_ref().map_or(Duration::ZERO, |d| d.duration());
                    shared.sleep_until(end).await;
                    Ok(0)
                }
            }
        };
        tokio::select! {
            r = player => {
                let n = r?;
                say!(
                    "recording ended at {:.1} s of bench time{}",
                    shared.now().as_secs_f64(),
                    if live.is_some() { format!(" ({n} messages shown)") } else { String::new() }
                );
                if served.is_some() {
                    say!("serving the last readings; Ctrl-C stops");
                    tokio::signal::ctrl_c().await?;
                }
            }
            r = tokio::signal::ctrl_c() => r?,
        }
        drop(served);
        Ok::<_, anyhow::Error>(())
    })?;
    Ok(ExitCode::SUCCESS)
}

/// Publish every message of the recording to `live` when `clock` reaches its log time (bench
/// time zero = the first message); the number published.
async fn play(path: &std::path::Path, live: &LiveView, clock: &dyn Clock) -> anyhow::Result<u64> {
    let mut first: Option<u64> = None;
    let mut n = 0u64;
    let mut reader = RecordingReader::open(path)?.raw();
    for item in reader.by_ref() {
        let Item::Other(m) = item? else { continue };
        let t0 = *first.get_or_insert(m.log_time_ns);
        clock.sleep_until(Duration::from_nanos(m.log_time_ns.saturating_sub(t0))).await;
        let c = &m.channel;
        // Channels beyond the contract's are shown with their schema name only.
        let _ = live.channel(&c.topic, None, &c.message_encoding);
        live.publish(&c.topic, m.log_time_ns, &m.data);
        n += 1;
    }
    if let bench_recording::End::Cut { at_byte, reason } = reader.end() {
        eprintln!("{}: cut at byte {at_byte}: {reason}", path.display());
    }
    Ok(n)
}
