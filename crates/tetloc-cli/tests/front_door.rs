//! Every command builds its locator through the front door (`tetloc_locator`): with
//! `TETLOC_EXPLAIN=1` each says its stack, which is the library's for the same options.

use std::process::Command;
use std::sync::Arc;
use tetloc_core::locate::Precision;
use tetloc_locator::{Backend, Locator};
use tetloc_testdata::KuhnGrid;

/// The `locator: ...` lines `tetloc ARGS` says on stderr.
fn stacks_said(args: &[&str]) -> Vec<String> {
    let out =
        Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).env("TETLOC_EXPLAIN", "1").output().expect("run tetloc");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "tetloc {args:?}: {err}");
    err.lines().filter_map(|l| l.strip_prefix("locator: ")).map(str::to_string).collect()
}

/// What the library builds on `cpu` for these options.
fn library_stack(precision: Precision, tolerance: &str) -> String {
    let mesh = Arc::new(KuhnGrid::new(2).mesh("grid"));
    let b = Locator::builder(mesh).backend(Backend::Cpu).precision(precision).tolerance(tolerance.parse().unwrap());
    let layers: Vec<&str> = b.stack().iter().map(|l| l.name()).collect();
    format!("cpu > {}", layers.join(" > "))
}

#[test]
fn every_command_says_the_librarys_stack() {
    let dir = std::env::temp_dir().join(format!("tetloc-front-door-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    std::fs::write(dir.join("p.csv"), "0.1,0.2,0.3\n0.5,0.5,0.5\n").unwrap();
    let mesh = "jets:2000";
    let locate = |backend: &str, extra: &[&str]| {
        let args = ["locate", mesh, "--points", &path("p.csv"), "--out", &path("ids.npy"), "--backend", backend, "-q"];
        stacks_said(&[&args[..], extra].concat())
    };
    assert_eq!(locate("cpu", &[]), [library_stack(Precision::F32, "0")]);
    assert_eq!(locate("cpu", &["--tolerance", "1%"]), [library_stack(Precision::F32, "1%")]);
    assert_eq!(locate("cpu", &["--precision", "f64", "--tolerance", "0.01"]), [library_stack(Precision::F64, "0.01")]);
    assert_eq!(library_stack(Precision::F64, "0.01"), "cpu > FiniteOnly > CellLocator > F64Values > WithTolerance");
    let probe = stacks_said(&[
        "probe",
        mesh,
        &path("p.csv"),
        "-o",
        &path("probed.vtu"),
        "--backend",
        "cpu",
        "--tolerance",
        "1%",
        "-q",
    ]);
    assert_eq!(probe, [library_stack(Precision::F32, "1%")]);
    let resample =
        stacks_said(&["resample", mesh, "--dims", "4,4,4", "-o", &path("image.vti"), "--backend", "cpu", "-q"]);
    assert_eq!(resample, [library_stack(Precision::F32, "0")]);
    let render =
        stacks_said(&["render", mesh, "--field", "f", "--size", "8x8", "-o", &path("r.png"), "--backend", "cpu", "-q"]);
    assert_eq!(render, [library_stack(Precision::F32, "0")]);
    // `auto` is decided by the library too, and stacked the same way.
    let auto = locate("auto", &["--tolerance", "1%"]);
    assert_eq!(auto.len(), 1);
    assert!(auto[0].ends_with("> FiniteOnly > CellLocator > WithTolerance"), "{auto:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
