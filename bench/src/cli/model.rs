//! `bench model REC`: a recording's nominal gyro model (`bench.gyro_model` and its `effect.*`
//! keys) as a model TOML file; and the one reader of `--model FILE` for the verbs that take a
//! nominal model, a model TOML or a recording (told apart by MCAP's magic bytes).

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use super::say::say;
use anyhow::Context as _;
use bench_physics::effects::Effects;
use bench_physics::GyroModel;
use bench_recording::model_file::{CalibrationFile, Source, Uncertainty};
use bench_recording::schema::META_GYRO_MODEL;
use bench_recording::{Item, RecordingReader};

/// The first bytes of every MCAP file.
const MCAP_MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Arguments of `bench model`.
#[derive(clap::Args, Debug)]
pub struct ModelArgs {
    /// Recording (MCAP) whose `bench.gyro_model` to write out.
    pub recording: PathBuf,
    /// Model TOML to write (loadable by `bench run --gyro-model` and `bench diagnose
    /// --model`); default: print it on stdout.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Also write the model as JSON (the `bench.gyro_model` keys as recorded).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Say nothing on success.
    #[arg(long, short)]
    pub quiet: bool,
    /// Replace existing outputs: a file given here, and in an output folder exactly the files
    /// bench wrote there before (any other file is kept).
    #[arg(long)]
    pub force: bool,
}

/// Whether the file at `path` starts like an MCAP file.
pub fn is_mcap(path: &Path) -> anyhow::Result<bool> {
    let mut head = [0u8; 8];
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e).with_context(|| format!("cannot read {}", path.display())),
        }
    }
    Ok(n == head.len() && &head == MCAP_MAGIC)
}

/// The last `bench.gyro_model` record of the recording at `path`, as recorded.
pub fn recorded_metadata(
    path: &Path,
) -> anyhow::Result<std::collections::BTreeMap<String, String>> {
    let mut reader = RecordingReader::open(path)
        .with_context(|| format!("cannot read {}", path.display()))?
        .raw();
    let mut found = None;
    for item in reader.by_ref() {
        if let Item::Metadata(m) =
            item.with_context(|| format!("cannot read {}", path.display()))?
        {
            if m.name == META_GYRO_MODEL {
                found = Some(m.entries);
            }
        }
    }
    found.with_context(|| {
        format!("{}: the recording has no {META_GYRO_MODEL} metadata record", path.display())
    })
}

/// The recording's nominal model: `bench.gyro_model`'s contract keys and its `effect.*` keys.
pub fn recorded_model(path: &Path) -> anyhow::Result<(GyroModel, Effects)> {
    let meta = recorded_metadata(path)?;
    let (model, _unknown) = GyroModel::from_metadata(&meta)
        .map_err(|e| anyhow::anyhow!("{}: {META_GYRO_MODEL}: {e}", path.display()))?;
    let effects = Effects::from_metadata(&meta)
        .map_err(|e| anyhow::anyhow!("{}: {META_GYRO_MODEL}: {e}", path.display()))?;
    Ok((model, effects))
}

/// A nominal model from `path`: a recording's `bench.gyro_model` (an MCAP file) or a model
/// TOML file; with the name it is reported under.
pub fn load_nominal(path: &Path) -> anyhow::Result<(GyroModel, Effects, String)> {
    if is_mcap(path)? {
        let (model, effects) = recorded_model(path)?;
        Ok((model, effects, format!("{} ({META_GYRO_MODEL})", path.display())))
    } else {
        let file = CalibrationFile::load(path)?;
        Ok((file.model(), file.effects, path.display().to_string()))
    }
}

/// Write the recording's model out.
pub fn run(args: ModelArgs) -> anyhow::Result<ExitCode> {
    super::say::set_quiet(args.quiet);
    super::kind::expect(&args.recording, &[super::kind::Kind::Recording])?;
    let mut outputs = super::outputs::Outputs::new(args.force);
    outputs.file(args.out.as_deref())?;
    outputs.file(args.json.as_deref())?;
    let meta = recorded_metadata(&args.recording)?;
    let (model, effects) = recorded_model(&args.recording)?;
    let name = args
        .recording
        .file_name()
        .map_or_else(|| args.recording.display().to_string(), |n| n.to_string_lossy().into_owned());
    let file = CalibrationFile::new(
        &model,
        &effects,
        Source {
            recording: name,
            software: format!("bench {}", env!("CARGO_PKG_VERSION")),
            method: format!("the recording's {META_GYRO_MODEL} (its nominal model), as recorded"),
        },
        Uncertainty::default(),
    );
    match &args.out {
        Some(path) => {
            file.save(path)?;
            if !args.quiet {
                say!("wrote {}", path.display());
            }
        }
        None => super::say::write(&file.to_toml()),
    }
    if let Some(path) = &args.json {
        super::write_json(path, &serde_json::json!({ META_GYRO_MODEL: meta }))?;
        if !args.quiet && args.out.is_some() {
            say!("wrote {}", path.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
