//! The whole simulated bench served on virtual ports at once (`bench sim serve`): one physics
//! world, each device reachable over its real protocols, faults switchable per device.

use std::io;
use std::sync::Arc;

use bench_drivers::protocol::modbus_map::Preset;
use bench_drivers::protocol::Dialect;
use bench_drivers::transport::{Endpoint, SerialSettings};
use bench_drivers::{Chamber, Clock, Gyro, RateTable};
use tokio::task::JoinHandle;

use super::chamber::{
    serve_chamber_rtu, serve_chamber_tcp, ChamberServeOptions, ChamberWireStats, ServedChamber,
};
use super::gyro::{
    serve_dsp3000, serve_kvh1750, serve_slcan_tallied, Dsp3000Output, GyroTally,
    SlcanAdapterOptions,
};
use super::table::{
    serve_table_pty, serve_table_tcp, TableController, TableServeOptions, TableServerStats,
};
use crate::faults::FaultSwitch;
use crate::ports::Pty;
use crate::{SimBench, SimConfig, SimConfigError};

/// The fault switches of the served devices.
#[derive(Debug, Clone, Default)]
pub struct BenchFaults {
    /// Rate table (every table port).
    pub table: FaultSwitch,
    /// Chamber (every chamber port).
    pub chamber: FaultSwitch,
    /// Gyro (every gyro output).
    pub gyro: FaultSwitch,
}

impl BenchFaults {
    /// The switch of `device` (`table`, `chamber` or `gyro`).
    pub fn device(&self, device: &str) -> Option<&FaultSwitch> {
        match device {
            "table" => Some(&self.table),
            "chamber" => Some(&self.chamber),
            "gyro" => Some(&self.gyro),
            _ => None,
        }
    }
}

/// Where each served device listens.
#[derive(Debug, Clone)]
pub struct ServedEndpoints {
    /// Table, Actidyn dialect, on a pseudo-terminal.
    pub table_actidyn_pty: Endpoint,
    /// Table, Actidyn dialect, on loopback TCP.
    pub table_actidyn_tcp: Endpoint,
    /// Table, ACUTROL dialect, on loopback TCP.
    pub table_acutrol_tcp: Endpoint,
    /// Chamber preset the Modbus servers use.
    pub chamber_preset: Preset,
    /// Chamber, Modbus RTU on a pseudo-terminal.
    pub chamber_rtu: Endpoint,
    /// Chamber, Modbus TCP on loopback.
    pub chamber_tcp: Endpoint,
    /// Gyro: SLCAN adapter with bench's CAN frame set, on a pseudo-terminal.
    pub gyro_slcan: SerialSettings,
    /// Gyro: KVH 1750 format A frames (z axis), on a pseudo-terminal.
    pub gyro_kvh1750: SerialSettings,
    /// Gyro: KVH DSP-3000 binary words, on a pseudo-terminal.
    pub gyro_dsp3000: SerialSettings,
    /// The simulated gyro's output rate, Hz.
    pub gyro_rate_hz: f64,
}

/// What the served ports the default bench config uses ([`ServedEndpoints::table_actidyn_pty`],
/// [`ServedEndpoints::chamber_rtu`], [`ServedEndpoints::gyro_slcan`]) carried: the samples the
/// simulators sent and those the fault injector withheld or damaged (`bench soak`).
#[derive(Debug, Clone)]
pub struct WireStats {
    /// The table's Actidyn pty.
    pub table: Arc<TableServerStats>,
    /// The chamber's Modbus RTU pty.
    pub chamber: Arc<ChamberWireStats>,
    /// The gyro's SLCAN pty, sample by sample.
    pub gyro: Arc<GyroTally>,
}

/// A running served bench; the servers stop when it is dropped.
pub struct ServedBench {
    /// Where each device listens.
    pub endpoints: ServedEndpoints,
    /// Fault switches.
    pub faults: BenchFaults,
    /// What the default ports carried.
    pub wire: WireStats,
    _chambers: Vec<ServedChamber>,
    tasks: Vec<JoinHandle<()>>,
}

impl Drop for ServedBench {
    fn drop(&mut self) {
        self.tasks.iter().for_each(JoinHandle::abort);
    }
}

fn serial(path: &str, baud: u32) -> SerialSettings {
    SerialSettings {
        path: path.to_string(),
        baud,
        parity: Default::default(),
        data_bits: 8,
        stop_bits: 1,
    }
}

/// Build the simulated bench of `config` on `clock` and serve every device on its ports. Needs
/// a tokio runtime; returns once every server is listening.
pub async fn serve_bench(
    config: SimConfig,
    clock: Arc<dyn Clock>,
) -> Result<ServedBench, ServeError> {
    let gyro_rate_hz = config.gyro_sample_rate_hz;
    let sim = SimBench::new(config, clock.clone())?;
    serve_devices(sim.table, sim.chamber, sim.gyro, gyro_rate_hz, clock).await
}

