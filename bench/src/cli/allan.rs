//! `bench allan REC`: the overlapping Allan deviation of a recording's gyro over a record
//! window (or any interval) — static, or rotating with the table's rate (the least-squares
//! slope of its angle over the interval) taken out — with IEEE 952 N, B, K
//! (`bench_analysis::allan_fit`); the curve as JSON and CSV.

use std::path::PathBuf;
use std::process::ExitCode;

use super::say::say;
use anyhow::Context as _;
use bench_analysis::allan_fit::{allan_fit, NoiseTerm};
use bench_analysis::stats::line;
use bench_physics::allan::adev_octaves;
use bench_physics::units::DEG_PER_H;
use bench_recording::message::is_record_label;
use bench_report::display;
use serde_json::json;

/// Arguments of `bench allan`.
#[derive(clap::Args, Debug)]
pub struct AllanArgs {
    /// Recording (MCAP).
    pub recording: PathBuf,
    /// The step whose label this is (e.g. `record cw 20C`); default: the whole recording.
    #[arg(long, conflicts_with_all = ["from", "to"])]
    pub window: Option<String>,
    /// Start of the interval, s from the recording's first message.
    #[arg(long)]
    pub from: Option<f64>,
    /// End of the interval, s from the recording's first message.
    #[arg(long)]
    pub to: Option<f64>,
    /// Write the curve and N, B, K as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write the curve as CSV (`tau_s,adev_rad_s,adev_deg_h,n_terms`).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

fn term(t: &NoiseTerm) -> serde_json::Value {
    json!({"value": t.value, "low": t.low, "high": t.high, "tau_s": t.tau_s, "upper_bound": t.upper_bound})
}

/// Compute and print the deviation.
pub fn run(args: AllanArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.json.as_deref())?;
    outputs.file(args.csv.as_deref())?;
    let rec = super::load_recording(&args.recording, args.quiet)?;
    let data = bench_report::load::load(&rec)
        .with_context(|| super::analysis_context(&rec, "read", &args.recording))?;
    let s = &data.series;
    let (from, to, what) = match &args.window {
        Some(label) => {
            let step = s.steps.iter().find(|w| &w.label == label).with_context(|| {
                let labels: Vec<&str> = s
                    .steps
                    .iter()
                    .map(|w| w.label.as_str())
                    .filter(|l| is_record_label(l))
                    .collect();
                format!(
                    "{}: no step labelled {label:?}; record windows: {}",
                    args.recording.display(),
                    labels.join(", ")
                )
            })?;
            (step.start_s, step.end_s, format!("window {label:?}"))
        }
        None => {
            let from = args.from.unwrap_or(f64::NEG_INFINITY);
            let to = args.to.unwrap_or(f64::INFINITY);
            anyhow::ensure!(from < to, "--from {from} s must be before --to {to} s");
            (from, to, "interval".to_string())
        }
    };
    let inside = |t: f64| t > from && t <= to;
    let (mut gt, mut gr) = (Vec::new(), Vec::new());
    for (t, r) in s.gyro_time_s.iter().zip(&s.gyro_rate_rad_s) {
        if inside(*t) {
            gt.push(*t);
            gr.push(*r);
        }
    }
    let (tt, ta): (Vec<f64>, Vec<f64>) = s
        .table_time_s
        .iter()
        .zip(&s.table_angle_rad)
        .filter(|(t, _)| inside(**t))
        .map(|(t, a)| (*t, *a))
        .unzip();
    anyhow::ensure!(
        gr.len() >= 16,
        "{}: {} gyro samples in the {what} ({from:.3}..{to:.3} s): too few for an Allan deviation",
        args.recording.display(),
        gr.len()
    );
    let table_rate = line(tt.iter().copied().zip(ta.iter().copied())).slope.unwrap_or(0.0);
    let rate: Vec<f64> = gr.iter().map(|r| r - table_rate).collect();
    let dt = data.gyro_dt_s;
    let curve = adev_octaves(&rate, dt);
    let fit = allan_fit(&curve, 0.95).with_context(|| {
        format!("{}: the Allan deviation cannot be fitted", args.recording.display())
    })?;
    let (t0, t1) = (gt[0], gt[gt.len() - 1]);
    say!(
        "{}: {what} {t0:.1}..{t1:.1} s, {} samples at {:.4} s, table rate {} °/s taken out",
        args.recording.display(),
        gr.len(),
        dt,
        display::sig(display::DEG_PER_S.of(table_rate), 6)
    );
    say!("| τ | ADEV | terms |");
    say!("| --- | --- | --- |");
    for p in &curve {
        say!(
            "| {} s | {} °/h | {} |",
            bench_report::display::sig(p.tau_s, 4),
            display::sig(display::RATE.of(p.adev), 4),
            p.n_terms
        );
    }
    // An upper bound reads "K ≤ 0.02", not "K = ≤ 0.02".
    let bound = |t: &NoiseTerm| if t.upper_bound { "≤" } else { "=" };
    say!(
        "N (ARW) {} {:.3e} °/√h [{:.3e}, {:.3e}], B {} {:.3e} °/h (floor {:.3e} °/h), K {} {:.3e} °/h/√h (95 %)",
        bound(&fit.arw),
        display::ARW.of(fit.arw.value),
        display::ARW.of(fit.arw.low),
        display::ARW.of(fit.arw.high),
        bound(&fit.bias_instability),
        display::RATE.of(fit.bias_instability.value),
        display::RATE.of(fit.flicker_floor().value),
        bound(&fit.rate_random_walk),
        fit.rate_random_walk_deg_per_h_per_sqrt_h().value,
    );
    if let Some(path) = &args.csv {
        let mut text = String::from("tau_s,adev_rad_s,adev_deg_h,n_terms\n");
        for p in &curve {
            text.push_str(&format!(
                "{},{},{},{}\n",
                p.tau_s,
                p.adev,
                p.adev / DEG_PER_H,
                p.n_terms
            ));
        }
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &args.json {
        super::write_json(
            path,
            &json!({
                "version": 1,
                "recording": args.recording.display().to_string(),
                "window": args.window,
                "from_s": t0,
                "to_s": t1,
                "samples": gr.len(),
                "dt_s": dt,
                "table_rate_rad_s": table_rate,
                "confidence": fit.confidence,
                "arw_rad_per_sqrt_s": term(&fit.arw),
                "bias_instability_rad_s": term(&fit.bias_instability),
                "flicker_floor_rad_s": term(&fit.flicker_floor()),
                "rate_random_walk_rad_s_per_sqrt_s": term(&fit.rate_random_walk),
                "curve": curve.iter().map(|p| json!({"tau_s": p.tau_s, "adev_rad_s": p.adev, "m": p.m, "n_terms": p.n_terms})).collect::<Vec<_>>(),
            }),
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
