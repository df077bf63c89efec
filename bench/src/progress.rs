//! Progress display for long runs: bench time, ETA and live values, drawn from a thread of its
//! own so it works the same whether the run is in virtual or real time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use bench_physics::units::DEG_PER_MIN;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::run::Live;

/// A running progress display; stops and clears itself when dropped.
pub struct Progress {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Progress {
    /// Show progress of a run expected to last `estimate` of bench time. Draws to stderr only
    /// when it is a terminal.
    pub fn start(live: Arc<Live>, estimate: Duration, steps: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let total_ms = estimate.as_millis().max(1) as u64;
        let thread = std::thread::Builder::new()
            .name("bench-progress".into())
            .spawn(move || {
                let bar = ProgressBar::with_draw_target(Some(total_ms), ProgressDrawTarget::stderr());
                let style = ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {bar:30} {msg}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar());
                bar.set_style(style);
                let wall = std::time::Instant::now();
                while !flag.load(Ordering::Relaxed) {
                    let s = live.snapshot();
                    // Bench seconds per wall second so far; the ETA assumes it stays so.
                    let speed = s.bench_time_s / wall.elapsed().as_secs_f64().max(1e-3);
                    let left_s = (total_ms as f64 * 1e-3 - s.bench_time_s).max(0.0);
                    let eta = if speed > 0.0 { format!("{:.0} s", left_s / speed) } else { "?".into() };
                    let pos = (s.bench_time_s * 1e3) as u64;
                    if pos > total_ms {
                        bar.set_length(pos);
                    }
                    bar.set_position(pos);
                    bar.set_message(format!(
                        "bench {} (ETA {eta}) | step {}/{} | table {:+.3} °/min | air {:.1} °C (sp {:.1}) | gyro {:.2} °C",
                        hms(s.bench_time_s),
                        s.step + 1,
                        steps,
                        s.table_rate_rad_s / DEG_PER_MIN,
                        s.air_temp_c,
                        s.setpoint_c,
                        s.gyro_temp_c
                    ));
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

/// Seconds as `h:mm:ss`.
pub fn hms(s: f64) -> String {
    let s = if s.is_finite() && s > 0.0 { s as u64 } else { 0 };
    format!("{}:{:02}:{:02}", s / 3600, (s / 60) % 60, s % 60)
}