/// Serve any table, chamber and gyro (simulators, replays of a recording) on every port
/// [`serve_bench`] opens. Each server gets its own clone of the device: clones of the
/// simulators share one world, clones of a replay play the same recording on the same clock.
/// Needs a tokio runtime; returns once every server is listening.
pub async fn serve_devices<T, C, G>(
    table: T,
    chamber: C,
    gyro: G,
    gyro_rate_hz: f64,
    clock: Arc<dyn Clock>,
) -> Result<ServedBench, ServeError>
where
    T: RateTable + Clone + 'static,
    C: Chamber + Clone + 'static,
    G: Gyro + Clone + 'static,
{
    struct Parts<T, C, G> {
        table: T,
        chamber: C,
        gyro: G,
    }
    let sim = Parts { table, chamber, gyro };
    let faults = BenchFaults::default();
    let mut tasks = Vec::new();
    let log_end = |what: &'static str| {
        move |r: io::Result<()>| {
            if let Err(e) = r {
                tracing::warn!("simulated {what} server stopped: {e}");
            }
        }
    };

    // Table: Actidyn on a pty and on TCP, ACUTROL on TCP; all share the one simulated axis.
    let table_opts = |d| TableServeOptions::new(d, faults.table.clone());
    let pty = Pty::new()?;
    let table_actidyn_pty = Endpoint::Serial(serial(&pty.path, 115_200));
    let ctl = TableController::new(sim.table.clone(), clock.clone(), table_opts(Dialect::Actidyn));
    let table_stats = ctl.stats();
    let done = log_end("table (pty)");
    tasks.push(tokio::spawn(async move { done(serve_table_pty(pty, ctl).await) }));
    let tcp_table = |dialect| -> io::Result<(Endpoint, JoinHandle<()>)> {
        let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?.to_string();
        let listener = tokio::net::TcpListener::from_std(listener)?;
        let ctl = TableController::new(sim.table.clone(), clock.clone(), table_opts(dialect));
        let done = log_end("table (tcp)");
        Ok((
            Endpoint::Tcp { addr },
            tokio::spawn(async move { done(serve_table_tcp(listener, ctl).await) }),
        ))
    };
    let (table_actidyn_tcp, t1) = tcp_table(Dialect::Actidyn)?;
    let (table_acutrol_tcp, t2) = tcp_table(Dialect::Acutrol)?;
    tasks.extend([t1, t2]);

    // Chamber: Eurotherm 3216 (ramps through its set-point rate limit) on RTU and TCP.
    let chamber_preset = Preset::Eurotherm3216;
    let chamber_opts = || {
        let mut o = ChamberServeOptions::preset(chamber_preset);
        o.faults = faults.chamber.clone();
        o
    };
    let rtu = serve_chamber_rtu(Box::new(sim.chamber.clone()), clock.clone(), chamber_opts())?;
    let tcp =
        serve_chamber_tcp(Box::new(sim.chamber.clone()), clock.clone(), chamber_opts()).await?;
    let (chamber_rtu, chamber_tcp) = (rtu.endpoint.clone(), tcp.endpoint.clone());
    let chamber_stats = rtu.wire_stats();

    // Gyro: SLCAN, KVH 1750 and DSP-3000 outputs of the same simulated coil.
    let slcan = Pty::new()?;
    let gyro_slcan = serial(&slcan.path, 115_200);
    let (g, f, c) = (sim.gyro.clone(), faults.gyro.clone(), clock.clone());
    let done = log_end("gyro (SLCAN)");
    let gyro_tally = Arc::new(GyroTally::default());
    let tally = gyro_tally.clone();
    tasks.push(tokio::spawn(async move {
        // The whole pty moves in: its held slave end keeps the device node alive.
        let mut slcan = slcan;
        let opts = SlcanAdapterOptions::default();
        done(serve_slcan_tallied(g, &mut slcan.server, opts, f, c, tally).await)
    }));
    let kvh = Pty::new()?;
    let gyro_kvh1750 = serial(&kvh.path, 921_600);
    let (g, f, c) = (sim.gyro.clone(), faults.gyro.clone(), clock.clone());
    let done = log_end("gyro (KVH 1750)");
    tasks.push(tokio::spawn(async move {
        let mut kvh = kvh;
        done(serve_kvh1750(g, &mut kvh.server, 2, f, c).await)
    }));
    let dsp = Pty::new()?;
    let gyro_dsp3000 = serial(&dsp.path, 115_200);
    let (g, f, c) = (sim.gyro.clone(), faults.gyro.clone(), clock.clone());
    let done = log_end("gyro (DSP-3000)");
    tasks.push(tokio::spawn(async move {
        let mut dsp = dsp;
        done(serve_dsp3000(g, &mut dsp.server, Dsp3000Output::BinaryRate, f, c).await)
    }));

    Ok(ServedBench {
        endpoints: ServedEndpoints {
            table_actidyn_pty,
            table_actidyn_tcp,
            table_acutrol_tcp,
            chamber_preset,
            chamber_rtu,
            chamber_tcp,
            gyro_slcan,
            gyro_kvh1750,
            gyro_dsp3000,
            gyro_rate_hz,
        },
        faults,
        wire: WireStats { table: table_stats, chamber: chamber_stats, gyro: gyro_tally },
        _chambers: vec![rtu, tcp],
        tasks,
    })
}

/// Why the bench could not be served.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The simulator configuration is invalid.
    #[error(transparent)]
    Config(#[from] SimConfigError),
    /// A port could not be made.
    #[error("cannot open a virtual port: {0}")]
    Io(#[from] io::Error),
}
