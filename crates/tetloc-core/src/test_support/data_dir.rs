//! Where the oracle data is: `../shared/data` from the project root (made with VTK, scipy and
//! gmsh), or the folder `TETLOC_DATA` names. When it is absent the tests say so and skip,
//! except in CI (`CI` set), where that is a failure.
//!
//! One source for two crates: core's unit tests compile it into `test_support`, and
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use std::path::{Path, PathBuf};

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
            eprintln!("SKIPPED {test}: oracle data not found (set TETLOC_DATA to ../shared/data)");
            None
        }
    }
}
