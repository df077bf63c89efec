//! The one overwrite rule of every verb that writes: an existing output is refused unless
//! `--force`, and an output folder holds one run's outputs only.
//!
//! A verb claims its outputs before it computes anything ([`Outputs::file`], [`Outputs::dir`]):
//! without `--force` an existing file, or a folder that holds anything, is refused there, and
//! nothing is written. Bench lists what it wrote into a folder in the folder's
//! [`MANIFEST`]; with `--force`, [`Outputs::prepare`] removes exactly those files before the new
//! ones are written, so no stale report is left beside a new model. A file bench did not write
//! (not in the manifest) is never removed: it is kept, and said so on stderr.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use anyhow::Context as _;

/// The name of the list of files bench wrote into an output folder.
pub const MANIFEST: &str = ".bench-outputs";

/// A file's identity for "did bench write it": modification time and length.
type Stamp = (Option<SystemTime>, u64);

#[derive(Debug)]
struct Folder {
    dir: PathBuf,
    /// What the folder held after [`Outputs::prepare`] (paths relative to it): what is still
    /// so when the verb ends was not written by it.
    before: BTreeMap<PathBuf, Stamp>,
}

/// The outputs of one command; the manifests of its folders are written when it is dropped.
#[derive(Debug)]
pub struct Outputs {
    force: bool,
    folders: Vec<Folder>,
    prepared: bool,
}

impl Outputs {
    /// Outputs under `--force` (`force`) or not.
    pub fn new(force: bool) -> Self {
        Self { force, folders: Vec::new(), prepared: false }
    }

    /// Claim an output file (`None` and `-`, stdout, claim nothing): refused if it exists,
    /// unless `--force`.
    pub fn file(&mut self, path: Option<&Path>) -> anyhow::Result<()> {
        let Some(path) = path.filter(|p| p.as_os_str() != "-") else { return Ok(()) };
        if path.is_dir() {
            anyhow::bail!("{} is a folder: give a file name", path.display());
        }
        if path.exists() && !self.force {
            anyhow::bail!(
                "{} exists: bench does not overwrite an output (--force replaces it, or choose \
                 another name)",
                path.display()
            );
        }
        Ok(())
    }

    /// Claim an output folder: refused if it holds anything, unless `--force`.
    pub fn dir(&mut self, dir: &Path) -> anyhow::Result<()> {
        if dir.exists() && !dir.is_dir() {
            anyhow::bail!("{} is a file, not a folder: choose another --out", dir.display());
        }
        let held = listing(dir);
        if !held.is_empty() && !self.force {
            let mut names: Vec<String> =
                held.keys().take(3).map(|p| p.display().to_string()).collect();
            if held.len() > 3 {
                names.push(format!("{} more", held.len() - 3));
            }
            let whose = if dir.join(MANIFEST).exists() {
                "the outputs of an earlier run"
            } else {
                "files bench did not write"
            };
            anyhow::bail!(
                "{} holds {whose} ({}): bench keeps one run's outputs per folder (--force \
                 replaces what bench wrote there and keeps any other file, or choose another \
                 --out)",
                dir.display(),
                names.join(", ")
            );
        }
        self.folders.push(Folder { dir: dir.to_owned(), before: BTreeMap::new() });
        Ok(())
    }

    /// Before the first output is written: remove what bench wrote into each claimed folder
    /// earlier (its manifest), say which other files are kept, and create the folders.
    pub fn prepare(&mut self) -> anyhow::Result<()> {
        for f in &mut self.folders {
            for name in manifest(&f.dir) {
                let path = f.dir.join(&name);
                if path.is_file() {
                    std::fs::remove_file(&path)
                        .with_context(|| format!("cannot remove {}", path.display()))?;
                }
            }
            let _ = std::fs::remove_file(f.dir.join(MANIFEST));
            f.before = listing(&f.dir);
            if !f.before.is_empty() {
                let names: Vec<String> = f.before.keys().map(|p| p.display().to_string()).collect();
                eprintln!(
                    "note: {} also holds {}, which bench did not write: kept",
                    f.dir.display(),
                    names.join(", ")
                );
            }
            std::fs::create_dir_all(&f.dir)
                .with_context(|| format!("cannot create {}", f.dir.display()))?;
        }
        self.prepared = true;
        Ok(())
    }
}

impl Drop for Outputs {
    /// The manifest of each folder: every file in it that is new or changed since
    /// [`Outputs::prepare`].
    fn drop(&mut self) {
        if !self.prepared {
            return;
        }
        for f in &self.folders {
            let written: Vec<String> = listing(&f.dir)
                .into_iter()
                .filter(|(p, stamp)| f.before.get(p) != Some(stamp))
                .map(|(p, _)| p.display().to_string())
                .collect();
            let text = format!(
                "# Files bench wrote here; `--force` removes exactly these before writing anew.\n{}\n",
                written.join("\n")
            );
            if let Err(e) = std::fs::write(f.dir.join(MANIFEST), text) {
                eprintln!("warning: cannot write {}: {e}", f.dir.join(MANIFEST).display());
            }
        }
    }
}

/// The files bench listed as its own in `dir` (relative paths; none without a manifest).
fn manifest(dir: &Path) -> Vec<PathBuf> {
    let Ok(text) = std::fs::read_to_string(dir.join(MANIFEST)) else { return Vec::new() };
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(PathBuf::from)
        // Only plain relative paths inside the folder: a manifest is never a way out of it.
        .filter(|p| p.components().all(|c| matches!(c, std::path::Component::Normal(_))))
        .collect()
}

/// Every file under `dir` (relative paths, the manifest aside) with its stamp.
fn listing(dir: &Path) -> BTreeMap<PathBuf, Stamp> {
    let mut out = BTreeMap::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(dir.join(&rel)) else { continue };
        for e in entries.flatten() {
            let path = rel.join(e.file_name());
            let Ok(meta) = e.metadata() else { continue };
            if meta.is_dir() {
                stack.push(path);
            } else if path.as_os_str() != MANIFEST {
                out.insert(path, (meta.modified().ok(), meta.len()));
            }
        }
    }
    out
}
