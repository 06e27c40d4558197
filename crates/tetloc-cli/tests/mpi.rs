//! `mpirun -n N tetloc ...` end to end (feature `mpi`; `scripts/test.sh` runs these with
//! OpenMPI installed): on the oracle sets partitioned by `tetloc partition`, every rank count
//! gives the one-process answers and no oracle mismatch; a failing, panicking or killed rank
//! ends the job with an error, within a time limit. Without `mpirun` these skip, except in CI.
#![cfg(feature = "mpi")]

mod common;

use common::{read, s, tmp_dir};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};
use tetloc_testdata::{in_ci, query_sets, require_data, QuerySet};

/// Longest a job may take before it counts as hung.
const LIMIT_S: u64 = 120;

fn have_mpirun(test: &str) -> bool {
    let ok = Command::new("mpirun").arg("--version").output().is_ok_and(|o| o.status.success());
    if !ok {
        assert!(!in_ci(), "{test}: no mpirun; CI installs OpenMPI (scripts/install-test-deps.sh)");
        tetloc_testdata::skip(test, "no mpirun [openmpi-bin]");
    }
    ok
}

fn tetloc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).output().expect("run tetloc")
}

/// `mpirun -n N tetloc ARGS` with `env` passed to every rank, killed after [`LIMIT_S`].
fn mpirun(n: usize, env: &[(&str, &str)], args: &[&str]) -> (Output, Duration) {
    let mut cmd = Command::new("timeout");
    cmd.args(["-k", "5", &LIMIT_S.to_string(), "mpirun", "--oversubscribe", "--allow-run-as-root"]);
    cmd.args(["--mca", "btl", "self,vader", "-n", &n.to_string()]);
    for (k, v) in env {
        cmd.env(k, v).args(["-x", k]);
    }
    cmd.arg(env!("CARGO_BIN_EXE_tetloc")).args(args).env("RAYON_NUM_THREADS", "1");
    let t = Instant::now();
    let out = cmd.output().expect("run mpirun");
    (out, t.elapsed())
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// The test's scratch folder `name`, or `None` (the test skipped) where there is no mpirun.
fn mpi_dir(test: &str, name: &str) -> Option<PathBuf> {
    have_mpirun(test).then(|| tmp_dir(name))
}

/// `mesh` cut into 4 pieces in `dir`.
fn partition(dir: &Path, mesh: &Path, name: &str, parts: usize) -> PathBuf {
    let out = dir.join(format!("{name}.pvtu"));
    let o = tetloc(&["partition", s(mesh), "--parts", &parts.to_string(), "-o", s(&out)]);
    assert!(o.status.success(), "{}", text(&o));
    out
}

/// The oracle sets of one mesh as one points file, with their oracle answers and flags.
fn join_sets(dir: &Path, sets: &[&QuerySet]) -> (PathBuf, Vec<i32>, Vec<u8>) {
    let pts: Vec<[f32; 3]> = sets.iter().flat_map(|s| s.points.iter().copied()).collect();
    let path = dir.join(format!("{}.points.bin", sets[0].label));
    std::fs::write(&path, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    (
        path,
        sets.iter().flat_map(|s| s.cell.iter().copied()).collect(),
        sets.iter().flat_map(|s| s.flags.iter().copied()).collect(),
    )
}

/// On torus, part, delaunay (tets) and hybrid (hexes, wedges, pyramids, tets), each in 4
/// pieces: 1, 2 and 4 ranks give the ids and values one process gives on the whole file
/// (points within rounding of a face, flags bit0, may go to either cell), and no mismatch
/// with the oracle outside flags bit0.
#[test]
fn ranks_answer_as_one_process() {
    let test = "ranks_answer_as_one_process";
    let Some(data) = require_data(test) else { return };
    if !have_mpirun(test) {
        return;
    }
    let dir = tmp_dir("oracle");
    let mut all = query_sets(&data);
    all.extend(query_sets(&data.join("mixed")));
    for mesh in ["torus_s", "part_s", "delaunay_s", "hybrid"] {
        let sets: Vec<&QuerySet> = all.iter().filter(|s| s.label.starts_with(&format!("{mesh}."))).collect();
        assert_eq!(sets.len(), 3, "{mesh}: centers, random, bbox");
        let field = if mesh == "hybrid" { "g" } else { "cellval" };
        let (points, oracle, flags) = join_sets(&dir, &sets);
        let pvtu = partition(&dir, &sets[0].mesh_path, mesh, 4);
        let (want_ids, want_vals) =
            locate_cpu::<f32>(&dir, &sets[0].mesh_path, &points, field, &format!("{mesh}.ref"), None);
        for n in [1, 2, 4] {
            let (ids, vals) = locate_cpu::<f32>(&dir, &pvtu, &points, field, &format!("{mesh}.{n}-ranks"), Some(n));
            assert_eq!(ids.len(), want_ids.len());
            let (mut ties, mut oracle_mismatch) = (0, 0);
            for i in 0..ids.len() {
                let on_face = flags[i] & 1 != 0;
                if ids[i] != want_ids[i] {
                    assert!(on_face, "{mesh}, {n} ranks, point {i}: {} but one process says {}", ids[i], want_ids[i]);
                    ties += 1;
                } else {
                    assert_eq!(vals[i].to_bits(), want_vals[i].to_bits(), "{mesh}, {n} ranks, point {i}: value");
                }
                if !on_face && ids[i] != oracle[i] {
                    oracle_mismatch += 1;
                }
            }
            assert_eq!(oracle_mismatch, 0, "{mesh}, {n} ranks: oracle mismatches outside flags bit0");
            eprintln!("{mesh}, {n} ranks: {} points, {ties} on a face answered by the other cell", ids.len());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A mesh in UTM coordinates stored in f64 (`utm/part_utm`), in 4 pieces, with its f64 query
/// points: 2 and 4 ranks write the ids and values one process writes on the whole file, byte
/// for byte, and `resample` the same mask (values within f32 rounding: one process's raster
/// interpolates in f32). The ranks exchange and answer the file's f64 points, as one process
/// takes them; in f32 the points moved by up to half a metre there, some into other cells.
#[test]
fn far_meshes_run_distributed_at_the_files_precision() {
    let test = "far_meshes_run_distributed_at_the_files_precision";
    let Some(data) = require_data(test) else { return };
    if !have_mpirun(test) {
        return;
    }
    let dir = tmp_dir("utm");
    let mesh = data.join("utm/part_utm.vtu");
    let pvtu = partition(&dir, &mesh, "part_utm", 4);
    for set in ["random", "bbox"] {
        let points = data.join(format!("utm/part_utm.{set}.points.npy"));
        // `f` is stored in f64: its values are written in f64.
        let (want_ids, want_vals) = locate_cpu::<f64>(&dir, &mesh, &points, "f", &format!("{set}.ref"), None);
        for n in [2, 4] {
            let (ids, vals) = locate_cpu::<f64>(&dir, &pvtu, &points, "f", &format!("{set}.{n}"), Some(n));
            assert!(ids == want_ids, "{set}, {n} ranks: the ids differ from one process's");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(bits(&vals) == bits(&want_vals), "{set}, {n} ranks: the values differ from one process's");
        }
    }
    let want = resample_f(&dir, &mesh, "r1.npy", None);
    let got = resample_f(&dir, &pvtu, "r2.npy", Some(2));
    assert_eq!(want.len(), got.len());
    let differ = (0..got.len()).filter(|&i| !same_value(got[i], want[i])).count();
    assert_eq!(differ, 0, "2 ranks: {differ} grid points differ from one process's");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `tetloc locate MESH --points POINTS --backend cpu --field FIELD`, ids and values written to
/// `dir` under `tag`, by one process (`ranks`: `None`) or `mpirun -n N`: the ids and values.
/// `V`: the values' type as written (f64 for a field stored in f64).
fn locate_cpu<V: bytemuck::Pod>(
    dir: &Path,
    mesh: &Path,
    points: &Path,
    field: &str,
    tag: &str,
    ranks: Option<usize>,
) -> (Vec<i32>, Vec<V>) {
    let (ids, vals) = (dir.join(format!("{tag}.ids.bin")), dir.join(format!("{tag}.f.bin")));
    let args = ["locate", s(mesh), "--points", s(points), "--backend", "cpu", "--field", field, "--out", s(&ids)];
    let args: Vec<&str> = args.into_iter().chain(["--values", s(&vals)]).collect();
    let o = match ranks {
        None => tetloc(&args),
        Some(n) => mpirun(n, &[], &args).0,
    };
    assert!(o.status.success(), "{tag}: {}", text(&o));
    (read(&ids), read(&vals))
}

/// `tetloc resample MESH --field f --dims 23,19,17 --backend cpu -o dir/OUT` by one process
/// (`ranks`: `None`) or `mpirun -n N`: the image's values.
fn resample_f(dir: &Path, mesh: &Path, out: &str, ranks: Option<usize>) -> Vec<f32> {
    let out = dir.join(out);
    let args = ["resample", s(mesh), "--field", "f", "--dims", "23,19,17", "--backend", "cpu", "-o", s(&out)];
    let o = match ranks {
        None => tetloc(&args),
        Some(n) => mpirun(n, &[], &args).0,
    };
    assert!(o.status.success(), "{}: {}", out.display(), text(&o));
    npy_values(&out)
}

/// A small generated mesh in 4 pieces.
fn small_pvtu(dir: &Path) -> PathBuf {
    let mesh = dir.join("jets.vtu");
    let o = tetloc(&["gen", "jets", "--tets", "20000", "-o", s(&mesh)]);
    assert!(o.status.success(), "{}", text(&o));
    partition(dir, &mesh, "jets", 4)
}

/// 5000 scattered points in the unit cube, in `dir/p.bin`.
fn points_file(dir: &Path) -> PathBuf {
    scattered_points(dir, 5000, |h| (h % 1000) as f32 / 1000.0)
}

/// `n` scattered points in `dir/p.bin`: coordinate k of point i is `coord` of the hash
/// i·7919 + k·104729.
fn scattered_points(dir: &Path, n: usize, coord: impl Fn(usize) -> f32) -> PathBuf {
    let pts: Vec<[f32; 3]> = (0..n).map(|i| std::array::from_fn(|k| coord(i * 7919 + k * 104729))).collect();
    let path = dir.join("p.bin");
    std::fs::write(&path, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    path
}

/// A rank that cannot load its piece, a rank that panics and a rank that dies on a signal:
/// each ends the whole job with a non-zero exit and a message naming the rank, well within
/// the time limit (no rank is left waiting).
#[test]
fn a_failing_rank_ends_the_job() {
    let Some(dir) = mpi_dir("a_failing_rank_ends_the_job", "fail") else { return };
    let pvtu = small_pvtu(&dir);
    let points = points_file(&dir);
    let out = dir.join("ids.bin");
    let args = ["locate", s(&pvtu), "--points", s(&points), "--backend", "cpu", "--out", s(&out)];
    for (fault, want) in [("panic:1", "rank 1 of 4 panicked"), ("abort:2", "rank 2")] {
        let (o, took) = mpirun(4, &[("TETLOC_MPI_FAULT", fault)], &args);
        assert!(!o.status.success(), "{fault}: {}", text(&o));
        assert!(took.as_secs() < LIMIT_S - 10, "{fault}: took {took:?}");
        assert!(text(&o).contains(want), "{fault}: {}", text(&o));
        assert!(!out.exists(), "{fault}: no output from a failed job");
    }
    // A piece missing: rank 3 (4 pieces, one each) fails to load, and says why.
    std::fs::remove_file(dir.join("jets/jets_3.vtu")).unwrap();
    let (o, took) = mpirun(4, &[], &args);
    let t = text(&o);
    assert!(!o.status.success() && took.as_secs() < LIMIT_S - 10, "{t}");
    assert!(t.contains("rank 3 of 4 failed to load") && t.contains("jets_3.vtu"), "{t}");
    assert_eq!(t.matches("failed to load").count(), 1, "said once, by rank 0: {t}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench` under mpirun: one JSON row per query set with the documented keys, every point
/// answered once; and `locate` of a file that is not partitioned is refused with a hint.
#[test]
fn bench_and_refusals() {
    let Some(dir) = mpi_dir("bench_and_refusals", "bench") else { return };
    let pvtu = small_pvtu(&dir);
    let (o, _) = mpirun(
        2,
        &[],
        &["bench", s(&pvtu), "--backend", "cpu", "--queries", "centers,random,bbox", "--json", "--repeats", "1"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let rows: Vec<serde_json::Value> =
        String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(rows.len(), 3, "{}", text(&o));
    for r in &rows {
        for key in [
            "ranks",
            "queries",
            "points",
            "samples_per_s",
            "total_s",
            "local_s",
            "routing_s",
            "ties",
            "load_s",
            "build_s",
        ] {
            assert!(r.get(key).is_some(), "{key} missing: {r}");
        }
        assert_eq!(r["ranks"], 2);
        assert!(r["points"].as_u64().unwrap() > 10_000);
    }
    assert_eq!(rows[0]["ties"], 0, "centres lie on no face");
    let (o, _) = mpirun(2, &[], &["locate", s(&dir.join("jets.vtu")), "--points", "p.bin", "--out", "x.bin"]);
    assert!(!o.status.success() && text(&o).contains("tetloc partition"), "{}", text(&o));
    // The ranks read the pieces' first step: a step asked for is refused, not answered on it.
    let out = dir.join("x.bin");
    let (o, _) = mpirun(2, &[], &["locate", s(&pvtu), "--points", "p.bin", "--out", s(&out), "--time-step", "0"]);
    assert!(!o.status.success() && text(&o).contains("--time-step is not supported under mpirun"), "{}", text(&o));
    assert!(!out.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The float32 values of a `.npy` written by `resample` (after its header).
fn npy_values(p: &Path) -> Vec<f32> {
    let bytes = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let header = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytemuck::pod_collect_to_vec(&bytes[10 + header..])
}

/// Two values agree: both NaN (outside), or within float32 rounding of the interpolation (a
/// point on a face between pieces may be answered by the other cell: the same value, computed
/// from the other cell's corners).
fn same_value(a: f32, b: f32) -> bool {
    (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-5 * (1.0 + a.abs())
}

/// `resample` and `probe` of a partitioned mesh under mpirun (rank 0 drives, the others
/// serve) write what one process writes on the whole mesh: the same valid points, the same
/// values; and options that do not run distributed are refused on every rank.
#[test]
fn resample_and_probe_run_distributed() {
    let Some(dir) = mpi_dir("resample_and_probe_run_distributed", "ops") else { return };
    let pvtu = small_pvtu(&dir);
    let whole = dir.join("jets.vtu");
    let want = resample_f(&dir, &whole, "one.npy", None);
    for n in [2, 3] {
        let got = resample_f(&dir, &pvtu, &format!("ranks{n}.npy"), Some(n));
        assert_eq!(got.len(), want.len());
        let valid = want.iter().filter(|v| !v.is_nan()).count();
        assert!(valid > 1000, "most of the grid is inside: {valid}");
        let differ = (0..got.len()).filter(|&i| !same_value(got[i], want[i])).count();
        assert_eq!(differ, 0, "{n} ranks: {differ} grid points differ from one process");
    }

    // probe onto a coarser mesh of the same shape: the target's vertices get f.
    let target = dir.join("target.vtu");
    let o = tetloc(&["gen", "jets", "--tets", "3000", "-o", s(&target)]);
    assert!(o.status.success(), "{}", text(&o));
    let (one, two) = (dir.join("probe1.vtu"), dir.join("probe2.vtu"));
    let o = tetloc(&["probe", s(&whole), s(&target), "--field", "f", "--backend", "cpu", "-o", s(&one)]);
    assert!(o.status.success(), "{}", text(&o));
    let (o, _) = mpirun(2, &[], &["probe", s(&pvtu), s(&target), "--field", "f", "--backend", "cpu", "-o", s(&two)]);
    assert!(o.status.success(), "{}", text(&o));
    let read = |p: &Path| tetloc_io::read_mesh(p, None).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (read(&one), read(&two));
    for name in ["f", "vtkValidPointMask"] {
        let (fa, fb) = (&a.field(name).unwrap().values, &b.field(name).unwrap().values);
        assert_eq!(fa.len(), fb.len());
        assert!((0..fa.len()).all(|i| same_value(fa[i], fb[i])), "{name} differs");
    }
    assert_eq!(a.points, b.points, "the target's points are written as they were");

    // A tolerance needs the nearest boundary cell over all ranks: refused on every rank.
    let (o, _) = mpirun(
        2,
        &[],
        &["probe", s(&pvtu), s(&target), "--tolerance", "1%", "--backend", "cpu", "-o", s(&dir.join("t.vtu"))],
    );
    let t = text(&o);
    assert!(!o.status.success() && t.contains("--tolerance does not run distributed"), "{t}");
    assert!(!dir.join("t.vtu").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A decomposed OpenFOAM case is partitioned as it stands: `mpirun -n N tetloc locate
/// CASE.foam` gives each rank some processor folders and answers as one process does on the
/// reconstructed case (cell ids its `celli`, by `cellProcAddressing`; values its `lin`). Points
/// off the hexes' faces: each has one answer. A reconstructed case is refused with a hint.
#[test]
fn decomposed_openfoam_cases_run_distributed() {
    use tetloc_testdata::foam_case::{decompose, hex_grid, write_case};
    let Some(dir) = mpi_dir("decomposed_openfoam_cases_run_distributed", "foam") else { return };
    let poly = hex_grid(6);
    write_case(&dir.join("whole"), &poly, None);
    let whole = dir.join("whole/whole.foam");
    std::fs::write(&whole, "").unwrap();
    // Four processors, cells dealt out scattered: most faces lie between processors.
    let proc_of: Vec<usize> = (0..poly.n_cells()).map(|c| c * 5 % 4).collect();
    decompose(&dir.join("cut"), &poly, &proc_of, true);
    let cut = dir.join("cut/cut.foam");
    std::fs::write(&cut, "").unwrap();
    // Points at odd multiples of 1/128 in [-0.5, 6.5)³: none on a face, some outside.
    let points = scattered_points(&dir, 4000, |h| (h % 448) as f32 / 64.0 - 0.5 + 1.0 / 128.0);
    let locate = |mesh: &Path, tag: &str, n: Option<usize>| locate_cpu::<f32>(&dir, mesh, &points, "lin", tag, n);
    let (want_ids, want_vals) = locate(&whole, "one", None);
    let inside = want_ids.iter().filter(|&&i| i >= 0).count();
    assert!(inside > 2000 && inside < want_ids.len(), "{inside} inside");
    for n in [1, 2, 3] {
        let (ids, vals) = locate(&cut, &format!("ranks{n}"), Some(n));
        assert_eq!(ids, want_ids, "{n} ranks");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&vals), bits(&want_vals), "{n} ranks");
    }
    let (o, _) = mpirun(2, &[], &["locate", s(&whole), "--points", s(&points), "--out", s(&dir.join("x.bin"))]);
    let t = text(&o);
    assert!(!o.status.success() && t.contains("decomposed OpenFOAM case"), "{t}");
    let _ = std::fs::remove_dir_all(&dir);
}
