//! The bench recording format: one MCAP file per run, format version 1, as `FORMAT.md` beside
//! this crate describes it (the binding contract, in this repository's words).
//!
//! - [`message`]: one type per channel (`/gyro/rate`, `/table/state`, `/chamber/state`,
//!   `/bench/step`), used both to write and to read; [`Outcome`], [`StepEvent`].
//! - [`site`]: `bench.site`, written and read with the same checks.
//! - [`schema`]: topics, schema names, JSON Schemas, metadata names; [`status`]: the bits of the
//!   `status` fields as bench writes them.
//! - [`writer`]: the [`Recorder`]; [`reader`]: [`RecordingReader`] (streaming) and [`Recording`]
//!   (in memory) for any conforming file, whoever wrote it; [`info`]: what `bench info` shows;
//!   [`recover`]: a readable indexed file from a cut one; [`export`] (feature `export`): one CSV
//!   or Parquet table per channel.
//! - [`model_file`]: the gyro model file (TOML, units in the key names) that calibration and
//!   diagnosis write and the simulator loads; [`toml_doc`]: located TOML errors.
//!
//! Write a file and read it back:
//!
//! ```
//! use std::{collections::BTreeMap, io::Cursor, time::Duration};
//! use bench_recording::{
//!     GyroMsg, Outcome, Recorder, Recording, RunInfo, Site, StepEvent, TableMsg,
//! };
//!
//! let info = RunInfo::new(1_700_000_000_000_000_000, "demo", "", Site::at_latitude(45.0),
//!     BTreeMap::new());
//! let mut rec = Recorder::new(Cursor::new(Vec::new()), info)?;
//! rec.step(Duration::ZERO, 0, "record", StepEvent::Start, "record cw 20C")?;
//! for k in 1..=20u64 {
//!     let t = Duration::from_millis(50 * k);
//!     rec.gyro(t, None, &GyroMsg { rate_rad_s: -2.9e-3, temperature_c: Some(20.0), seq: k, status: 0 })?;
//!     let angle_rad = -2.9e-3 * t.as_secs_f64();
//!     rec.table(t, None, &TableMsg { angle_rad, rate_rad_s: -2.9e-3, rate_command_rad_s: -2.9e-3, status: 0 })?;
//! }
//! rec.step(Duration::from_secs(1), 0, "record", StepEvent::End, "record cw 20C")?;
//! let bytes = rec.finish(&Outcome::Completed)?.into_inner();
//!
//! let back = Recording::from_bytes(&bytes)?;
//! assert_eq!(back.gyro.len(), 20);
//! assert_eq!(back.outcome(), Some(Outcome::Completed));
//! assert_eq!(back.site()?, Some(Site::at_latitude(45.0)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod effects_toml;
#[cfg(feature = "export")]
pub mod export;
pub mod info;
pub mod message;
pub mod model_file;
pub mod reader;
pub mod recover;
pub mod schema;
pub mod site;
pub mod status;
pub mod steps;
pub mod toml_doc;
pub mod writer;

pub use info::{
    container_info, human_duration, info, info_from_reader, ChannelReport, ContainerInfo,
    DeviceTiming, Gap, RecordingInfo, StepReport,
};
pub use message::{
    ChamberMsg, GyroMsg, LogLevel, ModelRole, Outcome, StepEvent, StepMsg, TableMsg,
};
pub use reader::{
    read_summary, summary_counts, AttachmentRecord, ChannelInfo, Damage, DamageKind, DamageReport,
    End, Item, MetadataRecord, OtherMessage, Recording, RecordingError, RecordingReader, Stamped,
};
pub use site::{Axis, MetadataError, Site, SiteNumber};
pub use writer::{RecordError, Recorder, RecorderOptions, RunInfo, TomlAttachment};
