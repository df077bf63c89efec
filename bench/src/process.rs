//! What this process uses, from Linux's `/proc/self` (`None` elsewhere): resident memory and
//! CPU time, for the soak's memory verdict and the timings `bench run` and `bench diagnose`
//! print.

/// VmRSS and VmHWM (peak) of this process, MiB.
pub fn memory_mib() -> Option<(f64, f64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    Some((status_kib(&status, "VmRSS:")? / 1024.0, status_kib(&status, "VmHWM:")? / 1024.0))
}

/// Peak resident set size of this process (VmHWM), MiB.
pub fn peak_rss_mib() -> Option<f64> {
    memory_mib().map(|m| m.1)
}

/// CPU time of this process so far, every thread, user and system, s (`/proc/self/stat`, in
/// clock ticks of 10 ms).
pub fn cpu_time_s() -> Option<f64> {
    stat_cpu_s(&std::fs::read_to_string("/proc/self/stat").ok()?)
}

/// A `kB` field of `/proc/self/status` (`VmRSS:   1234 kB`).
fn status_kib(status: &str, name: &str) -> Option<f64> {
    let line = status.lines().find(|l| l.starts_with(name))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// utime + stime of a `/proc/PID/stat` line, s. The command name, in parentheses, may hold
/// spaces: utime and stime are the 12th and 13th fields after its closing `) `.
fn stat_cpu_s(stat: &str) -> Option<f64> {
    let rest = stat.get(stat.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_read_from_the_kernels_text() {
        let status = "Name:\tbench\nVmHWM:\t   20480 kB\nVmRSS:\t   10240 kB\n";
        assert_eq!(status_kib(status, "VmRSS:"), Some(10240.0));
        assert_eq!(status_kib(status, "VmHWM:"), Some(20480.0));
        assert_eq!(status_kib(status, "VmSwap:"), None);
        // A command name with spaces and a parenthesis; utime 250 and stime 50 ticks.
        let stat = "42 (my (odd) cmd) S 1 42 42 0 -1 4194304 100 0 0 0 250 50 0 0 20 0 1 0";
        assert_eq!(stat_cpu_s(stat), Some(3.0));
        assert_eq!(stat_cpu_s("garbage"), None);
    }

    #[test]
    fn this_process_is_measured_on_linux() {
        if !std::path::Path::new("/proc/self/status").exists() {
            eprintln!("skipped: no /proc on this system");
            return;
        }
        let (rss, hwm) = memory_mib().expect("VmRSS and VmHWM");
        assert!(rss > 0.0 && hwm >= rss, "rss {rss} hwm {hwm}");
        assert!(cpu_time_s().is_some_and(|s| s >= 0.0));
    }
}
