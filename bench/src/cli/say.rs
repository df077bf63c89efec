//! Everything a command prints on stdout goes through here, for two rules of every verb:
//! `-q` leaves on stdout only what was asked for (`--json -`, a completion script), and a
//! closed stdout (`bench calibrate REC | head`) ends the printing quietly, never in a panic: the
//! command carries on, writes its files and ends with its own exit code. Errors, warnings and
//! notes go to stderr whatever `-q` says.

use std::io::Write as _;
use std::sync::atomic::{AtomicBool, Ordering};

static QUIET: AtomicBool = AtomicBool::new(false);
static CLOSED: AtomicBool = AtomicBool::new(false);

/// Set by each verb from its `-q`: [`say!`] then prints nothing.
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether `-q` was given.
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// Write `text` to stdout unless it was closed; a closed stdout is remembered and ends all
/// further printing without an error.
pub fn write(text: &str) {
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if out.write_all(text.as_bytes()).and_then(|()| out.flush()).is_err() {
        CLOSED.store(true, Ordering::Relaxed);
    }
}

/// A line of the report a verb prints (not with `-q`).
pub fn line(args: std::fmt::Arguments<'_>) {
    if !quiet() {
        write(&format!("{args}\n"));
    }
}

/// A line that was asked for (`--json -`): printed even with `-q`.
pub fn asked_line(args: std::fmt::Arguments<'_>) {
    write(&format!("{args}\n"));
}

/// `println!` for a verb's report: nothing with `-q`, nothing after stdout was closed.
macro_rules! say {
    () => { $crate::cli::say::line(format_args!("")) };
    ($($t:tt)*) => { $crate::cli::say::line(format_args!($($t)*)) };
}

/// `println!` for what was asked on stdout (`--json -`): printed with `-q` too.
macro_rules! asked {
    ($($t:tt)*) => { $crate::cli::say::asked_line(format_args!($($t)*)) };
}

pub(crate) use {asked, say};
