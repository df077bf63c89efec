//! Progress display for long runs: bench time, ETA and live values, drawn from a thread of its
//! own so it works the same whether the run is in virtual or real time; and a byte counter for
//! reading long recordings ([`ReadProgress`]).

use std::io::Read;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use bench_physics::units::DEG_PER_MIN;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::plan::{Estimate, RunPlan};
use crate::run::{Live, Snapshot};

/// A running progress display; stops and clears itself when dropped.
pub struct Progress {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// What the progress line says about a run at one instant.
#[derive(Debug, Clone)]
pub struct RunProgress {
    /// The plan's estimate.
    pub estimate: Estimate,
    /// Step labels (the step's kind where it has no label), by index.
    pub labels: Vec<String>,
    /// The step seen running last, and the bench time it was first seen at, s.
    step_seen: Option<(usize, f64)>,
}

impl RunProgress {
    /// Progress through `plan`, expected to unfold as `estimate`.
    pub fn new(plan: &RunPlan, estimate: Estimate) -> Self {
        let labels = plan
            .steps
            .iter()
            .map(|s| if s.label.is_empty() { s.name.clone() } else { s.label.clone() })
            .collect();
        Self { estimate, labels, step_seen: None }
    }

    /// Note `s` and return (position through the estimate, expected bench time left), s.
    pub fn update(&mut self, s: &Snapshot) -> (f64, f64) {
        let now = s.bench_time_s;
        let since = match self.step_seen {
            Some((step, since)) if step == s.step => since,
            previous => {
                // A step is first seen up to one display period after it started; the run's
                // first step started no later than its estimated start.
                let since = match previous {
                    None => now.min(self.estimate.step_start_s.get(s.step).copied().unwrap_or(now)),
                    Some(_) => now,
                };
                self.step_seen = Some((s.step, since));
                since
            }
        };
        let left = self.estimate.remaining_s(s.step, now - since);
        let total = self.estimate.total.as_secs_f64();
        ((total - left).max(0.0), left)
    }

    /// The progress line's message for `s`, `speed` bench seconds per wall second (0 when not
    /// known yet).
    pub fn message(&mut self, s: &Snapshot, speed: f64) -> String {
        let (_, left) = self.update(s);
        let eta = if speed > 0.0 && speed.is_finite() {
            format!("ETA {}", hms(left / speed))
        } else {
            "ETA ?".to_string()
        };
        let label = self.labels.get(s.step).map_or("", String::as_str);
        format!(
            "bench {} ({eta}, ~{} of bench time left) | step {}/{} {label} | table {} °/min | \
             air {} °C (sp {}) | gyro {} °C",
            hms(s.bench_time_s),
            hms(left),
            s.step + 1,
            self.labels.len(),
            value(s.table_rate_rad_s / DEG_PER_MIN, 3, true),
            value(s.air_temp_c, 1, false),
            value(s.setpoint_c, 1, false),
            value(s.gyro_temp_c, 2, false),
        )
    }
}

/// A reading for the progress line: `—` until there is one.
fn value(v: f64, decimals: usize, sign: bool) -> String {
    match (v.is_finite(), sign) {
        (false, _) => "—".to_string(),
        (true, true) => format!("{v:+.decimals$}"),
        (true, false) => format!("{v:.decimals$}"),
    }
}

/// Whether stderr may show colours and bars: a terminal, and `NO_COLOR` not set
/// (<https://no-color.org>).
pub fn stderr_is_styled() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

impl Progress {
    /// Show progress of a run of `plan` as its estimate expects it. Draws to stderr only when
    /// it is a terminal.
    pub fn start(live: Arc<Live>, plan: &RunPlan) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let mut progress = RunProgress::new(plan, plan.estimate());
        let total_ms = (progress.estimate.total.as_secs_f64() * 1e3).max(1.0) as u64;
        let thread = std::thread::Builder::new()
            .name("bench-progress".into())
            .spawn(move || {
                let bar =
                    ProgressBar::with_draw_target(Some(total_ms), ProgressDrawTarget::stderr());
                let style =
                    ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg}")
                        .unwrap_or_else(|_| ProgressStyle::default_bar());
                bar.set_style(style);
                let wall = std::time::Instant::now();
                while !flag.load(Ordering::Relaxed) {
                    let s = live.snapshot();
                    // Bench seconds per wall second so far; the ETA assumes it stays so.
                    let speed = s.bench_time_s / wall.elapsed().as_secs_f64().max(1e-3);
                    let msg = progress.message(&s, if s.bench_time_s > 0.0 { speed } else { 0.0 });
                    let (pos, _) = progress.update(&s);
                    bar.set_position(((pos * 1e3) as u64).min(total_ms.saturating_sub(1)));
                    bar.set_message(msg);
                    std::thread::sleep(Duration::from_millis(100));
                }
                bar.finish_and_clear();
            })
            .ok();
        Self { stop, thread }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The time left to read `len` bytes at the rate `pos` bytes took `elapsed_s`: none until a
/// rate is known (a second of reading and some bytes read), so a 2 s read never starts with an
/// ETA of "70m" from its first few bytes.
pub fn read_eta_s(pos: u64, len: u64, elapsed_s: f64) -> Option<f64> {
    (pos > 0 && elapsed_s >= 1.0 && len >= pos).then(|| (len - pos) as f64 * elapsed_s / pos as f64)
}

/// A reader that shows how much of a file it has read on a progress bar (bytes read / size),
/// on a terminal only.
pub struct ReadProgress<R> {
    inner: R,
    bar: ProgressBar,
}

impl<R: Read> ReadProgress<R> {
    /// Count `inner`'s bytes against `size`, showing `what` (e.g. the file name) when `show`.
    pub fn new(inner: R, size: u64, what: &str, show: bool) -> Self {
        let target = if show { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        let bar = ProgressBar::with_draw_target(Some(size.max(1)), target);
        let style = ProgressStyle::with_template(
            "reading {prefix} {bar:30} {binary_bytes}/{binary_total_bytes}{eta_known}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .with_key(
            "eta_known",
            |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                let left = read_eta_s(s.pos(), s.len().unwrap_or(0), s.elapsed().as_secs_f64());
                if let Some(left) = left {
                    let left = std::time::Duration::from_secs_f64(left.ceil());
                    let _ = write!(w, " ({} left)", indicatif::HumanDuration(left));
                }
            },
        );
        bar.set_style(style);
        bar.set_prefix(what.to_string());
        Self { inner, bar }
    }

