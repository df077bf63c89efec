//! `bench ports`: the serial ports of this machine.

use std::process::ExitCode;

/// List serial ports (USB adapters, on-board UARTs) by path.
pub fn run() -> anyhow::Result<ExitCode> {
    let ports = bench_drivers::transport::list_serial_ports()?;
    if ports.is_empty() {
        println!("no serial ports found (pseudo-terminals of `bench sim serve` are not listed)");
    }
    for p in ports {
        println!("{p}");
    }
    Ok(ExitCode::SUCCESS)
}
