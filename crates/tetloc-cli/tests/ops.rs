//! `resample`, `probe` and `trace` end to end, against VTK itself (vtkResampleToImage,
//! vtkResampleWithDataSet, vtkStreamTracer through `scripts/vtk_ops.py`), on the oracle
//! meshes; and their bad inputs.

mod common;

use common::{s, tetloc, tetloc_cpu, tmp, tmp_dir};
use std::path::{Path, PathBuf};
use tetloc_testdata::{read_f64s, require_data, run_vtk_script};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 * (1.0 + a.abs().max(b.abs()))
}

oracle_tests! {
    /// The image of every field and the valid mask are VTK's; the .npy of one field is the
    /// .vti's array; the grid is VTK's (bounds nudged inwards, points on both ends).
    fn resample_matches_vtk;
    /// The fresh-clone counterpart: [`resample_matches_vtk`] on meshes generated at test time.
    fn resample_matches_vtk_on_generated_meshes;
    resample_matches_vtk_on
}

fn resample_matches_vtk_on(test: &str, data: &Path) {
    for name in ["torus_s", "part_s"] {
        let dir = tmp_dir(&format!("{test}-{name}"));
        let mesh = data.join(format!("{name}.vtu"));
        let (vti, npy) = (dir.join("r.vti"), dir.join("f.npy"));
        let (ok, _, err) = tetloc_cpu(&["resample", s(&mesh), "--dims", "23,19,11", "-o", s(&vti)]);
        assert!(ok, "{err}");
        let (ok, _, err) = tetloc_cpu(&["resample", s(&mesh), "--dims", "23,19,11", "--field", "f", "-o", s(&npy)]);
        assert!(ok, "{err}");
        let Some(()) = run_vtk_script(test, "vtk_ops.py", &["resample", s(&mesh), "23,19,11", s(&vti), s(&dir)]) else {
            return;
        };
        let geometry = |who: &str| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(dir.join(format!("{who}.geometry.json"))).unwrap()).unwrap()
        };
        let (vg, tg) = (geometry("vtk"), geometry("tetloc"));
        assert_eq!(vg["dims"], tg["dims"]);
        // The same up to float32 rounding: tetloc keeps coordinates in float32, VTK's bounds
        // come from the file's float64 points.
        for key in ["origin", "spacing"] {
            for k in 0..3 {
                let (a, b) = (vg[key][k].as_f64().unwrap(), tg[key][k].as_f64().unwrap());
                assert!((a - b).abs() <= 1e-6 * (1.0 + a.abs()), "{name}: {key}: VTK {vg} vs {tg}");
            }
        }
        let mask = read_f64s(&dir.join("vtk.vtkValidPointMask.bin"));
        let ours = read_f64s(&dir.join("tetloc.vtkValidPointMask.bin"));
        // VTK's cell search accepts points a little outside a tet (see data/README.md: it
        // differs from the exact answer at 0.3-1 % of points): where the masks differ, VTK
        // must be the one saying "inside", for a point within 1 % of an edge of the boundary.
        let differ: Vec<usize> = (0..mask.len()).filter(|&i| mask[i] != ours[i]).collect();
        assert!(differ.len() * 200 <= mask.len(), "{name}: masks differ at {} of {} points", differ.len(), mask.len());
        if !differ.is_empty() {
            let g = |k: &str, a: usize| tg[k][a].as_f64().unwrap();
            let dims: Vec<usize> = (0..3).map(|a| tg["dims"][a].as_u64().unwrap() as usize).collect();
            let pts: Vec<[f32; 3]> = differ
                .iter()
                .map(|&i| {
                    let idx = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])];
                    std::array::from_fn(|a| (g("origin", a) + idx[a] as f64 * g("spacing", a)) as f32)
                })
                .collect();
            let (p, ids) = (dir.join("differ.bin"), dir.join("differ.ids.bin"));
            std::fs::write(&p, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
            let (ok, _, err) =
                tetloc_cpu(&["locate", s(&mesh), "--points", s(&p), "--out", s(&ids), "--tolerance", "1%"]);
            assert!(ok, "{err}");
            let near: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(&ids).unwrap());
            for (k, &i) in differ.iter().enumerate() {
                assert!(mask[i] == 1.0 && near[k] >= 0, "{name}: grid point {i} {:?}: VTK mask {}", pts[k], mask[i]);
            }
            eprintln!("{name}: VTK counts {} grid points within its slack of the boundary as inside", differ.len());
        }
        let valid = ours.iter().filter(|&&m| m == 1.0).count();
        assert!(valid > mask.len() / 20 && valid < mask.len(), "{name}: {valid} valid");
        // Values: VTK's within 1e-5 relative, except where VTK's tolerant cell search picked
        // a neighbour of the containing tet (a point within its slack of a face) and
        // extrapolates there: few points, and a small difference for the smooth field `f`.
        for field in ["f", "cellval"] {
            let (v, t) =
                (read_f64s(&dir.join(format!("vtk.{field}.bin"))), read_f64s(&dir.join(format!("tetloc.{field}.bin"))));
            let off: Vec<usize> = (0..v.len()).filter(|&i| ours[i] == 1.0 && !close(v[i], t[i])).collect();
            eprintln!("{name}: {field} differs from VTK's at {} of {valid} points", off.len());
            assert!(off.len() * 100 <= valid, "{name}: {field} differs from VTK's at {} of {valid} points", off.len());
            if field == "f" {
                for &i in &off {
                    assert!((v[i] - t[i]).abs() < 1e-3, "{name}: f at grid point {i}: VTK {} vs {}", v[i], t[i]);
                }
            }
            assert!((0..v.len()).filter(|&i| ours[i] == 0.0).all(|i| t[i].is_nan()), "{name}: NaN outside");
        }
        let bytes = std::fs::read(&npy).unwrap();
        let header_len = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = String::from_utf8_lossy(&bytes[10..header_len]);
        assert!(header.contains("'shape': (11, 19, 23)") && header.contains("'<f4'"), "{header}");
        let f: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes[header_len..]);
        let vti_f = read_f64s(&dir.join("tetloc.f.bin"));
        assert!(f.iter().zip(&vti_f).all(|(&a, &b)| (a.is_nan() && b.is_nan()) || a as f64 == b), "{name}: npy vs vti");
    }
}

