//! One file per subcommand; [`exit`] holds the exit codes of all of them.

pub mod allan;
pub mod calibrate;
pub mod design;
pub mod diagnose;
pub mod exit;
pub mod export;
pub mod info;
pub mod kind;
pub mod memory;
pub mod model;
pub mod monte_carlo;
pub mod outputs;
pub mod ports;
pub mod recover;
pub mod replay;
pub mod run;
pub mod say;
pub mod sim;
pub mod soak;
pub mod validate;
pub mod verify;

use say::say;
use tracing_subscriber::EnvFilter;

/// The terminal log layer: warnings and errors by default, more with `-v`; `RUST_LOG` wins.
/// Colours only on a terminal and without `NO_COLOR`.
pub fn console_layer(
    verbose: u8,
) -> Box<dyn tracing_subscriber::Layer<tracing_subscriber::Registry> + Send + Sync> {
    use tracing_subscriber::Layer;
    let default = match verbose {
        0 => "warn",
        1 => "info,bench=debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_ansi(bench::progress::stderr_is_styled())
        .with_filter(filter)
        .boxed()
}

/// Start the Foxglove live view on `rt` at `addr` if `on`, and say where it listens.
pub fn start_live(
    rt: &tokio::runtime::Runtime,
    on: bool,
    addr: std::net::SocketAddr,
) -> anyhow::Result<Option<std::sync::Arc<bench::live_view::LiveView>>> {
    if !on {
        return Ok(None);
    }
    let host = addr.ip().to_string();
    let live = rt.block_on(bench::live_view::LiveView::start(&host, addr.port()))?;
    let shown = if addr.ip().is_ipv6() { format!("[{host}]") } else { host };
    eprintln!("live view: Foxglove → Open connection → ws://{shown}:{}", live.port());
    Ok(Some(std::sync::Arc::new(live)))
}

/// Write the bench config for served devices to `path`, headed by who wrote it (`written_by`,
/// e.g. "`bench sim serve` for the simulated bench it serves") and the ports not in it.
pub(crate) fn write_served_config(
    path: &std::path::Path,
    written_by: &str,
    e: &bench_sim::serve::bench::ServedEndpoints,
    cfg: &bench::bench_config::BenchConfig,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let text = format!(
        "# Written by {written_by}; valid while it runs.\n# Alternatives: table Actidyn on {}, \
         ACUTROL on {}; chamber Modbus TCP on {}; gyro KVH 1750 on {}, DSP-3000 (binary) on \
         {}.\n\n{}",
        e.table_actidyn_tcp,
        e.table_acutrol_tcp,
        e.chamber_tcp,
        e.gyro_kvh1750.path,
        e.gyro_dsp3000.path,
        cfg.to_toml().context("cannot write the bench config")?
    );
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// Print the ports of served devices, one per line.
pub(crate) fn print_endpoints(e: &bench_sim::serve::bench::ServedEndpoints) {
    say!("  table    Actidyn  {}", e.table_actidyn_pty);
    say!("  table    Actidyn  {}", e.table_actidyn_tcp);
    say!("  table    ACUTROL  {}", e.table_acutrol_tcp);
    say!("  chamber  Modbus RTU ({:?})  {}", e.chamber_preset, e.chamber_rtu);
    say!("  chamber  Modbus TCP ({:?})  {}", e.chamber_preset, e.chamber_tcp);
    say!("  gyro     SLCAN (bench CAN frames)  {}", e.gyro_slcan.path);
    say!("  gyro     KVH 1750 format A         {}", e.gyro_kvh1750.path);
    say!("  gyro     KVH DSP-3000 binary        {}", e.gyro_dsp3000.path);
}

/// Write `value` as pretty JSON to `path`.
pub(crate) fn write_json(
    path: &std::path::Path,
    value: &impl serde::Serialize,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text + "\n").with_context(|| format!("cannot write {}", path.display()))
}

/// Load the recording at `path`, showing how much of it has been read on a terminal (not with
/// `quiet`, `NO_COLOR` or stderr not a terminal): reading is the long part on long files. Damage
/// skipped on the way is named on stderr (`warning: the recording is damaged: …`).
pub(crate) fn load_recording(
    path: &std::path::Path,
    quiet: bool,
) -> anyhow::Result<bench_recording::Recording> {
    read_with_progress(path, quiet, |reader| {
        bench_recording::Recording::from_items(reader).map(|rec| (rec, ()))
    })
    .map(|(rec, ())| rec)
}

/// Read the recording at `path` as a stream, as [`load_recording`] shows and warns: the
/// gyro's samples reduced to the thermal model's rate as they pass
/// ([`bench_report::load::read_stream`]), so the analysis's memory does not grow with the
/// sample rate. Its recording holds everything but the gyro's messages.
pub(crate) fn read_recording_stream(
    path: &std::path::Path,
    quiet: bool,
) -> anyhow::Result<bench_report::load::Streamed> {
    use bench_report::load::{read_stream, Reduction, Streamed};
    // A study tool, not an option: `BENCH_GYRO_FULL_RATE=1` keeps every sample (the analysis
    // before the reduction, its memory growing with the rate) to compare against the reduced
    // analysis (docs/calibrate.md, "Reduced samples").
    let reduction = match std::env::var_os("BENCH_GYRO_FULL_RATE") {
        Some(v) if v == "1" => Reduction::Full,
        _ => Reduction::ToModelRate,
    };
    read_with_progress(path, quiet, |reader| {
        read_stream(reader, reduction).map(|s| (s.rec, s.gyro))
    })
    .map(|(rec, gyro)| Streamed { rec, gyro })
}

/// Say on stderr (not with `quiet`) that the gyro's samples were averaged in blocks, when they
/// were (the loader's reduction: docs/calibrate.md, "Reduced samples").
pub(crate) fn note_reduction(run: &bench_report::load::RunData, quiet: bool) {
    let n = run.gyro_block_len;
    if n > 1 && !quiet {
        eprintln!(
            "note: gyro samples averaged in blocks of {n} ({:.0} Hz) for the thermal model; the \
             Allan curve below the block from every sample",
            1.0 / run.gyro_dt_s
        );
    }
}

/// Open `path` with a progress bar (bytes read / size, with the time left) and read it with
/// `read`; damage and a cut are named on stderr.
fn read_with_progress<T>(
    path: &std::path::Path,
    quiet: bool,
    read: impl FnOnce(
        bench_recording::RecordingReader<
            bench::progress::ReadProgress<std::io::BufReader<std::fs::File>>,
        >,
    ) -> Result<(bench_recording::Recording, T), bench_recording::RecordingError>,
) -> anyhow::Result<(bench_recording::Recording, T)> {
    use anyhow::Context as _;
    kind::expect(path, &[kind::Kind::Recording])?;
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let name = path
        .file_name()
        .map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    let show = !quiet && bench::progress::stderr_is_styled();
    let reader = bench_recording::RecordingReader::open_through(path, |file| {
        bench::progress::ReadProgress::new(file, size, &name, show)
    })
    .with_context(|| format!("cannot read {}", path.display()))?;
    let (rec, out) = read(reader).with_context(|| format!("cannot read {}", path.display()))?;
    if let Some(note) = rec.damage_note() {
        eprintln!("warning: {note}; the analysis uses the intact data");
    }
    if let Some(note) = rec.cut_note() {
        eprintln!("note: {note}");
    }
    Ok((rec, out))
}

/// The context of an analysis error on `rec`: `cannot VERB PATH`, after the cut or the damage
/// when the file has them (they are why an analysis finds too little), with how to keep the
/// intact part.
pub(crate) fn analysis_context(
    rec: &bench_recording::Recording,
    verb: &str,
    path: &std::path::Path,
) -> String {
    let notes: Vec<String> = rec.cut_note().into_iter().chain(rec.damage_note()).collect();
    if notes.is_empty() {
        return format!("cannot {verb} {}", path.display());
    }
    format!(
        "{}; too little intact data is left (`bench recover {} NEW.mcap` keeps the intact part \
         in a new indexed file): cannot {verb} {}",
        notes.join("; "),
        path.display(),
        path.display()
    )
}
