//! What a file given to a verb is, when it is not what the verb reads: an MCAP recording, a
//! scenario, a bench config, a model or calibration file. A wrong file is named with the verbs
//! that take it (`bench validate seed.mcap` → "this is an MCAP recording: use bench info /
//! calibrate / …"), a usage error (exit 2), before anything is read in earnest.

use std::io::Read as _;
use std::path::Path;

use super::exit::UsageError;

/// The first bytes of every MCAP file.
const MCAP_MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// The kinds of file bench reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// An MCAP recording.
    Recording,
    /// A scenario (TOML with `[scenario]` or `[[step]]`).
    Scenario,
    /// A bench config (TOML with `[table]`, `[chamber]` or `[gyro]` drivers, `[bench]`, `[limits]`).
    BenchConfig,
    /// A model or calibration file (TOML with `[gyro_model]`).
    Model,
}

impl Kind {
    /// What it is and the verbs that take it.
    fn hint(self) -> &'static str {
        match self {
            Kind::Recording => {
                "an MCAP recording: use bench info / calibrate / diagnose / replay / export / \
                 allan / model / verify"
            }
            Kind::Scenario => "a scenario (TOML): use bench validate / run / monte-carlo",
            Kind::BenchConfig => {
                "a bench config (TOML): give it as --bench to bench run / validate, or to \
                 bench sim serve"
            }
            Kind::Model => {
                "a model or calibration file (TOML, [gyro_model]): give it as --calibration to \
                 bench verify, --model to bench diagnose / monte-carlo, --gyro-model to bench run"
            }
        }
    }
}

/// What `path` is, from its first bytes and its TOML tables; `None` when unreadable or none of
/// bench's kinds.
pub fn sniff(path: &Path) -> Option<Kind> {
    let mut head = Vec::new();
    std::fs::File::open(path).ok()?.take(1 << 20).read_to_end(&mut head).ok()?;
    if head.starts_with(MCAP_MAGIC) {
        return Some(Kind::Recording);
    }
    let text = std::str::from_utf8(&head).ok()?;
    let value: toml::Table = text.parse().ok()?;
    if value.contains_key("scenario") || value.contains_key("step") {
        Some(Kind::Scenario)
    } else if value.contains_key("gyro_model") {
        Some(Kind::Model)
    } else if ["table", "chamber", "gyro", "bench", "limits"].iter().any(|k| value.contains_key(*k))
    {
        Some(Kind::BenchConfig)
    } else {
        None
    }
}

/// A usage error unless `path` is one of the `want` kinds or of no kind bench knows (then the verb's
/// own reader says what is wrong with it).
pub fn expect(path: &Path, want: &[Kind]) -> anyhow::Result<()> {
    match sniff(path) {
        Some(kind) if !want.contains(&kind) => {
            let e = UsageError(format!("{} is {}", path.display(), kind.hint()));
            Err(e.into())
        }
        _ => Ok(()),
    }
}