    /// Bytes read so far.
    pub fn position(&self) -> u64 {
        self.bar.position()
    }
}

impl<R> Drop for ReadProgress<R> {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

impl<R: Read> Read for ReadProgress<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.bar.inc(n as u64);
        Ok(n)
    }
}

/// A spinner with the elapsed time for a computation of unknown length (a calibration or a
/// diagnosis after its file is read), on a terminal only; it ticks on its own and clears when
/// dropped.
pub struct Working {
    bar: ProgressBar,
}

impl Working {
    /// Show `what` (e.g. `diagnosing run.mcap`) when `show`.
    pub fn new(what: &str, show: bool) -> Self {
        let target = if show { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() };
        let bar = ProgressBar::with_draw_target(None, target);
        let style = ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner());
        bar.set_style(style);
        bar.set_message(what.to_string());
        if show {
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
        }
        Self { bar }
    }
}

impl Drop for Working {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// Seconds as `h:mm:ss` (the one formatter, rounded to the nearest second).
pub use bench_report::display::hms;

#[cfg(test)]
mod tests {
    use super::*;

    fn plan() -> RunPlan {
        let text = "[scenario]\nname = \"t\"\n[site]\nlatitude_deg = 45\n\
                    [[step]]\nlabel = \"soak 20C\"\nwait = \"1 h\"\n\
                    [[step]]\nlabel = \"record cw 20C\"\nrecord = \"1 h\"\n";
        crate::scenario::parse(text, "t.toml", &crate::simulate::capabilities()).expect("valid")
    }

    fn snapshot(t: f64, step: usize) -> Snapshot {
        let live = Live::default();
        live.set_time(Duration::from_secs_f64(t));
        live.set_step(step);
        live.snapshot()
    }

    #[test]
    fn before_the_first_reading_no_nan_and_the_steps_label() {
        let p = plan();
        let mut r = RunProgress::new(&p, p.estimate());
        let m = r.message(&snapshot(0.0, 0), 0.0);
        assert!(!m.contains("NaN"), "{m}");
        assert!(m.contains("step 1/2 soak 20C"), "{m}");
        assert!(m.contains("air — °C"), "{m}");
        assert!(m.contains("ETA ?"), "{m}");
    }

    #[test]
    fn the_eta_counts_down_through_the_estimate_and_is_never_zero_early() {
        let p = plan();
        let mut r = RunProgress::new(&p, p.estimate());
        // Half-way through the first hour at 10× real time: 1.5 h of bench time left.
        let m = r.message(&snapshot(1800.0, 0), 10.0);
        assert!(m.contains("ETA 0:09:00"), "{m}");
        // The first step overruns by an hour: the second step's hour (+1 s tail) is still to go.
        let m = r.message(&snapshot(7200.0, 0), 1.0);
        assert!(m.contains("ETA 1:00:01"), "{m}");
        let m = r.message(&snapshot(7300.0, 1), 1.0);
        assert!(m.contains("step 2/2 record cw 20C"), "{m}");
        assert!(m.contains("ETA 1:00:01"), "{m}");
        let (pos, left) = r.update(&snapshot(9100.0, 1));
        assert!((left - 1801.0).abs() < 1e-6 && (pos - 5400.0).abs() < 1e-6, "{pos} {left}");
    }

    #[test]
    fn no_read_eta_before_a_rate_is_known() {
        assert_eq!(read_eta_s(0, 1000, 5.0), None);
        assert_eq!(read_eta_s(10, 1000, 0.2), None, "the first reads are no rate");
        assert_eq!(read_eta_s(500, 1000, 2.0), Some(2.0));
    }

    #[test]
    fn read_progress_counts_bytes() {
        let mut r = ReadProgress::new(&b"0123456789"[..], 10, "x", false);
        let mut buf = Vec::new();
        r.read_to_end(&mut buf).expect("reads");
        assert_eq!((buf.len(), r.position()), (10, 10));
    }
}
