//! `bench ports`: the serial ports of this machine, with what tells USB adapters apart (vendor
//! and product id, serial number, product), read from sysfs (`/sys/class/tty/NAME/device/..`):
//! the serial port library is built without libudev.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use super::say::say;
use serde_json::json;

/// Arguments of `bench ports`.
#[derive(clap::Args, Debug)]
pub struct PortsArgs {
    /// Also write the list as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The sysfs root (for tests).
    #[arg(long, default_value = "/sys", hide = true)]
    pub sysfs: PathBuf,
}

/// What sysfs says of a USB serial adapter.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UsbInfo {
    /// `idVendor`, 4 hex digits.
    pub vid: String,
    /// `idProduct`.
    pub pid: String,
    /// `serial`, if the device has one.
    pub serial: Option<String>,
    /// `manufacturer`.
    pub manufacturer: Option<String>,
    /// `product`.
    pub product: Option<String>,
}

fn read_trimmed(p: &Path) -> Option<String> {
    std::fs::read_to_string(p).ok().map(|s| s.trim().to_string()).filter(|s| !s.is_empty())
}

/// The USB device above `/dev/NAME` in the sysfs tree at `sysfs`: the first ancestor of
/// `class/tty/NAME/device` that has `idVendor` and `idProduct`. `None` for a port that is not
/// on USB (an on-board UART, a pseudo-terminal) or when sysfs has nothing.
pub fn usb_info(sysfs: &Path, port: &str) -> Option<UsbInfo> {
    let name = Path::new(port).file_name()?;
    let device = sysfs.join("class/tty").join(name).join("device");
    let mut dir = std::fs::canonicalize(&device).ok()?;
    for _ in 0..6 {
        if let (Some(vid), Some(pid)) =
            (read_trimmed(&dir.join("idVendor")), read_trimmed(&dir.join("idProduct")))
        {
            return Some(UsbInfo {
                vid,
                pid,
                serial: read_trimmed(&dir.join("serial")),
                manufacturer: read_trimmed(&dir.join("manufacturer")),
                product: read_trimmed(&dir.join("product")),
            });
        }
        if !dir.pop() {
            break;
        }
    }
    None
}

/// One line of the listing.
pub fn describe(port: &str, usb: Option<&UsbInfo>) -> String {
    match usb {
        Some(u) => format!(
            "{port}  USB {}:{}  serial {}  {}{}",
            u.vid,
            u.pid,
            u.serial.as_deref().unwrap_or("(none)"),
            u.manufacturer.as_deref().map(|m| format!("{m} ")).unwrap_or_default(),
            u.product.as_deref().unwrap_or("")
        )
        .trim_end()
        .to_string(),
        None => format!("{port}  no USB information"),
    }
}

/// List serial ports (USB adapters, on-board UARTs) with their USB identity.
pub fn run(args: PortsArgs) -> anyhow::Result<ExitCode> {
    let ports = bench_drivers::transport::list_serial_ports()?;
    if ports.is_empty() {
        say!("no serial ports found (pseudo-terminals of `bench sim serve` are not listed)");
    }
    let mut list = Vec::new();
    for p in &ports {
        let usb = usb_info(&args.sysfs, p);
        say!("{}", describe(p, usb.as_ref()));
        list.push(json!({
            "port": p,
            "usb": usb.map(|u| json!({"vid": u.vid, "pid": u.pid, "serial": u.serial, "manufacturer": u.manufacturer, "product": u.product})),
        }));
    }
    if let Some(path) = &args.json {
        super::write_json(path, &json!({ "ports": list }))?;
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake sysfs: ttyUSB0 on a USB-serial adapter (interface → device with ids), ttyS0 an
    /// on-board UART.
    #[test]
    fn usb_identity_from_a_sysfs_tree() {
        let root = tempfile::tempdir().expect("tempdir");
        let sys = root.path();
        let usb = sys.join("devices/pci0000:00/usb1/1-2");
        let iface = usb.join("1-2:1.0/ttyUSB0");
        std::fs::create_dir_all(&iface).expect("dirs");
        for (f, v) in [
            ("idVendor", "0403\n"),
            ("idProduct", "6001\n"),
            ("serial", "A10KZ3X4\n"),
            ("manufacturer", "FTDI\n"),
            ("product", "FT232R USB UART\n"),
        ] {
            std::fs::write(usb.join(f), v).expect("write");
        }
        let uart = sys.join("devices/platform/serial8250/tty/ttyS0");
        std::fs::create_dir_all(&uart).expect("dirs");
        std::fs::create_dir_all(sys.join("class/tty/ttyUSB0")).expect("dirs");
        std::fs::create_dir_all(sys.join("class/tty/ttyS0")).expect("dirs");
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink(&iface, sys.join("class/tty/ttyUSB0/device")).expect("link");
            std::os::unix::fs::symlink(&uart, sys.join("class/tty/ttyS0/device")).expect("link");
            let u = usb_info(sys, "/dev/ttyUSB0").expect("USB");
            assert_eq!((u.vid.as_str(), u.pid.as_str()), ("0403", "6001"));
            assert_eq!(
                describe("/dev/ttyUSB0", Some(&u)),
                "/dev/ttyUSB0  USB 0403:6001  serial A10KZ3X4  FTDI FT232R USB UART"
            );
            assert_eq!(usb_info(sys, "/dev/ttyS0"), None);
        }
        assert_eq!(usb_info(sys, "/dev/ttyACM7"), None);
        assert_eq!(describe("/dev/ttyS0", None), "/dev/ttyS0  no USB information");
    }
}
