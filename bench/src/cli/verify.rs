//! `bench verify RECORDING --calibration FILE`: a calibration file applied to another run of the
//! same gyro, judged window by window (`bench_report::verify`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use bench_recording::model_file::CalibrationFile;
use bench_report::verify::{
    summary_lines, verify_json, verify_recording, VerifyOutcome, VerifyVerdict,
};

use super::exit::Exit;
use super::say::say;

/// Arguments of `bench verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// The verification recording (MCAP, per the recording contract).
    pub recording: PathBuf,
    /// The calibration file to apply (`calibration.toml` of `bench calibrate`).
    #[arg(long, short = 'c')]
    pub calibration: PathBuf,
    /// Directory for `report.html` and its PNG figure.
    #[arg(long, short, default_value = "verification")]
    pub out: PathBuf,
    /// Also write the machine-readable result here (docs/calibrate.md).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Skip the HTML/PNG report.
    #[arg(long)]
    pub no_report: bool,
    /// No progress bar, nothing on stdout.
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// The exit code of a verification: 0 pass, 11 worse, 12 beyond the stated σ, 9 beyond the
/// acceptance limit.
pub fn exit_of(v: &VerifyOutcome) -> Exit {
    match v.verdict {
        VerifyVerdict::Pass => Exit::Success,
        VerifyVerdict::Worse => Exit::CompensationWorse,
        VerifyVerdict::Fail => Exit::AcceptanceFailed,
        VerifyVerdict::BeyondSigma => Exit::BeyondStatedSigma,
    }
}

fn file_name(p: &std::path::Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Verify and write the outputs.
pub fn run(args: VerifyArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.calibration, &[super::kind::Kind::Model])?;
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.json.as_deref())?;
    if !args.no_report {
        outputs.dir(&args.out)?;
    }
    let cal = CalibrationFile::load(&args.calibration)?;
    let rec = super::load_recording(&args.recording, args.quiet)?;
    let v = verify_recording(&rec, &cal)
        .with_context(|| format!("cannot verify on {}", args.recording.display()))?;
    let (name, cname) = (file_name(&args.recording), file_name(&args.calibration));
    outputs.prepare()?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&verify_json(&v, &name, &cname))?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let files = if args.no_report {
        None
    } else {
        Some(bench_report::verify_html::write_verify_report(&v, &name, &cname, &args.out)?)
    };
    if !args.quiet {
        say!("{name}: calibration {cname} (made on {})", v.calibration.source.recording);
        for (k, h) in &v.calibration.held {
            say!("held in the calibration: {k}: {}", h.reason);
        }
        for l in summary_lines(&v.compensation) {
            say!("{l}");
        }
        if let Some(a) = &v.acceptance {
            say!(
                "acceptance: bias after compensation within {} in every window: {} (worst `{}`)",
                bench_report::display::si_value(bench_report::display::RATE, a.limit, 4),
                a.result.key(),
                a.window
            );
        }
        say!("verification: {}", v.verdict.text());
        if let Some(p) = &args.json {
            say!("wrote {}", p.display());
        }
        if let Some(f) = &files {
            say!("wrote {}", f.html.display());
        }
    }
    Ok(exit_of(&v).into())
}