/// Bad input gets a clear error and no output.
#[test]
fn bad_inputs_are_refused() {
    let dir = tmp_dir("bad");
    let out = dir.join("x.vti");
    let (ok, _, err) = tetloc_cpu(&["resample", "jets:2000", "--dims", "4,0,4", "-o", s(&out)]);
    assert!(!ok && err.contains("at least 1"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["resample", "jets:2000", "--dims", "4,4,4", "-o", "/nonexistent-dir/x.vti"]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["resample", "jets:2000", "--dims", "4,4", "-o", s(&out)]);
    assert!(!ok && err.contains("three"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["resample", "jets:2000", "--dims", "4,4,4", "--field", "nope", "-o", s(&out)]);
    assert!(!ok && err.contains("'nope'") && err.contains("'f'"), "{err}");
    assert!(!out.exists());
    let vtp = dir.join("l.vtp");
    let (ok, _, err) =
        tetloc(&["trace", "jets:2000", "--vector", "nope", "--seeds", "line:0,0,0,1,1,1,3", "-o", s(&vtp)]);
    assert!(!ok && err.contains("'nope'"), "{err}");
    let (ok, _, err) = tetloc(&["trace", "jets:2000", "--vector", "f", "--seeds", "line:0,0,0,1,1,1,3", "-o", s(&vtp)]);
    assert!(!ok && err.contains("3 components"), "{err}");
    let (ok, _, err) = tetloc(&[
        "trace",
        "jets:2000",
        "--vector",
        "f",
        "--seeds",
        "line:0,0,0,1,1,1,3",
        "-o",
        "/nonexistent-dir/l.vtp",
    ]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    let trace = |extra: &[&str]| {
        let mut args = vec!["trace", "jets:2000", "--vector", "v", "-o", s(&vtp)];
        if !extra.contains(&"--seeds") {
            args.extend(["--seeds", "line:0,0,0,1,1,1,3"]);
        }
        args.extend(extra);
        tetloc(&args)
    };
    for (extra, want) in [
        (&["--integrator", "euler"][..], "integrator 'euler'"),
        (&["--integrator", "rk45", "--min-step", "0.1", "--max-step", "0.01"], "min <= max"),
        (&["--max-time=-1"], "maximum time"),
        (&["--step", "0"], "positive length"),
        (&["--seeds", "line:0,0,0,1,1,x,3"], "not a number"),
        (&["--seeds", "/nonexistent-dir/seeds.npy"], "nonexistent-dir"),
    ] {
        let (ok, _, err) = trace(extra);
        assert!(!ok && err.contains(want), "{extra:?}: {err}");
    }
    assert!(!vtp.exists());
    // probe: a field that does not exist, an output directory that does not exist, a mesh
    // target written as .vtp.
    let pts = dir.join("p.csv");
    std::fs::write(&pts, "0.5,0.5,0.5\n").unwrap();
    let vtu = dir.join("p.vtu");
    let (ok, _, err) = tetloc_cpu(&["probe", "jets:2000", s(&pts), "-o", s(&vtu), "--field", "nope"]);
    assert!(!ok && err.contains("'nope'"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["probe", "jets:2000", s(&pts), "-o", "/nonexistent-dir/p.vtu"]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["probe", "jets:2000", "jets:1000", "-o", s(&dir.join("p.vtp"))]);
    assert!(!ok && err.contains("vtu") && err.contains("p.vtp"), "{err}");
    assert!(!vtu.exists());
}

/// A trace with a huge --max-steps (its lines bounded by --max-length, so one batch) is the file
/// one batch makes, byte for byte, when the lines stop by length before either step limit.
#[test]
fn trace_in_batches_is_one_file() {
    let dir = tmp_dir("trace-batches");
    let run = |batch_points: &str, out: &Path| {
        let (ok, _, err) = tetloc_cpu(&[
            "trace",
            "jets:3000",
            "--vector",
            "v",
            "--seeds",
            "grid:0.1,0.9,0.1,0.9,0.1,0.9,13,13,13",
            "--direction",
            "both",
            "--step",
            "0.004",
            "--max-length",
            "0.02",
            "--batch-points",
            batch_points,
            "-o",
            s(out),
        ]);
        assert!(ok, "{err}");
        std::fs::read(out).unwrap()
    };
    let (one, batched) = (dir.join("one.vtp"), dir.join("batched.vtp"));
    // Lines of at most 0.02 / 0.004 + 2 = 7 steps, 9 points: the default holds all 2 × 13³
    // lines in one batch; 9,000 points a batch hold 1,000 lines, so each direction takes 3.
    let bytes = run("33554432", &one);
    // Every seed is inside: 13³ lines each way.
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).into_owned();
    assert!(head.contains(&format!("NumberOfLines=\"{}\"", 2 * 13 * 13 * 13)), "{head}");
    assert_eq!(bytes, run("9000", &batched));
}

/// The swirl on the torus (v = (-y + 0.2x, x + 0.2y, 0.3), so lines spiral outwards and
/// leave through the boundary) as a mesh file, and five seeds (the last, the origin, outside).
fn swirl_case(data: &Path, dir: &Path) -> (PathBuf, PathBuf) {
    let mut m = tetloc_io::read_mesh(&data.join("torus_s.vtu"), None).unwrap();
    let swirl = |p: [f32; 3]| [-p[1] + 0.2 * p[0], p[0] + 0.2 * p[1], 0.3];
    for c in 0..3 {
        let values = m.points.iter().map(|&p| swirl(p)[c]).collect();
        m.fields.push(tetloc_core::Field {
            values64: None,
            name: format!("v[{c}]"),
            location: tetloc_core::FieldLocation::Vertex,
            values,
        });
    }
    let mesh = dir.join("swirl.vtu");
    tetloc_io::vtk::write::write_mesh_vtu(&mesh, &m, false).unwrap();
    let seeds = dir.join("seeds.bin");
    let pts: Vec<[f32; 3]> =
        vec![[0.8, 0.0, 0.0], [1.0, 0.1, 0.1], [0.0, 1.2, -0.1], [-1.1, 0.0, 0.2], [0.0, 0.0, 0.0]];
    std::fs::write(&seeds, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    (mesh, seeds)
}

/// Lines as `vtk_ops.py trace` dumps them: (offsets, points, times, seeds, reasons).
type Lines = (Vec<i64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

fn dumped_lines(dir: &Path, who: &str) -> Lines {
    let read = |what: &str| read_f64s(&dir.join(format!("{who}.{what}.bin")));
    let offsets = bytemuck::pod_collect_to_vec(&std::fs::read(dir.join(format!("{who}.offsets.bin"))).unwrap());
    (offsets, read("points"), read("IntegrationTime"), read("SeedIds"), read("ReasonForTermination"))
}

/// Traces the swirl case with `extra` options, and VTK with `vtk_extra`; both lines dumped.
fn trace_both(test: &str, name: &str, extra: &[&str], vtk_extra: &[&str]) -> Option<(Lines, Lines, String)> {
    let data = require_data(test)?;
    trace_both_on(test, &data, name, extra, vtk_extra)
}

/// [`trace_both`] on the meshes of `data`.
fn trace_both_on(
    test: &str,
    data: &Path,
    name: &str,
    extra: &[&str],
    vtk_extra: &[&str],
) -> Option<(Lines, Lines, String)> {
    let dir = tmp_dir(&format!("{test}-{name}"));
    let (mesh, seeds) = swirl_case(data, &dir);
    let out = dir.join("lines.vtp");
    let mut args = vec!["trace", s(&mesh), "--vector", "v", "--seeds", s(&seeds), "-o", s(&out), "--step", "0.01"];
    args.extend(["--max-steps", "400", "--direction", "both", "--backend", "cpu"]);
    args.extend(extra);
    let (ok, _, err) = tetloc(&args);
    assert!(ok, "{err}");
    let mut vtk_args = vec!["trace", s(&mesh), "v", s(&seeds), "0.01", "400", "both", s(&out), s(&dir)];
    vtk_args.extend(vtk_extra);
    run_vtk_script(test, "vtk_ops.py", &vtk_args)?;
    Some((dumped_lines(&dir, "vtk"), dumped_lines(&dir, "tetloc"), err))
}

/// The same lines (seeds, reasons), every point within `tol` of VTK's, the times within
/// 1e-4; ending at the same boundary (at most one step apart: VTK's cell search accepts a
/// point just outside).
fn same_lines(vtk: &Lines, ours: &Lines, tol: f64) {
    let ((vo, vp, vt, vs, vr), (to, tp, tt, ts, tr)) = (vtk, ours);
    assert_eq!(vo.len(), to.len(), "lines: VTK {} vs {}", vo.len() - 1, to.len() - 1);
    assert_eq!((vs, vr), (ts, tr), "seeds and reasons");
    for l in 0..vo.len() - 1 {
        let (va, vb, ta, tb) = (vo[l] as usize, vo[l + 1] as usize, to[l] as usize, to[l + 1] as usize);
        assert!((vb - va).abs_diff(tb - ta) <= 1, "line {l}: {} points in VTK, {} here", vb - va, tb - ta);
        for k in 0..(vb - va).min(tb - ta) {
            let d = (0..3).map(|a| (vp[3 * (va + k) + a] - tp[3 * (ta + k) + a]).powi(2)).sum::<f64>().sqrt();
            assert!(d <= tol, "line {l}, point {k}: {d:e} from VTK's");
            assert!((vt[va + k] - tt[ta + k]).abs() <= 1e-4 * (1.0 + vt[va + k].abs()), "line {l}, point {k}: time");
        }
    }
}

/// The swirl's streamlines against vtkStreamTracer with the same RK4 step: the same lines
/// (seed, reason), the same points within 1e-4 of the domain size, ending at the same
/// boundary. A seed outside the mesh gives no line and a warning.
#[test]
fn trace_matches_vtk() {
    let Some((vtk, ours, err)) = trace_both("trace_matches_vtk", "trace", &[], &[]) else { return };
    assert!(err.contains("2 of 10 lines"), "the seed at the origin is outside: {err}");
    same_lines(&vtk, &ours, 1e-4 * TORUS_SIZE);
}

/// The fresh-clone counterpart: [`trace_matches_vtk`] on a torus generated at test time.
#[test]
fn trace_matches_vtk_on_a_generated_torus() {
    const TEST: &str = "trace_matches_vtk_on_a_generated_torus";
    let data = tetloc_testdata::generated_data();
    let Some((vtk, ours, err)) = trace_both_on(TEST, data, "trace", &[], &[]) else { return };
    assert!(err.contains("2 of 10 lines"), "the seed at the origin is outside: {err}");
    same_lines(&vtk, &ours, 1e-4 * TORUS_SIZE);
}

oracle_tests! {
    /// `tetloc trace --backend soft-bvh` (every particle advanced together, one batched lookup
    /// per stage on the GPU) gives the cpu backend's lines: the same lines, reasons and point
    /// counts, every point within 1e-5 of the domain (float32 sampling on the device against
    /// the CPU's: ~1e-7 per lookup, over a few hundred steps). Skipped without a Vulkan device
    /// (failed in CI).
    fn trace_on_the_gpu_matches_cpu;
    /// The fresh-clone counterpart: [`trace_on_the_gpu_matches_cpu`] on a torus generated at test time.
    fn trace_on_the_gpu_matches_cpu_on_a_generated_torus;
    trace_on_the_gpu_matches_cpu_on
}

fn trace_on_the_gpu_matches_cpu_on(test: &str, data: &Path) {
    let (ok, out, _) = tetloc(&["devices"]);
    if !ok || !out.contains("Vulkan") {
        assert!(!tetloc_testdata::in_ci(), "{test}: no Vulkan device in CI");
        tetloc_testdata::skip(test, "no Vulkan device");
        return;
    }
    let dir = tmp_dir(test);
    let (mesh, seeds) = swirl_case(data, &dir);
    let mut dumped = Vec::new();
    for (backend, integrator) in [("cpu", "rk4"), ("soft-bvh", "rk4"), ("cpu", "rk45"), ("soft-bvh", "rk45")] {
        let out = dir.join(format!("{backend}-{integrator}.vtp"));
        let mut args = vec!["trace", s(&mesh), "--vector", "v", "--seeds", s(&seeds), "-o", s(&out)];
        args.extend(["--step", "0.01", "--max-steps", "300", "--direction", "both", "--quiet"]);
        args.extend(["--backend", backend, "--integrator", integrator]);
        let (ok, _, err) = tetloc(&args);
        assert!(ok, "{backend}: {err}");
        let sub = dir.join(format!("{backend}-{integrator}"));
        std::fs::create_dir_all(&sub).unwrap();
        let vtk_args = ["trace", s(&mesh), "v", s(&seeds), "0.01", "300", "both", s(&out), s(&sub)];
        let Some(()) = run_vtk_script(test, "vtk_ops.py", &vtk_args) else { return };
        dumped.push(dumped_lines(&sub, "tetloc"));
    }
    for pair in dumped.chunks(2) {
        let ((co, cp, ct, cs, cr), (go, gp, gt, gs, gr)) = (&pair[0], &pair[1]);
        assert_eq!((co, cs, cr), (go, gs, gr), "lines, seeds, reasons and point counts");
        let worst = cp.iter().zip(gp).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        eprintln!(
            "{test}: points within {worst:e}, times within {:e}",
            ct.iter().zip(gt).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
        );
        assert!(worst <= 1e-5 * TORUS_SIZE, "a point {worst:e} from the cpu's");
    }
}

/// The torus' extent.
const TORUS_SIZE: f64 = 2.7;

/// The adaptive step against vtkStreamTracer's RK45 (vtkRungeKutta45). Where the error
/// allows the maximum step (bounds 0.001 and 0.05, maximum error 1e-6), Cash-Karp gives VTK's
/// lines point by point (the same tableau and loop). Where the error controls the step (bounds
/// 0.001 and 0.5, maximum error 1e-7), the step sizes differ a little: the field reaches the
/// integrator as float32 (the locators' values; VTK interpolates in float64), whose rounding
/// (~6e-8 relative) adds ~1e-11 to the error estimate of the small first step; so there both
/// integrators give the same lines (seeds, reasons) on the same paths: each point within
/// 1e-4 of the domain from VTK's polyline.
#[test]
fn trace_rk45_matches_vtk() {
    const TEST: &str = "trace_rk45_matches_vtk";
    let Some(data) = require_data(TEST) else { return };
    trace_rk45_matches_vtk_on(TEST, &data);
}

fn trace_rk45_matches_vtk_on(test: &str, data: &Path) {
    let clamped = ["--integrator", "cash-karp", "--min-step", "0.001", "--max-step", "0.05", "--max-error", "1e-6"];
    let Some((vtk, ours, _)) = trace_both_on(test, data, "trace-ck", &clamped, &["rk45", "0.001", "0.05", "1e-6"])
    else {
        return;
    };
    same_lines(&vtk, &ours, 1e-4 * TORUS_SIZE);
    for integrator in ["cash-karp", "rk45"] {
        let controlled =
            ["--integrator", integrator, "--min-step", "0.001", "--max-step", "0.5", "--max-error", "1e-7"];
        let vtk_args = ["rk45", "0.001", "0.5", "1e-7"];
        let name = format!("trace-{integrator}");
        let Some((vtk, ours, _)) = trace_both_on(test, data, &name, &controlled, &vtk_args) else { return };
        // The folder `trace_both_on` wrote.
        let worst = on_the_same_paths(&tmp(&format!("{test}-{name}")), &vtk, &ours);
        eprintln!("{integrator}: every point within {worst:e} of VTK's RK45 lines");
        assert!(worst <= 1e-4 * TORUS_SIZE, "{integrator}: a point {worst:e} from VTK's line");
    }
}

/// The same lines (seeds, reasons); the largest distance of a point of ours from VTK's path,
/// up to VTK's last point (in time: the last step to the boundary differs with the steps).
/// VTK's path between two of its points is the cubic Hermite curve through them along the
/// field (`v`, dumped with the lines): its error, ~h⁴/384 of the fourth derivative, is far
/// below the tolerance, where the chord's sagitta (h²/8R, 6e-3 for the 0.2 steps) is not.
fn on_the_same_paths(dir: &Path, vtk: &Lines, ours: &Lines) -> f64 {
    let ((vo, vp, vt, vs, vr), (to, tp, tt, ts, tr)) = (vtk, ours);
    assert_eq!((vo.len(), vs, vr), (to.len(), ts, tr), "lines, seeds and reasons");
    let vv = read_f64s(&dir.join("vtk.v.bin"));
    let point = |k: usize| -> [f64; 3] { std::array::from_fn(|a| vp[3 * k + a]) };
    let tangent = |k: usize| -> [f64; 3] {
        let v: [f64; 3] = std::array::from_fn(|a| vv[3 * k + a]);
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        v.map(|x| x / n)
    };
    // VTK's path of line `l` sampled finely.
    let path = |l: usize| -> Vec<[f64; 3]> {
        let mut out = Vec::new();
        for j in vo[l] as usize..vo[l + 1] as usize - 1 {
            let (a, b, mut ta, mut tb) = (point(j), point(j + 1), tangent(j), tangent(j + 1));
            let h = (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            if (0..3).map(|i| ta[i] * (b[i] - a[i])).sum::<f64>() < 0.0 {
                (ta, tb) = (ta.map(|x| -x), tb.map(|x| -x)); // a backward line
            }
            for q in 0..=64 {
                let s = q as f64 / 64.0;
                let (h00, h10, h01, h11) = (
                    2.0 * s.powi(3) - 3.0 * s * s + 1.0,
                    s.powi(3) - 2.0 * s * s + s,
                    -2.0 * s.powi(3) + 3.0 * s * s,
                    s.powi(3) - s * s,
                );
                out.push(std::array::from_fn(|i| h00 * a[i] + h10 * h * ta[i] + h01 * b[i] + h11 * h * tb[i]));
            }
        }
        out
    };
    let mut worst = 0f64;
    for l in 0..vo.len() - 1 {
        let fine = path(l);
        let end = vt[vo[l + 1] as usize - 1].abs();
        for k in (to[l] as usize..to[l + 1] as usize).filter(|&k| tt[k].abs() <= end) {
            let p: [f64; 3] = std::array::from_fn(|a| tp[3 * k + a]);
            let d = fine.windows(2).map(|w| point_segment_distance(p, (w[0], w[1]))).fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
    }
    worst
}

fn point_segment_distance(p: [f64; 3], (a, b): ([f64; 3], [f64; 3])) -> f64 {
    let ab: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
    let ap: [f64; 3] = std::array::from_fn(|i| p[i] - a[i]);
    let len2: f64 = ab.iter().map(|x| x * x).sum();
    let t = if len2 > 0.0 { (ap.iter().zip(&ab).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0) } else { 0.0 };
    (0..3).map(|i| (ap[i] - t * ab[i]).powi(2)).sum::<f64>().sqrt()
}

oracle_tests! {
    /// Probing the torus at its `bbox` query points (many outside) against vtkResampleWithDataSet:
    /// the mask is the exact oracle's, and VTK's but at a few points (its cell search takes
    /// points within its slack outside a tet as inside, and misses a few inside: about 0.1 %);
    /// the values are VTK's; VTK reads the point set we write.
    fn probe_matches_vtk;
    /// The fresh-clone counterpart: [`probe_matches_vtk`] on a torus generated at test time, with
    /// exact answers.
    fn probe_matches_vtk_on_a_generated_torus;
    probe_matches_vtk_on
}

fn probe_matches_vtk_on(test: &str, data: &Path) {
    let dir = tmp_dir(test);
    let (mesh, pts) = (data.join("torus_s.vtu"), data.join("torus_s.bbox.points.bin"));
    let out = dir.join("p.vtp");
    let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&pts), "-o", s(&out)]);
    assert!(ok, "{err}");
    let Some(()) = run_vtk_script(test, "vtk_ops.py", &["probe", s(&mesh), s(&pts), s(&out), s(&dir)]) else { return };
    let (vm, tm) =
        (read_f64s(&dir.join("vtk.vtkValidPointMask.bin")), read_f64s(&dir.join("tetloc.vtkValidPointMask.bin")));
    let valid = tm.iter().filter(|&&m| m == 1.0).count();
    assert!(valid > tm.len() / 10 && valid < tm.len(), "{valid} of {} valid", tm.len());
    let differ: Vec<usize> = (0..vm.len()).filter(|&i| vm[i] != tm[i]).collect();
    assert!(differ.len() * 200 <= vm.len(), "masks differ at {} of {} points", differ.len(), vm.len());
    let oracle: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(data.join("torus_s.bbox.cell.bin")).unwrap());
    let flags = std::fs::read(data.join("torus_s.bbox.flags.bin")).unwrap();
    let wrong = (0..tm.len()).filter(|&i| flags[i] & 1 == 0 && (tm[i] == 1.0) != (oracle[i] >= 0)).count();
    assert_eq!(wrong, 0, "the mask differs from the exact answer at {wrong} points");
    let (vf, tf) = (read_f64s(&dir.join("vtk.f.bin")), read_f64s(&dir.join("tetloc.f.bin")));
    // f: the exact interpolation (the oracle's f64 value) wherever the point is not within
    // rounding of a face; VTK's value where both have one, but where VTK's tolerant search
    // took a neighbouring tet and extrapolates.
    let exact = read_f64s(&data.join("torus_s.bbox.value.bin"));
    let inexact = (0..tf.len()).filter(|&i| flags[i] & 1 == 0 && oracle[i] >= 0 && !close(exact[i], tf[i])).count();
    assert_eq!(inexact, 0, "f differs from the exact interpolation at {inexact} points");
    let both = (0..vf.len()).filter(|&i| tm[i] == 1.0 && vm[i] == 1.0).count();
    let off = (0..vf.len()).filter(|&i| tm[i] == 1.0 && vm[i] == 1.0 && !close(vf[i], tf[i])).count();
    eprintln!("torus_s: masks differ at {} points, f at {off} of {both}", differ.len());
    assert!(off * 50 <= both, "f differs from VTK's at {off} of {both} points");
    assert!((0..tf.len()).filter(|&i| tm[i] == 0.0).all(|i| tf[i].is_nan()));
}

/// `--time-step all` runs each step with the locator the step before left, given that
/// step's fields (its search kept): every step's output is `--time-step K`'s run alone, byte
/// for byte, for `probe`, `resample`, `locate` and `trace` (streamlines in each step's `v`),
/// on the CPU and on a GPU kernel, and the
/// steps differ.
#[test]
fn each_step_of_all_is_that_step_run_alone() {
    let dir = tmp_dir("each_step");
    let series = dir.join("steps.msh");
    common::gmsh_series_of(&series, &[0.0, 0.5, 1.5], true);
    let pts = dir.join("p.csv");
    let text: String =
        (0..200).map(|i| format!("{},{},{}\n", 0.05 + 0.0045 * i as f64, 0.3 + 0.002 * i as f64, 0.61)).collect();
    std::fs::write(&pts, text).unwrap();
    let runs: [(&str, &str, Vec<&str>); 4] = [
        ("probe", "vtu", vec![s(&series), s(&pts)]),
        ("resample", "npy", vec![s(&series), "--dims", "9,8,7", "--field", "f"]),
        ("locate", "csv", vec![s(&series), "--points", s(&pts), "--field", "f"]),
        ("trace", "vtp", vec![s(&series), "--vector", "v", "--seeds", s(&pts), "--step", "0.01"]),
    ];
    for backend in ["cpu"].into_iter().chain(common::gpu_backend("each_step_of_all_is_that_step_run_alone")) {
        for (command, ext, args) in &runs {
            let out = |name: &str| dir.join(format!("{command}-{backend}-{name}.{ext}"));
            let run = |step: &str, to: &Path| {
                let mut a = vec![*command];
                a.extend(args);
                a.extend(["--time-step", step, "--backend", backend, "-q"]);
                a.extend([if *command == "locate" { "--out" } else { "-o" }, s(to)]);
                let (ok, _, err) = tetloc(&a);
                assert!(ok, "{command} {backend} --time-step {step}: {err}");
            };
            run("all", &out("all"));
            let mut steps = Vec::new();
            for k in 0..3 {
                run(&k.to_string(), &out(&format!("one{k}")));
                let all = std::fs::read(out(&format!("all_{k}"))).unwrap();
                assert!(all == std::fs::read(out(&format!("one{k}"))).unwrap(), "{command} {backend}: step {k}");
                steps.push(all);
            }
            assert!(steps[0] != steps[1] && steps[1] != steps[2], "{command} {backend}: the steps differ");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
