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

/// A Gmsh file of a Kuhn cube (3³ cubes, 162 tets) with the vertex field `f` = x + k·y at
/// step k of `times` (a pattern that changes, not only its scale).
pub fn gmsh_series(path: &std::path::Path, times: &[f64]) {
    gmsh_series_of(path, times, false)
}

/// [`gmsh_series`], and with `flow` a vector `v` at each step after its `f`:
/// `(0.2, 0.1 + step·(x − 0.5), 0.05)`.
pub fn gmsh_series_of(path: &std::path::Path, times: &[f64], flow: bool) {
    let n = 3usize;
    let id = |i: usize, j: usize, k: usize| 1 + i + (n + 1) * (j + (n + 1) * k);
    let corners: Vec<[usize; 3]> =
        (0..=n).flat_map(|k| (0..=n).flat_map(move |j| (0..=n).map(move |i| [i, j, k]))).collect();
    let mut tets = Vec::new();
    for c in (0..n).flat_map(|k| (0..n).flat_map(move |j| (0..n).map(move |i| [i, j, k]))) {
        for axes in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
            let mut v = c;
            let mut tet = vec![id(v[0], v[1], v[2])];
            for a in axes {
                v[a] += 1;
                tet.push(id(v[0], v[1], v[2]));
            }
            tets.push(tet);
        }
    }
    let x = |c: &[usize; 3]| c.map(|v| v as f64 / n as f64);
    let mut text = format!("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 {0} 1 {0}\n3 1 0 {0}\n", corners.len());
    (1..=corners.len()).for_each(|i| text += &format!("{i}\n"));
    corners.iter().for_each(|c| text += &format!("{} {} {}\n", x(c)[0], x(c)[1], x(c)[2]));
    text += &format!("$EndNodes\n$Elements\n1 {0} 1 {0}\n3 1 4 {0}\n", tets.len());
    for (e, t) in tets.iter().enumerate() {
        text += &format!("{} {} {} {} {}\n", e + 1, t[0], t[1], t[2], t[3]);
    }
    text += "$EndElements\n";
    for (step, t) in times.iter().enumerate() {
        text += &format!("$NodeData\n1\n\"f\"\n1\n{t:?}\n3\n{step}\n1\n{}\n", corners.len());
        for (i, c) in corners.iter().enumerate() {
            let p = x(c);
            text += &format!("{} {}\n", i + 1, p[0] + step as f64 * p[1]);
        }
        text += "$EndNodeData\n";
        if flow {
            text += &format!("$NodeData\n1\n\"v\"\n1\n{t:?}\n3\n{step}\n3\n{}\n", corners.len());
            for (i, c) in corners.iter().enumerate() {
                let p = x(c);
                text += &format!("{} 0.2 {} 0.05\n", i + 1, 0.1 + step as f64 * (p[0] - 0.5));
            }
            text += "$EndNodeData\n";
        }
    }
    std::fs::write(path, text).unwrap();
}

/// The Vulkan devices `tetloc devices` lists: (device type, ray tracing). `None` (after a
/// SKIPPED line) when there is none outside CI; a failure in CI.
pub fn vulkan_devices(test: &str) -> Option<Vec<(String, bool)>> {
    let (ok, out, err) = tetloc(&["devices"]);
    let list: Vec<(String, bool)> = out
        .lines()
        .filter_map(|l| {
            // `0: NAME (DRIVER, TYPE), Vulkan 1.3, ...`
            let kind = l.split_once("), Vulkan ")?.0.rsplit_once(", ")?.1.to_string();
            Some((kind, l.contains("ray tracing: yes")))
        })
        .collect();
    if ok && !list.is_empty() {
        return Some(list);
    }
    assert!(!tetloc_testdata::in_ci(), "{test}: no Vulkan device in CI: {out}{err}");
    tetloc_testdata::skip(test, "no Vulkan device");
    None
}

/// `soft-bvh` where there is a Vulkan device ([`vulkan_devices`]).
pub fn gpu_backend(test: &str) -> Option<&'static str> {
    vulkan_devices(test).map(|_| "soft-bvh")
}
