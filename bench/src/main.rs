//! `bench`: run FOG thermal-calibration scenarios on a simulated or real bench, and inspect the
//! recordings. The binary is glue: parse arguments, dispatch, map errors to exit codes.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

/// Hardware-in-the-loop bench for thermal calibration of fiber-optic gyros.
#[derive(Parser, Debug)]
#[command(name = "bench", version, about, long_about = None)]
struct Args {
    /// More log output on the terminal (-v: debug, -vv: trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a scenario and record it to MCAP (simulated bench unless a bench config is given).
    Run(cli::run::RunArgs),
    /// Check a scenario against the devices' capabilities without moving anything.
    Validate(cli::validate::ValidateArgs),
    /// Summarise a recording: duration, channels, gaps, steps, metadata, outcome.
    Info(cli::info::InfoArgs),
    /// The gyro's thermal calibration from a recording: calibration file, JSON and report.
    Calibrate(cli::calibrate::CalibrateArgs),
    /// A calibration file applied to another run of the gyro: the error per window with and
    /// without it, against what the calibration states; worse is a failure.
    Verify(cli::verify::VerifyArgs),
    /// Calibration accuracy over many simulated seeds (seed method vs joint fit).
    MonteCarlo(cli::monte_carlo::MonteCarloArgs),
    /// Design the shortest procedure that reaches the σ asked for (or the smallest σ in a time
    /// budget) under the gyro's noise model, within the bench's limits: a scenario.
    Design(cli::design::DesignArgs),
    /// Put a recording back on the bench: its devices on virtual ports (--serve), its streams
    /// live in Foxglove (--live).
    Replay(cli::replay::ReplayArgs),
    /// Rebuild a readable, indexed file from a truncated recording.
    Recover(cli::recover::RecoverArgs),
    /// Export a recording's channels as CSV or Parquet tables, one per channel.
    Export(cli::export::ExportArgs),
    /// Memory benchmark: peak RSS and wall of reading, loading, calibrating and diagnosing a
    /// recording, per phase and per gyro sample.
    Memory(cli::memory::MemoryArgs),
    /// Where a recording departs from the simulation of its run: missing physics named and fitted.
    Diagnose(cli::diagnose::DiagnoseArgs),
    /// Write a recording's nominal gyro model (`bench.gyro_model`) out as a model TOML file.
    Model(cli::model::ModelArgs),
    /// List the serial ports of this machine (USB VID:PID, serial number, product).
    Ports(cli::ports::PortsArgs),
    /// Allan deviation of a recording's gyro (static or rotating record) with N, B, K.
    Allan(cli::allan::AllanArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) on stdout.
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
    /// The simulated bench behind virtual ports.
    #[command(subcommand)]
    Sim(cli::sim::SimCommand),
    /// Hours of bench time through the virtual ports with faults injected at random: samples
    /// sent vs recorded per channel, memory over time, every fault's outcome.
    Soak(cli::soak::SoakArgs),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Run(a) => cli::run::run(a, args.verbose),
        Command::Validate(a) => cli::validate::run(a),
        Command::Info(a) => cli::info::run(a),
        Command::Calibrate(a) => cli::calibrate::run(a),
        Command::Verify(a) => cli::verify::run(a),
        Command::MonteCarlo(a) => cli::monte_carlo::run(a),
        Command::Design(a) => cli::design::run(a),
        Command::Replay(a) => cli::replay::run(a),
        Command::Recover(a) => cli::recover::run(a),
        Command::Export(a) => cli::export::run(a),
        Command::Memory(a) => cli::memory::run(a),
        Command::Diagnose(a) => cli::diagnose::run(a),
        Command::Model(a) => cli::model::run(a),
        Command::Ports(a) => cli::ports::run(a),
        Command::Sim(c) => cli::sim::run(c),
        Command::Soak(a) => cli::soak::run(a),
        Command::Allan(a) => cli::allan::run(a),
        Command::Completions { shell } => {
            use clap::CommandFactory as _;
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Args::command(), "bench", &mut script);
            cli::say::write(&String::from_utf8_lossy(&script));
            Ok(ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", cli::exit::error_text(&e));
            cli::exit::Exit::of_error(&e).into()
        }
    }
}
