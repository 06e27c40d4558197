//! What the `tetloc` binary's tests share: running it, scratch folders, paths as arguments
//! and the files it writes.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs `tetloc ARGS`: whether it succeeded, its stdout and its stderr.
pub fn tetloc(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).output().expect("run tetloc");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

/// Runs `tetloc ARGS --backend cpu`: the CPU path, which runs anywhere.
pub fn tetloc_cpu(args: &[&str]) -> (bool, String, String) {
    tetloc(&[args, &["--backend", "cpu"]].concat())
}

/// A scratch file or folder of this test process (named by the process, so that test binaries
/// do not meet).
pub fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("tetloc-cli-{}-{name}", std::process::id()))
}

/// A fresh, empty directory for one test.
pub fn tmp_dir(name: &str) -> PathBuf {
    let d = tmp(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The names in `dir`, sorted.
pub fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// A file of raw values (ids, coordinates) as `T`s.
pub fn read<T: bytemuck::Pod>(p: &Path) -> Vec<T> {
    bytemuck::pod_collect_to_vec(&std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())))
}

/// Declares test `$shared`, which runs `$checks(test, data)` on the shared oracle data
/// (skipped without it, outside CI), and `$generated`, its fresh-clone counterpart on the data
/// generated at test time (`tetloc_testdata::generated_data`).
#[macro_export]
macro_rules! oracle_tests {
    ($(#[$shared_attr:meta])* fn $shared:ident; $(#[$generated_attr:meta])* fn $generated:ident; $checks:ident) => {
        $(#[$shared_attr])*
        #[test]
        fn $shared() {
            let test = stringify!($shared);
            if let Some(data) = tetloc_testdata::require_data(test) {
                $checks(test, &data);
            }
        }

        $(#[$generated_attr])*
        #[test]
        fn $generated() {
            $checks(stringify!($generated), tetloc_testdata::generated_data());
        }
    };
}
