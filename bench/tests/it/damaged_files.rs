//! Damaged and cut recordings through the binary (issue 28): an analysis of a file with
//! damaged chunks warns with the damage and its bench time and analyses the rest; an analysis
//! that fails on a cut file names the cut first and `bench recover`; `recover X X` is a usage
//! error (exit 2).

use std::path::{Path, PathBuf};

use crate::common::{bench, text};

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/demo-warm-up-and-step.mcap")
}

#[test]
fn recover_into_its_own_input_is_a_usage_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::copy(demo(), dir.path().join("r.mcap")).expect("copy");
    let before = std::fs::read(dir.path().join("r.mcap")).expect("read");
    let r = bench(&["recover", "r.mcap", "r.mcap"], dir.path());
    assert_eq!(r.status.code(), Some(2), "{}", text(&r.stderr));
    assert!(text(&r.stderr).contains("both the input and the output"), "{}", text(&r.stderr));
    assert_eq!(std::fs::read(dir.path().join("r.mcap")).expect("read"), before, "input kept");
}

#[test]
fn calibrate_warns_of_damaged_chunks_and_analyses_the_rest() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut bytes = std::fs::read(demo()).expect("demo");
    // Three bits flipped well inside the data section (seeded positions, past the first 5 %).
    let n = bytes.len();
    for (i, bit) in [(n / 3, 2u8), (n / 2, 5), (2 * n / 3, 1)] {
        bytes[i] ^= 1 << bit;
    }
    std::fs::write(dir.path().join("flip.mcap"), &bytes).expect("write");
    let info = bench(&["info", "flip.mcap"], dir.path());
    let shown = text(&info.stdout);
    assert!(shown.contains("DAMAGED"), "{shown}");
    assert!(shown.contains("CRC-checked"), "{shown}");
    let r = bench(&["calibrate", "flip.mcap", "-o", "cal"], dir.path());
    let (out, err) = (text(&r.stdout), text(&r.stderr));
    assert!(err.contains("warning: the recording is damaged"), "{err}");
    assert!(err.contains("of bench time, between"), "{err}");
    assert!(err.contains("at byte"), "{err}");
    assert!(!out.contains("NaN"), "{out}");
    assert!(!out.contains("0 checks passed"), "{out}");
}

#[test]
fn an_analysis_that_fails_on_a_cut_file_names_the_cut_first() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bytes = std::fs::read(demo()).expect("demo");
    // The first 5 %: five minutes of warm-up, no record window yet.
    std::fs::write(dir.path().join("cut.mcap"), &bytes[..bytes.len() / 20]).expect("write");
    let r = bench(&["calibrate", "cut.mcap", "-o", "cal"], dir.path());
    assert!(!r.status.success());
    let err = text(&r.stderr);
    let line = err.lines().find(|l| l.starts_with("error:")).expect("an error line");
    let cut = line.find("the recording is cut at byte").expect("names the cut");
    let recover = line.find("bench recover cut.mcap").expect("names bench recover");
    let why = line.find("cannot calibrate").expect("then the analysis's reason");
    assert!(cut < recover && recover < why, "{line}");
    assert!(line.contains("bench time"), "{line}");
}
