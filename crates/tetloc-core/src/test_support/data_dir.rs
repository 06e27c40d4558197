//! Where the oracle data is: `../shared/data` from the project root (made with VTK, scipy and
//! gmsh), or the folder `TETLOC_DATA` names. When it is absent the tests say so and skip,
//! except in CI (`CI` set), where that is a failure. Every skip of every test goes through
//! [`skip`], which also lists it for the run's summary.
//!
//! One source for two crates: core's unit tests compile it into `test_support`, and
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Why tests skip without `../shared`: the reason [`require_data`] records.
pub const NO_DATA: &str = "no ../shared oracle data [TETLOC_DATA]";

/// The data folder, if it exists.
pub fn data_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("TETLOC_DATA") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    };
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// True when running in CI, where nothing may be skipped.
pub fn in_ci() -> bool {
    std::env::var("CI").map(|v| !v.is_empty() && v != "false" && v != "0").unwrap_or(false)
}

/// The data folder for a test, or `None` (after saying so) when a user's clone lacks it.
/// Panics in CI.
pub fn require_data(test: &str) -> Option<PathBuf> {
    match data_dir() {
        Some(d) => Some(d),
        None if in_ci() => {
            panic!("{test}: oracle data not found (set TETLOC_DATA or lay out ../shared/data); CI must not skip")
        }
        None => {
            skip(test, NO_DATA);
            None
        }
    }
}

/// Records that `test` (or a part of it) did not run, and why: prints a SKIPPED line and
/// appends `test<TAB>reason` to the file `TETLOC_SKIP_LOG` names, if any (`scripts/test.sh`
/// sets it and ends its run with the count by reason, so a skip never passes for a pass).
/// `reason` is short and shared by every test skipped for the same cause.
///
/// # Panics
/// When the log cannot be written: a skip nobody hears of would count as a pass.
pub fn skip(test: &str, reason: &str) {
    eprintln!("SKIPPED {test}: {reason}");
    let Some(log) = std::env::var_os("TETLOC_SKIP_LOG") else { return };
    // One short write in append mode: lines of tests running in parallel do not interleave.
    let line = format!("{test}\t{reason}\n");
    let appended = std::fs::OpenOptions::new().create(true).append(true).open(&log);
    if let Err(e) = appended.and_then(|mut f| f.write_all(line.as_bytes())) {
        panic!("{test}: cannot record its skip in {}: {e}", Path::new(&log).display());
    }
}
